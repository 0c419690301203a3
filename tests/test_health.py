"""The recording health check (issue 24) against known truth: synthetic recordings with a known
rate, jitter, share of repeated samples, marker swaps and field disturbance."""

import re

import numpy as np
import pytest
from _recordings import FS, turning_recording

from wsnlib import quaternion as Q
from wsnlib.frames import STANDARD_GRAVITY
from wsnlib.io.health import recording_health
from wsnlib.io.recording import Recording
from wsnlib.plausibility import check_imu_plausible


@pytest.fixture(scope="module")
def clean():
    """60 s of a turning sensor at 50 Hz with noise and a small gyro bias: ``time, gyr, acc, mag, quat``
    (read-only: a test copies what it changes)."""
    arrays = (np.arange(3000) / FS, *turning_recording(3000, seed=3, noise=0.01))
    for arr in arrays:
        arr.setflags(write=False)
    return arrays


def test_a_clean_recording_has_no_finding(clean):
    time, gyr, acc, mag, quat = clean
    health = recording_health(time, gyr, acc, mag, quat, fs=FS)
    assert health.findings == ()
    assert str(health) == "Recording health: no problem found."
    row = health.table.iloc[0]
    assert row.fs_effective_hz == pytest.approx(FS, rel=1e-9) and row.step_jitter < 1e-6
    assert row.gap_share == 0.0 and row.repeated_share == 0.0 and row.ref_coverage == 1.0
    assert row.ref_gyro_diff_median_rad_s < 0.06 and row.ref_jumps == 0
    assert row.mag_norm_spread < 0.1 and row.mag_disturbed_share == 0.0
    assert row.units_problem == "" and row.mag_problem == "" and row.implausible_share == 0.0


def test_jittered_stamps_give_the_true_rate_and_the_jitter(clean, rng):
    _, gyr, acc, mag, _ = clean
    true_fs, half_width = 47.3, 0.2  # stamps jitter uniformly by ±0.2 steps around k / 47.3 Hz
    time = (np.arange(3000) + rng.uniform(-half_width, half_width, 3000)) / true_fs
    health = recording_health(time, gyr, acc, mag, fs=FS)
    row = health.table.iloc[0]
    assert row.fs_effective_hz == pytest.approx(true_fs, rel=0.005)
    # a step is 1 + (u₂ − u₁): triangular on ±2a, median |·| = 2a(1 − 1/√2), times 1.4826
    assert row.step_jitter == pytest.approx(1.4826 * 2 * half_width * (1 - 2**-0.5), rel=0.1)
    assert row.fs_nominal_hz == FS
    text = " ".join(health.findings)
    assert re.search(r"run at 47\.(29|30)\d* Hz \(median step\), not the nominal 50 Hz", text)
    assert "jitters by" in text and "wsnlib.io.resample_timestamps" in text


def test_missing_rows_and_repeated_stamps_are_counted(clean):
    time, gyr, acc, mag, _ = clean
    keep = np.ones(3000, dtype=bool)
    keep[[100, 700, 1500, 2000, 2900]] = False  # five missing rows: five steps of two
    time, gyr, acc, mag = time[keep], gyr[keep], acc[keep], mag[keep]
    time[50] = time[49]  # one time stamp repeated: a step of zero, then one of two
    health = recording_health(time, gyr, acc, mag, fs=FS)
    row = health.table.iloc[0]
    assert row.gap_share == 6 / (time.size - 1) and row.nonincreasing_share == 1 / (time.size - 1)
    assert row.fs_effective_hz == pytest.approx(FS)
    text = " ".join(health.findings)
    assert "time steps are gaps" in text and "do not advance" in text


def test_sample_and_hold_repeats_are_reported_within_one_percent(clean, rng):
    time, gyr, acc, mag, _ = clean
    gyr, acc = gyr.copy(), acc.copy()
    held = np.sort(rng.choice(np.arange(1, 2999), size=900, replace=False))  # 30 % of the 2999 steps
    for k in held:  # in time order, so a run holds the last new reading
        gyr[k], acc[k] = gyr[k - 1], acc[k - 1]
    mag = mag.copy()
    mag[1::2] = mag[::2]  # a magnetometer at half the rate, held: no repeated inertial sample
    gyr[2999] = gyr[2998]  # the gyro alone held: acc is new, so no repeat either
    health = recording_health(time, gyr, acc, mag, fs=FS)
    row = health.table.iloc[0]
    assert row.repeated_share == pytest.approx(0.30, abs=0.01)
    assert row.repeated_share == 900 / 2999  # exactly the held samples
    assert row.new_data_rate_hz == pytest.approx(0.70 * FS, abs=0.5)
    assert any("30.0% of the samples repeat the previous gyr and acc" in f for f in health.findings)


