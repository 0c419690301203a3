import os
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import paths
from wsnlib import quaternion as Q
from wsnlib.io import broad, resample

FS_IN = 2000 / 7  # BROAD
FS_OUT = 50.0
SOURCE_DIR = Path(os.environ.get(broad.BROAD_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "broad")


def _times(n, fs):
    return np.arange(n) / fs


@pytest.mark.parametrize(
    ("fs_in", "fs_out", "factors"),
    [(FS_IN, 50.0, (7, 40)), (100.0, 50.0, (1, 2)), (1000.0, 50.0, (1, 20)), (50.0, 50.0, (1, 1)),
     (100.0, 30.0, (3, 10))],
)
def test_factors(fs_in, fs_out, factors):
    assert resample.resample_factors(fs_in, fs_out) == factors


@pytest.mark.parametrize(
    ("fs_in", "fs_out", "match"),
    [
        (285.714, 50.0, "ratio of integers"),  # rounded rate: not 7/40 to 1e-9
        (50.0, 100.0, "only downsampling"),
        (0.0, 50.0, "fs_in"),
        (FS_IN, -1.0, "fs_out"),
        (np.nan, 50.0, "fs_in"),
        (FS_IN, np.inf, "fs_out"),
    ],
)
def test_bad_rates(fs_in, fs_out, match):
    with pytest.raises(ValueError, match=match):
        resample.resample_factors(fs_in, fs_out)
    with pytest.raises(ValueError, match=match):
        resample.resample_signal(np.zeros((100, 3)), fs_in, fs_out)


@pytest.mark.parametrize("n", [2, 3, 40, 41, 47, 53240])
def test_lengths_agree(n):
    n_out = (n - 1) * 7 // 40 + 1
    assert resample.n_resampled(n, FS_IN, FS_OUT) == n_out
    times = resample.resampled_times(n, FS_IN, FS_OUT)
    np.testing.assert_allclose(times, np.arange(n_out) / FS_OUT)
    assert times[-1] <= (n - 1) / FS_IN + 1e-12  # inside the input span
    assert resample.resample_signal(np.ones((n, 3)), FS_IN, FS_OUT).shape == (n_out, 3)
    assert resample.resample_quaternion(Q.identity((n,)), FS_IN, FS_OUT).shape == (n_out, 4)
    assert resample.resample_mask(np.ones(n, bool), FS_IN, FS_OUT).shape == (n_out,)


def test_bad_signal_inputs():
    x = np.ones((100, 3))
    x[50, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        resample.resample_signal(x, FS_IN, FS_OUT)
    with pytest.raises(ValueError, match="axis"):
        resample.resample_signal(np.ones((100, 3)), FS_IN, FS_OUT, axis=2)
    with pytest.raises(ValueError, match="at least 2"):
        resample.resample_signal(np.ones((1, 3)), FS_IN, FS_OUT)
    with pytest.raises(ValueError, match="inf"):
        resample.resample_quaternion(np.full((10, 4), np.inf), FS_IN, FS_OUT)
    with pytest.raises(ValueError, match="boolean"):
        resample.resample_mask(np.ones(10), FS_IN, FS_OUT)


def test_constant_rate_survives_exactly_including_edges():
    gyr = np.tile([0.3, -1.2, 2.5], (4000, 1))  # rad/s
    out = resample.resample_signal(gyr, FS_IN, FS_OUT)
    np.testing.assert_allclose(out, np.broadcast_to([0.3, -1.2, 2.5], out.shape), rtol=0, atol=1e-12)


def test_linear_trend_continues_through_the_edges():
    t = _times(2000, FS_IN)
    out = resample.resample_signal(np.stack([1.0 + 0.5 * t, -2.0 * t, np.full_like(t, 9.81)], -1), FS_IN, FS_OUT)
    t_out = _times(out.shape[0], FS_OUT)
    expected = np.stack([1.0 + 0.5 * t_out, -2.0 * t_out, np.full_like(t_out, 9.81)], -1)
    np.testing.assert_allclose(out, expected, atol=1e-4)


@pytest.mark.parametrize("freq", [0.5, 3.0, 10.0, 18.0])
def test_sinusoid_below_the_new_nyquist_keeps_amplitude_and_phase(freq):
    t = _times(6000, FS_IN)
    x = np.sin(2 * np.pi * freq * t + 0.7)[:, None]
    out = resample.resample_signal(x, FS_IN, FS_OUT)[:, 0]
    t_out = _times(out.size, FS_OUT)
    inner = (t_out > 0.5) & (t_out < t[-1] - 0.5)  # away from the edges (filter half length 0.2 s)
    np.testing.assert_allclose(out[inner], np.sin(2 * np.pi * freq * t_out[inner] + 0.7), atol=3e-3)


@pytest.mark.parametrize("freq", [32.0, 40.0, 75.0, 140.0])
def test_sinusoid_above_the_new_nyquist_is_removed(freq):
    t = _times(6000, FS_IN)
    out = resample.resample_signal(np.cos(2 * np.pi * freq * t)[:, None], FS_IN, FS_OUT)[:, 0]
    t_out = _times(out.size, FS_OUT)
    inner = (t_out > 0.5) & (t_out < t[-1] - 0.5)
    assert np.max(np.abs(out[inner])) < 3e-3  # ≥ 50 dB down; plain decimation would alias it at full size


def test_batches_and_axis(rng):
    x = rng.normal(size=(2, 3, 500, 3))
    out = resample.resample_signal(x, FS_IN, FS_OUT)
    assert out.shape == (2, 3, 88, 3)
    np.testing.assert_allclose(out[1, 2], resample.resample_signal(x[1, 2], FS_IN, FS_OUT), atol=1e-12)
    np.testing.assert_allclose(
        resample.resample_signal(np.moveaxis(x, -2, -1), FS_IN, FS_OUT, axis=-1), np.moveaxis(out, -2, -1), atol=1e-12
    )


def _constant_rate_rotation(t, rate=1.3, axis=(0.2, -0.5, 0.8)):
    """q(t) = q0 ⊗ exp(rate·t·axis/2): constant body rate about a fixed axis (a geodesic)."""
    q0 = Q.from_scipy(Rotation.from_euler("xyz", [0.4, -0.3, 2.0]))
    return Q.multiply(q0, Q.from_axis_angle(np.asarray(axis, float), rate * np.asarray(t)))


def test_constant_rate_rotation_is_resampled_exactly():
    t = _times(3000, FS_IN)
    quat = _constant_rate_rotation(t)
    quat[1::2] *= -1.0  # q and -q alternate: the shorter arc must still be taken
    out = resample.resample_quaternion(quat, FS_IN, FS_OUT)
    expected = _constant_rate_rotation(_times(out.shape[0], FS_OUT))
    assert np.max(Q.angle_between(out, expected)) < 1e-9
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    # on common sample times (every 7th output is input 40·k/7) it returns the input itself
    np.testing.assert_allclose(out[::7], quat[::40], rtol=0, atol=1e-15)


def test_quaternion_batches():
    t = _times(400, FS_IN)
    quat = np.stack([_constant_rate_rotation(t, rate=r) for r in (0.5, 4.0)])
    out = resample.resample_quaternion(quat, FS_IN, FS_OUT)
    assert out.shape == (2, 70, 4)
    np.testing.assert_array_equal(out[1], resample.resample_quaternion(quat[1], FS_IN, FS_OUT))


@pytest.mark.parametrize(("start", "stop"), [(0, 30), (100, 101), (100, 160), (333, 400), (2950, 3000)])
def test_nan_gaps_stay_nan_and_spread_at_most_one_output_sample(start, stop):
    n = 3000
    quat = _constant_rate_rotation(_times(n, FS_IN))
    quat[start:stop] = np.nan
    out = resample.resample_quaternion(quat, FS_IN, FS_OUT)
    t_out = _times(out.shape[0], FS_OUT)
    nan_rows = np.isnan(out).any(axis=-1)
    assert np.array_equal(nan_rows, np.isnan(out).all(axis=-1))
    # NaN exactly where an output time is closer than one input step to a lost sample
    touching = (t_out > (start - 1) / FS_IN) & (t_out < stop / FS_IN)
    np.testing.assert_array_equal(nan_rows, touching)
    inside = (t_out >= start / FS_IN) & (t_out <= (stop - 1) / FS_IN)
    assert np.all(nan_rows[inside])
    assert nan_rows.sum() <= inside.sum() + 2  # at most one extra output sample per side
    expected = _constant_rate_rotation(t_out[~nan_rows])
    assert np.max(Q.angle_between(out[~nan_rows], expected)) < 1e-9


def test_mask_takes_the_nearest_input_sample(rng):
    mask = rng.random((2, 700)) < 0.5
    out = resample.resample_mask(mask, FS_IN, FS_OUT)
    t_in, t_out = _times(700, FS_IN), _times(out.shape[-1], FS_OUT)
    nearest = np.argmin(np.abs(t_out[:, None] - t_in[None, :]), axis=1)
    np.testing.assert_array_equal(out, mask[:, nearest])


def test_resample_broad_keeps_everything_on_one_grid():
    if not (SOURCE_DIR / "02_undisturbed_slow_rotation_B.mat").exists():
        pytest.skip(f"BROAD files not found in {SOURCE_DIR}")
    trial = broad.load_broad(2, SOURCE_DIR, download=False)
    low = resample.resample_broad(trial)
    n_out = 9317
    assert isinstance(low, broad.BroadTrial) and low.name == trial.name and low.fs == 50.0
    np.testing.assert_allclose(low.time_s, np.arange(n_out) / 50.0)
    for name, width in (("gyr", 3), ("acc", 3), ("mag", 3), ("quat_ref", 4)):
        assert getattr(low, name).shape == (n_out, width)
    assert low.movement.shape == (n_out,)
    assert abs(low.movement.sum() - trial.movement.sum() * 7 / 40) <= 2
    # reference gaps stay gaps, barely wider than at the input rate
    lost, lost_in = ~low.reference_valid, ~trial.reference_valid
    np.testing.assert_array_equal(lost[::7], lost_in[::40])
    n_runs = np.count_nonzero(np.diff(lost_in.astype(int)) == 1) + int(lost_in[0])
    assert lost_in.sum() * 7 / 40 - n_runs <= lost.sum() <= lost_in.sum() * 7 / 40 + 3 * n_runs
    np.testing.assert_allclose(low.quat_ref[::7][~lost[::7]], trial.quat_ref[::40][~lost[::7]], rtol=0, atol=1e-15)
    assert "Resampled from 285.714286 Hz to 50 Hz" in low.info
    with pytest.raises(ValueError, match="BroadTrial"):
        resample.resample_broad(trial.gyr)
