import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import metrics
from wsnlib import quaternion as Q
from wsnlib.metrics.smoothness import _rms_without_gap_ends, _squared_angular_jerk

#: The keys of broad_errors_deg and broad_rmse_deg.
_BROAD_KEYS = ("total", "heading", "inclination")


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
    assert metrics.broad_errors_deg(Q.multiply(q_true, delta), q_true)["total"] == pytest.approx(np.full(20, 7.0))
    # q and -q are the same orientation
    assert metrics.broad_errors_deg(-q_true, q_true)["total"] == pytest.approx(np.zeros(20), abs=1e-6)


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


def test_single_burst_response_against_the_error_just_before_it():
    """Paper 001's protocol: one burst per run, its effect measured from where the method was."""
    fs = 10.0
    received = np.ones((3, 100), bool)
    received[:, 40:45] = False                          # one burst: samples 40-44, first received after it 45
    error = np.full((3, 100), 2.0)
    error[0, 40:50] = 12.0                              # run 0: +10° from the burst's start to 49, then back
    error[1] = 20.0                                     # run 1: high before, and still 25° (> 20 + 2) at the end
    error[1, 45:] = 25.0
    error[2, 30:35] = 6.0                               # run 2: an earlier excursion sets what "before" means
    error[2, 35:40] = np.nan                            # ... its last half second has no reference
    res = metrics.single_burst_response(error, received, fs, before_s=1.0, window_s=3.0, threshold_deg=2.0,
                                        level_deg=10.0)
    assert res["start"].tolist() == [40] * 3 and res["end"].tolist() == [45] * 3
    np.testing.assert_allclose(res["before_deg"], [2.0, 20.0, 6.0])
    np.testing.assert_allclose(res["peak_increase_deg"], [10.0, 5.0, -4.0])
    np.testing.assert_allclose(res["mean_increase_deg"], [10.0 * 5 / 30, 5.0, -4.0])
    # Back within 2° of the error before: after sample 49 (0.5 s from 45); never (inf); at once (0).
    np.testing.assert_allclose(res["recovery_s"], [0.5, np.inf, 0.0])
    # Below an absolute 10°: the same for run 0; never for run 1, which was above it already; at once for run 2.
    np.testing.assert_allclose(res["level_recovery_s"], [0.5, np.inf, 0.0])
    # A window without enough reference gives NaN, not a number.
    sparse = error[:1].copy()
    sparse[0, 45:70] = np.nan
    assert np.isnan(metrics.single_burst_response(sparse, received[:1], fs, window_s=3.0)["recovery_s"]).all()
    two = received[0].copy()
    two[60:65] = False
    with pytest.raises(ValueError, match="exactly one run"):
        metrics.single_burst_response(error[0], two, fs)
    with pytest.raises(ValueError, match="before it and one after"):
        metrics.single_burst_response(error[0], np.arange(100) > 3, fs)
    with pytest.raises(ValueError, match="boolean"):
        metrics.single_burst_response(error[0], received[0].astype(int), fs)


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
    for key in _BROAD_KEYS:
        np.testing.assert_allclose(ours[key], np.degrees(theirs[key]), rtol=0, atol=1e-6)
    # q and -q are the same orientation
    flipped = metrics.broad_errors_deg(-q_est, q_ref)
    for key in _BROAD_KEYS:
        np.testing.assert_allclose(flipped[key], ours[key], atol=1e-12)


def test_broad_errors_keep_reference_nan_and_broadcast():
    q_ref = Q.from_scipy(Rotation.random(30, random_state=4))
    q_ref[[0, 5, 6, 29]] = np.nan
    q_ref[10, 2] = np.nan  # a partly NaN row is a missing sample too
    q_est = np.stack([Q.identity((30,)), Q.from_scipy(Rotation.random(30, random_state=5))])
    err = metrics.broad_errors_deg(q_est, q_ref)
    for key in _BROAD_KEYS:
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
    for key in _BROAD_KEYS:
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


