"""Compiled kernels of the gap-aware error-state Kalman filter (:mod:`wsnlib.orientation.kalman`).

The prediction of one sample (:func:`kalman_predict`), the loop over time of one recording
(:func:`kalman_stream`, also the forward pass of :func:`wsnlib.orientation.smooth_orientation`)
and its parallel batch driver (:func:`run_kalman`).  The other steps have their own modules,
whose names are re-exported here: the settings vector and state layout
(:mod:`._kalman_layout`), the measurement updates (:mod:`._kalman_update_kernels`) and the
gap's linear prediction of the rate (:mod:`._gap_rate_kernels`).  The scalar quaternion
helpers are those of :mod:`._kernels`, shared with Madgwick's filter.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from wsnlib.orientation._gap_rate_kernels import (
    AR_RIDGE,
    gap_rate_end_weights,
    gap_rate_fit,
    gap_rate_predict,
)
from wsnlib.orientation._kalman_layout import (
    _ACC_SENSOR_VAR,
    _AR_ON,
    _AR_ORDER,
    _AR_WINDOW,
    _BIAS_VAR,
    _DT,
    _GAP_ACC_VAR,
    _GAP_DECAY,
    _GAP_NOISE,
    _GAP_RELATIVE_NOISE,
    _GAP_REPLAY,
    _GAP_SIGMA,
    _GRAVITY,
    _GYRO_VAR,
    _INIT_BIAS_VAR,
    _INIT_HEADING_VAR,
    _INIT_TILT_VAR,
    _LOST_RUN,
    _N_GATE,
    _PREV_OK,
    _VEL,
    _VEL_DECAY,
    _VEL_VAR,
    KALMAN_AR_ON,
    KALMAN_AR_ORDER,
    KALMAN_AR_WINDOW,
    KALMAN_DT,
    KALMAN_GAP_REPLAY,
    KALMAN_VARIANCES,
    NX,
    kalman_settings_vector,
)
from wsnlib.orientation._kalman_update_kernels import (
    kalman_correct,
    kalman_correct_mag,
    kalman_hard_iron,
    kalman_inject,
    kalman_scalar_update,
)
from wsnlib.orientation._kernels import (
    COMPILE,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    rotation_matrix,
    vec_norm,
)

__all__ = [
    "AR_RIDGE", "KALMAN_AR_ON", "KALMAN_AR_ORDER", "KALMAN_AR_WINDOW", "KALMAN_DT", "KALMAN_GAP_REPLAY",
    "KALMAN_VARIANCES", "NX", "gap_rate_end_weights", "gap_rate_fit", "gap_rate_predict", "kalman_correct",
    "kalman_correct_mag", "kalman_hard_iron", "kalman_initial_covariance", "kalman_inject", "kalman_predict",
    "kalman_scalar_update", "kalman_settings_vector", "kalman_stream", "run_kalman",
]

# ------------------------------------------------------------------------------------------
# Kalman filter: prediction of one sample (equations in wsnlib.orientation.kalman's docstring)
# ------------------------------------------------------------------------------------------


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
