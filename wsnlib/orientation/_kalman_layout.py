"""Layout of the arrays the gap-aware Kalman filter's kernels share (:mod:`wsnlib.orientation.kalman`).

The settings vector handed to every kernel (positions, and :func:`kalman_settings_vector`,
which fills it from a ``KalmanSettings`` and Δt), the error-state size :data:`NX` and the
positions in each stream's auxiliary state (magnetometer gate, gap, leaky velocity,
hard-iron estimate).  Plain Python, no numba: the kernels read these names as compile-time
constants.
"""

from __future__ import annotations

import math

import numpy as np

# ------------------------------------------------------------------------------------------
# Gap-aware error-state Kalman filter (wsnlib.orientation.kalman): the settings vector
# ------------------------------------------------------------------------------------------

# Positions in the settings vector handed to the kernels.
_DT, _GYRO_VAR, _BIAS_VAR, _ACC_VAR, _MAG_VAR, _GAP_VAR, _GAP_DECAY, _GRAVITY = range(8)
_ACC_NORM_GATE, _ACC_RATE_GATE, _MAG_NORM_GATE, _MAG_DIP_GATE, _MAG_REF_GAIN = range(8, 13)
_MAG_NEW_TIME, _MAG_NEW_MIN_RATE, _MAG_MAX_REJECT, _MAG_REJECT_VAR_FACTOR = range(13, 17)
_INIT_TILT_VAR, _INIT_HEADING_VAR, _INIT_BIAS_VAR, _BIAS_LIMIT = range(17, 21)
_ACC_INNOVATION_GATE, _GAP_NOISE, _GAP_RELATIVE_NOISE = range(21, 24)
_VEL_DECAY, _VEL_VAR, _ACC_SENSOR_VAR, _GAP_ACC_VAR, _MAG_DIP_TILT_SIGMAS = range(24, 29)
_HI_DECAY, _HI_RIDGE, _HI_MIN_BIAS, _GAP_REPLAY = range(29, 33)
_AR_ON, _AR_ORDER, _AR_WINDOW = range(33, 36)
_ACC_DIST_FACTOR, _ACC_DIST_GAIN = range(36, 38)
_N_SETTINGS = 38
#: Position of the gap-replay switch (1.0 on, 0.0 off) in the settings vector.
KALMAN_GAP_REPLAY = _GAP_REPLAY
#: Positions of the gap's linear prediction (switch, order, window in samples).
KALMAN_AR_ON, KALMAN_AR_ORDER, KALMAN_AR_WINDOW = _AR_ON, _AR_ORDER, _AR_WINDOW
#: Error-state size: [δθ (3), δb (3), δv (3)].
NX = 9
#: Positions of Δt and of the variances (which must be finite and > 0) in the settings vector.
KALMAN_DT = _DT
KALMAN_VARIANCES = (_GYRO_VAR, _BIAS_VAR, _ACC_VAR, _MAG_VAR, _GAP_VAR, _VEL_VAR, _ACC_SENSOR_VAR, _GAP_ACC_VAR)

# Auxiliary state per stream: magnetometer gate (reference norm (0 = unset) and dip,
# candidate norm/dip/time, time rejected), the number of samples lost in a row, the gap's
# rate-error std, and the leaky velocity v̂ (earth frame, m/s).
_REF_NORM, _REF_DIP, _CAND_NORM, _CAND_DIP, _CAND_T, _REJECT_T, _LOST_RUN, _GAP_SIGMA = range(8)
_VEL = 8  # v̂ at _VEL, _VEL + 1, _VEL + 2
# Online hard-iron estimate (kalman_hard_iron): the normal equations A (6 unique entries of the
# symmetric 3 × 3, order 00 01 02 11 12 22) and r (3), the previous received field and rate
# (3 each), whether the previous sample was received (1/0), and the estimate b̂_m (3).
_HI_A, _HI_R, _PREV_M, _PREV_W, _PREV_OK, _HI_B = 11, 17, 20, 23, 26, 27
# Low-pass of (‖a‖ − g)² over received samples (m²/s⁴): the recent linear-acceleration level.
_LIN_VAR = 30
_N_GATE = 31


