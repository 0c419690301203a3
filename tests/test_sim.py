import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.arm_model import ArmGeometry
from wsnlib.io.recording import Recording
from wsnlib.sim import (
    ArmTrajectory,
    ImuSpec,
    arm_extension,
    arm_kinematics,
    ideal_imu,
    minimum_jerk,
    movement_set,
    pitch_ramp,
    reach_and_flex,
    simulate_imu,
    simulate_recording,
)

X = np.array([1.0, 0.0, 0.0])


def _pitch_deg(quat):
    """Elevation of body x above the horizontal, as metrics computes it."""
    return np.degrees(np.arcsin(np.clip(Q.rotate(quat, X)[..., 2], -1.0, 1.0)))


def _elbow_deg(truth):
    x = Q.rotate(truth.quat, X)
    return np.degrees(np.arccos(np.clip(np.sum(x[0] * x[1], axis=-1), -1.0, 1.0)))


def _wavy_trajectory(fs, duration_s=4.0):
    """A 3-D movement with every joint angle moving, with closed-form derivatives."""
    t = np.arange(int(round(duration_s * fs))) / fs
    amp = np.array([0.6, 0.7, 0.5, 0.6])
    freq = np.array([0.9, 1.3, 1.7, 2.1])
    offset = np.array([0.2, -0.3, 0.1, 0.8])
    phase = t[:, None] * freq
    angles = offset + amp * np.sin(phase)
    rates = amp * freq * np.cos(phase)
    accelerations = -amp * freq**2 * np.sin(phase)
    return ArmTrajectory(fs, t, angles, rates, accelerations)


def _integrate(quat0, gyr, fs):
    """q_{k+1} = q_k ⊗ exp(ω̄ Δt / 2), ω̄ the mean of the body rates at k and k+1."""
    out = np.empty(gyr.shape[:-1] + (4,))
    out[..., 0, :] = quat0
    mid = 0.5 * (gyr[..., 1:, :] + gyr[..., :-1, :])
    for k in range(gyr.shape[-2] - 1):
        out[..., k + 1, :] = Q.multiply(out[..., k, :], Q.from_rotation_vector(mid[..., k, :] / fs))
    return out


# ------------------------------------------------------------------ kinematics


def test_reference_posture_frames():
    truth = arm_kinematics(arm_extension(pitch_start_deg=0.0, pitch_end_deg=0.0))
    q = truth.quat[:, 0]
    np.testing.assert_allclose(Q.rotate(q, [1.0, 0.0, 0.0]), [[0, 1, 0]] * 2, atol=1e-12)  # north
    np.testing.assert_allclose(Q.rotate(q, [0.0, 1.0, 0.0]), [[-1, 0, 0]] * 2, atol=1e-12)  # west
    np.testing.assert_allclose(Q.rotate(q, [0.0, 0.0, 1.0]), [[0, 0, 1]] * 2, atol=1e-12)  # up
    geom = truth.geometry
    upper, fore = geom.segment_lengths_m
    np.testing.assert_allclose(truth.joint_pos[1, 0], [0, upper, 0], atol=1e-12)
    np.testing.assert_allclose(truth.joint_pos[2, 0], [0, upper + fore, 0], atol=1e-12)


@pytest.mark.parametrize("heading_deg", [0.0, 90.0, -135.0])
@pytest.mark.parametrize("axial_deg", [0.0, 40.0])
def test_pitch_and_elbow_of_aligned_extension(heading_deg, axial_deg):
    traj = arm_extension(heading_deg=heading_deg, axial_deg=axial_deg)
    truth = arm_kinematics(traj)
    assert truth.quat.shape == (2, traj.n_samples, 4)
    assert truth.nodes == ("humerus", "forearm")
    np.testing.assert_allclose(_pitch_deg(truth.quat[0]), np.degrees(traj.angles[:, 1]), atol=1e-6)
    np.testing.assert_allclose(_pitch_deg(truth.quat[1]), np.degrees(traj.angles[:, 1]), atol=1e-6)
    np.testing.assert_allclose(_elbow_deg(truth), 0.0, atol=1e-5)
    assert np.degrees(traj.angles[0, 1]) == pytest.approx(-90.0)
    assert np.degrees(traj.angles[-1, 1]) == pytest.approx(0.0)
    # Heading: the horizontal part of the humerus direction points at azimuth ψ from north
    # towards west (right-hand rule about up).
    x = Q.rotate(truth.quat[0, -1], X)
    psi = np.radians(heading_deg)
    np.testing.assert_allclose(x, [-np.sin(psi), np.cos(psi), 0.0], atol=1e-9)