# --- Smoothness split, quantile and phases (issue 12) ---------------------------------------


def _gappy_trace():
    """A smooth sine with two gaps during which the output is held, so each gap ends in a step."""
    fs = 50.0
    t = np.arange(300) / fs
    truth = 20.0 * np.sin(2 * np.pi * 0.5 * t)
    received = np.ones(300, dtype=bool)
    received[100:120] = False
    received[200:210] = False
    held = truth.copy()
    for start, stop in ((100, 120), (200, 210)):
        held[start:stop] = truth[start - 1]
    return fs, truth, held, received


def test_gap_end_mask_marks_first_received_sample_after_each_gap():
    received = np.array([False, False, True, True, False, True, False])
    assert np.flatnonzero(metrics.gap_end_mask(received)).tolist() == [2, 5]  # the open gap at the end: none
    assert not metrics.gap_end_mask(np.ones(5, dtype=bool)).any()
    with pytest.raises(ValueError, match="received"):
        metrics.gap_end_mask(np.array([1, 0, 1]))


def test_gap_end_steps_recover_planted_steps():
    fs, truth, held, received = _gappy_trace()
    steps = metrics.gap_end_steps_deg(held, received)
    planted = [abs(truth[119 + 1] - truth[99]), abs(truth[209 + 1] - truth[199])]
    assert steps["step_deg"][steps["gap_end"]] == pytest.approx(planted)
    assert steps["n_gaps"] == 2
    assert steps["max_deg"] == pytest.approx(max(planted))
    assert steps["mean_deg"] == pytest.approx(np.mean(planted))
    # No gap: no step, explicitly zero with n_gaps 0; batches keep their shape.
    batch = metrics.gap_end_steps_deg(np.stack([held, truth]), np.stack([received, np.ones(300, bool)]))
    assert batch["n_gaps"].tolist() == [2, 0] and batch["max_deg"][1] == 0.0


def test_quaternion_gap_end_steps_match_the_angle_version():
    fs, truth, held, received = _gappy_trace()
    quat = Q.from_axis_angle([0.0, 1.0, 0.0], np.radians(held))
    ours = metrics.quat_gap_end_steps_deg(quat, received)
    assert ours["step_deg"] == pytest.approx(metrics.gap_end_steps_deg(held, received)["step_deg"], abs=1e-6)


def test_jitter_excludes_the_gap_end_step_but_jerk_does_not():
    fs, truth, _, received = _gappy_trace()
    # During each gap the estimate drifts away smoothly (quadratic, no kink) and snaps back
    # at the gap's end: one planted step per gap, nothing else rough.
    drifting = truth.copy()
    for start, stop in ((100, 120), (200, 210)):
        drifting[start:stop] += 10.0 * (np.arange(1, stop - start + 1) / (stop - start)) ** 2
    steps = metrics.gap_end_steps_deg(drifting - truth, received)
    assert steps["step_deg"][steps["gap_end"]] == pytest.approx([10.0, 10.0])
    smooth = metrics.angle_jerk_rms_deg(truth, fs)
    jerk = metrics.angle_jerk_rms_deg(drifting, fs)
    jitter = metrics.angle_jerk_rms_deg(drifting, fs, received)
    assert jerk > 100 * smooth            # the two steps dominate the whole-record jerk
    assert jitter < 3 * smooth            # without them the trace is about as smooth as the truth
    # Without loss, jitter is the jerk.
    assert metrics.angle_jerk_rms_deg(truth, fs, np.ones(300, bool)) == pytest.approx(smooth)
    # A noisy record stays noisy: the jitter is not blind.
    noisy = drifting + np.random.default_rng(0).normal(scale=0.5, size=300)
    assert metrics.angle_jerk_rms_deg(noisy, fs, received) > 30 * jitter


