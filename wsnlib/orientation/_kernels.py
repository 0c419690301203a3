"""Compiled kernels of the orientation filters: one scalar step per equation group, a loop over time.

Every function here is compiled by numba (options :data:`COMPILE`) and works on plain floats
and tuples: a quaternion is a tuple ``(w, x, y, z)``, a vector ``(x, y, z)``.  A student can
read :func:`madgwick_update` next to Madgwick's report, :func:`triad` next to Shuster & Oh,
:func:`slerp_weight` and :func:`slerp` next to paper 001's eqs. (2)–(4), and
:func:`filter_stream` as the whole of :func:`wsnlib.orientation.estimate_orientation` for
one recording.  The gap-aware Kalman filter of :mod:`wsnlib.orientation.kalman` is here too
(:func:`kalman_predict`, :func:`kalman_correct`, :func:`kalman_correct_mag`,
:func:`kalman_stream`; equations in that module's docstring), with the quaternion helpers it
shares with :mod:`wsnlib.orientation.smoothing` (:func:`quat_exp`, :func:`quat_log`, …).
The ``run_*`` drivers loop over a flattened batch with ``prange`` (one thread
per core); which recording, mask and parameters batch element ``b`` uses is given by index
arrays, so broadcasting (one recording, many masks or a (ρ, τ) grid) copies nothing.

Nothing here validates: the public functions in :mod:`.madgwick`, :mod:`.loss_handling`
and :mod:`.triad` check their arguments (clear ``ValueError``\\ s) before calling a kernel,
and the kernels never read a lost sample.  A kernel that meets a non-finite state (an
overflow from extreme but finite parameters) reports it through its status array instead
of returning NaN.

The compiled code is cached next to this file (``__pycache__``) or under
``NUMBA_CACHE_DIR``: the first call in a fresh process loads it instead of compiling.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from wsnlib import frames

# ------------------------------------------------------------------------------------------
# Codes (ints, so that one compiled loop serves every method)
# ------------------------------------------------------------------------------------------

#: Loss-handling methods, in the order of :data:`wsnlib.orientation.loss_handling.METHODS`.
HOLD_LAST, DT_EXTENSION, GYRO_INTERPOLATION, ADAPTIVE_BETA, HYBRID = range(5)
#: λ schedules, in the order of :data:`wsnlib.orientation.loss_handling.SCHEDULES`.
DECAY, HOLD, INSTANT = range(3)
#: Hybrid blends: none, output stage, feedback into the state.
NO_BLEND, OUTPUT_BLEND, FEEDBACK_BLEND = range(3)
#: numba options of every kernel: machine code cached on disk; float division by zero gives
#: inf/NaN as in numpy (no exception check on every division), caught by the status below.
COMPILE = {"cache": True, "error_model": "numpy"}
#: Status of a batch element after a run.
OK, OVERFLOW = 0, 1

_C45 = math.sqrt(0.5)  # cos 45° = sin 45°
# SLERP's angle Ω is raised to at least this (rad), so that sin(kΩ)/sin Ω is k, not 0/0, when
# the two quaternions coincide; sin(x) = x exactly at this size, and kx stays a normal float.
_SLERP_TINY_ANGLE = 1e-150
# Below this |sin(angle)| between acc and mag the heading is undetermined (TRIAD).
PARALLEL_SIN_TOL = 1e-8
# Squared norms outside [_SMALL, _LARGE] are rescaled first, so that huge or tiny finite
# inputs (1e300, 1e-300) normalise without overflow or underflow.
_SMALL, _LARGE = 1e-280, 1e280


# ------------------------------------------------------------------------------------------
# Vectors and quaternions
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def squared_norm3(x, y, z):
    """``(x² + y²) + z²``, in this order wherever a squared norm is taken (same rounding)."""
    return x * x + y * y + z * z


@njit(**COMPILE)
def unit3(x, y, z):
    """``v/‖v‖`` for a finite non-zero vector; rescaled first when ‖v‖² would over/underflow."""
    sq = squared_norm3(x, y, z)
    if not (_SMALL < sq < _LARGE):
        m = max(abs(x), abs(y), abs(z))
        x, y, z = x / m, y / m, z / m
        sq = squared_norm3(x, y, z)
    inv = 1.0 / math.sqrt(sq)
    return x * inv, y * inv, z * inv


@njit(**COMPILE)
def quat_normalize(q):
    w, x, y, z = q
    sq = w * w + x * x + y * y + z * z
    if not (_SMALL < sq < _LARGE):
        m = max(abs(w), abs(x), abs(y), abs(z))
        w, x, y, z = w / m, x / m, y / m, z / m
        sq = w * w + x * x + y * y + z * z
    n = math.sqrt(sq)
    return w / n, x / n, y / n, z / n


@njit(**COMPILE)
def quat_multiply(p, q):
    """Hamilton product ``p ⊗ q``."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


