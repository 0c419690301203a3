import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import metrics
from wsnlib import quaternion as Q


def _pitched(pitch_deg, heading_deg=0.0):
    """Quaternions whose body x axis has the given elevation (about body -y) and heading."""
    pitch = np.radians(np.asarray(pitch_deg, dtype=float))
    rot = Rotation.from_euler("ZY", np.stack([np.full_like(pitch, np.radians(heading_deg)), -pitch], -1))
    return Q.from_scipy(rot)


@pytest.mark.parametrize("pitch", [-89.0, -45.0, 0.0, 12.5, 60.0, 89.0])
@pytest.mark.parametrize("heading", [0.0, 90.0, -135.0])
def test_segment_pitch_recovers_elevation(pitch, heading):
    assert metrics.segment_pitch_deg(_pitched(pitch, heading)) == pytest.approx(pitch, abs=1e-9)


def test_elbow_angle_methods_agree_in_a_vertical_plane():
    humerus = _pitched(np.array([-80.0, -30.0, 10.0]))
    forearm = _pitched(np.array([-60.0, 0.0, 10.0]))
    diff = metrics.elbow_angle_deg(humerus, forearm)
    assert diff == pytest.approx([20.0, 30.0, 0.0], abs=1e-9)
    assert metrics.elbow_angle_deg(humerus, forearm, method="axis_angle") == pytest.approx(np.abs(diff), abs=1e-6)
    with pytest.raises(ValueError, match="method"):
        metrics.elbow_angle_deg(humerus, forearm, method="euler")


def test_orientation_error_is_the_relative_rotation_angle():
    q_true = Q.from_scipy(Rotation.random(20, random_state=3))
    delta = Q.from_axis_angle([0.0, 0.0, 1.0], np.radians(7.0))
    assert metrics.orientation_error_deg(Q.multiply(q_true, delta), q_true) == pytest.approx(np.full(20, 7.0))
    # q and -q are the same orientation
    assert metrics.orientation_error_deg(-q_true, q_true) == pytest.approx(np.zeros(20), abs=1e-6)


def test_time_above_and_recovery():
    fs = 50.0
    err = np.zeros((2, 100))
    err[0, 10:30] = 8.0   # above 5 for 20 samples, recovers at sample 30
    err[1, 90:] = 9.0     # still above at the end
    assert metrics.time_above_s(err, 5.0, fs) == pytest.approx([0.4, 0.2])
    assert metrics.time_above_s(err, 5.0, fs, start=20) == pytest.approx([0.2, 0.2])
    rec = metrics.recovery_time_s(err, 5.0, fs, start=10)
    assert rec[0] == pytest.approx(20 / fs)
    assert np.isinf(rec[1])
    assert metrics.recovery_time_s(np.zeros(10), 5.0, fs, start=0) == 0.0
    assert metrics.max_abs_error(np.array([1.0, -4.0, 2.0])) == 4.0
    assert metrics.max_abs_error(np.array([1.0, -4.0, 2.0]), start=2) == 2.0
    assert metrics.max_abs_error(np.array([1.0, -4.0, 2.0]), where=np.array([True, False, True])) == 2.0
    with pytest.raises(ValueError, match="where"):
        metrics.max_abs_error(np.array([1.0, -4.0]), where=np.array([1, 0]))


@pytest.mark.parametrize("start", [-1, 100, 2.5])
def test_bad_start_is_rejected(start):
    with pytest.raises(ValueError, match="start"):
        metrics.time_above_s(np.zeros(100), 1.0, 50.0, start=start)


def test_bad_fs_and_nan_are_rejected():
    with pytest.raises(ValueError, match="fs"):
        metrics.recovery_time_s(np.zeros(10), 1.0, 0.0, start=0)
    with pytest.raises(ValueError, match="error"):
        metrics.max_abs_error(np.array([1.0, np.nan]))


def test_angular_jerk_zero_for_constant_rate_and_large_for_noise(rng):
    fs = 50.0
    t = np.arange(200) / fs
    steady = Q.from_axis_angle([0.3, -0.2, 1.0], 0.8 * t)
    assert metrics.angular_jerk_rms_deg(steady, fs) < 1e-6
    noisy = Q.multiply(steady, Q.from_rotation_vector(rng.normal(scale=np.radians(1.0), size=(200, 3))))
    assert metrics.angular_jerk_rms_deg(noisy, fs) > 1e5
    # batches keep their leading shape
    assert metrics.angular_jerk_rms_deg(np.stack([steady, noisy]), fs).shape == (2,)