def test_quaternion_jitter_matches_the_angle_version_for_one_axis():
    fs, truth, held, received = _gappy_trace()
    quat = Q.from_axis_angle([0.0, 1.0, 0.0], np.radians(held))
    assert metrics.angular_jerk_rms_deg(quat, fs, received) == pytest.approx(
        metrics.angle_jerk_rms_deg(held, fs, received), rel=1e-6)
    assert metrics.angular_jerk_rms_deg(quat, fs, np.ones(300, bool)) == pytest.approx(
        metrics.angular_jerk_rms_deg(quat, fs), rel=1e-9)


def test_jitter_raises_when_no_window_is_free():
    received = np.array([True, False, True, False, True, False, True])
    with pytest.raises(ValueError, match="no jerk window"):
        metrics.angle_jerk_rms_deg(np.arange(7.0), 50.0, received)


def test_quantile_error_is_stable_where_the_maximum_shrinks():
    rng = np.random.default_rng(3)
    error = np.abs(rng.normal(size=(1, 20000)))
    received = rng.random(error.shape) < 0.02      # 98 % random loss: 400 samples left
    # The maximum over fewer samples is smaller, though nothing got better ...
    assert metrics.max_abs_error(error, where=received) < metrics.max_abs_error(error) - 0.5
    # ... while the 95th percentile estimates the same number (1.96 for |N(0, 1)|) either way.
    q_all = metrics.quantile_error(error, 0.95)
    assert q_all == pytest.approx(1.96, abs=0.05)
    assert metrics.quantile_error(error, 0.95, where=received) == pytest.approx(q_all, abs=0.2)
    assert metrics.quantile_error(error, 1.0) == pytest.approx(metrics.max_abs_error(error))
    with pytest.raises(ValueError, match="no sample counts"):
        metrics.quantile_error(error, where=np.zeros(error.shape, bool))
    with pytest.raises(ValueError, match="q must"):
        metrics.quantile_error(error, q=95)


def test_error_by_phase_on_a_planted_trace():
    fs = 10.0
    received = np.ones(60, dtype=bool)
    received[10:20] = False                        # gap: error 6
    error = np.full(60, 1.0)                       # steady: error 1
    error[10:20] = 6.0
    error[20:25] = 3.0                             # 0.5 s after the gap: error 3
    error[25:30] = -3.0
    phases = metrics.error_by_phase(error, received, fs, after_s=1.0)
    assert phases["lost"] == pytest.approx(6.0) and phases["n_lost"] == 10
    assert phases["after_gap"] == pytest.approx(3.0) and phases["n_after_gap"] == 10
    assert phases["steady"] == pytest.approx(1.0) and phases["n_steady"] == 40
    mean = metrics.error_by_phase(error, received, fs, after_s=0.5, statistic="mean")
    assert mean["after_gap"] == pytest.approx(3.0) and mean["n_after_gap"] == 5
    assert mean["steady"] == pytest.approx((40 * 1.0 + 5 * 3.0) / 45) and mean["n_steady"] == 45
    # No loss: explicit NaN with count 0; NaN errors (no reference) skipped.
    clean = metrics.error_by_phase(np.r_[np.nan, np.ones(9)], np.ones(10, bool), fs)
    assert np.isnan(clean["lost"]) and clean["n_lost"] == 0 and clean["n_steady"] == 9
    with pytest.raises(ValueError, match="statistic"):
        metrics.error_by_phase(error, received, fs, statistic="max")
    with pytest.raises(ValueError, match="received"):
        metrics.error_by_phase(error, received[:10], fs)


def test_extended_figures_of_merit():
    fs, truth, held, received = _gappy_trace()
    error = held - truth
    foms = metrics.loss_figures_of_merit(error, fs=fs, received=received, extended=True)
    assert foms[metrics.GAP_STEP_MAX] == pytest.approx(metrics.gap_end_steps_deg(error, received)["max_deg"])
    assert foms[metrics.JITTER] < foms[metrics.JERK] / 10
    assert foms[metrics.P95_ERROR] <= foms[metrics.MAX_ERROR]
    assert metrics.GAP_STEP_MAX not in metrics.loss_figures_of_merit(error, fs=fs, received=received)


