"""Simulation of the paper's two-node arm set-up: kinematics (:mod:`.arm`) and IMUs (:mod:`.imu`).

Typical use::

    rng = np.random.default_rng(seed)
    trajectory = arm_extension(fs=50.0)
    truth = arm_kinematics(trajectory)                  # quat (2, T, 4), gyr, pos, acc_lin …
    gyr, acc, mag = simulate_imu(truth, rng=rng, n_runs=100)   # each (100, 2, T, 3)
    recording = simulate_recording(trajectory, rng=rng)        # wsnlib.datasets.Recording

See the module docstrings for the body-frame convention and the datasheet sources.
"""

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
from wsnlib.sim.imu import ImuSamples, ImuSpec, ideal_imu, simulate_imu, simulate_recording

__all__ = [
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
