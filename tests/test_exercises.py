"""The exercise checkers accept the library's own functions and reject plausible mistakes."""

import numpy as np
import pytest

from wsnlib import exercises, quaternion, tuning
from wsnlib.exercises.orientation import _reference_gyro_interpolation
from wsnlib.orientation import madgwick_step, slerp_weight, triad
from wsnlib.radio import SHEPARD_EPS


def _rng():
    return np.random.default_rng(12)


# Correct answers: thin wrappers around the library (what a right student function returns).
CORRECT = {
    exercises.check_madgwick_step: lambda q, g, a, m, dt, beta: madgwick_step(q, g, a, m, dt, beta),
    exercises.check_slerp_weight: lambda lam, rho, tau: rho / (lam / tau + rho),
    exercises.check_slerp: lambda qa, qb, mu: quaternion.slerp(qa, qb, mu),
    exercises.check_knee_point: lambda a, b: tuning.knee_point(a, b),
    exercises.check_gyro_interpolation: lambda gyr, rx: _reference_gyro_interpolation(gyr, rx),
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
    filled = _reference_gyro_interpolation(gyr, received)
    np.testing.assert_allclose(filled[:, 0], [1, 2, 3, 4, 5])


# ------------------------------------------------------------------------------------------
# Paper 002: notebooks 06–09
# ------------------------------------------------------------------------------------------


def _shepard_knn(radio_map, positions, rss, n_neighbors, power, metric, *, eps=SHEPARD_EPS):
    difference = radio_map - rss
    distance = (np.sqrt(np.sum(difference ** 2, axis=1)) if metric == "euclidean"
                else np.sum(np.abs(difference), axis=1))
    nearest = np.argsort(distance, kind="stable")[:n_neighbors]
    weights = 1.0 / (distance[nearest] ** power + eps)
    return weights @ positions[nearest] / weights.sum()


def _gated_pitch(acc, xi, gravity, *, hold=True):
    magnitude = np.linalg.norm(acc, axis=1)
    pitch = np.arcsin(np.clip(acc[:, 0] / magnitude, -1.0, 1.0))
    if not hold:
        return pitch  # forgets the gate
    accepted = np.abs(magnitude - gravity) <= xi
    last = np.maximum.accumulate(np.where(accepted, np.arange(acc.shape[0]), -1))
    last[last < 0] = np.flatnonzero(accepted)[0]
    return pitch[last]


CORRECT_002 = {
    exercises.check_shepard_knn: _shepard_knn,
    exercises.check_gated_pitch: _gated_pitch,
    exercises.check_mean_position_error: lambda est, true: np.linalg.norm(est - true, axis=-1).mean(),
    exercises.check_precision_at_accuracy: lambda errors, accuracy: np.mean(errors <= accuracy),
}

WRONG_002 = {
    # Manhattan computed as Euclidean (the metric argument ignored).
    exercises.check_shepard_knn: lambda m, p, r, k, s, metric: _shepard_knn(m, p, r, k, s, "euclidean"),
    exercises.check_gated_pitch: lambda acc, xi, g: _gated_pitch(acc, xi, g, hold=False),
    # RMS instead of the mean distance.
    exercises.check_mean_position_error: lambda est, true: np.sqrt(np.mean(np.sum((est - true) ** 2, axis=-1))),
    # Strictly lower than the accuracy: misses the errors equal to it.
    exercises.check_precision_at_accuracy: lambda errors, accuracy: np.mean(errors < accuracy),
}


@pytest.mark.parametrize("checker", list(CORRECT_002), ids=lambda c: c.__name__)
def test_a_correct_function_passes_paper_002(checker):
    report = checker(CORRECT_002[checker], rng=_rng(), n_cases=60)
    assert report.n_cases == 60
    assert report.max_abs_difference <= 1e-9
    assert "passed" in str(report)


@pytest.mark.parametrize("checker", list(WRONG_002), ids=lambda c: c.__name__)
def test_a_plausible_mistake_fails_with_a_message_paper_002(checker):
    with pytest.raises(AssertionError, match="expected|returned"):
        checker(WRONG_002[checker], rng=_rng())


def test_shepard_knn_checker_catches_weights_without_the_epsilon():
    # Only online vectors lying on a fingerprint (d = 0) tell the two apart: 1/0 is not finite.
    with pytest.raises(AssertionError):
        exercises.check_shepard_knn(lambda *args: _shepard_knn(*args, eps=0.0), rng=_rng())


def test_paper_002_checkers_name_a_bad_argument():
    with pytest.raises(ValueError, match="rng"):
        exercises.check_shepard_knn(_shepard_knn, rng=12)
    with pytest.raises(ValueError, match="student_function"):
        exercises.check_precision_at_accuracy("np.mean", rng=_rng())
