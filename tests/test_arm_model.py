"""One arm model: the same motion through every consumer agrees on the geometry.

Two motion generators (paper 001's joint-angle trajectories, paper 002's straight-arm motions)
produce :class:`wsnlib.arm_model.ArmKinematics`; the IMU simulator, the radio link budget and
RSS table, the SunSPOT accelerometer, the Kinect model and the posture chain consume it.
"""

import numpy as np
import pytest
from _sim_helpers import paper_user

from wsnlib import quaternion as Q
from wsnlib.arm_model import ArmGeometry, ArmKinematics
from wsnlib.frames import STANDARD_GRAVITY
from wsnlib.posture import PAPER_ARM_CHAIN, ArmChain, forward_chain, recursive_chain
from wsnlib.sim.arm import arm_kinematics, reach_and_flex
from wsnlib.sim.arm_motion import concatenate, hold, movement
from wsnlib.sim.campaign import simulate_kinect_stream
from wsnlib.sim.imu import ideal_imu, simulate_imu
from wsnlib.sim.optical import KinectModel
from wsnlib.sim.radio import RadioChannel, antenna_positions, link_budget, simulate_rss
from wsnlib.sim.sunspot import SunspotAccSpec, ideal_specific_force, simulate_sunspot_acc

FS = 200.0
USER = paper_user()


def _paper002(times=None):
    """Paper 002's horizontal movement P4 → P3 → P5 (3 s), sampled strictly inside it."""
    motion = movement("horizontal_P4_P3_P5", 3.0)
    times = np.arange(20, 580) / FS if times is None else times
    return motion.kinematics(times, USER, fs=FS)


def _paper001():
    """Paper 001's three-joint reach (pitch, heading, elbow), on paper 002's user's arm."""
    return arm_kinematics(reach_and_flex(fs=FS, duration_s=4.0), USER.geometry)


GENERATORS = {"paper002 ArmMotion": _paper002, "paper001 arm_kinematics": _paper001}


@pytest.fixture(params=list(GENERATORS), scope="module")
def kin(request):
    return GENERATORS[request.param]()


def test_one_type_for_both_papers():
    assert ArmChain is ArmGeometry
    assert USER.geometry == PAPER_ARM_CHAIN
    assert isinstance(_paper002(), ArmKinematics) and isinstance(_paper001(), ArmKinematics)


def test_layout_is_node_time_component(kin):
    t = kin.n_samples
    assert kin.quat.shape == (2, t, 4) and kin.gyr.shape == (2, t, 3) and kin.pos.shape == (2, t, 3)
    assert kin.joint_pos.shape == (3, t, 3)
    np.testing.assert_allclose(np.linalg.norm(kin.quat, axis=-1), 1.0, atol=1e-12)