@njit(**COMPILE)
def quat_conjugate(q):
    """``q*``: the inverse rotation of a unit quaternion."""
    return q[0], -q[1], -q[2], -q[3]


@njit(**COMPILE)
def quat_exp(v):
    """Rotation vector ``v`` (rad) → unit quaternion ``[cos(θ/2), sin(θ/2) v/θ]``, θ = ‖v‖."""
    theta = math.sqrt(squared_norm3(v[0], v[1], v[2]))
    half = 0.5 * theta
    if theta < 1e-8:  # sin(θ/2)/θ = 1/2 − θ²/48 + …; the θ² term is below rounding here
        k = 0.5
    else:
        k = math.sin(half) / theta
    return math.cos(half), k * v[0], k * v[1], k * v[2]


@njit(**COMPILE)
def quat_log(q):
    """Unit quaternion → rotation vector (rad) of the shorter rotation, angle in [0, π]."""
    w, x, y, z = q
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(squared_norm3(x, y, z))
    if s < 1e-12:  # 2·atan2(s, w)/s → 2/w (w ≈ 1)
        k = 2.0 / w
    else:
        k = 2.0 * math.atan2(s, w) / s
    return k * x, k * y, k * z


@njit(**COMPILE)
def quat_rotate(q, v):
    """``q ⊗ [0, v] ⊗ q*`` (body → earth for wsnlib's quaternions), ``v`` a 3-tuple or (3,) array."""
    w, x, y, z = q
    # v + 2w (u × v) + 2 u × (u × v), u = (x, y, z)
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    return (
        v[0] + w * tx + (y * tz - z * ty),
        v[1] + w * ty + (z * tx - x * tz),
        v[2] + w * tz + (x * ty - y * tx),
    )


