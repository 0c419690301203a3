"""Settings of the gap-aware Kalman filter: :class:`KalmanSettings`, its documented defaults and checks.

Used by :func:`wsnlib.orientation.kalman.kalman_orientation` (equations and gates in that
module's docstring) and :func:`wsnlib.orientation.smooth_orientation`.  The compiled step
reads them, per sample and with the gap options, as one record of named constants
(:data:`CONSTANTS_DTYPE`, :func:`kalman_constants`): ``constants.gyro_var`` is σ_g² Δt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wsnlib._validation import check_positive, check_settings_fields
from wsnlib.orientation import gaps

# ==========================================================================================
# Settings
# ==========================================================================================


@dataclass(frozen=True)
class KalmanSettings:
    """Noise levels and gates of :func:`~wsnlib.orientation.kalman.kalman_orientation` (and
    :func:`~wsnlib.orientation.smoothing.smooth_orientation`).

    What the filter does in a gap (``gap``, ``replay``, ``output_on_lost``, ``gap_time_constant``)
    is not a setting but the keywords every filter of :mod:`wsnlib.orientation` shares (see
    :func:`~wsnlib.orientation.kalman.kalman_orientation`); the parameters of its "ar"
    prediction and its noise model are here.

    Defaults: ``acc_disturbance_factor``, ``gap_rate_prediction_span_s`` and
    ``gap_rate_prediction_window_s`` are the values chosen most often by leave-one-trial-out
    tuning (8 settings, as every peer: replay ∈ {True, False} × acc_disturbance_factor ∈
    {4, 16} × (span, window) ∈ {(0.48 s, 3 s), (0.96 s, 6 s)}) on the 17 shared BROAD trials at 50 Hz
    under Gilbert–Elliott loss (10 %, mean burst 3 packets of 6 samples), see
    :mod:`wsnlib.studies.loss_tolerance`; ``acc_disturbance_factor`` > 0 was chosen by every
    fold in earlier runs of that study against 0, as were ``mag_hard_iron_min_bias``,
    ``gap_rate_relative_noise``, ``mag_noise_density``, ``mag_norm_gate``,
    ``velocity_noise_density``, ``acc_noise_density`` and ``gap_rate_noise`` (most often, with
    other grids); the other numbers are as documented per field.

    Limits (what the filter cannot do): the heading rests on the magnetometer, so a field whose
    direction is disturbed for longer than ``mag_max_rejection_s`` pulls it (with inflated noise);
    a field whose *strength* drifts faster than ``mag_norm_tau_s`` follows (more than about
    ``mag_norm_gate / mag_norm_tau_s`` = 10 % per second at the defaults) is rejected as
    disturbed, and a disturbance that keeps the field's dip while its strength changes slowly
    is followed and used — a rejection longer than 10 s is counted in
    ``KalmanOutput.long_mag_rejections`` and warned of; a magnet attached to the sensor while
    the field's strength drifts can pull the heading for a few seconds until the hard-iron
    estimate has followed (``mag_hard_iron_tau_s``; the worst case measured, BROAD trial 33
    under a scale 0.4–1.2 and GE 10 %, costs a few degrees of heading); the tilt needs
    the accelerometer's gates to pass now and then (a recording in constant fast motion keeps
    its tilt from the velocity pseudo-measurement alone); the rate
    predictor in a gap spans at most 64 samples (0.22 s at BROAD's native rate).

    Every setting is in physical units (per second, not per sample), so one settings object
    behaves the same at 40, 50, 100 Hz or BROAD's native 2000/7 Hz (measured:
    ``benchmarks/eval_rates_and_starts.py``); the values tuned at 50 Hz are kept.

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
    acc_noise_density : float
        Noise density of the measured tilt error of an accepted accelerometer sample (rad·√s):
        one sample's variance is ``acc_noise_density² / Δt``, so a second of samples weighs the
        same at any rate.  Default ``0.4·√0.02`` ≈ 0.057 (0.4 rad per sample at 50 Hz), chosen
        most often by LOTO from {0.05, 0.1, 0.2, 0.4} rad per sample at 50 Hz
        (eval_loss_tolerance.py, before the leaky velocity was added).
    mag_noise_density : float
        Noise density of the measured heading error of an accepted magnetometer sample (rad·√s;
        one sample's variance ``mag_noise_density² / Δt``).  Default ``0.2·√0.02`` ≈ 0.028
        (0.2 rad per sample at 50 Hz), chosen most often by LOTO from {0.2, 0.5} rad per sample.
    gap_rate_noise : float
        Std of the error of the extrapolated angular rate during a gap (rad/s).  Default 0.3,
        chosen most often by LOTO from {0.3, 1.0} (eval_loss_tolerance.py, before the leaky
        velocity was added).
    gap_rate_relative_noise : float
        Added to ``gap_rate_noise`` times the last received rate's norm (dimensionless): the
        faster the motion, the less the rate at the start of a gap says about the rest of it.
        Default 0.1, chosen most often by LOTO from {0.5, 0.1} (a larger value lets the first
        samples after a gap in fast motion over-correct).
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
        Time constant (s) of the reference norm/dip low-pass on accepted fields, VQF's
        ``magRefTau`` = 20 s.
    mag_norm_tau_s : float
        Time constant (s) with which the norm gate's reference follows every field whose dip
        passes the dip gate (the field's direction holds, its strength may drift: a sensor's gain,
        a room's field).  A field strength that drifts by a fraction ρ per second lags the
        follower by about ρ·τ, so it passes ``mag_norm_gate`` up to ρ ≈ ``mag_norm_gate``/τ
        (10 %/s at the default).  Default 1 s: on the 17 BROAD trials at 50 Hz it follows a
        magnetometer scaled by a slow factor 0.4–1.2 per minute (up to ~7 %/s; 20 s, VQF's
        ``magRefTau``, rejected it on 85 % of the samples and cost up to +45° of heading under
        GE 10 %), at a cost of +0.1° mean lossless RMSE (the attached-magnet trials; 2 s
        followed the scale less well; ``benchmarks/eval_rates_and_starts.py`` and
        ``benchmarks/eval_kalman_accuracy.py``, November 2026).  ``inf``: the gate's norm stays
        where the reference was set.  The follower cannot follow in a gap: after L lost samples
        the norm tolerance is ``mag_norm_gate · (1 + LΔt/τ)`` and the follower catches up with
        the gain of (L + 1)Δt (the same drift rate passes as without a gap).
    mag_new_time_s : float
        Consistent time (s) after which a new field becomes the reference, VQF's
        ``magNewTime`` = 20 s.
    mag_new_first_time_s : float
        The first sample's field is the reference only provisionally: until it has been confirmed
        by this long (s) of undisturbed fields, a new field consistent for this long, turning or
        not, replaces it (so a recording that starts in motion or in a disturbance does not keep
        the gates of its first sample).  VQF's ``magNewFirstTime`` = 5 s.
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
    velocity_noise_density : float
        Noise density σ_v (m/s·√s) of the pseudo-measurement ``v_x = v_y = v_z = 0`` (one
        sample's variance ``σ_v² / Δt``).  Default ``1.0·√0.02`` ≈ 0.14 (1 m/s per sample at
        50 Hz), chosen most often by LOTO from {0.5, 1.0} m/s per sample (eval_loss_tolerance.py).
    initial_velocity_sigma : float
        Prior std of the leaky velocity (m/s).  Default 1.0.
    velocity_random_walk : float
        Random walk σ_s (m/s/√s) of the leaky velocity from accelerometer noise: its variance grows
        by ``σ_s² Δt`` per received sample.  Default ``0.05·√0.02`` ≈ 0.0071 (0.05 m/s² of
        accelerometer noise per sample at 50 Hz, MEMS datasheet order).
    gap_acc_noise : float
        Std (m/s²) of the unknown linear acceleration during a gap (velocity variance grows
        like ``(σ kΔt)²`` after ``k`` lost samples).  Default 5 m/s² (about half a g).
    mag_dip_tilt_sigmas : float
        The dip gate widens by this many tilt standard deviations.  Default 3.
    mag_hard_iron_tau_s : float
        Forgetting time constant (s) of the online hard-iron estimate (a magnet or iron fixed
        to the sensor: a constant body-frame offset of the field, estimated from the gyroscope
        and the field's rate of change, see
        :func:`wsnlib.orientation._kalman_kernels.hard_iron`).  Default 1 s: about 50
        samples of rotation at 50 Hz average the differentiated field's noise down to ~2 µT
        (below ``mag_hard_iron_min_bias`` of a 45 µT field), a removed magnet is forgotten within
        a second or two, and an offset that changes with the sensor's gain is followed.  It was
        3 s until November 2026: with the magnetometer scaled by a slow factor 0.4–1.2 (issue 24,
        ``benchmarks/eval_rates_and_starts.py``) the 3 s estimate lagged the scaled magnet of
        BROAD trial 33 and cost +14° of heading under GE 10 % (1 s: +4.4°), and on the 17 trials
        1 s was 0.12° better lossless and within 0.02° under GE 10 %
        (``benchmarks/eval_kalman_accuracy.py --compare``, 5 draws).  3 s stays a design
        alternative of the loss study (``KALMAN_DESIGNS``), chosen in the fold.
    mag_lag_tau_s : float
        Forgetting time constant (s) of the online estimate of the magnetometer's lag behind the
        gyroscope (a sensor's own filter or sampling delay δ: the field read at t is the field of
        t − δ, so in a turn the heading is off by ω_z δ — 3° at 5 rad/s and 10 ms).  Two
        consecutive received samples give ``ṁ + ω × m ≈ δ ω̇ × m`` (the field lags the rate that
        turns it), a scalar least-squares estimate forgotten with this time constant, with a ridge
        of 1 s of 3 rad/s² angular acceleration (so it stays near 0 until the sensor has turned
        and braked), clipped to ``± mag_lag_max_s``; the field is then advanced by ``−δ̂ ω × m``
        before everything else (:func:`wsnlib.orientation._kalman_kernels.mag_lag`).  Estimated
        from the sensors alone, causally, on every recording anew.  Default 30 s: the lag is a
        constant of the sensor, and a long memory averages the differentiated field's noise.
        BROAD's magnetometer lags by ~10 ms on all 17 trials (8.4–11.7 ms offline at the native
        rate); at 50 Hz the online estimate is within 8.6–11.3 ms 10 s after the motion starts on
        15 of them and within 7.6–11.3 ms after a minute on all.  Not swept: the three values
        are set from the physics above (November 2026: on the 17 trials, defaults, 5 draws,
        lossless −0.29°, GE 10 % −0.56°, ``benchmarks/eval_kalman_accuracy.py --compare``).
    mag_lag_max_s : float
        Largest lag (s) the compensation applies, either sign; 0 switches it off.  Default 0.05 s.
    mag_hard_iron_min_bias : float
        The estimate is subtracted only when its norm is at least this times the reference
        field norm and the corrected field is closer to the reference norm, its norm steadier
        than the raw one's, or the offset explains at least half of the field's rate residual
        beyond its white noise (:func:`wsnlib.orientation._kalman_kernels.hard_iron`);
        ``inf`` switches the correction off.  Default 0.1, the size ``mag_norm_gate`` would
        reject; chosen most often by LOTO from {0.1, inf}.
    gap_rate_prediction_span_s : float
        With ``gap="ar"``: how far back (s) the linear predictor of the rate looks (an
        autoregressive model per axis, :func:`wsnlib.orientation.gaps.ar_fit`, fitted at the
        gap's start on the rates of the last ``gap_rate_prediction_window_s``): its order is
        ``round(span · fs)`` samples, at least 1 and at most 64 (:data:`wsnlib.orientation.gaps.MAX_ORDER`;
        above 66.7 Hz the default span is cut to 64 samples).  Default 0.96 s (48 samples at
        50 Hz; LOTO, see the class's defaults).
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
    acc_noise_density: float = 0.4 * math.sqrt(0.02)
    mag_noise_density: float = 0.2 * math.sqrt(0.02)
    gap_rate_noise: float = 0.3
    gap_rate_relative_noise: float = 0.1
    gravity: float = 9.80665
    acc_norm_gate: float = 0.2 * 9.80665
    acc_rate_gate: float = 10.0
    mag_norm_gate: float = 0.1
    mag_dip_gate: float = math.radians(10.0)
    mag_reference_tau_s: float = 20.0
    mag_norm_tau_s: float = 1.0
    mag_new_time_s: float = 20.0
    mag_new_first_time_s: float = 5.0
    mag_new_min_rate: float = math.radians(20.0)
    mag_max_rejection_s: float = 60.0
    mag_rejection_factor: float = 2.0
    acc_innovation_gate: float = 13.8
    velocity_tau_s: float = 3.0
    velocity_noise_density: float = 1.0 * math.sqrt(0.02)
    initial_velocity_sigma: float = 1.0
    velocity_random_walk: float = 0.05 * math.sqrt(0.02)
    gap_acc_noise: float = 5.0
    mag_dip_tilt_sigmas: float = 3.0
    mag_hard_iron_tau_s: float = 1.0
    mag_hard_iron_min_bias: float = 0.1
    mag_lag_tau_s: float = 30.0
    mag_lag_max_s: float = 0.05
    gap_rate_prediction_span_s: float = 0.96
    gap_rate_prediction_window_s: float = 6.0
    acc_disturbance_factor: float = 4.0
    acc_disturbance_tau_s: float = 0.5

    def __post_init__(self):
        check_settings_fields(self, may_be_zero=_MAY_BE_ZERO, may_be_infinite=_MAY_BE_INFINITE,
                              largest=_LARGEST_SETTING)


#: Ridge of the magnetometer lag's estimate, ((rad/s²)² s): 1 s of 3 rad/s² angular acceleration.
MAG_LAG_RIDGE = 9.0
#: A hard-iron estimate that explains this share of the field's rate residual beyond the field's white
#: noise (more than it leaves) is used whatever the reference norm
#: (:func:`wsnlib.orientation._kalman_kernels.hard_iron`).
MAG_HARD_IRON_EXPLAINED = 0.5
#: ... counted only while that residual is this many standard deviations above what white noise alone
#: gives (three, set from the noise statistics before looking at any recording).
MAG_HARD_IRON_SIGNIFICANCE = 3.0
#: Settings that may be 0 (switches the feature off).
_MAY_BE_ZERO = frozenset({"acc_disturbance_factor", "mag_lag_max_s"})
#: Settings that may be ``inf`` (switches the feature off).
_MAY_BE_INFINITE = frozenset({"acc_innovation_gate", "acc_norm_gate", "acc_rate_gate",
                              "mag_norm_gate", "mag_dip_gate", "mag_reference_tau_s", "mag_norm_tau_s",
                              "mag_new_time_s",
                              "mag_max_rejection_s", "velocity_tau_s", "mag_hard_iron_tau_s",
                              "mag_hard_iron_min_bias",
                              "bias_limit"})
#: Finite settings above this would overflow when squared.
_LARGEST_SETTING = 1e100


# ==========================================================================================
# What the compiled step reads: per-sample constants
# ==========================================================================================

#: The constants of one run, per sample of Δt (s); variances in rad², (rad/s)², (m/s)².
CONSTANTS_DTYPE = np.dtype([
    ("dt", "f8"),                    # Δt (s)
    ("gyro_var", "f8"),              # σ_g² Δt: attitude variance added per sample
    ("bias_var", "f8"),              # σ_b² Δt: bias random walk per sample
    ("acc_var", "f8"),               # σ_a²/Δt: tilt measurement variance
    ("mag_var", "f8"),               # σ_m²/Δt: heading measurement variance
    ("gap_noise", "f8"),             # σ_gap (rad/s)
    ("gap_relative_noise", "f8"),    # × ‖ω_last‖
    ("gravity", "f8"),               # g (m/s²)
    ("acc_norm_gate", "f8"), ("acc_rate_gate", "f8"),
    ("acc_innovation_gate", "f8"),   # χ² gate of the tilt innovation
    ("acc_dist_factor", "f8"),       # f of the adaptive accelerometer noise
    ("acc_dist_gain", "f8"),         # 1 − exp(−Δt/τ_dist)
    ("mag_norm_gate", "f8"), ("mag_dip_gate", "f8"),
    ("mag_ref_gain", "f8"),          # 1 − exp(−Δt/τ_ref): the reference's low-pass
    ("mag_gate_norm_gain", "f8"),    # 1 − exp(−Δt/τ_norm): the norm gate's follower
    ("mag_norm_tau", "f8"),          # τ_norm (s): the follower after a gap
    ("mag_new_first_time", "f8"),
    ("mag_new_time", "f8"), ("mag_new_min_rate", "f8"), ("mag_max_reject", "f8"),
    ("mag_reject_var_factor", "f8"), ("mag_dip_tilt_sigmas", "f8"),
    ("init_tilt_var", "f8"), ("init_heading_var", "f8"), ("init_bias_var", "f8"), ("bias_limit", "f8"),
    ("vel_decay", "f8"),             # c = exp(−Δt/τ_v)
    ("vel_var", "f8"),               # σ_v²/Δt: the pseudo-measurement v = 0
    ("init_vel_var", "f8"),          # prior variance of the velocity
    ("acc_sensor_var", "f8"),        # σ_s² Δt: velocity process noise per received sample
    ("gap_acc_var", "f8"),           # (σ_gap,acc Δt)²
    ("hi_decay", "f8"),              # exp(−Δt/τ_hard-iron)
    ("hi_ridge", "f8"),              # ridge of the hard-iron normal equations
    ("hi_min_bias", "f8"),
    ("hi_min_explained", "f8"),      # share of ṁ + ω × m (noise aside) the offset must explain to be used regardless
    ("hi_significance", "f8"),       # standard deviations (on white noise) that residual must exceed
    ("lag_decay", "f8"),             # exp(−Δt/τ_lag): the magnetometer lag's forgetting
    ("lag_ridge", "f8"),             # its ridge ((rad/s²)² s)
    ("lag_max", "f8"),               # largest |δ| applied (s); 0: off
    ("gap", "i8"), ("gap_factor", "f8"), ("replay", "?"),  # the gap options (wsnlib.orientation.gaps)
    ("ar_order", "i8"), ("ar_window", "i8"),
    ("has_mag", "?"),                # a magnetometer is given
    ("record", "?"),                 # keep the prediction (q⁻, b⁻, v⁻, P⁻, F) of every sample (smoother)
])


def gap_prediction_order(settings: KalmanSettings, dt: float) -> int:
    """The rate predictor's order (samples) at Δt (s): ``round(gap_rate_prediction_span_s / Δt)`` in
    ``[1, MAX_ORDER]``."""
    return int(min(max(round(settings.gap_rate_prediction_span_s / dt), 1), gaps.MAX_ORDER))


def gap_prediction_window(gap: str, span_s, window_s, fs: float, filter_name: str) -> tuple[int, int]:
    """The AR predictor's order and window (samples) at ``fs`` (Hz) from its span and window (s;
    None: :class:`KalmanSettings`' defaults), for a filter other than the Kalman filter that takes
    ``gap="ar"`` (Madgwick's, the peers); ``ValueError`` when they are given with another ``gap``."""
    given = {name: value for name, value in (("gap_rate_prediction_span_s", span_s),
                                              ("gap_rate_prediction_window_s", window_s)) if value is not None}
    if given and gap != "ar":
        raise ValueError(f"{', '.join(given)} only apply to gap='ar' in {filter_name} (the linear prediction's "
                         f"span and window), got gap={gap!r}")
    settings = KalmanSettings(**{name: check_positive(value, name) for name, value in given.items()})
    return gap_prediction_order(settings, 1.0 / fs), round(settings.gap_rate_prediction_window_s * fs)


def kalman_constants(settings: KalmanSettings, dt: float, *, gap: int, replay: bool, gap_time_constant: float,
                     has_mag: bool, record: bool = False) -> np.ndarray:
    """The compiled step's constants (a record of :data:`CONSTANTS_DTYPE`, shape ``(1,)``) for
    ``settings``, Δt (s) and the gap options (``gap`` a code of :data:`wsnlib.orientation.gaps.GAP_CODES`,
    ``gap_time_constant`` in s, ``inf`` = constant); checked by the caller."""
    s = settings
    c = np.zeros(1, CONSTANTS_DTYPE)
    values = {
        "dt": dt, "gyro_var": s.gyro_noise**2 * dt, "bias_var": s.bias_noise**2 * dt,
        "acc_var": s.acc_noise_density**2 / dt, "mag_var": s.mag_noise_density**2 / dt,
        "gap_noise": s.gap_rate_noise, "gap_relative_noise": s.gap_rate_relative_noise,
        "gravity": s.gravity, "acc_norm_gate": s.acc_norm_gate, "acc_rate_gate": s.acc_rate_gate,
        "acc_innovation_gate": s.acc_innovation_gate, "acc_dist_factor": s.acc_disturbance_factor,
        "acc_dist_gain": -math.expm1(-dt / s.acc_disturbance_tau_s), "mag_norm_gate": s.mag_norm_gate,
        "mag_dip_gate": s.mag_dip_gate, "mag_ref_gain": -math.expm1(-dt / s.mag_reference_tau_s),
        "mag_gate_norm_gain": -math.expm1(-dt / s.mag_norm_tau_s), "mag_norm_tau": s.mag_norm_tau_s,
        "mag_new_first_time": s.mag_new_first_time_s,
        "mag_new_time": s.mag_new_time_s, "mag_new_min_rate": s.mag_new_min_rate,
        "mag_max_reject": s.mag_max_rejection_s, "mag_reject_var_factor": s.mag_rejection_factor**2,
        "mag_dip_tilt_sigmas": s.mag_dip_tilt_sigmas, "init_tilt_var": s.initial_tilt_sigma**2,
        "init_heading_var": s.initial_heading_sigma**2, "init_bias_var": s.initial_bias_sigma**2,
        "bias_limit": s.bias_limit, "vel_decay": math.exp(-dt / s.velocity_tau_s),
        "vel_var": s.velocity_noise_density**2 / dt, "init_vel_var": s.initial_velocity_sigma**2,
        "acc_sensor_var": s.velocity_random_walk**2 * dt, "gap_acc_var": (s.gap_acc_noise * dt) ** 2,
        "hi_decay": math.exp(-dt / s.mag_hard_iron_tau_s),
        # Ridge of the hard-iron normal equations: as much as 1 s of rotation at 0.3 rad/s, so that
        # the estimate shrinks to 0 when the sensor has not turned enough to observe it.
        "hi_ridge": 0.09 / dt, "hi_min_bias": s.mag_hard_iron_min_bias,
        "hi_min_explained": MAG_HARD_IRON_EXPLAINED, "hi_significance": MAG_HARD_IRON_SIGNIFICANCE,
        # The lag's ridge: as much as 1 s of 3 rad/s² angular acceleration (unit field).
        "lag_decay": math.exp(-dt / s.mag_lag_tau_s), "lag_ridge": MAG_LAG_RIDGE, "lag_max": s.mag_lag_max_s,
        # The held rate's factor per lost sample: 0 holds the state, 1 keeps the rate constant.
        "gap": gap, "gap_factor": 0.0 if gap == 0 else math.exp(-dt / gap_time_constant), "replay": replay,
        "ar_order": gap_prediction_order(s, dt), "ar_window": round(s.gap_rate_prediction_window_s / dt),
        "has_mag": has_mag, "record": record,
    }
    for name, value in values.items():
        c[name] = value
    return c
