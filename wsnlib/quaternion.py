"""Vectorised unit-quaternion operations, scalar first ``[w, x, y, z]``.

A quaternion ``q`` rotates a body-frame vector into the earth frame (ENU):
``v_E = q ⊗ [0, v_B] ⊗ q*``.  Every function accepts arrays of shape ``(..., 4)`` and
broadcasts over the leading dimensions.

SLERP is eq. (2) of De Vito et al. (paper 001)::

    SLERP(q_A, q_B, μ) = sin((1-μ)Ω)/sin Ω · q_A + sin(μΩ)/sin Ω · q_B,  cos Ω = q_A · q_B

taken along the shorter arc (``q_B`` is negated when ``q_A · q_B < 0``, since ``q`` and ``-q``
are the same rotation), and replaced by normalised linear interpolation when Ω → 0 where the
sine ratio is 0/0.

:func:`to_scipy` and :func:`from_scipy` are the only places in wsnlib that convert to the
scalar-last layout of :class:`scipy.spatial.transform.Rotation`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation

from wsnlib._validation import as_float_array, check_nonzero_norm

#: Below this angle (rad) between the two quaternions, SLERP falls back to normalised lerp.
_SLERP_SMALL_ANGLE = 1e-6


def _last_axis(value, name: str, size: int, what: str) -> np.ndarray:
    """``value`` as a float array of shape ``(..., size)`` (``what`` its rows), or ``ValueError`` naming ``name``.

    A shape check only (O(1)): these helpers run inside loops, and values are the caller's.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of {what}, got {type(value).__name__}") from exc
    if arr.ndim == 0 or arr.shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), {what}; got shape {arr.shape}")
    return arr


def _quat_array(q, name: str) -> np.ndarray:
    return _last_axis(q, name, 4, "quaternions [w, x, y, z]")


def _broadcast(names: str, *shapes) -> tuple[int, ...]:
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError:
        raise ValueError(f"{names} must broadcast against each other; got shapes "
                         f"{', '.join(map(str, shapes))}") from None


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions of shape ``shape + (4,)``."""
    q = np.zeros(tuple(shape) + (4,))
    q[..., 0] = 1.0
    return q


def normalize(q, name: str = "q") -> np.ndarray:
    """Scale quaternions to unit norm. ``ValueError`` naming ``name`` on a zero, NaN or infinite quaternion."""
    return _unit(q, name)


def _unit(q, name: str) -> np.ndarray:
    q = as_float_array(q, name, last_dim=4)
    out = np.empty(q.shape)
    first_zero = _unit_rows(_rows(q, q.shape), out.reshape(-1, 4))
    if first_zero >= 0:
        where = tuple(int(i) for i in np.unravel_index(first_zero, q.shape[:-1]))
        raise ValueError(f"{name} has a zero-norm vector at index {where} (a zero quaternion is not a rotation)")
    return out


@njit(cache=True, error_model="numpy")
def _unit_rows(q, out):
    """``out[n] = q[n]/‖q[n]‖`` for rows ``(N, 4)``, compiled (a metric normalises whole recordings under
    many masks); returns the first row whose norm is not > 0, or −1.  The norm sums the squares left
    to right, as :func:`numpy.linalg.norm` does over a short last axis: the same bits."""
    first_zero = -1
    for n in range(q.shape[0]):
        w, x, y, z = q[n, 0], q[n, 1], q[n, 2], q[n, 3]
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if norm <= 0.0 and first_zero < 0:
            first_zero = n
        out[n, 0], out[n, 1], out[n, 2], out[n, 3] = w / norm, x / norm, y / norm, z / norm
    return first_zero


def conjugate(q) -> np.ndarray:
    """Quaternion conjugate ``[w, -x, -y, -z]`` (the inverse rotation for unit quaternions)."""
    q = _quat_array(q, "q")
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def multiply(p, q) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (apply ``q`` first, then ``p``), broadcasting."""
    p = _quat_array(p, "p")
    q = _quat_array(q, "q")
    shape = p.shape if p.shape == q.shape else _broadcast("p and q", p.shape, q.shape)
    out = np.empty(shape)
    _hamilton_rows(_rows(p, shape), _rows(q, shape), out.reshape(-1, 4))
    return out


