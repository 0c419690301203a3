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
  last one under the fitted model (:func:`~wsnlib.orientation.gaps.ar_end_weights`: a linear
  ramp for a slowly varying rate, following the oscillation for a swing); without it,
  ``ω_k`` is linear between the bias-corrected rates before and after the gap (paper 001's
  gyroscope interpolation applied to the state).  Causal: the lost samples were already
  output as the extrapolation; ``P`` keeps the gap's growth.
* **Accelerometer (tilt) update**: ``e = R(q⁻) a/‖a‖`` should be earth up ``e_z``; the
  measured tilt error is the rotation taking ``e`` onto ``e_z``,
  ``φ = atan2(‖e × e_z‖, e·e_z) · (e × e_z)/‖e × e_z‖`` (exact for large errors, e.g. after a
  gap), and ``φ_x = δθ_x``, ``φ_y = δθ_y`` (two scalar updates, ``H = e_0ᵀ, e_1ᵀ``).
* **Velocity pseudo-measurement** (every received sample, after the tilt update, before the
  injection: the accelerometer's updates are one sensor's): ``v = 0`` with noise variance
  ``σ_v²/Δt`` (three scalar updates, ``H = e_6ᵀ, e_7ᵀ, e_8ᵀ``, innovation ``−v̂_i − δv_i``).  A tilt
  error ``δθ`` makes ``v̂`` ramp by ``g δθ Δt`` per sample,
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
* **Injection** after each sensor (accelerometer: tilt and velocity; magnetometer):
  ``q ← Exp(δθ) ⊗ q``, ``b ← b + δb`` (clipped), ``v̂ ← v̂ + δv``, ``δx ← 0``
  (the covariance reset Jacobian is taken as the identity, as usual for small δθ).

Gates (where they come from)
----------------------------
* Accelerometer, hard: used only if ``|‖a‖ − g| ≤ acc_norm_gate`` and ``‖ω − b̂‖ ≤
  acc_rate_gate``.  Soft: inside the gate the noise variance is inflated to ``σ_a²/Δt +
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
  that is learned online: set from the first received sample, then low-pass filtered on
  accepted samples, and the norm gate's own reference follows every field whose dip passes
  (``mag_norm_tau_s``; after a gap of ``L`` samples, in which it could not follow, the norm
  tolerance is ``mag_norm_gate · (1 + LΔt/mag_norm_tau_s)``, so the same drift rate passes as
  without a gap); a new field that stays consistent for ``mag_new_time_s`` while the
  sensor turns faster than ``mag_new_min_rate`` becomes the new reference — or for
  ``mag_new_first_time_s``, turning or not, while the reference has not yet been confirmed by
  that long of undisturbed fields (so a recording that starts in motion or in a disturbance
  does not keep the gates of its first sample); after
  ``mag_max_rejection_s`` of rejection the field is used again with its variance multiplied
  by ``mag_rejection_factor²`` (VQF divides its gain by the factor).  Timers count received
  samples (time the sensor was observed).  The heading measured through a tilt error ε is
  off by up to ``tan(dip) · ε``, so the heading variance is ``σ_m²/Δt + tan²(dip_ref) σ_tilt²``
  (``|dip_ref|`` capped at 1.5 rad).
* Magnetometer, lag (a sensor's own filter or sampling delay δ behind the gyroscope; BROAD's
  ~10 ms on every trial): a field read δ late is off by ``ω δ`` in a turn (3° at 5 rad/s and
  10 ms).  Two consecutive received samples give ``ṁ + ω × m ≈ δ ω̇ × m``; a scalar
  least-squares estimate with a long memory (``mag_lag_tau_s``) advances every field by
  ``−δ̂ ω × m`` before the hard-iron estimate and the gates (:func:`~._kalman_kernels.mag_lag`;
  ``mag_lag_max_s=0`` switches it off).
* Magnetometer, hard iron (a magnet or ferrous part fixed to the sensor, BROAD trials 33–36):
  the field is ``m = Rᵀ m_E + b_m`` with a constant body-frame ``b_m``; the gyroscope makes
  ``b_m`` observable without any orientation, ``ṁ + ω × m = ω × b_m``, and an exponentially
  forgotten least-squares estimate (``mag_hard_iron_tau_s``) is subtracted before the gate when
  it is large (``mag_hard_iron_min_bias``) and brings the norm closer to the reference,
  makes it steadier (a low-pass of the squared norm step, ``mag_hard_iron_tau_s``: the
  earth's field keeps its norm while the sensor turns, whatever a drifting strength does to
  the reference) or explains more of ``ṁ + ω × m`` than it leaves, the field's white noise
  aside (the same sums, and that of consecutive residuals' products, which sets the noise
  apart; counted while what is left beyond the noise is three standard deviations above
  chance; a magnet the data show, while the reference norm lags a drifting gain and the
  estimate still settles) (:func:`~._kalman_kernels.hard_iron`).  Without it such a field
  fails the norm gate for as long as the magnet stays, and the heading runs on the gyroscope
  alone.

