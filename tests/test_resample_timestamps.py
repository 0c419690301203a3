"""Resampling from time stamps (issue 24): irregular, repeated and missing stamps, any fs_out.

Every test compares with known truth: analytic sines and constant-rate rotations evaluated at
the output times, and validity patterns derived independently (integer arithmetic, brute force).
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import quaternion as Q
from wsnlib.io import resample, resample_timestamps

T0 = 3.0  # s; the stamps' origin is arbitrary


def _jittered_stamps(rng, n, fs, jitter):
    """``T0 + (i + e_i) / fs`` with ``e_i`` uniform in ±``jitter`` (< 0.5: stamps stay increasing)."""
    return T0 + (np.arange(n) + rng.uniform(-jitter, jitter, n)) / fs


def _imu(t):
    """Three smooth channels (rad/s) that never repeat a value: 1.3 Hz, 0.7 Hz and 2.1 Hz."""
    return np.stack([np.sin(2 * np.pi * 1.3 * t + 0.7), np.cos(2 * np.pi * 0.7 * t),
                     0.5 * np.sin(2 * np.pi * 2.1 * t + 1.0)], axis=-1)


def _sine(t, freq, phase=0.7):
    return np.sin(2 * np.pi * freq * t + phase)[..., None]


def _interior(time_s, t_in, margin=0.5):
    """Output times more than ``margin`` s from both ends (the filter's half length is 10 / fs_out s)."""
    return (time_s > t_in[0] + margin) & (time_s < t_in[-1] - margin)


# --------------------------------------------------------------------------------------------
# The grid
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("fs_out", "n_out"), [(50.0, 501), (200.0, 2001), (37.3, 374), (7.0, 71), (7.03, 71)])
def test_grid_starts_at_the_first_stamp_and_stays_inside_the_span(rng, fs_out, n_out):
    t = np.linspace(T0, T0 + 10.0, 901)  # 90 Hz, exactly 10 s
    t[1:-1] += rng.uniform(-0.3, 0.3, 899) / 90.0
    out = resample_timestamps.resample_signal_timestamped(_imu(t), t, fs_out)
    assert out.time_s.shape == (n_out,) and out.values.shape == (n_out, 3) and out.valid.shape == (n_out,)
    np.testing.assert_allclose(out.time_s, T0 + np.arange(n_out) / fs_out, rtol=0, atol=1e-12)
    assert out.time_s[0] == T0 and out.time_s[-1] <= t[-1] + 1e-9
    assert out.valid.all()


# --------------------------------------------------------------------------------------------
# Irregular stamps: analytic sines at 50 Hz (downsampled, filtered) and 200 Hz (upsampled)
# --------------------------------------------------------------------------------------------

# (frequency Hz, output rate Hz, tolerance): at 50 Hz the filter's passband ripple (≤ 0.21 %)
# dominates at low frequencies; at 200 Hz (no filter) the cubic spline's error from ±30 % jitter,
# as the module docstring states it: ~1e-5 at fs_in/45, 5e-3 at fs_in/9, 3 % at fs_in/6.
@pytest.mark.parametrize(
    ("freq", "fs_out", "atol"),
    [(0.5, 50.0, 2.5e-3), (2.0, 50.0, 2.5e-3), (10.0, 50.0, 4e-3), (15.0, 50.0, 2e-2),
     (0.5, 200.0, 1e-6), (2.0, 200.0, 2e-5), (10.0, 200.0, 8e-3), (15.0, 200.0, 4e-2)],
)
def test_jittered_90_hz_sine_matches_the_analytic_sine(rng, freq, fs_out, atol):
    t = _jittered_stamps(rng, 1800, 90.0, 0.3)
    out = resample_timestamps.resample_signal_timestamped(_sine(t, freq), t, fs_out)
    assert out.valid.all()
    inner = _interior(out.time_s, t)
    error = np.abs(out.values[inner, 0] - _sine(out.time_s[inner], freq)[:, 0])
    assert error.max() < atol
    if fs_out > 90.0:  # no filter when upsampling: no edge effect beyond the spline's ends (2×)
        assert np.max(np.abs(out.values[:, 0] - _sine(out.time_s, freq)[:, 0])) < 2 * atol


