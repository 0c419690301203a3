"""Body and users of paper 002's testbed (Giuberti et al., Sec. 4.1).

The user stands still; two targets are strapped to the straight right arm (T1 mid upper arm,
T2 mid forearm); seven anchors are worn (A1, A4, A6, A7: t-shirt pockets and a hat) or fixed
in the room (A2, A3, A5).  This module holds the user's geometry — body shape, anchor sites,
:class:`User` (with its arm as :attr:`User.geometry`) and the solids that shadow the radio links
(:func:`body_solids`, :func:`chord_length`); the arm's postures and movements are
:mod:`wsnlib.sim.arm_motion`, and :mod:`wsnlib.sim.radio` turns the geometry into
received signal strengths.

Shoulder frame
--------------
Origin at the centre of the right shoulder joint; **x** to the user's right (lateral),
**y** forward, **z** up (paper 002, footnote 4: z vertical, y forward, x normal to the
sagittal plane; the signs follow Table 1: P4, the arm held out sideways, has x > 0, and P5,
across the body, has x < 0).  The frame is right-handed and is the package's ENU earth frame
for a user facing north, so quaternions, angular rates and accelerations here follow
``wsnlib/__init__.py`` unchanged.  Lengths are in metres.

Users and anchors
-----------------
Segment lengths from body height H (D. A. Winter, *Biomechanics and Motor Control of Human
Movement*, 4th ed., Wiley 2009, Fig. 4.1, after Drillis & Contini 1966: upper arm 0.186 H,
forearm 0.146 H, shoulder height 0.818 H; see :mod:`wsnlib.sim.arm` for how far these were
checked).  Paper 002's own user had T1 at 15 cm and T2 at 42.5 cm: upper arm 30 cm and
forearm 25 cm, i.e. H ≈ 1.62 m by Winter's fractions.

The paper's anchor placement (its Fig. 4) is not in the text, so the sites below are our
choice, made to be plausible for "a home-made t-shirt with folders" and "a hat" and to give
the targets a mix of short line-of-sight and body-shadowed links:

====  ======  =============================================================================
A1    worn    left chest pocket, on the front of the torso at sternum height
A2    room    on a table 1.5 m in front and 1.0 m to the right, 0.75 m above the floor
A3    room    on a shelf 2.0 m to the right and 0.3 m behind, 1.80 m above the floor
A4    worn    upper back, between the shoulder blades
A5    room    on a stand 2.5 m in front and 1.2 m to the left, 1.20 m above the floor
A6    worn    right front of the waist (belt pocket)
A7    worn    on the hat, top front of the head
====  =============================================================================

Worn sites scale with H (given for H = 1.75 m, 1 cm outside the modelled body surface for
the pocket/cloth); room sites are fixed in the room (heights above the floor), the user
standing on a floor mark.  :func:`make_users` jitters worn anchors by σ = 2 cm per axis
(fit of the t-shirt on different users, assumed) and the floor mark by σ = 2 cm per
horizontal axis (assumed).  :meth:`User.moved` is a later day: the t-shirt re-donned (worn
anchors σ = 1.5 cm per axis), the user on the mark again (σ = 2 cm horizontally), the targets
re-strapped (σ = 1 cm along the arm) — all assumed.

Body for shadowing
------------------
Simple solids in the shoulder frame, for a 1.75 m adult and scaled by H / 1.75 m (all sizes
assumed, of the order of adult anthropometric averages; chest breadth ≈ 30 cm, chest depth
≈ 22 cm):

* torso: vertical elliptic cylinder, semi-axes 0.15 m (lateral) × 0.11 m (front–back),
  centred 0.19 m to the left of the shoulder joint (joint centres ≈ 38 cm apart), from
  0.60 m below the shoulder to shoulder level;
* legs (one block): vertical elliptic cylinder 0.15 × 0.10 m from the floor to the torso;
* neck: vertical cylinder, radius 0.06 m, from shoulder level up 0.10 m;
* head: sphere, radius 0.10 m, centre 0.205 m above the shoulder (0.935 H − 0.818 H);
* left arm: hanging straight down, cylinder of radius 0.045 m, 0.58 m long;
* right arm: upper arm cylinder radius 0.045 m, forearm 0.040 m, along the arm direction.

The targets sit on the lateral surface of their segment (body −y of the segment frame, 1 cm
outside the modelled skin): that is where the radio antenna is.  The positions written to
recordings and compared with estimates are the points on the arm axis (Table 1 convention).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from wsnlib._validation import as_float_array, check_count, check_fields, check_nonnegative, check_positive, check_type
from wsnlib.arm_model import FOREARM_FRACTION, UPPER_ARM_FRACTION, ArmGeometry
from wsnlib.io.sidecar import check_name
from wsnlib.testbed import ANCHOR_NAMES, ANCHOR_WORN, posture_direction

# --------------------------------------------------------------------------------------------
# Body shape
# --------------------------------------------------------------------------------------------

#: Height (m) for which the body sizes and worn-anchor sites below are given.
REFERENCE_HEIGHT_M = 1.75

#: Shoulder height as a fraction of body height (Winter 2009, Fig. 4.1).
SHOULDER_HEIGHT_FRACTION = 0.818


@dataclass(frozen=True)
class BodyShape:
    """Sizes (m) of the simple solids used for body shadowing (module docstring, "Body for shadowing"; assumed).

    Every length is for the user's height; :meth:`from_height` scales the 1.75 m defaults.
    """

    torso_half_width_m: float = 0.15
    torso_half_depth_m: float = 0.11
    torso_center_x_m: float = -0.19
    torso_bottom_z_m: float = -0.60
    torso_top_z_m: float = 0.0
    legs_half_width_m: float = 0.15
    legs_half_depth_m: float = 0.10
    neck_radius_m: float = 0.06
    neck_length_m: float = 0.10
    head_radius_m: float = 0.10
    head_center_z_m: float = 0.205
    upper_arm_radius_m: float = 0.045
    forearm_radius_m: float = 0.040
    left_arm_length_m: float = 0.58
    floor_z_m: float = -SHOULDER_HEIGHT_FRACTION * REFERENCE_HEIGHT_M

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name.endswith("_z_m") or f.name == "torso_center_x_m":
                object.__setattr__(self, f.name, float(value))
            else:
                object.__setattr__(self, f.name, check_positive(value, f.name))
        if not self.floor_z_m < self.torso_bottom_z_m < self.torso_top_z_m:
            raise ValueError("need floor_z_m < torso_bottom_z_m < torso_top_z_m")

    @classmethod
    def from_height(cls, height_m: float) -> BodyShape:
        """Body of height ``height_m``: every default length scaled by ``height_m / 1.75``."""
        height = check_positive(height_m, "height_m")
        s = height / REFERENCE_HEIGHT_M
        base = cls()
        values = {f.name: getattr(base, f.name) * s for f in dataclasses.fields(cls)}
        values["floor_z_m"] = -SHOULDER_HEIGHT_FRACTION * height
        return cls(**values)


# --------------------------------------------------------------------------------------------
# Anchor sites
# --------------------------------------------------------------------------------------------

#: Worn anchor sites (m, shoulder frame) for a 1.75 m user; scaled with height.
_WORN_SITES_175 = {
    # left chest pocket: 8 cm left of the midline on the front of the torso ellipse, + 1 cm.
    "A1": (-0.27, 0.11 * np.sqrt(1.0 - (0.08 / 0.15) ** 2) + 0.01, -0.15),
    # upper back, midline, + 1 cm.
    "A4": (-0.19, -0.12, -0.10),
    # right front of the waist: 11 cm right of the midline, + 1 cm.
    "A6": (-0.08, 0.11 * np.sqrt(1.0 - (0.11 / 0.15) ** 2) + 0.01, -0.50),
    # hat, top front of the head: 5 cm forward of the head centre, 1 cm above the scalp.
    "A7": (-0.19, 0.05, 0.205 + np.sqrt(0.11**2 - 0.05**2)),
}

#: Room anchor sites: (x, y) on the floor plan relative to the user's floor mark (m) and
#: height above the floor (m).
_ROOM_SITES = {"A2": (1.0, 1.5, 0.75), "A3": (2.0, -0.3, 1.80), "A5": (-1.2, 2.5, 1.20)}

#: Antenna axis of each anchor (unit vector, shoulder frame; assumed): worn nodes stand
#: upright in their pocket, the hat node lies flat pointing forward, room nodes stand upright.
ANCHOR_AXES: dict[str, tuple[float, float, float]] = {
    "A1": (0.0, 0.0, 1.0), "A2": (0.0, 0.0, 1.0), "A3": (0.0, 0.0, 1.0), "A4": (0.0, 0.0, 1.0),
    "A5": (0.0, 0.0, 1.0), "A6": (0.0, 0.0, 1.0), "A7": (0.0, 1.0, 0.0),
}


def nominal_anchor_positions(height_m: float = REFERENCE_HEIGHT_M) -> np.ndarray:
    """Anchor positions (7, 3) in m, shoulder frame, for a user of ``height_m`` (no jitter)."""
    height = check_positive(height_m, "height_m")
    s = height / REFERENCE_HEIGHT_M
    shoulder_height = SHOULDER_HEIGHT_FRACTION * height
    out = np.empty((len(ANCHOR_NAMES), 3))
    for i, name in enumerate(ANCHOR_NAMES):
        if ANCHOR_WORN[name]:
            out[i] = np.asarray(_WORN_SITES_175[name]) * s
        else:
            x, y, h = _ROOM_SITES[name]
            out[i] = (x, y, h - shoulder_height)
    return out


# --------------------------------------------------------------------------------------------
# Users
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class User:
    """One user wearing the testbed (module docstring).

    Attributes
    ----------
    name : str
        Identifier written to recordings (no commas or quotes), e.g. ``"U1"``.
    height_m : float
        Body height H (m).
    upper_arm_m, forearm_m : float
        Shoulder–elbow and elbow–wrist lengths (m).
    target_distances_m : tuple of 2 floats
        Distance (m) from the shoulder along the straight arm of T1 (mid upper arm) and T2
        (mid forearm).
    anchor_positions_m : numpy.ndarray, shape (7, 3)
        Anchor positions (m, shoulder frame), in :data:`ANCHOR_NAMES` order.
    anchor_axes : numpy.ndarray, shape (7, 3)
        Unit antenna axes of the anchors (:data:`ANCHOR_AXES`).
    body : BodyShape
        Solids for shadowing.
    environment_seed : int
        Seed of the quenched randomness of this user's radio environment (the spatial
        shadowing field and the radios' RSSI offsets, :mod:`wsnlib.sim.radio`): the same on
        every day, so a training session and an online session see the same room.
    day : int
        0 for the training day; :meth:`moved` increments it (new anchor placement, partly
        new propagation environment).
    """

    name: str
    height_m: float
    upper_arm_m: float
    forearm_m: float
    target_distances_m: tuple[float, float]
    anchor_positions_m: np.ndarray
    anchor_axes: np.ndarray = field(default_factory=lambda: np.array([ANCHOR_AXES[a] for a in ANCHOR_NAMES],
                                                                     dtype=float))
    body: BodyShape = field(default_factory=BodyShape)
    environment_seed: int = 0
    day: int = 0

    def __post_init__(self):
        check_name(self.name, "name")
        check_fields(self, positive=("height_m", "upper_arm_m", "forearm_m"))
        d = as_float_array(self.target_distances_m, "target_distances_m")
        if d.shape != (2,) or not (0.0 < d[0] <= self.upper_arm_m < d[1] <= self.upper_arm_m + self.forearm_m):
            raise ValueError("target_distances_m must be (d1, d2) with T1 on the upper arm and T2 on the forearm, "
                             f"got {tuple(d)} for upper arm {self.upper_arm_m:g} m and forearm {self.forearm_m:g} m")
        object.__setattr__(self, "target_distances_m", (float(d[0]), float(d[1])))
        for name in ("anchor_positions_m", "anchor_axes"):
            arr = as_float_array(getattr(self, name), name, last_dim=3)
            if arr.shape != (len(ANCHOR_NAMES), 3):
                raise ValueError(f"{name} must have shape ({len(ANCHOR_NAMES)}, 3), got {arr.shape}")
            if name == "anchor_axes":
                arr = arr / np.linalg.norm(arr, axis=-1, keepdims=True)
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        check_type(self.body, BodyShape, "body")
        for name in ("environment_seed", "day"):
            object.__setattr__(self, name, check_count(getattr(self, name), name, 0))

    @property
    def worn(self) -> np.ndarray:
        """Boolean (7,): which anchors are worn (on-body links)."""
        return np.array([ANCHOR_WORN[a] for a in ANCHOR_NAMES])

    @property
    def geometry(self) -> ArmGeometry:
        """The user's arm (:class:`wsnlib.arm_model.ArmGeometry`, devices on the segment axes).

        Segment lengths ``(upper_arm_m, forearm_m)``; device offsets: T1's distance from the
        shoulder and T2's distance from the elbow, ``(d1, d2 − upper_arm_m)`` (m).  This is
        also the user's :class:`wsnlib.posture.ArmChain` (paper 002's d and d′).
        """
        d1, d2 = self.target_distances_m
        return ArmGeometry.on_axis((self.upper_arm_m, self.forearm_m), (d1, d2 - self.upper_arm_m))

    def target_positions(self, posture: str) -> np.ndarray:
        """Target positions (2, 3) in m on the arm axis in ``posture`` (Table 1 for this user)."""
        return np.outer(self.target_distances_m, posture_direction(posture))

    def anchor_dict(self) -> dict[str, list[float]]:
        """``{anchor: [x, y, z]}`` (m), JSON-ready."""
        return {a: [float(v) for v in p] for a, p in zip(ANCHOR_NAMES, self.anchor_positions_m, strict=True)}

    def moved(self, rng: np.random.Generator, *, worn_sigma_m: float = 0.015, stance_sigma_m: float = 0.02,
              target_sigma_m: float = 0.01) -> User:
        """The same user on another day: t-shirt re-donned, back on the floor mark, targets re-strapped.

        Parameters
        ----------
        rng : numpy.random.Generator
        worn_sigma_m : float
            Std (m, per axis) of the displacement of each worn anchor (assumed 1.5 cm).
        stance_sigma_m : float
            Std (m, per horizontal axis) of where the user stands; room anchors move by the
            opposite offset relative to the shoulder (assumed 2 cm).
        target_sigma_m : float
            Std (m) of each target's displacement along the arm (assumed 1 cm); clipped so
            T1 stays on the upper arm and T2 on the forearm.

        Returns
        -------
        User
            ``day`` incremented, same ``environment_seed``.
        """
        anchors = _jitter_anchors(self.anchor_positions_m, rng, worn_sigma_m, stance_sigma_m)
        sigma = check_nonnegative(target_sigma_m, "target_sigma_m")
        d = np.asarray(self.target_distances_m) + rng.normal(0.0, sigma, 2)
        margin = 0.02
        d[0] = np.clip(d[0], margin, self.upper_arm_m - margin)
        d[1] = np.clip(d[1], self.upper_arm_m + margin, self.upper_arm_m + self.forearm_m - margin)
        return dataclasses.replace(self, anchor_positions_m=anchors, target_distances_m=tuple(d), day=self.day + 1)


def _jitter_anchors(positions: np.ndarray, rng: np.random.Generator, worn_sigma: float,
                    stance_sigma: float) -> np.ndarray:
    worn_sigma = check_nonnegative(worn_sigma, "worn_sigma_m")
    stance_sigma = check_nonnegative(stance_sigma, "stance_sigma_m")
    worn = np.array([ANCHOR_WORN[a] for a in ANCHOR_NAMES])
    out = np.array(positions, dtype=float)
    out[worn] += rng.normal(0.0, worn_sigma, (int(worn.sum()), 3))
    stance = np.array([*rng.normal(0.0, stance_sigma, 2), 0.0])
    out[~worn] -= stance
    return out


def user_from_height(name: str, height_m: float, *, environment_seed: int = 0, anchor_positions_m=None) -> User:
    """A user of body height ``height_m`` with Winter's proportions and nominal anchors.

    Upper arm 0.186 H, forearm 0.146 H, T1 at mid upper arm, T2 at mid forearm, body solids
    scaled from 1.75 m, anchors at :func:`nominal_anchor_positions` unless given.
    """
    height = check_positive(height_m, "height_m")
    upper = UPPER_ARM_FRACTION * height
    fore = FOREARM_FRACTION * height
    anchors = nominal_anchor_positions(height) if anchor_positions_m is None else anchor_positions_m
    return User(name=name, height_m=height, upper_arm_m=upper, forearm_m=fore,
                target_distances_m=(0.5 * upper, upper + 0.5 * fore), anchor_positions_m=anchors,
                body=BodyShape.from_height(height), environment_seed=environment_seed)


def make_users(n_users: int = 5, *, rng: np.random.Generator, heights_m=None, worn_sigma_m: float = 0.02,
               stance_sigma_m: float = 0.02) -> list[User]:
    """``n_users`` users ("U1", "U2", …) with different heights and slightly different anchor placement.

    Parameters
    ----------
    n_users : int
        Paper 002 had five users (Sec. 4.1).
    rng : numpy.random.Generator
    heights_m : array_like, optional
        Body heights (m); default drawn uniformly in [1.60, 1.90] m (an adult range; assumed).
    worn_sigma_m : float
        Std (m, per axis) of each worn anchor's offset from its nominal site (t-shirt fit;
        assumed 2 cm).
    stance_sigma_m : float
        Std (m, per horizontal axis) of the user's stance relative to the room anchors
        (assumed 2 cm).

    Returns
    -------
    list of User
        Each with its own ``environment_seed`` drawn from ``rng``, ``day = 0``.
    """
    check_count(n_users, "n_users")
    if heights_m is None:
        heights = rng.uniform(1.60, 1.90, n_users)
    else:
        heights = as_float_array(heights_m, "heights_m")
        if heights.shape != (n_users,):
            raise ValueError(f"heights_m must have shape ({n_users},), got {heights.shape}")
    users = []
    for i, height in enumerate(heights):
        anchors = _jitter_anchors(nominal_anchor_positions(height), rng, worn_sigma_m, stance_sigma_m)
        seed = int(rng.integers(0, 2**31 - 1))
        users.append(user_from_height(f"U{i + 1}", float(height), environment_seed=seed, anchor_positions_m=anchors))
    return users


# --------------------------------------------------------------------------------------------
# Body solids and the length of a radio link inside them
# --------------------------------------------------------------------------------------------


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
        Solid("torso", "cylinder", np.array([cx, 0.0, b.torso_bottom_z_m]), b.torso_half_width_m, ez,
              b.torso_top_z_m - b.torso_bottom_z_m, ex, b.torso_half_depth_m),
        Solid("legs", "cylinder", np.array([cx, 0.0, b.floor_z_m]), b.legs_half_width_m, ez,
              b.torso_bottom_z_m - b.floor_z_m, ex, b.legs_half_depth_m),
        Solid("neck", "cylinder", np.array([cx, 0.0, b.torso_top_z_m]), b.neck_radius_m, ez, b.neck_length_m, ex,
              b.neck_radius_m),
        Solid("head", "sphere", np.array([cx, 0.0, b.head_center_z_m]), b.head_radius_m),
        # The left shoulder mirrors the right one (the origin) about the torso centre.
        Solid("left_arm", "cylinder", np.array([2.0 * cx, 0.0, -b.left_arm_length_m]), b.upper_arm_radius_m,
              ez, b.left_arm_length_m, ex, b.upper_arm_radius_m),
    ]
    if arm_direction is not None:
        u = as_float_array(arm_direction, "arm_direction", last_dim=3)
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        ref = perpendicular_unit(u)
        solids.append(Solid("upper_arm", "cylinder", np.zeros_like(u), b.upper_arm_radius_m, u, user.upper_arm_m, ref,
                            b.upper_arm_radius_m))
        solids.append(Solid("forearm", "cylinder", u * user.upper_arm_m, b.forearm_radius_m, u, user.forearm_m, ref,
                            b.forearm_radius_m))
    return solids


def perpendicular_unit(u: np.ndarray) -> np.ndarray:
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
