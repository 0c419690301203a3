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
baseline, and ``"hybrid"`` is eqs. (3)–(4).  ``method="kalman"`` runs the gap-aware
error-state Kalman filter (:func:`wsnlib.orientation.kalman_orientation`) on the same inputs
instead of Madgwick's filter.

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

Implementation
--------------
All methods are one compiled loop, :func:`wsnlib.orientation._kernels.filter_stream`, whose
branches are the methods (read it beside this docstring); λ_eff is updated in the same loop
(:func:`wsnlib.orientation._kernels.next_lost_run`), so no ``(..., T)`` array of λ or μ is made.

Held output
-----------
On a lost sample every Madgwick-family method outputs the previous output (the receiver has
nothing new to show), as :func:`wsnlib.orientation.madgwick` does, unless ``gap="constant_rate"``
(and ``"kalman"``, whose default is ``gap="constant_rate"``).  Before a batch element's first received
sample the output is the initial estimate.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K
from wsnlib.orientation.kalman import KalmanSettings, kalman_orientation

#: Loss-handling methods of :func:`estimate_orientation` built on Madgwick's filter.
METHODS = ("hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid")
#: Every ``method`` of :func:`estimate_orientation`: :data:`METHODS` and the gap-aware Kalman filter.
ALL_METHODS = METHODS + ("kalman",)
#: λ schedules of :func:`effective_lost_run`.
SCHEDULES = ("decay", "hold", "instant")
#: Where the hybrid's SLERP acts.
BLENDS = ("output", "feedback")
#: Default ``hold_window`` (received samples): 1 s at the paper's 50 Hz, about how long the
#: hybrid's elbow error stays high after the paper's 4-packet loss (Sec. IV, Fig. 8).
DEFAULT_HOLD_WINDOW = 50
#: Default ``beta_max`` of ``method="adaptive_beta"``, as a multiple of β.
DEFAULT_BETA_MAX_FACTOR = 10.0

_METHOD_CODES = dict(zip(METHODS, (K.HOLD_LAST, K.DT_EXTENSION, K.GYRO_INTERPOLATION, K.ADAPTIVE_BETA, K.HYBRID),
                         strict=True))
_SCHEDULE_CODES = dict(zip(SCHEDULES, (K.DECAY, K.HOLD, K.INSTANT), strict=True))
_BLEND_CODES = {"output": K.OUTPUT_BLEND, "feedback": K.FEEDBACK_BLEND}


# --------------------------------------------------------------------------------------------
# Eq. (3) and the λ schedules
# --------------------------------------------------------------------------------------------


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
    schedule = B.check_choice(schedule, "schedule", SCHEDULES)
    window = B.check_hold_window(hold_window, schedule, DEFAULT_HOLD_WINDOW)
    shapes = {"received": mask.shape[:-1]}
    if window is not None:
        shapes["hold_window"] = window.shape
    B.broadcast_batch(shapes)
    return _effective_lost_run(mask, schedule, window, leading_gap=True)


def _effective_lost_run(mask: np.ndarray, schedule: str, window, leading_gap: bool) -> np.ndarray:
    """λ_eff ``(..., T)`` without validation; ``leading_gap=False``: no gap before the first sample."""
    window = np.asarray(1 if window is None else window, dtype=np.int64)
    batch = np.broadcast_shapes(mask.shape[:-1], window.shape)
    n_t = mask.shape[-1]
    out = B.new_output(batch, n_t, 1)[..., 0]
    if n_t:
        K.run_lost_run(B.flat(mask, 1), B.index_into(mask.shape[:-1], batch), _SCHEDULE_CODES[schedule],
                       B.per_element(window, batch, np.int64), leading_gap, out.reshape(-1, n_t))
    return out


# --------------------------------------------------------------------------------------------
# The batch filter
# --------------------------------------------------------------------------------------------


