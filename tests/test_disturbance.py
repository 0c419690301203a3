"""Tests of the simulator's magnetic disturbance and acceleration-rich motion (wsnlib.sim.disturbance) and
of its calibration against BROAD (wsnlib.sim.triad_calibration)."""

import dataclasses
import os
from pathlib import Path

import _calibration as C
import numpy as np
import pytest

from wsnlib import frames, paths
from wsnlib import quaternion as Q
from wsnlib.io import broad
from wsnlib.loss import LossProfile
from wsnlib.sim import disturbance as D
from wsnlib.sim import triad_calibration as TC
from wsnlib.sim.arm import arm_kinematics, movement_set
from wsnlib.sim.imu import ImuSpec, simulate_imu
from wsnlib.sim.trials import arm_loss_trials

BROAD_DIR = Path(os.environ.get(broad.BROAD_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "broad")


@pytest.fixture(scope="module")
def truth():
    return arm_kinematics(movement_set()["reach and flex"])


def test_off_is_bit_identical_to_no_disturbance(truth):
    for spec in (ImuSpec(), ImuSpec.noise_free()):
        plain = simulate_imu(truth, spec, rng=np.random.default_rng(5), n_runs=3)
        off = simulate_imu(truth, spec, rng=np.random.default_rng(5), n_runs=3, disturbance=D.Disturbance())
        for a, b in zip(plain, off, strict=True):
            assert np.array_equal(a, b)


def test_trials_without_disturbance_unchanged():
    movements = movement_set()
    profiles = [LossProfile.burst(80 / 50.0, 4), LossProfile.gilbert_elliott(0.1)]
    plain = arm_loss_trials(movements, profiles, 2, rng=np.random.default_rng(7))
    off = arm_loss_trials(movements, profiles, 2, rng=np.random.default_rng(7), disturbance=None)
    for name in ("gyr", "acc", "mag", "received"):
        assert np.array_equal(getattr(plain, name), getattr(off, name))
    disturbed = arm_loss_trials(movements, profiles, 2, rng=np.random.default_rng(7), disturbance=D.DISTURBED_BROAD)
    first = slice(0, 4)  # the first movement's trials: same sensor noise, drawn before the disturbance
    assert np.array_equal(plain.gyr[first], disturbed.gyr[first])
    assert not np.allclose(plain.acc[first], disturbed.acc[first])
    assert not np.allclose(plain.mag[first], disturbed.mag[first])


def test_same_seed_same_signals_other_seed_other(truth):
    runs = [simulate_imu(truth, rng=np.random.default_rng(seed), n_runs=2, disturbance=D.DISTURBED_BROAD)
            for seed in (3, 3, 4)]
    for a, b in zip(runs[0], runs[1], strict=True):
        assert np.array_equal(a, b)
    assert not np.array_equal(runs[0].acc, runs[2].acc)
    assert not np.array_equal(runs[0].mag, runs[2].mag)


def test_translation_only_changes_specific_force_by_rotated_acceleration(truth):
    spec = ImuSpec.noise_free()
    setting = D.Disturbance(translation_acc_rms_m_s2=3.0)
    clean = simulate_imu(truth, spec, rng=np.random.default_rng(1), n_runs=2)
    moved = simulate_imu(truth, spec, rng=np.random.default_rng(1), n_runs=2, disturbance=setting)
    assert np.array_equal(clean.gyr, moved.gyr)
    assert np.array_equal(clean.mag, moved.mag)
    added = Q.rotate(truth.quat, moved.acc - clean.acc)               # back to the earth frame
    assert np.allclose(added[:, 0], added[:, 1], atol=1e-9)          # the same translation for both nodes
    rms = np.sqrt(np.mean(np.sum(added[:, 0] ** 2, axis=-1), axis=-1))
    assert np.all(rms > 0.05) and np.all(rms < 60.0)


def test_translation_motion_is_scaled_and_integrates():
    fs, n = 50.0, 2000
    acc, pos = D.translation_motion(n, fs, np.array([1.0, 4.0]), (0.5, 4.0), rng=np.random.default_rng(0))
    assert acc.shape == pos.shape == (2, n, 3)
    assert np.allclose(np.sqrt(np.mean(np.sum(acc**2, axis=-1), axis=-1)), [1.0, 4.0])
    second_difference = (pos[:, 2:] - 2 * pos[:, 1:-1] + pos[:, :-2]) * fs**2
    assert np.allclose(second_difference, acc[:, 1:-1], atol=0.05 * 4.0)
    spectrum = np.abs(np.fft.rfft(acc, axis=1))
    freq = np.fft.rfftfreq(n, 1 / fs)
    assert np.all(spectrum[:, (freq < 0.5) | (freq > 4.0)] < 1e-9)


def test_hard_iron_is_constant_in_body_frame_and_soft_iron_scales(truth):
    spec = ImuSpec.noise_free()
    clean = simulate_imu(truth, spec, rng=np.random.default_rng(2))
    hard = simulate_imu(truth, spec, rng=np.random.default_rng(2), disturbance=D.Disturbance(hard_iron_ut=10.0))
    offset = hard.mag - clean.mag
    assert np.allclose(offset, offset[:, :1], atol=1e-9)
    assert np.all(np.linalg.norm(offset[:, 0], axis=-1) == pytest.approx(10.0))
    soft = simulate_imu(truth, spec, rng=np.random.default_rng(2), disturbance=D.Disturbance(soft_iron_std=0.05))
    ratio = np.linalg.norm(soft.mag, axis=-1) / np.linalg.norm(clean.mag, axis=-1)
    assert 0.7 < ratio.min() < 1.0 < ratio.max() < 1.3


@pytest.mark.parametrize(("direction", "expected"), [((0.0, 0.0, 1.0), (0.0, 0.0, 2.0)),
                                                     ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0))])
