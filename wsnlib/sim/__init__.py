"""Simulation of the paper's two-node arm set-up: kinematics (:mod:`.arm`) and IMUs (:mod:`.imu`).

Typical use::

    rng = np.random.default_rng(seed)
    trajectory = arm_extension(fs=50.0)
    truth = arm_kinematics(trajectory)                  # ArmKinematics: quat (2, T, 4), gyr, pos, acc_lin …
    gyr, acc, mag = simulate_imu(truth, rng=rng, n_runs=100)   # each (100, 2, T, 3)
    recording = simulate_recording(trajectory, rng=rng)        # wsnlib.io.recording.Recording

See the module docstrings for the body-frame convention and the datasheet sources.

Both papers share one arm model, :mod:`wsnlib.arm_model` (:class:`ArmGeometry`,
:class:`ArmKinematics` in the layout ``(node, T, C)``): paper 001's joint-angle trajectories
(:mod:`.arm`) and paper 002's straight-arm motions (:mod:`.arm_motion`) both produce it.

Paper 002's radio testbed (:mod:`.users`, :mod:`.arm_motion`, :mod:`.body_solids` — overview in
:mod:`.body` — and the radio in :mod:`.radio_channel`, :mod:`.radio_links`, :mod:`.radio_rss`,
:mod:`.radio_sessions`, re-exported by :mod:`.radio`)::

    users = make_users(5, rng=rng)
    train = training_session(users[0], rng=rng)                     # long RSS table
    online = online_dynamic_session(users[0].moved(rng), rng=rng)   # another day
    kin = movement("lower_P2_P3_P1", 3.0).sample(users[0], fs=50.0)  # ArmKinematics
"""

from wsnlib.arm_model import ArmKinematics
from wsnlib.sim.arm import (
    ANGLE_NAMES,
    JOINT_NAMES,
    NODE_NAMES,
    ArmGeometry,
    ArmTrajectory,
    ArmTruth,
    arm_extension,
    arm_kinematics,
    from_joint_angles,
    minimum_jerk,
    movement_set,
    pitch_ramp,
    reach_and_flex,
)
from wsnlib.sim.body import (
    ANCHOR_NAMES,
    MOVEMENTS,
    POSTURE_DIRECTIONS,
    POSTURES,
    TABLE1_POSITIONS_CM,
    TARGET_NAMES,
    ArmMotion,
    BodyShape,
    User,
    arc,
    concatenate,
    hold,
    make_users,
    movement,
    paper_user,
    posture_direction,
    transition,
    user_from_height,
)
from wsnlib.sim.imu import ImuSamples, ImuSpec, ideal_imu, simulate_imu, simulate_recording
from wsnlib.sim.radio import (
    RadioChannel,
    concat_rss,
    link_budget,
    online_dynamic_session,
    online_static_session,
    simulate_rss,
    static_session,
    training_session,
)

__all__ = [
    "ANCHOR_NAMES",
    "MOVEMENTS",
    "POSTURE_DIRECTIONS",
    "POSTURES",
    "TABLE1_POSITIONS_CM",
    "TARGET_NAMES",
    "ArmKinematics",
    "ArmMotion",
    "BodyShape",
    "RadioChannel",
    "User",
    "arc",
    "concat_rss",
    "concatenate",
    "hold",
    "link_budget",
    "make_users",
    "movement",
    "online_dynamic_session",
    "online_static_session",
    "paper_user",
    "posture_direction",
    "simulate_rss",
    "static_session",
    "training_session",
    "transition",
    "user_from_height",
    "ANGLE_NAMES",
    "JOINT_NAMES",
    "NODE_NAMES",
    "ArmGeometry",
    "ArmTrajectory",
    "ArmTruth",
    "ImuSamples",
    "ImuSpec",
    "arm_extension",
    "arm_kinematics",
    "from_joint_angles",
    "ideal_imu",
    "minimum_jerk",
    "movement_set",
    "pitch_ramp",
    "reach_and_flex",
    "simulate_imu",
    "simulate_recording",
]