def estimate_orientation(
    gyr,
    acc,
    mag=None,
    *,
    fs: float,
    beta=None,
    received=None,
    method: str = "hybrid",
    rho=2.0,
    tau=6.0,
    schedule: str = "decay",
    hold_window=None,
    blend: str = "output",
    beta_max=None,
    q0=None,
    gap: str | None = None,
    gap_time_constant=None,
    return_weight: bool = False,
    kalman_settings: KalmanSettings | None = None,
):
    """Madgwick's filter under packet loss with a choice of loss handling, or the Kalman filter, batched.

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
    * ``"kalman"`` (issue 11): not Madgwick's filter but the gap-aware error-state Kalman
      filter, :func:`wsnlib.orientation.kalman_orientation` with ``kalman_settings`` (default:
      the settings tuned on BROAD).  It uses ``gyr``, ``acc``, ``mag`` (optional), ``fs``,
      ``received``, ``q0``, ``gap`` (default ``"constant_rate"``: it always predicts over a
      gap) and ``gap_time_constant``; ``beta``, ``rho``, ``tau``, ``schedule``,
      ``hold_window``, ``blend`` and ``beta_max`` are not used (ignored), ``return_weight``
      is refused.

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
        the leading dimensions of the signals).  Required by every method except
        ``"kalman"``.
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all
        received.
    method : {"hybrid", "hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "kalman"}
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
    gap : {"hold", "constant_rate"}, optional
        During a gap: hold the previous output (the paper's receiver), or keep turning the
        state by the last received angular rate (dead reckoning, gyroscope only; then the
        output on a lost sample is that prediction, and the method acts from there when the
        gap ends).  ``"constant_rate"`` cannot be combined with ``"dt_extension"`` or
        ``"gyro_interpolation"``, which fill the same gap with the gyroscope their own way.
        Default (None): ``"hold"``, except ``"constant_rate"`` for ``"kalman"``, which always
        predicts inside; its ``"hold"`` holds only the output on lost samples.
    gap_time_constant : float, optional
        With ``"constant_rate"``: the extrapolated rate decays as ``exp(−t/τ)``, τ in s (for
        ``"kalman"`` it replaces ``kalman_settings.gap_rate_decay_s``).
    return_weight : bool
        Also return μ (not with ``"kalman"``).
    kalman_settings : KalmanSettings, optional
        Only for ``"kalman"``: its noise levels and gates (default ``KalmanSettings()``).

    Returns
    -------
    quat : numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth).  ``...`` is the broadcast of the leading
        dimensions of the signals, ``received``, ``q0``, ``beta`` (except for ``"kalman"``),
        and of the parameters the method uses (``rho``, ``tau``, ``hold_window`` for ``"hybrid"`` and
        ``"adaptive_beta"``, ``beta_max`` for ``"adaptive_beta"``); parameters a method does
        not use add no dimension.  Lost samples hold the previous output (or, with
        ``gap="constant_rate"``, the prediction).
    mu : numpy.ndarray, shape (..., T)
        Only with ``return_weight``: μ of eq. (3) from λ_eff on every sample (1 where
        λ_eff = 0), whatever the method, with the leading dimensions of ``quat`` broadcast
        with those of ``received``, ``rho``, ``tau`` and ``hold_window``.

    Raises
    ------
    ValueError
        Naming the argument: an unknown ``method``, ``schedule`` or ``blend``; ``beta``
        missing (other than ``"kalman"``); ``kalman_settings`` with another method or not a
        :class:`KalmanSettings`; ``return_weight`` with ``"kalman"``; ρ or τ <= 0,
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
    method = B.check_choice(method, "method", ALL_METHODS)
    if method == "kalman":
        return _kalman(gyr, acc, mag, fs=fs, received=received, q0=q0, gap=gap, gap_time_constant=gap_time_constant,
                       return_weight=return_weight, kalman_settings=kalman_settings)
    if kalman_settings is not None:
        raise ValueError(f"kalman_settings is only used with method='kalman', not method={method!r}")
    if beta is None:
        raise ValueError(f"beta (rad/s) is required for method={method!r} (Madgwick's gain)")
    schedule = B.check_choice(schedule, "schedule", SCHEDULES)
    blend = B.check_choice(blend, "blend", BLENDS)
    fs = B.check_fs(fs)
    beta = B.check_beta(beta)
    if beta_max is None:
        beta_max = DEFAULT_BETA_MAX_FACTOR * beta
    else:
        beta_max = B.check_beta(beta_max, "beta_max")
    rho = B.positive_array(rho, "rho")
    tau = B.positive_array(tau, "tau")
    window = B.check_hold_window(hold_window, schedule, DEFAULT_HOLD_WINDOW)
    gap, gap_time_constant = B.check_gap("hold" if gap is None else gap, gap_time_constant, method)
    if method == "hybrid" and mag is None:
        raise ValueError("mag is required for method='hybrid': TRIAD (q_s) needs the magnetometer")

    signals, mask, q0, shapes = B.check_inputs(gyr, acc, mag, received, q0)
    n_t = signals["gyr"].shape[-2]
    if mask is None:
        mask = np.ones(n_t, dtype=bool)
    shapes["received"] = mask.shape[:-1]
    B.broadcast_batch(shapes)
    params = {"beta": beta.shape, "beta_max": beta_max.shape, "rho": rho.shape, "tau": tau.shape}
    if window is not None:
        params["hold_window"] = window.shape
    B.broadcast_batch(shapes | params)
    if np.any(beta_max < beta):
        raise ValueError("beta_max must be >= beta (element by element)")
    if q0 is None and n_t == 0:
        raise ValueError("no samples (T = 0): pass q0 to define the output")

    # Parameters a method does not use add no batch dimension.
    uses_mu = method in ("hybrid", "adaptive_beta")
    batch = B.broadcast_batch(shapes | {"beta": beta.shape})
    if uses_mu:
        batch = np.broadcast_shapes(batch, rho.shape, tau.shape, () if window is None else window.shape)
        if method == "adaptive_beta":
            batch = np.broadcast_shapes(batch, beta_max.shape)
    blend_code = _BLEND_CODES[blend] if method == "hybrid" else K.NO_BLEND
    unused = {} if uses_mu else {"rho": 1.0, "tau": 1.0, "window": 1}
    quat = B.run_filter(signals, mask, q0, batch, fs=fs, method=_METHOD_CODES[method], blend=blend_code,
                        beta=beta, beta_max=beta_max if method == "adaptive_beta" else beta,
                        **({"rho": rho, "tau": tau, "window": 1 if window is None else window} | unused),
                        schedule=_SCHEDULE_CODES[schedule], gap=gap, gap_time_constant=gap_time_constant)
    if not return_weight:
        return quat
    lam = _effective_lost_run(mask, schedule, window, leading_gap=q0 is not None)
    mu = rho[..., None] / (lam / tau[..., None] + rho[..., None])
    mu_batch = np.broadcast_shapes(quat.shape[:-2], mu.shape[:-1])
    return quat, np.array(np.broadcast_to(mu, mu_batch + mu.shape[-1:]))


def _kalman(gyr, acc, mag, *, fs, received, q0, gap, gap_time_constant, return_weight, kalman_settings):
    """``estimate_orientation(..., method="kalman")``: the parameters it uses, checked, then
    :func:`wsnlib.orientation.kalman_orientation`."""
    if return_weight:
        raise ValueError("return_weight is not available for method='kalman' (it has no SLERP weight μ)")
    gap, gap_time_constant = B.check_gap("constant_rate" if gap is None else gap, gap_time_constant, "kalman")
    if kalman_settings is None:
        kalman_settings = KalmanSettings()
    if not isinstance(kalman_settings, KalmanSettings):
        raise ValueError(f"kalman_settings must be a KalmanSettings, got {type(kalman_settings).__name__}")
    if gap_time_constant is not None:
        kalman_settings = dataclasses.replace(kalman_settings, gap_rate_decay_s=gap_time_constant)
    return kalman_orientation(gyr, acc, mag, fs=fs, received=received, q0=q0, settings=kalman_settings, gap=gap)


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
    schedule = B.check_choice(schedule, "schedule", SCHEDULES)
    rho = B.positive_array(rho, "rho")
    tau = B.positive_array(tau, "tau")
    window = B.check_hold_window(hold_window, schedule, DEFAULT_HOLD_WINDOW)
    quat_d = B.unit_quaternions(quat_d, "quat_d")
    if quat_d.ndim < 2:
        raise ValueError(f"quat_d must have shape (..., T, 4), got shape {quat_d.shape}")
    signals = {"acc": B.as_signal(acc, "acc"), "mag": B.as_signal(mag, "mag")}
    n_t = quat_d.shape[-2]
    for name, arr in signals.items():
        if arr.shape[-2] != n_t:
            raise ValueError(f"{name} has {arr.shape[-2]} samples (axis -2), quat_d has {n_t}")
    if received is None:
        mask = np.ones(n_t, dtype=bool)
    else:
        mask = B.check_received(received)
        if mask.shape[-1] != n_t:
            raise ValueError(f"received must have shape (..., {n_t}), got {mask.shape}")
    shapes = {name: arr.shape[:-2] for name, arr in signals.items()} | {"received": mask.shape[:-1]}
    B.broadcast_batch(shapes)
    shapes["quat_d"] = quat_d.shape[:-2]
    params = {"rho": rho.shape, "tau": tau.shape}
    if window is not None:
        params["hold_window"] = window.shape
    batch = B.broadcast_batch(shapes | params)
    B.check_usable(signals, mask)
    out = B.new_output(batch, n_t)
    if n_t:
        K.run_output_blend(B.flat(quat_d, 2), B.flat(signals["acc"], 2), B.flat(signals["mag"], 2),
                           B.flat(mask, 1), B.index_into(quat_d.shape[:-2], batch),
                           B.index_into(signals["acc"].shape[:-2], batch),
                           B.index_into(signals["mag"].shape[:-2], batch), B.index_into(mask.shape[:-1], batch),
                           B.per_element(rho, batch), B.per_element(tau, batch), _SCHEDULE_CODES[schedule],
                           B.per_element(1 if window is None else window, batch, np.int64), leading_gap,
                           out.reshape(-1, n_t, 4))
    return out
