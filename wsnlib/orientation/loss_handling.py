"""Packet-loss handling for Madgwick's filter: paper 001's hybrid SLERP and the Sec. V alternatives.

Paper 001 (De Vito et al.) counts λ, "the number of samples lost consecutively" (Sec. III),
and interpolates between the single-frame (TRIAD) estimate ``q_s`` and the data-fusion
(Madgwick) estimate ``q_d``:

* eq. (2): ``SLERP(q_A, q_B, μ) = sin((1−μ)Ω)/sin Ω · q_A + sin(μΩ)/sin Ω · q_B``
  (:func:`wsnlib.quaternion.slerp`);
* eq. (3): ``μ_λ = ρ / (λ/τ + ρ) ∈ (0, 1]``, ``ρ, τ ∈ ℕ₊`` (:func:`slerp_weight`);
* eq. (4): ``q_f = SLERP(q_s, q_d, μ_λ)``: μ = 1 gives the data fusion, μ → 0 the single
  frame;
* eq. (5): eqs. (2)–(4) combined, printed with ``ρ/(λ + ρ)``, i.e. eq. (3) with τ = 1.

Sec. V adds three alternatives, all offered by :func:`estimate_orientation` so that they
run on identical data: integrating the first gyroscope sample after a gap over
``(1 + λ)Δt`` (``method="dt_extension"``), linear interpolation of the gyroscope across the
gap (``"gyro_interpolation"``), and a step size β that depends on λ (``"adaptive_beta"``).
``"hold_last"`` is plain Madgwick under loss (:func:`wsnlib.orientation.madgwick`), the
baseline, and ``"hybrid"`` is eqs. (3)–(4).

Two questions the paper leaves open
-----------------------------------
1. *What is λ on a received sample?*  Read literally, λ counts the samples lost in a row, so
   it is 0 on every received sample: μ = 1 there, and eq. (4) returns ``q_d`` unchanged
   whenever there is anything to output; the method would do nothing.  λ must therefore
   live on after reception resumes, and decay, or μ would stay below 1 for ever.
   :func:`effective_lost_run` offers three schedules (exact definitions there):
   ``"decay"`` (λ drops by one per received sample; the default), ``"hold"`` (λ stays at
   the gap length for ``hold_window`` received samples, then drops to 0) and
   ``"instant"`` (the literal reading, shown for comparison).
2. *Is the SLERP output fed back into the filter?*  Fig. 4 draws it as an output stage,
   while Sec. V speaks of a method "to make the internal state of [the] data-fusion
   algorithm recover fast".  ``blend="output"`` leaves Madgwick's state untouched and
   blends only what is shown; ``blend="feedback"`` replaces the state by ``q_f`` after each
   received sample.  With ``"output"`` the display returns to Madgwick's state, however
   far it still lags, as soon as λ_eff is back to 0; with ``"feedback"`` the state itself
   is pulled towards TRIAD while λ_eff > 0.
   :func:`blend_with_single_frame` applies the output blend to any filter's output (the
   peer filters of :mod:`wsnlib.orientation.peers` use it).

Held output
-----------
On a lost sample every method outputs the previous output (the receiver has nothing new to
show), as :func:`wsnlib.orientation.madgwick` does.  Before a batch element's first received
sample the output is the initial estimate.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array, check_nonzero_norm, check_positive
from wsnlib.loss import lost_run_length
from wsnlib.orientation.madgwick import (
    _as_signal,
    _broadcast_batch,
    _check_inputs,
    _initial_estimate,
    _update,
    _usable,
)
from wsnlib.orientation.triad import triad

#: Loss-handling methods of :func:`estimate_orientation`.
METHODS = ("hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid")
#: λ schedules of :func:`effective_lost_run`.
SCHEDULES = ("decay", "hold", "instant")
#: Where the hybrid's SLERP acts.
BLENDS = ("output", "feedback")
#: Default ``hold_window`` (received samples): 1 s at the paper's 50 Hz, about how long the
#: hybrid's elbow error stays high after the paper's 4-packet loss (Sec. IV, Fig. 8).
DEFAULT_HOLD_WINDOW = 50
#: Default ``beta_max`` of ``method="adaptive_beta"``, as a multiple of β.
DEFAULT_BETA_MAX_FACTOR = 10.0

# SLERP's angle Ω is raised to at least this (rad), so that sin(kΩ)/sin Ω is k, not 0/0, when
# the two quaternions coincide; sin(x) = x exactly at this size, and kx stays a normal float.
_SLERP_TINY_ANGLE = 1e-150
# Doubles (32 MB) of the time-first buffer through which outputs are written.
_OUTPUT_BUFFER_SIZE = 2**22


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------


def _check_choice(value, name: str, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        listed = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name} must be one of {listed}; got {value!r}")
    return value


def _positive_array(value, name: str) -> np.ndarray:
    arr = as_float_array(value, name, min_ndim=0)  # raises on NaN/inf, naming the argument
    if np.any(arr <= 0.0):
        raise ValueError(f"{name} must be > 0 (and finite), got {value!r}")
    return arr


def _nonnegative_array(value, name: str) -> np.ndarray:
    arr = as_float_array(value, name, min_ndim=0)
    if np.any(arr < 0.0):
        raise ValueError(f"{name} must be >= 0 (and finite), got {value!r}")
    return arr


def _check_received(received) -> np.ndarray:
    mask = np.asarray(received)
    if mask.dtype != np.bool_:
        raise ValueError(f"received must be a boolean mask (True = received), got dtype {mask.dtype}")
    if mask.ndim < 1:
        raise ValueError(f"received must have shape (..., T), got shape {mask.shape}")
    return mask


def _check_hold_window(hold_window, schedule: str) -> np.ndarray | None:
    """``hold_window`` as an int64 array for ``schedule="hold"``, else ``None``."""
    if schedule != "hold":
        if hold_window is not None:
            raise ValueError(f"hold_window is only used with schedule='hold', not schedule={schedule!r}")
        return None
    if hold_window is None:
        return np.asarray(DEFAULT_HOLD_WINDOW, dtype=np.int64)
    arr = np.asarray(hold_window)
    if arr.dtype == np.bool_ or not np.issubdtype(arr.dtype, np.integer) or np.any(arr < 1):
        raise ValueError(f"hold_window must be a positive integer (samples) or an array of them, got {hold_window!r}")
    return arr.astype(np.int64)


# --------------------------------------------------------------------------------------------
# Eq. (3) and the λ schedules
# --------------------------------------------------------------------------------------------


def _weight(lam, rho, tau):
    """Eq. (3) without validation."""
    return rho / (lam / tau + rho)


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
    lam = _nonnegative_array(lost_run, "lost_run")
    rho = _positive_array(rho, "rho")
    tau = _positive_array(tau, "tau")
    try:
        np.broadcast_shapes(lam.shape, rho.shape, tau.shape)
    except ValueError as exc:
        raise ValueError(f"lost_run {lam.shape}, rho {rho.shape} and tau {tau.shape} do not broadcast") from exc
    return _weight(lam, rho, tau)


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
    mask = _check_received(received)
    schedule = _check_choice(schedule, "schedule", SCHEDULES)
    window = _check_hold_window(hold_window, schedule)
    shapes = {"received": mask.shape[:-1]}
    if window is not None:
        shapes["hold_window"] = window.shape
    _broadcast_batch(shapes)
    return _effective_lost_run(mask, schedule, window)


def _effective_lost_run(mask: np.ndarray, schedule: str, window) -> np.ndarray:
    """:func:`effective_lost_run` without validation; a loop over time, vectorised over batches."""
    if schedule == "instant":
        return lost_run_length(mask).astype(float)
    batch = np.broadcast_shapes(mask.shape[:-1], () if window is None else window.shape)
    n_t = mask.shape[-1]
    rec = np.moveaxis(np.broadcast_to(mask, batch + (n_t,)), -1, 0)
    out = np.empty((n_t,) + batch)
    lam = np.zeros(batch)
    if schedule == "decay":
        prev_lost = np.zeros(batch, dtype=bool)
        for t in range(n_t):
            on_received = np.where(prev_lost, lam, np.maximum(lam - 1.0, 0.0))
            lam = np.where(rec[t], on_received, lam + 1.0)
            prev_lost = ~rec[t]
            out[t] = lam
    else:  # hold
        since = np.zeros(batch, dtype=np.int64)  # received samples since the last gap, inclusive
        for t in range(n_t):
            since = np.where(rec[t], since + 1, 0)
            lam = np.where(rec[t], np.where(since <= window, lam, 0.0), lam + 1.0)
            out[t] = lam
    return np.ascontiguousarray(np.moveaxis(out, 0, -1))


# --------------------------------------------------------------------------------------------
# Component-first helpers of the hot loops
# --------------------------------------------------------------------------------------------


def _slerp_first(q_a, q_b, mu):
    """Eq. (2) for component-first unit quaternions ``(4, ...)``, no validation.

    ``q_a`` is negated where ``q_a · q_b < 0`` (shorter arc), so the result stays in
    ``q_b``'s hemisphere: the hybrid output then keeps the sign of Madgwick's estimate
    (:func:`wsnlib.quaternion.slerp` keeps ``q_a``'s; the rotation is the same).  μ = 1
    returns ``q_b``, μ = 0 returns ``±q_a``.  The angle Ω is computed on the batch of the
    quaternions only (``mu`` may widen it, e.g. a (ρ, τ) grid).  For small Ω the ratios
    ``sin(kΩ)/sin Ω`` stay accurate (→ k); only Ω = 0 exactly needs a guard.
    """
    dot = q_a[0] * q_b[0] + q_a[1] * q_b[1] + q_a[2] * q_b[2] + q_a[3] * q_b[3]
    q_a = np.where(dot < 0.0, -q_a, q_a)
    omega = np.maximum(np.arccos(np.minimum(np.abs(dot), 1.0)), _SLERP_TINY_ANGLE)
    sin_omega = np.sin(omega)
    weight_a = np.sin((1.0 - mu) * omega) / sin_omega
    weight_b = np.sin(mu * omega) / sin_omega
    out = weight_a * q_a + weight_b * q_b
    out /= np.sqrt(np.einsum("i...,i...->...", out, out))
    return out


def _time_first(arr: np.ndarray, n_components: int = 0) -> np.ndarray:
    """``(..., T)`` → ``(T, ...)``, or ``(..., T, C)`` → ``(T, C, ...)`` with ``n_components``."""
    if n_components:
        return np.ascontiguousarray(np.moveaxis(arr, (-2, -1), (0, 1)))
    return np.ascontiguousarray(np.moveaxis(arr, -1, 0))


def _pad(shape: tuple[int, ...], ndim: int) -> tuple[int, ...]:
    """``shape`` with leading ones up to ``ndim`` dimensions."""
    return (1,) * (ndim - len(shape)) + tuple(shape)


def _any_to_shape(arr: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Reduce ``arr`` (broadcast of ``shape`` with something) by ``any`` to fit ``shape``."""
    extra = arr.ndim - len(shape)
    if extra > 0:
        arr = arr.any(axis=tuple(range(extra)))
    axes = tuple(i for i, n in enumerate(shape) if n == 1 and arr.shape[i] != 1)
    if axes:
        arr = arr.any(axis=axes, keepdims=True)
    return np.broadcast_to(arr, shape)


class _Output:
    """The ``(*S, T, 4)`` output, filled one time step ``(4, *S)`` at a time.

    Steps are collected in a small time-first buffer and copied out in blocks: writing each
    step straight into ``(..., T, 4)`` scatters 4 numbers per batch element and is several
    times slower, and transposing a whole time-first array at the end costs as much.
    """

    def __init__(self, batch: tuple[int, ...], n_t: int):
        self.result = np.empty(batch + (n_t, 4))
        self._view = np.moveaxis(self.result, (-2, -1), (0, 1))  # (T, 4, *S)
        size = max(int(np.prod(batch, dtype=np.int64)), 1)
        self._block = int(np.clip(_OUTPUT_BUFFER_SIZE // (4 * size), 1, 32))
        self._buffer = np.empty((self._block, 4) + batch)
        self._start = 0

    def write(self, t: int, q: np.ndarray) -> None:
        k = t - self._start
        self._buffer[k] = q
        if k + 1 == self._block or t + 1 == self._view.shape[0]:
            self._view[self._start : t + 1] = self._buffer[: k + 1]
            self._start = t + 1


def _run(q, gyr, acc, mag, update, dt, beta_dt, *, shown=None, blend=None):
    """The time loop: Madgwick updates where ``update[t]``, optional SLERP feedback.

    Component- and time-first arrays: ``q`` ``(4, *S)`` (already the full state batch),
    ``gyr``/``acc``/``mag`` ``(T, 3, ...)``, ``update`` ``(T, ...)`` bool, ``dt`` and
    ``beta_dt`` indexable by ``t`` (``(T, ...)`` arrays, broadcast views or
    :class:`_AdaptiveBetaDt`).  ``blend = (blend_at, q_s, lam, rho, tau)``, time-first
    ``(T, ...)`` / ``(T, 4, ...)``: the updated state is replaced by
    ``SLERP(q_s[t], ·, μ(lam[t], ρ, τ))`` where ``blend_at[t]`` (feedback hybrid), computed
    there only.  The output is the state, or, with ``shown`` ``(T, ...)``, the state on
    samples where ``shown[t]`` and the previous output elsewhere.  Returns ``(*S, T, 4)``.
    """
    n_t = update.shape[0]
    out = _Output(q.shape[1:], n_t)
    any_update = update.reshape(n_t, -1).any(axis=1)
    if blend is not None:
        blend_at, q_s, lam, rho, tau = blend
        any_blend = blend_at.reshape(n_t, -1).any(axis=1)
    shown_q = q
    for t in range(n_t):
        if any_update[t]:
            q_new = _update(q, gyr[t], acc[t], None if mag is None else mag[t], dt[t], beta_dt[t])
            if blend is not None and any_blend[t]:  # SLERP only where needed
                q_new = np.array(q_new)  # writeable and contiguous, whatever _update returns
                batch = q_new.shape[1:]
                flat = q_new.reshape(4, -1)  # a view; an unbatched state is a batch of one
                where = np.flatnonzero(np.broadcast_to(blend_at[t], batch))
                mu = _weight(*(np.broadcast_to(x, batch).reshape(-1)[where] for x in (lam[t], rho, tau)))
                q_s_t = np.broadcast_to(q_s[t], q_new.shape).reshape(4, -1)
                flat[:, where] = _slerp_first(q_s_t[:, where], flat[:, where], mu)
            q = np.where(update[t], q_new, q)
        if shown is not None:
            shown_q = np.where(shown[t], q, shown_q)
        out.write(t, q if shown is None else shown_q)
    return out.result


def _filled_gyr(gyr: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Gyroscope with every lost sample linearly interpolated between its received neighbours.

    ``gyr`` ``(..., T, 3)`` (finite), ``mask`` ``(..., T)``.  A lost sample ``t`` between
    received samples ``j < t < k`` gets ``ω_j + (ω_k − ω_j)(t − j)/(k − j)``; before the first
    received sample it gets ``ω`` of the first one, after the last received sample that of
    the last one (the filter never shows those); received samples are unchanged.
    """
    batch = np.broadcast_shapes(gyr.shape[:-2], mask.shape[:-1])
    n_t = mask.shape[-1]
    mask = np.broadcast_to(mask, batch + (n_t,))
    gyr = np.broadcast_to(gyr, batch + (n_t, 3))
    index = np.arange(n_t)
    prev = np.maximum.accumulate(np.where(mask, index, -1), axis=-1)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(mask, index, n_t), axis=-1), axis=-1), axis=-1)
    has_prev, has_next = prev >= 0, nxt < n_t
    lo = np.clip(np.where(has_prev, prev, nxt), 0, max(n_t - 1, 0))
    hi = np.where(has_next, nxt, lo)
    span = hi - lo
    frac = np.divide(index - lo, span, out=np.zeros(span.shape), where=span > 0)
    g_lo = np.take_along_axis(gyr, lo[..., None], axis=-2)
    g_hi = np.take_along_axis(gyr, hi[..., None], axis=-2)
    return g_lo + frac[..., None] * (g_hi - g_lo)


# --------------------------------------------------------------------------------------------
# The batch filter
# --------------------------------------------------------------------------------------------


def estimate_orientation(
    gyr,
    acc,
    mag=None,
    *,
    fs: float,
    beta,
    received=None,
    method: str = "hybrid",
    rho=2.0,
    tau=6.0,
    schedule: str = "decay",
    hold_window=None,
    blend: str = "output",
    beta_max=None,
    q0=None,
    return_weight: bool = False,
):
    """Madgwick's filter under packet loss with a choice of loss handling, batched.

    Every method runs Madgwick's filter (:mod:`wsnlib.orientation.madgwick`) on the received
    samples and outputs the previous output on lost ones; they differ in what happens once
    a gap ends.  λ below is the length of the gap that just ended, λ_eff the effective λ of
    ``schedule`` (:func:`effective_lost_run`) and μ = ``slerp_weight(λ_eff, ρ, τ)`` (eq. (3)).

    * ``"hold_last"``: nothing; plain :func:`wsnlib.orientation.madgwick` (the baseline).
    * ``"dt_extension"`` (Sec. V): the first received sample after a gap of λ samples is
      integrated over ``(1 + λ)Δt``, i.e. as if the node had turned at that sample's rate
      throughout the gap.  Only the gyroscope term ``½ q ⊗ ω`` is integrated over the longer
      interval; the correction step stays β·Δt.  The paper speaks of "the first angular
      rates [...] handled as gyroscope data sampled over an extended period", and one
      accelerometer/magnetometer sample is one correction: Madgwick's step along the
      *normalised* gradient has the fixed length β·Δt whatever the error, so scaling it by
      ``1 + λ`` would make one jump of about ``2β(1 + λ)Δt`` rad in one direction (0.1 rad
      for β = 0.1 rad/s after the paper's 24-sample gap) even when the gyroscope
      extrapolation was right.  (On the simulated arm extension with that gap, the mean error
      over the next second was 0.5° this way against 1.8° with the whole update scaled, at
      β = 0.1.)  The step is first order, as every Madgwick step: a rotation
      θ = |ω|(1+λ)Δt comes out as ``2·atan(θ/2)`` (0.5 rad → 0.49 rad).
    * ``"gyro_interpolation"`` (Sec. V): when the first sample after a gap arrives, the
      filter replays the λ lost samples as gyroscope-only updates (their acc/mag never
      arrived) with ω interpolated linearly between the last received sample before the gap
      and the first one after it, then makes the normal update.  A gap at the start (with
      ``q0`` given) uses the first received ω throughout; a gap at the end is never
      replayed.  Computed as one pass (gyro-only updates on lost samples with the filled ω,
      output held there), which equals replaying at the end of the gap since nothing of the
      state is shown before then.
    * ``"adaptive_beta"`` (Sec. V, "adjusting [β] in accordance with λ"): each update uses
      ``β_eff = β + (β_max − β)(1 − μ)``, so β_eff = β while nothing was lost and tends to
      β_max after long gaps, then returns to β as the schedule decays.
    * ``"hybrid"`` (Sec. III, eq. (4)): ``q_f = SLERP(q_s, q_d, μ)`` on every received sample,
      ``q_s`` = TRIAD of that sample, ``q_d`` Madgwick's estimate.  ``blend="output"``:
      Madgwick's state runs as in ``"hold_last"`` and only the output is blended;
      ``blend="feedback"``: ``q_f`` replaces the state after each received update.  Needs
      ``mag``.

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s²) in the body frame.
    mag : array_like, shape (..., T, 3), optional
        Magnetic field in the body frame (µT); ``None`` runs Madgwick's IMU form (not
        allowed for ``"hybrid"``, whose TRIAD needs it).
    fs : float
        Sampling rate (Hz), > 0; Δt = 1/fs.
    beta : float or array_like
        Gain β (rad/s), >= 0; an array gives one per batch element (it broadcasts against
        the leading dimensions of the signals).
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all
        received.
    method : {"hybrid", "hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta"}
    rho, tau : float or array_like
        ρ, τ of eq. (3), finite and > 0 (positive integers in the paper; defaults ρ = 2,
        τ = 6, so μ = 1/2 at λ_eff = 12 samples).  Arrays broadcast against the leading
        dimensions: with ``gyr`` ``(R, T, 3)``, ``rho`` ``(8, 1, 1)`` and ``tau`` ``(1, 8, 1)``
        give an ``(8, 8, R, T, 4)`` output in one pass.  Used by ``"hybrid"`` and
        ``"adaptive_beta"``.
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap (:func:`effective_lost_run`); used by ``"hybrid"`` and
        ``"adaptive_beta"``.
    hold_window : int or array_like of int, optional
        For ``schedule="hold"`` only: received samples during which λ_eff is held, >= 1
        (default 50), scalar or per batch element.
    blend : {"output", "feedback"}
        Where the hybrid's SLERP acts (see above); only used by ``"hybrid"``.
    beta_max : float or array_like, optional
        β after a very long gap for ``"adaptive_beta"``, finite and >= β.  Default
        ``10 β`` (:data:`DEFAULT_BETA_MAX_FACTOR`).
    q0 : array_like, shape (4,) or (..., 4), optional
        Estimate before the first sample, as in :func:`wsnlib.orientation.madgwick`.
        ``None``: each batch element starts from TRIAD (IMU form: the tilt) of its first
        received sample.  A gap before that sample is then no gap of the filter, which had
        not started: λ_eff is 0 up to that sample, and nothing is replayed or extended.
        With ``q0`` a gap at the start is a gap like any other.
    return_weight : bool
        Also return μ.

    Returns
    -------
    quat : numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth).  ``...`` is the broadcast of the leading
        dimensions of the signals, ``received``, ``q0``, ``beta``, and of the parameters the
        method uses (``rho``, ``tau``, ``hold_window`` for ``"hybrid"`` and
        ``"adaptive_beta"``, ``beta_max`` for ``"adaptive_beta"``); parameters a method does
        not use add no dimension.  Lost samples hold the previous output.
    mu : numpy.ndarray, shape (..., T)
        Only with ``return_weight``: μ of eq. (3) from λ_eff on every sample (1 where
        λ_eff = 0), whatever the method, with the leading dimensions of ``quat`` broadcast
        with those of ``received``, ``rho``, ``tau`` and ``hold_window``.

    Raises
    ------
    ValueError
        Naming the argument: an unknown ``method``, ``schedule`` or ``blend``; ρ or τ <= 0,
        NaN or inf; β < 0 or not finite; ``beta_max`` < β or not finite; ``hold_window`` not
        a positive integer with ``schedule="hold"`` or given with another schedule;
        ``mag`` None for ``"hybrid"``; and everything :func:`wsnlib.orientation.madgwick`
        rejects (shapes, NaN/inf or zero vectors in received samples, ``fs``, ``q0``, a
        batch element with nothing received when ``q0`` is None).  A received sample with
        ``acc`` parallel to ``mag`` fails in TRIAD when the hybrid needs it.

    Notes
    -----
    One Python loop over time; batches and parameter grids are vectorised.  λ_eff depends
    only on the mask, ``schedule`` and ``hold_window`` and is computed once; μ is computed
    where it is used (no ``(..., T)`` array of it unless ``return_weight``).  TRIAD and
    SLERP are computed only on the received samples with λ_eff > 0 (elsewhere μ = 1 and
    eq. (4) returns ``q_d`` exactly).  Methods that do not use ρ, τ run on the batch without
    them, and with ``blend="output"`` Madgwick's state does not depend on ρ, τ or the
    schedule either: it runs once on the un-broadcast batch, and the blend is applied
    afterwards, in one vectorised pass over the blended samples.
    """
    method = _check_choice(method, "method", METHODS)
    schedule = _check_choice(schedule, "schedule", SCHEDULES)
    blend = _check_choice(blend, "blend", BLENDS)
    fs = check_positive(fs, "fs")
    beta = _nonnegative_array(beta, "beta")
    if beta_max is None:
        beta_max = DEFAULT_BETA_MAX_FACTOR * beta
    else:
        beta_max = as_float_array(beta_max, "beta_max", min_ndim=0)
    rho = _positive_array(rho, "rho")
    tau = _positive_array(tau, "tau")
    window = _check_hold_window(hold_window, schedule)
    if method == "hybrid" and mag is None:
        raise ValueError("mag is required for method='hybrid': TRIAD (q_s) needs the magnetometer")

    # ---- signals, mask and q0: madgwick()'s checks, with its helpers
    signals, mask, q0, shapes = _check_inputs(gyr, acc, mag, received, q0)
    n_t = signals["gyr"].shape[-2]
    if mask is None:
        mask = np.ones(n_t, dtype=bool)
    shapes["received"] = mask.shape[:-1]
    data_batch = _broadcast_batch(shapes)
    params = {"beta": beta.shape, "beta_max": beta_max.shape, "rho": rho.shape, "tau": tau.shape}
    if window is not None:
        params["hold_window"] = window.shape
    _broadcast_batch(shapes | params)
    if np.any(beta_max < beta):
        raise ValueError("beta_max must be >= beta (element by element)")
    for name, arr in signals.items():
        signals[name] = _usable(arr, name, mask, unit=name != "gyr")

    # ---- start of the filter, λ_eff and μ (mask and parameters only)
    seen = np.logical_or.accumulate(mask, axis=-1)  # a sample received at or before t
    if q0 is None:
        q_init, _ = _initial_estimate(signals, mask, data_batch, n_t)  # raises if nothing received
        started = np.zeros_like(seen)
        started[..., 1:] = seen[..., :-1]  # the first received sample only initialises
        gap_mask = mask | ~seen  # no gap before the filter starts
    else:
        q_init = q0
        started = np.ones_like(mask)
        gap_mask = mask
    update = mask & started
    uses_mu = method in ("hybrid", "adaptive_beta")
    lam = _effective_lost_run(gap_mask, schedule, window) if uses_mu or return_weight else None
    base_batch = np.broadcast_shapes(data_batch, beta.shape)
    out_batch = base_batch
    if uses_mu:
        out_batch = np.broadcast_shapes(base_batch, lam.shape[:-1], rho.shape, tau.shape)
        if method == "adaptive_beta":
            out_batch = np.broadcast_shapes(out_batch, beta_max.shape)
    if n_t == 0:
        return _finish(np.empty(out_batch + (0, 4)), lam, rho, tau, return_weight)

    # Component-first arrays (C, *batch) only broadcast if every batch has the output's ndim;
    # so do λ_eff (T, *batch) and ρ, τ, β against it.
    nd = len(out_batch)
    data_batch, base_batch = _pad(data_batch, nd), _pad(base_batch, nd)
    signals = {name: arr.reshape(_pad(arr.shape[:-2], nd) + arr.shape[-2:]) for name, arr in signals.items()}
    q_init = q_init.reshape(_pad(q_init.shape[:-1], nd) + (4,))
    sig = {name: _time_first(arr, 3) for name, arr in signals.items()}
    mag_tf = sig.get("mag")
    if uses_mu:
        lam = lam.reshape(_pad(lam.shape[:-1], nd) + (n_t,))
        lam_tf = _time_first(lam)
    dt = 1.0 / fs

    def initial(batch):
        return np.array(np.moveaxis(np.broadcast_to(q_init, batch + (4,)), -1, 0))

    def constant(value):
        return np.broadcast_to(value, (n_t,) + np.shape(value))

    if method in ("hold_last", "dt_extension", "adaptive_beta") or (method == "hybrid" and blend == "output"):
        batch, dt_steps, beta_dt = base_batch, constant(dt), constant(beta * dt)
        if method == "dt_extension":
            before = np.zeros(gap_mask.shape)
            before[..., 1:] = lost_run_length(gap_mask)[..., :-1]  # λ of the gap just ended
            dt_steps = _time_first((1.0 + before) * dt)  # the gyroscope term only
        elif method == "adaptive_beta":
            batch, beta_dt = out_batch, _AdaptiveBetaDt(lam_tf, rho, tau, beta, beta_max, dt)
        q_d = _run(initial(batch), sig["gyr"], sig["acc"], mag_tf, _time_first(update), dt_steps, beta_dt)
        if method != "hybrid":
            return _finish(q_d, lam, rho, tau, return_weight)
        blended = _output_blend(q_d, signals, mask, lam, rho, tau, data_batch, out_batch)
        return _finish(blended, lam, rho, tau, return_weight)

    if method == "gyro_interpolation":
        gyr_tf = _time_first(_filled_gyr(signals["gyr"], mask), 3)
        beta_dt = _time_first(np.where(mask, beta[..., None] * dt, 0.0))  # gyro only on lost samples
        started_tf, shown = _time_first(started), _time_first(mask)
        q = _run(initial(base_batch), gyr_tf, sig["acc"], mag_tf, started_tf, constant(dt), beta_dt, shown=shown)
        return _finish(q, lam, rho, tau, return_weight)

    # Feedback hybrid: the blend replaces the state after every received update.
    blend_at = update & (lam > 0.0)
    q_s = _time_first(_triad_where(signals, blend_at, data_batch), 4)
    q = _run(
        initial(out_batch),
        sig["gyr"],
        sig["acc"],
        mag_tf,
        _time_first(update),
        constant(dt),
        constant(beta * dt),
        blend=(_time_first(blend_at), q_s, lam_tf, rho, tau),
    )
    return _finish(q, lam, rho, tau, return_weight)


class _AdaptiveBetaDt:
    """``β_eff·Δt`` at step ``t`` on demand, ``β_eff = β + (β_max − β)(1 − μ)``: no (T, ...) array."""

    def __init__(self, lam_tf, rho, tau, beta, beta_max, dt):
        self._args = lam_tf, rho, tau, beta, beta_max, dt

    def __getitem__(self, t):
        lam_tf, rho, tau, beta, beta_max, dt = self._args
        return (beta + (beta_max - beta) * (1.0 - _weight(lam_tf[t], rho, tau))) * dt


def _triad_where(signals, where: np.ndarray, data_batch) -> np.ndarray:
    """TRIAD ``(*data_batch, T, 4)`` on the samples where ``where`` ``(..., T)``; identity elsewhere."""
    n_t = where.shape[-1]
    needed = _any_to_shape(where, data_batch + (n_t,))
    q_s = np.zeros(data_batch + (n_t, 4))
    q_s[..., 0] = 1.0
    index = np.nonzero(needed)
    if index[0].size:
        acc = np.broadcast_to(signals["acc"], data_batch + (n_t, 3))[index]
        mag = np.broadcast_to(signals["mag"], data_batch + (n_t, 3))[index]
        q_s[index] = triad(acc, mag)
    return q_s


def blend_with_single_frame(
    quat_d,
    acc,
    mag,
    received=None,
    *,
    rho=2.0,
    tau=6.0,
    schedule: str = "decay",
    hold_window=None,
    leading_gap: bool = False,
) -> np.ndarray:
    """Paper 001's hybrid as an output stage on any data-fusion output: eqs. (3)–(4).

    ``q_f = SLERP(q_s, q_d, μ)`` with ``μ = slerp_weight(λ_eff, ρ, τ)`` on every received
    sample where λ_eff > 0 (:func:`effective_lost_run`), ``q_s`` = TRIAD of that sample's
    ``acc`` and ``mag``, ``q_d`` = ``quat_d`` there; elsewhere ``quat_d`` unchanged.  On a
    lost sample the output is eq. (4) with the held ``q_d`` and the ``q_s``, μ of the last
    received sample, i.e. the previous output whenever ``quat_d`` holds its previous value
    there, as every filter of wsnlib does.  This is ``estimate_orientation(...,
    method="hybrid", blend="output")`` with Madgwick's filter replaced by whatever produced
    ``quat_d`` (e.g. :mod:`wsnlib.orientation.peers`): with ``quat_d`` the output of
    :func:`wsnlib.orientation.madgwick` (same mask, ``q0=None``) the two agree to rounding.

    Parameters
    ----------
    quat_d : array_like, shape (..., T, 4)
        Data-fusion estimate (ENU, body → earth), finite and non-zero (normalised here).
    acc, mag : array_like, shape (..., T, 3)
        Specific force (m/s²) and magnetic field (µT) in the body frame, for TRIAD; only
        received samples are read (lost ones may hold NaN).
    received : array_like of bool, shape (..., T), optional
        True = received; ``None``: all received (then λ_eff = 0 and ``quat_d`` comes back).
    rho, tau : float or array_like
        ρ, τ of eq. (3), finite and > 0; arrays broadcast against the leading dimensions, as
        in :func:`estimate_orientation`.
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap (:func:`effective_lost_run`).
    hold_window : int or array_like of int, optional
        For ``schedule="hold"`` only (default 50 received samples).
    leading_gap : bool
        Whether a gap before a batch element's first received sample counts.  ``False``
        (default): the filter had not started, λ_eff is 0 up to that sample, as in
        :func:`estimate_orientation` with ``q0=None``; ``True``: it counts like any gap,
        as there with ``q0`` given.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        Blended ENU unit quaternions; ``...`` is the broadcast of the leading dimensions of
        all array arguments.  Blended samples keep the sign (hemisphere) of ``quat_d``.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes or mismatched T, leading dimensions that do not
        broadcast, NaN/inf or a zero quaternion in ``quat_d``, NaN/inf or a zero vector in a
        received ``acc``/``mag`` sample, a non-boolean ``received``, an unknown
        ``schedule``, ρ or τ not finite and > 0, a bad ``hold_window``.  ``acc`` parallel to
        ``mag`` on a blended sample fails in TRIAD.
    """
    schedule = _check_choice(schedule, "schedule", SCHEDULES)
    rho = _positive_array(rho, "rho")
    tau = _positive_array(tau, "tau")
    window = _check_hold_window(hold_window, schedule)
    quat_d = as_float_array(quat_d, "quat_d", last_dim=4, min_ndim=2)
    quat_d = quat_d / check_nonzero_norm(quat_d, "quat_d", "a zero quaternion is not a rotation")[..., None]
    signals = {"acc": _as_signal(acc, "acc"), "mag": _as_signal(mag, "mag")}
    n_t = quat_d.shape[-2]
    for name, arr in signals.items():
        if arr.shape[-2] != n_t:
            raise ValueError(f"{name} has {arr.shape[-2]} samples (axis -2), quat_d has {n_t}")
    if received is None:
        mask = np.ones(n_t, dtype=bool)
    else:
        mask = _check_received(received)
        if mask.shape[-1] != n_t:
            raise ValueError(f"received must have shape (..., {n_t}), got {mask.shape}")
    shapes = {name: arr.shape[:-2] for name, arr in signals.items()} | {"received": mask.shape[:-1]}
    data_batch = _broadcast_batch(shapes)
    shapes["quat_d"] = quat_d.shape[:-2]
    base_batch = _broadcast_batch(shapes)
    params = {"rho": rho.shape, "tau": tau.shape}
    if window is not None:
        params["hold_window"] = window.shape
    _broadcast_batch(shapes | params)
    signals = {name: _usable(arr, name, mask, unit=True) for name, arr in signals.items()}
    gap_mask = mask if leading_gap else mask | ~np.logical_or.accumulate(mask, axis=-1)
    lam = _effective_lost_run(gap_mask, schedule, window)
    out_batch = np.broadcast_shapes(base_batch, lam.shape[:-1], rho.shape, tau.shape)
    if n_t == 0:
        return np.empty(out_batch + (0, 4))
    nd = len(out_batch)
    data_batch = _pad(data_batch, nd)
    signals = {name: arr.reshape(_pad(arr.shape[:-2], nd) + arr.shape[-2:]) for name, arr in signals.items()}
    lam = lam.reshape(_pad(lam.shape[:-1], nd) + (n_t,))
    return _output_blend(quat_d, signals, mask, lam, rho, tau, data_batch, out_batch)


def _output_blend(q_d, signals, mask, lam, rho, tau, data_batch, out_batch) -> np.ndarray:
    """Eq. (4) as an output stage (``blend="output"``), no validation.

    ``q_d`` ``(*base, T, 4)``: the data-fusion output, held on lost samples; ``signals``:
    ``"acc"`` and ``"mag"`` ``(*data, T, 3)`` usable on received samples; ``mask``
    ``(..., T)``; ``lam`` λ_eff ``(..., T)`` and ``data_batch`` padded to ``len(out_batch)``
    dimensions; ``rho``, ``tau`` arrays broadcasting to ``out_batch``.  Returns
    ``(*out_batch, T, 4)``.
    """
    n_t = mask.shape[-1]
    nd = len(out_batch)
    # The state is held on lost samples, so the output at t is eq. (4) with q_d[t] and the
    # q_s, μ of the last received sample s(t) <= t (t itself before any):
    # SLERP(q_s[s], q_d[t], μ[s]) where a blend happened at s, q_d[t] elsewhere.  Only
    # those positions are computed, all at once.
    index = np.arange(n_t)
    src = np.maximum.accumulate(np.where(mask, index, -1), axis=-1)
    src = np.where(src < 0, index, src)
    blend_at = mask & (lam > 0.0)
    q_s = _triad_where(signals, blend_at, data_batch)  # (*data, T, 4)
    src, blend_at = (x.reshape(_pad(x.shape[:-1], nd) + (n_t,)) for x in (src, blend_at))
    held = np.take_along_axis(blend_at, src, axis=-1)
    result = np.empty(out_batch + (n_t, 4))
    result[...] = q_d
    where = np.nonzero(np.broadcast_to(held, out_batch + (n_t,)))
    if where[0].size:
        at_src = where[:-1] + (np.broadcast_to(src, out_batch + (n_t,))[where],)
        q_s = np.broadcast_to(q_s, out_batch + (n_t, 4))[at_src]
        q_d = np.broadcast_to(q_d, out_batch + (n_t, 4))[where]
        mu = _weight(
            np.broadcast_to(lam, out_batch + (n_t,))[at_src],
            np.broadcast_to(rho, out_batch)[where[:-1]],
            np.broadcast_to(tau, out_batch)[where[:-1]],
        )
        result[where] = _slerp_first(q_s.T, q_d.T, mu).T
    return result


def _finish(quat: np.ndarray, lam, rho, tau, return_weight: bool):
    """The output, and with ``return_weight`` μ ``(..., T)`` broadcast to its batch."""
    if not return_weight:
        return quat
    mu = _weight(lam, rho[..., None], tau[..., None])
    batch = np.broadcast_shapes(quat.shape[:-2], mu.shape[:-1])
    return quat, np.array(np.broadcast_to(mu, batch + mu.shape[-1:]))
