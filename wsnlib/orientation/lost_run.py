"""Paper 001's weight μ_λ (eq. (3)) and the effective λ after a gap (the λ schedules).

Paper 001 (De Vito et al.) counts λ, "the number of samples lost consecutively" (Sec. III),
and weights the data-fusion estimate by ``μ_λ = ρ / (λ/τ + ρ) ∈ (0, 1]``, ``ρ, τ ∈ ℕ₊``
(eq. (3), :func:`slerp_weight`; eq. (5) prints it with τ = 1).  What λ is on a received
sample the paper leaves open.  Read literally, λ counts the samples lost in a row, so it is 0
on every received sample: μ = 1 there, and eq. (4) returns the data fusion unchanged whenever
there is anything to output; the method would do nothing.  λ must therefore live on after
reception resumes, and decay, or μ would stay below 1 for ever.  :func:`effective_lost_run`
offers three schedules (exact definitions there): ``"decay"`` (λ drops by one per received
sample; the default), ``"hold"`` (λ stays at the gap length for ``hold_window`` received
samples, then drops to 0) and ``"instant"`` (the literal reading, shown for comparison).

The filters do not call these functions: they update λ_eff in their compiled loop
(:func:`wsnlib.orientation._kernels.next_lost_run`), so no ``(..., T)`` array of λ or μ is
made.  These functions give the same numbers as arrays, to plot or to test against.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import check_choice
from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K

#: λ schedules of :func:`effective_lost_run`.
SCHEDULES = ("decay", "hold", "instant")
#: Default ``hold_window`` (received samples): 1 s at the paper's 50 Hz, about how long the
#: hybrid's elbow error stays high after the paper's 4-packet loss (Sec. IV, Fig. 8).
DEFAULT_HOLD_WINDOW = 50
#: The kernels' code of each schedule.
SCHEDULE_CODES = dict(zip(SCHEDULES, (K.DECAY, K.HOLD, K.INSTANT), strict=True))
#: Defaults of eq. (3)'s ρ, τ and of the λ schedule (μ = 1/2 at λ_eff = 12 samples).
DEFAULT_RHO, DEFAULT_TAU, DEFAULT_SCHEDULE = 2.0, 6.0, "decay"


def check_weight_options(rho, tau, schedule, hold_window):
    """The options of μ every hybrid shares, checked (``None``: the defaults above): ρ and τ as
    float arrays > 0, the schedule's name and ``hold_window`` as :func:`effective_lost_run` takes it."""
    schedule = check_choice(DEFAULT_SCHEDULE if schedule is None else schedule, "schedule", SCHEDULES)
    return (B.positive_array(DEFAULT_RHO if rho is None else rho, "rho"),
            B.positive_array(DEFAULT_TAU if tau is None else tau, "tau"), schedule,
            B.check_hold_window(hold_window, schedule, DEFAULT_HOLD_WINDOW))


def slerp_weight(lost_run, rho, tau) -> np.ndarray:
    """Interpolation amount μ_λ of eq. (3) of paper 001: ``μ = ρ / (λ/τ + ρ)``.

    μ = 1 at λ = 0 (the data-fusion estimate is kept whole) and μ → 0 as λ grows (the
    single-frame estimate takes over); μ falls as λ grows and rises with ρ and with τ.  It
    equals ``ρτ / (λ + ρτ)``, so only the product ρτ matters: ``ρτ`` is the λ at which
    μ = 1/2.  Eq. (5) of the paper writes ``ρ / (λ + ρ)``, which is eq. (3) with τ = 1.

    Parameters
    ----------
    lost_run : array_like
        λ, samples lost in a row (or an effective λ from :func:`effective_lost_run`),
        finite and >= 0.
    rho, tau : float or array_like
        ρ and τ, positive integers in the paper; any finite positive reals are accepted.

    Returns
    -------
    numpy.ndarray
        μ in (0, 1], shape the broadcast of the three arguments (numpy rules: to give one
        ρ per batch element of a ``(..., T)`` λ, append an axis, ``rho[..., None]``).

    Raises
    ------
    ValueError
        If λ < 0, ρ <= 0 or τ <= 0, if any is NaN or inf, or if the shapes do not broadcast,
        naming the argument.
    """
    lam = B.nonnegative_array(lost_run, "lost_run")
    rho = B.positive_array(rho, "rho")
    tau = B.positive_array(tau, "tau")
    try:
        np.broadcast_shapes(lam.shape, rho.shape, tau.shape)
    except ValueError as exc:
        raise ValueError(f"lost_run {lam.shape}, rho {rho.shape} and tau {tau.shape} do not broadcast") from exc
    return rho / (lam / tau + rho)