@njit(**COMPILE)
def rotation_matrix(q, out):
    """``R(q)`` (body → earth) of a unit quaternion into the 3×3 array ``out``."""
    w, x, y, z = q
    out[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    out[0, 1] = 2.0 * (x * y - w * z)
    out[0, 2] = 2.0 * (x * z + w * y)
    out[1, 0] = 2.0 * (x * y + w * z)
    out[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    out[1, 2] = 2.0 * (y * z - w * x)
    out[2, 0] = 2.0 * (x * z - w * y)
    out[2, 1] = 2.0 * (y * z + w * x)
    out[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit(**COMPILE)
def vec_norm(v):
    """Euclidean norm of a 3-vector (3-tuple or (3,) array)."""
    return math.sqrt(squared_norm3(v[0], v[1], v[2]))


@njit(**COMPILE)
def cross3(a, b):
    """``a × b`` of two 3-vectors (tuples or (3,) arrays), as a tuple."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(**COMPILE)
def nwu_from_enu(q):
    """``q_NWU = q_z(+90°)* ⊗ q_ENU = c·[w + z, x + y, y − x, z − w]``, c = cos 45°."""
    w, x, y, z = q
    return (w + z) * _C45, (x + y) * _C45, (y - x) * _C45, (z - w) * _C45


@njit(**COMPILE)
def enu_from_nwu(q):
    """``q_ENU = q_z(+90°) ⊗ q_NWU = c·[w − z, x − y, x + y, z + w]``, c = cos 45°."""
    w, x, y, z = q
    return (w - z) * _C45, (x - y) * _C45, (x + y) * _C45, (z + w) * _C45


@njit(**COMPILE)
def is_finite4(q):
    return math.isfinite(q[0]) and math.isfinite(q[1]) and math.isfinite(q[2]) and math.isfinite(q[3])


# ------------------------------------------------------------------------------------------
# Madgwick's filter (report: S. O. H. Madgwick, University of Bristol, 2010)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def madgwick_gradient(q, a, m, use_mag):
    """Half the objective-function gradient ½ Jᵀ f, NWU, eqs. (25)–(34) and (45)–(46).

    ``q`` unit (NWU), ``a`` and ``m`` unit body-frame vectors (``m`` ignored unless
    ``use_mag``).  The common factor 2 of J is dropped: only the direction of ∇f is used,
    eq. (44).  Expressions are ordered as in the report's expanded formulas.
    """
    qw, qx, qy, qz = q
    ax, ay, az = a
    two_w, two_x, two_y, two_z = 2.0 * qw, 2.0 * qx, 2.0 * qy, 2.0 * qz
    xx, xy, xz = two_x * qx, two_x * qy, two_x * qz
    yy, yz, zz = two_y * qy, two_y * qz, two_z * qz
    wx, wy, wz = two_w * qx, two_w * qy, two_w * qz
    # Third row of R (body → NWU): earth z in the body frame.
    r31, r32, r33 = xz - wy, yz + wx, 1.0 - xx - yy
    # Eq. (25): f_g = q* ⊗ [0, 0, 0, 1] ⊗ q − a.
    e1, e2, e3 = r31 - ax, r32 - ay, r33 - az
    jw = jx = jy = jz = 0.0
    bx = 0.0
    if use_mag:
        mx, my, mz = m
        r11, r12, r13 = 1.0 - yy - zz, xy - wz, xz + wy
        r21, r22, r23 = xy + wz, 1.0 - xx - zz, yz - wx
        # Eq. (45): h = q ⊗ [0, m] ⊗ q* = R m.
        h1 = r11 * mx + r12 * my + r13 * mz
        h2 = r21 * mx + r22 * my + r23 * mz
        h3 = r31 * mx + r32 * my + r33 * mz
        # Eq. (46): b = [0, √(h_x² + h_y²), 0, h_z].
        bx = math.sqrt(h1 * h1 + h2 * h2)
        bz = h3
        # Eq. (29): f_b = b_x (row 1 of R) + b_z (row 3 of R) − m.
        f4 = r11 * bx + r31 * bz - mx
        f5 = r12 * bx + r32 * bz - my
        f6 = r13 * bx + r33 * bz - mz
        # Eqs. (30), (32), (34): J_gᵀ (f_g + b_z f_b) + b_x J_xᵀ f_b (halved, like J_g).
        e1, e2, e3 = e1 + f4 * bz, e2 + f5 * bz, e3 + f6 * bz
        jw = qy * f6 - qz * f5
        jx = qy * f5 + qz * f6
        jy = qx * f5 + qw * f6 - two_y * f4
        jz = qx * f6 - qw * f5 - two_z * f4
    # Eqs. (26), (34): J_gᵀ e.
    gw = qx * e2 - qy * e1
    gx = qz * e1 + qw * e2 - two_x * e3
    gy = qz * e2 - qw * e1 - two_y * e3
    gz = qx * e1 + qy * e2
    if use_mag:
        gw, gx, gy, gz = gw + jw * bx, gx + jx * bx, gy + jy * bx, gz + jz * bx
    return gw, gx, gy, gz


@njit(**COMPILE)
def madgwick_update(q, g, a, m, use_mag, dt_gyro, beta_dt):
    """One update of Madgwick's filter, ENU in and out (NWU inside, as the report).

    ``q`` unit ENU quaternion, ``g`` angular rate (rad/s), ``a``, ``m`` unit vectors (body),
    ``dt_gyro`` the interval the rate is integrated over (s), ``beta_dt = β·Δt`` the length of
    the correction step (0: gyroscope only, no gradient is computed).
    """
    qn = nwu_from_enu(q)
    qw, qx, qy, qz = qn
    step = 0.0
    sw = sx = sy = sz = 0.0
    if beta_dt != 0.0:
        sw, sx, sy, sz = madgwick_gradient(qn, a, m, use_mag)
        # Eq. (44): unit gradient; at an exact optimum ∇f = 0 has no direction: no correction.
        norm = math.sqrt(sw * sw + sx * sx + sy * sy + sz * sz)
        if norm > 0.0:
            step = 1.0 / norm * beta_dt
    # Eq. (11): q ⊗ [0, ω] (the ½ goes into ½Δt below).
    gx, gy, gz = g
    dw = -(qx * gx + qy * gy + qz * gz)
    dx = qw * gx + qy * gz - qz * gy
    dy = qw * gy - qx * gz + qz * gx
    dz = qw * gz + qx * gy - qy * gx
    # Eqs. (42)–(43): q + ½ q ⊗ [0, ω] Δt − β Δt ∇f/‖∇f‖, then normalised.
    half_dt = 0.5 * dt_gyro
    nw = dw * half_dt + qw - sw * step
    nx = dx * half_dt + qx - sx * step
    ny = dy * half_dt + qy - sy * step
    nz = dz * half_dt + qz - sz * step
    norm = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    return enu_from_nwu((nw / norm, nx / norm, ny / norm, nz / norm))


# ------------------------------------------------------------------------------------------
# Single frame: TRIAD (Shuster & Oh 1981) and the tilt-only start
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def quat_from_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """Unit quaternion of a rotation matrix (Shepperd's method, as scipy), ``w >= 0``."""
    trace = r00 + r11 + r22
    if trace >= r00 and trace >= r11 and trace >= r22:
        w, x, y, z = 1.0 + trace, r21 - r12, r02 - r20, r10 - r01
    elif r00 >= r11 and r00 >= r22:
        w, x, y, z = r21 - r12, 1.0 + 2.0 * r00 - trace, r01 + r10, r02 + r20
    elif r11 >= r22:
        w, x, y, z = r02 - r20, r01 + r10, 1.0 + 2.0 * r11 - trace, r12 + r21
    else:
        w, x, y, z = r10 - r01, r02 + r20, r12 + r21, 1.0 + 2.0 * r22 - trace
    q = quat_normalize((w, x, y, z))
    if q[0] < 0.0:
        return -q[0], -q[1], -q[2], -q[3]
    return q


def _reference_triad():
    """Columns ``[r1, r2, r3]`` of the ENU reference triad (gravity up first, then the field)."""
    r1 = frames.gravity_specific_force_enu() / frames.STANDARD_GRAVITY
    field = frames.magnetic_field_enu() / frames.MAGNETIC_INTENSITY_UT
    r2 = np.cross(r1, field)
    r2 /= np.linalg.norm(r2)
    return np.stack([r1, r2, np.cross(r1, r2)], axis=-1)


#: The ENU reference triad of TRIAD, columns r1, r2, r3 (a compile-time constant).
M_REF = _reference_triad()


@njit(**COMPILE)
def triad(a, m):
    """TRIAD body → ENU from unit ``a`` (specific force) and unit ``m`` (field), ``w >= 0``.

    ``s1 = a``, ``s2 = (a × m)/|a × m|``, ``s3 = s1 × s2``; ``R = M_ref M_obsᵀ`` so that
    ``R s_i = r_i``.  The caller guarantees ``|a × m| > 0``.
    """
    s1 = a
    c = cross3(a, m)
    s2 = unit3(c[0], c[1], c[2])
    s3 = cross3(s1, s2)
    # R[i][j] = Σ_k M_ref[i, k] s_k[j]
    r = M_REF
    return quat_from_matrix(
        r[0, 0] * s1[0] + r[0, 1] * s2[0] + r[0, 2] * s3[0],
        r[0, 0] * s1[1] + r[0, 1] * s2[1] + r[0, 2] * s3[1],
        r[0, 0] * s1[2] + r[0, 1] * s2[2] + r[0, 2] * s3[2],
        r[1, 0] * s1[0] + r[1, 1] * s2[0] + r[1, 2] * s3[0],
        r[1, 0] * s1[1] + r[1, 1] * s2[1] + r[1, 2] * s3[1],
        r[1, 0] * s1[2] + r[1, 1] * s2[2] + r[1, 2] * s3[2],
        r[2, 0] * s1[0] + r[2, 1] * s2[0] + r[2, 2] * s3[0],
        r[2, 0] * s1[1] + r[2, 1] * s2[1] + r[2, 2] * s3[1],
        r[2, 0] * s1[2] + r[2, 1] * s2[2] + r[2, 2] * s3[2],
    )


@njit(**COMPILE)
def tilt(a):
    """Smallest rotation taking unit ``a`` (body up) onto earth up: zero heading, ``w >= 0``."""
    ax, ay, az = a
    w, x, y = 1.0 + az, ay, -ax
    n = math.sqrt(w * w + x * x + y * y)
    if n == 0.0:  # upside down: rotate about body x
        return 0.0, 1.0, 0.0, 0.0
    return w / n, x / n, y / n, 0.0


# ------------------------------------------------------------------------------------------
# Paper 001: eq. (3) weight, eq. (2) SLERP, the λ schedules
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def slerp_weight(lam, rho, tau):
    """Eq. (3): μ = ρ / (λ/τ + ρ)."""
    return rho / (lam / tau + rho)


@njit(**COMPILE)
def slerp(q_a, q_b, mu):
    """Eq. (2) along the shorter arc, in ``q_b``'s hemisphere: μ = 0 gives ±``q_a``, 1 gives ``q_b``."""
    dot = q_a[0] * q_b[0] + q_a[1] * q_b[1] + q_a[2] * q_b[2] + q_a[3] * q_b[3]
    sign = 1.0
    if dot < 0.0:
        sign, dot = -1.0, -dot
    omega = max(math.acos(min(dot, 1.0)), _SLERP_TINY_ANGLE)
    sin_omega = math.sin(omega)
    wa = sign * math.sin((1.0 - mu) * omega) / sin_omega
    wb = math.sin(mu * omega) / sin_omega
    return quat_normalize((wa * q_a[0] + wb * q_b[0], wa * q_a[1] + wb * q_b[1],
                           wa * q_a[2] + wb * q_b[2], wa * q_a[3] + wb * q_b[3]))


@njit(**COMPILE)
def next_lost_run(lam, counts_as_received, prev_lost, since, schedule, window):
    """One step of the effective λ (see :func:`wsnlib.orientation.effective_lost_run`).

    Returns ``(λ_t, lost_t, since_t)``: the new λ, whether this sample counts as lost, and
    (``"hold"``) the received samples since the last gap.
    """
    if not counts_as_received:
        return lam + 1.0, True, 0
    if schedule == DECAY:
        return (lam if prev_lost else max(lam - 1.0, 0.0)), False, since + 1
    if schedule == HOLD:
        since += 1
        return (lam if since <= window else 0.0), False, since
    return 0.0, False, since + 1  # INSTANT: the literal reading


# ------------------------------------------------------------------------------------------
# One recording
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def _vec(arr, t):
    return arr[t, 0], arr[t, 1], arr[t, 2]


@njit(**COMPILE)
def _unit_at(arr, t):
    return unit3(arr[t, 0], arr[t, 1], arr[t, 2])


@njit(**COMPILE)
def _store(out, t, q):
    out[t, 0], out[t, 1], out[t, 2], out[t, 3] = q[0], q[1], q[2], q[3]


@njit(**COMPILE)
def filter_stream(gyr, acc, mag, use_mag, received, q0, has_q0, method, blend, dt, beta, beta_max,
                  rho, tau, schedule, window, predict_gap, rate_factor, out):
    """Madgwick's filter with one loss-handling method over one recording; returns a status.

    ``gyr``, ``acc``, ``mag`` ``(T, 3)`` (only received samples are read), ``received`` ``(T,)``,
    ``q0`` ``(4,)`` used if ``has_q0`` (else the filter starts from TRIAD, or the tilt without
    ``mag``, of the first received sample, which then only initialises), ``out`` ``(T, 4)``.
    On a lost sample the output is the previous output, or with ``predict_gap`` the state
    turned on by the last received rate, times ``rate_factor`` per lost sample (1: constant
    rate).  See :func:`wsnlib.orientation.estimate_orientation` for what each method does.
    """
    n_t = received.shape[0]
    q = (q0[0], q0[1], q0[2], q0[3])
    m = (0.0, 0.0, 0.0)
    if not has_q0:  # start from the first received sample; before it, show that start
        for first in range(n_t):
            if received[first]:
                a = _unit_at(acc, first)
                if use_mag:
                    q = triad(a, _unit_at(mag, first))
                else:
                    q = tilt(a)
                break
    shown = q
    started = has_q0
    lam, prev_lost, since = 0.0, False, 0  # λ_eff schedule state
    run = 0  # samples lost since the last received one (after the start)
    last = -1  # last received sample
    g_gap = (0.0, 0.0, 0.0)  # the rate a predicted gap turns at
    for t in range(n_t):
        rx = received[t]
        # A gap before the filter starts is no gap: λ_eff counts only once it runs.
        lam, prev_lost, since = next_lost_run(lam, rx or not started, prev_lost, since, schedule, window)
        if not rx:
            if started:
                run += 1
                if predict_gap and last >= 0:  # dead reckoning on the last received rate
                    g_gap = (g_gap[0] * rate_factor, g_gap[1] * rate_factor, g_gap[2] * rate_factor)
                    q = madgwick_update(q, g_gap, g_gap, g_gap, False, dt, 0.0)
                    shown = q
            _store(out, t, shown)
            continue
        a = _unit_at(acc, t)
        if use_mag:
            m = _unit_at(mag, t)
        if not started:  # the first received sample only initialised the filter (above)
            started, last = True, t
            _store(out, t, q)
            continue
        g = _vec(gyr, t)
        if method == GYRO_INTERPOLATION and run > 0:
            # Replay the lost samples, gyroscope only, ω interpolated from the last received
            # sample before the gap (or the first after it, for a gap at the start).
            for s in range(t - run, t):
                if last >= 0:
                    frac = (s - last) / (t - last)
                    g_s = (gyr[last, 0] + frac * (g[0] - gyr[last, 0]),
                           gyr[last, 1] + frac * (g[1] - gyr[last, 1]),
                           gyr[last, 2] + frac * (g[2] - gyr[last, 2]))
                else:
                    g_s = g
                q = madgwick_update(q, g_s, a, m, use_mag, dt, 0.0)
        dt_gyro = dt * (1.0 + run) if method == DT_EXTENSION else dt
        beta_dt = beta * dt
        if method == ADAPTIVE_BETA:  # β_eff = β + (β_max − β)(1 − μ)
            beta_dt = (beta + (beta_max - beta) * (1.0 - slerp_weight(lam, rho, tau))) * dt
        q = madgwick_update(q, g, a, m, use_mag, dt_gyro, beta_dt)
        shown = q
        if blend != NO_BLEND and lam > 0.0:  # eq. (4): q_f = SLERP(q_s, q_d, μ)
            q_f = slerp(triad(a, m), q, slerp_weight(lam, rho, tau))
            shown = q_f
            if blend == FEEDBACK_BLEND:
                q = q_f
        if not is_finite4(q):
            return OVERFLOW
        _store(out, t, shown)
        run, last, g_gap = 0, t, g
    return OK


@njit(parallel=True, **COMPILE)
def run_filter(gyr, acc, mag, use_mag, received, q0, has_q0, i_gyr, i_acc, i_mag, i_rx, i_q0,
               method, blend, dt, beta, beta_max, rho, tau, schedule, window, predict_gap, rate_factor, out, status):
    """:func:`filter_stream` for every batch element ``b`` of ``out`` ``(B, T, 4)``, in parallel.

    Element ``b`` reads recording ``gyr[i_gyr[b]]`` (likewise ``acc``, ``mag``), mask
    ``received[i_rx[b]]``, start ``q0[i_q0[b]]`` and parameters ``beta[b]``, ``beta_max[b]``,
    ``rho[b]``, ``tau[b]``, ``window[b]``; ``status[b]`` receives its status.
    """
    for b in prange(out.shape[0]):
        status[b] = filter_stream(gyr[i_gyr[b]], acc[i_acc[b]], mag[i_mag[b]], use_mag, received[i_rx[b]],
                                  q0[i_q0[b]], has_q0, method, blend, dt, beta[b], beta_max[b], rho[b],
                                  tau[b], schedule, window[b], predict_gap, rate_factor, out[b])


@njit(parallel=True, **COMPILE)
def run_step(q, gyr, acc, mag, use_mag, dt, beta_dt, out):
    """One Madgwick update per row: ``q`` ``(B, 4)`` unit, signals ``(B, 3)`` (acc, mag non-zero)."""
    for b in prange(q.shape[0]):
        q_b = (q[b, 0], q[b, 1], q[b, 2], q[b, 3])
        m = _unit_at(mag, b) if use_mag else (0.0, 0.0, 0.0)
        _store(out, b, madgwick_update(q_b, _vec(gyr, b), _unit_at(acc, b), m, use_mag, dt[b], beta_dt[b]))


@njit(parallel=True, **COMPILE)
def run_lost_run(received, i_rx, schedule, window, leading_gap, out):
    """Effective λ ``out`` ``(B, T)`` of mask ``received[i_rx[b]]`` (:func:`next_lost_run`)."""
    for b in prange(out.shape[0]):
        rx = received[i_rx[b]]
        lam, prev_lost, since, seen = 0.0, False, 0, leading_gap
        for t in range(out.shape[1]):
            seen = seen or rx[t]
            lam, prev_lost, since = next_lost_run(lam, rx[t] or not seen, prev_lost, since, schedule, window[b])
            out[b, t] = lam


@njit(parallel=True, **COMPILE)
def run_output_blend(quat_d, acc, mag, received, i_q, i_acc, i_mag, i_rx, rho, tau, schedule, window,
                     leading_gap, out):
    """Eq. (4) as an output stage on any filter's output ``quat_d`` (unit), ``out`` ``(B, T, 4)``.

    On a received sample with λ_eff > 0: ``SLERP(TRIAD, q_d, μ)``; elsewhere on received samples
    ``q_d``; on a lost sample eq. (4) with that sample's ``q_d`` and the TRIAD and μ of the last
    received sample (the previous output when ``q_d`` is held there).
    """
    for b in prange(out.shape[0]):
        q_d, a_b, m_b, rx = quat_d[i_q[b]], acc[i_acc[b]], mag[i_mag[b]], received[i_rx[b]]
        lam, prev_lost, since, seen = 0.0, False, 0, leading_gap
        blended, mu = False, 1.0
        q_s = (1.0, 0.0, 0.0, 0.0)
        for t in range(out.shape[1]):
            seen = seen or rx[t]
            lam, prev_lost, since = next_lost_run(lam, rx[t] or not seen, prev_lost, since, schedule, window[b])
            q_t = (q_d[t, 0], q_d[t, 1], q_d[t, 2], q_d[t, 3])
            if rx[t]:
                blended = lam > 0.0
                if blended:
                    q_s = triad(_unit_at(a_b, t), _unit_at(m_b, t))
                    mu = slerp_weight(lam, rho[b], tau[b])
            _store(out[b], t, slerp(q_s, q_t, mu) if blended else q_t)


@njit(parallel=True, **COMPILE)
def run_triad(acc, mag, out):
    """TRIAD per row: ``acc``, ``mag`` ``(B, 3)`` unit, ``out`` ``(B, 4)``."""
    for b in prange(out.shape[0]):
        _store(out, b, triad(_vec(acc, b), _vec(mag, b)))


@njit(**COMPILE)
def first_unusable_stream(x, rx, check_zero):
    """First received sample of ``x`` ``(T, 3)`` that is not finite (kind 1) or, with
    ``check_zero``, a zero vector (kind 2): ``(t, kind)``, ``(-1, 0)`` if there is none."""
    for t in range(x.shape[0]):
        if not rx[t]:
            continue
        if not (math.isfinite(x[t, 0]) and math.isfinite(x[t, 1]) and math.isfinite(x[t, 2])):
            return t, 1
        if check_zero and x[t, 0] == 0.0 and x[t, 1] == 0.0 and x[t, 2] == 0.0:
            return t, 2
    return -1, 0


@njit(**COMPILE)
def first_unusable(arr, i_arr, received, i_rx, check_zero, out):
    """:func:`first_unusable_stream` of ``arr[i_arr[b]]`` under ``received[i_rx[b]]`` into ``out[b]``."""
    for b in range(out.shape[0]):
        out[b, 0], out[b, 1] = first_unusable_stream(arr[i_arr[b]], received[i_rx[b]], check_zero)


@njit(parallel=True, **COMPILE)
def first_unusable_parallel(arr, i_arr, received, i_rx, check_zero, out):
    """:func:`first_unusable` with the batch elements in parallel (for large batches only: a check
    reads each sample once, and for small inputs starting the threads costs more)."""
    for b in prange(out.shape[0]):
        out[b, 0], out[b, 1] = first_unusable_stream(arr[i_arr[b]], received[i_rx[b]], check_zero)


@njit(parallel=True, **COMPILE)
def run_hold_lost(out, received, i_rx):
    """Hold the output over gaps, in place: ``out[b, t] = out[b, t − 1]`` on every lost ``t > 0``.

    ``out`` ``(B, T, C)``, mask ``received[i_rx[b]]`` ``(T,)`` (``gap="hold"`` of a filter that
    predicts inside, e.g. :func:`wsnlib.orientation.kalman_orientation`).
    """
    for b in prange(out.shape[0]):
        rx = received[i_rx[b]]
        for t in range(1, out.shape[1]):
            if not rx[t]:
                for c in range(out.shape[2]):
                    out[b, t, c] = out[b, t - 1, c]
