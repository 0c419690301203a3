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

Sec. V adds three alternatives.  In the vocabulary every filter of :mod:`wsnlib.orientation`
shares (its docstring) they are: integrating the first gyroscope sample after a gap over
``(1 + λ)Δt`` (``method="dt_extension"``), linear interpolation of the gyroscope across the
gap (``replay=True``: the gap re-run at its end), and a step size β that depends on λ
(``method="adaptive_beta"``); the hybrid of eqs. (3)–(4) is ``blend=``, its SLERP either an
output stage (``blend="output"``) or fed back into the filter's state after each received
sample (``blend="feedback"``): Fig. 4 draws the former, Sec. V's "make the internal state
[...] recover fast" suggests the latter.  Plain Madgwick under loss (the paper's receiver, the
baseline) is every option at its default.  :data:`PAPER_OPTIONS` names the paper's five options
as keywords.

Every combination is one compiled loop, :func:`wsnlib.orientation._kernels.filter_stream`
(read it beside :func:`estimate_orientation`'s docstring); λ_eff is updated in the same loop.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import check_choice, check_flag
from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K
from wsnlib.orientation.hybrid_blend import check_single_frame_gate
from wsnlib.orientation.kalman_settings import gap_prediction_window
from wsnlib.orientation.lost_run import SCHEDULE_CODES, check_weight_options, effective_lost_run_unchecked

#: Madgwick's update after a gap (``method``): the standard one, or one of paper 001's Sec. V.
METHODS = ("madgwick", "dt_extension", "adaptive_beta")
#: Default ``beta_max`` of ``method="adaptive_beta"``, as a multiple of β.
DEFAULT_BETA_MAX_FACTOR = 10.0
#: Paper 001's loss-handling options (the labels the notebooks use) as keywords of
#: :func:`estimate_orientation`; the hybrid's blend and μ are the caller's choice.
PAPER_OPTIONS = {"hold_last": {}, "dt_extension": {"method": "dt_extension"},
                 "gyro_interpolation": {"replay": True}, "adaptive_beta": {"method": "adaptive_beta"},
                 "hybrid": {"blend": "output"}}

_METHOD_CODES = dict(zip(METHODS, (K.STANDARD, K.DT_EXTENSION, K.ADAPTIVE_BETA), strict=True))
_BLEND_CODES = {None: K.NO_BLEND, "output": K.OUTPUT_BLEND, "feedback": K.FEEDBACK_BLEND}
#: Spellings of earlier versions, and what they are now (for the error message).
_NOW_SPELLED = {"hold_last": "the default (method='madgwick')", "gyro_interpolation": "replay=True",
                "hybrid": "blend='output' or blend='feedback'", "kalman": "wsnlib.orientation.kalman_orientation"}


def estimate_orientation(gyr, acc, mag=None, *, fs: float, beta, received=None, q0=None, method: str = "madgwick",
                         gap: str = "hold", replay: bool = False, output_on_lost: str = "estimate",
                         gap_time_constant=None, gap_rate_prediction_span_s=None, gap_rate_prediction_window_s=None,
                         blend: str | None = None, rho=None, tau=None, schedule=None, hold_window=None,
                         single_frame_gate=None, beta_max=None, return_weight: bool = False):
    """Madgwick's filter under packet loss with every loss-handling option, batched.

    Madgwick's filter (:mod:`wsnlib.orientation.madgwick`) runs on the received samples.  The
    options, in the vocabulary of :mod:`wsnlib.orientation`: what its state does inside a gap
    (``gap``), whether the gap is re-run once it ends (``replay``), what is output on a lost
    sample (``output_on_lost``), how the update after a gap differs (``method``) and whether
    paper 001's hybrid pulls the estimate towards the single frame (``blend``).  λ below is
    the length of the gap that just ended, λ_eff the effective λ of ``schedule``
    (:func:`~wsnlib.orientation.lost_run.effective_lost_run`) and μ =
    ``slerp_weight(λ_eff, ρ, τ)`` (eq. (3)).  With every option at its default this is
    :func:`wsnlib.orientation.madgwick` (the paper's baseline, "hold last").

    * ``method="dt_extension"`` (Sec. V): the first received sample after a gap of λ samples is
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
      θ = |ω|(1+λ)Δt comes out as ``2·atan(θ/2)`` (0.5 rad → 0.49 rad).  Only with
      ``gap="hold"`` and no ``replay`` (they fill the same gap with the gyroscope).
    * ``replay=True`` (Sec. V's gyroscope interpolation): when the first sample after a gap
      arrives, the filter re-runs the λ lost samples from its state at the gap's start as
      gyroscope-only updates (their acc/mag never arrived) with ω interpolated linearly between
      the last received sample before the gap and the first one after it, then makes the
      normal update.  A gap at the start (with ``q0`` given) uses the first received ω
      throughout; a gap at the end is never replayed.  Causal: the lost samples were already
      output; only the state from the gap's end on changes.
    * ``method="adaptive_beta"`` (Sec. V, "adjusting [β] in accordance with λ"): each update uses
      ``β_eff = β + (β_max − β)(1 − μ)``, so β_eff = β while nothing was lost and tends to
      β_max after long gaps, then returns to β as the schedule decays.
    * ``blend`` (Sec. III, eq. (4)): ``q_f = SLERP(q_s, q_d, μ)`` on every received sample,
      ``q_s`` = TRIAD of that sample, ``q_d`` Madgwick's estimate.  ``"output"``: Madgwick's
      state runs as without the hybrid and only the output is blended; ``"feedback"``: ``q_f``
      replaces the state after each received update.  Needs ``mag``.  With
      ``single_frame_gate`` (the *gated hybrid*) μ = 1 also on every received sample whose
      single frame looks untrustworthy (:class:`~wsnlib.orientation.SingleFrameGate`).

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s²) in the body frame.
    mag : array_like, shape (..., T, 3), optional
        Magnetic field in the body frame (µT); ``None`` runs Madgwick's IMU form (not
        allowed with ``blend``, whose TRIAD needs it).
    fs : float
        Sampling rate (Hz), > 0; Δt = 1/fs.
    beta : float or array_like
        Gain β (rad/s), >= 0; an array gives one per batch element (it broadcasts against
        the leading dimensions of the signals).
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all
        received.
    q0 : array_like, shape (4,) or (..., 4), optional
        Estimate before the first sample, as in :func:`wsnlib.orientation.madgwick`.
        ``None``: each batch element starts from TRIAD (IMU form: the tilt) of its first
        received sample.  A gap before that sample is then no gap of the filter, which had
        not started: λ_eff is 0 up to that sample, and nothing is replayed or extended.
        With ``q0`` a gap at the start is a gap like any other.
    method : {"madgwick", "dt_extension", "adaptive_beta"}
        The update after a gap (above); ``"madgwick"``: the standard one.
    gap : {"hold", "constant_rate", "ar"}
        What the state does in a gap: stay (the paper's receiver), keep turning by the last
        received angular rate (dead reckoning, gyroscope only; the method acts from there when
        the gap ends), or turn by the autoregressive prediction of the raw rate fitted at the
        gap's start (:mod:`wsnlib.orientation.gaps`, the Kalman filter's gap module).
    replay : bool
        Re-run the gap at its end from the state at its start (above); with ``gap="ar"`` the
        replay's rates are the AR prediction corrected towards the first received rate
        (:func:`wsnlib.orientation.gaps.replay_rate`) instead of the linear ramp.
    output_on_lost : {"estimate", "hold"}
        What is output on a lost sample: the filter's estimate (the held state with
        ``gap="hold"``, the prediction otherwise), or the previous output.
    gap_time_constant : float, optional
        With ``"constant_rate"``: the extrapolated rate decays as ``exp(−t/τ)``, τ in s;
        ``None`` or ``inf``: constant.
    gap_rate_prediction_span_s, gap_rate_prediction_window_s : float, optional
        With ``gap="ar"`` only: the predictor's span (its order is the span in samples) and the
        window of rates it is fitted on (s).  ``None``: :class:`wsnlib.orientation.KalmanSettings`'
        defaults (0.96 s, 6 s).
    blend : {None, "output", "feedback"}
        Paper 001's hybrid (above); ``None``: none.
    rho, tau : float or array_like, optional
        ρ, τ of eq. (3), finite and > 0 (positive integers in the paper; defaults ρ = 2,
        τ = 6, so μ = 1/2 at λ_eff = 12 samples).  Arrays broadcast against the leading
        dimensions: with ``gyr`` ``(R, T, 3)``, ``rho`` ``(8, 1, 1)`` and ``tau`` ``(1, 8, 1)``
        give an ``(8, 8, R, T, 4)`` output in one pass.  Used by ``blend``,
        ``"adaptive_beta"`` and ``return_weight``; given without them, a ``ValueError``.
    schedule : {"decay", "hold", "instant"}, optional
        λ_eff after a gap (:func:`~wsnlib.orientation.lost_run.effective_lost_run`, default
        ``"decay"``); used as ``rho``.
    hold_window : int or array_like of int, optional
        For ``schedule="hold"`` only: received samples during which λ_eff is held, >= 1
        (default 50), scalar or per batch element.
    single_frame_gate : SingleFrameGate or bool, optional
        With ``blend``: the gated hybrid, eq. (4) skipped (μ = 1) on received samples whose
        TRIAD fails a check of :class:`~wsnlib.orientation.SingleFrameGate` (``True``: default
        tolerances).  Not with ``return_weight`` (μ would depend on the signals).
    beta_max : float or array_like, optional
        β after a very long gap for ``"adaptive_beta"`` (only), finite and >= β.  Default
        ``10 β`` (:data:`DEFAULT_BETA_MAX_FACTOR`).
    return_weight : bool
        Also return μ from ``rho``, ``tau``, ``schedule`` and ``hold_window`` (without ``blend``
        or ``"adaptive_beta"`` only a diagnostic of the λ schedule).

    Returns
    -------
    quat : numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth).  ``...`` is the broadcast of the leading
        dimensions of the signals, ``received``, ``q0``, ``beta``, and of the parameters the
        options use (``rho``, ``tau``, ``hold_window`` with ``blend`` or ``"adaptive_beta"``,
        ``beta_max`` with ``"adaptive_beta"``).
    mu : numpy.ndarray, shape (..., T)
        Only with ``return_weight``: μ of eq. (3) from λ_eff on every sample (1 where
        λ_eff = 0), with the leading dimensions of ``quat`` broadcast with those of
        ``received``, ``rho``, ``tau`` and ``hold_window``.

    Raises
    ------
    ValueError
        Naming the argument: an unknown ``method`` (an earlier spelling is named with its
        replacement), ``gap``, ``output_on_lost``, ``blend`` or ``schedule``; an option given
        where nothing uses it (``rho``, ``tau``, ``schedule``, ``hold_window`` without
        ``blend``, ``"adaptive_beta"`` or ``return_weight``; ``single_frame_gate`` without
        ``blend``; ``beta_max`` without ``"adaptive_beta"``; ``gap_time_constant`` with
        ``gap="hold"``; ``gap_rate_prediction_*`` without ``gap="ar"``); ``"dt_extension"``
        with another ``gap`` than ``"hold"`` or with ``replay``; ρ or
        τ <= 0, NaN or inf; β < 0 or not finite; ``beta_max`` < β or not finite;
        ``hold_window`` not a positive integer with ``schedule="hold"`` or given with another
        schedule; ``mag`` None with ``blend``; and everything
        :func:`wsnlib.orientation.madgwick` rejects (shapes, NaN/inf or zero vectors in
        received samples, ``fs``, ``q0``, a batch element with nothing received when ``q0``
        is None).  A received sample with ``acc`` parallel to ``mag`` fails in TRIAD when the
        hybrid needs it.

    Notes
    -----
    One compiled loop over time per batch element, the elements in parallel
    (:func:`wsnlib.orientation._kernels.run_filter`); λ_eff and μ are computed in that loop
    (no ``(..., T)`` array of them unless ``return_weight``).  TRIAD and SLERP are computed only
    on the received samples with λ_eff > 0 (elsewhere μ = 1 and eq. (4) returns ``q_d``
    exactly).  Parameters the options do not use add no batch dimension.
    """
    if isinstance(method, str) and method in _NOW_SPELLED:
        raise ValueError(f"method={method!r} is now {_NOW_SPELLED[method]}")
    method = check_choice(method, "method", METHODS)
    gap, gap_time_constant = B.check_gap(gap, gap_time_constant, "estimate_orientation", supported=B.GAPS)
    replay = check_flag(replay, "replay")
    hold_output = B.check_output_on_lost(output_on_lost)
    if method == "dt_extension" and (gap != "hold" or replay):
        raise ValueError("method='dt_extension' fills the gap with the gyroscope its own way: not with "
                         f"gap={gap!r} or replay=True")
    blend = B.check_blend(blend, mag, "estimate_orientation")
    uses_mu = blend is not None or method == "adaptive_beta"
    if not uses_mu and not return_weight:
        B.refuse_unused("estimate_orientation", "without blend, method='adaptive_beta' or return_weight", rho=rho,
                        tau=tau, schedule=schedule, hold_window=hold_window)
    if blend is None:
        B.refuse_unused("estimate_orientation", "without blend", single_frame_gate=single_frame_gate)
    if method != "adaptive_beta":
        B.refuse_unused("estimate_orientation", f"with method={method!r}", beta_max=beta_max)
    gate = check_single_frame_gate(single_frame_gate)
    if gate is not None and return_weight:
        raise ValueError("return_weight is not available with single_frame_gate (μ then depends on the signals)")
    rho, tau, schedule, window = check_weight_options(rho, tau, schedule, hold_window)
    fs = B.check_fs(fs)
    ar_order, ar_window = gap_prediction_window(gap, gap_rate_prediction_span_s, gap_rate_prediction_window_s, fs,
                                                "estimate_orientation")
    beta = B.check_beta(beta)
    beta_max = DEFAULT_BETA_MAX_FACTOR * beta if beta_max is None else B.check_beta(beta_max, "beta_max")

    signals, mask, q0, shapes = B.check_inputs(gyr, acc, mag, received, q0)
    n_t = signals["gyr"].shape[-2]
    B.broadcast_batch(shapes)
    params = {"beta": beta.shape, "beta_max": beta_max.shape, "rho": rho.shape, "tau": tau.shape}
    if window is not None:
        params["hold_window"] = window.shape
    B.broadcast_batch(shapes | params)
    if np.any(beta_max < beta):
        raise ValueError("beta_max must be >= beta (element by element)")
    if q0 is None and n_t == 0:
        raise ValueError("no samples (T = 0): pass q0 to define the output")

    # Parameters the options do not use add no batch dimension.
    batch = B.broadcast_batch(shapes | {"beta": beta.shape})
    if uses_mu:
        batch = np.broadcast_shapes(batch, rho.shape, tau.shape, () if window is None else window.shape)
        if method == "adaptive_beta":
            batch = np.broadcast_shapes(batch, beta_max.shape)
    unused = {} if uses_mu else {"rho": 1.0, "tau": 1.0, "window": 1}
    quat = B.run_filter(signals, mask, q0, batch, fs=fs, method=_METHOD_CODES[method], replay=replay,
                        blend=_BLEND_CODES[blend], beta=beta, beta_max=beta_max if method == "adaptive_beta" else beta,
                        **({"rho": rho, "tau": tau, "window": 1 if window is None else window} | unused),
                        schedule=SCHEDULE_CODES[schedule], gap=gap, gap_time_constant=gap_time_constant,
                        ar_order=ar_order, ar_window=ar_window,
                        single_frame_gate=None if gate is None else gate.vector(fs))
    if hold_output:
        B.hold_lost_output(quat, mask)
    if not return_weight:
        return quat
    lam = effective_lost_run_unchecked(mask, schedule, window, leading_gap=q0 is not None)
    mu = rho[..., None] / (lam / tau[..., None] + rho[..., None])
    mu_batch = np.broadcast_shapes(quat.shape[:-2], mu.shape[:-1])
    return quat, np.array(np.broadcast_to(mu, mu_batch + mu.shape[-1:]))