Initialisation: with ``q0=None`` each batch element starts at its first received sample from
TRIAD (``mag`` given) or the tilt (no ``mag``, zero heading), as Madgwick's filter in wsnlib
does; that sample only initialises.  Output before it: the initial estimate.

Gap options (the vocabulary of :mod:`wsnlib.orientation`): ``gap`` is the rate the prediction
turns by in a gap — ``"ar"`` (default) the linear prediction above, ``"constant_rate"`` the last
received bias-corrected rate, decaying with ``gap_time_constant`` (default
:data:`KALMAN_GAP_TIME_CONSTANT_S`), ``"hold"`` none (the state stays; the covariance still
grows); ``replay`` (default on) the gap replay above; ``output_on_lost`` ``"estimate"``
(default: the prediction) or ``"hold"`` (the previous output; the state still predicts).

Implementation, in three files: :class:`KalmanSettings`, its defaults and the per-sample
constants the compiled step reads (``constants.gyro_var``) are in
:mod:`wsnlib.orientation.kalman_settings`; the compiled step on a named state (``state.bias``,
``state.P``) is :mod:`._kalman_kernels` — one function per step above: :func:`~._kalman_kernels.predict`,
:func:`~._kalman_kernels.correct_acc`, :func:`~._kalman_kernels.mag_lag`, :func:`~._kalman_kernels.hard_iron`,
:func:`~._kalman_kernels.correct_mag`, :func:`~._kalman_kernels.scalar_updates`,
:func:`~._kalman_kernels.heading_update` (both leave P's change as products, which
:func:`~._kalman_kernels.subtract_products` applies once per sample),
:func:`~._kalman_kernels.inject`, one sample :func:`~._kalman_kernels.kalman_step`, the loop
:func:`~._kalman_kernels.kalman_stream` (also the forward pass of
:func:`wsnlib.orientation.smooth_orientation`; a batch runs it on numba's threads side by side,
:func:`wsnlib.orientation._batch.in_threads`) (speed by structure: ``predict`` propagates only the
non-zero blocks of F, written as two shears ``F = F_v F_θ``, and every measurement update is a
sequence of scalar ones, those of one sensor in one pass over P, with one injection); this module
holds the public functions
(:func:`kalman_orientation` over recordings, :func:`kalman_step` on a :class:`KalmanState` one
sample at a time) and :class:`KalmanReference`, the same equations as numpy matrices.  What
happens in a gap (the rates, the replay) is :mod:`wsnlib.orientation.gaps`, shared with
Madgwick's filter.  The argument checks are Madgwick's (:mod:`wsnlib.orientation._batch`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib import quaternion as Q
from wsnlib._user_warnings import warn_user
from wsnlib._validation import check_flag
from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kalman_kernels as K
from wsnlib.orientation import gaps
from wsnlib.orientation._kalman_kernels import NX
from wsnlib.orientation.kalman_settings import MAG_LAG_RIDGE, KalmanSettings, gap_prediction_order, kalman_constants
from wsnlib.orientation.triad import tilt_quaternion, triad
from wsnlib.plausibility import magnetometer_problem

# ==========================================================================================
# Input checks (outside the kernels) and the public function
# ==========================================================================================


@dataclass(frozen=True)
class KalmanInputs:
    """Checked inputs of :func:`kalman_orientation` / :func:`smooth_orientation`, flattened.

    ``gyr``, ``acc``, ``mag`` ``(M, T, 3)`` (``mag`` a dummy ``(1, 1, 3)`` without
    magnetometer), ``received`` ``(M', T)``, ``index`` ``(N, 4)`` rows read by batch element
    ``n``, ``q_init`` ``(N, 4)``, ``start`` ``(N,)``, ``init_only``, ``batch`` (the output's
    leading shape), ``n_t``; ``treated_as_lost`` ``(..., T)`` bool, the received samples whose
    reading no sensor can give (:func:`wsnlib.plausibility.implausible_samples`), run as lost.
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
    treated_as_lost: np.ndarray


def prepare_inputs(gyr, acc, mag, received, q0, gravity: float) -> KalmanInputs:
    """Check the arguments with Madgwick's checks (:mod:`._batch`) and flatten them.

    ``ValueError`` naming the argument, as :func:`wsnlib.orientation.madgwick`: lost samples
    are never read (they may hold NaN); received ones must be finite, ``acc`` and ``mag``
    non-zero; with ``q0=None`` every batch element must receive a sample; the recording must be
    plausible with the settings' ``gravity`` (m/s², :func:`wsnlib.plausibility.check_imu_plausible`).
    """
    signals, mask, q0, shapes = B.check_inputs(gyr, acc, mag, received, q0)
    n_t = signals["gyr"].shape[-2]
    batch = B.broadcast_batch(shapes)
    if q0 is None and n_t == 0:
        raise ValueError("no samples (T = 0): pass q0 to define the output")
    given = mask
    if n_t:
        mask = B.check_usable(signals, mask, gravity)
        problem = None if mag is None else magnetometer_problem(signals["mag"], mask)
        if problem:
            warn_user(f"{problem}; the filter's magnetometer gates will reject it, and the heading then rests "
                      f"on the gyroscope alone")
    if q0 is None:
        B.check_has_sample(mask, batch)
    has_mag = mag is not None
    rows = {name: B.index_into(arr.shape[:-2], batch) for name, arr in signals.items()}
    index = B.kernel_input(np.stack([rows["gyr"], rows["acc"], rows["mag"] if has_mag else np.zeros_like(rows["gyr"]),
                                     B.index_into(mask.shape[:-1], batch)], axis=-1))
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
        gyr=flat["gyr"], acc=flat["acc"], mag=flat["mag"] if has_mag else B.flat(np.ones((1, 1, 3)), 2),
        has_mag=has_mag, received=flat_mask, index=index, q_init=B.kernel_input(np.asarray(q_init, dtype=float)),
        start=B.kernel_input(start),
        init_only=q0 is None, batch=tuple(batch), n_t=n_t, treated_as_lost=given & ~mask,
    )


#: ``gap_time_constant`` (s) of the Kalman filter and the smoother when None: chosen most often by
#: leave-one-trial-out from {inf, 0.2} (17 BROAD trials, GE 10 %); with ``gap="ar"`` it acts only
#: where the linear prediction falls back (less than a window of rates before the gap).
KALMAN_GAP_TIME_CONSTANT_S = 0.2


#: Constants that are variances (must be finite and > 0 at the chosen ``fs``) → the setting each squares.
_VARIANCES = {"gyro_var": "gyro_noise", "bias_var": "bias_noise", "acc_var": "acc_noise_density",
              "mag_var": "mag_noise_density", "vel_var": "velocity_noise_density",
              "init_vel_var": "initial_velocity_sigma", "acc_sensor_var": "velocity_random_walk",
              "gap_acc_var": "gap_acc_noise"}


def constants(settings, fs, *, gap, replay, gap_time_constant, has_mag, filter_name, record=False) -> np.ndarray:
    """Checked ``settings`` (None: defaults), ``fs`` and gap options as the compiled step's constants."""
    fs = B.check_fs(fs)
    if settings is None:
        settings = KalmanSettings()
    if not isinstance(settings, KalmanSettings):
        raise ValueError(f"settings must be a KalmanSettings, got {type(settings).__name__}")
    gap, gap_time_constant = B.check_gap(gap, gap_time_constant, filter_name, supported=B.GAPS)
    replay = check_flag(replay, "replay")
    tau = KALMAN_GAP_TIME_CONSTANT_S if gap_time_constant is None else gap_time_constant
    c = kalman_constants(settings, 1.0 / fs, gap=gaps.GAP_CODES[gap], replay=replay, gap_time_constant=tau,
                         has_mag=has_mag, record=record)
    bad = [field for name, field in _VARIANCES.items() if not (np.isfinite(c[name][0]) and c[name][0] > 0.0)]
    if bad:
        listed = ", ".join(f"{field}={getattr(settings, field)!r}" for field in bad)
        raise ValueError(f"KalmanSettings {listed} at fs = {fs!r} Hz gives a noise variance that is not finite and > 0 "
                         f"(it underflows or overflows double precision)")
    return c


#: Above this fraction of received samples with the magnetometer rejected, :func:`kalman_orientation` warns.
MAG_REJECTED_FRACTION = 0.5
#: A magnetometer rejected for longer than this (s) is counted (``KalmanOutput.long_mag_rejections``) and warned of.
MAG_LONG_REJECTION_S = 10.0


def long_mag_rejections(mag_used: np.ndarray, received: np.ndarray, fs: float) -> np.ndarray:
    """Per row of ``mag_used``/``received`` (N, T): how many times the magnetometer stayed rejected on
    every received sample for longer than :data:`MAG_LONG_REJECTION_S` (lost samples inside do
    not end a rejection; its length runs from its first to its last rejected sample), counted in
    one compiled pass (:func:`._kalman_kernels.long_rejections`)."""
    counts = np.zeros(mag_used.shape[0], dtype=np.int64)
    K.long_rejections(B.kernel_input(mag_used), B.kernel_input(received), float(fs), MAG_LONG_REJECTION_S, counts)
    return counts


def _warn_if_magnetometer_unused(mag_used: np.ndarray, received: np.ndarray, long_rejections: np.ndarray,
                                 settings, fs: float) -> None:
    """One ``UserWarning`` per call when the magnetometer was rejected for longer than
    :data:`MAG_LONG_REJECTION_S` or, in recordings longer than three times ``mag_new_time_s``, on
    most received samples (a magnet fixed near the sensor, a saturated or frozen sensor, a field
    whose strength changes faster than ``mag_norm_tau_s`` follows): the heading then rests on
    the gyroscope."""
    n_received = np.count_nonzero(received)
    rejected = (n_received - np.count_nonzero(received & mag_used)) / max(n_received, 1)
    mostly = mag_used.shape[1] >= 3.0 * settings.mag_new_time_s * fs and rejected > MAG_REJECTED_FRACTION
    if long_rejections.any() or mostly:
        warn_user(f"the magnetometer was rejected on {rejected:.0%} of the received samples, "
                  f"{int(long_rejections.sum())} time(s) for longer than {MAG_LONG_REJECTION_S:g} s (saturated, "
                  f"frozen, a magnetic disturbance, or a field strength that drifts?): the heading rests on the "
                  f"gyroscope there; full_output's mag_used and long_mag_rejections say where")


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
    long_mag_rejections : numpy.ndarray of int, shape (...)
        How many times the magnetometer stayed rejected for longer than :data:`MAG_LONG_REJECTION_S`
        (:func:`long_mag_rejections`; also warned of, once per call).
    treated_as_lost : numpy.ndarray of bool, shape (..., T)
        Received samples with a reading no sensor can give (e.g. a gyro of 1e6 rad/s), run as lost.
    """

    quat: np.ndarray
    gyro_bias: np.ndarray
    covariance: np.ndarray
    acc_used: np.ndarray
    mag_used: np.ndarray
    long_mag_rejections: np.ndarray
    treated_as_lost: np.ndarray


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
        Noise levels, gates and the "ar" prediction's span and window; default
        ``KalmanSettings()`` (tuned on BROAD, see there).
    gap : {"ar", "constant_rate", "hold"}
        The rate the state turns by in a gap (the vocabulary of :mod:`wsnlib.orientation`).
        ``"ar"`` (default): the linear (autoregressive) prediction fitted at the gap's start on
        the last ``settings.gap_rate_prediction_window_s`` of rates (module docstring); an
        arm's swing is a damped oscillation, which a short linear predictor follows for a
        fraction of a period, while a held or decaying rate overshoots it.  Its norm is capped
        at the window's largest; it falls back to ``"constant_rate"`` when fewer than a window
        of rates precede the gap, or when the window holds fewer than three times the
        predictor's order (``gap_rate_prediction_span_s`` in samples at this ``fs``).  (On gaps of 18 samples cut
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
    settings = KalmanSettings() if settings is None else settings  # built once: each construction checks every field
    c = constants(settings, fs, gap=gap, replay=replay, gap_time_constant=gap_time_constant,
                  has_mag=mag is not None, filter_name="kalman_orientation")
    inputs = prepare_inputs(gyr, acc, mag, received, q0, settings.gravity)
    hold_output = B.check_output_on_lost(output_on_lost)
    n_batch, n_t, batch = inputs.index.shape[0], inputs.n_t, inputs.batch
    # quaternion, bias and covariance, and the rate history (a row per sample at most: a recording lost throughout)
    n_floats = 4 + (3 + NX * NX if full_output else 0) + 3
    B.check_memory((8 * n_floats + 2) * n_t * n_batch, f"kalman_orientation's output for batch {batch}, T = {n_t}")
    # Bias and P only when asked, the velocity never (else one dummy row: not written, no memory to touch)
    kept, kept_t = (n_batch, n_t) if full_output else (1, 1)
    outputs = (np.empty((n_batch, n_t, 4)), np.empty((kept, kept_t, 3)), np.empty((1, 1, 3)),
               np.empty((kept, kept_t, NX, NX)), np.empty((n_batch, n_t), dtype=bool),
               np.empty((n_batch, n_t), dtype=bool))
    no_records = K.new_records(0)
    per_element = [out.shape[0] == n_batch for out in outputs]  # else one dummy row for every element

    def run_one(n, _slot):
        i_gyr, i_acc, i_mag, i_rx = inputs.index[n]
        K.kalman_stream(inputs.gyr[i_gyr], inputs.acc[i_acc], inputs.mag[i_mag], inputs.received[i_rx],
                        inputs.q_init[n], inputs.start[n], inputs.init_only, c[0],
                        tuple(out[n if own else 0] for out, own in zip(outputs, per_element, strict=True))
                        + no_records)

    B.in_threads(run_one, n_batch)  # the streams side by side
    out_q, out_bias, _, out_P, acc_used, mag_used = outputs
    long_rejections = np.zeros(n_batch, dtype=np.int64)
    if inputs.has_mag:
        received_rows = inputs.received[inputs.index[:, 3]]
        long_rejections = long_mag_rejections(mag_used, received_rows, fs)
        _warn_if_magnetometer_unused(mag_used, received_rows, long_rejections, settings, fs)
    quat = check_finite_output(out_q.reshape(batch + (n_t, 4)))
    if hold_output:
        B.hold_lost_output(quat, received)
    if not full_output:
        return quat
    return KalmanOutput(quat=quat, gyro_bias=out_bias.reshape(batch + (n_t, 3)),
                        covariance=out_P.reshape(batch + (n_t, NX, NX)), acc_used=acc_used.reshape(batch + (n_t,)),
                        mag_used=mag_used.reshape(batch + (n_t,)), long_mag_rejections=long_rejections.reshape(batch),
                        treated_as_lost=np.broadcast_to(inputs.treated_as_lost, batch + (n_t,)).copy())


# ==========================================================================================
# One sample at a time: the compiled step on a named state (a live receiver's filter)
# ==========================================================================================

class KalmanState:
    """One stream's filter between samples: named, copyable, advanced by :func:`kalman_step`.

    Attributes (read-only views; ``copy()`` for an independent state)
    ----------
    quat : numpy.ndarray (4,)
        ENU estimate (body → earth) after the last sample.
    gyro_bias : numpy.ndarray (3,)
        Gyroscope bias (rad/s, body frame).
    velocity : numpy.ndarray (3,)
        The leaky velocity (m/s, earth frame; module docstring).
    covariance : numpy.ndarray (9, 9)
        Error covariance, order ``[δθ, δb, δv]``.
    prediction : dict
        The last sample's prediction: ``quat`` (q⁻), ``gyro_bias``, ``velocity``, ``covariance``
        (P⁻) and ``transition`` (F), what an RTS smoother needs.
    started : bool
        Whether a sample has initialised the filter (with ``q0=None``, the first received one).
    record : numpy structured array
        The compiled step's whole state (:data:`wsnlib.orientation._kalman_kernels.STATE_DTYPE`:
        ``record["mag_ref_norm"]``, ``record["hard_iron"]``, …).
    """

    def __init__(self, constants, record, gap, history, work, started):
        self.constants, self.record, self.gap, self.history, self.work = constants, record, gap, history, work
        self.started = started

    quat = property(lambda self: self.record["q"][0])
    gyro_bias = property(lambda self: self.record["bias"][0])
    velocity = property(lambda self: self.record["velocity"][0])
    covariance = property(lambda self: self.record["P"][0])

    @property
    def prediction(self) -> dict:
        w, c = self.work[0], self.constants[0]
        F = np.empty((NX, NX))
        K.transition_matrix(w["R"], w["a_e"], c["vel_decay"], c["dt"], F)
        return {"quat": w["q_pred"], "gyro_bias": w["bias_pred"], "velocity": w["vel_pred"],
                "covariance": w["P_pred"], "transition": F}

    def copy(self) -> KalmanState:
        return KalmanState(self.constants, self.record.copy(), self.gap.copy(), self.history.copy(), self.work.copy(),
                           self.started)


def kalman_initial_state(*, fs: float, settings=None, q0=None, has_mag: bool = True, gap: str = "ar",
                         replay: bool = True, gap_time_constant=None) -> KalmanState:
    """The state before the first sample of a stream, for :func:`kalman_step`.

    Parameters as :func:`kalman_orientation`; ``has_mag``: whether samples will carry a
    magnetometer reading.  ``q0=None``: the first received sample initialises the filter (TRIAD,
    or the tilt without magnetometer) and is not filtered, as in :func:`kalman_orientation`.
    """
    c = constants(settings, fs, gap=gap, replay=replay, gap_time_constant=gap_time_constant, has_mag=has_mag,
                  filter_name="kalman_initial_state", record=True)
    record = np.zeros(1, K.STATE_DTYPE)
    start = np.array([1.0, 0.0, 0.0, 0.0]) if q0 is None else B.unit_quaternions(q0, "q0")
    if start.shape != (4,):
        raise ValueError(f"q0 must be one quaternion (4,), got shape {start.shape}")
    K.initial_state(record[0], c[0], start)
    window = int(c["ar_window"][0])
    history = np.zeros((gaps.history_length(window, int(np.ceil(gaps.LONGEST_AR_REPLAY_S * fs))), 3))
    gap_state = gaps.new_gap_state(int(c["gap"][0]), float(c["gap_factor"][0]), int(c["ar_order"][0]), window)
    return KalmanState(c, record, gap_state, history, np.zeros(1, K.WORK_DTYPE), started=q0 is not None)


def kalman_step(state: KalmanState, gyr, acc, mag=None, received: bool = True) -> KalmanState:
    """Advance ``state`` by one sample (in place; returns it): the compiled step of :func:`kalman_orientation`.

    ``gyr`` (rad/s), ``acc`` (m/s²), ``mag`` (µT; None when the state was made without one), body
    frame, shape (3,); ``received`` False for a lost sample (its values are not read).  The outputs
    equal :func:`kalman_orientation`'s on the same samples, sample by sample.
    """
    if not isinstance(state, KalmanState):
        raise ValueError(f"state must be a KalmanState (kalman_initial_state), got {type(state).__name__}")
    c = state.constants[0]
    received = check_flag(received, "received")
    signals = [np.zeros(3) if x is None else np.asarray(x, dtype=float) for x in (gyr, acc, mag)]
    if received:
        if (mag is None) == bool(c["has_mag"]):
            raise ValueError("mag must be given exactly when the state was made with has_mag=True")
        for name, x in zip(("gyr", "acc", "mag"), signals, strict=True):
            if x.shape != (3,) or not np.all(np.isfinite(x)):
                raise ValueError(f"{name} must be 3 finite numbers, got {x!r}")
    if not state.started:
        if received:  # the first received sample only initialises (q0=None)
            q = triad(signals[1], signals[2]) if c["has_mag"] else tilt_quaternion(signals[1])
            K.initial_state(state.record[0], c, q)
            gaps.gap_received(state.gap[0], state.history, (signals[0][0], signals[0][1], signals[0][2]))
            state.started = True
        return state
    K.kalman_step(state.record[0], state.gap[0], state.history, state.work[0], c, *signals, received,
                  np.empty((0, 4)))
    return state


# ==========================================================================================
# The same equations as matrices, in plain numpy (the reference the compiled step is checked against)
# ==========================================================================================


class KalmanReference:
    """The filter of this module's docstring written with numpy matrices ``F``, ``Q``, ``H``, ``K``.

    A reference to read beside the equations and to check the compiled step against (the tests
    require relative 1e-9 over 2,000 samples).  It is slow (one Python step per sample) and covers
    the whole filter except the online hard-iron estimate and the magnetometer's disturbance
    gate: it takes every field as undisturbed, and raises ``ValueError`` on a sample the compiled
    gate would reject (so a comparison never passes by accident).  The accelerometer's two tilt and
    three velocity scalar updates are written as one joint update (the same result: sequential
    scalar updates with ``H = e_iᵀ`` equal the joint update), followed by one injection.

    Use ``KalmanReference(settings, fs=…, q0=…, gap=…, replay=…)`` then ``step(gyr, acc, mag,
    received)`` per sample, or :meth:`run` over a recording.
    """

    def __init__(self, settings=None, *, fs: float, q0, gap: str = "ar", replay: bool = True,
                 gap_time_constant=None, first_rate=None):
        s = KalmanSettings() if settings is None else settings
        self.s, self.dt = s, 1.0 / fs
        self.gap, self.replay = gap, replay
        tau = KALMAN_GAP_TIME_CONSTANT_S if gap_time_constant is None else gap_time_constant
        self.decay = 0.0 if gap == "hold" else float(np.exp(-self.dt / tau))
        self.order, self.window = gap_prediction_order(s, self.dt), round(s.gap_rate_prediction_window_s * fs)
        self.q = np.asarray(q0, dtype=float)
        self.b, self.v = np.zeros(3), np.zeros(3)
        self.P = np.diag([s.initial_tilt_sigma**2] * 2 + [s.initial_heading_sigma**2] + [s.initial_bias_sigma**2] * 3
                         + [s.initial_velocity_sigma**2] * 3)
        self.rates = [] if first_rate is None else [np.asarray(first_rate, dtype=float)]  # the rate of every sample
        self.held, self.lost, self.gap_sigma, self.lin_var = np.zeros(3), 0, 0.0, 0.0
        self.q_last = self.q.copy()
        self.last_rate = self.rates[0] if self.rates else np.zeros(3)
        self.ref = None  # the magnetometer's reference norm and dip
        self.gate_norm = 0.0
        self.lag, self.lag_num, self.lag_den, self.lag_prev = 0.0, 0.0, 0.0, None  # the magnetometer's lag
        self.coef, self.largest = None, 0.0

    @staticmethod
    def _exp(v):
        return Q.from_rotation_vector(np.asarray(v, dtype=float))

    def _ar_fit(self):
        """Per axis, ridge least squares of ``ω[k] ≈ Σ_i c_i ω[k − p + i]`` over the last window."""
        x = np.array(self.rates[-self.window:])
        p = self.order
        coef = np.empty((3, p))
        for a in range(3):
            X = np.stack([x[k:k + p, a] for k in range(self.window - p)])
            A = X.T @ X
            A += gaps.AR_RIDGE * max(1.0, np.trace(A) / p) * np.eye(p)
            coef[a] = np.linalg.solve(A, X.T @ x[p:, a])
        return coef, float(np.max(np.linalg.norm(x, axis=1)))

    def _ar_predict(self):
        w = np.array([self.coef[a] @ np.array(self.rates[-self.order:])[:, a] for a in range(3)])
        norm = np.linalg.norm(w)
        return w * self.largest / norm if norm > self.largest else w

    def _end_weights(self, n):
        """``w_k`` (3, n): conditional expectation of the k-th prediction error given the n-th (gaps module)."""
        out = np.empty((3, n))
        for a in range(3):
            h = np.zeros(n)
            h[0] = 1.0
            for j in range(1, n):
                h[j] = sum(self.coef[a, i] * h[j - self.order + i] for i in range(self.order)
                           if j - self.order + i >= 0)
            out[a] = [sum(h[k - i] * h[n - i] for i in range(1, k + 1)) / np.sum(h**2) for k in range(1, n + 1)]
        return out

    def step(self, gyr, acc, mag, received: bool) -> np.ndarray:
        """One sample; returns the estimate (4,)."""
        dt = self.dt
        if received:
            omega = np.asarray(gyr, dtype=float) - self.b
            if self.replay and self.lost and len(self.rates) > self.lost:  # re-run the gap from its start
                n = self.lost
                if self.coef is not None:
                    gap_rates = np.array(self.rates[-n:])
                    error = omega - self._ar_predict()
                    rates = gap_rates + self._end_weights(n + 1)[:, :n].T * error
                else:
                    rates = [self.last_rate + k / (n + 1.0) * (omega - self.last_rate) for k in range(1, n + 1)]
                q = self.q_last
                for w in rates:
                    q = Q.normalize(Q.multiply(q, self._exp(w * dt)))
                self.q = q
            lost, self.lost = self.lost, 0
        else:
            if self.lost == 0:
                ar = self.gap == "ar" and len(self.rates) >= self.window and self.window >= 3 * self.order
                self.coef, self.largest = self._ar_fit() if ar else (None, 0.0)
                self.held = self.last_rate.copy()
            self.lost += 1
            if self.coef is not None:
                self.held = self._ar_predict()
            else:
                self.held = self.held * self.decay
            omega = self.held
        self.rates.append(omega.copy())
        self._predict(omega, acc, received)
        if received:
            self.last_rate = omega.copy()
            self._update(acc, mag, omega, lost)
            self.q_last = self.q.copy()
        return self.q

    def _predict(self, omega, acc, received):
        """``q⁻ = q ⊗ Exp(ω Δt)``, the leaky velocity, and ``P⁻ = F P Fᵀ + Q``."""
        s, dt = self.s, self.dt
        self.q = Q.normalize(Q.multiply(self.q, self._exp(omega * dt)))
        R = Q.to_scipy(self.q).as_matrix()
        c = float(np.exp(-dt / s.velocity_tau_s))
        a_e = R @ acc if received else np.zeros(3)
        self.v = c * self.v + ((a_e - [0.0, 0.0, s.gravity]) * dt if received else 0.0)
        cross = np.array([[0.0, -a_e[2], a_e[1]], [a_e[2], 0.0, -a_e[0]], [-a_e[1], a_e[0], 0.0]])  # [a_E]×
        F = np.eye(9)
        F[:3, 3:6] = -R * dt
        F[6:, :3] = -cross * dt
        F[6:, 3:6] = cross @ R * dt**2
        F[6:, 6:] = c * np.eye(3)
        Qn = np.diag([s.gyro_noise**2 * dt] * 3 + [s.bias_noise**2 * dt] * 3 + [s.velocity_random_walk**2 * dt] * 3)
        if not received:
            if self.lost == 1:
                self.gap_sigma = s.gap_rate_noise + s.gap_rate_relative_noise * np.linalg.norm(omega)
            Qn[:3, :3] += np.eye(3) * (self.gap_sigma * dt) ** 2 * (2 * self.lost - 1)
            Qn[6:, 6:] = np.eye(3) * (s.gap_acc_noise * dt) ** 2 * (2 * self.lost - 1)
        self.P = F @ self.P @ F.T + Qn
        self.F = F

    def _correct(self, H, innovation, r, heading_only=False):
        """``K = P Hᵀ S⁻¹`` (tilt rows zeroed for the heading), ``δx = K z``, Joseph-form ``P``, then the
        injection; ``r`` the noise variance of each measurement (one or one per row of H)."""
        noise = np.diag(np.broadcast_to(r, (H.shape[0],)))
        S = H @ self.P @ H.T + noise
        K = self.P @ H.T @ np.linalg.inv(S)
        if heading_only:
            K[:2] = 0.0
        dx = K @ innovation
        IKH = np.eye(9) - K @ H
        self.P = IKH @ self.P @ IKH.T + K @ noise @ K.T
        self.q = Q.normalize(Q.multiply(self._exp(dx[:3]), self.q))
        self.b = np.clip(self.b + dx[3:6], -self.s.bias_limit, self.s.bias_limit)
        self.v = self.v + dx[6:]

    def _update(self, acc, mag, omega, lost):
        s, dt = self.s, self.dt
        a_norm = np.linalg.norm(acc)
        dev = abs(a_norm - s.gravity)
        self.lin_var += -np.expm1(-dt / s.acc_disturbance_tau_s) * (dev**2 - self.lin_var)
        rows, z, noise = [6, 7, 8], list(-self.v), [s.velocity_noise_density**2 / dt] * 3  # the leaky velocity: v = 0
        if dev <= s.acc_norm_gate and np.linalg.norm(omega) <= s.acc_rate_gate:  # the tilt update
            e = Q.rotate(self.q, acc / a_norm)
            axis = np.cross(e, [0.0, 0.0, 1.0])
            norm = np.linalg.norm(axis)
            phi = (np.arctan2(norm, e[2]) * axis / norm)[:2] if norm > 0 else np.zeros(2)
            r = s.acc_noise_density**2 / dt + (dev**2 + s.acc_disturbance_factor * self.lin_var) / s.gravity**2
            H = np.eye(9)[:2]
            d2 = phi @ np.linalg.solve(H @ self.P @ H.T + r * np.eye(2), phi)
            if d2 > s.acc_innovation_gate:  # robust: the pull is bounded
                tilt_var = 0.5 * (self.P[0, 0] + self.P[1, 1])
                r = np.sqrt(d2 / s.acc_innovation_gate) * (tilt_var + r) - tilt_var
            rows, z, noise = [0, 1] + rows, list(phi) + z, [r, r] + noise
        self._correct(np.eye(9)[rows], np.array(z), np.array(noise))  # tilt and velocity: one update
        if mag is None:
            return
        mag = self._advanced_by_lag(np.asarray(mag, dtype=float), omega, lost)
        m_e = Q.rotate(self.q, mag)
        m_norm, dip = np.linalg.norm(mag), np.arctan2(-m_e[2], np.hypot(m_e[0], m_e[1]))
        tilt_var = max(self.P[0, 0], self.P[1, 1])
        gain = -np.expm1(-dt / s.mag_reference_tau_s)  # the reference follows accepted fields
        if self.ref is None:
            self.ref, self.gate_norm = [m_norm, dip], m_norm
        dip_consistent = abs(dip - self.ref[1]) < s.mag_dip_gate + s.mag_dip_tilt_sigmas * np.sqrt(tilt_var)
        norm_gate = s.mag_norm_gate * (1.0 + lost * dt / s.mag_norm_tau_s)  # the follower stood still in the gap
        if not (dip_consistent and abs(m_norm - self.gate_norm) < norm_gate * self.gate_norm):
            raise ValueError("the field looks disturbed: the reference covers undisturbed fields only")
        self.gate_norm += -np.expm1(-(lost + 1) * dt / s.mag_norm_tau_s) * (m_norm - self.gate_norm)
        self.ref = [self.ref[0] + gain * (m_norm - self.ref[0]), self.ref[1] + gain * (dip - self.ref[1])]
        r = s.mag_noise_density**2 / dt + np.tan(min(abs(self.ref[1]), 1.5)) ** 2 * tilt_var
        self._correct(np.eye(9)[2:3], np.array([np.arctan2(m_e[0], m_e[1])]), r, heading_only=True)

    def _advanced_by_lag(self, mag, omega, lost):
        """``m − δ̂ ω × m`` with the lag's estimate updated by this sample (``mag_lag_tau_s``)."""
        s, dt = self.s, self.dt
        if s.mag_lag_max_s == 0.0:
            return mag
        if self.lag_prev is not None and lost == 0:  # two consecutive received samples
            pm, pw = self.lag_prev
            mm = 0.5 * (mag + pm)
            y = (mag - pm) / dt + np.cross(0.5 * (omega + pw), mm)  # ≈ δ ω̇ × m
            g = np.cross((omega - pw) / dt, mm) / np.linalg.norm(mm)
            decay = np.exp(-dt / s.mag_lag_tau_s)
            self.lag_num = decay * self.lag_num + g @ y / np.linalg.norm(mm) * dt
            self.lag_den = decay * self.lag_den + g @ g * dt
            self.lag = float(np.clip(self.lag_num / (MAG_LAG_RIDGE + self.lag_den), -s.mag_lag_max_s, s.mag_lag_max_s))
        self.lag_prev = (mag.copy(), np.asarray(omega, dtype=float).copy())
        return mag - self.lag * np.cross(omega, mag)

    @classmethod
    def run(cls, gyr, acc, mag, received, *, fs: float, settings=None, gap: str = "ar", replay: bool = True,
            gap_time_constant=None) -> tuple[np.ndarray, np.ndarray]:
        """Over one recording ``(T, 3)`` from its first received sample (TRIAD, as ``q0=None``):
        the estimates ``(T, 4)`` and the last covariance (9, 9)."""
        received = np.asarray(received, dtype=bool)
        first = int(np.argmax(received))
        ref = cls(settings, fs=fs, q0=triad(acc[first], mag[first]) if mag is not None else tilt_quaternion(acc[first]),
                  gap=gap, replay=replay, gap_time_constant=gap_time_constant, first_rate=gyr[first])
        out = np.empty((len(gyr), 4))
        out[: first + 1] = ref.q
        for t in range(first + 1, len(gyr)):
            out[t] = ref.step(gyr[t], acc[t], None if mag is None else mag[t], bool(received[t]))
        return out, ref.P