def test_angle_jerk_matches_analytic_cubic():
    fs = 50.0
    t = np.arange(100) / fs
    angle = 2.0 * t**3  # third derivative 12
    assert metrics.angle_jerk_rms_deg(angle, fs) == pytest.approx(12.0)


def test_loss_figures_of_merit_and_summary_table():
    fs = 50.0
    err = np.zeros((3, 100))
    err[:, 20:40] = 10.0           # a 20-sample excursion
    received = np.ones(100, bool)
    received[20:30] = False        # the first half of it is during the gap
    foms = metrics.loss_figures_of_merit(err, fs=fs, received=received, threshold_deg=5.0, start=20,
                                         recovery_start=30)
    assert foms[metrics.MAX_ERROR] == pytest.approx([10.0] * 3)
    assert foms[metrics.TIME_ABOVE] == pytest.approx([0.4] * 3)
    assert foms[metrics.MEAN_ERROR] == pytest.approx([10.0 * 20 / 80] * 3)
    assert foms[metrics.RECOVERY] == pytest.approx([0.2] * 3)
    assert foms[metrics.JERK].shape == (3,)
    assert metrics.RECOVERY not in metrics.loss_figures_of_merit(err, fs=fs, received=received)
    table = metrics.summary_table({"a": foms, "b": {k: 2 * v for k, v in foms.items()}})
    assert list(table.index) == ["a", "b"]
    assert table.loc["b", (metrics.MAX_ERROR, "median")] == pytest.approx(20.0)
    assert (metrics.TIME_ABOVE, "q90") in table.columns
    with pytest.raises(ValueError, match="received"):
        metrics.loss_figures_of_merit(err, fs=fs, received=received.astype(int))


def test_burst_response_on_a_known_excursion():
    fs = 10.0
    lossless = np.ones(100)
    lossy = lossless.copy()
    lossy[20:25] += 6.0      # burst ending at 20: 0.5 s of +6°, then back
    lossy[60:] += 3.0        # burst ending at 60: still +3° at the end of its 2 s window
    lossy[78:95] = np.nan    # reference lost: the window after 75 is mostly NaN
    res = metrics.burst_response(lossy, lossless, np.array([20, 60, 75, 95]), fs, window_s=2.0, threshold_deg=1.0)
    np.testing.assert_array_equal(res["kept"], [0, 1])     # 75: 3 of 20 valid; 95: runs past the end
    assert res["dropped"] == 2
    assert res["peak_increase_deg"] == pytest.approx([6.0, 3.0])
    assert res["mean_increase_deg"] == pytest.approx([6.0 * 5 / 20, 3.0])
    assert res["recovery_s"][0] == pytest.approx(0.5)
    assert np.isinf(res["recovery_s"][1])
    with pytest.raises(ValueError, match="burst_ends"):
        metrics.burst_response(lossy, lossless, np.array([1.5]), fs)


# --- BROAD error metrics ----------------------------------------------------------------------


def _broad_reference_formulas(imu_quat, opt_quat):
    """BROAD's example code (broad_utils.py), restated for (N, 4) arrays: errors in radians."""
    imu_quat = imu_quat / np.linalg.norm(imu_quat, axis=1)[:, None]
    opt_quat = opt_quat / np.linalg.norm(opt_quat, axis=1)[:, None]
    q = Q.multiply(imu_quat, opt_quat * np.array([1.0, -1.0, -1.0, -1.0]))
    q = q / np.linalg.norm(q, axis=1)[:, None]
    total = 2 * np.arccos(np.clip(np.abs(q[:, 0]), 0, 1))
    heading = 2 * np.arctan(np.abs(q[:, 3] / q[:, 0]))
    inclination = 2 * np.arccos(np.clip(np.sqrt(q[:, 0] ** 2 + q[:, 3] ** 2), 0, 1))
    return {"total": total, "heading": heading, "inclination": inclination}


def test_broad_errors_pure_heading_error():
    q_ref = Q.from_scipy(Rotation.random(50, random_state=7))
    angles = np.linspace(-170.0, 170.0, 50)
    q_est = Q.multiply(Q.from_axis_angle([0.0, 0.0, 1.0], np.radians(angles)), q_ref)  # about earth z
    err = metrics.broad_errors_deg(q_est, q_ref)
    np.testing.assert_allclose(err["heading"], np.abs(angles), atol=1e-9)
    np.testing.assert_allclose(err["total"], np.abs(angles), atol=1e-9)
    np.testing.assert_allclose(err["inclination"], 0.0, atol=1e-9)