def test_pitch_ramp_is_linear_and_elbow_angle_is_flexion():
    traj = pitch_ramp(duration_s=10.0, pitch_start_deg=-40.0, pitch_end_deg=60.0)
    truth = arm_kinematics(traj)
    pitch = _pitch_deg(truth.quat[0])
    assert pitch[0] == pytest.approx(-40.0) and pitch[-1] == pytest.approx(60.0)
    np.testing.assert_allclose(np.diff(pitch), np.diff(pitch)[0], atol=1e-9)

    wavy = _wavy_trajectory(50.0)
    truth = arm_kinematics(wavy)
    np.testing.assert_allclose(_pitch_deg(truth.quat[0]), np.degrees(wavy.angles[:, 1]), atol=1e-6)
    np.testing.assert_allclose(_elbow_deg(truth), np.degrees(np.abs(wavy.angles[:, 3])), atol=1e-5)


def test_quaternions_are_unit_and_continuous():
    truth = arm_kinematics(_wavy_trajectory(50.0))
    np.testing.assert_allclose(np.linalg.norm(truth.quat, axis=-1), 1.0, atol=1e-12)
    assert np.all(np.sum(truth.quat[:, 1:] * truth.quat[:, :-1], axis=-1) > 0.0)


def test_integrated_rate_reproduces_quaternions_arm_extension():
    """50 Hz samples, trapezoidal rate: the paper's movement rotates about one fixed axis."""
    truth = arm_kinematics(arm_extension(heading_deg=30.0, axial_deg=20.0))
    q = _integrate(truth.quat[:, 0], truth.gyr, truth.fs)
    err = np.degrees(Q.angle_between(q, truth.quat))
    assert err.max() < 0.5
    assert err.max() < 0.01  # in fact exact up to the trapezoidal quadrature error


def test_integrated_rate_reproduces_quaternions_3d():
    """A 3-D movement (non-commuting rotations), integrated at a 1 kHz internal rate."""
    truth = arm_kinematics(_wavy_trajectory(1000.0))
    q = _integrate(truth.quat[:, 0], truth.gyr, truth.fs)
    assert np.degrees(Q.angle_between(q, truth.quat)).max() < 0.01
    # At 50 Hz the trapezoidal rule still stays within 0.5° over 4 s of brisk 3-D motion.
    truth = arm_kinematics(_wavy_trajectory(50.0))
    q = _integrate(truth.quat[:, 0], truth.gyr, truth.fs)
    assert np.degrees(Q.angle_between(q, truth.quat)).max() < 0.5


def test_rates_match_finite_differences_of_quaternions():
    fs = 2000.0
    truth = arm_kinematics(_wavy_trajectory(fs, duration_s=2.0))
    qdot = np.gradient(truth.quat, 1.0 / fs, axis=1)
    gyr_fd = 2.0 * Q.multiply(Q.conjugate(truth.quat), qdot)[..., 1:]
    np.testing.assert_allclose(gyr_fd[:, 2:-2], truth.gyr[:, 2:-2], atol=1e-5)
    ang_acc_fd = np.gradient(truth.gyr, 1.0 / fs, axis=1)
    np.testing.assert_allclose(ang_acc_fd[:, 2:-2], truth.ang_acc[:, 2:-2], atol=1e-4)


@pytest.mark.parametrize("make", [lambda fs: _wavy_trajectory(fs, 2.0), arm_extension])
def test_linear_acceleration_matches_finite_difference_of_positions(make):
    fs = 2000.0
    truth = arm_kinematics(make(fs))
    dt = 1.0 / fs
    acc_fd = (truth.pos[:, 2:] - 2.0 * truth.pos[:, 1:-1] + truth.pos[:, :-2]) / dt**2
    # 1 mm/s² (the minimum-jerk profile has a jerk step at its ends, seen by the 2nd difference)
    np.testing.assert_allclose(acc_fd, truth.acc_lin[:, 1:-1], atol=1e-3)
    assert np.abs(truth.acc_lin).max() > 0.5
    vel_fd = (truth.pos[:, 2:] - truth.pos[:, :-2]) / (2.0 * dt)
    np.testing.assert_allclose(vel_fd, truth.vel[:, 1:-1], atol=1e-5)
    # Mounting points keep their distances to the joints.
    geom = truth.geometry
    np.testing.assert_allclose(
        np.linalg.norm(truth.pos[0], axis=-1), np.linalg.norm(geom.device_points_m[0]), atol=1e-12
    )
    np.testing.assert_allclose(
        np.linalg.norm(truth.pos[1] - truth.joint_pos[1], axis=-1),
        np.linalg.norm(geom.device_points_m[1]),
        atol=1e-12,
    )


