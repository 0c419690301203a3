"""Packet-loss handling for Madgwick's filter: paper 001's hybrid SLERP and the Sec. V alternatives.

Paper 001 (De Vito et al.) interpolates between the single-frame (TRIAD) estimate ``q_s`` and
the data-fusion (Madgwick) estimate ``q_d``:

* eq. (2): ``SLERP(q_A, q_B, μ) = sin((1−μ)Ω)/sin Ω · q_A + sin(μΩ)/sin Ω · q_B``
  (:func:`wsnlib.quaternion.slerp`);
* eq. (3): ``μ_λ = ρ / (λ/τ + ρ) ∈ (0, 1]``, ``ρ, τ ∈ ℕ₊``, λ the number of samples lost in a
  row (:func:`~wsnlib.orientation.lost_run.slerp_weight`, and what λ is once reception resumes:
  :func:`~wsnlib.orientation.lost_run.effective_lost_run`, module :mod:`.lost_run`);
* eq. (4): ``q_f = SLERP(q_s, q_d, μ_λ)``: μ = 1 gives the data fusion, μ → 0 the single
  frame (as an output stage on any filter, and gated: module :mod:`.hybrid_blend`);
* eq. (5): eqs. (2)–(4) combined, printed with ``ρ/(λ + ρ)``, i.e. eq. (3) with τ = 1.

Sec. V adds three alternatives, all offered by :func:`estimate_orientation` so that they
run on identical data: integrating the first gyroscope sample after a gap over
``(1 + λ)Δt`` (``method="dt_extension"``), linear interpolation of the gyroscope across the
gap (``"gyro_interpolation"``), and a step size β that depends on λ (``"adaptive_beta"``).
``"hold_last"`` is plain Madgwick under loss (:func:`wsnlib.orientation.madgwick`), the
baseline, and ``"hybrid"`` is eqs. (3)–(4), its SLERP either an output stage
(``blend="output"``) or fed back into the filter's state after each received sample
(``blend="feedback"``): Fig. 4 draws the former, Sec. V's "make the internal state [...]
recover fast" suggests the latter.  ``method="kalman"`` runs the gap-aware error-state Kalman
filter (:func:`wsnlib.orientation.kalman_orientation`) on the same inputs instead.

How it dispatches: one settings object per method (:mod:`.method_settings`), passed as
``method`` or built from the keywords in one place
(:func:`~wsnlib.orientation.method_settings.settings_from_arguments`); the object's type picks
the runner.  Every Madgwick-family method is one compiled loop,
:func:`wsnlib.orientation._kernels.filter_stream`, whose branches are the methods (read it
beside :func:`estimate_orientation`'s docstring); λ_eff is updated in the same loop.

On a lost sample every Madgwick-family method outputs the previous output (the receiver has
nothing new to show), as :func:`wsnlib.orientation.madgwick` does, unless
``gap="constant_rate"`` (and ``"kalman"``, whose default is ``gap="constant_rate"``).  Before a
batch element's first received sample the output is the initial estimate.

This module also re-exports, from their homes, what it held before it was split (issue 13):
:func:`slerp_weight`, :func:`effective_lost_run`, :data:`SCHEDULES`,
:data:`DEFAULT_HOLD_WINDOW` (:mod:`.lost_run`); :class:`SingleFrameGate`,
:func:`single_frame_trusted`, :func:`blend_with_single_frame` (:mod:`.hybrid_blend`);
:data:`METHODS`, :data:`ALL_METHODS`, :data:`BLENDS` (:mod:`.method_settings`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K
from wsnlib.orientation.hybrid_blend import (  # noqa: F401  (re-exported: the old import path)
    SingleFrameGate,
    blend_with_single_frame,
    check_single_frame_gate,
    single_frame_trusted,
)
from wsnlib.orientation.hybrid_blend import trusted_unchecked as _trusted  # noqa: F401  (peers imports it)
from wsnlib.orientation.kalman import KalmanSettings, kalman_orientation
from wsnlib.orientation.lost_run import (  # noqa: F401  (re-exported: the old import path)
    DEFAULT_HOLD_WINDOW,
    SCHEDULE_CODES,
    SCHEDULES,
    effective_lost_run,
    effective_lost_run_unchecked,
    slerp_weight,
)
from wsnlib.orientation.method_settings import (  # noqa: F401  (re-exported: the old import path)
    ALL_METHODS,
    BLENDS,
    METHODS,
    UNSET,
    AdaptiveBetaSettings,
    HybridSettings,
    KalmanMethodSettings,
    settings_from_arguments,
)

#: Default ``beta_max`` of ``method="adaptive_beta"``, as a multiple of β.
DEFAULT_BETA_MAX_FACTOR = 10.0

_METHOD_CODES = dict(zip(METHODS, (K.HOLD_LAST, K.DT_EXTENSION, K.GYRO_INTERPOLATION, K.ADAPTIVE_BETA, K.HYBRID),
                         strict=True))
_BLEND_CODES = {"output": K.OUTPUT_BLEND, "feedback": K.FEEDBACK_BLEND}
#: λ_eff and μ parameters of ``return_weight`` for a method that has none (the settings' defaults).
_WEIGHT_DEFAULTS = {"rho": 2.0, "tau": 6.0, "schedule": "decay", "hold_window": None}


def estimate_orientation(
    gyr,
    acc,
    mag=None,
    *,
    fs: float,
    beta=UNSET,
    received=None,
    method="hybrid",
    rho=UNSET,
    tau=UNSET,
    schedule=UNSET,
    hold_window=UNSET,
    blend=UNSET,
    beta_max=UNSET,
    q0=None,
    gap=UNSET,
    gap_time_constant=UNSET,
    return_weight: bool = False,
    kalman_settings=UNSET,
    single_frame_gate=UNSET,
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
      ``mag``.  With ``single_frame_gate`` (the *gated hybrid*) μ = 1 also on every received
      sample whose single frame looks untrustworthy (:class:`SingleFrameGate`).
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
    method : {"hybrid", "hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "kalman"} or settings
        A settings object holding the method and its parameters
        (:mod:`wsnlib.orientation.method_settings`: :class:`~.method_settings.HybridSettings`,
        :class:`~.method_settings.AdaptiveBetaSettings`, :class:`~.method_settings.HoldLastSettings`,
        :class:`~.method_settings.DtExtensionSettings`,
        :class:`~.method_settings.GyroInterpolationSettings`,
        :class:`~.method_settings.KalmanMethodSettings`, or a bare :class:`KalmanSettings` for
        ``"kalman"``); then none of the method keywords below (``beta`` … ``single_frame_gate``)
        may be passed.  Or the method's name, with its parameters as the keywords below (the
        compatibility layer: they become the settings object,
        :func:`~.method_settings.settings_from_arguments`).
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
        Also return μ (not with ``"kalman"``), from ``rho``, ``tau``, ``schedule`` and
        ``hold_window`` (the settings object's, else those passed, else the defaults: for a
        method that does not use them, μ is only a diagnostic of the λ schedule).
    kalman_settings : KalmanSettings, optional
        Only for ``"kalman"``: its noise levels and gates (default ``KalmanSettings()``).
    single_frame_gate : SingleFrameGate or bool, optional
        Only for ``"hybrid"``: the gated hybrid, eq. (4) skipped (μ = 1) on received samples
        whose TRIAD fails a check of :class:`SingleFrameGate` (``True``: default tolerances;
        ``None``/``False``: the plain hybrid).  Not with ``return_weight`` (μ would depend on
        the signals).

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
        Naming the argument: a method keyword passed beside a settings object (whatever its
        value); an unknown ``method``, ``schedule`` or ``blend``; ``beta``
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
    The method keywords default to :data:`~.method_settings.UNSET` ("not passed"); the
    defaults written above are those of the settings classes.  One compiled loop over time
    per batch element, the elements in parallel (:func:`wsnlib.orientation._kernels.run_filter`);
    λ_eff and μ are computed in that loop (no ``(..., T)`` array of them unless
    ``return_weight``).  TRIAD and SLERP are computed only on the received samples with
    λ_eff > 0 (elsewhere μ = 1 and eq. (4) returns ``q_d`` exactly).  Parameters a method does
    not use add no batch dimension.
    """
    keywords = {"beta": beta, "rho": rho, "tau": tau, "schedule": schedule, "hold_window": hold_window,
                "blend": blend, "beta_max": beta_max, "gap": gap, "gap_time_constant": gap_time_constant,
                "kalman_settings": kalman_settings, "single_frame_gate": single_frame_gate}
    settings = settings_from_arguments(method, keywords)
    if isinstance(settings, KalmanMethodSettings):
        if return_weight:
            raise ValueError("return_weight is not available for method='kalman' (it has no SLERP weight μ)")
        return _run_kalman(gyr, acc, mag, fs=fs, received=received, q0=q0, settings=settings)
    weight = None
    if return_weight:  # μ's parameters: the settings', else those passed (compatibility), else defaults
        weight = {name: getattr(settings, name, keywords[name]) for name in _WEIGHT_DEFAULTS}
        weight = {name: _WEIGHT_DEFAULTS[name] if value is UNSET else value for name, value in weight.items()}
    return _run_madgwick(gyr, acc, mag, fs=fs, received=received, q0=q0, settings=settings, weight=weight)