def test_linear_interpolation_would_fail_the_upsampling_tolerance(rng):
    """The 200 Hz tolerance above is tight enough to tell a cubic spline from straight lines."""
    t = _jittered_stamps(rng, 1800, 90.0, 0.3)
    grid = T0 + np.arange(3000) / 200.0
    linear = np.interp(grid, t, _sine(t, 2.0)[:, 0])
    assert np.max(np.abs(linear - _sine(grid, 2.0)[:, 0])) > 100 * 3e-5


def test_constant_and_linear_trend_survive_downsampling_including_edges(rng):
    t = _jittered_stamps(rng, 900, 90.0, 0.3)
    x = np.stack([1.0 + 0.5 * (t - T0), -2.0 * (t - T0), 9.81 + 0.01 * np.sin(t)], -1)
    out = resample_timestamps.resample_signal_timestamped(x, t, 50.0)
    tt = out.time_s
    expected = np.stack([1.0 + 0.5 * (tt - T0), -2.0 * (tt - T0), 9.81 + 0.01 * np.sin(tt)], -1)
    np.testing.assert_allclose(out.values, expected, atol=2e-4)


# --------------------------------------------------------------------------------------------
# The anti-alias filter: above the new Nyquist frequency, at least 55 dB down
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("freq", [32.0, 35.0, 40.0, 44.0])
@pytest.mark.parametrize(("fs_in", "jitter"), [(99.73, 0.0), (500.0, 0.3)])
def test_tone_above_the_new_nyquist_is_attenuated_55_db(rng, freq, fs_in, jitter):
    """99.73 → 50 Hz is no small-integer ratio (the rational path refuses it); ~500 Hz jittered."""
    t = _jittered_stamps(rng, int(30 * fs_in), fs_in, jitter)
    x = np.cos(2 * np.pi * freq * t + 0.3)[:, None]
    out = resample_timestamps.resample_signal_timestamped(x, t, 50.0)
    inner = _interior(out.time_s, t)
    assert np.max(np.abs(out.values[inner, 0])) < 10 ** (-55 / 20)
    # without the filter the tone would fold to 50 - freq Hz at full amplitude
    aliased = np.cos(2 * np.pi * freq * out.time_s[inner] + 0.3)
    assert np.max(np.abs(aliased)) > 0.9


def test_passband_edge_keeps_its_gain(rng):
    """0.4·fs_out: gain within 0.21 % (the filter's documented passband)."""
    t = _jittered_stamps(rng, 15000, 500.0, 0.3)
    out = resample_timestamps.resample_signal_timestamped(_sine(t, 20.0), t, 50.0)
    inner = _interior(out.time_s, t)
    np.testing.assert_allclose(out.values[inner, 0], _sine(out.time_s[inner], 20.0)[:, 0], atol=2.5e-3)


# --------------------------------------------------------------------------------------------
# Repeated stamps and sample-and-hold
# --------------------------------------------------------------------------------------------

def _sample_and_hold(rng, fs_sensor=50.0, polls_per_update=4, seconds=20.0):
    """A sensor measuring at jittered ~50 Hz, logged 4× per update: each update's row carries
    the time it was measured, the 3 polls after it repeat its value; every 7th row is written
    twice with the same stamp."""
    updates = _jittered_stamps(rng, int(seconds * fs_sensor), fs_sensor, 0.2)
    step = np.diff(updates, append=updates[-1] + 1.0 / fs_sensor)
    stamps = (updates[:, None] + step[:, None] * np.arange(polls_per_update) / polls_per_update).ravel()
    values = np.repeat(_imu(updates), polls_per_update, axis=0)
    twice = np.repeat(np.arange(stamps.size), np.where(np.arange(stamps.size) % 7 == 0, 2, 1))
    return stamps[twice], values[twice]


