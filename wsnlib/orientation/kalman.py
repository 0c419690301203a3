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
  by default (``gap_rate_prediction``) a linear predictor (autoregressive, order ``p``, per
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
* **Gap replay** (``gap_replay``): at the first received sample after a gap of ``L`` samples
  the state at the gap's end is recomputed from the last received state ``q_s`` as
  ``q_s ⊗ Π_{k=1..L} Exp(ω_k Δt)``.  With the linear prediction, ``ω_k`` is the predicted
  rate plus ``w_k`` times the predictor's error at the received sample (measured − predicted),
  ``w_k`` the Gaussian conditional expectation of the k-th step's prediction error given the
  last one under the fitted model (:func:`~._kalman_kernels.gap_rate_end_weights`: a linear
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
  (:func:`~._kalman_kernels.kalman_hard_iron`).  Without it such a field fails the norm gate
  for as long as the magnet stays, and the heading runs on the gyroscope alone.

Initialisation: with ``q0=None`` each batch element starts at its first received sample from
TRIAD (``mag`` given) or the tilt (no ``mag``, zero heading), as Madgwick's filter in wsnlib
does; that sample only initialises.  Output before it: the initial estimate.

Gap (the ``gap`` argument, as for Madgwick's filter): the filter always predicts over a gap;
``gap="constant_rate"`` (default) outputs that prediction on lost samples, ``gap="hold"``
holds the previous output there (the state still predicts inside).

Implementation: the arithmetic is in :mod:`wsnlib.orientation._kalman_kernels` (numba, cached), one
function per step above — :func:`~._kalman_kernels.kalman_predict`, :func:`~._kalman_kernels.kalman_correct`
(accelerometer), :func:`~._kalman_kernels.kalman_correct_mag`, :func:`~._kalman_kernels.kalman_scalar_update`,
:func:`~._kalman_kernels.kalman_inject` — and the loop :func:`~._kalman_kernels.kalman_stream` (also the
forward pass of :func:`wsnlib.orientation.smooth_orientation`); a batch runs in parallel over
its flattened elements (:func:`~._kalman_kernels.run_kalman`).  The argument checks are Madgwick's
(:mod:`wsnlib.orientation._batch`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from wsnlib.orientation import _batch as B
from wsnlib.orientation._kalman_kernels import KALMAN_VARIANCES, NX, kalman_settings_vector, run_kalman
from wsnlib.orientation._kernels import run_hold_lost
from wsnlib.orientation.triad import tilt_quaternion, triad

# ==========================================================================================
# Settings
# ==========================================================================================


@dataclass(frozen=True)
class KalmanSettings:
    """Noise levels and gates of :func:`kalman_orientation` (and :func:`smooth_orientation`).

    Defaults: ``gap_replay``, ``acc_disturbance_factor``, ``gap_rate_prediction_order`` and
    ``gap_rate_prediction_window_s`` are the values chosen most often by leave-one-trial-out
    tuning (8 settings, as every peer: gap_replay ∈ {True, False} × acc_disturbance_factor ∈
    {4, 16} × (order, window) ∈ {(24, 3 s), (48, 6 s)}) on the 17 shared BROAD trials at 50 Hz
    under Gilbert–Elliott loss (10 %, mean burst 3 packets of 6 samples), see
    ``benchmarks/eval_loss_tolerance.py``; ``gap_rate_prediction`` (on) and
    ``acc_disturbance_factor`` > 0 were chosen by every fold in earlier runs of that script
    against the decaying rate (``gap_rate_prediction=False``) and 0, as were
    ``mag_hard_iron_min_bias``, ``gap_rate_relative_noise``, ``mag_noise``,
    ``mag_norm_gate``, ``gap_rate_decay_s``, ``velocity_noise``, ``acc_noise`` and
    ``gap_rate_noise`` (most often, with other grids); the other numbers are as documented
    per field.

    Attributes
    ----------
    gyro_noise : float
        Angular-rate white noise density σ_g (rad/s/√Hz): attitude variance grows by
        ``σ_g² Δt`` per sample.  Far above a MEMS datasheet (≈ 1e-4): at 50 Hz the
        first-order integration of real, fast motion dominates the error.  Default 0.002
        (best of 0.01 and 0.002 on the shared BROAD trials, lossless).
    bias_noise : float
        Gyroscope bias random walk σ_b (rad/s/√s).  Default 1e-4 (slow thermal drift).
    initial_bias_sigma : float
        Prior std of the bias (rad/s).  Default 0.5 °/s, VQF's ``biasSigmaInit``.
    bias_limit : float
        Each bias component is clipped to ±this (rad/s).  Default 2 °/s, VQF's ``biasClip``.
    initial_tilt_sigma, initial_heading_sigma : float
        Prior std (rad) of the initial estimate's inclination and heading.  Defaults 5° and
        20°: TRIAD on one sample is exact at rest, but its heading is off by tens of degrees
        near a disturbance or under acceleration (BROAD, notebook 05).
    acc_noise : float
        Std of the measured tilt error (rad) of an accepted accelerometer sample.  Default 0.4,
        chosen most often by LOTO from {0.05, 0.1, 0.2, 0.4} (eval_loss_tolerance.py, before
        the leaky velocity was added).
    mag_noise : float
        Std of the measured heading error (rad) of an accepted magnetometer sample.
        Default 0.2 rad, chosen most often by LOTO from {0.2, 0.5}.
    gap_rate_noise : float
        Std of the error of the extrapolated angular rate during a gap (rad/s).  Default 0.3,
        chosen most often by LOTO from {0.3, 1.0} (eval_loss_tolerance.py, before the leaky
        velocity was added).
    gap_rate_relative_noise : float
        Added to ``gap_rate_noise`` times the last received rate's norm (dimensionless): the
        faster the motion, the less the rate at the start of a gap says about the rest of it.
        Default 0.1, chosen most often by LOTO from {0.5, 0.1} (a larger value lets the first
        samples after a gap in fast motion over-correct).
    gap_rate_decay_s : float
        Time constant (s) with which the extrapolated rate decays to 0 during a gap; ``inf``
        keeps it constant.  Default 0.2 s, chosen most often by LOTO from {inf, 0.2}.
    gravity : float
        Norm of gravity (m/s²); default standard gravity.
    acc_norm_gate : float
        Accelerometer used only if ``|‖a‖ − g| ≤`` this (m/s²).  Default 0.2 g ≈ 1.96 m/s².
    acc_rate_gate : float
        Accelerometer used only if the bias-corrected rate is at most this (rad/s): fast
        rotation adds centripetal and tangential acceleration.  Default 10 rad/s.
    mag_norm_gate : float
        Relative norm tolerance.  Default 0.1 (VQF's ``magNormTh``), chosen most often by LOTO
        from {0.1, 0.05}.
    mag_dip_gate : float
        Dip angle tolerance (rad), VQF's ``magDipTh`` = 10°.
    mag_reference_tau_s : float
        Time constant (s) of the reference norm/dip low-pass, VQF's ``magRefTau`` = 20 s.
    mag_new_time_s : float
        Consistent time (s) after which a new field becomes the reference, VQF's
        ``magNewTime`` = 20 s.
    mag_new_min_rate : float
        Only time spent turning faster than this (rad/s) counts for ``mag_new_time_s``, VQF's
        ``magNewMinGyr`` = 20 °/s.
    mag_max_rejection_s : float
        After this long rejected (s) the field is used again, with inflated noise; VQF's
        ``magMaxRejectionTime`` = 60 s.
    mag_rejection_factor : float
        Noise std multiplier for fields used after ``mag_max_rejection_s``; VQF's
        ``magRejectionFactor`` = 2.
    velocity_tau_s : float
        Time constant τ_v (s) of the leaky velocity (module docstring).  Default 3 s, VQF's
        ``tauAcc``.
    velocity_noise : float
        Std σ_v (m/s) of the pseudo-measurement ``v_x = v_y = v_z = 0``.  Default 1.0, chosen
        most often by LOTO from {0.5, 1.0} (eval_loss_tolerance.py).
    acc_sensor_noise : float
        Accelerometer noise σ_s (m/s² per sample) in the leaky velocity's process noise.
        Default 0.05 (MEMS datasheet order at 50 Hz).
    gap_acc_noise : float
        Std (m/s²) of the unknown linear acceleration during a gap (velocity variance grows
        like ``(σ kΔt)²`` after ``k`` lost samples).  Default 5 m/s² (about half a g).
    mag_dip_tilt_sigmas : float
        The dip gate widens by this many tilt standard deviations.  Default 3.
    mag_hard_iron_tau_s : float
        Forgetting time constant (s) of the online hard-iron estimate (a magnet or iron fixed
        to the sensor: a constant body-frame offset of the field, estimated from the gyroscope
        and the field's rate of change, see
        :func:`wsnlib.orientation._kalman_kernels.kalman_hard_iron`).  Default 3 s: about 150
        samples of rotation at 50 Hz average the differentiated field's noise down to ~1 µT,
        and a removed magnet is forgotten within seconds.
    mag_hard_iron_min_bias : float
        The estimate is subtracted only when its norm is at least this times the reference
        field norm (and the corrected norm is closer to the reference than the raw one);
        ``inf`` switches the correction off.  Default 0.1, the size ``mag_norm_gate`` would
        reject; chosen most often by LOTO from {0.1, inf}.
    gap_replay : bool
        When the first sample after a gap arrives, re-integrate the state over the gap from
        the last received state with the angular rate interpolated linearly between the rates
        before and after the gap (paper 001's gyroscope interpolation applied to the state;
        causal: the lost samples were already output as the extrapolation, only the state
        from the gap's end on changes).  Default True.  :func:`smooth_orientation` always
        runs its forward pass without it (its Hermite curve uses both ends instead, and the
        RTS pass needs the recorded predictions to be the filter's own).  Chosen most often
        by LOTO from {True, False}.
    gap_rate_prediction : bool
        Over a gap, predict the angular rate by linear prediction (an autoregressive model per
        axis, :func:`wsnlib.orientation._kalman_kernels.gap_rate_fit`) fitted at the gap's start
        on the rates of the last ``gap_rate_prediction_window_s``, instead of the last received
        rate decaying with ``gap_rate_decay_s``; with ``gap_replay`` the replay then uses these
        rates plus a linear ramp that brings the prediction at the first received sample onto
        the measured rate.  An arm's swing is a damped oscillation, which a short linear
        predictor follows for a fraction of a period, while a held or decaying rate overshoots
        it.  The predicted rate's norm is capped at the window's largest.  Falls back to the
        decay when fewer than a window of rates precede the gap, or when the window holds
        fewer than ``3 × gap_rate_prediction_order`` samples at this ``fs``.  Default True
        (see the class's defaults; on gaps of 18 samples cut into the 17 shared BROAD trials,
        starting from the true orientation, order 8 on 1 s gives a mean error at the gap's end
        of 34° against 47° for the rate decaying with 0.2 s).
    gap_rate_prediction_order : int
        Order of the linear predictor (rates of the last this many samples), 1 to 64.
        Default 48 (LOTO, see the class's defaults).
    gap_rate_prediction_window_s : float
        Length (s) of the rate history the predictor is fitted on.  Default 6 s (LOTO, see
        the class's defaults): a long window averages the fit over many swings.
    acc_disturbance_factor : float
        Adaptive accelerometer noise: the tilt variance of an accepted sample is
        ``σ_a² + ((‖a‖ − g)² + acc_disturbance_factor · ℓ²)/g²`` with ``ℓ²`` the low-pass
        (time constant ``acc_disturbance_tau_s``) of ``(‖a‖ − g)²`` over received samples: a
        linear acceleration perpendicular to gravity hardly changes the norm but tilts the
        direction, and it comes in phases of motion, so the recent level says how far a
        sample that passes the norm gate may still be off.  ``0``: off.  Default 4 (LOTO, see
        the class's defaults).
    acc_disturbance_tau_s : float
        Time constant (s) of that low-pass.  Default 0.5 s (about one swing of the arm).
    acc_innovation_gate : float
        Beyond this normalised innovation ``d² = φᵀ S⁻¹ φ`` (2 degrees of freedom) the
        accelerometer's variance is enlarged so that its pull stays bounded (Huber-type
        robust update); default 13.8, the χ²₂ 99.9 % quantile.  ``inf``: off.
    """

    gyro_noise: float = 0.002
    bias_noise: float = 1e-4
    initial_bias_sigma: float = math.radians(0.5)
    bias_limit: float = math.radians(2.0)
    initial_tilt_sigma: float = math.radians(5.0)
    initial_heading_sigma: float = math.radians(20.0)
    acc_noise: float = 0.4
    mag_noise: float = 0.2
    gap_rate_noise: float = 0.3
    gap_rate_relative_noise: float = 0.1
    gap_rate_decay_s: float = 0.2
    gravity: float = 9.80665
    acc_norm_gate: float = 0.2 * 9.80665
    acc_rate_gate: float = 10.0
    mag_norm_gate: float = 0.1
    mag_dip_gate: float = math.radians(10.0)
    mag_reference_tau_s: float = 20.0
    mag_new_time_s: float = 20.0
    mag_new_min_rate: float = math.radians(20.0)
    mag_max_rejection_s: float = 60.0
    mag_rejection_factor: float = 2.0
    acc_innovation_gate: float = 13.8
    velocity_tau_s: float = 3.0
    velocity_noise: float = 1.0
    acc_sensor_noise: float = 0.05
    gap_acc_noise: float = 5.0
    mag_dip_tilt_sigmas: float = 3.0
    mag_hard_iron_tau_s: float = 3.0
    mag_hard_iron_min_bias: float = 0.1
    gap_replay: bool = True
    gap_rate_prediction: bool = True
    gap_rate_prediction_order: int = 48
    gap_rate_prediction_window_s: float = 6.0
    acc_disturbance_factor: float = 4.0
    acc_disturbance_tau_s: float = 0.5

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in _BOOLEAN_SETTINGS:
                if not isinstance(value, (bool, np.bool_)):
                    raise ValueError(f"KalmanSettings.{f.name} must be True or False, got {value!r}")
                object.__setattr__(self, f.name, bool(value))
                continue
            try:
                number = float(value)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"KalmanSettings.{f.name} must be a number, got {value!r}") from exc
            if number == 0.0 and f.name in _MAY_BE_ZERO:
                object.__setattr__(self, f.name, number)
                continue
            if math.isnan(number) or number <= 0.0:
                raise ValueError(f"KalmanSettings.{f.name} must be > 0, got {value!r}")
            if math.isinf(number) and f.name not in _MAY_BE_INFINITE:
                raise ValueError(f"KalmanSettings.{f.name} must be finite, got {value!r}")
            if number > _LARGEST_SETTING and not math.isinf(number):
                raise ValueError(f"KalmanSettings.{f.name} = {value!r} is too large (> {_LARGEST_SETTING:g})")
            if f.name in _INTEGER_SETTINGS:
                if number != round(number) or number > _LARGEST_ORDER:
                    raise ValueError(f"KalmanSettings.{f.name} must be a whole number in [1, {_LARGEST_ORDER}], "
                                     f"got {value!r}")
                number = int(number)
            object.__setattr__(self, f.name, number)


#: Settings that are switches (True/False).
_BOOLEAN_SETTINGS = frozenset({"gap_replay", "gap_rate_prediction"})
#: Settings that may be 0 (switches the feature off).
_MAY_BE_ZERO = frozenset({"acc_disturbance_factor"})
#: Settings that are whole numbers, and their largest value.
_INTEGER_SETTINGS = frozenset({"gap_rate_prediction_order"})
_LARGEST_ORDER = 64
#: Settings that may be ``inf`` (switches the feature off).
_MAY_BE_INFINITE = frozenset({"gap_rate_decay_s", "acc_innovation_gate", "acc_norm_gate", "acc_rate_gate",
                              "mag_norm_gate", "mag_dip_gate", "mag_reference_tau_s", "mag_new_time_s",
                              "mag_max_rejection_s", "velocity_tau_s", "mag_hard_iron_tau_s",
                              "mag_hard_iron_min_bias",
                              "bias_limit"})
#: Finite settings above this would overflow when squared.
_LARGEST_SETTING = 1e100

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


def settings_vector(settings, fs) -> np.ndarray:
    """Checked ``settings`` (None: defaults) and ``fs`` as the kernels' settings vector."""
    fs = B.check_fs(fs)
    if settings is None:
        settings = KalmanSettings()
    if not isinstance(settings, KalmanSettings):
        raise ValueError(f"settings must be a KalmanSettings, got {type(settings).__name__}")
    vector = kalman_settings_vector(settings, 1.0 / fs)
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


def kalman_orientation(gyr, acc, mag=None, *, fs: float, received=None, q0=None, settings=None,
                       gap: str = "constant_rate", full_output: bool = False):
    """Gap-aware error-state Kalman filter (MEKF with gyro bias) over whole recordings, batched.

    See the module docstring for the equations and gates.  The filter always *predicts* over
    a gap: its state is turned by the last received angular rate (minus bias; decaying if
    ``settings.gap_rate_decay_s`` is finite) and its covariance grows with the elapsed gap,
    so that the first received samples after a gap correct it strongly.  ``gap`` only says
    what is output on lost samples.

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
        Noise levels and gates; default ``KalmanSettings()`` (tuned on BROAD, see there).
    gap : {"constant_rate", "hold"}
        During a gap (the words of :func:`wsnlib.orientation.estimate_orientation`):
        ``"constant_rate"`` (default) keeps turning by the last received angular rate (dead
        reckoning, gyroscope only): the output on a lost sample is the filter's prediction.
        ``"hold"`` holds the previous output (the paper's receiver); the filter still
        predicts inside, so the output from the first sample after the gap on is the same
        for both.
    full_output : bool
        Return a :class:`KalmanOutput` (quaternions, bias, covariance, gate decisions)
        instead of the quaternions alone.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4), or KalmanOutput
        ENU unit quaternions (body → earth); ``...`` is the broadcast of the leading
        dimensions of the signals, ``received`` and ``q0``.  (With ``gap="hold"`` only
        ``quat`` is held; bias and covariance are the filter's state.)

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, NaN/inf (or a zero ``acc``/``mag`` vector) in a received sample, a
        non-boolean ``received``, ``fs`` outside [1e-6, 1e9], a zero ``q0``, a batch element
        with nothing received when ``q0`` is None, settings that are not a
        :class:`KalmanSettings`, an unknown ``gap``; or a result that is not finite.
    MemoryError
        At once, with the size, if the outputs would not fit in memory.
    """
    s = settings_vector(settings, fs)
    gap = B.check_choice(gap, "gap", B.GAPS)
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
    if gap == "hold" and n_t:
        run_hold_lost(out_q, inputs.received, np.ascontiguousarray(inputs.index[:, 3]))
    quat = check_finite_output(out_q.reshape(batch + (n_t, 4)))
    if not full_output:
        return quat
    return KalmanOutput(quat=quat, gyro_bias=out_bias.reshape(batch + (n_t, 3)),
                        covariance=out_P.reshape(batch + (n_t, NX, NX)), acc_used=acc_used.reshape(batch + (n_t,)),
                        mag_used=mag_used.reshape(batch + (n_t,)))