def test_minimum_jerk_profile():
    t = np.linspace(0.0, 4.0, 401)
    s, ds, dds = minimum_jerk(t, 1.0, 2.0)
    assert s[0] == 0.0 and s[-1] == 1.0 and s[200] == pytest.approx(0.5)
    assert ds[100] == 0.0 and ds[300] == 0.0
    assert ds.max() == pytest.approx(1.875 / 2.0)
    np.testing.assert_allclose(np.gradient(s, t)[1:-1], ds[1:-1], atol=2e-3)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: arm_extension(fs=0.0), "fs"),
        (lambda: arm_extension(duration_s=-1.0), "duration_s"),
        (lambda: arm_extension(rise_s=0.0), "rise_s"),
        (lambda: arm_extension(start_s=-1.0), "start_s"),
        (lambda: pitch_ramp(pitch_end_deg=120.0), "pitch_end_deg"),
        (lambda: ArmGeometry((0.0, 0.25), (0.0, 0.1)), "segment_lengths_m"),
        (lambda: ArmGeometry((0.3, 0.25), (0.1, 0.1), ((0.0, 0.0),)), "device_normal_offsets_m"),
        (lambda: arm_kinematics(arm_extension(), ArmGeometry((0.3,), (0.1,))), "2 segments"),
        (lambda: ArmGeometry.from_height(-1.7), "height_m"),
        (lambda: arm_kinematics("not a trajectory"), "trajectory"),
    ],
)
def test_bad_kinematics_inputs(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_geometry_from_height():
    geom = ArmGeometry.from_height(1.80)
    assert geom.segment_lengths_m == pytest.approx((0.186 * 1.80, 0.146 * 1.80))
    assert geom.device_points_m[0, 0] == pytest.approx(0.6 * 0.186 * 1.80)


# ------------------------------------------------------------------ IMU


@pytest.fixture(scope="module")
def extension_truth():
    return arm_kinematics(arm_extension())


def test_ideal_readings_at_rest(extension_truth):
    truth = extension_truth
    ideal = ideal_imu(truth)
    rest = slice(0, 40)  # the raise starts at 1 s = sample 50
    g = frames.STANDARD_GRAVITY
    expected_acc = Q.rotate_inverse(truth.quat[:, rest], [0.0, 0.0, g])
    np.testing.assert_allclose(ideal.acc[:, rest], expected_acc, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(ideal.acc[:, rest], axis=-1), g, atol=1e-12)
    # Arm hanging down: body x points down, so the specific force reads -g along x.
    np.testing.assert_allclose(ideal.acc[:, 0], [[-g, 0.0, 0.0]] * 2, atol=1e-12)
    field = frames.magnetic_field_enu()
    np.testing.assert_allclose(
        Q.rotate(truth.quat, ideal.mag), np.broadcast_to(field, ideal.mag.shape), atol=1e-12
    )
    np.testing.assert_allclose(ideal.gyr[:, rest], 0.0, atol=1e-15)


def test_noise_free_simulation_equals_ideal(extension_truth, rng):
    gyr, acc, mag = simulate_imu(extension_truth, ImuSpec.noise_free(), rng=rng)
    ideal = ideal_imu(extension_truth)
    np.testing.assert_array_equal(gyr, ideal.gyr)
    np.testing.assert_array_equal(acc, ideal.acc)
    np.testing.assert_array_equal(mag, ideal.mag)


def test_quantisation_steps_equal_sensitivities(extension_truth, rng):
    spec = ImuSpec()
    gyr, acc, mag = simulate_imu(extension_truth, spec, rng=rng)
    for values, step in (
        (gyr, np.radians(8.75e-3)),
        (acc, 1e-3 * frames.STANDARD_GRAVITY),
        (mag, np.array([100.0 / 1100.0, 100.0 / 1100.0, 100.0 / 980.0])),
    ):
        codes = values / step
        np.testing.assert_allclose(codes, np.rint(codes), atol=1e-6)
        # Distinct values are spaced by exactly one step somewhere (the resolution is used).
        diffs = np.diff(np.unique(np.round(codes[..., 0]).ravel()))
        assert diffs.min() == 1
    assert spec.gyr_step_si == pytest.approx(np.radians(0.00875))
    np.testing.assert_allclose(spec.mag_step_si, [0.0909090909, 0.0909090909, 0.1020408163])


def test_saturation_at_full_scale(rng):
    # A fast raise: 90° in 0.2 s peaks at 1.875 · 90 / 0.2 ≈ 844 dps, above the 250 dps range.
    truth = arm_kinematics(arm_extension(rise_s=0.2))
    spec = ImuSpec.noise_free(quantize=True, saturate=True)
    gyr, acc, _ = simulate_imu(truth, spec, rng=rng)
    limit = np.floor(250.0 / 8.75e-3) * np.radians(8.75e-3)
    assert np.abs(gyr).max() == pytest.approx(limit)
    assert np.abs(ideal_imu(truth).gyr).max() > np.radians(800.0)
    assert np.abs(acc).max() <= 2.0 * frames.STANDARD_GRAVITY + 1e-9
    low = dataclasses.replace(spec, acc_full_scale_g=0.5, mag_full_scale_gauss=0.2)
    _, acc, mag = simulate_imu(truth, low, rng=rng)
    assert np.abs(acc).max() == pytest.approx(0.5 * frames.STANDARD_GRAVITY)
    assert np.abs(mag).max() <= 20.0 + 1e-9
    assert np.isclose(np.abs(mag).max(), 20.0, atol=0.11)


def test_same_seed_same_arrays_different_seed_differs(extension_truth):
    a = simulate_imu(extension_truth, rng=np.random.default_rng(3), n_runs=2)
    b = simulate_imu(extension_truth, rng=np.random.default_rng(3), n_runs=2)
    c = simulate_imu(extension_truth, rng=np.random.default_rng(4), n_runs=2)
    for x, y, z in zip(a, b, c, strict=True):
        np.testing.assert_array_equal(x, y)
        assert not np.array_equal(x, z)
    # Runs within a batch are independent.
    assert not np.array_equal(a.gyr[0], a.gyr[1])


def test_batch_shapes(extension_truth, rng):
    n = extension_truth.quat.shape[1]
    single = simulate_imu(extension_truth, rng=rng)
    assert all(x.shape == (2, n, 3) for x in single)
    batch = simulate_imu(extension_truth, rng=rng, n_runs=5)
    assert all(x.shape == (5, 2, n, 3) for x in batch)
    assert all(np.all(np.isfinite(x)) for x in batch)


def test_noise_standard_deviation_matches_spec():
    fs = 50.0
    # At rest throughout: the raise would start after the end.
    truth = arm_kinematics(arm_extension(fs=fs, duration_s=40.0, start_s=50.0, rise_s=1.0))
    ideal = ideal_imu(truth)
    white = ImuSpec(gyr_bias_dps=0.0, gyr_bias_walk_dps=0.0, quantize=False)
    gyr, acc, mag = simulate_imu(truth, white, rng=np.random.default_rng(11), n_runs=20)
    # 20 runs × 2 nodes × 2000 samples × 3 axes = 240k draws: relative std error 0.15 %.
    assert np.std(gyr - ideal.gyr) == pytest.approx(np.radians(0.03) * np.sqrt(fs / 2), rel=0.01)
    assert np.std(acc - ideal.acc) == pytest.approx(220e-6 * 9.80665 * np.sqrt(fs / 2), rel=0.01)
    assert np.std(mag - ideal.mag) == pytest.approx(0.3, rel=0.01)
    assert white.gyr_noise_std_si(fs) == pytest.approx(np.radians(0.15))
    # Quantised: white noise plus uniform rounding error of variance step² / 12.
    quantised = dataclasses.replace(white, quantize=True)
    _, acc_q, _ = simulate_imu(truth, quantised, rng=np.random.default_rng(11), n_runs=20)
    sigma = white.acc_noise_std_si(fs)
    step = quantised.acc_step_si
    assert np.std(acc_q - ideal.acc) == pytest.approx(np.sqrt(sigma**2 + step**2 / 12.0), rel=0.02)


def test_gyro_bias_is_constant_per_run_plus_walk():
    truth = arm_kinematics(arm_extension(duration_s=20.0, start_s=30.0))  # at rest
    spec = ImuSpec.noise_free(gyr_bias_dps=0.5)
    gyr, _, _ = simulate_imu(truth, spec, rng=np.random.default_rng(5), n_runs=400)
    # Constant over time within a run, different across runs with the specified spread.
    np.testing.assert_array_equal(gyr, np.broadcast_to(gyr[..., :1, :], gyr.shape))
    assert np.std(gyr[..., 0, :]) == pytest.approx(np.radians(0.5), rel=0.06)
    walk = ImuSpec.noise_free(gyr_bias_walk_dps=0.01)
    gyr, _, _ = simulate_imu(truth, walk, rng=np.random.default_rng(5), n_runs=400)
    assert np.all(gyr[..., 0, :] == 0.0)
    # Random walk: std after t seconds is 0.01 dps · √t.
    t_end = (gyr.shape[-2] - 1) / truth.fs
    assert np.std(gyr[..., -1, :]) == pytest.approx(np.radians(0.01) * np.sqrt(t_end), rel=0.06)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda t: simulate_imu(t, rng=None), "rng"),
        (lambda t: simulate_imu(t, rng=np.random.default_rng(0), n_runs=0), "n_runs"),
        (lambda t: simulate_imu(t, "spec", rng=np.random.default_rng(0)), "spec"),
        (lambda t: ideal_imu(t, mag_field_enu=[1.0, 2.0]), "mag_field_enu"),
        (lambda t: ideal_imu(t, gravity=-9.8), "gravity"),
        (lambda t: ImuSpec(gyr_noise_density_dps=-1.0), "gyr_noise_density_dps"),
        (lambda t: ImuSpec(acc_bits=12.5), "acc_bits"),
        (lambda t: ImuSpec(mag_gain_z_lsb_per_gauss=0.0), "mag_gain_z_lsb_per_gauss"),
        (lambda t: ImuSpec(noise_bandwidth_hz=0.0), "noise_bandwidth_hz"),
    ],
)
def test_bad_imu_inputs(extension_truth, call, match):
    with pytest.raises(ValueError, match=match):
        call(extension_truth)


