"""The simulated Kinect's view of one user's motion in one session (:func:`simulate_kinect_stream`):
camera placement (:func:`kinect_camera`), frames at 30 fps, reported joints
(:func:`wsnlib.sim.kinect.simulate_kinect`) and the target positions derived from them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib.sim.arm_motion import ArmMotion
from wsnlib.sim.kinect import kinect_target_positions, simulate_kinect
from wsnlib.sim.kinect_model import PAPER_CAMERA_DISTANCE_M, KinectModel
from wsnlib.sim.sunspot import output_times
from wsnlib.sim.users import User

#: Height of the Kinect relative to the shoulder for a 1.75 m user (m): chest height, the
#: level of the left chest pocket (A1) in :mod:`wsnlib.sim.body`; scaled with the user's height.
CAMERA_HEIGHT_175_M = -0.15


def kinect_camera(user: User, distance_m: float = PAPER_CAMERA_DISTANCE_M) -> tuple[np.ndarray, np.ndarray]:
    """Kinect position (3,) and viewing direction (3,) in ``user``'s shoulder frame.

    ``distance_m`` in front of the user (paper 002: "at a distance of about 3 m"), facing the
    user (looking along −y), centred on the torso (x = the torso centre, 19 cm left of the right
    shoulder for a 1.75 m user), at chest height (:data:`CAMERA_HEIGHT_175_M`, scaled).  The
    height and centring are *assumed*; the paper gives only the distance.
    """
    scale = user.height_m / 1.75
    position = np.array([user.body.torso_center_x_m, float(distance_m), CAMERA_HEIGHT_175_M * scale])
    return position, np.array([0.0, -1.0, 0.0])


@dataclass(frozen=True, eq=False)
class KinectStream:
    """What the simulated Kinect reported during one session (shapes with ``K`` frames).

    Attributes
    ----------
    time_s : (K,)
        Frame times (s), ``k / frame_rate_hz`` from 0, rounded to 1 µs.
    joints : (K, 3, 3)
        Reported shoulder, elbow, wrist (m, shoulder frame; referenced to the tracked shoulder
        unless ``relative_to`` said otherwise).
    targets : (K, 2, 3)
        Target positions derived from the reported joints at each target's fraction along its
        segment (:func:`wsnlib.sim.optical.kinect_target_positions`), m.
    true_joints : (K, 3, 3)
        The true joints at the frame times (m).
    true_targets : (K, 2, 3)
        The true target positions on the arm axis (m).
    label : (K,) object
        Label of the motion piece at each frame.
    camera_position, camera_axis : (3,)
        Camera placement (:func:`kinect_camera`).
    """

    time_s: np.ndarray
    joints: np.ndarray
    targets: np.ndarray
    true_joints: np.ndarray
    true_targets: np.ndarray
    label: np.ndarray
    camera_position: np.ndarray
    camera_axis: np.ndarray


def simulate_kinect_stream(
    motion: ArmMotion,
    user: User,
    *,
    rng: np.random.Generator,
    model: KinectModel | None = None,
    camera_distance_m: float = PAPER_CAMERA_DISTANCE_M,
    relative_to: str = "tracked_shoulder",
    duration_s: float | None = None,
) -> KinectStream:
    """The Kinect's view of ``motion``: true joints at 30 fps → :func:`simulate_kinect` → targets.

    Frames at ``k / frame_rate_hz`` for ``k = 0 … ⌊duration · rate⌋``; camera from
    :func:`kinect_camera`; T1 at ``d1 / upper_arm`` along shoulder → elbow and T2 at
    ``(d2 − upper_arm) / forearm`` along elbow → wrist (the user's true strap positions, which
    paper 002's experimenters knew).  ``rng`` draws the Kinect errors only.
    """
    model = KinectModel() if model is None else model
    duration = motion.total_duration_s if duration_s is None else float(duration_s)
    times = output_times(duration, model.frame_rate_hz)
    kin = motion.kinematics(times, user)
    upper, fore = user.upper_arm_m, user.forearm_m
    true_joints = np.moveaxis(kin.joint_pos, 0, 1)  # (K, 3, 3)
    position, axis = kinect_camera(user, camera_distance_m)
    joints = simulate_kinect(
        true_joints,
        rng=rng,
        fs=model.frame_rate_hz,
        camera_position=position,
        camera_axis=axis,
        model=model,
        relative_to=relative_to,
    )
    d1, d2 = user.target_distances_m
    fractions = (d1 / upper, (d2 - upper) / fore)
    return KinectStream(
        time_s=times,
        joints=joints,
        targets=kinect_target_positions(joints, fractions=fractions),
        true_joints=true_joints,
        true_targets=np.moveaxis(kin.pos, 0, 1).copy(),
        label=kin.label,
        camera_position=position,
        camera_axis=axis,
    )