@pytest.mark.parametrize("fs_out", [100.0, 20.0])
def test_sample_and_hold_copies_make_no_stair(rng, fs_out):
    stamps, values = _sample_and_hold(rng)
    out = resample_timestamps.resample_signal_timestamped(values, stamps, fs_out)
    inner = _interior(out.time_s, stamps)
    # the last update's copies reach past its measuring time: nothing fresh after it
    assert out.valid[inner].all()
    error = np.abs(out.values[inner] - _imu(out.time_s[inner]))
    assert error.max() < 2.5e-3
    # keeping the copies draws the stair: the error is then the signal's change over a hold
    stair = resample_timestamps.resample_signal_timestamped(values, stamps, fs_out, drop_repeated_values=False)
    assert np.abs(stair.values[inner] - _imu(stair.time_s[inner])).max() > 10 * 2.5e-3


def test_samples_sharing_a_stamp_are_averaged(rng):
    t = T0 + np.arange(1000) / 100.0
    noise = rng.normal(scale=0.05, size=(1000, 3))
    # each stamp twice: truth + d and truth - d; their mean is the truth
    stamps = np.repeat(t, 2)
    values = np.stack([_imu(t) + noise, _imu(t) - noise], axis=1).reshape(2000, 3)
    out = resample_timestamps.resample_signal_timestamped(values, stamps, 100.0)
    np.testing.assert_allclose(out.time_s, t, atol=1e-12)
    np.testing.assert_allclose(out.values, _imu(t), atol=1e-12)


def test_a_stuck_sensor_is_a_gap(rng):
    t = _jittered_stamps(rng, 1800, 90.0, 0.2)
    x = _imu(t)
    stuck = (t > T0 + 8.0) & (t < T0 + 8.3)
    first = np.argmax(stuck)
    x[stuck] = x[first]  # the value of the run's first sample, held
    out = resample_timestamps.resample_signal_timestamped(x, t, 50.0)
    last_fresh, next_fresh = t[first], t[np.flatnonzero(stuck)[-1] + 1]
    np.testing.assert_array_equal(out.valid, ~((out.time_s > last_fresh) & (out.time_s < next_fresh)))
    assert np.isnan(out.values[~out.valid]).all() and np.isfinite(out.values[out.valid]).all()


# --------------------------------------------------------------------------------------------
# Gaps: not invented
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("fs_out", [50.0, 200.0])
def test_missing_stamps_longer_than_the_max_gap_are_invalid(rng, fs_out):
    t_all = _jittered_stamps(rng, 1800, 90.0, 0.2)
    index = np.arange(1800)
    lost_run = np.flatnonzero((t_all >= T0 + 6.0) & (t_all < T0 + 6.5))  # 0.5 s
    lost = np.isin(index, lost_run) | (index == 1000)  # and a single sample: bridged
    lost |= (index >= 1400) & (index < 1403)  # three samples: 4 intervals > 2.5 median intervals
    t, x = t_all[~lost], _imu(t_all[~lost])
    out = resample_timestamps.resample_signal_timestamped(x, t, fs_out)
    gaps = [(t_all[lost_run[0] - 1], t_all[lost_run[-1] + 1]), (t_all[1399], t_all[1403])]
    in_gap = np.zeros(out.time_s.size, bool)
    for before, after in gaps:
        in_gap |= (out.time_s > before) & (out.time_s < after)
    np.testing.assert_array_equal(out.valid, ~in_gap)
    assert np.isnan(out.values[in_gap]).all()
    # away from the gaps' edges (the filter's half length, 0.2 s at 50 Hz) the signal is right,
    # the single lost sample included (bridged: 2 intervals ≤ 2.5 median intervals)
    near_edge = np.zeros(out.time_s.size, bool)
    for before, after in gaps:
        near_edge |= (out.time_s > before - 0.25) & (out.time_s < after + 0.25)
    keep = ~near_edge & _interior(out.time_s, t)
    assert np.abs(out.values[keep] - _imu(out.time_s[keep])).max() < 2.5e-3
    # a larger max_gap_s bridges everything
    assert resample_timestamps.resample_signal_timestamped(x, t, fs_out, max_gap_s=0.6).valid.all()


