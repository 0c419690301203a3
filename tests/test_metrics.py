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