def _run_madgwick(gyr, acc, mag, *, fs, received, q0, settings, weight):
    """A Madgwick-family settings object (:mod:`.method_settings`) on the inputs, checked here;
    ``weight``: None, or ``rho``, ``tau``, ``schedule``, ``hold_window`` of μ to return too."""
    method = settings.method
    uses_mu = isinstance(settings, (HybridSettings, AdaptiveBetaSettings))
    mu_params = weight if weight is not None else _WEIGHT_DEFAULTS
    if uses_mu:
        mu_params = {name: getattr(settings, name) for name in _WEIGHT_DEFAULTS}
    gate = check_single_frame_gate(getattr(settings, "single_frame_gate", None))
    if gate is not None and weight is not None:
        raise ValueError("return_weight is not available with single_frame_gate (μ then depends on the signals)")
    if settings.beta is None:
        raise ValueError(f"beta (rad/s) is required for method={method!r} (Madgwick's gain)")
    schedule = B.check_choice(mu_params["schedule"], "schedule", SCHEDULES)
    blend = B.check_choice(getattr(settings, "blend", "output"), "blend", BLENDS)
    fs = B.check_fs(fs)
    beta = B.check_beta(settings.beta)
    beta_max = getattr(settings, "beta_max", None)
    beta_max = DEFAULT_BETA_MAX_FACTOR * beta if beta_max is None else B.check_beta(beta_max, "beta_max")
    rho = B.positive_array(mu_params["rho"], "rho")
    tau = B.positive_array(mu_params["tau"], "tau")
    window = B.check_hold_window(mu_params["hold_window"], schedule, DEFAULT_HOLD_WINDOW)
    gap, gap_time_constant = B.check_gap("hold" if settings.gap is None else settings.gap, settings.gap_time_constant,
                                         method)
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
                        schedule=SCHEDULE_CODES[schedule], gap=gap, gap_time_constant=gap_time_constant,
                        single_frame_gate=None if gate is None else gate.vector(fs))
    if weight is None:
        return quat
    lam = effective_lost_run_unchecked(mask, schedule, window, leading_gap=q0 is not None)
    mu = rho[..., None] / (lam / tau[..., None] + rho[..., None])
    mu_batch = np.broadcast_shapes(quat.shape[:-2], mu.shape[:-1])
    return quat, np.array(np.broadcast_to(mu, mu_batch + mu.shape[-1:]))


def _run_kalman(gyr, acc, mag, *, fs, received, q0, settings: KalmanMethodSettings):
    """A :class:`~.method_settings.KalmanMethodSettings` on the inputs:
    :func:`wsnlib.orientation.kalman_orientation` with its settings and gap options, checked."""
    gap, gap_time_constant = B.check_gap("constant_rate" if settings.gap is None else settings.gap,
                                         settings.gap_time_constant, "kalman")
    kalman_settings = KalmanSettings() if settings.settings is None else settings.settings
    if not isinstance(kalman_settings, KalmanSettings):
        raise ValueError(f"kalman_settings must be a KalmanSettings, got {type(kalman_settings).__name__}")
    if gap_time_constant is not None:
        kalman_settings = dataclasses.replace(kalman_settings, gap_rate_decay_s=gap_time_constant)
    return kalman_orientation(gyr, acc, mag, fs=fs, received=received, q0=q0, settings=kalman_settings, gap=gap)