@pytest.mark.parametrize("axis", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.6, -0.8, 0.0]])
def test_broad_errors_pure_tilt_error(axis):
    q_ref = Q.from_scipy(Rotation.random(50, random_state=8))
    angles = np.linspace(-170.0, 170.0, 50)
    q_est = Q.multiply(Q.from_axis_angle(axis, np.radians(angles)), q_ref)  # about a horizontal earth axis
    err = metrics.broad_errors_deg(q_est, q_ref)
    np.testing.assert_allclose(err["inclination"], np.abs(angles), atol=1e-9)
    np.testing.assert_allclose(err["total"], np.abs(angles), atol=1e-9)
    np.testing.assert_allclose(err["heading"], 0.0, atol=1e-9)


def test_broad_errors_body_frame_yaw_of_a_tilted_body_is_not_pure_heading():
    q_ref = Q.from_axis_angle([1.0, 0.0, 0.0], np.radians(60.0))
    q_est = Q.multiply(q_ref, Q.from_axis_angle([0.0, 0.0, 1.0], np.radians(10.0)))  # about body z
    err = metrics.broad_errors_deg(q_est, q_ref)
    assert err["total"] == pytest.approx(10.0)
    assert 0.0 < err["inclination"] < 10.0 and 0.0 < err["heading"] < 10.0


def test_broad_errors_agree_with_broads_formulas():
    q_est = Q.from_scipy(Rotation.random(2000, random_state=1)) * 1.7  # not normalised, as BROAD allows
    q_ref = Q.from_scipy(Rotation.random(2000, random_state=2))
    ours = metrics.broad_errors_deg(q_est, q_ref)
    theirs = _broad_reference_formulas(q_est, q_ref)
    for key in metrics.BROAD_ERROR_KEYS:
        np.testing.assert_allclose(ours[key], np.degrees(theirs[key]), rtol=0, atol=1e-6)
    # q and -q are the same orientation
    flipped = metrics.broad_errors_deg(-q_est, q_ref)
    for key in metrics.BROAD_ERROR_KEYS:
        np.testing.assert_allclose(flipped[key], ours[key], atol=1e-12)


def test_broad_errors_keep_reference_nan_and_broadcast():
    q_ref = Q.from_scipy(Rotation.random(30, random_state=4))
    q_ref[[0, 5, 6, 29]] = np.nan
    q_ref[10, 2] = np.nan  # a partly NaN row is a missing sample too
    q_est = np.stack([Q.identity((30,)), Q.from_scipy(Rotation.random(30, random_state=5))])
    err = metrics.broad_errors_deg(q_est, q_ref)
    for key in metrics.BROAD_ERROR_KEYS:
        assert err[key].shape == (2, 30)
        np.testing.assert_array_equal(np.flatnonzero(np.isnan(err[key][1])), [0, 5, 6, 10, 29])
        assert np.all((err[key][~np.isnan(err[key])] >= 0) & (err[key][~np.isnan(err[key])] <= 180))


def test_broad_rmse_over_movement_without_reference_gaps(rng):
    n = 400
    q_ref = Q.from_scipy(Rotation.random(n, random_state=6))
    heading = rng.uniform(-20.0, 20.0, n)
    q_est = Q.multiply(Q.from_axis_angle([0.0, 0.0, 1.0], np.radians(heading)), q_ref)
    q_ref[50:80] = np.nan
    movement = np.zeros(n, bool)
    movement[40:300] = True
    counted = movement & ~np.isnan(q_ref[:, 0])
    rmse = metrics.broad_rmse_deg(q_est, q_ref, movement)
    expected = np.sqrt(np.mean(heading[counted] ** 2))
    assert rmse["heading"] == pytest.approx(expected) and rmse["total"] == pytest.approx(expected)
    assert rmse["inclination"] == pytest.approx(0.0, abs=1e-9)
    assert np.isfinite(rmse["total"])
    # BROAD's calculateRMSE: movement samples, nanmean
    theirs = _broad_reference_formulas(q_est, q_ref)
    for key in metrics.BROAD_ERROR_KEYS:
        assert rmse[key] == pytest.approx(np.degrees(np.sqrt(np.nanmean(theirs[key][movement] ** 2))), abs=1e-6)
    # batches: one RMSE per run
    other = Q.identity((n,))
    batch = metrics.broad_rmse_deg(np.stack([q_est, other]), q_ref, movement)
    assert batch["total"].shape == (2,)
    assert batch["total"][0] == pytest.approx(rmse["total"])
    assert batch["total"][1] == pytest.approx(metrics.broad_rmse_deg(other, q_ref, movement)["total"])


