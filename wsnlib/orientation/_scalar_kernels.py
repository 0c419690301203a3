"""Scalar kernels of the orientation filters: vectors, quaternions, Madgwick's update, TRIAD, SLERP.

Every function here is compiled by numba (options :data:`COMPILE`) and works on plain floats
and tuples: a quaternion is a tuple ``(w, x, y, z)``, a vector ``(x, y, z)``.  A student can
read :func:`madgwick_update` next to Madgwick's report, :func:`triad` next to Shuster & Oh, and
:func:`slerp_weight` and :func:`slerp` next to paper 001's eqs. (2)–(4).  The loops over time
and the parallel batch drivers that call them are in :mod:`._kernels` (Madgwick's filter and
every loss option) and :mod:`._kalman_kernels` (the Kalman filter); the quaternion helpers
(:func:`quat_exp`, :func:`quat_log`, …) also serve :mod:`wsnlib.orientation.smoothing`.

Nothing here validates (the public functions do).  The compiled code is cached on disk
(``__pycache__`` next to this file, or ``NUMBA_CACHE_DIR``).  A cached kernel of another
module that calls one of these functions holds its own compiled copy, which numba alone would
recompile only when *that* module's file changes; :mod:`._numba_cache` therefore drops the
package's whole cache whenever any of its sources changes (checked on import).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wsnlib import fixed_order, frames

#: numba options of every kernel: machine code cached on disk; float division by zero gives
#: inf/NaN as in numpy (no exception check on every division), caught by the callers' status.
COMPILE = {"cache": True, "error_model": "numpy"}
#: ``True``, ``False`` and ``0`` as numpy scalars, for a kernel to pass to a large jitted callee (the
#: Kalman step, the receiver's calls into it): numba compiles a callee once per *literal* argument value
#: (``Literal[bool](True)``, ``Literal[int](0)``), and these are plain ``bool``/``int64``, so the callee is
#: compiled once.  Same values, same machine arithmetic: only compile time changes.
PLAIN_TRUE, PLAIN_FALSE, PLAIN_ZERO = np.bool_(True), np.bool_(False), np.int64(0)

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
def integrate_rates(q_start, rates, dt, out):
    """Strapdown integration: ``out[k] = q_k = q_{k−1} ⊗ Exp(ω_k Δt)``, normalised, from ``q_{−1}`` =
    ``q_start`` (4,), one step per row ω_k of ``rates`` (L, 3; rad/s), ``dt`` (s)."""
    q = (q_start[0], q_start[1], q_start[2], q_start[3])
    for k in range(rates.shape[0]):
        q = quat_normalize(quat_multiply(q, quat_exp((rates[k, 0] * dt, rates[k, 1] * dt, rates[k, 2] * dt))))
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = q


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
    r2 /= fixed_order.norm(r2)
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
# Paper 001: eq. (3) weight, eq. (2) SLERP
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
