"""Recordings implausible as a whole (issue 23): one check, the likely cause named."""

import numpy as np
import pytest

from wsnlib.frames import STANDARD_GRAVITY
from wsnlib.plausibility import check_imu_plausible


@pytest.fixture
def recording(rng):
    """Two seconds of a body sensor at 50 Hz in the documented units: rad/s, m/s², µT."""
    t = np.arange(100) / 50.0
    gyr = np.stack([np.sin(3 * t), np.cos(2 * t), 0.5 * np.ones_like(t)], axis=-1)
    gyr = gyr + 0.01 * rng.standard_normal((100, 3))
    acc = np.array([0.3, -0.2, STANDARD_GRAVITY]) + 0.5 * rng.standard_normal((100, 3))
    mag = np.array([0.0, 25.0, -38.0]) + 0.3 * rng.standard_normal((100, 3))
    return gyr, acc, mag


def test_documented_units_pass(recording):
    gyr, acc, mag = recording
    check_imu_plausible(gyr, acc, mag, gravity=STANDARD_GRAVITY)
    check_imu_plausible(gyr[None], acc[None] / STANDARD_GRAVITY, mag[None] / 46.0)  # normalised, no gravity: fine


def test_gyro_in_degrees_per_second(recording):
    gyr, acc, mag = recording
    with pytest.raises(ValueError, match=r"madgwick: gyr looks like deg/s.*np\.radians"):
        check_imu_plausible(np.degrees(gyr) * 10, acc, mag, where="madgwick")


def test_acc_and_mag_swapped(recording):
    gyr, acc, mag = recording
    with pytest.raises(ValueError, match="acc and mag look swapped"):
        check_imu_plausible(gyr, mag, acc)


@pytest.mark.parametrize(("scale", "hint"), [(1 / STANDARD_GRAVITY, "in g"), (1000.0, "other units")])
def test_acc_scale_against_the_filters_gravity(recording, scale, hint):
    gyr, acc, mag = recording
    with pytest.raises(ValueError, match=rf"gravity of 9\.807 m/s² is expected: .*{hint}"):
        check_imu_plausible(gyr, acc * scale, mag, gravity=STANDARD_GRAVITY)
    with pytest.raises(ValueError, match="gravity of 1.62 m/s² is expected"):
        check_imu_plausible(gyr, acc, mag, gravity=1.62)


def test_only_received_samples_count(recording):
    gyr, acc, mag = recording
    garbage = gyr.copy()
    garbage[:40] = 1e3  # lost samples may hold anything
    received = np.arange(100) >= 40
    check_imu_plausible(garbage, acc, mag, received)
    with pytest.raises(ValueError, match="deg/s"):
        check_imu_plausible(garbage, acc, mag, ~received)


def test_every_problem_as_text_and_the_check_raises_the_first(recording):
    from wsnlib.plausibility import imu_unit_problems

    gyr, acc, mag = recording
    assert imu_unit_problems(gyr, acc, mag, gravity=STANDARD_GRAVITY) == []
    problems = imu_unit_problems(np.degrees(gyr) * 10, acc / STANDARD_GRAVITY, mag, gravity=STANDARD_GRAVITY)
    assert len(problems) == 2
    assert problems[0].startswith("gyr looks like deg/s") and problems[1].startswith("acc's median norm is 0.98")
    with pytest.raises(ValueError) as raised:
        check_imu_plausible(np.degrees(gyr) * 10, acc / STANDARD_GRAVITY, mag, gravity=STANDARD_GRAVITY, where="f")
    assert str(raised.value) == "f: " + problems[0]