def test_simulate_recording(rng):
    traj = arm_extension()
    rec = simulate_recording(traj, rng=rng, metadata={"seed": 12345})
    assert isinstance(rec, Recording)
    assert rec.nodes == ("humerus", "forearm")
    assert rec.gyr.shape == (2, traj.n_samples, 3) and rec.fs == 50.0
    np.testing.assert_allclose(rec.quat_true, arm_kinematics(traj).quat)
    assert rec.metadata["trajectory"]["generator"] == "wsnlib.sim.arm.arm_extension"
    assert rec.metadata["seed"] == 12345
    assert rec.metadata["rng_entropy"] == 12345
    again = simulate_recording(traj, rng=np.random.default_rng(12345), metadata={"seed": 12345})
    np.testing.assert_array_equal(rec.gyr, again.gyr)


def test_scipy_cross_check_of_humerus_orientation():
    """q_humerus = R_z(ψ + 90°) R_y(−θ) R_x(axial) as intrinsic z-y-x Euler angles."""
    traj = _wavy_trajectory(50.0, duration_s=1.0)
    truth = arm_kinematics(traj)
    euler = np.stack([traj.angles[:, 0] + np.pi / 2, -traj.angles[:, 1], traj.angles[:, 2]], axis=-1)
    expected = Q.from_scipy(Rotation.from_euler("ZYX", euler))
    assert np.degrees(Q.angle_between(truth.quat[0], expected)).max() < 1e-9


def test_reach_and_flex_reaches_its_end_posture_and_rates_are_consistent():
    trajectory = reach_and_flex(fs=50.0, duration_s=5.0, start_s=1.0, rise_s=2.5)
    truth = arm_kinematics(trajectory)
    np.testing.assert_allclose(_pitch_deg(truth.quat[0])[-1], -20.0, atol=1e-6)
    np.testing.assert_allclose(_elbow_deg(truth)[-1], 90.0, atol=1e-6)
    # Numerical derivative of the closed-form angles equals the closed-form rates.
    fd = np.gradient(trajectory.angles, trajectory.t, axis=0)
    np.testing.assert_allclose(fd[5:-5], trajectory.rates[5:-5], atol=2e-3)


def test_movement_set_has_equal_lengths_and_ordered_speeds():
    moves = movement_set(fs=50.0, duration_s=8.0)
    lengths = {m.n_samples for m in moves.values()}
    assert lengths == {400}
    names = ("extension fast", "extension medium", "extension slow")
    peak = [np.max(np.abs(moves[name].rates[:, 1])) for name in names]
    assert peak[0] > peak[1] > peak[2]
