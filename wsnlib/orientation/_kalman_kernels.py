"""The gap-aware Kalman filter's compiled step and its loop over time.

The equations are in :mod:`wsnlib.orientation.kalman`'s docstring (names below follow it); the
same equations in plain numpy, matrix by matrix, are :class:`wsnlib.orientation.kalman.KalmanReference`.
One stream's filter is a record of :data:`STATE_DTYPE` (``state.q``, ``state.bias``,
``state.velocity``, ``state.P``, the magnetometer gate's references and timers, the hard-iron
estimate), a gap record and rate history of :mod:`wsnlib.orientation.gaps`, and scratch
(:data:`WORK_DTYPE`, which also keeps the last prediction for the smoother); the constants of a
run are one record of :data:`wsnlib.orientation.kalman_settings.CONSTANTS_DTYPE` (``c.gyro_var``).
:func:`kalman_step` is one sample; :func:`kalman_stream` loops it over a recording (also the
forward pass of :func:`wsnlib.orientation.smooth_orientation`), without the GIL: a batch's streams
run on threads side by side (:func:`wsnlib.orientation._batch.in_threads`).  Quaternion helpers are
those of :mod:`._scalar_kernels`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wsnlib.orientation import gaps
from wsnlib.orientation._scalar_kernels import (
    COMPILE,
    PLAIN_FALSE,
    PLAIN_TRUE,
    PLAIN_ZERO,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    rotation_matrix,
    squared_norm3,
    vec_norm,
)

#: Error-state size: [δθ (3), δb (3), δv (3)].
NX = 9

#: One stream's filter: the estimate (quaternion body → ENU, gyro bias rad/s, leaky velocity
#: m/s in the earth frame, error covariance in the order of δx), the rate of the last prediction
#: (rad/s, bias-corrected) and the state after the last received sample (where a replay starts),
#: the gap's rate-error std, the magnetometer gate (reference norm and dip, 0 = unset; the
#: candidate's norm, dip and time; the time rejected), the hard-iron estimate's normal
#: equations (``hi_A``: 00 01 02 11 12 22 of the symmetric 3 × 3, ``hi_r``) and the forgotten sums of
#: the squared field-rate residuals and of the products of consecutive ones (``hi_syy``, ``hi_syy1``,
#: µT²/s²), the previous residual and whether it was of the previous sample (``hi_prev_y``, ``hi_prev_y_ok``),
#: the sums' weights and squared weights (``hi_w``, ``hi_w2``), the previous received field and rate, the
#: low-pass of (‖a‖ − g)² (``lin_var``, m²/s⁴), and the raw and hard-iron corrected field norms of the previous
#: received sample and the low-passes of their squared steps (``hi_prev_norms``, ``hi_norm_vars``: µT, µT²); the
#: magnetometer's lag estimate (s), the sums of its normal equation and the previous received raw field (``lag``,
#: ``lag_num``, ``lag_den``, ``lag_prev_mag``).
STATE_DTYPE = np.dtype([
    ("q", "f8", (4,)), ("bias", "f8", (3,)), ("velocity", "f8", (3,)), ("P", "f8", (NX, NX)),
    ("rate", "f8", (3,)), ("q_last", "f8", (4,)), ("gap_sigma", "f8"),
    ("mag_ref_norm", "f8"), ("mag_ref_dip", "f8"), ("mag_cand_norm", "f8"), ("mag_cand_dip", "f8"),
    ("mag_cand_time", "f8"), ("mag_reject_time", "f8"), ("mag_gate_norm", "f8"),
    ("mag_ref_time", "f8"),
    ("hi_A", "f8", (6,)), ("hi_r", "f8", (3,)), ("hi_prev_mag", "f8", (3,)), ("hi_prev_rate", "f8", (3,)),
    ("hard_iron", "f8", (3,)), ("hi_syy", "f8"), ("lin_var", "f8"), ("hi_prev_ok", "?"),
    ("hi_syy1", "f8"), ("hi_prev_y", "f8", (3,)), ("hi_prev_y_ok", "?"), ("hi_w", "f8"), ("hi_w2", "f8"),
    ("hi_prev_norms", "f8", (2,)), ("hi_norm_vars", "f8", (2,)),
    ("lag", "f8"), ("lag_num", "f8"), ("lag_den", "f8"), ("lag_prev_mag", "f8", (3,)),
])

#: Entries of a covariance's upper triangle (row by row): how the smoother stores P.
NP = NX * (NX + 1) // 2

#: Most scalar updates one sensor makes at a sample (the accelerometer's two tilt and three
#: velocity updates).
MAX_UPDATES = 5
#: Products of a sample's covariance update (:func:`subtract_products`): the accelerometer's
#: :data:`MAX_UPDATES`, then the heading's (at index :data:`HEADING_PRODUCT`).
N_PRODUCTS = MAX_UPDATES + 1
HEADING_PRODUCT = MAX_UPDATES
# subtract_products and after_acc write their sums out term by term for these counts
assert (MAX_UPDATES, N_PRODUCTS) == (5, 6), "rewrite subtract_products and after_acc for the new counts"

#: Scratch of one stream, and the prediction of the last sample (``q_pred``, ``bias_pred``,
#: ``vel_pred``, ``P_pred``; ``R`` = R(q⁻) and ``a_e`` = a_E, which define the transition F; ``noise``
#: Q's diagonal, attitude and velocity, :func:`add_process_noise`) kept for the smoother.  A sensor's
#: scalar updates (:func:`scalar_updates`) read their measurements from ``index`` (i of ``H = e_iᵀ``),
#: ``z`` and ``r`` (noise variance), and leave the covariance's change as products
#: ``P ← P − Σ_u gains_u rows_uᵀ``, to which the heading update adds its own; the sample's
#: :func:`subtract_products` applies them all.
WORK_DTYPE = np.dtype([
    ("R", "f8", (3, 3)), ("a_e", "f8", (3,)), ("dx", "f8", (NX,)),
    ("index", "i8", (MAX_UPDATES,)), ("z", "f8", (MAX_UPDATES,)), ("r", "f8", (MAX_UPDATES,)),
    ("gains", "f8", (N_PRODUCTS, NX)), ("rows", "f8", (N_PRODUCTS, NX)),
    ("ar_A", "f8", (3, gaps.MAX_ORDER, gaps.MAX_ORDER + 1)), ("ar_r", "f8", (3, gaps.MAX_ORDER + 1)),
    ("q_pred", "f8", (4,)), ("bias_pred", "f8", (3,)), ("vel_pred", "f8", (3,)), ("P_pred", "f8", (NX, NX)),
    ("noise", "f8", (2,)),
])


@njit(**COMPILE)
def initial_state(st, c, q0):
    """The state before the first sample in ``st``, a record of zeros (``np.zeros(1, STATE_DTYPE)[0]``,
    or one this function set and nothing stepped): ``q0``, no bias or velocity, ``P0 = diag(σ_tilt²,
    σ_tilt², σ_heading², σ_b² I₃, σ_v² I₃)``, the gate unset (every other field stays 0)."""
    for a in range(4):
        st.q[a] = q0[a]
        st.q_last[a] = q0[a]
    P = st.P
    P[0, 0] = P[1, 1] = c.init_tilt_var
    P[2, 2] = c.init_heading_var
    for a in range(3, 6):
        P[a, a] = c.init_bias_var
        P[a + 3, a + 3] = c.init_vel_var


@njit(**COMPILE)
def small_rotation(v):
    """``Exp(v) = [cos(θ/2), sin(θ/2) v/θ]`` (θ = ‖v‖, rad) as :func:`quat_exp` gives it, but below
    θ = 0.1 rad (a step's rotation or correction) by the Taylor series of cos(θ/2) and sin(θ/2)/θ
    in h = (θ/2)², to h⁵ and h⁴: the first terms left out are below 1e-20 relative, and it costs
    a fraction of ``sin`` and ``cos``."""
    sq = squared_norm3(v[0], v[1], v[2])
    if sq >= 0.01:
        return quat_exp(v)
    h = 0.25 * sq
    w = 1.0 + h * (-1.0 / 2.0 + h * (1.0 / 24.0 + h * (-1.0 / 720.0 + h * (1.0 / 40320.0 + h * (-1.0 / 3628800.0)))))
    k = 0.5 + h * (-0.5 / 6.0 + h * (0.5 / 120.0 + h * (-0.5 / 5040.0 + h * (0.5 / 362880.0))))
    return w, k * v[0], k * v[1], k * v[2]


# ------------------------------------------------------------------------------------------
# Prediction
# ------------------------------------------------------------------------------------------


@njit(inline="always", **COMPILE)
def pack_upper(P, out):
    """The upper triangle of the symmetric ``P`` (9 × 9), row by row, into ``out`` (:data:`NP`,)."""
    k = 0
    for a in range(NX):
        for b in range(a, NX):
            out[k] = P[a, b]
            k += 1


@njit(inline="always", **COMPILE)
def packed_index(a, b):
    """Index of ``P[a, b]`` (a ≤ b) in :func:`pack_upper`'s row-by-row upper triangle."""
    return a * NX - a * (a - 1) // 2 + b - a


@njit(inline="always", **COMPILE)
def unpack_upper(packed, P):
    """The symmetric ``P`` (9 × 9) from its upper triangle ``packed`` (:func:`pack_upper`)."""
    k = 0
    for a in range(NX):
        for b in range(a, NX):
            P[a, b] = P[b, a] = packed[k]
            k += 1


# Copies written as loops: an array assignment (``a[:] = b``) compiles numba's shape check and its
# error message, seconds of compile time for each kernel that calls these.
@njit(inline="always", **COMPILE)
def copy_vector(src, dst):
    """``dst[i] = src[i]`` for every ``i`` of ``src`` (1-D)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@njit(inline="always", **COMPILE)
def copy_matrix(src, dst):
    """``dst[i, j] = src[i, j]`` for every entry of ``src`` (2-D)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@njit(**COMPILE)
def transition_matrix(R, a_e, decay, dt, F):
    """``F = [[I, −R Δt, 0], [0, I, 0], [−[a_E]× Δt, [a_E]× R Δt², c I]]`` into ``F`` (9 × 9), from
    ``R`` = R(q⁻) and ``a_e`` = a_E (0 when lost), as :func:`predict` leaves them in the work record."""
    for a in range(NX):
        for b in range(NX):
            F[a, b] = 1.0 if a == b else 0.0
    for a in range(3):
        for b in range(3):
            F[a, 3 + b] = -R[a, b] * dt
        F[6 + a, 6 + a] = decay
    F[6, 1], F[6, 2] = a_e[2] * dt, -a_e[1] * dt  # −[a_E]× Δt
    F[7, 0], F[7, 2] = -a_e[2] * dt, a_e[0] * dt
    F[8, 0], F[8, 1] = a_e[1] * dt, -a_e[0] * dt
    for a in range(3):  # [a_E]× R Δt² = (−[a_E]× Δt)(−R Δt)
        for b in range(3):
            F[6 + a, 3 + b] = F[6 + a, 0] * F[0, 3 + b] + F[6 + a, 1] * F[1, 3 + b] + F[6 + a, 2] * F[2, 3 + b]


@njit(inline="always", **COMPILE)
def transition_transpose_times(R, a_e, decay, dt, y, out):
    """``out = Fᵀ y`` (9,) for :func:`transition_matrix`'s F, from its non-zero blocks only:

        (Fᵀ y)_θ = y_θ + Nᵀ y_v,   (Fᵀ y)_b = Mᵀ y_θ + y_b + (N M)ᵀ y_v,   (Fᵀ y)_v = c y_v

    (M = −R Δt, N = −[a_E]× Δt).  Each entry of F is formed as :func:`transition_matrix` forms it
    and the terms are added in the order of the dense product, whose other terms are exact zeros:
    the same numbers, bit for bit, with ~40 multiply-adds instead of 81 and no F."""
    m = ((-R[0, 0] * dt, -R[0, 1] * dt, -R[0, 2] * dt),  # M = −R Δt
         (-R[1, 0] * dt, -R[1, 1] * dt, -R[1, 2] * dt),
         (-R[2, 0] * dt, -R[2, 1] * dt, -R[2, 2] * dt))
    # N = −[a_E]× Δt: rows (0, n01, n02), (n10, 0, n12), (n20, n21, 0)
    n01, n02 = a_e[2] * dt, -a_e[1] * dt
    n10, n12 = -a_e[2] * dt, a_e[0] * dt
    n20, n21 = a_e[1] * dt, -a_e[0] * dt
    y6, y7, y8 = y[6], y[7], y[8]
    out[0] = y[0] + n10 * y7 + n20 * y8  # y_θ + Nᵀ y_v
    out[1] = y[1] + n01 * y6 + n21 * y8
    out[2] = y[2] + n02 * y6 + n12 * y7
    for j in range(3):  # Mᵀ y_θ + y_b + (N M)ᵀ y_v, (N M)_ij = Σ_k N_ik M_kj
        nm0 = n01 * m[1][j] + n02 * m[2][j]
        nm1 = n10 * m[0][j] + n12 * m[2][j]
        nm2 = n20 * m[0][j] + n21 * m[1][j]
        out[3 + j] = m[0][j] * y[0] + m[1][j] * y[1] + m[2][j] * y[2] + y[3 + j] + nm0 * y6 + nm1 * y7 + nm2 * y8
    out[6], out[7], out[8] = decay * y6, decay * y7, decay * y8  # c y_v


@njit(inline="always", **COMPILE)
def propagate_covariance(P, R, a_e, decay, dt):
    """``P ← F P Fᵀ`` in place (9 × 9, exactly symmetric) for :func:`transition_matrix`'s F, from ``R`` =
    R(q⁻) and ``a_e`` = a_E (3-tuple or array; 0 when lost): :func:`predict`'s propagation, and the
    smoother's recomputation of P⁻ from the recorded P⁺ (the same operations, so the same bits).

    F is written as two shears F = F_v F_θ:
    F_θ = [[I, M, 0], [0, I, 0], [0, 0, I]], M = −R(q⁻) Δt: the attitude error takes up the
    bias error.  F_v = [[I, 0, 0], [0, I, 0], [N, 0, c I]], N = −[a_E]× Δt: the velocity error
    takes up the tilt error (a_E = 0 when lost).  F_v F_θ = [[I, M, 0], [0, I, 0], [N, N M, c I]]
    is the module docstring's F.  A shear S P Sᵀ changes one block row and, symmetrically, the same
    block column: the row is computed, its diagonal block gets the column's term too, and the
    column is the row's mirror (~200 multiply-adds instead of a dense F P Fᵀ's ~1,500; P stays
    exactly symmetric).
    """
    # M = −R Δt and a_E read once: the updates of P below write to memory that the compiler
    # cannot tell apart from R's.
    m00, m01, m02 = -R[0, 0] * dt, -R[0, 1] * dt, -R[0, 2] * dt
    m10, m11, m12 = -R[1, 0] * dt, -R[1, 1] * dt, -R[1, 2] * dt
    m20, m21, m22 = -R[2, 0] * dt, -R[2, 1] * dt, -R[2, 2] * dt
    n0, n1, n2 = a_e[0] * dt, a_e[1] * dt, a_e[2] * dt

    # P ← F_θ P F_θᵀ.  Rows δθ: P_θ· ← P_θ· + M P_b· (every column) ...
    for j in range(NX):
        b0, b1, b2 = P[3, j], P[4, j], P[5, j]
        P[0, j] += m00 * b0 + m01 * b1 + m02 * b2
        P[1, j] += m10 * b0 + m11 * b1 + m12 * b2
        P[2, j] += m20 * b0 + m21 * b1 + m22 * b2
    # ... and block θθ also + P_θb Mᵀ (P_θb as just updated), upper triangle, mirrored.
    for a in range(3):
        p3, p4, p5 = P[a, 3], P[a, 4], P[a, 5]
        t0 = P[a, 0] + (p3 * m00 + p4 * m01 + p5 * m02)
        t1 = P[a, 1] + (p3 * m10 + p4 * m11 + p5 * m12)
        t2 = P[a, 2] + (p3 * m20 + p4 * m21 + p5 * m22)
        if a == 0:
            P[0, 0], P[0, 1], P[0, 2] = t0, t1, t2
        elif a == 1:
            P[1, 1], P[1, 2] = t1, t2
        else:
            P[2, 2] = t2
    P[1, 0], P[2, 0], P[2, 1] = P[0, 1], P[0, 2], P[1, 2]
    for a in range(3):
        for j in range(3, NX):
            P[j, a] = P[a, j]
    # P ← F_v P F_vᵀ.  Rows δv: P_v· ← c P_v· + N P_θ·, N u = (u × a_E) Δt = u × n, n = a_E Δt;
    # block vv also + (c P_vθ part) Nᵀ, i.e. the row's new θ entries crossed with n.
    for j in range(NX):
        u0, u1, u2 = P[0, j], P[1, j], P[2, j]
        P[6, j] = decay * P[6, j] + (u1 * n2 - u2 * n1)
        P[7, j] = decay * P[7, j] + (u2 * n0 - u0 * n2)
        P[8, j] = decay * P[8, j] + (u0 * n1 - u1 * n0)
    for a in range(3):
        u0, u1, u2 = P[6 + a, 0], P[6 + a, 1], P[6 + a, 2]
        P[6 + a, 6] = decay * P[6 + a, 6] + (u1 * n2 - u2 * n1)
        P[6 + a, 7] = decay * P[6 + a, 7] + (u2 * n0 - u0 * n2)
        P[6 + a, 8] = decay * P[6 + a, 8] + (u0 * n1 - u1 * n0)
    for a in range(3):
        for b in range(a + 1, 3):
            P[6 + a, 6 + b] = P[6 + b, 6 + a] = 0.5 * (P[6 + a, 6 + b] + P[6 + b, 6 + a])
        for j in range(6):
            P[j, 6 + a] = P[6 + a, j]


@njit(inline="always", **COMPILE)
def add_process_noise(P, noise, bias_var):
    """``P ← P + Q`` with ``Q = diag(noise[0] I₃, bias_var I₃, noise[1] I₃)``: the attitude's (gyro noise,
    plus the extrapolated rate's error over a gap) and the velocity's (the sensor's random walk, or the
    unknown linear acceleration over a gap) as :func:`predict` sets them in ``work.noise``."""
    for a in range(3):
        P[a, a] += noise[0]
        P[3 + a, 3 + a] += bias_var
        P[6 + a, 6 + a] += noise[1]

@njit(**COMPILE)
def predict(st, work, c, omega, acc, received, lost_run):
    """Prediction of one sample by the bias-corrected rate ``omega`` (3-tuple; over a gap the gap
    module's); ``lost_run``: samples lost in a row (0 when received).  Leaves R(q⁻) in ``work.R``
    and a_E in ``work.a_e`` (what defines the transition matrix, :func:`transition_matrix`)."""
    dt = c.dt
    for a in range(3):
        st.rate[a] = omega[a]
    # --- Strapdown prediction: q⁻ = q ⊗ Exp((ω − b) Δt) -----------------------------------
    q = (st.q[0], st.q[1], st.q[2], st.q[3])
    if omega[0] != 0.0 or omega[1] != 0.0 or omega[2] != 0.0:  # (gap="hold": exactly still)
        q = quat_normalize(quat_multiply(q, small_rotation((omega[0] * dt, omega[1] * dt, omega[2] * dt))))
    for a in range(4):
        st.q[a] = q[a]
    R = work.R
    rotation_matrix(q, R)
    a_e = (0.0, 0.0, 0.0)  # a_E = R(q⁻) a (0 when lost)
    if received:
        a_e = (R[0, 0] * acc[0] + R[0, 1] * acc[1] + R[0, 2] * acc[2],
               R[1, 0] * acc[0] + R[1, 1] * acc[1] + R[1, 2] * acc[2],
               R[2, 0] * acc[0] + R[2, 1] * acc[1] + R[2, 2] * acc[2])
    for a in range(3):
        work.a_e[a] = a_e[a]

    # --- Leaky velocity: v̂ ← c v̂ + (R(q⁻) a − g e_z) Δt (received), v̂ ← c v̂ (lost) -------
    decay = c.vel_decay
    v = st.velocity
    if received:
        v[0] = decay * v[0] + a_e[0] * dt
        v[1] = decay * v[1] + a_e[1] * dt
        v[2] = decay * v[2] + (a_e[2] - c.gravity) * dt
    else:
        for a in range(3):
            v[a] *= decay

    # --- Error propagation: P⁻ = F P Fᵀ + Q --------------------------------------------------
    propagate_covariance(st.P, R, a_e, decay, dt)
    # Q: gyro noise and bias random walk; over a gap, the extrapolated rate's error, whose std
    # is fixed at the gap's first sample: σ_gap,k² Δt² (2k − 1) makes it (σ_gap kΔt)² after k
    # samples.  Over a gap also the unknown linear acceleration: δv grows like (σ_gap,acc kΔt)².
    extra = 0.0
    extra_v = c.acc_sensor_var
    if not received:
        if lost_run == 1:
            st.gap_sigma = c.gap_noise + c.gap_relative_noise * vec_norm(omega)
        extra = (st.gap_sigma * dt) ** 2 * (2.0 * lost_run - 1.0)
        extra_v = c.gap_acc_var * (2.0 * lost_run - 1.0)
    work.noise[0], work.noise[1] = c.gyro_var + extra, extra_v
    add_process_noise(st.P, work.noise, c.bias_var)


# ------------------------------------------------------------------------------------------
# Measurement updates
# ------------------------------------------------------------------------------------------


@njit(inline="always", **COMPILE)
def zero_products(gains, rows, first, last):
    """Products ``first … last − 1`` to zero (unused at this sample: they subtract exact zeros)."""
    for u in range(first, last):
        for a in range(NX):
            gains[u, a] = 0.0
            rows[u, a] = 0.0


@njit(inline="always", **COMPILE)
def subtract_products(P, gains, rows):
    """``P ← P − Σ_u gains_u rows_uᵀ`` over the sample's :data:`N_PRODUCTS` products (unused ones zero)
    for a sum that is symmetric (as every covariance update below is): its upper triangle,
    mirrored, in one pass over P.  Each entry is one expression, the products subtracted in
    order: the accelerometer's (:func:`scalar_updates`), then the heading's (:func:`heading_update`),
    the same numbers as a pass per sensor."""
    r0, r1, r2, r3, r4, r5 = rows[0], rows[1], rows[2], rows[3], rows[4], rows[5]
    for a in range(NX):
        g0, g1, g2, g3, g4, g5 = gains[0, a], gains[1, a], gains[2, a], gains[3, a], gains[4, a], gains[5, a]
        for b in range(a, NX):
            v = P[a, b] - g0 * r0[b] - g1 * r1[b] - g2 * r2[b] - g3 * r3[b] - g4 * r4[b] - g5 * r5[b]
            P[a, b] = v
            P[b, a] = v


@njit(inline="always", **COMPILE)
def after_acc(P, gains, rows, a, b):
    """``P[a, b]`` (a ≤ b) after the accelerometer's updates, which :func:`subtract_products` applies
    later: the same expression, so the same bits."""
    return (P[a, b] - gains[0, a] * rows[0, b] - gains[1, a] * rows[1, b] - gains[2, a] * rows[2, b]
            - gains[3, a] * rows[3, b] - gains[4, a] * rows[4, b])


@njit(inline="always", **COMPILE)
def scalar_updates(P, dx, work, n):
    """The scalar updates u = 0 … n − 1 (module docstring) with ``H = e_iᵀ``, ``i = work.index[u]``,
    measurement ``work.z[u]``, noise variance ``work.r[u]``, in order, leaving P's change as products.

    With the optimal gain update u is ``P ← P − K_u P_i·`` (``K_u = P_·i/S_u``, ``S_u = P_ii + r_u``)
    and needs only row i of P after the earlier updates, ``row_u = P_i· − Σ_{w<u} K_w[i] row_w``;
    so the rows and gains come first (``δx += K_u (z_u − δx_i)``) and P takes
    ``− Σ_u K_u row_uᵀ`` once, with the heading's product, at the sample's end
    (:func:`subtract_products`; :func:`after_acc` reads an entry before).  Products n … 4 are zeroed.
    """
    gains, rows = work.gains, work.rows
    for u in range(n):
        i, row = work.index[u], rows[u]
        for a in range(NX):
            row[a] = P[i, a]
        for w in range(u):
            k_wi, earlier = gains[w, i], rows[w]
            for a in range(NX):
                row[a] -= k_wi * earlier[a]
        inv_S = 1.0 / (row[i] + work.r[u])
        innovation = work.z[u] - dx[i]
        gain = gains[u]
        for a in range(NX):
            gain[a] = row[a] * inv_S
            dx[a] += gain[a] * innovation
    zero_products(gains, rows, n, MAX_UPDATES)


@njit(inline="always", **COMPILE)
def heading_update(P, work, innovation, r):
    """The heading's scalar update (``H = e_2ᵀ``) with the gain's tilt rows zeroed (the magnetometer
    must not tilt), so in Joseph form (valid for any gain): ``P − K P_2· − P_·2 Kᵀ + S K Kᵀ``.
    Since ``S K_b = P_2b`` wherever K is not zeroed, that is ``P − P_·2 Kᵀ − K tᵀ`` with ``t`` =
    P_2· on the tilt entries and 0 elsewhere.  With ``p = P_·2`` and ``k_b = p_b/S`` (b ≥ 2, else
    0), entry (a, b) of the upper triangle (a ≤ b) loses ``p_a k_b`` when b ≥ 2 and nothing in
    the tilt block (a, b < 2): one more product for :func:`subtract_products` (gains ``p``, rows
    ``k``; ``p_a k_b`` with ``k_b = 0`` subtracts an exact zero), the same numbers as the two dense
    products, whose other terms are exact zeros.  P is read after the accelerometer's updates
    (:func:`after_acc`); ``work.dx`` takes ``K · innovation``."""
    gains, rows, dx = work.gains, work.rows, work.dx
    p = gains[HEADING_PRODUCT]
    k = rows[HEADING_PRODUCT]
    p[0], p[1] = after_acc(P, gains, rows, 0, 2), after_acc(P, gains, rows, 1, 2)
    for b in range(2, NX):
        p[b] = after_acc(P, gains, rows, 2, b)
    inv_S = 1.0 / (p[2] + r)
    k[0] = k[1] = 0.0
    for a in range(2, NX):
        k[a] = p[a] * inv_S  # K
        dx[a] += k[a] * innovation  # δx += K (z − δθ_z)


@njit(inline="always", **COMPILE)
def inject(st, dx, bias_limit):
    """``q ← Exp(δθ) ⊗ q``, ``b ← b + δb`` (clipped), ``v̂ ← v̂ + δv``, ``δx ← 0``."""
    q = quat_normalize(quat_multiply(small_rotation((dx[0], dx[1], dx[2])), (st.q[0], st.q[1], st.q[2], st.q[3])))
    for a in range(4):
        st.q[a] = q[a]
    for a in range(3):
        st.bias[a] = min(max(st.bias[a] + dx[3 + a], -bias_limit), bias_limit)
        st.velocity[a] += dx[6 + a]
    for a in range(NX):
        dx[a] = 0.0


@njit(**COMPILE)
def correct_acc(st, work, c, acc, omega):
    """The accelerometer's updates: the tilt (gated) and the leaky velocity's pseudo-measurement
    ``v = 0``, as one sequence of scalar updates and one injection; returns whether the tilt
    update was used.  Reads a_E = R(q⁻) a from ``work.a_e`` (:func:`predict`)."""
    P = st.P
    n = 0
    acc_norm = vec_norm(acc)
    deviation = abs(acc_norm - c.gravity)
    st.lin_var += c.acc_dist_gain * (deviation * deviation - st.lin_var)
    if deviation <= c.acc_norm_gate and vec_norm(omega) <= c.acc_rate_gate:
        e = (work.a_e[0] / acc_norm, work.a_e[1] / acc_norm, work.a_e[2] / acc_norm)  # R(q⁻) a/‖a‖
        cx, cy = e[1], -e[0]  # e × e_z
        sin_angle = math.sqrt(cx * cx + cy * cy)
        angle = math.atan2(sin_angle, e[2])
        if sin_angle > 0.0:
            phi_x, phi_y = angle * cx / sin_angle, angle * cy / sin_angle
        else:
            phi_x, phi_y = (angle, 0.0) if e[2] < 0.0 else (0.0, 0.0)
        # Linear acceleration tilts the measured direction: by at least |‖a‖ − g|/g now, and by
        # about the recent level (low-passed (‖a‖ − g)², × acc_disturbance_factor) sideways.
        r = c.acc_var + (deviation * deviation + c.acc_dist_factor * st.lin_var) / c.gravity ** 2
        # Innovation gate (robust, Huber): d² = φᵀ S⁻¹ φ with S = P_tilt + r I (2 × 2).  Beyond
        # the gate the sample is not dropped but S is scaled by d/√gate (r enlarged to match),
        # so its pull is bounded: an outlier moves the estimate little, while a filter that is
        # really off (e.g. after a long gap in fast motion) keeps being pulled back.
        s00, s01, s11 = P[0, 0] + r, P[0, 1], P[1, 1] + r
        d2 = (s11 * phi_x * phi_x - 2.0 * s01 * phi_x * phi_y + s00 * phi_y * phi_y) / (s00 * s11 - s01 * s01)
        if d2 > c.acc_innovation_gate:
            scale = math.sqrt(d2 / c.acc_innovation_gate)
            tilt_var = 0.5 * (P[0, 0] + P[1, 1])
            r = scale * (tilt_var + r) - tilt_var
        work.index[0], work.z[0], work.r[0] = 0, phi_x, r  # δθ_x = φ_x
        work.index[1], work.z[1], work.r[1] = 1, phi_y, r  # δθ_y = φ_y
        n = 2
    # --- Leaky velocity: pseudo-measurement v = 0 (every received sample) ----------------
    # Linear acceleration averages out (the position stays bounded), so the horizontal
    # leaky velocity stays small, while a tilt error δθ makes it ramp by g δθ Δt per sample:
    # VQF's low-pass of the earth-frame specific force (τ_acc), as a Kalman measurement.
    # v̂ + δv = 0: measurement −v̂ (the innovation −v̂ − δv_i takes in the tilt updates' δv).
    for a in range(3):
        work.index[n + a], work.z[n + a], work.r[n + a] = 6 + a, -st.velocity[a], c.vel_var
    scalar_updates(P, work.dx, work, n + 3)
    inject(st, work.dx, c.bias_limit)
    return n > 0


@njit(inline="always", **COMPILE)
def field_rate_residual(m, pm, omega, pw, rate):
    """``(ω̄, m̄, y)`` of two consecutive received samples (field ``pm`` then ``m``, bias-corrected
    rate ``pw`` then ``omega``; ``rate`` = 1/Δt): the midpoint rate and field, and ``y = ṁ + ω̄ × m̄``,
    which is 0 for the earth's field seen from a turning sensor (``ṁ = −ω × m``); what is left is
    what :func:`mag_lag` and :func:`hard_iron` estimate."""
    w = (0.5 * (omega[0] + pw[0]), 0.5 * (omega[1] + pw[1]), 0.5 * (omega[2] + pw[2]))
    mm = (0.5 * (m[0] + pm[0]), 0.5 * (m[1] + pm[1]), 0.5 * (m[2] + pm[2]))
    wxm = (w[1] * mm[2] - w[2] * mm[1], w[2] * mm[0] - w[0] * mm[2], w[0] * mm[1] - w[1] * mm[0])
    y = ((m[0] - pm[0]) * rate + wxm[0], (m[1] - pm[1]) * rate + wxm[1], (m[2] - pm[2]) * rate + wxm[2])
    return w, mm, y


@njit(**COMPILE)
def mag_lag(st, c, mag, omega):
    """Update the online estimate of the magnetometer's lag δ with one received field; returns the
    field advanced by it, ``m − δ̂ ω × m`` (``KalmanSettings.mag_lag_tau_s``).

    A field read δ late is ``m(t) = m_true(t − δ)``; with ``ṁ_true = −ω × m_true`` (the earth's field
    seen from a turning sensor), two consecutive received samples give ``y = ṁ + ω × m = (ω(t) −
    ω(t − δ)) × m ≈ δ ω̇ × m`` (ṁ, ω̇ from the two samples, m and ω at their midpoint).  With the
    unit field ``g = ω̇ × m/‖m‖``, ``δ̂ = Σ λ^k g·y/‖m‖ / (ε + Σ λ^k ‖g‖²)`` (each term × Δt; λ the
    forgetting, ε ``lag_ridge``), clipped to ``± lag_max``.  It runs on the raw field, before the
    hard-iron estimate (a magnet on the sensor adds ``ω × b_m`` to y, which averages out against ω̇ × m).
    """
    m = (mag[0], mag[1], mag[2])
    if c.lag_max == 0.0:
        return m
    pm, pw = st.lag_prev_mag, st.hi_prev_rate
    if st.hi_prev_ok:  # the previous sample was received (hard_iron keeps the flag and the rate)
        dt = c.dt
        rate = 1.0 / dt
        _, mm, y = field_rate_residual(m, pm, omega, pw, rate)
        norm = vec_norm(mm)
        if norm > 0.0:
            inv = 1.0 / norm
            wd = ((omega[0] - pw[0]) * rate, (omega[1] - pw[1]) * rate, (omega[2] - pw[2]) * rate)  # ω̇
            g = ((wd[1] * mm[2] - wd[2] * mm[1]) * inv, (wd[2] * mm[0] - wd[0] * mm[2]) * inv,
                 (wd[0] * mm[1] - wd[1] * mm[0]) * inv)
            lam = c.lag_decay
            st.lag_num = lam * st.lag_num + (g[0] * y[0] + g[1] * y[1] + g[2] * y[2]) * inv * dt
            st.lag_den = lam * st.lag_den + (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) * dt
            st.lag = min(max(st.lag_num / (c.lag_ridge + st.lag_den), -c.lag_max), c.lag_max)
    for k in range(3):
        pm[k] = m[k]
    d = st.lag
    wxm = (omega[1] * m[2] - omega[2] * m[1], omega[2] * m[0] - omega[0] * m[2], omega[0] * m[1] - omega[1] * m[0])
    return (m[0] - d * wxm[0], m[1] - d * wxm[1], m[2] - d * wxm[2])


@njit(**COMPILE)
def hard_iron(st, c, mag, omega):
    """Update the online hard-iron estimate with one received field; returns the field to use.

    A magnet or ferrous part fixed to the sensor adds a constant body-frame offset ``b_m``:
    ``m = Rᵀ m_E + b_m``.  Since ``d/dt (Rᵀ m_E) = −ω × (Rᵀ m_E)``, two consecutive received
    samples give ``ṁ + ω × m = ω × b_m`` (ṁ, ω, m at the midpoint), linear in ``b_m`` and
    independent of the orientation (gyroscope-aided hard-iron estimation).  ``b̂_m`` solves the
    exponentially forgotten (time constant ``mag_hard_iron_tau_s``) least-squares normal
    equations ``(A + εI) b = r``, ``A = Σ [ω]×ᵀ[ω]×``, ``r = Σ [ω]×ᵀ y``, ε the ridge
    (1 s at 0.3 rad/s), so it shrinks to 0 while the sensor does not turn.  ``m − b̂_m`` is
    returned if ``‖b̂_m‖ ≥ mag_hard_iron_min_bias · ‖m_ref‖`` and its norm is closer to the
    reference norm than the raw field's or steadier (``hi_norm_vars``: low-passes, with the same
    forgetting, of the squared change of each norm from one received sample to the next), or if the
    offset explains at least ``c.hi_min_explained``
    (:data:`~wsnlib.orientation.kalman_settings.MAG_HARD_IRON_EXPLAINED`) of the residuals' energy beyond
    the field's white noise, ``(Σ‖y‖² − Σ‖y − ω × b̂_m‖²)/S`` (``Σ‖y − ω × b̂_m‖² = Σ‖y‖² − 2 b̂·r + b̂ᵀ A
    b̂`` from the same sums: a magnet on the sensor seen in the data, whatever the reference norm, which
    lags a sensor whose gain drifts); otherwise ``m``.

    ``S`` leaves out the field's white noise, which no offset can explain and which the
    differentiation amplifies (its energy in ``y`` grows with the rate squared; BROAD trial 34 at
    50 Hz, at rest: 60 µT/s rms, as much as ``ω × b_m`` of a 20 µT magnet turning at 3 rad/s).
    Differentiated white noise ``(n_k − n_{k−1})/Δt`` has energy ``N`` per sample and the product of
    consecutive residuals ``−N/2`` on average, while a smooth residual (``ω × b_m``, a lag, a
    misalignment) has a product close to its energy ``S``: with ``Σ y_k·y_{k−1}`` (``hi_syy1``, same
    forgetting) ``Σ‖y‖² = S + N`` and ``Σ y_k·y_{k−1} = S − N/2`` give ``S = (Σ‖y‖² + 2 Σ y_k·y_{k−1})/3``.
    On white noise alone (``S = 0``) this estimate is a difference of large sums: it averages 0 with a
    standard deviation of ``√(2/27) N √(Σw²)/Σw`` (``w`` the forgetting weights, ``hi_w``, ``hi_w2``:
    ``1/√n`` for ``n`` pairs without forgetting), so the rule counts only while ``S`` is at least
    ``c.hi_significance`` (:data:`~wsnlib.orientation.kalman_settings.MAG_HARD_IRON_SIGNIFICANCE`) of
    them; otherwise a chance ``S`` near 0 would let any offset "explain" it.
    """
    m = (mag[0], mag[1], mag[2])
    A, rr, pm, pw, b = st.hi_A, st.hi_r, st.hi_prev_mag, st.hi_prev_rate, st.hard_iron
    had_y = st.hi_prev_y_ok
    st.hi_prev_y_ok = st.hi_prev_ok
    if st.hi_prev_ok:
        w, _, y = field_rate_residual(m, pm, omega, pw, 1.0 / c.dt)
        lam = c.hi_decay
        w2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
        # [ω]×ᵀ[ω]× = ‖ω‖² I − ω ωᵀ;  [ω]×ᵀ y = y × ω
        A[0] = lam * A[0] + w2 - w[0] * w[0]
        A[1] = lam * A[1] - w[0] * w[1]
        A[2] = lam * A[2] - w[0] * w[2]
        A[3] = lam * A[3] + w2 - w[1] * w[1]
        A[4] = lam * A[4] - w[1] * w[2]
        A[5] = lam * A[5] + w2 - w[2] * w[2]
        rr[0] = lam * rr[0] + (y[1] * w[2] - y[2] * w[1])
        rr[1] = lam * rr[1] + (y[2] * w[0] - y[0] * w[2])
        rr[2] = lam * rr[2] + (y[0] * w[1] - y[1] * w[0])
        st.hi_syy = lam * st.hi_syy + y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
        st.hi_w = lam * st.hi_w + 1.0
        st.hi_w2 = lam * lam * st.hi_w2 + 1.0
        py = st.hi_prev_y  # the residual of the previous pair, if that pair ended at the previous sample
        if had_y:
            st.hi_syy1 = lam * st.hi_syy1 + y[0] * py[0] + y[1] * py[1] + y[2] * py[2]
        else:
            st.hi_syy1 = lam * st.hi_syy1
        py[0], py[1], py[2] = y[0], y[1], y[2]
        # (A + εI) b = r by Cramer's rule (symmetric positive definite 3 × 3)
        eps = c.hi_ridge
        a00, a01, a02 = A[0] + eps, A[1], A[2]
        a11, a12, a22 = A[3] + eps, A[4], A[5] + eps
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        inv_det = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
        b[0] = (c00 * rr[0] + c01 * rr[1] + c02 * rr[2]) * inv_det
        b[1] = (c01 * rr[0] + c11 * rr[1] + c12 * rr[2]) * inv_det
        b[2] = (c02 * rr[0] + c12 * rr[1] + c22 * rr[2]) * inv_det
    ref = st.mag_ref_norm
    raw_norm = vec_norm(m)
    corrected = (m[0] - b[0], m[1] - b[1], m[2] - b[2])
    corrected_norm = vec_norm(corrected)
    # How fast each norm changes (low-pass of its squared step): the earth's field keeps its norm
    # while the sensor turns, a field with a magnet on the sensor does not, whatever the
    # reference norm (which lags a field whose strength drifts).
    steps, norms = st.hi_norm_vars, st.hi_prev_norms
    if st.hi_prev_ok:
        lam = c.hi_decay
        steps[0] = lam * steps[0] + (1.0 - lam) * (raw_norm - norms[0]) ** 2
        steps[1] = lam * steps[1] + (1.0 - lam) * (corrected_norm - norms[1]) ** 2
    norms[0], norms[1] = raw_norm, corrected_norm
    for k in range(3):
        pm[k] = m[k]
        pw[k] = omega[k]
    st.hi_prev_ok = True
    if ref == 0.0:
        ref = raw_norm
    if vec_norm((b[0], b[1], b[2])) >= c.hi_min_bias * ref:
        if abs(corrected_norm - ref) < abs(raw_norm - ref) or steps[1] < steps[0]:
            return corrected
        # Σ‖y − ω × b‖² = Σ‖y‖² − 2 b·r + bᵀ A b  (A = Σ [ω]×ᵀ[ω]×, r = Σ [ω]×ᵀ y, without the ridge)
        bab = (A[0] * b[0] * b[0] + A[3] * b[1] * b[1] + A[5] * b[2] * b[2]
               + 2.0 * (A[1] * b[0] * b[1] + A[2] * b[0] * b[2] + A[4] * b[1] * b[2]))
        unexplained = st.hi_syy - 2.0 * (b[0] * rr[0] + b[1] * rr[1] + b[2] * rr[2]) + bab
        smooth = (st.hi_syy + 2.0 * st.hi_syy1) / 3.0  # Σ‖y‖² without the field's white noise
        noise = st.hi_syy - smooth
        # S is significant: above hi_significance of its standard deviation on white noise alone,
        # √(2/27) N √(Σw²)/Σw (a difference of large sums when the residual is mostly noise)
        spread2 = (2.0 / 27.0) * noise * noise * st.hi_w2  # (its standard deviation × Σw)²
        significant = smooth > 0.0 and (smooth * st.hi_w) ** 2 >= c.hi_significance**2 * spread2
        if significant and st.hi_syy - unexplained >= c.hi_min_explained * smooth:
            return corrected
    return m


@njit(**COMPILE)
def correct_mag(st, work, c, mag, omega, lost):
    """Heading update from the magnetometer, gated on its norm and dip; returns whether it was used.
    ``lost``: samples lost right before this one (0 without a gap)."""
    dt = c.dt
    P = st.P
    mag = hard_iron(st, c, mag_lag(st, c, mag, omega), omega)
    m_norm = vec_norm(mag)
    m_e = quat_rotate((st.q[0], st.q[1], st.q[2], st.q[3]), (mag[0], mag[1], mag[2]))
    horizontal = math.sqrt(m_e[0] * m_e[0] + m_e[1] * m_e[1])
    dip = math.atan2(-m_e[2], horizontal)
    if st.mag_ref_norm == 0.0:  # first sample: a provisional reference (see mag_new_first_time_s)
        st.mag_ref_norm, st.mag_ref_dip, st.mag_gate_norm = m_norm, dip, m_norm
        st.mag_cand_norm, st.mag_cand_dip = m_norm, dip
    # The dip is seen through the estimated tilt: its tolerance widens by the tilt's std
    # (× mag_dip_tilt_sigmas), so a tilt that is merely uncertain (after a gap, in fast
    # motion) does not reject an undisturbed field.
    tilt_var = max(after_acc(P, work.gains, work.rows, 0, 0), after_acc(P, work.gains, work.rows, 1, 1))
    dip_tolerance = c.mag_dip_gate + c.mag_dip_tilt_sigmas * math.sqrt(tilt_var)
    dip_consistent = abs(dip - st.mag_ref_dip) < dip_tolerance
    # The norm gate's follower stands still while nothing is received: after L lost samples a
    # norm drifting by a fraction ρ per second lags it by ρ(τ + LΔt) instead of ρτ, so the gate
    # widens by 1 + LΔt/τ (the same largest drift rate passes as without a gap) and the follower
    # catches up with the gain of (L + 1)Δt.
    norm_gate, follow = c.mag_norm_gate, c.mag_gate_norm_gain
    if lost > 0:
        norm_gate *= 1.0 + lost * dt / c.mag_norm_tau
        follow = -math.expm1(-(lost + 1) * dt / c.mag_norm_tau)
    undisturbed = dip_consistent and abs(m_norm - st.mag_gate_norm) < norm_gate * st.mag_gate_norm
    if dip_consistent:
        # The gate's norm follows a field whose direction holds (a sensor's gain or the room's
        # field strength drifting): only a norm that changes faster than it follows is rejected.
        st.mag_gate_norm += follow * (m_norm - st.mag_gate_norm)
    # A reference not yet confirmed by mag_new_first_time_s of undisturbed fields (the first
    # sample's, taken in motion or in a disturbance) gives way to a field consistent that long.
    provisional = st.mag_ref_time < c.mag_new_first_time
    if undisturbed:
        st.mag_ref_norm += c.mag_ref_gain * (m_norm - st.mag_ref_norm)
        st.mag_ref_dip += c.mag_ref_gain * (dip - st.mag_ref_dip)
        st.mag_reject_time = 0.0
        st.mag_ref_time += dt
    else:
        # A new field that stays consistent while the sensor turns becomes the reference.
        if (abs(m_norm - st.mag_cand_norm) < c.mag_norm_gate * st.mag_cand_norm
                and abs(dip - st.mag_cand_dip) < c.mag_dip_gate):
            if provisional or vec_norm(omega) >= c.mag_new_min_rate:
                st.mag_cand_time += dt
            st.mag_cand_norm += c.mag_ref_gain * (m_norm - st.mag_cand_norm)
            st.mag_cand_dip += c.mag_ref_gain * (dip - st.mag_cand_dip)
        else:
            st.mag_cand_time = 0.0
            st.mag_cand_norm, st.mag_cand_dip = m_norm, dip
        if st.mag_cand_time >= (c.mag_new_first_time if provisional else c.mag_new_time):
            st.mag_ref_norm, st.mag_ref_dip = st.mag_cand_norm, st.mag_cand_dip
            st.mag_gate_norm = st.mag_cand_norm
            st.mag_ref_time = 0.0
            st.mag_cand_time = 0.0
            st.mag_reject_time = 0.0
            undisturbed = True
        else:
            st.mag_reject_time += dt
    # Heading seen through an uncertain tilt: a tilt error ε moves the measured heading by
    # up to tan(dip)·ε, so that variance is added (the gain's tilt rows stay zero).
    tan_dip = math.tan(min(abs(st.mag_ref_dip), 1.5))
    r = c.mag_var + tan_dip * tan_dip * tilt_var
    use = undisturbed
    if not undisturbed and st.mag_reject_time > c.mag_max_reject:
        use = True
        r *= c.mag_reject_var_factor
    if use and horizontal > 0.0:
        psi = math.atan2(m_e[0], m_e[1])  # heading error δθ_z
        heading_update(P, work, psi - work.dx[2], r)
        inject(st, work.dx, c.bias_limit)
        return True
    return False


# ------------------------------------------------------------------------------------------
# One sample, one recording, a batch
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def kalman_step(st, gs, history, work, c, gyr, acc, mag, received, replayed):
    """One sample of the filter: the gap module's rate or the measured one, the replay at a gap's
    end, the prediction and, if received, the measurement updates.  Returns ``(acc_used,
    mag_used)``.  ``gs``/``history``: :mod:`wsnlib.orientation.gaps`'s record and rate history;
    ``replayed`` (≥ L, 4): receives the replayed estimates of a gap of L samples that ends here
    (for a smoother; shape (0, 4) when not wanted)."""
    if not received:
        st.hi_prev_ok = False  # the hard-iron estimate differentiates consecutive received fields
        omega = gaps.gap_lost(gs, history, work.ar_A, work.ar_r)
        predict(st, work, c, omega, acc, PLAIN_FALSE, gs.lost)
        _keep_prediction(st, work, c)
        return False, False
    omega = (gyr[0] - st.bias[0], gyr[1] - st.bias[1], gyr[2] - st.bias[2])
    lost = gs.lost
    if c.replay and lost > 0 and gs.n > lost:
        _replay(st, gs, history, omega, c.dt, replayed)
    predict(st, work, c, omega, acc, PLAIN_TRUE, PLAIN_ZERO)
    _keep_prediction(st, work, c)
    gaps.gap_received(gs, history, omega)
    acc_used = correct_acc(st, work, c, acc, omega)
    zero_products(work.gains, work.rows, HEADING_PRODUCT, N_PRODUCTS)
    mag_used = correct_mag(st, work, c, mag, omega, lost) if c.has_mag else False
    subtract_products(st.P, work.gains, work.rows)  # P⁺: both sensors' updates in one pass
    for a in range(4):
        st.q_last[a] = st.q[a]
    return acc_used, mag_used


@njit(**COMPILE)
def _replay(st, gs, history, omega, dt, replayed):
    """Re-integrate the state over the gap that ends now from the state after its last received
    sample, with the gap module's replay rates (the covariance keeps the gap's growth); the
    k-th lost sample's estimate goes to ``replayed[k − 1]`` if it has the rows."""
    n_lost = gs.lost
    weights = np.empty((3, n_lost + 1))
    impulse = np.empty(n_lost + 1)
    predicted = np.empty(3)
    use_ar = gaps.replay_weights(gs, history, omega, weights, impulse, predicted)
    keep = replayed.shape[0] >= n_lost
    q = (st.q_last[0], st.q_last[1], st.q_last[2], st.q_last[3])
    for k in range(1, n_lost + 1):
        w = gaps.replay_rate(gs, history, k, omega, use_ar, weights, predicted)
        q = quat_normalize(quat_multiply(q, small_rotation((w[0] * dt, w[1] * dt, w[2] * dt))))
        if keep:
            for a in range(4):
                replayed[k - 1, a] = q[a]
    for a in range(4):
        st.q[a] = q[a]


@njit(**COMPILE)
def _keep_prediction(st, work, c):
    if c.record:
        copy_vector(st.q, work.q_pred)
        copy_vector(st.bias, work.bias_pred)
        copy_vector(st.velocity, work.vel_pred)
        copy_matrix(st.P, work.P_pred)


@njit(**COMPILE)
def new_records(n_t):
    """What :func:`kalman_stream` records for a smoother (``c.record``), ``n_t`` rows each: q⁻, v⁻,
    P⁺ packed (:func:`pack_upper`), R(q⁻) and a_E, which define F (:func:`transition_matrix`), and Q's
    diagonal (``work.noise``).  Not b⁻: it is the previous sample's b⁺ (the prediction keeps the bias).
    Not P⁻: ``P⁻_{k+1} = F_{k+1} P⁺_k F_{k+1}ᵀ + Q_{k+1}`` is recomputed from these
    (:func:`propagate_covariance`, :func:`add_process_noise`: the same operations, so the same bits),
    which takes the smoother's scratch from 118 to 75 numbers per sample."""
    return (np.empty((n_t, 4)), np.empty((n_t, 3)), np.empty((n_t, NP)), np.empty((n_t, 3, 3)), np.empty((n_t, 3)),
            np.empty((n_t, 2)))


@njit(**COMPILE)
def longest_lost_run(received, start):
    """Most samples lost in a row from sample ``start`` on (what the rate history must hold besides a window)."""
    longest = run = 0
    for t in range(start, received.shape[0]):
        run = 0 if received[t] else run + 1
        longest = max(longest, run)
    return longest


@njit(nogil=True, **COMPILE)
def kalman_stream(gyr, acc, mag, received, q_init, start, init_only, c, outputs):
    """The filter over one recording ``(T, 3)``; ``outputs`` receive, per sample, the estimate (``q``;
    ``bias``, ``velocity``, ``P`` where given T rows, else not written), the gate decisions and, with
    ``c.record``, :func:`new_records`' arrays (before the start, where a smoother does not read them,
    P⁺ = the initial P and zero ``R``, ``a_e``, Q).

    ``start``: first sample the filter sees; ``init_only``: that sample only initialises
    (``q0=None``), else it is filtered from ``q_init`` like any other.  Samples before the
    start output ``q_init``.
    """
    out_q, out_bias, out_vel, out_P, acc_used, mag_used = outputs[:6]
    pred_q, pred_vel, post_P, pred_R, pred_a_e, pred_noise = outputs[6:]
    n_t = out_q.shape[0]
    # bias, velocity, P are written only where the caller gave a row per sample (else one dummy row)
    keep_bias, keep_vel, keep_P = out_bias.shape[0] == n_t, out_vel.shape[0] == n_t, out_P.shape[0] == n_t
    # The records are views into these arrays, which must stay referenced while they are used.
    state_array, work_array, gap_array = np.zeros(1, STATE_DTYPE), np.zeros(1, WORK_DTYPE), np.zeros(1, gaps.GAP_DTYPE)
    st, work, gs = state_array[0], work_array[0], gap_array[0]
    initial_state(st, c, q_init)
    history = np.empty((gaps.history_length(c.ar_window, longest_lost_run(received, start)), 3))
    gs.mode, gs.factor, gs.order, gs.window = c.gap, c.gap_factor, c.ar_order, c.ar_window
    first = start + 1 if init_only else start
    if init_only and start < n_t:  # the first sample's rate opens the history
        gaps.gap_received(gs, history, (gyr[start, 0], gyr[start, 1], gyr[start, 2]))
    no_path = np.empty((0, 4))
    for t in range(n_t):
        if t >= first:
            # With c.record, a replayed gap's estimates overwrite what was recorded on its lost
            # samples (filtered = predicted there), so the smoother sees one consistent path.
            n_lost = gs.lost if c.record and received[t] and c.replay else 0
            path = pred_q[t - n_lost:t] if n_lost > 0 and t - n_lost >= first else no_path
            # The sample's readings as tuples, not row views (a view costs a reference count).
            m = t if c.has_mag else 0
            acc_used[t], mag_used[t] = kalman_step(st, gs, history, work, c, (gyr[t, 0], gyr[t, 1], gyr[t, 2]),
                                                   (acc[t, 0], acc[t, 1], acc[t, 2]),
                                                   (mag[m, 0], mag[m, 1], mag[m, 2]), received[t], path)
            for k in range(path.shape[0]):
                copy_vector(path[k], out_q[t - n_lost + k])
        else:
            acc_used[t], mag_used[t] = False, False
            _keep_prediction(st, work, c)
        # (the copies are inlined: their row views need no reference count)
        copy_vector(st.q, out_q[t])
        if keep_bias:
            copy_vector(st.bias, out_bias[t])
        if keep_vel:
            copy_vector(st.velocity, out_vel[t])
        if keep_P:
            copy_matrix(st.P, out_P[t])
        if c.record:
            copy_vector(work.q_pred, pred_q[t])
            copy_vector(work.vel_pred, pred_vel[t])
            copy_matrix(work.R, pred_R[t])
            copy_vector(work.a_e, pred_a_e[t])
            copy_vector(work.noise, pred_noise[t])
            pack_upper(st.P, post_P[t])
    # Keep the record arrays alive to here (the loop reads them through st, work, gs).
    state_array[0], work_array[0], gap_array[0] = st, work, gs


@njit(**COMPILE)
def long_rejections(used, received, fs, longest_s, counts):
    """Per row ``n`` of ``used`` and ``received`` (N, T) bool, into ``counts[n]``: how many times
    ``used`` stayed False on every received sample for longer than ``longest_s`` (s) at ``fs`` (Hz).

    Lost samples inside do not end a rejection; its length, ``(last − first + 1)/fs``, runs from its
    first to its last rejected received sample (the magnetometer's long rejections,
    :func:`wsnlib.orientation.kalman.long_mag_rejections`).  One pass, nothing allocated.
    """
    for n in range(used.shape[0]):
        count = 0
        first = last = -1  # the current rejection's first and last received samples (-1: none open)
        for t in range(used.shape[1]):
            if not received[n, t]:
                continue
            if not used[n, t]:
                if first < 0:
                    first = t
                last = t
                continue
            if first >= 0 and (last - first + 1) / fs > longest_s:
                count += 1
            first = -1
        if first >= 0 and (last - first + 1) / fs > longest_s:
            count += 1
        counts[n] = count