@pytest.mark.parametrize("flip_deg", [180.0, 30.0])
def test_a_marker_swap_segment_is_detected(clean, flip_deg):
    time, gyr, acc, mag, quat = clean
    swapped = quat.copy()
    flip = Q.from_axis_angle([0.0, 0.0, 1.0], np.radians(flip_deg))  # the body frame assigned to other markers
    swapped[1000:1200] = Q.multiply(quat[1000:1200], flip)
    health = recording_health(time, gyr, acc, mag, swapped, fs=FS)
    row = health.table.iloc[0]
    assert row.ref_jumps == 2 and row.ref_first_jump_s == time[999]
    assert row.ref_jump_share == pytest.approx(2 / 2999)
    assert any("the reference jumps 2 time(s)" in f and "t = 19.98, 23.98 s" in f for f in health.findings)


def _swing(fs: float, n: int, rate: float = 8.0, freq: float = 1.5):
    """``time, gyr, acc, mag, quat`` of a swing about a fixed body axis, exact at every sample: rate
    ``rate·sin(2π freq t)`` rad/s, the orientation its integral."""
    time = np.arange(n) / fs
    axis = np.array([0.2, 0.9, 0.39]) / np.linalg.norm([0.2, 0.9, 0.39])
    omega = 2 * np.pi * freq
    gyr = rate * np.sin(omega * time)[:, None] * axis
    quat = Q.from_axis_angle(axis, rate / omega * (1.0 - np.cos(omega * time)))
    acc = Q.rotate_inverse(quat, [0.0, 0.0, STANDARD_GRAVITY])
    mag = Q.rotate_inverse(quat, [0.0, 20.0, -40.0])
    return time, gyr, acc, mag, quat


def _with_noise(quat, sd_deg: float, rng):
    """``quat`` turned by a random body-frame rotation per sample, each axis N(0, sd_deg)."""
    return Q.multiply(quat, Q.from_rotation_vector(rng.normal(0.0, np.radians(sd_deg), quat.shape[:-1] + (3,))))


def test_a_fast_clean_reference_is_no_jump_and_a_missing_stretch_is_no_jump():
    time, gyr, acc, mag, quat = _swing(FS, 1500)  # up to 8 rad/s: 9° per step
    quat[300:400] = np.nan  # markers lost; the rows on either side are 100 steps apart
    health = recording_health(time, gyr, acc, mag, quat, fs=FS)
    row = health.table.iloc[0]
    assert row.ref_jumps == 0 and row.ref_coverage == pytest.approx(1400 / 1500)
    assert row.ref_gyro_diff_median_rad_s < 0.05
    assert health.findings == ()


def test_a_noisy_reference_at_rest_is_no_jump(clean, rng):
    """Optical noise of 0.5° per axis turns the reference by up to ~4° per step while the gyro reads ~0."""
    time, gyr, acc, mag, quat = clean
    still = np.broadcast_to(quat[0], quat.shape)
    noisy = _with_noise(still, 0.5, rng)
    health = recording_health(time, 0.01 * rng.standard_normal(gyr.shape), Q.rotate_inverse(still, [0, 0, 9.81]),
                              Q.rotate_inverse(still, [0.0, 20.0, -40.0]), noisy, fs=FS)
    assert health.table.iloc[0].ref_jumps == 0


def test_the_agreement_does_not_grow_with_the_reference_rate(rng):
    """At 500 Hz a reference noise of 0.05° per axis differenced over one step would read ≈ 1 rad/s;
    over the 20 ms window it is about what it is at 50 Hz."""
    readings = {}
    for fs in (50.0, 500.0):
        time, gyr, acc, mag, quat = _swing(fs, int(30 * fs), rate=2.0, freq=0.5)
        health = recording_health(time, gyr, acc, mag, _with_noise(quat, 0.05, rng), fs=fs)
        readings[fs] = health.table.iloc[0].ref_gyro_diff_median_rad_s
        assert health.findings == ()
    assert readings[500.0] == pytest.approx(readings[50.0], rel=0.3) and readings[500.0] < 0.15


def test_a_reference_of_another_node_disagrees_with_the_gyro(clean):
    time, gyr, acc, mag, quat = clean
    other = turning_recording(3000, seed=11)[3]
    health = recording_health(time, gyr, acc, mag, other, fs=FS)
    assert health.table.iloc[0].ref_gyro_diff_median_rad_s > 0.5
    assert any("differs from the gyroscope's" in f for f in health.findings)


def test_a_slowly_scaled_magnetometer_gives_its_range(clean):
    time, gyr, acc, mag, quat = clean
    field = np.linalg.norm(turning_recording(3000, seed=3)[2], axis=-1).mean()  # the exact field's norm (µT)
    factor = 0.8 + 0.4 * np.sin(2 * np.pi * time / 20.0)  # 0.4 … 1.2 over three whole periods
    health = recording_health(time, gyr, acc, mag * factor[:, None], fs=FS)
    row = health.table.iloc[0]
    # percentiles of a sinusoid over whole periods: 0.8 ∓ 0.4·sin(0.45π)
    assert row.mag_norm_p5_uT / field == pytest.approx(0.8 - 0.4 * np.sin(0.45 * np.pi), abs=0.005)
    assert row.mag_norm_p95_uT / field == pytest.approx(0.8 + 0.4 * np.sin(0.45 * np.pi), abs=0.005)
    assert row.mag_norm_p5_uT / field == pytest.approx(0.4, abs=0.01)
    assert row.mag_norm_p95_uT / field == pytest.approx(1.2, abs=0.01)
    assert row.mag_norm_median_uT / field == pytest.approx(0.8, abs=0.005)
    # off the median 0.8 by more than 10 %: |sin| > 0.2
    assert row.mag_disturbed_share == pytest.approx(1 - 2 / np.pi * np.arcsin(0.2), abs=0.01)
    assert any("the magnetic field's norm ranges" in f for f in health.findings)


