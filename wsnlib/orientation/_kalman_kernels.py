"""Compiled kernels of the gap-aware error-state Kalman filter (:mod:`wsnlib.orientation.kalman`).

One numba function per step of the filter's equations (prediction, accelerometer and
magnetometer corrections, the scalar update, the injection, the gap's linear prediction of
the rate and its end correction), the loop over time of one
recording (:func:`kalman_stream`) and its parallel batch driver (:func:`run_kalman`).  The
scalar quaternion helpers are those of :mod:`._kernels`, shared with Madgwick's filter.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from wsnlib.orientation._kernels import (
    COMPILE,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    rotation_matrix,
    vec_norm,
)

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
#: Ridge of the gap's linear-prediction fit, relative to the mean squared rate of the window
#: (and at least this in (rad/s)²): keeps a window of near rest from fitting its noise.
AR_RIDGE = 1e-3
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


def kalman_settings_vector(settings, dt: float) -> np.ndarray:
    """What the Kalman kernels read from a ``KalmanSettings`` and Δt (s): variances per sample and
    gates, in the order of the indices above (plain Python; checked by the caller)."""
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
    vector[_GAP_DECAY] = math.exp(-dt / s.gap_rate_decay_s)
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
    vector[_GAP_REPLAY] = 1.0 if s.gap_replay else 0.0
    vector[_AR_ON] = 1.0 if s.gap_rate_prediction else 0.0
    vector[_AR_ORDER] = s.gap_rate_prediction_order
    vector[_AR_WINDOW] = round(s.gap_rate_prediction_window_s / dt)
    vector[_ACC_DIST_FACTOR] = s.acc_disturbance_factor
    vector[_ACC_DIST_GAIN] = -math.expm1(-dt / s.acc_disturbance_tau_s)
    return vector


# ------------------------------------------------------------------------------------------
# Kalman filter: one sample (equations in wsnlib.orientation.kalman's docstring)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def kalman_scalar_update(P, dx, i, innovation, r, heading_only, K, row):
    """Scalar Kalman update with ``H = e_iᵀ``: ``S = P_ii + r``, ``K = P_·i/S``, Joseph form."""
    S = P[i, i] + r
    for a in range(NX):
        K[a] = P[a, i] / S
        row[a] = P[i, a]
    if heading_only:  # the magnetometer must not tilt: zero the gain's tilt rows
        K[0] = 0.0
        K[1] = 0.0
    for a in range(NX):
        dx[a] += K[a] * innovation
    # P ← P − K P_i· − P_·i Kᵀ + S K Kᵀ   ((I − K H) P (I − K H)ᵀ + r K Kᵀ, any K)
    for a in range(NX):
        for b in range(NX):
            P[a, b] += -K[a] * row[b] - row[a] * K[b] + S * K[a] * K[b]


@njit(**COMPILE)
def kalman_inject(q, bias, gate, dx, bias_limit):
    """``q ← Exp(δθ) ⊗ q``, ``b ← b + δb`` (clipped), ``v̂ ← v̂ + δv``, ``δx ← 0``; returns ``q``."""
    q = quat_normalize(quat_multiply(quat_exp((dx[0], dx[1], dx[2])), q))
    for a in range(3):
        bias[a] = min(max(bias[a] + dx[3 + a], -bias_limit), bias_limit)
        gate[_VEL + a] += dx[6 + a]
    for a in range(NX):
        dx[a] = 0.0
    return q


@njit(**COMPILE)
def kalman_predict(q, bias, P, held_rate, gate, gyr, acc, received, s, R, F, FP, predicted_rate, use_predicted):
    """Prediction of one sample (module docstring); returns ``q⁻``.

    ``q`` 4-tuple; ``bias`` (3,) read; ``P`` (NX, NX), ``held_rate`` (3,) (the bias-corrected
    rate used, on return) and ``gate`` (_N_GATE, with v̂) updated in place; ``gyr``, ``acc``
    (3,) read only if ``received``.  On a lost sample the rate is ``predicted_rate`` (3,) if
    ``use_predicted`` (the gap's linear prediction, :func:`gap_rate_fit`), else the held rate
    times the decay.  On return ``R`` (3, 3) holds R(q⁻) and ``F`` (NX, NX) the
    transition matrix of the sample; ``FP`` (NX, NX) is scratch.
    """
    dt = s[_DT]
    # --- Angular rate of the prediction: measured, or extrapolated over a gap -------------
    if received:
        for a in range(3):
            held_rate[a] = gyr[a] - bias[a]
        gate[_LOST_RUN] = 0.0
    else:
        for a in range(3):
            held_rate[a] = predicted_rate[a] if use_predicted else held_rate[a] * s[_GAP_DECAY]
        gate[_LOST_RUN] += 1.0
        gate[_PREV_OK] = 0.0
    omega = (held_rate[0], held_rate[1], held_rate[2])

    # --- Strapdown prediction: q⁻ = q ⊗ Exp((ω − b) Δt) -----------------------------------
    q = quat_normalize(quat_multiply(q, quat_exp((omega[0] * dt, omega[1] * dt, omega[2] * dt))))
    rotation_matrix(q, R)

    # --- Leaky velocity: v̂ ← c v̂ + (R(q⁻) a − g e_z) Δt (received), v̂ ← c v̂ (lost) -------
    decay = s[_VEL_DECAY]
    a_e = (0.0, 0.0, 0.0)
    if received:
        a_e = quat_rotate(q, (acc[0], acc[1], acc[2]))
        gate[_VEL] = decay * gate[_VEL] + a_e[0] * dt
        gate[_VEL + 1] = decay * gate[_VEL + 1] + a_e[1] * dt
        gate[_VEL + 2] = decay * gate[_VEL + 2] + (a_e[2] - s[_GRAVITY]) * dt
    else:
        for a in range(3):
            gate[_VEL + a] *= decay

    # --- Error propagation: P⁻ = F P Fᵀ + Q ----------------------------------------------
    # F = [[I, −R Δt, 0], [0, I, 0], [−[a_E]× Δt, [a_E]× R Δt², c I]]  (a_E = 0 when lost)
    for a in range(NX):
        for b in range(NX):
            F[a, b] = 1.0 if a == b else 0.0
    for a in range(3):
        for b in range(3):
            F[a, 3 + b] = -R[a, b] * dt
        F[6 + a, 6 + a] = decay
    # −[a_E]× Δt: rows of the cross-product matrix of a_E, negated
    F[6, 1], F[6, 2] = a_e[2] * dt, -a_e[1] * dt
    F[7, 0], F[7, 2] = -a_e[2] * dt, a_e[0] * dt
    F[8, 0], F[8, 1] = a_e[1] * dt, -a_e[0] * dt
    for a in range(3):  # [a_E]× R Δt² = (−[a_E]× Δt)(−R Δt)
        for b in range(3):
            F[6 + a, 3 + b] = F[6 + a, 0] * F[0, 3 + b] + F[6 + a, 1] * F[1, 3 + b] + F[6 + a, 2] * F[2, 3 + b]
    for a in range(NX):  # FP = F P
        for b in range(NX):
            acc_ab = 0.0
            for c in range(NX):
                acc_ab += F[a, c] * P[c, b]
            FP[a, b] = acc_ab
    for a in range(NX):  # P = (F P) Fᵀ
        for b in range(NX):
            acc_ab = 0.0
            for c in range(NX):
                acc_ab += FP[a, c] * F[b, c]
            P[a, b] = acc_ab
    # Q: gyro noise and bias random walk; over a gap, the extrapolated rate's error.
    # Over a gap also the unknown linear acceleration: δv grows like (σ_gap,acc · kΔt)².
    extra = 0.0
    extra_v = s[_ACC_SENSOR_VAR]
    if not received:
        if gate[_LOST_RUN] == 1.0:  # std of the extrapolated rate's error, fixed for the gap
            gate[_GAP_SIGMA] = s[_GAP_NOISE] + s[_GAP_RELATIVE_NOISE] * vec_norm(omega)
        extra = (gate[_GAP_SIGMA] * dt) ** 2 * (2.0 * gate[_LOST_RUN] - 1.0)
        extra_v = s[_GAP_ACC_VAR] * (2.0 * gate[_LOST_RUN] - 1.0)
    for a in range(3):
        P[a, a] += s[_GYRO_VAR] + extra
        P[3 + a, 3 + a] += s[_BIAS_VAR]
        P[6 + a, 6 + a] += extra_v
    return q


@njit(**COMPILE)
def kalman_correct(q, bias, P, gate, acc, mag, has_mag, omega, s, dx, K, row):
    """Measurement updates of one received sample; returns ``(q, acc_used, mag_used)``.

    ``q`` = q⁻ (4-tuple), ``omega`` the bias-corrected rate of the sample (3-tuple, for the
    rate gates); ``bias``, ``P``, ``gate`` updated in place; ``dx``, ``K``, ``row`` (NX,)
    scratch.
    """
    # --- Accelerometer: tilt update -----------------------------------------------------
    acc_used = False
    acc_norm = vec_norm(acc)
    deviation = abs(acc_norm - s[_GRAVITY])
    gate[_LIN_VAR] += s[_ACC_DIST_GAIN] * (deviation * deviation - gate[_LIN_VAR])
    if deviation <= s[_ACC_NORM_GATE] and vec_norm(omega) <= s[_ACC_RATE_GATE]:
        e = quat_rotate(q, (acc[0] / acc_norm, acc[1] / acc_norm, acc[2] / acc_norm))
        cx, cy = e[1], -e[0]  # e × e_z
        sin_angle = math.hypot(cx, cy)
        angle = math.atan2(sin_angle, e[2])
        if sin_angle > 0.0:
            phi_x, phi_y = angle * cx / sin_angle, angle * cy / sin_angle
        else:
            phi_x, phi_y = (angle, 0.0) if e[2] < 0.0 else (0.0, 0.0)
        # Linear acceleration tilts the measured direction: by at least |‖a‖ − g|/g now, and by
        # about the recent level (low-passed (‖a‖ − g)², × acc_disturbance_factor) sideways.
        r = s[_ACC_VAR] + (deviation * deviation + s[_ACC_DIST_FACTOR] * gate[_LIN_VAR]) / s[_GRAVITY] ** 2
        # Innovation gate (robust, Huber): d² = φᵀ S⁻¹ φ with S = P_tilt + r I (2 × 2).  Beyond
        # the gate the sample is not dropped but S is scaled by d/√gate (r enlarged to match),
        # so its pull is bounded: an outlier moves the estimate little, while a filter that is
        # really off (e.g. after a long gap in fast motion) keeps being pulled back.
        s00, s01, s11 = P[0, 0] + r, P[0, 1], P[1, 1] + r
        d2 = (s11 * phi_x * phi_x - 2.0 * s01 * phi_x * phi_y + s00 * phi_y * phi_y) / (s00 * s11 - s01 * s01)
        if d2 > s[_ACC_INNOVATION_GATE]:
            scale = math.sqrt(d2 / s[_ACC_INNOVATION_GATE])
            tilt_var = 0.5 * (P[0, 0] + P[1, 1])
            r = scale * (tilt_var + r) - tilt_var
        kalman_scalar_update(P, dx, 0, phi_x - dx[0], r, False, K, row)
        kalman_scalar_update(P, dx, 1, phi_y - dx[1], r, False, K, row)
        q = kalman_inject(q, bias, gate, dx, s[_BIAS_LIMIT])
        acc_used = True
    # --- Leaky velocity: pseudo-measurement v = 0 (every received sample) ----------------
    # Linear acceleration averages out (the position stays bounded), so the horizontal
    # leaky velocity stays small, while a tilt error δθ makes it ramp by g δθ Δt per sample:
    # VQF's low-pass of the earth-frame specific force (τ_acc), as a Kalman measurement.
    r_v = s[_VEL_VAR]
    kalman_scalar_update(P, dx, 6, -gate[_VEL] - dx[6], r_v, False, K, row)
    kalman_scalar_update(P, dx, 7, -gate[_VEL + 1] - dx[7], r_v, False, K, row)
    kalman_scalar_update(P, dx, 8, -gate[_VEL + 2] - dx[8], r_v, False, K, row)
    q = kalman_inject(q, bias, gate, dx, s[_BIAS_LIMIT])
    return kalman_correct_mag(q, bias, P, gate, mag, has_mag, omega, s, dx, K, row, acc_used)


@njit(**COMPILE)
def kalman_hard_iron(gate, mag, omega, s):
    """Update the online hard-iron estimate with one received field; returns the field to use.

    A magnet or ferrous part fixed to the sensor adds a constant body-frame offset ``b_m``:
    ``m = Rᵀ m_E + b_m``.  Since ``d/dt (Rᵀ m_E) = −ω × (Rᵀ m_E)``, two consecutive received
    samples give ``ṁ + ω × m = ω × b_m`` (ṁ, ω, m at the midpoint), linear in ``b_m`` and
    independent of the orientation (gyroscope-aided hard-iron estimation).  ``b̂_m`` solves the
    exponentially forgotten (time constant ``mag_hard_iron_tau_s``) least-squares normal
    equations ``(A + εI) b = r``, ``A = Σ [ω]×ᵀ[ω]×``, ``r = Σ [ω]×ᵀ y``, ε the ridge
    (1 s at 0.3 rad/s), so it shrinks to 0 while the sensor does not turn.  ``m − b̂_m`` is
    returned if ``‖b̂_m‖ ≥ mag_hard_iron_min_bias · ‖m_ref‖`` and its norm is closer to the
    reference norm than the raw field's; otherwise ``m``.
    """
    m = (mag[0], mag[1], mag[2])
    if gate[_PREV_OK] == 1.0:
        dt = s[_DT]
        w = (0.5 * (omega[0] + gate[_PREV_W]), 0.5 * (omega[1] + gate[_PREV_W + 1]),
             0.5 * (omega[2] + gate[_PREV_W + 2]))
        mm = (0.5 * (m[0] + gate[_PREV_M]), 0.5 * (m[1] + gate[_PREV_M + 1]), 0.5 * (m[2] + gate[_PREV_M + 2]))
        wxm = (w[1] * mm[2] - w[2] * mm[1], w[2] * mm[0] - w[0] * mm[2], w[0] * mm[1] - w[1] * mm[0])
        y = ((m[0] - gate[_PREV_M]) / dt + wxm[0], (m[1] - gate[_PREV_M + 1]) / dt + wxm[1],
             (m[2] - gate[_PREV_M + 2]) / dt + wxm[2])
        lam = s[_HI_DECAY]
        w2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
        # [ω]×ᵀ[ω]× = ‖ω‖² I − ω ωᵀ;  [ω]×ᵀ y = y × ω
        a = _HI_A
        gate[a] = lam * gate[a] + w2 - w[0] * w[0]
        gate[a + 1] = lam * gate[a + 1] - w[0] * w[1]
        gate[a + 2] = lam * gate[a + 2] - w[0] * w[2]
        gate[a + 3] = lam * gate[a + 3] + w2 - w[1] * w[1]
        gate[a + 4] = lam * gate[a + 4] - w[1] * w[2]
        gate[a + 5] = lam * gate[a + 5] + w2 - w[2] * w[2]
        gate[_HI_R] = lam * gate[_HI_R] + (y[1] * w[2] - y[2] * w[1])
        gate[_HI_R + 1] = lam * gate[_HI_R + 1] + (y[2] * w[0] - y[0] * w[2])
        gate[_HI_R + 2] = lam * gate[_HI_R + 2] + (y[0] * w[1] - y[1] * w[0])
        # (A + εI) b = r by Cramer's rule (symmetric positive definite 3 × 3)
        eps = s[_HI_RIDGE]
        a00, a01, a02 = gate[a] + eps, gate[a + 1], gate[a + 2]
        a11, a12, a22 = gate[a + 3] + eps, gate[a + 4], gate[a + 5] + eps
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        det = a00 * c00 + a01 * c01 + a02 * c02
        r0, r1, r2 = gate[_HI_R], gate[_HI_R + 1], gate[_HI_R + 2]
        gate[_HI_B] = (c00 * r0 + c01 * r1 + c02 * r2) / det
        gate[_HI_B + 1] = (c01 * r0 + c11 * r1 + c12 * r2) / det
        gate[_HI_B + 2] = (c02 * r0 + c12 * r1 + c22 * r2) / det
    for k in range(3):
        gate[_PREV_M + k] = m[k]
        gate[_PREV_W + k] = omega[k]
    gate[_PREV_OK] = 1.0
    b = (gate[_HI_B], gate[_HI_B + 1], gate[_HI_B + 2])
    ref = gate[_REF_NORM]
    raw_norm = vec_norm(m)
    if ref == 0.0:
        ref = raw_norm
    if vec_norm(b) >= s[_HI_MIN_BIAS] * ref:
        corrected = (m[0] - b[0], m[1] - b[1], m[2] - b[2])
        if abs(vec_norm(corrected) - ref) < abs(raw_norm - ref):
            return corrected
    return m


@njit(**COMPILE)
def kalman_correct_mag(q, bias, P, gate, mag, has_mag, omega, s, dx, K, row, acc_used):
    """Magnetometer part of :func:`kalman_correct`; returns ``(q, acc_used, mag_used)``."""
    dt = s[_DT]
    # --- Magnetometer: heading update, gated on norm and dip ----------------------------
    mag_used = False
    if has_mag:
        mag = kalman_hard_iron(gate, mag, omega, s)
        m_norm = vec_norm(mag)
        m_e = quat_rotate(q, (mag[0], mag[1], mag[2]))
        dip = math.atan2(-m_e[2], math.hypot(m_e[0], m_e[1]))
        if gate[_REF_NORM] == 0.0:  # first sample: it defines the reference
            gate[_REF_NORM], gate[_REF_DIP] = m_norm, dip
            gate[_CAND_NORM], gate[_CAND_DIP] = m_norm, dip
        # The dip is seen through the estimated tilt: its tolerance widens by the tilt's std
        # (× mag_dip_tilt_sigmas), so a tilt that is merely uncertain (after a gap, in fast
        # motion) does not reject an undisturbed field.
        dip_tolerance = s[_MAG_DIP_GATE] + s[_MAG_DIP_TILT_SIGMAS] * math.sqrt(max(P[0, 0], P[1, 1]))
        undisturbed = (abs(m_norm - gate[_REF_NORM]) < s[_MAG_NORM_GATE] * gate[_REF_NORM]
                       and abs(dip - gate[_REF_DIP]) < dip_tolerance)
        if undisturbed:
            gate[_REF_NORM] += s[_MAG_REF_GAIN] * (m_norm - gate[_REF_NORM])
            gate[_REF_DIP] += s[_MAG_REF_GAIN] * (dip - gate[_REF_DIP])
            gate[_REJECT_T] = 0.0
        else:
            # A new field that stays consistent while the sensor turns becomes the reference.
            if (abs(m_norm - gate[_CAND_NORM]) < s[_MAG_NORM_GATE] * gate[_CAND_NORM]
                    and abs(dip - gate[_CAND_DIP]) < s[_MAG_DIP_GATE]):
                if vec_norm(omega) >= s[_MAG_NEW_MIN_RATE]:
                    gate[_CAND_T] += dt
                gate[_CAND_NORM] += s[_MAG_REF_GAIN] * (m_norm - gate[_CAND_NORM])
                gate[_CAND_DIP] += s[_MAG_REF_GAIN] * (dip - gate[_CAND_DIP])
            else:
                gate[_CAND_T] = 0.0
                gate[_CAND_NORM], gate[_CAND_DIP] = m_norm, dip
            if gate[_CAND_T] >= s[_MAG_NEW_TIME]:
                gate[_REF_NORM], gate[_REF_DIP] = gate[_CAND_NORM], gate[_CAND_DIP]
                gate[_CAND_T] = 0.0
                gate[_REJECT_T] = 0.0
                undisturbed = True
            else:
                gate[_REJECT_T] += dt
        # Heading seen through an uncertain tilt: a tilt error ε moves the measured heading by
        # up to tan(dip)·ε, so that variance is added (the gain's tilt rows stay zero).
        tan_dip = math.tan(min(abs(gate[_REF_DIP]), 1.5))
        r = s[_MAG_VAR] + tan_dip * tan_dip * max(P[0, 0], P[1, 1])
        use = undisturbed
        if not undisturbed and gate[_REJECT_T] > s[_MAG_MAX_REJECT]:
            use = True
            r *= s[_MAG_REJECT_VAR_FACTOR]
        if use and math.hypot(m_e[0], m_e[1]) > 0.0:
            psi = math.atan2(m_e[0], m_e[1])  # heading error δθ_z
            kalman_scalar_update(P, dx, 2, psi - dx[2], r, True, K, row)
            q = kalman_inject(q, bias, gate, dx, s[_BIAS_LIMIT])
            mag_used = True
    return q, acc_used, mag_used


# ------------------------------------------------------------------------------------------
# Gap: linear prediction of the angular rate (gap_rate_prediction)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def gap_rate_fit(rates, end, window, order, coef, A, r):
    """Fit the linear predictor of the rate on ``rates[end − window : end]``; returns its largest norm.

    Per axis ``a``, least squares for ``ω_a[k] ≈ Σ_i c_ai ω_a[k − order + i]`` over the window
    (an autoregressive model of order ``order``: a sum of damped oscillations, which is what
    an arm's swing looks like over a fraction of a second), with ridge ``AR_RIDGE ·
    max(1, tr(XᵀX)/order)`` on the normal equations, solved by Cholesky.  ``rates`` (T, 3)
    holds the bias-corrected rates the filter used; ``coef`` (3, order) receives the
    coefficients; ``A`` (order, order) and ``r`` (order,) are scratch.
    """
    lo = end - window
    for a in range(3):
        for i in range(order):
            r[i] = 0.0
            for j in range(order):
                A[i, j] = 0.0
        for k in range(lo, end - order):
            y = rates[k + order, a]
            for i in range(order):
                xi = rates[k + i, a]
                r[i] += xi * y
                for j in range(i + 1):
                    A[i, j] += xi * rates[k + j, a]
        trace = 0.0
        for i in range(order):
            trace += A[i, i]
        ridge = AR_RIDGE * max(1.0, trace / order)
        for i in range(order):  # in-place Cholesky of the lower triangle: A = L Lᵀ
            A[i, i] += ridge
            for j in range(i + 1):
                acc_ij = A[i, j]
                for k in range(j):
                    acc_ij -= A[i, k] * A[j, k]
                A[i, j] = math.sqrt(acc_ij) if i == j else acc_ij / A[j, j]
        for i in range(order):  # L y = r, then Lᵀ c = y
            acc_i = r[i]
            for k in range(i):
                acc_i -= A[i, k] * coef[a, k]
            coef[a, i] = acc_i / A[i, i]
        for i in range(order - 1, -1, -1):
            acc_i = coef[a, i]
            for k in range(i + 1, order):
                acc_i -= A[k, i] * coef[a, k]
            coef[a, i] = acc_i / A[i, i]
    largest = 0.0
    for k in range(lo, end):
        largest = max(largest, math.sqrt(rates[k, 0] ** 2 + rates[k, 1] ** 2 + rates[k, 2] ** 2))
    return largest


@njit(**COMPILE)
def gap_rate_predict(rates, t, order, coef, largest, out):
    """One step of the linear predictor: ``out[a] = Σ_i coef[a, i] rates[t − order + i, a]``,
    its norm capped at ``largest`` (the window's largest rate: an unstable fit cannot run away)."""
    for a in range(3):
        v = 0.0
        for i in range(order):
            v += coef[a, i] * rates[t - order + i, a]
        out[a] = v
    norm = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
    if norm > largest:
        for a in range(3):
            out[a] *= largest / norm


@njit(**COMPILE)
def gap_rate_end_weights(coef, axis, order, n, h, weights):
    """Weights ``w_k`` (k = 1..n) of the end correction of the gap's predicted rates, one axis.

    The predictor is an autoregressive model ``ω[j] = Σ_i c_i ω[j − order + i] + e[j]`` with
    white innovations ``e``; the prediction error at the k-th step after the gap's start is
    ``Σ_{i=1..k} h[k − i] e[i]`` (``h`` the model's impulse response, ``h[0] = 1``).  Knowing the
    error at step ``n`` (the first received sample after the gap, measured minus predicted),
    the conditional expectation of the error at step ``k`` is ``w_k`` times it, with

        w_k = Σ_{i=1..k} h[k − i] h[n − i] / Σ_{j=0..n−1} h[j]²

    (Gaussian conditioning; ``w_n = 1``).  For a slowly varying rate (``h ≈ 1``) this is the
    linear ramp ``k/n``; for an oscillation it follows the oscillation instead of ramping
    across it.  If the impulse response grows beyond 1e50 (an unstable fit over a long gap),
    the linear ramp is used.  ``h``, ``weights`` (≥ n,) are written.
    """
    h[0] = 1.0
    unstable = False
    for j in range(1, n):
        v = 0.0
        for i in range(order):
            lag = j - order + i  # h at a negative index is 0
            if lag >= 0:
                v += coef[axis, i] * h[lag]
        h[j] = v
        if abs(v) > 1e50:
            unstable = True
            break
    if unstable:
        for k in range(1, n + 1):
            weights[k - 1] = k / n
        return
    den = 0.0
    for j in range(n):
        den += h[j] * h[j]
    for k in range(1, n + 1):
        cov = 0.0
        for i in range(1, k + 1):
            cov += h[k - i] * h[n - i]
        weights[k - 1] = cov / den


# ------------------------------------------------------------------------------------------
# Kalman filter: one stream (also the forward pass of the smoother), a batch in parallel
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def kalman_initial_covariance(s, P):
    """``P0 = diag(σ_tilt², σ_tilt², σ_heading², σ_b² I₃, σ_v² I₃)`` into ``P`` (NX, NX)."""
    for a in range(NX):
        for b in range(NX):
            P[a, b] = 0.0
    P[0, 0] = s[_INIT_TILT_VAR]
    P[1, 1] = s[_INIT_TILT_VAR]
    P[2, 2] = s[_INIT_HEADING_VAR]
    for a in range(3, 6):
        P[a, a] = s[_INIT_BIAS_VAR]
        P[a + 3, a + 3] = s[_VEL_VAR]


@njit(**COMPILE)
def kalman_stream(gyr, acc, mag, has_mag, received, q_init, start, init_only, s,
                  out_q, out_bias, out_vel, out_P, keep_P, acc_used, mag_used,
                  record, pred_q, pred_bias, pred_vel, pred_P, pred_F):
    """The filter over one recording ``(T, 3)`` into ``out_q`` (T, 4), ``out_bias``, ``out_vel`` (T, 3).

    ``start``: first sample the filter sees; ``init_only``: that sample only initialises
    (``q0=None``), else it is filtered from ``q_init`` like any other.  Samples before the
    start output ``q_init``.  ``keep_P``: write ``P⁺`` into ``out_P`` (T, NX, NX).  ``record``:
    also write the predictions ``q⁻``, ``b⁻``, ``v̂⁻``, ``P⁻`` and the transition matrix ``F``
    of every sample (for the RTS smoother).  ``acc_used``, ``mag_used`` (T,) say which
    measurements were taken.
    """
    n_t = out_q.shape[0]
    P = np.empty((NX, NX))
    R = np.empty((3, 3))
    F = np.empty((NX, NX))
    FP = np.empty((NX, NX))
    bias = np.zeros(3)
    held_rate = np.zeros(3)
    gate = np.zeros(_N_GATE)
    dx = np.zeros(NX)
    K = np.zeros(NX)
    row = np.zeros(NX)
    kalman_initial_covariance(s, P)
    q = (q_init[0], q_init[1], q_init[2], q_init[3])
    first = start + 1 if init_only else start
    for t in range(min(first, n_t)):
        for a in range(4):
            out_q[t, a] = q[a]
        for a in range(3):
            out_bias[t, a] = 0.0
            out_vel[t, a] = 0.0
        if keep_P:
            out_P[t] = P
        acc_used[t] = False
        mag_used[t] = False
        if record:
            for a in range(4):
                pred_q[t, a] = q[a]
            for a in range(3):
                pred_bias[t, a] = 0.0
                pred_vel[t, a] = 0.0
            pred_P[t] = P
            for a in range(NX):
                for b in range(NX):
                    pred_F[t, a, b] = 1.0 if a == b else 0.0
    replay = s[_GAP_REPLAY] != 0.0
    dt = s[_DT]
    # Gap's linear prediction: the rates used at every sample (the window it is fitted on).
    order = int(s[_AR_ORDER])
    window = int(s[_AR_WINDOW])
    use_ar = s[_AR_ON] != 0.0 and window >= 3 * order
    rates = np.zeros((n_t if use_ar else 1, 3))
    coef = np.zeros((3, order))
    ar_A = np.empty((order, order))
    ar_r = np.empty(order)
    predicted = np.zeros(3)
    gap_predicted = False  # this gap's rates come from the linear prediction
    largest = 0.0
    history_start = start  # first sample whose rate is in `rates`
    last_rx = start if init_only else -1  # last received sample the filter has used
    q_last = q  # the state after it, and its bias-corrected rate
    rate_last = np.zeros(3)
    if init_only and start < n_t:
        for a in range(3):
            rate_last[a] = gyr[start, a]
            if use_ar:
                rates[start, a] = gyr[start, a]
    for t in range(first, n_t):
        ok = received[t]
        if use_ar and not ok:
            if t == first or received[t - 1]:  # a gap starts: fit the predictor on the last window
                gap_predicted = t - window >= history_start
                if gap_predicted:
                    largest = gap_rate_fit(rates, t, window, order, coef, ar_A, ar_r)
            if gap_predicted:
                gap_rate_predict(rates, t, order, coef, largest, predicted)
        if ok and replay and last_rx >= 0 and t - last_rx > 1 and use_ar and gap_predicted:
            # Gap replay with the linear prediction: the rates the gap used, plus the predictor's
            # error at this sample (measured − predicted) spread over the gap by its conditional
            # expectation (gap_rate_end_weights).
            n_lost = t - last_rx - 1
            gap_rate_predict(rates, t, order, coef, largest, predicted)
            impulse = np.empty(n_lost + 1)
            weights = np.empty((3, n_lost + 1))
            for a in range(3):
                gap_rate_end_weights(coef, a, order, n_lost + 1, impulse, weights[a])
            q = q_last
            for k in range(1, n_lost + 1):
                w0 = rates[last_rx + k, 0] + weights[0, k - 1] * (gyr[t, 0] - bias[0] - predicted[0])
                w1 = rates[last_rx + k, 1] + weights[1, k - 1] * (gyr[t, 1] - bias[1] - predicted[1])
                w2 = rates[last_rx + k, 2] + weights[2, k - 1] * (gyr[t, 2] - bias[2] - predicted[2])
                q = quat_normalize(quat_multiply(q, quat_exp((w0 * dt, w1 * dt, w2 * dt))))
        elif ok and replay and last_rx >= 0 and t - last_rx > 1:
            # Gap replay: the gap's samples were output as the extrapolation; now that the rate
            # after the gap is known, the state at its end is re-integrated from the last
            # received state with the rate interpolated linearly between both ends (the
            # paper's gyroscope interpolation, applied to the filter's state; P keeps the
            # growth of the gap).
            n_lost = t - last_rx - 1
            q = q_last
            for k in range(1, n_lost + 1):
                frac = k / (n_lost + 1.0)
                w0 = rate_last[0] + frac * (gyr[t, 0] - bias[0] - rate_last[0])
                w1 = rate_last[1] + frac * (gyr[t, 1] - bias[1] - rate_last[1])
                w2 = rate_last[2] + frac * (gyr[t, 2] - bias[2] - rate_last[2])
                q = quat_normalize(quat_multiply(q, quat_exp((w0 * dt, w1 * dt, w2 * dt))))
        q = kalman_predict(q, bias, P, held_rate, gate, gyr[t], acc[t], ok, s, R, F, FP, predicted,
                           use_ar and gap_predicted)
        if use_ar:
            for a in range(3):
                rates[t, a] = held_rate[a]
        if record:
            for a in range(4):
                pred_q[t, a] = q[a]
            for a in range(3):
                pred_bias[t, a] = bias[a]
                pred_vel[t, a] = gate[_VEL + a]
            pred_P[t] = P
            pred_F[t] = F
        used_a, used_m = False, False
        if ok:
            omega = (held_rate[0], held_rate[1], held_rate[2])
            q, used_a, used_m = kalman_correct(q, bias, P, gate, acc[t], mag[t if has_mag else 0], has_mag, omega, s,
                                               dx, K, row)
            last_rx, q_last = t, q
            for a in range(3):
                rate_last[a] = omega[a]
        for a in range(4):
            out_q[t, a] = q[a]
        for a in range(3):
            out_bias[t, a] = bias[a]
            out_vel[t, a] = gate[_VEL + a]
        if keep_P:
            out_P[t] = P
        acc_used[t] = used_a
        mag_used[t] = used_m


@njit(parallel=True, **COMPILE)
def run_kalman(gyr, acc, mag, has_mag, received, index, q_init, start, init_only, s,
               out_q, out_bias, out_vel, out_P, keep_P, acc_used, mag_used):
    """:func:`kalman_stream` on every element ``n`` of a flattened batch, in parallel.

    ``index`` (N, 4): for element ``n`` the rows of ``gyr``, ``acc``, ``mag`` (each
    ``(M, T, 3)``) and ``received`` ``(M', T)`` it reads (broadcasting without copies).
    """
    p_stride = 1 if keep_P else 0
    n_batch = out_q.shape[0]
    none4 = np.empty((1, 4))
    none3 = np.empty((1, 3))
    none_p = np.empty((1, NX, NX))
    for n in prange(n_batch):
        p = n * p_stride  # row of out_P: n, or 0 when P is not kept
        kalman_stream(gyr[index[n, 0]], acc[index[n, 1]], mag[index[n, 2]], has_mag, received[index[n, 3]],
                      q_init[n], start[n], init_only, s, out_q[n], out_bias[n], out_vel[n], out_P[p], keep_P,
                      acc_used[n], mag_used[n], False, none4, none3, none3, none_p, none_p)
