"""The one arm model of the package: geometry and kinematics of the two-segment arm.

Both papers use the same arm: the chain shoulder → upper arm (humerus) → elbow → forearm →
wrist, one device on each segment.  Paper 001 puts an IMU node on each segment, paper 002 a
radio target (T1 mid upper arm, T2 mid forearm) with a SunSPOT accelerometer, and recovers the
elbow and wrist with the recursive chain of :mod:`wsnlib.posture`.  This module holds what they
share, below every simulator and estimator (it imports neither :mod:`wsnlib.sim` nor
:mod:`wsnlib.posture`):

* :class:`ArmGeometry` — segment lengths and device mounting points (m);
* :class:`ArmKinematics` — the exact state of both segments and devices over time, in the
  package's ``(node, T, C)`` layout: orientation, angular rate and acceleration, device and
  joint positions, velocities and accelerations, and the specific force a device feels.

Motion generators produce :class:`ArmKinematics`: the joint-angle trajectories of paper 001
(:func:`wsnlib.sim.arm.arm_kinematics`) and the constant-speed straight-arm motions of paper
002 (:meth:`wsnlib.sim.arm_motion.ArmMotion.kinematics`).  Consumers read it: the IMU simulator
(:mod:`wsnlib.sim.imu`), the radio link budget (:mod:`wsnlib.sim.radio`), the SunSPOT
accelerometer (:mod:`wsnlib.sim.sunspot`), the Kinect-like optical tracker
(:func:`wsnlib.sim.campaign.simulate_kinect_stream`), and the posture chain
(:func:`wsnlib.posture.forward_chain`/:func:`~wsnlib.posture.recursive_chain`, whose
``ArmChain`` is :class:`ArmGeometry`).

Frame
-----
Earth frame ENU with the origin at the centre of the (right) shoulder joint: x east, y north,
z up.  For paper 002's user facing north this is Table 1's frame (x to the user's right, y
forward, z up).  Lengths in metres, times in seconds, angles in radians.

Segment (body) frames
---------------------
Each segment's body frame: **x** along the segment, distally (shoulder → elbow, elbow →
wrist); **z** the dorsal side, up when the arm points forward (north) palm down; **y = z × x**
(west, the user's left, in that reference posture).  Quaternions ``[w, x, y, z]`` rotate body
vectors into the earth frame (body → ENU), as everywhere in the package.  In the reference
posture both segments have :data:`Q_REFERENCE` (90° about earth z).

Devices
-------
Device ``s`` sits on segment ``s`` at ``device_offsets_m[s]`` along body x from the segment's
proximal joint (the paper-002 chain's d′), and ``device_normal_offsets_m[s] = (y, z)`` off the
segment axis in the segment's body frame (e.g. the 4 cm soft tissue to the dorsal skin of
paper 001's IMU straps).  Paper 002's targets are on the axis (Table 1 convention); the radio
puts its antenna on the lateral skin on top of that (:func:`wsnlib.sim.radio.antenna_positions`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib._validation import as_float_array, check_nonnegative, check_positive

#: Node (segment) names, in the order of the node axis of every array of :class:`ArmKinematics`.
NODE_NAMES: tuple[str, str] = ("humerus", "forearm")

#: Joint names, in the order of the joint axis of :attr:`ArmKinematics.joint_pos`.
JOINT_NAMES: tuple[str, str, str] = ("shoulder", "elbow", "wrist")

#: Orientation of both segments in the reference posture (arm forward/north, palm down):
#: 90° about earth z, so body x → north, body y → west, body z → up.
Q_REFERENCE = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])

#: Body height (m) of the default :class:`ArmGeometry`: an adult of 1.75 m.
DEFAULT_BODY_HEIGHT_M = 1.75

#: Upper-arm (shoulder–elbow) length as a fraction of body height (D. A. Winter,
#: *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley 2009, Fig. 4.1).
UPPER_ARM_FRACTION = 0.186

#: Forearm (elbow–wrist) length as a fraction of body height (same source).
FOREARM_FRACTION = 0.146

#: Paper 001's IMU mounting (assumed): node at 60 % of the upper arm and 80 % of the forearm
#: from the proximal joint, on the dorsal skin 4 cm and 3 cm off the bone axis.
PAPER001_NODE_FRACTIONS: tuple[float, float] = (0.6, 0.8)
PAPER001_NODE_DORSAL_M: tuple[float, float] = (0.04, 0.03)

_X = np.array([1.0, 0.0, 0.0])


@dataclass(frozen=True)
class ArmGeometry:
    """Segment lengths and device mounting points of an arm (a chain of S segments, m).

    The one geometry type of the package (module docstring).  :mod:`wsnlib.posture` calls it
    ``ArmChain`` (its recursive chain works for any S); the kinematics needs S = 2.

    Parameters
    ----------
    segment_lengths_m : sequence of float, length S
        Proximal → distal joint distance of each segment (paper 002's d), m, ``> 0``: upper
        arm (shoulder → elbow), forearm (elbow → wrist), …
    device_offsets_m : sequence of float, length S
        Distance of each segment's device from the segment's proximal joint along the segment
        (paper 002's d′), m, in ``[0, segment length]``.
    device_normal_offsets_m : sequence of S pairs of float, optional
        Offset ``(y, z)`` of each device from the segment axis, in the segment's body frame
        (m); default on the axis, ``(0, 0)``.

    Notes
    -----
    Paper 001's arm is :meth:`paper001`; paper 002's users carry theirs as
    :attr:`wsnlib.sim.body.User.geometry`, and its paper arm is
    :data:`wsnlib.posture.PAPER_ARM_CHAIN`.
    """

    segment_lengths_m: tuple[float, ...]
    device_offsets_m: tuple[float, ...]
    device_normal_offsets_m: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self):
        lengths = tuple(check_positive(v, "segment_lengths_m") for v in np.atleast_1d(self.segment_lengths_m))
        offsets = tuple(check_nonnegative(v, "device_offsets_m") for v in np.atleast_1d(self.device_offsets_m))
        if not lengths:
            raise ValueError("segment_lengths_m must hold at least one segment")
        if len(offsets) != len(lengths):
            raise ValueError(f"device_offsets_m has {len(offsets)} entries but segment_lengths_m has {len(lengths)}")
        for i, (offset, length) in enumerate(zip(offsets, lengths, strict=True)):
            if offset > length:
                raise ValueError(f"device_offsets_m[{i}] = {offset!r} exceeds segment_lengths_m[{i}] = {length!r}: "
                                 f"the device must sit on its segment")
        if self.device_normal_offsets_m is None:
            normal = ((0.0, 0.0),) * len(lengths)
        else:
            arr = as_float_array(self.device_normal_offsets_m, "device_normal_offsets_m", last_dim=2)
            if arr.shape != (len(lengths), 2):
                raise ValueError(f"device_normal_offsets_m must have shape ({len(lengths)}, 2) (y, z per segment, m), "
                                 f"got {arr.shape}")
            normal = tuple((float(y), float(z)) for y, z in arr)
        object.__setattr__(self, "segment_lengths_m", lengths)
        object.__setattr__(self, "device_offsets_m", offsets)
        object.__setattr__(self, "device_normal_offsets_m", normal)

    @classmethod
    def paper001(cls) -> ArmGeometry:
        """Paper 001's arm (the default of :func:`wsnlib.sim.arm.arm_kinematics`).

        A 1.75 m adult by Winter's fractions (upper arm 0.186 · 1.75 ≈ 0.326 m, forearm
        0.146 · 1.75 ≈ 0.256 m), IMU nodes at :data:`PAPER001_NODE_FRACTIONS` of each segment
        from its proximal joint, :data:`PAPER001_NODE_DORSAL_M` above the axis on the dorsal
        skin (body z): 60 % / 80 % and 4 cm / 3 cm, all assumed (typical strap positions).
        """
        upper = UPPER_ARM_FRACTION * DEFAULT_BODY_HEIGHT_M
        fore = FOREARM_FRACTION * DEFAULT_BODY_HEIGHT_M
        return cls(
            (upper, fore),
            (
                PAPER001_NODE_FRACTIONS[0] * UPPER_ARM_FRACTION * DEFAULT_BODY_HEIGHT_M,
                PAPER001_NODE_FRACTIONS[1] * FOREARM_FRACTION * DEFAULT_BODY_HEIGHT_M,
            ),
            ((0.0, PAPER001_NODE_DORSAL_M[0]), (0.0, PAPER001_NODE_DORSAL_M[1])),
        )

    @classmethod
    def on_axis(cls, segment_lengths_m, device_offsets_m) -> ArmGeometry:
        """Devices on the segment axes (paper 002's chain): no normal offsets."""
        return cls(segment_lengths_m, device_offsets_m, None)

    @classmethod
    def from_height(cls, height_m: float, humerus_node_fraction: float = PAPER001_NODE_FRACTIONS[0],
                    forearm_node_fraction: float = PAPER001_NODE_FRACTIONS[1],
                    humerus_node_offset_m: float = PAPER001_NODE_DORSAL_M[0],
                    forearm_node_offset_m: float = PAPER001_NODE_DORSAL_M[1]) -> ArmGeometry:
        """Arm of an adult of body height ``height_m`` (m), Winter's proportions.

        Parameters
        ----------
        height_m : float
            Body height H (m); segment lengths 0.186 H and 0.146 H.
        humerus_node_fraction, forearm_node_fraction : float
            Device position along each segment, as a fraction of its length from the
            proximal joint.
        humerus_node_offset_m, forearm_node_offset_m : float
            Device offset along the segment's body z (dorsal skin), m.
        """
        height = check_positive(height_m, "height_m")
        upper = UPPER_ARM_FRACTION * height
        fore = FOREARM_FRACTION * height
        return cls((upper, fore), (humerus_node_fraction * upper, forearm_node_fraction * fore),
                   ((0.0, float(humerus_node_offset_m)), (0.0, float(forearm_node_offset_m))))

    @property
    def n_segments(self) -> int:
        """Number of segments S."""
        return len(self.segment_lengths_m)

    @property
    def device_points_m(self) -> np.ndarray:
        """Device positions (S, 3) in their segment's body frame from its proximal joint (m)."""
        normal = np.asarray(self.device_normal_offsets_m, dtype=float)
        return np.column_stack([np.asarray(self.device_offsets_m), normal])

    def to_dict(self) -> dict:
        """JSON-ready fields (lists)."""
        return {"segment_lengths_m": list(self.segment_lengths_m), "device_offsets_m": list(self.device_offsets_m),
                "device_normal_offsets_m": [list(p) for p in self.device_normal_offsets_m]}


@dataclass(frozen=True, eq=False)
class ArmKinematics:
    """Exact state of the two segments and their devices at ``T`` times, layout ``(node, T, C)``.

    Node axis order :data:`NODE_NAMES` (upper arm, forearm); joint axis :data:`JOINT_NAMES`.
    Earth frame and segment frames as in the module docstring.  Produced by the motion
    generators (:func:`wsnlib.sim.arm.arm_kinematics`,
    :meth:`wsnlib.sim.arm_motion.ArmMotion.kinematics`), not by hand.

    Attributes
    ----------
    time_s : numpy.ndarray, shape (T,)
        Sample times (s).
    quat : numpy.ndarray, shape (2, T, 4)
        Segment orientations ``[w, x, y, z]``, body → earth (ENU), unit norm.
    gyr : numpy.ndarray, shape (2, T, 3)
        Body-frame angular rate ω (rad/s), ``q̇ = ½ q ⊗ [0, ω]`` (what a gyroscope reads).
    ang_acc : numpy.ndarray, shape (2, T, 3)
        Body-frame angular acceleration ω̇ (rad/s²).
    pos : numpy.ndarray, shape (2, T, 3)
        Device positions, earth frame (m), shoulder at the origin.
    vel : numpy.ndarray, shape (2, T, 3)
        Device velocities, earth frame (m/s).
    acc_lin : numpy.ndarray, shape (2, T, 3)
        Device linear accelerations, earth frame (m/s²), gravity not included.
    joint_pos : numpy.ndarray, shape (3, T, 3)
        Shoulder, elbow and wrist centres, earth frame (m).
    geometry : ArmGeometry
        The arm the state belongs to (2 segments).
    fs : float or None
        Sampling rate (Hz) when the times are uniform from a generator that knows it, else None.
    nodes : tuple of str
        :data:`NODE_NAMES`.
    label : numpy.ndarray (T,) of object, or None
        Label of the motion piece at each time (paper 002's postures and movements).
    trajectory : object or None
        The generator's description of the motion (e.g. the
        :class:`wsnlib.sim.arm.ArmTrajectory` or :class:`wsnlib.sim.arm_motion.ArmMotion`).
    """

    time_s: np.ndarray
    quat: np.ndarray
    gyr: np.ndarray
    ang_acc: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc_lin: np.ndarray
    joint_pos: np.ndarray
    geometry: ArmGeometry
    fs: float | None = None
    nodes: tuple[str, ...] = NODE_NAMES
    label: np.ndarray | None = None
    trajectory: object = None

    def __post_init__(self):
        t = as_float_array(self.time_s, "time_s")
        if t.ndim != 1:
            raise ValueError(f"time_s must be 1-D, got shape {t.shape}")
        n = t.size
        for name, shape in (("quat", (2, n, 4)), ("gyr", (2, n, 3)), ("ang_acc", (2, n, 3)), ("pos", (2, n, 3)),
                            ("vel", (2, n, 3)), ("acc_lin", (2, n, 3)), ("joint_pos", (3, n, 3))):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != shape:
                raise ValueError(f"{name} must have shape {shape} (node, T, C), got {arr.shape}")
        if not isinstance(self.geometry, ArmGeometry) or self.geometry.n_segments != 2:
            raise ValueError("geometry must be a two-segment ArmGeometry")
        if self.fs is not None:
            object.__setattr__(self, "fs", check_positive(self.fs, "fs"))
        if self.label is not None and np.shape(self.label) != (n,):
            raise ValueError(f"label must have shape ({n},), got {np.shape(self.label)}")

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.time_s.size

    @property
    def directions(self) -> np.ndarray:
        """Unit segment axes (body x in the earth frame), shape (2, T, 3)."""
        return Q.rotate(self.quat, _X)

    def specific_force(self, gravity: float = frames.STANDARD_GRAVITY, mounting=None) -> np.ndarray:
        """Exact accelerometer reading of each device, ``q* ⊗ (a_lin + [0, 0, g]) ⊗ q`` (m/s²).

        Parameters
        ----------
        gravity : float
            g (m/s²); the reading at rest is ``+g`` along earth up.
        mounting : array_like (4,) or (2, 4), optional
            Device → segment rotation of each device (``v_S = q_m ⊗ v_D ⊗ q_m*``); default
            identity (device frame = segment frame).

        Returns
        -------
        numpy.ndarray, shape (2, T, 3)
            Device-frame specific force.
        """
        gravity = check_positive(gravity, "gravity")
        q = self.quat
        if mounting is not None:
            mount = Q.normalize(as_float_array(mounting, "mounting", last_dim=4))
            if mount.shape not in ((4,), (2, 4)):
                raise ValueError(f"mounting must have shape (4,) or (2, 4) (one per device), got {mount.shape}")
            q = Q.multiply(q, mount if mount.ndim == 1 else mount[:, None, :])
        return Q.rotate_inverse(q, self.acc_lin + frames.gravity_specific_force_enu(gravity))


__all__ = ["DEFAULT_BODY_HEIGHT_M", "FOREARM_FRACTION", "JOINT_NAMES", "NODE_NAMES", "Q_REFERENCE",
           "UPPER_ARM_FRACTION", "ArmGeometry", "ArmKinematics"]
