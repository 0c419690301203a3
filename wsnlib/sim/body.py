"""Body, users, arm postures and movements of paper 002's testbed (Giuberti et al., Sec. 4.1).

The user stands still; two targets are strapped to the straight right arm (T1 mid upper arm,
T2 mid forearm); seven anchors are worn (A1, A4, A6, A7: t-shirt pockets and a hat) or fixed
in the room (A2, A3, A5).  This module holds the geometry; :mod:`wsnlib.sim.radio` turns it
into received signal strengths.

Shoulder frame
--------------
Origin at the centre of the right shoulder joint; **x** to the user's right (lateral),
**y** forward, **z** up (paper 002, footnote 4: z vertical, y forward, x normal to the
sagittal plane; the signs follow Table 1: P4, the arm held out sideways, has x > 0, and P5,
across the body, has x < 0).  The frame is right-handed and is the package's ENU earth frame
for a user facing north, so quaternions, angular rates and accelerations here follow
``wsnlib/__init__.py`` unchanged.  Lengths are in metres.

Postures (paper 002, Table 1)
-----------------------------
The arm is straight in every posture, so both targets lie on one ray from the shoulder, at
``d1`` (T1) and ``d2`` (T2) along the arm direction ``u``:

====  =============================  =========================================
P1    arm down                       u = (0, 0, −1)
P2    arm up                         u = (0, 0, +1)
P3    forward, horizontal            u = (0, +1, 0)
P4    sideways (right), horizontal   u = (+1, 0, 0)
P5    across the body, horizontal    u = (−sin 56.7°, cos 56.7°, 0)
====  =============================  =========================================

Table 1's P5 entries, T1 (−11, 11, 0) cm and T2 (−34, 21, 0) cm, are not collinear with the
shoulder (45° and 58° across the body; T2 is 40 cm from the shoulder, not 42.5 cm), so no
straight arm passes through both.  We take the straight arm that fits both points in least
squares, ``u ∝ d1·T1 + d2·T2`` (56.7° across the body), which misses the table by 3.2 cm
(T1) and 2.7 cm (T2).  :data:`TABLE1_POSITIONS_CM` keeps the table verbatim.

Segment (node) frames follow :mod:`wsnlib.sim.arm`: body x along the segment (distal), body
z "dorsal" (up when the arm points forward palm down), body y = z × x.  A posture's
orientation is ``R_z(ψ) ⊗ q_ref ⊗ R_y(−θ)`` with heading ψ and pitch θ of ``u`` (ψ = 0 for
the vertical postures), i.e. each posture is P3 turned rigidly about the vertical (P4, P5) or
the lateral axis (P1, P2).  Moving the arm along the paper's movements reproduces exactly
these orientations at the end points (tested).

Movements (paper 002, Sec. 4.1 and Fig. 5)
------------------------------------------
Four transitional movements, each at constant angular speed (the paper's users were asked to
move "at constant speed", 2–4 s per movement), each a rotation of the straight arm about one
fixed axis through the shoulder:

* ``lower_P2_P3_P1``: from P2 down through P3 to P1 (180° about −x);
* ``horizontal_P4_P3_P5``: from P4 through P3 to P5 (146.7° about +z);
* ``raise_P1_P3``: from P1 up to P3 (90° about −x);
* ``horizontal_P3_P4``: from P3 to P4 (90° about −z).

:func:`arc` builds any constant-speed great-circle arc between two directions (SLERP of the
directions), optionally through a via-point (two great-circle pieces at the same angular
speed; the angular velocity jumps at the via-point unless both pieces share the axis, as in
the paper's movements).  Angular acceleration is zero inside every piece; the steps of the
angular velocity at the start and end of a constant-speed movement are idealised away (a
real arm needs some 100 ms to get up to speed).

Users and anchors
-----------------
Segment lengths from body height H (D. A. Winter, *Biomechanics and Motor Control of Human
Movement*, 4th ed., Wiley 2009, Fig. 4.1, after Drillis & Contini 1966: upper arm 0.186 H,
forearm 0.146 H, shoulder height 0.818 H; see :mod:`wsnlib.sim.arm` for how far these were
checked).  Paper 002's own user had T1 at 15 cm and T2 at 42.5 cm: upper arm 30 cm and
forearm 25 cm (:func:`paper_user`), i.e. H ≈ 1.62 m by Winter's fractions.

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

from wsnlib import quaternion as Q
from wsnlib._validation import as_float_array, check_nonnegative, check_positive
from wsnlib.sim.arm import FOREARM_FRACTION, Q_REFERENCE, UPPER_ARM_FRACTION

# The testbed of paper 002 (names, Table 1, postures, movements) lives in wsnlib.testbed, which
# the file formats read too; re-exported here for the simulators and for users' scripts.
from wsnlib.testbed import (  # noqa: F401
    ANCHOR_NAMES,
    ANCHOR_WORN,
    MOVEMENTS,
    PAPER_TARGET_DISTANCES_M,
    POSTURE_DIRECTIONS,
    POSTURES,
    TABLE1_POSITIONS_CM,
    TARGET_NAMES,
    TRANSITION_LABEL,
    posture_direction,
)


def _unit(v, name: str) -> np.ndarray:
    v = as_float_array(v, name)
    if v.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {v.shape}")
    norm = np.linalg.norm(v)
    if norm == 0.0:
        raise ValueError(f"{name} must not be the zero vector")
    return v / norm


def direction_orientation(direction) -> np.ndarray:
    """Segment orientation (4,) for an arm pointing along ``direction``, axial rotation 0.

    ``R_z(ψ) ⊗ q_ref ⊗ R_y(−θ)`` (the convention of :mod:`wsnlib.sim.arm`) with heading
    ``ψ = atan2(−u_x, u_y)`` (0 for a vertical arm) and pitch ``θ = asin(u_z)``; the segment's
    body x axis is rotated onto ``direction``.
    """
    u = _unit(direction, "direction")
    pitch = float(np.arcsin(np.clip(u[2], -1.0, 1.0)))
    horizontal = np.hypot(u[0], u[1])
    heading = 0.0 if horizontal < 1e-12 else float(np.arctan2(-u[0], u[1]))
    q_heading = Q.from_axis_angle([0.0, 0.0, 1.0], heading)
    q_pitch = Q.from_axis_angle([0.0, 1.0, 0.0], -pitch)
    return Q.multiply(Q.multiply(q_heading, Q_REFERENCE), q_pitch)


def posture_orientation(posture: str) -> np.ndarray:
    """Orientation (4,) of both segments in ``posture`` (:func:`direction_orientation`)."""
    return direction_orientation(posture_direction(posture))


# --------------------------------------------------------------------------------------------
# Body shape
# --------------------------------------------------------------------------------------------

#: Height (m) for which the body sizes and worn-anchor sites below are given.
REFERENCE_HEIGHT_M = 1.75

#: Shoulder height as a fraction of body height (Winter 2009, Fig. 4.1).
SHOULDER_HEIGHT_FRACTION = 0.818


@dataclass(frozen=True)
class BodyShape:
    """Sizes (m) of the simple solids used for body shadowing (module docstring; assumed).

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

    @property
    def left_shoulder_x_m(self) -> float:
        """x (m) of the left shoulder joint (mirror of the right one about the torso)."""
        return 2.0 * self.torso_center_x_m


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
_ROOM_SITES = {
    "A2": (1.0, 1.5, 0.75),
    "A3": (2.0, -0.3, 1.80),
    "A5": (-1.2, 2.5, 1.20),
}