def kalman_settings_vector(settings, dt: float, gap: str, replay: bool, gap_time_constant: float) -> np.ndarray:
    """What the Kalman kernels read from a ``KalmanSettings``, Δt (s) and the gap options (the
    vocabulary of :mod:`wsnlib.orientation`: ``gap`` "hold", "constant_rate" or "ar",
    ``replay``, ``gap_time_constant`` in s, ``inf`` = constant): variances per sample, gates
    and switches, in the order of the indices above (plain Python; checked by the caller)."""
    s = settings
    vector = np.empty(_N_SETTINGS)
    vector[_DT] = dt
    vector[_GYRO_VAR] = s.gyro_noise**2 * dt
    vector[_BIAS_VAR] = s.bias_noise**2 * dt
    vector[_ACC_VAR] = s.acc_noise**2
    vector[_MAG_VAR] = s.mag_noise**2
    vector[_GAP_VAR] = (s.gap_rate_noise * dt) ** 2
    vector[_GAP_NOISE] = s.gap_rate_noise
    vector[_GAP_RELATIVE_NOISE] = s.gap_rate_relative_noise
    # The held rate's factor per lost sample: 0 holds the state, 1 keeps the rate constant.
    vector[_GAP_DECAY] = 0.0 if gap == "hold" else math.exp(-dt / gap_time_constant)
    vector[_GRAVITY] = s.gravity
    vector[_ACC_NORM_GATE] = s.acc_norm_gate
    vector[_ACC_RATE_GATE] = s.acc_rate_gate
    vector[_MAG_NORM_GATE] = s.mag_norm_gate
    vector[_MAG_DIP_GATE] = s.mag_dip_gate
    vector[_MAG_REF_GAIN] = -math.expm1(-dt / s.mag_reference_tau_s)
    vector[_MAG_NEW_TIME] = s.mag_new_time_s
    vector[_MAG_NEW_MIN_RATE] = s.mag_new_min_rate
    vector[_MAG_MAX_REJECT] = s.mag_max_rejection_s
    vector[_MAG_REJECT_VAR_FACTOR] = s.mag_rejection_factor**2
    vector[_INIT_TILT_VAR] = s.initial_tilt_sigma**2
    vector[_INIT_HEADING_VAR] = s.initial_heading_sigma**2
    vector[_INIT_BIAS_VAR] = s.initial_bias_sigma**2
    vector[_BIAS_LIMIT] = s.bias_limit
    vector[_ACC_INNOVATION_GATE] = s.acc_innovation_gate
    vector[_VEL_DECAY] = math.exp(-dt / s.velocity_tau_s)
    vector[_VEL_VAR] = s.velocity_noise**2
    vector[_ACC_SENSOR_VAR] = (s.acc_sensor_noise * dt) ** 2
    vector[_GAP_ACC_VAR] = (s.gap_acc_noise * dt) ** 2
    vector[_MAG_DIP_TILT_SIGMAS] = s.mag_dip_tilt_sigmas
    vector[_HI_DECAY] = math.exp(-dt / s.mag_hard_iron_tau_s)
    # Ridge of the hard-iron normal equations: as much as 1 s of rotation at 0.3 rad/s, so that
    # the estimate shrinks to 0 when the sensor has not turned enough to observe it.
    vector[_HI_RIDGE] = 0.09 / dt
    vector[_HI_MIN_BIAS] = s.mag_hard_iron_min_bias
    vector[_GAP_REPLAY] = 1.0 if replay else 0.0
    vector[_AR_ON] = 1.0 if gap == "ar" else 0.0
    vector[_AR_ORDER] = s.gap_rate_prediction_order
    vector[_AR_WINDOW] = round(s.gap_rate_prediction_window_s / dt)
    vector[_ACC_DIST_FACTOR] = s.acc_disturbance_factor
    vector[_ACC_DIST_GAIN] = -math.expm1(-dt / s.acc_disturbance_tau_s)
    return vector
