"""Gap-aware error-state Kalman filter for orientation under packet loss (issue 11).

A multiplicative extended Kalman filter (MEKF; F. L. Markley, "Attitude error representations
for Kalman filtering", J. Guidance Control Dyn. 26(2):311–317, 2003; J. Solà, "Quaternion
kinematics for the error-state Kalman filter", arXiv:1711.02508, 2017, Sec. 7) on the
quaternion ``q`` (body → ENU), the gyroscope bias ``b`` (rad/s) and a leaky velocity ``v``
(m/s, earth frame; below), with a 9-state error

    δx = [δθ, δb, δv],   q_true = Exp(δθ) ⊗ q̂   (δθ: rotation vector in the EARTH frame, rad),
                         b_true = b̂ + δb        (rad/s, body frame),
                         v_true = v̂ + δv        (m/s, earth frame).

With the error in the earth frame, gravity observes exactly the horizontal components
(δθ_x, δθ_y: tilt) and the magnetometer's heading exactly δθ_z, so every measurement below is
a scalar update with ``H`` a unit row (no Jacobian to differentiate by hand).

Equations (one sample, Δt = 1/fs; names used in the kernel's comments)
-----------------------------------------------------------------------
* **Strapdown prediction**: ``q⁻ = q ⊗ Exp((ω − b̂) Δt)``, ``b⁻ = b̂``.
* **Leaky velocity** (VQF's accelerometer low-pass as a state): on a received sample
  ``v̂⁻ = c v̂ + (a_E − g e_z) Δt`` with ``a_E = R(q⁻) a``, ``c = exp(−Δt/τ_v)``; on a lost one
  ``v̂⁻ = c v̂``.  ``v`` is τ_v times the low-pass (time constant τ_v) of the earth-frame
  linear acceleration, i.e. about the velocity minus its recent mean: it stays small for a
  body that does not travel, whatever its acceleration (VQF low-pass filters the specific
  force in an almost-inertial frame for the same reason, Laidig & Seel 2023, Sec. 3.2).
* **Error propagation**: ``δθ⁻ = δθ − R(q⁻) δb Δt``, ``δv⁻ = c δv − [a_E]× δθ⁻ Δt`` (since
  ``R_true a = a_E + δθ × a_E``), i.e.
  ``F = [[I, −R Δt, 0], [0, I, 0], [−[a_E]× Δt, [a_E]× R Δt², c I]]`` (``a_E = 0`` when lost),
  and ``P⁻ = F P Fᵀ + Q``, ``Q = diag(σ_g² Δt I, σ_b² Δt I, (σ_s Δt)² I)`` (gyro white noise
  density σ_g, bias random walk σ_b, accelerometer noise σ_s; isotropic, so
  ``R σ_g² Rᵀ = σ_g² I``).
* **Gap**: on a lost sample nothing is measured; the prediction goes on with a predicted rate:
  by default (``gap="ar"``) a linear predictor (autoregressive, order ``p``, per
  axis) fitted at the gap's start on the rates of the last ``gap_rate_prediction_window_s``
  and run on its own outputs, ``ω_k = Σ_i c_i ω_{k−p+i}`` (norm capped at the window's
  largest), which follows a swing of the arm instead of overshooting it; otherwise (or
  without a full window of history) the last received bias-corrected rate, optionally
  decaying, ``ω_k = ω_last · exp(−kΔt/τ_decay)``.  The error of that extrapolated rate (std
  ``σ_gap``, constant across the gap) adds ``σ_gap² Δt² (2k − 1)`` to the attitude variances
  at the k-th lost sample, so that after ``k`` lost samples the added variance is
  ``(σ_gap · kΔt)²``: the covariance grows with the elapsed gap, and the first measurements
  after it get large gains by construction.  The
  unknown linear acceleration of the gap (std ``σ_gap,acc``) likewise replaces ``(σ_s Δt)²``
  in the velocity variances by ``(σ_gap,acc Δt)² (2k − 1)``.
* **Gap replay** (``replay``): at the first received sample after a gap of ``L`` samples
  the state at the gap's end is recomputed from the last received state ``q_s`` as
  ``q_s ⊗ Π_{k=1..L} Exp(ω_k Δt)``.  With the linear prediction, ``ω_k`` is the predicted
  rate plus ``w_k`` times the predictor's error at the received sample (measured − predicted),
  ``w_k`` the Gaussian conditional expectation of the k-th step's prediction error given the
  last one under the fitted model (:func:`~._gap_rate_kernels.gap_rate_end_weights`: a linear
  ramp for a slowly varying rate, following the oscillation for a swing); without it,
  ``ω_k`` is linear between the bias-corrected rates before and after the gap (paper 001's
  gyroscope interpolation applied to the state).  Causal: the lost samples were already
  output as the extrapolation; ``P`` keeps the gap's growth.
* **Accelerometer (tilt) update**: ``e = R(q⁻) a/‖a‖`` should be earth up ``e_z``; the
  measured tilt error is the rotation taking ``e`` onto ``e_z``,
  ``φ = atan2(‖e × e_z‖, e·e_z) · (e × e_z)/‖e × e_z‖`` (exact for large errors, e.g. after a
  gap), and ``φ_x = δθ_x``, ``φ_y = δθ_y`` (two scalar updates, ``H = e_0ᵀ, e_1ᵀ``).
* **Velocity pseudo-measurement** (every received sample, after the accelerometer):
  ``v = 0`` with noise std ``σ_v`` (three scalar updates, ``H = e_6ᵀ, e_7ᵀ, e_8ᵀ``,
  innovation ``−v̂_i``).  A tilt error ``δθ`` makes ``v̂`` ramp by ``g δθ Δt`` per sample,
  and ``P``'s cross terms from ``F`` turn that ramp into a tilt correction — with no
  accelerometer gate, so tilt stays observed during fast motion, where the gated update
  below almost never fires; and after a gap the ramp starts from the gap's error, with the
  gains the grown covariance gives.  The vertical component is measured too: after a gap in
  fast motion it is what reveals a large tilt error (a 2–3 g acceleration seen through a
  tilt error of 30° makes ``v̂_z`` ramp); a gravity or scale error of 1 % biases it by only
  ``τ_v · 0.1 m/s²`` ≈ 0.3 m/s.
* **Magnetometer (heading) update**: ``m_E = R(q⁻) m``; the heading error is
  ``ψ = atan2(m_E,x, m_E,y)`` (as VQF's "disagreement angle") and ``ψ = δθ_z``
  (``H = e_2ᵀ``).  Heading only: the gain's tilt rows are set to zero, so a disturbed field
  can never tilt the estimate (VQF and Fusion also correct heading about the vertical only);
  the covariance is updated in Joseph form, which is exact for any gain.
* **Scalar update** (each of the above, ``H = e_iᵀ``, noise variance ``r``):
  ``S = P_ii + r``, ``K = P_·i / S``, ``δx += K (z − δx_i)``,
  ``P ← P − K P_i· − P_·i Kᵀ + S K Kᵀ`` (Joseph form ``(I − KH)P(I − KH)ᵀ + r K Kᵀ``).
* **Injection** after each sensor: ``q ← Exp(δθ) ⊗ q``, ``b ← b + δb``, ``v̂ ← v̂ + δv``,
  ``δx ← 0``
  (the covariance reset Jacobian is taken as the identity, as usual for small δθ).

Gates (where they come from)
----------------------------
* Accelerometer, hard: used only if ``|‖a‖ − g| ≤ acc_norm_gate`` and ``‖ω − b̂‖ ≤
  acc_rate_gate``.  Soft: inside the gate the noise variance is inflated to ``σ_a² +
  ((‖a‖ − g)² + f ℓ²)/g²``, since a linear acceleration that changes the norm by ``d`` tilts
  the direction by at least about ``d/g`` rad, and one perpendicular to gravity tilts it
  without changing the norm: ``ℓ²`` is the low-pass (``acc_disturbance_tau_s``) of
  ``(‖a‖ − g)²`` over received samples, the recent linear-acceleration level, and ``f`` is
  ``acc_disturbance_factor`` (an adaptive measurement noise; VQF instead low-passes the
  earth-frame specific force, which the leaky velocity below does).  Rejecting outright far from ``g`` (rather than
  only inflating) keeps impacts and fast swings out of the tilt, which under loss matters
  more than usual: after a gap the gain is large and one bad sample would be taken almost
  whole.  Fusion rejects by the angle between measured and estimated gravity instead; that
  angle is also large after a gap, when the measurement is most needed, so we gate on what
  the sensor shows regardless of the estimate.
* Magnetometer: VQF's magnetic disturbance detection (Laidig & Seel 2023, Sec. 3.4; its
  parameters ``magNormTh``, ``magDipTh``, ``magRefTau``, ``magNewTime``, ``magNewMinGyr``,
  ``magMaxRejectionTime``, ``magRejectionFactor`` with the same defaults): the field is used
  only while its norm is within ``mag_norm_gate`` (relative) and its dip angle within
  ``mag_dip_gate + mag_dip_tilt_sigmas · σ_tilt`` (``σ_tilt² = max(P_00, P_11)``: the dip is
  seen through the estimated tilt, so an uncertain tilt, e.g. after a gap, must not reject an
  undisturbed field; VQF has no tilt covariance and uses the fixed threshold) of a reference
  that is learned online (set from the first received sample, then low-pass filtered on
  accepted samples); a new field that stays consistent for ``mag_new_time_s`` while the
  sensor turns faster than ``mag_new_min_rate`` becomes the new reference; after
  ``mag_max_rejection_s`` of rejection the field is used again with its variance multiplied
  by ``mag_rejection_factor²`` (VQF divides its gain by the factor).  Timers count received
  samples (time the sensor was observed).  The heading measured through a tilt error ε is
  off by up to ``tan(dip) · ε``, so the heading variance is ``σ_m² + tan²(dip_ref) σ_tilt²``
  (``|dip_ref|`` capped at 1.5 rad).
* Magnetometer, hard iron (a magnet or ferrous part fixed to the sensor, BROAD trials 33–36):
  the field is ``m = Rᵀ m_E + b_m`` with a constant body-frame ``b_m``; the gyroscope makes
  ``b_m`` observable without any orientation, ``ṁ + ω × m = ω × b_m``, and an exponentially
  forgotten least-squares estimate (``mag_hard_iron_tau_s``) is subtracted before the gate when
  it is large (``mag_hard_iron_min_bias``) and brings the norm closer to the reference
  (:func:`~._kalman_update_kernels.kalman_hard_iron`).  Without it such a field fails the norm gate
  for as long as the magnet stays, and the heading runs on the gyroscope alone.

Initialisation: with ``q0=None`` each batch element starts at its first received sample from
TRIAD (``mag`` given) or the tilt (no ``mag``, zero heading), as Madgwick's filter in wsnlib
does; that sample only initialises.  Output before it: the initial estimate.

Gap options (the vocabulary of :mod:`wsnlib.orientation`): ``gap`` is the rate the prediction
turns by in a gap — ``"ar"`` (default) the linear prediction above, ``"constant_rate"`` the last
received bias-corrected rate, decaying with ``gap_time_constant`` (default
:data:`KALMAN_GAP_TIME_CONSTANT_S`), ``"hold"`` none (the state stays; the covariance still
grows); ``replay`` (default on) the gap replay above; ``output_on_lost`` ``"estimate"``
(default: the prediction) or ``"hold"`` (the previous output; the state still predicts).

Implementation: :class:`KalmanSettings` and its defaults are in
:mod:`wsnlib.orientation.kalman_settings` (re-exported here).  The arithmetic is numba
(cached), one function per step above: the prediction :func:`~._kalman_kernels.kalman_predict`;
the updates :func:`~._kalman_update_kernels.kalman_correct` (accelerometer),
:func:`~._kalman_update_kernels.kalman_correct_mag`, :func:`~._kalman_update_kernels.kalman_scalar_update`,
:func:`~._kalman_update_kernels.kalman_inject`; the gap's linear prediction in
:mod:`~._gap_rate_kernels`; the settings vector in :mod:`~._kalman_layout` — and the loop
:func:`~._kalman_kernels.kalman_stream` (also the forward pass of
:func:`wsnlib.orientation.smooth_orientation`); a batch runs in parallel over its flattened
elements (:func:`~._kalman_kernels.run_kalman`).  The argument checks are Madgwick's
(:mod:`wsnlib.orientation._batch`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib.orientation import _batch as B
from wsnlib.orientation._kalman_kernels import KALMAN_VARIANCES, NX, kalman_settings_vector, run_kalman
from wsnlib.orientation.kalman_settings import KalmanSettings
from wsnlib.orientation.triad import tilt_quaternion, triad

# ==========================================================================================
# Input checks (outside the kernels) and the public function
# ==========================================================================================


@dataclass(frozen=True)
class KalmanInputs:
    """Checked inputs of :func:`kalman_orientation` / :func:`smooth_orientation`, flattened.

    ``gyr``, ``acc``, ``mag`` ``(M, T, 3)`` (``mag`` a dummy ``(1, 1, 3)`` without
    magnetometer), ``received`` ``(M', T)``, ``index`` ``(N, 4)`` rows read by batch element
    ``n``, ``q_init`` ``(N, 4)``, ``start`` ``(N,)``, ``init_only``, ``batch`` (the output's
    leading shape), ``n_t``.
    """

    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    has_mag: bool
    received: np.ndarray
    index: np.ndarray
    q_init: np.ndarray
    start: np.ndarray
    init_only: bool
    batch: tuple
    n_t: int


def prepare_inputs(gyr, acc, mag, received, q0) -> KalmanInputs:
    """Check the arguments with Madgwick's checks (:mod:`._batch`) and flatten them.

    ``ValueError`` naming the argument, as :func:`wsnlib.orientation.madgwick`: lost samples
    are never read (they may hold NaN); received ones must be finite, ``acc`` and ``mag``
    non-zero; with ``q0=None`` every batch element must receive a sample.
    """
    signals, mask, q0, shapes = B.check_inputs(gyr, acc, mag, received, q0)
    n_t = signals["gyr"].shape[-2]
    if mask is None:
        mask = np.ones(n_t, dtype=bool)
    shapes["received"] = mask.shape[:-1]
    batch = B.broadcast_batch(shapes)
    if q0 is None and n_t == 0:
        raise ValueError("no samples (T = 0): pass q0 to define the output")
    if n_t:
        B.check_usable(signals, mask)
    if q0 is None:
        B.check_has_sample(mask, batch)
    has_mag = mag is not None
    rows = {name: B.index_into(arr.shape[:-2], batch) for name, arr in signals.items()}
    index = np.stack([rows["gyr"], rows["acc"], rows["mag"] if has_mag else np.zeros_like(rows["gyr"]),
                      B.index_into(mask.shape[:-1], batch)], axis=-1)
    flat = {name: B.flat(arr, 2) for name, arr in signals.items()}
    flat_mask = B.flat(mask, 1)
    if q0 is None:  # start at the first received sample, from TRIAD (or the tilt)
        start = flat_mask.argmax(axis=-1)[index[:, 3]].astype(np.int64)
        acc0 = flat["acc"][index[:, 1], start]
        q_init = triad(acc0, flat["mag"][index[:, 2], start]) if has_mag else tilt_quaternion(acc0)
    else:
        q_init = np.broadcast_to(q0, batch + (4,)).reshape(-1, 4)
        start = np.zeros(index.shape[0], dtype=np.int64)
    return KalmanInputs(
        gyr=flat["gyr"], acc=flat["acc"], mag=flat["mag"] if has_mag else np.ones((1, 1, 3)), has_mag=has_mag,
        received=flat_mask, index=index, q_init=np.ascontiguousarray(q_init, dtype=float), start=start,
        init_only=q0 is None, batch=tuple(batch), n_t=n_t,
    )


#: ``gap_time_constant`` (s) of the Kalman filter and the smoother when None: chosen most often by
#: leave-one-trial-out from {inf, 0.2} (17 BROAD trials, GE 10 %); with ``gap="ar"`` it acts only
#: where the linear prediction falls back (less than a window of rates before the gap).
KALMAN_GAP_TIME_CONSTANT_S = 0.2


def settings_vector(settings, fs, *, gap, replay, gap_time_constant, filter_name) -> np.ndarray:
    """Checked ``settings`` (None: defaults), ``fs`` and gap options as the kernels' settings vector."""
    fs = B.check_fs(fs)
    if settings is None:
        settings = KalmanSettings()
    if not isinstance(settings, KalmanSettings):
        raise ValueError(f"settings must be a KalmanSettings, got {type(settings).__name__}")
    gap, gap_time_constant = B.check_gap(gap, gap_time_constant, filter_name, supported=B.GAPS)
    replay = B.check_flag(replay, "replay")
    tau = KALMAN_GAP_TIME_CONSTANT_S if gap_time_constant is None else gap_time_constant
    vector = kalman_settings_vector(settings, 1.0 / fs, gap, replay, tau)
    variances = vector[list(KALMAN_VARIANCES)]
    if not (np.all(np.isfinite(variances)) and np.all(variances > 0.0)):
        raise ValueError(f"fs = {fs!r} Hz with these settings gives noise variances that are not finite and > 0")
    return vector


def check_finite_output(quat: np.ndarray) -> np.ndarray:
    """Raise instead of returning NaN (extreme settings or ``fs`` can overflow in the kernel)."""
    if not np.all(np.isfinite(quat)):
        raise ValueError("the filter produced NaN/inf: fs or the settings are too extreme for double precision")
    return quat


@dataclass(frozen=True)
class KalmanOutput:
    """Everything :func:`kalman_orientation` computes (``full_output=True``).

    Attributes
    ----------
    quat : numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth).
    gyro_bias : numpy.ndarray, shape (..., T, 3)
        Estimated gyroscope bias (rad/s, body frame) after each sample.
    covariance : numpy.ndarray, shape (..., T, 9, 9)
        Error covariance after each sample, order ``[δθ_x, δθ_y, δθ_z, δb_x, δb_y, δb_z,
        δv_x, δv_y, δv_z]``: δθ the attitude error in the earth frame (rad; x, y tilt, z
        heading), δb the bias error (rad/s), δv the leaky velocity's error (m/s, earth frame).
    acc_used, mag_used : numpy.ndarray of bool, shape (..., T)
        Whether the sample's accelerometer / magnetometer passed the gates and was used.
    """

    quat: np.ndarray
    gyro_bias: np.ndarray
    covariance: np.ndarray
    acc_used: np.ndarray
    mag_used: np.ndarray


def kalman_orientation(gyr, acc, mag=None, *, fs: float, received=None, q0=None, settings=None, gap: str = "ar",
                       replay: bool = True, output_on_lost: str = "estimate", gap_time_constant=None,
                       full_output: bool = False):
    """Gap-aware error-state Kalman filter (MEKF with gyro bias) over whole recordings, batched.

    See the module docstring for the equations and gates.  Over a gap the filter *predicts*:
    its state turns by a predicted rate (``gap``) and its covariance grows with the elapsed gap,
    so that the first received samples after a gap correct it strongly; with ``replay`` the gap
    is then re-run from the state at its start with rates that meet the first received one.

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s², +g up at rest), body frame.
    mag : array_like, shape (..., T, 3), optional
        Magnetic field, body frame (µT; any unit works, only its norm relative to the learned
        reference and its direction are used).  ``None``: no heading correction (heading from
        the gyroscope, zero at the start).
    fs : float
        Sampling rate (Hz), in [1e-6, 1e9]; Δt = 1/fs, lost samples included.
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all.
    q0 : array_like, shape (4,) or (..., 4), optional
        ENU estimate before the first sample (prior std ``settings.initial_*_sigma``); every
        received sample then updates it.  ``None``: each batch element starts at its first
        received sample, from TRIAD (or the tilt without ``mag``); that sample only
        initialises, and the output before it is that initial estimate.
    settings : KalmanSettings, optional
        Noise levels, gates and the "ar" prediction's order and window; default
        ``KalmanSettings()`` (tuned on BROAD, see there).
    gap : {"ar", "constant_rate", "hold"}
        The rate the state turns by in a gap (the vocabulary of :mod:`wsnlib.orientation`).
        ``"ar"`` (default): the linear (autoregressive) prediction fitted at the gap's start on
        the last ``settings.gap_rate_prediction_window_s`` of rates (module docstring); an
        arm's swing is a damped oscillation, which a short linear predictor follows for a
        fraction of a period, while a held or decaying rate overshoots it.  Its norm is capped
        at the window's largest; it falls back to ``"constant_rate"`` when fewer than a window
        of rates precede the gap, or when the window holds fewer than
        ``3 × gap_rate_prediction_order`` samples at this ``fs``.  (On gaps of 18 samples cut
        into the 17 shared BROAD trials, starting from the true orientation, order 8 on 1 s
        gives a mean error at the gap's end of 34° against 47° for the rate decaying with
        0.2 s; chosen by every fold of leave-one-trial-out against ``"constant_rate"``.)
        ``"constant_rate"``: the last received bias-corrected rate, decaying with
        ``gap_time_constant``.  ``"hold"``: no rotation (the covariance still grows).
    replay : bool
        When the first sample after a gap arrives, re-integrate the state over the gap from
        the state at its start (module docstring, "Gap replay"): with ``"ar"`` the predicted
        rates plus a ramp that brings the prediction at the first received sample onto the
        measured rate, otherwise the rate linear between both ends (paper 001's gyroscope
        interpolation applied to the state).  Causal: the lost samples were already output;
        only the state from the gap's end on changes.  Default True (chosen most often by
        leave-one-trial-out from {True, False}).
    output_on_lost : {"estimate", "hold"}
        What is output on a lost sample: the filter's prediction (default), or the previous
        output (the paper's receiver; the state still predicts inside, so the output from
        the first sample after the gap on is the same for both).
    gap_time_constant : float, optional
        Time constant (s) with which the ``"constant_rate"`` rate (and the ``"ar"`` fall-back)
        decays to 0 in a gap; ``inf`` keeps it constant; None:
        :data:`KALMAN_GAP_TIME_CONSTANT_S`.  Not with ``gap="hold"``.
    full_output : bool
        Return a :class:`KalmanOutput` (quaternions, bias, covariance, gate decisions)
        instead of the quaternions alone.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4), or KalmanOutput
        ENU unit quaternions (body → earth); ``...`` is the broadcast of the leading
        dimensions of the signals, ``received`` and ``q0``.  (With ``output_on_lost="hold"``
        only ``quat`` is held; bias and covariance are the filter's state.)

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, NaN/inf (or a zero ``acc``/``mag`` vector) in a received sample, a
        non-boolean ``received``, ``fs`` outside [1e-6, 1e9], a zero ``q0``, a batch element
        with nothing received when ``q0`` is None, settings that are not a
        :class:`KalmanSettings`, an unknown ``gap`` or ``output_on_lost``, a non-boolean
        ``replay``, a ``gap_time_constant`` <= 0 or with ``gap="hold"``; or a result that is
        not finite.
    MemoryError
        At once, with the size, if the outputs would not fit in memory.
    """
    s = settings_vector(settings, fs, gap=gap, replay=replay, gap_time_constant=gap_time_constant,
                        filter_name="kalman_orientation")
    hold_output = B.check_output_on_lost(output_on_lost)
    inputs = prepare_inputs(gyr, acc, mag, received, q0)
    n_batch, n_t, batch = inputs.index.shape[0], inputs.n_t, inputs.batch
    n_floats = 4 + 3 + 3 + (NX * NX if full_output else 0)  # quaternion, bias, velocity, covariance
    B.check_memory((8 * n_floats + 2) * n_t * n_batch, f"kalman_orientation's output for batch {batch}, T = {n_t}")
    out_q = np.empty((n_batch, n_t, 4))
    out_bias = np.empty((n_batch, n_t, 3))
    out_vel = np.empty((n_batch, n_t, 3))
    out_P = np.empty((n_batch if full_output else 1, n_t if full_output else 1, NX, NX))
    acc_used = np.empty((n_batch, n_t), dtype=bool)
    mag_used = np.empty((n_batch, n_t), dtype=bool)
    run_kalman(inputs.gyr, inputs.acc, inputs.mag, inputs.has_mag, inputs.received, inputs.index, inputs.q_init,
               inputs.start, inputs.init_only, s, out_q, out_bias, out_vel, out_P, full_output, acc_used, mag_used)
    quat = check_finite_output(out_q.reshape(batch + (n_t, 4)))
    if hold_output:
        B.hold_lost_output(quat, received)
    if not full_output:
        return quat
    return KalmanOutput(quat=quat, gyro_bias=out_bias.reshape(batch + (n_t, 3)),
                        covariance=out_P.reshape(batch + (n_t, NX, NX)), acc_used=acc_used.reshape(batch + (n_t,)),
                        mag_used=mag_used.reshape(batch + (n_t,)))