#: Antenna axis of each anchor (unit vector, shoulder frame; assumed): worn nodes stand
#: upright in their pocket, the hat node lies flat pointing forward, room nodes stand upright.
ANCHOR_AXES: dict[str, tuple[float, float, float]] = {
    "A1": (0.0, 0.0, 1.0),
    "A2": (0.0, 0.0, 1.0),
    "A3": (0.0, 0.0, 1.0),
    "A4": (0.0, 0.0, 1.0),
    "A5": (0.0, 0.0, 1.0),
    "A6": (0.0, 0.0, 1.0),
    "A7": (0.0, 1.0, 0.0),
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
    anchor_axes: np.ndarray = field(
        default_factory=lambda: np.array([ANCHOR_AXES[a] for a in ANCHOR_NAMES], dtype=float)
    )
    body: BodyShape = field(default_factory=BodyShape)
    environment_seed: int = 0
    day: int = 0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip() or any(c in self.name for c in ',"\n\r'):
            raise ValueError(f"name must be a non-empty string without commas or quotes, got {self.name!r}")
        for name in ("height_m", "upper_arm_m", "forearm_m"):
            object.__setattr__(self, name, check_positive(getattr(self, name), name))
        d = as_float_array(self.target_distances_m, "target_distances_m")
        if d.shape != (2,) or not (0.0 < d[0] <= self.upper_arm_m < d[1] <= self.upper_arm_m + self.forearm_m):
            raise ValueError(
                "target_distances_m must be (d1, d2) with T1 on the upper arm and T2 on the forearm, "
                f"got {tuple(d)} for upper arm {self.upper_arm_m:g} m and forearm {self.forearm_m:g} m"
            )
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
        if not isinstance(self.body, BodyShape):
            raise ValueError(f"body must be a BodyShape, got {type(self.body).__name__}")
        for name in ("environment_seed", "day"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
            object.__setattr__(self, name, int(value))

    @property
    def worn(self) -> np.ndarray:
        """Boolean (7,): which anchors are worn (on-body links)."""
        return np.array([ANCHOR_WORN[a] for a in ANCHOR_NAMES])

    def target_positions(self, posture: str) -> np.ndarray:
        """Target positions (2, 3) in m on the arm axis in ``posture`` (Table 1 for this user)."""
        return np.outer(self.target_distances_m, posture_direction(posture))

    def anchor_dict(self) -> dict[str, list[float]]:
        """``{anchor: [x, y, z]}`` (m), JSON-ready."""
        return {a: [float(v) for v in p] for a, p in zip(ANCHOR_NAMES, self.anchor_positions_m, strict=True)}

    def to_dict(self) -> dict:
        """JSON-ready parameters (for recording sidecars)."""
        return {
            "name": self.name,
            "height_m": self.height_m,
            "upper_arm_m": self.upper_arm_m,
            "forearm_m": self.forearm_m,
            "target_distances_m": list(self.target_distances_m),
            "anchor_positions_m": self.anchor_dict(),
            "environment_seed": self.environment_seed,
            "day": self.day,
        }

    def moved(
        self,
        rng: np.random.Generator,
        *,
        worn_sigma_m: float = 0.015,
        stance_sigma_m: float = 0.02,
        target_sigma_m: float = 0.01,
    ) -> User:
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
        d = np.asarray(self.target_distances_m) + rng.normal(
            0.0, check_nonnegative(target_sigma_m, "target_sigma_m"), 2
        )
        margin = 0.02
        d[0] = np.clip(d[0], margin, self.upper_arm_m - margin)
        d[1] = np.clip(d[1], self.upper_arm_m + margin, self.upper_arm_m + self.forearm_m - margin)
        return dataclasses.replace(self, anchor_positions_m=anchors, target_distances_m=tuple(d), day=self.day + 1)


def _jitter_anchors(
    positions: np.ndarray, rng: np.random.Generator, worn_sigma: float, stance_sigma: float
) -> np.ndarray:
    worn_sigma = check_nonnegative(worn_sigma, "worn_sigma_m")
    stance_sigma = check_nonnegative(stance_sigma, "stance_sigma_m")
    worn = np.array([ANCHOR_WORN[a] for a in ANCHOR_NAMES])
    out = np.array(positions, dtype=float)
    out[worn] += rng.normal(0.0, worn_sigma, (int(worn.sum()), 3))
    stance = np.array([*rng.normal(0.0, stance_sigma, 2), 0.0])
    out[~worn] -= stance
    return out


def user_from_height(
    name: str,
    height_m: float,
    *,
    environment_seed: int = 0,
    anchor_positions_m=None,
) -> User:
    """A user of body height ``height_m`` with Winter's proportions and nominal anchors.

    Upper arm 0.186 H, forearm 0.146 H, T1 at mid upper arm, T2 at mid forearm, body solids
    scaled from 1.75 m, anchors at :func:`nominal_anchor_positions` unless given.
    """
    height = check_positive(height_m, "height_m")
    upper = UPPER_ARM_FRACTION * height
    fore = FOREARM_FRACTION * height
    anchors = nominal_anchor_positions(height) if anchor_positions_m is None else anchor_positions_m
    return User(
        name=name,
        height_m=height,
        upper_arm_m=upper,
        forearm_m=fore,
        target_distances_m=(0.5 * upper, upper + 0.5 * fore),
        anchor_positions_m=anchors,
        body=BodyShape.from_height(height),
        environment_seed=environment_seed,
    )


def paper_user(name: str = "paper", *, environment_seed: int = 0) -> User:
    """Paper 002's user: T1 at 15 cm and T2 at 42.5 cm (Table 1), upper arm 0.30 m, forearm 0.25 m.

    Height 1.62 m (Winter's 0.186 H = 0.30 m); anchors at their nominal sites, no jitter.
    """
    height = 0.30 / UPPER_ARM_FRACTION
    return User(
        name=name,
        height_m=height,
        upper_arm_m=0.30,
        forearm_m=0.25,
        target_distances_m=PAPER_TARGET_DISTANCES_M,
        anchor_positions_m=nominal_anchor_positions(height),
        body=BodyShape.from_height(height),
        environment_seed=environment_seed,
    )


def make_users(
    n_users: int = 5,
    *,
    rng: np.random.Generator,
    heights_m=None,
    worn_sigma_m: float = 0.02,
    stance_sigma_m: float = 0.02,
) -> list[User]:
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
    if isinstance(n_users, bool) or not isinstance(n_users, (int, np.integer)) or n_users < 1:
        raise ValueError(f"n_users must be a positive integer, got {n_users!r}")
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
# Arm motion: pieces of constant-speed rotation about fixed axes
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ArmMotion:
    """Motion of the straight right arm: consecutive pieces, each a rotation at constant
    angular speed about a fixed axis through the shoulder (speed 0 = holding still).

    Build with :func:`hold`, :func:`arc`, :func:`movement`, :func:`transition` and
    :meth:`then` / :func:`concatenate`; evaluate with :meth:`kinematics` or :meth:`sample`.

    Attributes (one entry per piece)
    --------------------------------
    start_s : numpy.ndarray (P,)
        Piece start times (s), from 0; piece ``i`` lasts ``duration_s[i]``.
    duration_s : numpy.ndarray (P,)
    quat_start : numpy.ndarray (P, 4)
        Segment orientation at the start of the piece (both segments: the arm is straight).
    axis : numpy.ndarray (P, 3)
        Unit rotation axis (shoulder frame).
    speed : numpy.ndarray (P,)
        Angular speed (rad/s), ≥ 0.
    labels : tuple of str (P,)
        Label of each piece (posture name, movement label or :data:`TRANSITION_LABEL`).
    """

    start_s: np.ndarray
    duration_s: np.ndarray
    quat_start: np.ndarray
    axis: np.ndarray
    speed: np.ndarray
    labels: tuple[str, ...]

    def __post_init__(self):
        n = len(self.labels)
        if n == 0:
            raise ValueError("an ArmMotion needs at least one piece")
        for name, shape in (
            ("start_s", (n,)),
            ("duration_s", (n,)),
            ("quat_start", (n, 4)),
            ("axis", (n, 3)),
            ("speed", (n,)),
        ):
            arr = as_float_array(getattr(self, name), name)
            if arr.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if np.any(self.duration_s <= 0.0) or np.any(self.speed < 0.0):
            raise ValueError("durations must be > 0 and speeds >= 0")
        for label in self.labels:
            if not isinstance(label, str) or not label or any(c in label for c in ',"\n\r'):
                raise ValueError(f"labels must be non-empty strings without commas or quotes, got {label!r}")
        object.__setattr__(self, "labels", tuple(self.labels))

    @property
    def total_duration_s(self) -> float:
        """End time (s) of the last piece."""
        return float(self.start_s[-1] + self.duration_s[-1])

    @property
    def quat_end(self) -> np.ndarray:
        """Orientation (4,) at the end of the motion."""
        angle = self.speed[-1] * self.duration_s[-1]
        return Q.multiply(Q.from_axis_angle(self.axis[-1], angle), self.quat_start[-1])

    @property
    def direction_end(self) -> np.ndarray:
        """Arm direction (3,) at the end of the motion."""
        return Q.rotate(self.quat_end, [1.0, 0.0, 0.0])

    def then(self, other: ArmMotion) -> ArmMotion:
        """This motion followed by ``other`` (shifted in time to start at this one's end).

        ``other`` must start where this one ends (same orientation within 1e-6 rad); build it
        from :attr:`quat_end` (the builders take ``q_start``) if the segment's axial twist
        matters.
        """
        return concatenate([self, other])

    def _piece_at(self, t: np.ndarray) -> np.ndarray:
        idx = np.searchsorted(self.start_s, t, side="right") - 1
        return np.clip(idx, 0, len(self.labels) - 1)

    def kinematics(self, time_s, user: User) -> ArmKinematics:
        """Exact state of both segments and targets at times ``time_s`` (s).

        Times before 0 or after the end hold the first/last orientation (at rest).
        """
        t = as_float_array(time_s, "time_s")
        if t.ndim != 1:
            raise ValueError(f"time_s must be 1-D, got shape {t.shape}")
        if not isinstance(user, User):
            raise ValueError(f"user must be a User, got {type(user).__name__}")
        idx = self._piece_at(t)
        local = np.clip(t - self.start_s[idx], 0.0, self.duration_s[idx])
        moving = (t >= self.start_s[idx]) & (t < self.start_s[idx] + self.duration_s[idx])
        axis = self.axis[idx]
        speed = self.speed[idx]
        quat = Q.multiply(Q.from_axis_angle(axis, speed * local), self.quat_start[idx])
        quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
        direction = Q.rotate(quat, np.array([1.0, 0.0, 0.0]))
        omega = np.where(moving[:, None], speed[:, None] * axis, 0.0)
        distances = np.asarray(user.target_distances_m)
        r = direction[:, None, :] * distances[None, :, None]  # (T, 2, 3)
        w = omega[:, None, :]
        velocity = np.cross(np.broadcast_to(w, r.shape), r)
        acceleration = np.cross(np.broadcast_to(w, r.shape), velocity)  # α = 0 within pieces
        quat2 = np.repeat(quat[:, None, :], 2, axis=1)
        return ArmKinematics(
            time_s=t.copy(),
            label=np.array(self.labels, dtype=object)[idx],
            positions=r,
            directions=np.repeat(direction[:, None, :], 2, axis=1),
            quat=quat2,
            omega=omega,
            omega_body=Q.rotate_inverse(quat2, np.broadcast_to(w, r.shape)),
            alpha=np.zeros_like(omega),
            velocity=velocity,
            acceleration=acceleration,
            distances_m=(float(distances[0]), float(distances[1])),
        )

    def sample(self, user: User, fs: float = 30.0) -> ArmKinematics:
        """:meth:`kinematics` at ``k / fs`` for ``k = 0 … round(total · fs)`` (both ends included)."""
        fs = check_positive(fs, "fs")
        n = int(round(self.total_duration_s * fs)) + 1
        return self.kinematics(np.arange(n) / fs, user)


@dataclass(frozen=True, eq=False)
class ArmKinematics:
    """State of the arm at a set of times (shapes with ``T`` samples; axis 1 = target/segment).

    Attributes
    ----------
    time_s : (T,)
        Times (s).
    label : (T,) object
        Label of the piece being executed.
    positions : (T, 2, 3)
        T1 and T2 on the arm axis (m, shoulder frame).
    directions : (T, 2, 3)
        Unit direction of the upper arm and forearm (equal: the arm is straight).
    quat : (T, 2, 4)
        Orientation of the upper-arm and forearm segment frames (convention of
        :mod:`wsnlib.sim.arm`: body x along the segment), rotating segment vectors into the
        shoulder (ENU) frame.
    omega : (T, 3)
        Angular velocity of the arm (rad/s, shoulder frame); constant within a piece.
    omega_body : (T, 2, 3)
        The same in each segment frame (what a gyroscope on the segment would read).
    alpha : (T, 3)
        Angular acceleration (rad/s², shoulder frame): zero inside constant-speed pieces
        (the steps between pieces are impulses, not represented).
    velocity, acceleration : (T, 2, 3)
        Linear velocity (m/s) and acceleration (m/s², gravity not included) of T1 and T2:
        ``ω × r`` and ``ω × (ω × r)``.
    distances_m : tuple of 2 floats
        Target distances along the arm (m).
    """

    time_s: np.ndarray
    label: np.ndarray
    positions: np.ndarray
    directions: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    omega_body: np.ndarray
    alpha: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    distances_m: tuple[float, float]

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.time_s.size


def _single_piece(duration_s, quat_start, axis, speed, label) -> ArmMotion:
    return ArmMotion(
        start_s=np.zeros(1),
        duration_s=np.array([check_positive(duration_s, "duration_s")]),
        quat_start=np.asarray(quat_start, dtype=float)[None],
        axis=np.asarray(axis, dtype=float)[None],
        speed=np.array([speed]),
        labels=(label,),
    )


def hold(posture_or_direction, duration_s: float, *, label: str | None = None, q_start=None) -> ArmMotion:
    """Hold the arm still for ``duration_s`` seconds.

    Parameters
    ----------
    posture_or_direction : str or array_like (3,)
        A posture name or an arm direction.
    duration_s : float
    label : str, optional
        Default: the posture name, or ``"hold"`` for a direction.
    q_start : array_like (4,), optional
        Orientation to hold (overrides the direction, e.g. the end of a previous motion).
    """
    if isinstance(posture_or_direction, str):
        q = posture_orientation(posture_or_direction)
        label = posture_or_direction if label is None else label
    else:
        q = direction_orientation(posture_or_direction)
        label = "hold" if label is None else label
    if q_start is not None:
        q = Q.normalize(as_float_array(q_start, "q_start", last_dim=4))
    return _single_piece(duration_s, q, [0.0, 0.0, 1.0], 0.0, label)


def arc(
    direction_start,
    direction_end,
    duration_s: float,
    *,
    via=None,
    label: str = "arc",
    q_start=None,
) -> ArmMotion:
    """Constant-angular-speed great-circle arc of the straight arm (SLERP of directions).

    Parameters
    ----------
    direction_start, direction_end : array_like (3,) or posture name
        Arm directions (normalised here).
    duration_s : float
        Duration of the whole arc (s).
    via : array_like (3,) or posture name, optional
        Pass through this direction: two great-circle pieces with the same angular speed,
        times split in proportion to their angles.  Needed when start and end are (nearly)
        opposite, where the great circle is not defined.
    label : str
        Label of every piece.
    q_start : array_like (4,), optional
        Segment orientation at the start; default :func:`direction_orientation` of
        ``direction_start``.  Must point along ``direction_start``.

    Returns
    -------
    ArmMotion
        With angular speed ``(total angle) / duration_s``.
    """

    def _dir(v, name):
        return posture_direction(v) if isinstance(v, str) else _unit(v, name)

    points = [_dir(direction_start, "direction_start")]
    if via is not None:
        points.append(_dir(via, "via"))
    points.append(_dir(direction_end, "direction_end"))
    duration = check_positive(duration_s, "duration_s")
    angles, axes = [], []
    for a, b in zip(points[:-1], points[1:], strict=True):
        angle = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
        cross = np.cross(a, b)
        if angle > np.pi - 1e-3:
            raise ValueError("start and end of an arc piece are opposite: give a via direction")
        if angle < 1e-9:
            raise ValueError("an arc piece has zero length (equal directions); use hold()")
        angles.append(angle)
        axes.append(cross / np.linalg.norm(cross))
    speed = sum(angles) / duration
    q = (
        direction_orientation(points[0])
        if q_start is None
        else Q.normalize(as_float_array(q_start, "q_start", last_dim=4))
    )
    if not np.allclose(Q.rotate(q, [1.0, 0.0, 0.0]), points[0], atol=1e-6):
        raise ValueError("q_start does not point the arm along direction_start")
    starts, quats = [], []
    t = 0.0
    for angle, axis in zip(angles, axes, strict=True):
        starts.append(t)
        quats.append(q)
        q = Q.multiply(Q.from_axis_angle(axis, angle), q)
        t += angle / speed
    return ArmMotion(
        start_s=np.array(starts),
        duration_s=np.array(angles) / speed,
        quat_start=np.array(quats),
        axis=np.array(axes),
        speed=np.full(len(angles), speed),
        labels=(label,) * len(angles),
    )


def movement(name: str, duration_s: float, *, label: str | None = None) -> ArmMotion:
    """One of the paper's transitional movements (:data:`MOVEMENTS`) at constant speed.

    Parameters
    ----------
    name : str
        Key of :data:`MOVEMENTS`, e.g. ``"lower_P2_P3_P1"``.
    duration_s : float
        Duration (s); the paper's users took 2–4 s.
    label : str, optional
        Default ``name``.
    """
    try:
        postures = MOVEMENTS[name]
    except KeyError:
        raise ValueError(f"movement must be one of {list(MOVEMENTS)}, got {name!r}") from None
    via = postures[1] if len(postures) == 3 else None
    return arc(postures[0], postures[-1], duration_s, via=via, label=name if label is None else label)


def rotate_to(q_start, q_end, duration_s: float, *, label: str = TRANSITION_LABEL) -> ArmMotion:
    """Turn the arm from orientation ``q_start`` to ``q_end`` at constant angular speed.

    One rotation about the fixed axis of ``q_end ⊗ q_start*`` (SLERP of the orientations,
    shorter way round), so the arm arrives in ``q_end`` exactly, axial twist included.
    Equal orientations give a hold.
    """
    q0 = Q.normalize(as_float_array(q_start, "q_start", last_dim=4))
    q1 = Q.normalize(as_float_array(q_end, "q_end", last_dim=4))
    rel = Q.canonical(Q.multiply(q1, Q.conjugate(q0)))
    vec_norm = float(np.linalg.norm(rel[1:]))
    angle = 2.0 * float(np.arctan2(vec_norm, rel[0]))
    duration = check_positive(duration_s, "duration_s")
    if angle < 1e-9:
        return _single_piece(duration, q0, [0.0, 0.0, 1.0], 0.0, label)
    return _single_piece(duration, q0, rel[1:] / vec_norm, angle / duration, label)


def transition(posture_from, posture_to, duration_s: float, *, label: str = TRANSITION_LABEL) -> ArmMotion:
    """Move between postures at constant angular speed, arriving in ``posture_to``'s orientation.

    ``posture_from`` / ``posture_to``: a posture name (its :func:`posture_orientation`), an
    arm direction (3,) (:func:`direction_orientation`) or an orientation quaternion (4,).
    Used for the unlabelled moves between the recorded postures and movements of a session;
    see :func:`rotate_to`.
    """
    return rotate_to(_as_orientation(posture_from), _as_orientation(posture_to), duration_s, label=label)


def _as_orientation(value) -> np.ndarray:
    if isinstance(value, str):
        return posture_orientation(value)
    arr = as_float_array(value, "orientation")
    if arr.shape == (4,):
        return Q.normalize(arr)
    if arr.shape == (3,):
        return direction_orientation(arr)
    raise ValueError(f"expected a posture name, a direction (3,) or a quaternion (4,), got shape {arr.shape}")


def concatenate(motions) -> ArmMotion:
    """Motions one after the other; each must start in the orientation where the previous ended."""
    motions = list(motions)
    if not motions:
        raise ValueError("concatenate needs at least one motion")
    starts, durations, quats, axes, speeds, labels = [], [], [], [], [], []
    offset = 0.0
    for i, m in enumerate(motions):
        if not isinstance(m, ArmMotion):
            raise ValueError(f"motions[{i}] must be an ArmMotion, got {type(m).__name__}")
        if i > 0:
            gap = float(Q.angle_between(motions[i - 1].quat_end, m.quat_start[0]))
            if gap > 1e-6:
                raise ValueError(f"motions[{i}] starts {np.degrees(gap):.3g}° away from where motions[{i - 1}] ends")
        starts.append(m.start_s + offset)
        durations.append(m.duration_s)
        quats.append(m.quat_start)
        axes.append(m.axis)
        speeds.append(m.speed)
        labels.extend(m.labels)
        offset += m.total_duration_s
    return ArmMotion(
        start_s=np.concatenate(starts),
        duration_s=np.concatenate(durations),
        quat_start=np.concatenate(quats),
        axis=np.concatenate(axes),
        speed=np.concatenate(speeds),
        labels=tuple(labels),
    )


def jittered_direction(posture: str, sigma_deg: float, rng: np.random.Generator) -> np.ndarray:
    """``posture``'s direction turned by a small random rotation (rotation vector ~ N(0, σ²) per axis).

    Models a user replicating a posture within a few degrees (paper 002, footnote 8: "slight
    variations of the kept arm postures are unavoidable").
    """
    sigma = np.radians(check_nonnegative(sigma_deg, "sigma_deg"))
    rot = Q.from_rotation_vector(rng.normal(0.0, sigma, 3))
    return Q.rotate(rot, posture_direction(posture))


# --------------------------------------------------------------------------------------------
# Body solids and segment–solid intersection (for shadowing)
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


def antenna_positions(kin: ArmKinematics, user: User, standoff_m: float = 0.01) -> np.ndarray:
    """Radio antenna position (T, 2, 3) of T1 and T2: on the lateral skin of their segment.

    The node sits on the segment's body −y side (lateral in the reference posture, arm
    forward), ``radius + standoff_m`` from the arm axis (module docstring).
    """
    lateral = Q.rotate(kin.quat, np.array([0.0, -1.0, 0.0]))  # (T, 2, 3)
    radii = np.array([user.body.upper_arm_radius_m, user.body.forearm_radius_m]) + standoff_m
    return kin.positions + lateral * radii[None, :, None]