def test_joints_and_devices_sit_on_the_geometry(kin):
    shoulder, elbow, wrist = kin.joint_pos
    lengths = kin.geometry.segment_lengths_m
    np.testing.assert_allclose(shoulder, 0.0)
    np.testing.assert_allclose(np.linalg.norm(elbow - shoulder, axis=-1), lengths[0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(wrist - elbow, axis=-1), lengths[1], atol=1e-12)
    np.testing.assert_allclose(elbow, lengths[0] * kin.directions[0], atol=1e-12)
    np.testing.assert_allclose(wrist - elbow, lengths[1] * kin.directions[1], atol=1e-12)
    points = kin.geometry.device_points_m
    for s, proximal in enumerate((shoulder, elbow)):
        np.testing.assert_allclose(kin.pos[s], proximal + Q.rotate(kin.quat[s], points[s]), atol=1e-12)


def test_posture_chain_with_true_angles_returns_the_kinematics_positions(kin):
    # Heading and pitch of each segment axis u in the posture chain's convention, (T, 2); asin
    # near ±90° costs a few digits.
    u = np.moveaxis(kin.directions, 0, 1)
    heading = np.mod(np.arctan2(u[..., 1], u[..., 0]), 2.0 * np.pi)
    pitch = np.arcsin(np.clip(u[..., 2], -1.0, 1.0))
    chain = forward_chain(heading, pitch, kin.geometry)
    np.testing.assert_allclose(chain["joints"], np.moveaxis(kin.joint_pos[1:], 0, 1), atol=1e-9)
    np.testing.assert_allclose(chain["devices"], np.moveaxis(kin.pos, 0, 1), atol=1e-9)
    # Radio estimates at the true device positions + true pitch → the true elbow and wrist.
    rebuilt = recursive_chain(np.moveaxis(kin.pos, 0, 1), pitch, kin.geometry)
    np.testing.assert_allclose(rebuilt["joints"], np.moveaxis(kin.joint_pos[1:], 0, 1), atol=1e-9)


def test_imu_specific_force_and_rate_match_the_kinematics(kin):
    ideal = ideal_imu(kin)
    # The accelerometer reads the device's second derivative of position plus gravity.
    acc_fd = np.gradient(np.gradient(kin.pos, 1.0 / FS, axis=1), 1.0 / FS, axis=1)
    felt = Q.rotate(kin.quat, ideal.acc) - np.array([0.0, 0.0, STANDARD_GRAVITY])
    assert np.abs(acc_fd).max() > 0.2  # the devices do accelerate (m/s²)
    np.testing.assert_allclose(felt[:, 2:-2], acc_fd[:, 2:-2], atol=1e-2)  # FD error at the jerk steps
    np.testing.assert_allclose(ideal.acc, kin.specific_force(), atol=0.0)
    # The gyroscope's rate integrates to the orientation.
    q = kin.quat[:, 0]
    for k in range(kin.n_samples - 1):
        q = Q.multiply(q, Q.from_rotation_vector(0.5 * (ideal.gyr[:, k] + ideal.gyr[:, k + 1]) / FS))
    assert np.all(Q.angle_between(q, kin.quat[:, -1]) < 1e-5)
    gyr, acc, mag = simulate_imu(kin, rng=np.random.default_rng(0))
    assert gyr.shape == acc.shape == mag.shape == kin.pos.shape


def test_sunspot_reads_the_same_specific_force_as_the_imu(kin):
    force = ideal_specific_force(kin)
    assert force.shape == (kin.n_samples, 2, 3)
    np.testing.assert_allclose(np.moveaxis(force, 1, 0), ideal_imu(kin).acc, atol=1e-12)


def test_radio_antennas_sit_on_the_devices(kin):
    antenna = antenna_positions(kin, USER)  # (2, T, 3)
    offset = antenna - kin.pos
    radii = np.array([USER.body.upper_arm_radius_m, USER.body.forearm_radius_m]) + 0.01
    np.testing.assert_allclose(np.linalg.norm(offset, axis=-1), radii[:, None] * np.ones(kin.n_samples), atol=1e-12)
    np.testing.assert_allclose(np.sum(offset * kin.directions, axis=-1), 0.0, atol=1e-12)  # on the skin, beside
    for target in (0, 1):
        budget = link_budget(kin, USER, target, RadioChannel().ideal())
        expected = np.linalg.norm(USER.anchor_positions_m[None] - antenna[target][:, None], axis=-1)
        np.testing.assert_allclose(budget.distance_m, expected, atol=1e-12)


def test_rss_table_kinect_and_accelerometer_follow_one_motion():
    motion = concatenate([hold("P1", 0.5), movement("raise_P1_P3", 2.0), hold("P3", 0.5)])
    rss = simulate_rss(motion, USER, rng=np.random.default_rng(1), channel=RadioChannel().ideal())
    for target, name in enumerate(("T1", "T2")):
        rows = rss[rss["target"] == name].drop_duplicates("time_s")
        truth = motion.kinematics(rows["time_s"].to_numpy(), USER).pos[target]
        np.testing.assert_allclose(rows[["x_m", "y_m", "z_m"]].to_numpy(), truth, atol=1e-12)
    stream = simulate_kinect_stream(motion, USER, rng=np.random.default_rng(2), model=KinectModel.noise_free())
    kin = motion.kinematics(stream.time_s, USER)
    np.testing.assert_allclose(stream.true_joints, np.moveaxis(kin.joint_pos, 0, 1), atol=0.0)
    np.testing.assert_allclose(stream.true_targets, np.moveaxis(kin.pos, 0, 1), atol=0.0)
    np.testing.assert_allclose(stream.targets, stream.true_targets, atol=1e-9)
    acc = simulate_sunspot_acc(motion, USER, rng=np.random.default_rng(3), spec=SunspotAccSpec.noise_free())
    np.testing.assert_allclose(acc.raw_acc, ideal_specific_force(motion.kinematics(acc.raw_time_s, USER)), atol=1e-12)


def test_geometry_validation_and_forms():
    paper001 = ArmGeometry.paper001()
    assert paper001.device_normal_offsets_m == ((0.0, 0.04), (0.0, 0.03))
    assert ArmGeometry((0.3, 0.25), (0.15, 0.125)).device_normal_offsets_m == ((0.0, 0.0), (0.0, 0.0))
    with pytest.raises(ValueError, match="device_offsets_m"):
        ArmGeometry((0.3, 0.25), (0.15, 0.3))
    with pytest.raises(ValueError, match="ArmGeometry"):
        movement("raise_P1_P3", 2.0).kinematics(np.zeros(2), paper001)  # devices off the axis
    with pytest.raises(ValueError, match="fs"):
        simulate_imu(movement("raise_P1_P3", 2.0).kinematics(np.arange(5) / 10.0, USER), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="pos"):
        good, bad = np.zeros((2, 3, 3)), np.zeros((3, 2, 3))  # (node, T, C) with T = 3, and (T, node, C)
        ArmKinematics(np.zeros(3), np.zeros((2, 3, 4)), good, good, bad, good, good, np.zeros((3, 3, 3)), paper001)


def test_the_model_and_the_posture_chain_import_no_simulator():
    import subprocess
    import sys

    code = (
        "import sys, wsnlib.arm_model, wsnlib.posture; "
        "print(sorted(m for m in sys.modules if m.startswith('wsnlib.sim')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