def test_default_max_gap_is_2_5_median_intervals():
    t = T0 + np.arange(200) / 100.0
    keep = np.ones(200, bool)
    keep[[50, 51]] = False  # 3 intervals (0.03 s) > 2.5 × 0.01 s
    keep[100] = False  # 2 intervals, bridged
    out = resample_timestamps.resample_signal_timestamped(_imu(t[keep]), t[keep], 100.0)
    expected = np.ones(out.time_s.size, bool)
    expected[[50, 51]] = False
    np.testing.assert_array_equal(out.valid, expected)
    assert resample_timestamps.resample_signal_timestamped(_imu(t[keep]), t[keep], 100.0, max_gap_s=0.03).valid.all()
    assert resample_timestamps.MAX_GAP_INTERVALS == 2.5


def test_batches_share_the_stamps(rng):
    t = _jittered_stamps(rng, 500, 90.0, 0.3)
    x = rng.normal(size=(2, 3, 500, 3))
    for fs_out in (50.0, 200.0):
        out = resample_timestamps.resample_signal_timestamped(x, t, fs_out)
        assert out.values.shape == (2, 3, out.time_s.size, 3) and out.valid.shape == out.time_s.shape
        single = resample_timestamps.resample_signal_timestamped(x[1, 2], t, fs_out)
        np.testing.assert_allclose(out.values[1, 2], single.values, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# Quaternions: SLERP onto any times
# --------------------------------------------------------------------------------------------

def _constant_rate_rotation(t, rate=1.3, axis=(0.2, -0.5, 0.8)):
    """q(t) = q0 ⊗ exp(rate·t·axis/2): constant body rate about a fixed axis (a geodesic)."""
    q0 = Q.from_scipy(Rotation.from_euler("xyz", [0.4, -0.3, 2.0]))
    return Q.multiply(q0, Q.from_axis_angle(np.asarray(axis, float), rate * (np.asarray(t) - T0)))


def test_slerp_of_a_constant_rate_rotation_onto_an_irregular_grid_is_exact(rng):
    t = _jittered_stamps(rng, 400, 40.0, 0.3)
    quat = _constant_rate_rotation(t)
    quat[1::2] *= -1.0  # q and -q alternate: the shorter arc must still be taken
    quat[::3] *= 2.5  # not normalised
    inside = rng.uniform(t[0], t[-1], 700)
    times = np.concatenate([inside, t[[0, 17, 399]], [t[0] - 0.01, t[-1] + 0.01]])
    out = resample_timestamps.resample_quaternion_timestamped(quat, t, times)
    assert out.shape == (times.size, 4)
    assert np.isnan(out[-2:]).all()  # outside the span
    good = out[:-2]
    assert np.max(Q.angle_between(good, _constant_rate_rotation(times[:-2]))) < 1e-9
    np.testing.assert_allclose(np.linalg.norm(good, axis=-1), 1.0, atol=1e-12)
    # on a stamp: the sample itself, normalised
    np.testing.assert_allclose(good[-3:], Q.normalize(quat[[0, 17, 399]]), rtol=0, atol=1e-15)


def test_40_hz_reference_with_11_percent_nan_frames(rng):
    """NaN exactly where the output time is a NaN frame or between two frames one of which is
    NaN, or inside a stretch of missing stamps longer than the max gap; found here in integers:
    output k (50 Hz) is at frame position 4k/5 (40 Hz)."""
    n = 1200
    frames = np.arange(n)
    quat = _constant_rate_rotation(T0 + frames / 40.0)
    nan_frame = rng.random(n) < 0.11
    nan_frame[300:310] = True  # a run as well
    quat[nan_frame] = np.nan
    present = np.ones(n, bool)
    present[600:606] = False  # rows (and stamps) missing: frames 599 → 606 is 7 intervals
    grid = resample_timestamps.resample_signal_timestamped(np.zeros((n, 3)) + frames[:, None], T0 + frames / 40.0, 50.0)
    out = resample_timestamps.resample_quaternion_timestamped(quat[present], T0 + frames[present] / 40.0, grid.time_s)
    k = np.arange(grid.time_s.size)
    lower, on_frame = 4 * k // 5, 4 * k % 5 == 0
    upper = np.minimum(lower + 1, n - 1)
    usable = ~nan_frame & present
    expected_valid = np.where(on_frame, usable[lower], usable[lower] & usable[upper])
    missing_stretch = (4 * k > 5 * 599) & (4 * k < 5 * 606)
    expected_valid &= ~missing_stretch
    valid = ~np.isnan(out).any(axis=-1)
    assert np.array_equal(valid, ~np.isnan(out).all(axis=-1))
    np.testing.assert_array_equal(valid, expected_valid)
    assert 0.15 < 1 - valid.mean() < 0.35  # 11 % of frames lost → about twice as many outputs
    assert np.max(Q.angle_between(out[valid], _constant_rate_rotation(grid.time_s[valid]))) < 1e-9


def test_quaternion_batches_and_shared_stamps(rng):
    t = _jittered_stamps(rng, 200, 40.0, 0.3)
    quat = np.stack([_constant_rate_rotation(t, rate=r) for r in (0.5, 4.0)])
    quat[1, 50] = np.nan
    times = T0 + np.sort(rng.uniform(0.0, 4.9, 300))
    out = resample_timestamps.resample_quaternion_timestamped(quat, t, times)
    assert out.shape == (2, 300, 4)
    np.testing.assert_array_equal(out[0], resample_timestamps.resample_quaternion_timestamped(quat[0], t, times))
    np.testing.assert_array_equal(np.isnan(out[1, :, 0]), (times > t[49]) & (times < t[51]))
    assert not np.isnan(out[0]).any()


def test_quaternions_sharing_a_stamp_are_averaged_on_the_shorter_arc():
    t = T0 + np.arange(100) / 40.0
    truth = _constant_rate_rotation(t)
    tilt = Q.from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.02)
    plus, minus = Q.multiply(truth, tilt), Q.multiply(truth, Q.conjugate(tilt))
    minus[::2] *= -1.0
    pairs = np.stack([plus, minus], axis=1).reshape(200, 4)
    pairs[[10, 51]] = np.nan  # one of a pair missing: the other one stands
    out = resample_timestamps.resample_quaternion_timestamped(pairs, np.repeat(t, 2), t)
    expected = truth.copy()
    expected[5], expected[25] = minus[5], plus[25]
    assert np.max(Q.angle_between(out, expected)) < 1e-12