def test_units_findings_are_the_filters_own_checks(clean):
    time, gyr, acc, mag, quat = clean
    health = recording_health(time, np.degrees(gyr), acc / STANDARD_GRAVITY, mag, fs=FS)
    row = health.table.iloc[0]
    with pytest.raises(ValueError) as raised:
        check_imu_plausible(np.degrees(gyr), acc, mag)
    assert str(raised.value) in health.findings and str(raised.value) in row.units_problem
    assert "the accelerometer in g? multiply it by 9.80665" in row.units_problem
    swapped = recording_health(time, gyr, mag, acc)
    assert "acc and mag look swapped" in swapped.table.iloc[0].units_problem


def test_single_implausible_samples_and_a_frozen_magnetometer(clean):
    time, gyr, acc, mag, _ = clean
    gyr = gyr.copy()
    gyr[[100, 200, 300]] = 1e6
    frozen = np.broadcast_to(mag[0], mag.shape)
    health = recording_health(time, gyr, acc, frozen)
    row = health.table.iloc[0]
    assert row.implausible_share == 3 / 3000
    assert row.mag_problem.startswith("mag is frozen")
    text = " ".join(health.findings)
    assert "0.10% of the samples hold a reading no body-worn sensor gives" in text and "mag is frozen" in text


def test_nodes_of_a_recording_are_checked_one_by_one(clean):
    time, gyr, acc, mag, quat = clean
    rec = Recording(fs=FS, time_s=time, nodes=("wrist", "elbow"), gyr=np.stack([gyr, np.degrees(gyr)]),
                    acc=np.stack([acc, acc]), mag=np.stack([mag, mag]), quat_true=np.stack([quat, quat]))
    health = recording_health(rec.time_s, rec.gyr, rec.acc, rec.mag, rec.quat_true, fs=rec.fs, names=rec.nodes)
    assert list(health.table.index) == ["wrist", "elbow"]
    assert health.table.loc["wrist", "units_problem"] == ""
    assert health.table.loc["elbow", "units_problem"].startswith("gyr looks like deg/s")
    assert all(f.startswith("elbow: ") for f in health.findings) and len(health.findings) >= 2
    assert str(health).splitlines()[0] == f"Recording health: {len(health.findings)} finding(s)"
    batch = recording_health(time, gyr[None, None], acc, mag[None])  # leading shapes broadcast: (1, 1)
    assert list(batch.table.index) == [0]


@pytest.mark.parametrize(("change", "message"), [
    (lambda a: a | {"gyr": a["gyr"][:, :2]}, r"gyr must have shape \(\.\.\., 3\)"),
    (lambda a: a | {"acc": a["acc"][:-1]}, "acc has 2999 samples"),
    (lambda a: a | {"time_s": a["time_s"][:-1]}, r"time_s must have shape \(\.\.\., 3000\)"),
    (lambda a: a | {"time_s": np.where(np.arange(3000) == 5, np.nan, a["time_s"])}, "time_s contains NaN"),
    (lambda a: a | {"time_s": np.zeros(3000)}, "time_s never increases"),
    (lambda a: a | {"gyr": np.where(np.arange(3000)[:, None] == 7, np.inf, a["gyr"])}, "gyr contains NaN or inf"),
    (lambda a: a | {"fs": 0.0}, "fs must be a positive"),
    (lambda a: a | {"quat_ref": a["quat_ref"][:-1]}, r"quat_ref must have shape \(\.\.\., 3000, 4\)"),
    (lambda a: a | {"quat_ref": a["quat_ref"][:, :3]}, r"quat_ref must have shape \(\.\.\., 4\)"),
    (lambda a: a | {k: a[k][:1] for k in ("time_s", "gyr", "acc", "mag", "quat_ref")}, "at least 2 samples"),
    (lambda a: a | {"gyr": np.stack([a["gyr"]] * 2), "acc": np.stack([a["acc"]] * 3)}, "do not broadcast"),
    (lambda a: a | {"names": ("wrist", "elbow")}, "names has 2 labels but the signals have 1"),
    (lambda a: a | {"names": "wrist"}, "names must be a sequence"),
])
def test_bad_inputs_are_refused_by_name(clean, change, message):
    time, gyr, acc, mag, quat = clean
    args = change({"time_s": time, "gyr": gyr, "acc": acc, "mag": mag, "quat_ref": quat, "fs": FS})
    with pytest.raises(ValueError, match=message):
        recording_health(**args)