def test_dipole_field_on_and_off_axis(direction, expected):
    r = 0.2
    field = D.dipole_field_ut([0.0, 0.0, 1.0], np.array(direction) * r)
    assert np.allclose(field, np.array(expected) * 0.1 / r**3)


def test_passing_dipole_is_time_local(truth):
    spec = ImuSpec.noise_free()
    setting = D.Disturbance(dipole_moment_am2=2.0, dipole_distance_m=(0.1, 0.15), dipole_speed_m_s=1.0)
    clean = simulate_imu(truth, spec, rng=np.random.default_rng(3), n_runs=4)
    passed = simulate_imu(truth, spec, rng=np.random.default_rng(3), n_runs=4, disturbance=setting)
    change = np.linalg.norm(passed.mag - clean.mag, axis=-1)             # (runs, nodes, T)
    assert change.max() > 20.0                                           # strong when close
    assert np.all(np.median(change, axis=-1) < 0.2 * change.max(axis=-1))  # small most of the time


def test_calibrated_simulator_matches_broad_within_tolerance():
    for seed in (3, 4):
        for group in TC.BROAD_GROUPS:
            stats = TC.error_statistics(TC.simulated_triad_errors(
                D.BROAD_CALIBRATED[group], rng=np.random.default_rng(seed), n_repetitions=32)["total"])
            for stat in ("median", "p90"):
                target = TC.BROAD_TRIAD_ERROR_DEG[group]["total"][stat]
                assert abs(stats[stat] / target - 1.0) < C.CALIBRATION_TOLERANCE, (seed, group, stat, stats)
    clean = TC.error_statistics(TC.simulated_triad_errors(None, rng=np.random.default_rng(3), n_repetitions=4)["total"])
    assert clean["p90"] < 0.25 * TC.BROAD_TRIAD_ERROR_DEG["undisturbed"]["total"]["median"]


def test_calibrated_point_beats_its_grid_neighbours():
    grid = {"translation_acc_rms_m_s2": [1.3, 1.4, 1.6], "translation_acc_log_sd": [1.5], "magnetic_scale": [2.0]}
    result = C.calibrate_disturbance("undisturbed", grid, n_repetitions=32)
    assert result.loc[0, "translation_acc_rms_m_s2"] == D.UNDISTURBED_BROAD.translation_acc_rms_m_s2
    assert list(result["score"]) == sorted(result["score"])


def test_calibration_table_layout():
    table = TC.triad_calibration_table(n_repetitions=2)
    assert list(table.index) == [(g, k) for g in TC.BROAD_GROUPS for k in TC.ERROR_KINDS]
    assert table.notna().all().all()
    assert table.loc[("undisturbed", "total"), "BROAD median (°)"] == TC.BROAD_TRIAD_ERROR_DEG["undisturbed"][
        "total"]["median"]


@pytest.mark.parametrize(("changes", "match"), [({"translation_acc_rms_m_s2": -1.0}, "translation_acc_rms_m_s2"),
                                                ({"translation_band_hz": (4.0, 0.5)}, "translation_band_hz"),
                                                ({"dipole_distance_m": (0.01, 0.5)}, "dipole_distance_m"),
                                                ({"dipole_speed_m_s": 0.0}, "dipole_speed_m_s")])
def test_bad_settings_raise(changes, match):
    with pytest.raises(ValueError, match=match):
        dataclasses.replace(D.Disturbance(), **changes)


def test_bad_arguments_raise(truth):
    with pytest.raises(ValueError, match="disturbance"):
        simulate_imu(truth, rng=np.random.default_rng(0), disturbance={"hard_iron_ut": 3})
    with pytest.raises(ValueError, match="group"):
        C.calibrate_disturbance("windy", {"magnetic_scale": [1.0]})
    with pytest.raises(ValueError, match="grid"):
        C.calibrate_disturbance("disturbed", {"wind_speed": [1.0]})
    with pytest.raises(ValueError, match="band_hz"):
        D.translation_motion(10, 50.0, 1.0, (21.0, 24.0), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="trial_name"):
        C.broad_group("01_slow_rotation")
    assert C.broad_group("33_disturbed_attached_magnet_2cm") == "disturbed"


def test_gravity_reference_unchanged():
    # The translation is added to the specific force, gravity stays g up (guards the hook's frame).
    assert np.allclose(frames.gravity_specific_force_enu(frames.STANDARD_GRAVITY), [0, 0, frames.STANDARD_GRAVITY])


@pytest.mark.skipif(not all((BROAD_DIR / f"{name}.mat").exists() for name in C.BROAD_CALIBRATION_TRIALS),
                    reason=f"the 17 BROAD trials are not all in {BROAD_DIR}")
def test_recorded_broad_statistics_match_the_files():
    errors = C.broad_triad_errors(C.BROAD_CALIBRATION_TRIALS, data_dir=BROAD_DIR)
    stats = C.broad_triad_statistics(errors)
    for group in TC.BROAD_GROUPS:
        for kind in TC.ERROR_KINDS:
            for stat in ("median", "p90"):
                assert stats[group][kind][stat] == pytest.approx(TC.BROAD_TRIAD_ERROR_DEG[group][kind][stat], abs=0.006)