def test_a_held_reference_pose_is_a_gap_and_drop_repeated_values_false_keeps_it():
    t = T0 + np.arange(400) / 40.0
    quat = _constant_rate_rotation(t)
    quat[200:210] = quat[199]  # the system held its last pose for 10 frames
    times = T0 + np.arange(0, 399, 0.5) / 40.0
    out = resample_timestamps.resample_quaternion_timestamped(quat, t, times)
    held = (times > t[199]) & (times < t[210])
    np.testing.assert_array_equal(np.isnan(out[:, 0]), held)
    kept = resample_timestamps.resample_quaternion_timestamped(quat, t, times, drop_repeated_values=False)
    assert not np.isnan(kept).any()


# --------------------------------------------------------------------------------------------
# Masks: nearest sample
# --------------------------------------------------------------------------------------------

def test_mask_takes_the_nearest_sample_and_is_invalid_in_gaps(rng):
    t_all = _jittered_stamps(rng, 700, 90.0, 0.3)
    present = np.ones(700, bool)
    present[300:320] = False
    t = t_all[present]
    mask = rng.random((2, t.size)) < 0.5
    times = rng.uniform(t[0] - 0.05, t[-1] + 0.05, 900)
    out = resample_timestamps.resample_mask_timestamped(mask, t, times)
    assert out.values.shape == (2, 900) and out.valid.shape == (900,)
    np.testing.assert_array_equal(out.time_s, times)
    nearest = np.argmin(np.abs(times[:, None] - t[None, :]), axis=1)
    in_gap = (times > t_all[299]) & (times < t_all[320])
    expected_valid = (times >= t[0]) & (times <= t[-1]) & ~in_gap
    np.testing.assert_array_equal(out.valid, expected_valid)
    np.testing.assert_array_equal(out.values, mask[:, nearest] & expected_valid)


# --------------------------------------------------------------------------------------------
# Errors name the argument
# --------------------------------------------------------------------------------------------

