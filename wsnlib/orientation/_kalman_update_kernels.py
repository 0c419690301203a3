"""Compiled kernels of the Kalman filter's measurement updates (:mod:`wsnlib.orientation.kalman`).

The scalar update (:func:`kalman_scalar_update`) and the injection of the error state
(:func:`kalman_inject`), the accelerometer's tilt update with the leaky velocity's
pseudo-measurement (:func:`kalman_correct`), the online hard-iron estimate
(:func:`kalman_hard_iron`) and the magnetometer's gated heading update
(:func:`kalman_correct_mag`).  The prediction and the loop over time are in
:mod:`._kalman_kernels`.
"""

from __future__ import annotations

import math

from numba import njit

from wsnlib.orientation._kalman_layout import (
    _ACC_DIST_FACTOR,
    _ACC_DIST_GAIN,
    _ACC_INNOVATION_GATE,
    _ACC_NORM_GATE,
    _ACC_RATE_GATE,
    _ACC_VAR,
    _BIAS_LIMIT,
    _CAND_DIP,
    _CAND_NORM,
    _CAND_T,
    _DT,
    _GRAVITY,
    _HI_A,
    _HI_B,
    _HI_DECAY,
    _HI_MIN_BIAS,
    _HI_R,
    _HI_RIDGE,
    _LIN_VAR,
    _MAG_DIP_GATE,
    _MAG_DIP_TILT_SIGMAS,
    _MAG_MAX_REJECT,
    _MAG_NEW_MIN_RATE,
    _MAG_NEW_TIME,
    _MAG_NORM_GATE,
    _MAG_REF_GAIN,
    _MAG_REJECT_VAR_FACTOR,
    _MAG_VAR,
    _PREV_M,
    _PREV_OK,
    _PREV_W,
    _REF_DIP,
    _REF_NORM,
    _REJECT_T,
    _VEL,
    _VEL_VAR,
    NX,
)
from wsnlib.orientation._kernels import (
    COMPILE,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    vec_norm,
)

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
