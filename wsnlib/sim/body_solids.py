"""Body solids of paper 002's user and the length of a radio link inside them (for shadowing).

The solids (torso, legs, neck, head, both arms) and their sizes are described in
:mod:`wsnlib.sim.body` (section "Body for shadowing"); :mod:`wsnlib.sim.radio_links` turns
the chord lengths into body loss.  Shoulder frame, metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib._validation import as_float_array
from wsnlib.sim.users import User


@dataclass(frozen=True)
class Solid:
    """A convex solid: a finite cylinder with elliptic cross-section, or a sphere.

    ``kind`` is ``"cylinder"`` (axis from ``base`` along unit ``axis`` for ``length`` m,
    cross-section semi-axes ``radius`` along ``ref`` and ``radius2`` along ``axis × ref``) or
    ``"sphere"`` (centre ``base``, radius ``radius``).  Arrays may carry a leading time axis
    ``(T, 3)`` for moving solids (the arm).
    """

    name: str
    kind: str
    base: np.ndarray
    radius: float
    axis: np.ndarray | None = None
    length: float = 0.0
    ref: np.ndarray | None = None
    radius2: float | None = None


def body_solids(user: User, arm_direction=None) -> list[Solid]:
    """Solids of ``user``'s body (module docstring); the right arm along ``arm_direction``.

    Parameters
    ----------
    user : User
    arm_direction : array_like (3,) or (T, 3), optional
        Unit direction of the right arm; omitted → no right-arm solids.
    """
    b = user.body
    ez = np.array([0.0, 0.0, 1.0])
    ex = np.array([1.0, 0.0, 0.0])
    cx = b.torso_center_x_m
    solids = [
        Solid(
            "torso",
            "cylinder",
            np.array([cx, 0.0, b.torso_bottom_z_m]),
            b.torso_half_width_m,
            ez,
            b.torso_top_z_m - b.torso_bottom_z_m,
            ex,
            b.torso_half_depth_m,
        ),
        Solid(
            "legs",
            "cylinder",
            np.array([cx, 0.0, b.floor_z_m]),
            b.legs_half_width_m,
            ez,
            b.torso_bottom_z_m - b.floor_z_m,
            ex,
            b.legs_half_depth_m,
        ),
        Solid(
            "neck",
            "cylinder",
            np.array([cx, 0.0, b.torso_top_z_m]),
            b.neck_radius_m,
            ez,
            b.neck_length_m,
            ex,
            b.neck_radius_m,
        ),
        Solid("head", "sphere", np.array([cx, 0.0, b.head_center_z_m]), b.head_radius_m),
        Solid(
            "left_arm",
            "cylinder",
            np.array([b.left_shoulder_x_m, 0.0, -b.left_arm_length_m]),
            b.upper_arm_radius_m,
            ez,
            b.left_arm_length_m,
            ex,
            b.upper_arm_radius_m,
        ),
    ]
    if arm_direction is not None:
        u = as_float_array(arm_direction, "arm_direction", last_dim=3)
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        ref = _perpendicular(u)
        solids.append(
            Solid(
                "upper_arm",
                "cylinder",
                np.zeros_like(u),
                b.upper_arm_radius_m,
                u,
                user.upper_arm_m,
                ref,
                b.upper_arm_radius_m,
            )
        )
        solids.append(
            Solid(
                "forearm",
                "cylinder",
                u * user.upper_arm_m,
                b.forearm_radius_m,
                u,
                user.forearm_m,
                ref,
                b.forearm_radius_m,
            )
        )
    return solids


def _perpendicular(u: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each ``u`` (…, 3)."""
    helper = np.where(np.abs(u[..., 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    p = np.cross(u, helper)
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def chord_length(p, q, solid: Solid, trim_m: float = 0.0) -> np.ndarray:
    """Length (m) of the part of segment ``p → q`` inside ``solid``.

    Parameters
    ----------
    p, q : array_like (..., 3)
        Segment end points (broadcast together and with the solid's arrays).
    solid : Solid
    trim_m : float
        Ignore the first and last ``trim_m`` metres of the segment (the nodes sit on the skin:
        their own few millimetres of contact do not shadow the link).

    Returns
    -------
    numpy.ndarray (...)
        0 where the segment misses the solid.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    v = q - p
    length = np.linalg.norm(v, axis=-1)
    safe = np.where(length > 0.0, length, 1.0)
    trim = np.minimum(trim_m / safe, 0.5)
    lo = trim
    hi = 1.0 - trim
    if solid.kind == "sphere":
        d = p - solid.base
        a = np.sum(v * v, axis=-1)
        bq = 2.0 * np.sum(d * v, axis=-1)
        c = np.sum(d * d, axis=-1) - solid.radius**2
        s0, s1 = _quadratic_interval(a, bq, c)
    elif solid.kind == "cylinder":
        axis = np.asarray(solid.axis, dtype=float)
        ref = np.asarray(solid.ref, dtype=float)
        other = np.cross(axis, ref)
        d = p - solid.base
        # Coordinates along the axis and in the (ref, other) cross-section, scaled to a unit circle.
        da, va = np.sum(d * axis, axis=-1), np.sum(v * axis, axis=-1)
        r2 = solid.radius if solid.radius2 is None else solid.radius2
        d1, v1 = np.sum(d * ref, axis=-1) / solid.radius, np.sum(v * ref, axis=-1) / solid.radius
        d2, v2 = np.sum(d * other, axis=-1) / r2, np.sum(v * other, axis=-1) / r2
        a = v1 * v1 + v2 * v2
        bq = 2.0 * (d1 * v1 + d2 * v2)
        c = d1 * d1 + d2 * d2 - 1.0
        s0, s1 = _quadratic_interval(a, bq, c)
        # Slab 0 <= da + s va <= length.
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = np.where(va != 0.0, (0.0 - da) / va, -np.inf)
            t1 = np.where(va != 0.0, (solid.length - da) / va, np.inf)
        inside_slab = (da >= 0.0) & (da <= solid.length)
        slab_lo = np.where(va != 0.0, np.minimum(t0, t1), np.where(inside_slab, -np.inf, np.inf))
        slab_hi = np.where(va != 0.0, np.maximum(t0, t1), np.where(inside_slab, np.inf, -np.inf))
        s0 = np.maximum(s0, slab_lo)
        s1 = np.minimum(s1, slab_hi)
    else:
        raise ValueError(f"unknown solid kind {solid.kind!r}")
    s0 = np.maximum(s0, lo)
    s1 = np.minimum(s1, hi)
    return np.maximum(s1 - s0, 0.0) * length


def _quadratic_interval(a, b, c):
    """Interval ``[s0, s1]`` where ``a s² + b s + c <= 0`` (empty → s0 > s1); ``a >= 0``."""
    a = np.asarray(a, dtype=float)
    disc = b * b - 4.0 * a * c
    ok = (disc >= 0.0) & (a > 1e-18)
    root = np.sqrt(np.where(ok, disc, 0.0))
    denom = np.where(ok, 2.0 * a, 1.0)
    s0 = np.where(ok, (-b - root) / denom, np.inf)
    s1 = np.where(ok, (-b + root) / denom, -np.inf)
    # Segment parallel to the axis (a = 0): inside for all s iff c <= 0.
    parallel = a <= 1e-18
    s0 = np.where(parallel, np.where(c <= 0.0, -np.inf, np.inf), s0)
    s1 = np.where(parallel, np.where(c <= 0.0, np.inf, -np.inf), s1)
    return s0, s1


__all__ = ["Solid", "body_solids", "chord_length"]