GOOD_T = T0 + np.arange(10) / 90.0
GOOD_X = _imu(GOOD_T)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"time_s": np.r_[GOOD_T[:4], np.nan, GOOD_T[5:]]}, r"time_s contains NaN or inf \(first at index 4\)"),
        ({"time_s": np.r_[GOOD_T[:4], np.inf, GOOD_T[5:]]}, "time_s contains NaN or inf"),
        ({"time_s": GOOD_T[[0, 1, 2, 4, 3, 5, 6, 7, 8, 9]]}, r"time_s must not decrease .*time_s\[3\]"),
        ({"time_s": GOOD_T[:9]}, "time_s has 9 stamps but x has 10 samples"),
        ({"time_s": GOOD_T[None]}, "time_s must be 1-D"),
        ({"time_s": np.full(10, T0)}, "x needs at least 2 samples with distinct stamps"),
        ({"x": GOOD_X[:1], "time_s": GOOD_T[:1]}, "x needs at least 2 samples along axis -2"),
        ({"x": np.ones((10, 3))}, "x needs at least 2 samples with distinct stamps and values"),
        ({"x": np.r_[GOOD_X[:3], [[np.nan, 0, 0]], GOOD_X[4:]]}, "x contains NaN"),
        ({"x": np.ones(10)}, "x must have at least 2 dimension"),
        ({"fs_out": 0.0}, "fs_out"),
        ({"fs_out": -50.0}, "fs_out"),
        ({"fs_out": np.nan}, "fs_out"),
        ({"max_gap_s": 0.0}, "max_gap_s"),
        ({"drop_repeated_values": "yes"}, "drop_repeated_values"),
    ],
)
def test_signal_errors_name_the_argument(kwargs, match):
    args = {"x": GOOD_X, "time_s": GOOD_T, "fs_out": 50.0} | kwargs
    with pytest.raises(ValueError, match=match):
        resample_timestamps.resample_signal_timestamped(**args)


def test_quaternion_and_mask_errors_name_the_argument():
    quat = _constant_rate_rotation(GOOD_T)
    with pytest.raises(ValueError, match="time_s has 9 stamps but quat has 10 samples"):
        resample_timestamps.resample_quaternion_timestamped(quat, GOOD_T[:9], GOOD_T)
    with pytest.raises(ValueError, match="time_out_s contains NaN"):
        resample_timestamps.resample_quaternion_timestamped(quat, GOOD_T, np.r_[GOOD_T[:3], np.nan])
    with pytest.raises(ValueError, match="time_out_s must be 1-D"):
        resample_timestamps.resample_quaternion_timestamped(quat, GOOD_T, GOOD_T[None])
    with pytest.raises(ValueError, match="quat must have shape"):
        resample_timestamps.resample_quaternion_timestamped(quat[0], GOOD_T[:1], GOOD_T)
    with pytest.raises(ValueError, match="time_s must not decrease"):
        resample_timestamps.resample_quaternion_timestamped(quat, GOOD_T[::-1], GOOD_T)
    with pytest.raises(ValueError, match="max_gap_s"):
        resample_timestamps.resample_quaternion_timestamped(quat, GOOD_T, GOOD_T, max_gap_s=-1.0)
    with pytest.raises(ValueError, match="quat needs at least 2 rows"):
        resample_timestamps.resample_quaternion_timestamped(np.tile(quat[:1], (10, 1)), GOOD_T, GOOD_T)
    with pytest.raises(ValueError, match="boolean"):
        resample_timestamps.resample_mask_timestamped(np.ones(10), GOOD_T, GOOD_T)
    with pytest.raises(ValueError, match="time_s has 10 stamps but mask has 9 samples along its last axis"):
        resample_timestamps.resample_mask_timestamped(np.ones(9, bool), GOOD_T, GOOD_T)
    with pytest.raises(ValueError, match="mask needs at least 2 samples with distinct"):
        resample_timestamps.resample_mask_timestamped(np.ones(10, bool), np.full(10, T0), GOOD_T)


# --------------------------------------------------------------------------------------------
# The rational path points to the time-stamp path
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("fs_in", "fs_out"), [(99.73, 50.0), (285.714, 50.0), (50.0, 100.0)])
def test_rational_path_errors_point_to_the_time_stamp_function(fs_in, fs_out):
    with pytest.raises(ValueError, match=r"resample_signal_timestamped\(x, time_s, fs_out\)"):
        resample.resample_signal(np.zeros((100, 3)), fs_in, fs_out)