def test_broad_rmse_refuses_when_nothing_is_left():
    q_ref = Q.from_scipy(Rotation.random(20, random_state=9))
    q_est = Q.identity((20,))
    movement = np.zeros(20, bool)
    movement[5:10] = True
    q_ref[5:10] = np.nan
    with pytest.raises(ValueError, match="no sample"):
        metrics.broad_rmse_deg(q_est, q_ref, movement)
    with pytest.raises(ValueError, match="no sample"):
        metrics.broad_rmse_deg(q_est, np.full((20, 4), np.nan), np.ones(20, bool))
    with pytest.raises(ValueError, match=r"batch index \(1,\)"):
        metrics.broad_rmse_deg(np.stack([q_est, q_est]), q_ref, np.stack([np.ones(20, bool), movement]))


def test_broad_metrics_reject_bad_inputs():
    q = Q.identity((10,))
    bad_est = q.copy()
    bad_est[3, 0] = np.nan
    with pytest.raises(ValueError, match="quat_est"):
        metrics.broad_errors_deg(bad_est, q)
    bad_ref = q.copy()
    bad_ref[3, 0] = np.inf
    with pytest.raises(ValueError, match="quat_ref contains inf"):
        metrics.broad_errors_deg(q, bad_ref)
    with pytest.raises(ValueError, match="zero quaternion"):
        metrics.broad_errors_deg(q, np.zeros((10, 4)))
    with pytest.raises(ValueError, match="broadcast"):
        metrics.broad_errors_deg(q, Q.identity((9,)))
    with pytest.raises(ValueError, match="boolean"):
        metrics.broad_rmse_deg(q, q, np.ones(10))
    with pytest.raises(ValueError, match="movement has shape"):
        metrics.broad_rmse_deg(q, q, np.ones(9, bool))


# --- position error and precision/accuracy (paper 002, Section 4.2) ---------------------------


def test_position_error_is_euclidean_and_zero_for_a_perfect_estimate(rng):
    true = rng.normal(size=(4, 30, 3))
    assert np.array_equal(metrics.position_error(true, true), np.zeros((4, 30)))
    est = true + np.array([0.03, -0.04, 0.0])
    assert metrics.position_error(est, true) == pytest.approx(np.full((4, 30), 0.05))
    # broadcasting: one true trajectory against a batch of estimates
    assert metrics.position_error(est, true[0]).shape == (4, 30)
    with pytest.raises(ValueError, match="est"):
        metrics.position_error(np.zeros((5, 2)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match="true"):
        metrics.position_error(np.zeros((5, 3)), np.full((5, 3), np.nan))
    with pytest.raises(ValueError, match="broadcast"):
        metrics.position_error(np.zeros((5, 3)), np.zeros((4, 3)))


def test_precision_at_accuracy_is_the_empirical_cdf(rng):
    errors = np.array([0.02, 0.10, 0.05, 0.10, 0.30])
    accuracy = np.array([0.0, 0.01, 0.02, 0.05, 0.099, 0.10, 0.2, 0.30, 1.0])
    precision = metrics.precision_at_accuracy(errors, accuracy)
    assert precision == pytest.approx([0.0, 0.0, 0.2, 0.4, 0.4, 0.8, 0.8, 1.0, 1.0])
    # monotone, 0 below the smallest error, 1 at and above the largest
    many = rng.gamma(2.0, 0.05, size=(3, 200))
    grid = np.linspace(0.0, 1.0, 501)
    curve = metrics.precision_at_accuracy(many, grid)
    assert np.all(np.diff(curve) >= 0.0)
    assert metrics.precision_at_accuracy(many, np.nextafter(many.min(), 0.0)) == 0.0
    assert metrics.precision_at_accuracy(many, many.max()) == 1.0
    assert metrics.precision_at_accuracy(many, np.inf) == 1.0
    with pytest.raises(ValueError, match="errors"):
        metrics.precision_at_accuracy([], grid)
    with pytest.raises(ValueError, match="errors"):
        metrics.precision_at_accuracy([0.1, np.nan], grid)
    with pytest.raises(ValueError, match="accuracies"):
        metrics.precision_at_accuracy(errors, [np.nan])