# --- The compiled metrics give numpy's bits (wsnlib.metrics._kernels) -----------------------------

def _numpy_broad_errors_deg(est, ref):
    """broad_errors_deg as numpy expressions (what the compiled steps replace), for a bit-for-bit check."""
    est = est / np.linalg.norm(est, axis=-1)[..., None]
    ref = ref / np.linalg.norm(ref, axis=-1, keepdims=True)
    # (the product: tests/test_quaternion.py checks Q.multiply against numpy's expressions bit for bit)
    w, x, y, z = np.moveaxis(Q.multiply(est, ref * np.array([1.0, -1.0, -1.0, -1.0])), -1, 0)
    errors = {"total": 2.0 * np.arctan2(np.sqrt(x * x + y * y + z * z), np.abs(w)),
              "heading": 2.0 * np.arctan2(np.abs(z), np.abs(w)),
              "inclination": 2.0 * np.arctan2(np.hypot(x, y), np.hypot(w, z))}
    return {key: np.degrees(value) for key, value in errors.items()}


def _numpy_squared_jerk(quat, fs):
    """The squared angular jerk as numpy expressions (what the compiled steps replace)."""
    delta = Q.canonical(Q.multiply(Q.conjugate(quat[..., :-1, :]), quat[..., 1:, :]))
    sin_half = np.linalg.norm(delta[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sin_half, delta[..., :1])
    axis = np.divide(delta[..., 1:], sin_half, out=np.zeros_like(delta[..., 1:]), where=sin_half > 0)
    return np.sum((np.diff(axis * angle * fs, n=2, axis=-2) * fs**2) ** 2, axis=-1)


def _bitwise_equal(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


def test_broad_errors_are_numpys_bits(rng):
    """Unnormalised estimates over many magnitudes, a batch against one reference with NaN rows (BROAD's
    lost markers), a reference row equal to an estimate's (error 0), a strided estimate."""
    est = rng.normal(size=(3, 500, 4)) * 10.0 ** rng.uniform(-3, 3, size=(3, 500, 1))
    ref = rng.normal(size=(500, 4))
    ref[::37] = np.nan
    ref[5] = est[0, 5]
    # (the last: one reference per sample of a recording of 4, as many values as one recording's reference)
    for e, r in ((est, ref), (est[:, ::2], ref[::2]), (est[0], ref), (est[:, :7], est[:, :7]),
                 (est[:1, :4], est[0, :4, None])):
        ours, expected = metrics.broad_errors_deg(e, r), _numpy_broad_errors_deg(np.asarray(e), np.asarray(r))
        for key in _BROAD_KEYS:
            assert np.array_equal(ours[key], expected[key], equal_nan=True), key
            finite = np.isfinite(expected[key])
            assert _bitwise_equal(ours[key][finite], expected[key][finite]), key
    assert metrics.broad_errors_deg(est, ref)["total"][0, 5] < 1e-6


def test_angular_jerk_is_numpys_bits(rng):
    """A smooth rotation, noise, repeated samples (steps of no rotation) and sign flips (q and −q)."""
    fs = 50.0
    rotvec = np.cumsum(rng.normal(scale=0.05, size=(2, 400, 3)), axis=-2)
    quat = Q.from_rotation_vector(rotvec)
    quat[:, 100:110] = quat[:, 100:101]  # no rotation: the axis is 0
    quat[:, ::7] *= -1.0
    for q in (quat, quat[0], quat[:, ::3]):
        expected = np.degrees(_rms_without_gap_ends(_numpy_squared_jerk(q, fs), None, q.shape[:-1]))
        assert _bitwise_equal(np.atleast_1d(metrics.angular_jerk_rms_deg(q, fs)), np.atleast_1d(expected))
    assert _bitwise_equal(_squared_angular_jerk(quat, fs), _numpy_squared_jerk(quat, fs))
