"""The exercise checkers accept the library's own functions and reject plausible mistakes."""

import numpy as np
import pytest

from wsnlib import exercises, quaternion, tuning
from wsnlib.orientation import madgwick_step, slerp_weight, triad


def _rng():
    return np.random.default_rng(12)


# Correct answers: thin wrappers around the library (what a right student function returns).
CORRECT = {
    exercises.check_madgwick_step: lambda q, g, a, m, dt, beta: madgwick_step(q, g, a, m, dt, beta),
    exercises.check_slerp_weight: lambda lam, rho, tau: rho / (lam / tau + rho),
    exercises.check_slerp: lambda qa, qb, mu: quaternion.slerp(qa, qb, mu),
    exercises.check_knee_point: lambda a, b: tuning.knee_point(a, b),
    exercises.check_gyro_interpolation: lambda gyr, rx: exercises._reference_gyro_interpolation(gyr, rx),
    exercises.check_triad: lambda acc, mag: triad(acc, mag),
}


@pytest.mark.parametrize("checker", list(CORRECT), ids=lambda c: c.__name__)
def test_a_correct_function_passes(checker):
    report = checker(CORRECT[checker], rng=_rng(), n_cases=40)
    assert report.n_cases == 40
    assert report.max_abs_difference <= 1e-9
    assert "passed" in str(report)


def test_negated_quaternions_pass_since_they_are_the_same_rotation():
    exercises.check_triad(lambda acc, mag: -triad(acc, mag), rng=_rng(), n_cases=20)
    exercises.check_slerp(lambda qa, qb, mu: -quaternion.slerp(qa, qb, mu), rng=_rng(), n_cases=20)


def _gyro_only_forgot_half(q, g, a, m, dt, beta):
    qn = np.asarray(madgwick_step(q, g, a, m, dt, beta))
    return qn if beta else quaternion.multiply(q, quaternion.from_rotation_vector(2.0 * np.asarray(g) * dt))


def _slerp_long_arc(qa, qb, mu):
    omega = np.arccos(np.clip(np.dot(qa, qb), -1, 1))
    if omega < 1e-12:
        return qa
    return (np.sin((1 - mu) * omega) * qa + np.sin(mu * omega) * qb) / np.sin(omega)


def _knee_over_all_points(a, b):
    scaled = [(c - c.min()) / (np.ptp(c) or 1.0) for c in (a, b)]
    return int(np.argmin(np.hypot(*scaled)))


def _interp_including_lost(gyr, rx):
    return gyr  # keeps the garbage stored on lost samples


def _triad_ned(acc, mag):
    q = triad(acc, mag)
    return quaternion.multiply(quaternion.from_rotation_vector([0.0, 0.0, np.pi / 2]), q)


WRONG = {
    exercises.check_madgwick_step: _gyro_only_forgot_half,
    exercises.check_slerp_weight: lambda lam, rho, tau: rho / (lam + rho),       # eq. (5): tau dropped
    exercises.check_slerp: _slerp_long_arc,
    exercises.check_knee_point: _knee_over_all_points,
    exercises.check_gyro_interpolation: _interp_including_lost,
    exercises.check_triad: _triad_ned,
}


@pytest.mark.parametrize("checker", list(WRONG), ids=lambda c: c.__name__)
def test_a_plausible_mistake_fails_with_a_message(checker):
    with pytest.raises(AssertionError, match="expected|returned"):
        checker(WRONG[checker], rng=_rng())


def test_wrong_shape_and_non_finite_output_are_reported():
    with pytest.raises(AssertionError, match="shape"):
        exercises.check_triad(lambda acc, mag: np.zeros(3), rng=_rng())
    with pytest.raises(AssertionError, match="non-finite"):
        exercises.check_slerp_weight(lambda lam, rho, tau: np.nan, rng=_rng())


@pytest.mark.parametrize("kwargs, name", [
    (dict(student_function=1, rng=np.random.default_rng(0)), "student_function"),
    (dict(student_function=slerp_weight, rng=0), "rng"),
    (dict(student_function=slerp_weight, rng=np.random.default_rng(0), n_cases=0), "n_cases"),
    (dict(student_function=slerp_weight, rng=np.random.default_rng(0), atol=-1.0), "atol"),
])
def test_bad_arguments_raise_value_errors_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        exercises.check_slerp_weight(**kwargs)


def test_the_reference_gyro_interpolation_is_linear_inside_a_gap():
    gyr = np.zeros((5, 3))
    gyr[0], gyr[4] = 1.0, 5.0
    received = np.array([True, False, False, False, True])
    filled = exercises._reference_gyro_interpolation(gyr, received)
    np.testing.assert_allclose(filled[:, 0], [1, 2, 3, 4, 5])