def _rows(q: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``q`` broadcast to ``shape`` as contiguous rows ``(N, 4)``: a view, or a copy of an operand that is
    broadcast or strided (one memory layout, so the kernels are compiled for one)."""
    return np.ascontiguousarray((q if q.shape == shape else np.broadcast_to(q, shape)).reshape(-1, 4))


@njit(cache=True, error_model="numpy")
def _hamilton_rows(p, q, out):
    """``out[n] = p[n] ⊗ q[n]`` for rows ``(N, 4)``, compiled: the metrics take products of whole
    recordings under many loss masks, where numpy's 28 temporaries per product cost ~10× more.
    Each component is summed left to right, as numpy evaluates the same expression: the same bits."""
    for n in range(out.shape[0]):
        pw, px, py, pz = p[n, 0], p[n, 1], p[n, 2], p[n, 3]
        qw, qx, qy, qz = q[n, 0], q[n, 1], q[n, 2], q[n, 3]
        out[n, 0] = pw * qw - px * qx - py * qy - pz * qz
        out[n, 1] = pw * qx + px * qw + py * qz - pz * qy
        out[n, 2] = pw * qy - px * qz + py * qw + pz * qx
        out[n, 3] = pw * qz + px * qy - py * qx + pz * qw


def rotate(q, v) -> np.ndarray:
    """Rotate vectors ``v`` (``(..., 3)``, body frame) into the earth frame by unit ``q`` (``(..., 4)``).

    ``ValueError`` naming ``q`` or ``v`` when a shape is wrong or they do not broadcast.
    """
    q = _quat_array(q, "q")
    v = _last_axis(v, "v", 3, "3-vectors")
    if q.shape[:-1] != v.shape[:-1]:
        _broadcast("q[..., 1:] and v", q.shape[:-1] + (3,), v.shape)
    w = q[..., :1]
    u = q[..., 1:]
    # v' = v + 2w (u × v) + 2 u × (u × v), the expanded form of q ⊗ v ⊗ q*.
    uv = np.cross(u, v)
    return v + 2.0 * w * uv + 2.0 * np.cross(u, uv)


def rotate_inverse(q, v) -> np.ndarray:
    """Rotate earth-frame vectors into the body frame: ``q* ⊗ v ⊗ q``."""
    return rotate(conjugate(q), v)


def canonical(q) -> np.ndarray:
    """Pick the representative with ``w >= 0`` (``q`` and ``-q`` are the same rotation)."""
    q = np.asarray(q, dtype=float)
    return np.where(q[..., :1] < 0.0, -q, q)


def angle_between(q_a, q_b) -> np.ndarray:
    """Rotation angle (rad, in ``[0, π]``) of ``q_a* ⊗ q_b``: how far apart two orientations are.

    Uses ``2·atan2(‖vec‖, |w|)``, which stays accurate for small angles where ``arccos`` does not.
    ``ValueError`` naming ``q_a`` or ``q_b`` for a wrong shape or a zero quaternion (no rotation).
    """
    q_a = _quat_array(q_a, "q_a")
    q_b = _quat_array(q_b, "q_b")
    d = multiply(conjugate(q_a), q_b)
    vec_norm, w_abs = np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0])
    zero = (vec_norm == 0.0) & (w_abs == 0.0)  # |q_a* ⊗ q_b| = |q_a|·|q_b|: zero iff one of them is
    if np.any(zero):
        for q, name in ((q_a, "q_a"), (q_b, "q_b")):
            bad = ~np.broadcast_to(q, d.shape).any(axis=-1)
            if np.any(bad):
                index = tuple(int(i) for i in np.argwhere(bad)[0])
                where = f" at index {index}" if index else ""
                raise ValueError(f"{name} is a zero quaternion{where} (a zero quaternion is not a rotation)")
    return 2.0 * np.arctan2(vec_norm, w_abs)


def from_axis_angle(axis, angle) -> np.ndarray:
    """Quaternion for a rotation by ``angle`` (rad) about ``axis`` (``(..., 3)``, normalised here).

    ``ValueError`` naming ``axis`` or ``angle`` on NaN/inf, a zero axis or shapes that do not
    broadcast.
    """
    axis = as_float_array(axis, "axis", last_dim=3)
    norm = check_nonzero_norm(axis, "axis", "a rotation axis needs a direction")
    angle = as_float_array(angle, "angle", min_ndim=0)
    _broadcast("axis[..., 0] and angle", axis.shape[:-1], angle.shape)
    half = 0.5 * angle
    unit = axis / norm[..., None]
    return np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * unit], axis=-1)


def from_rotation_vector(rotvec) -> np.ndarray:
    """Quaternion ``exp(rotvec/2)`` for rotation vectors (rad) ``(..., 3)``; exact at zero."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(rotvec, axis=-1)
    half = 0.5 * angle
    # sin(θ/2)/θ → 1/2 as θ → 0; np.sinc(x) = sin(πx)/(πx).
    scale = 0.5 * np.sinc(half / np.pi)
    return np.concatenate([np.cos(half)[..., None], scale[..., None] * rotvec], axis=-1)


def slerp(q_a, q_b, mu) -> np.ndarray:
    """Spherical linear interpolation, eq. (2) of paper 001, along the shorter arc.

    Parameters
    ----------
    q_a, q_b : array_like, shape (..., 4)
        Unit quaternions; ``mu = 0`` returns ``q_a`` and ``mu = 1`` returns ``q_b`` (or
        ``-q_b`` when that is the nearer representative of the same rotation).
    mu : array_like, shape (...)
        Interpolation amount per sample, in ``[0, 1]``; broadcasts against the leading
        dimensions of the quaternions.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        Unit quaternions.

    Raises
    ------
    ValueError
        Naming ``q_a``, ``q_b`` or ``mu``: a wrong shape, NaN/inf, a zero quaternion, ``mu``
        outside [0, 1], or shapes that do not broadcast.
    """
    q_a = _unit(q_a, "q_a")
    q_b = _unit(q_b, "q_b")
    mu = as_float_array(mu, "mu", min_ndim=0)
    _broadcast("q_a[..., 0], q_b[..., 0] and mu", q_a.shape[:-1], q_b.shape[:-1], mu.shape)
    if np.any((mu < 0.0) | (mu > 1.0)):
        raise ValueError("mu must lie in [0, 1]")
    dot = np.sum(q_a * q_b, axis=-1)
    q_b = np.where(dot[..., None] < 0.0, -q_b, q_b)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    omega = np.arccos(dot)
    small = omega < _SLERP_SMALL_ANGLE
    sin_omega = np.where(small, 1.0, np.sin(omega))
    weight_a = np.where(small, 1.0 - mu, np.sin((1.0 - mu) * omega) / sin_omega)
    weight_b = np.where(small, mu, np.sin(mu * omega) / sin_omega)
    out = weight_a[..., None] * q_a + weight_b[..., None] * q_b
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def to_scipy(q) -> Rotation:
    """Convert ``[w, x, y, z]`` quaternions to a :class:`~scipy.spatial.transform.Rotation`."""
    q = as_float_array(q, "q", last_dim=4)
    return Rotation.from_quat(q[..., [1, 2, 3, 0]])


def from_scipy(rotation: Rotation) -> np.ndarray:
    """Convert a :class:`~scipy.spatial.transform.Rotation` to ``[w, x, y, z]`` quaternions."""
    return rotation.as_quat()[..., [3, 0, 1, 2]]


def as_quat_with_gaps(value, name: str, unit: bool = False) -> np.ndarray:
    """Quaternions ``(..., 4)`` in which a row holding NaN marks a missing sample, as a float copy.

    Parameters
    ----------
    value : array_like, shape (..., 4)
        Quaternions ``[w, x, y, z]`` (not necessarily unit); a row with any NaN is a gap (e.g.
        an optical reference whose markers were lost).
    name : str
        Argument name used in error messages.
    unit : bool
        Also divide each row outside the gaps by its norm (the bits of ``q / np.linalg.norm(q, axis=-1,
        keepdims=True)``), in the same compiled pass as the checks: a metric does this for the same
        reference on every call.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        A new float array; gap rows are entirely NaN, the others unchanged (not normalised) or, with
        ``unit``, unit quaternions.

    Raises
    ------
    ValueError
        Not numeric, last axis not 4, any inf, or a zero quaternion outside the gaps.
    """
    try:
        arr = np.array(value, dtype=float, order="C")  # (C order: its rows below are a view, changed in place)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {type(value).__name__}") from exc
    if arr.ndim < 1 or arr.shape[-1] != 4:
        raise ValueError(f"{name} must have shape (..., 4), got shape {arr.shape}")
    has_inf, has_zero = _gap_rows(arr.reshape(-1, 4), unit)
    if has_inf:
        raise ValueError(f"{name} contains inf")
    if has_zero:
        raise ValueError(f"{name} has a zero quaternion, which is not a rotation")
    return arr


@njit(cache=True, error_model="numpy")
def _gap_rows(q, unit):
    """In place on rows ``(N, 4)``: a row holding NaN becomes all NaN, and with ``unit`` every other row is
    divided by its norm (summed as :func:`_unit_rows` sums it: numpy's bits); returns whether some entry is
    inf and whether some row outside the gaps has norm 0 (:func:`as_quat_with_gaps`)."""
    has_inf = has_zero = False
    for n in range(q.shape[0]):
        w, x, y, z = q[n, 0], q[n, 1], q[n, 2], q[n, 3]
        if math.isinf(w) or math.isinf(x) or math.isinf(y) or math.isinf(z):
            has_inf = True
        if math.isnan(w) or math.isnan(x) or math.isnan(y) or math.isnan(z):
            q[n, 0] = q[n, 1] = q[n, 2] = q[n, 3] = math.nan
            continue
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if norm == 0.0:
            has_zero = True
        elif unit:
            q[n, 0], q[n, 1], q[n, 2], q[n, 3] = w / norm, x / norm, y / norm, z / norm
    return has_inf, has_zero