def effective_lost_run(received, schedule: str = "decay", hold_window=None) -> np.ndarray:
    """Effective λ at every sample: how far the data-fusion estimate may lag behind.

    Paper 001 defines λ as the number of samples lost in a row; on a received sample that
    count is 0, so eq. (3) would give μ = 1 exactly where the hybrid has something to show
    (module docstring).  A schedule says what λ is once reception resumes.  All schedules
    share the rule on lost samples, ``λ_t = λ_{t−1} + 1`` with ``λ_{−1} = 0``: the running
    count, added to whatever was left from earlier gaps.  On a received sample ``t``:

    * ``"decay"``: ``λ_t = λ_{t−1}`` if sample ``t − 1`` was lost (the first received sample
      after a gap gets the full count), else ``λ_t = max(λ_{t−1} − 1, 0)``.  After an
      isolated gap of ``L`` samples the received samples see ``L, L−1, …, 1, 0``.  A gap
      that starts before λ reached 0 adds its count to what is left: after a gap of 24,
      three received samples (24, 23, 22) and a gap of 6, λ is 23…28 on the lost samples
      and 28, 27, … after them.
    * ``"hold"``: ``λ_t = λ_{t−1}`` for the first ``hold_window`` received samples after a
      gap, then 0.  After an isolated gap of ``L`` samples the received samples see ``L``
      ``hold_window`` times, then 0.  A gap starting within the window adds to the held
      value (as for ``"decay"``), and the window restarts after it.
    * ``"instant"``: ``λ_t = 0``, the literal reading of the paper (then λ is
      :func:`wsnlib.loss.lost_run_length`, and eq. (4) never changes a received sample).

    A gap at the start counts like any other (λ = L on the first received sample); a gap
    at the end just keeps counting.

    Parameters
    ----------
    received : array_like of bool, shape (..., T)
        True = received.
    schedule : {"decay", "hold", "instant"}
    hold_window : int or array_like of int, optional
        Received samples during which ``"hold"`` keeps λ, >= 1; one per batch element if
        an array (broadcasting against the leading dimensions of ``received``).  Default
        :data:`DEFAULT_HOLD_WINDOW` = 50 (1 s at 50 Hz).  Only for ``schedule="hold"``.

    Returns
    -------
    numpy.ndarray of float, shape (..., T)
        Effective λ (samples); ``...`` is the broadcast of the leading dimensions of
        ``received`` and ``hold_window``.

    Raises
    ------
    ValueError
        For a non-boolean ``received``, an unknown ``schedule``, a ``hold_window`` that is
        not a positive integer, or given with another schedule.
    """
    mask = B.check_received(received)
    schedule = check_choice(schedule, "schedule", SCHEDULES)
    window = B.check_hold_window(hold_window, schedule, DEFAULT_HOLD_WINDOW)
    shapes = {"received": mask.shape[:-1]}
    if window is not None:
        shapes["hold_window"] = window.shape
    B.broadcast_batch(shapes)
    return effective_lost_run_unchecked(mask, schedule, window, leading_gap=True)


def effective_lost_run_unchecked(mask: np.ndarray, schedule: str, window, leading_gap: bool) -> np.ndarray:
    """λ_eff ``(..., T)`` without validation; ``leading_gap=False``: no gap before the first sample."""
    window = np.asarray(1 if window is None else window, dtype=np.int64)
    batch = np.broadcast_shapes(mask.shape[:-1], window.shape)
    n_t = mask.shape[-1]
    out = B.new_output(batch, n_t, 1)[..., 0]
    if n_t:
        K.run_lost_run(B.flat(mask, 1), B.index_into(mask.shape[:-1], batch), SCHEDULE_CODES[schedule],
                       B.per_element(window, batch, np.int64), leading_gap, out.reshape(-1, n_t))
    return out
