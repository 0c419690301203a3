"""Users of paper 002's testbed: body shape, anchor sites and arm geometry (Giuberti et al., Sec. 4.1).

The testbed, the shoulder frame and the choices behind every number below are described in
:mod:`wsnlib.sim.body` (sections "Users and anchors" and "Body for shadowing").  A
:class:`User` carries its arm as :attr:`User.geometry`, a :class:`wsnlib.arm_model.ArmGeometry`
(the one geometry type of the package), which the motions (:mod:`wsnlib.sim.arm_motion`), the
radio (:mod:`wsnlib.sim.radio_links`) and the posture chain (:mod:`wsnlib.posture`) read.
Lengths in metres, shoulder frame (x right, y forward, z up).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from wsnlib._validation import as_float_array, check_nonnegative, check_positive
from wsnlib.arm_model import FOREARM_FRACTION, UPPER_ARM_FRACTION, ArmGeometry
from wsnlib.testbed import ANCHOR_NAMES, ANCHOR_WORN, PAPER_TARGET_DISTANCES_M, posture_direction

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


__all__ = [
    "ANCHOR_AXES",
    "REFERENCE_HEIGHT_M",
    "SHOULDER_HEIGHT_FRACTION",
    "BodyShape",
    "User",
    "make_users",
    "nominal_anchor_positions",
    "paper_user",
    "user_from_height",
]
