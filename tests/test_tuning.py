"""Pareto fronts, knee points and their bootstrap (wsnlib.tuning)."""

import numpy as np
import pytest

from wsnlib import tuning


def test_pareto_front_of_a_known_set():
    a = np.array([1.0, 2.0, 3.0, 2.0, 4.0])
    b = np.array([5.0, 3.0, 1.0, 4.0, 4.0])
    # (2,4) is beaten by (2,3); (4,4) by (3,1) and (2,3).
    np.testing.assert_array_equal(tuning.pareto_front(a, b), [True, True, True, False, False])


def test_knee_is_the_balanced_point():
    a = np.array([0.0, 0.2, 1.0])
    b = np.array([1.0, 0.2, 0.0])
    assert tuning.knee_point(a, b) == 1
    assert tuning.knee_point(np.array([1.0]), np.array([2.0])) == 0


def test_bootstrap_knee_is_stable_for_a_clear_optimum(rng):
    n_real = 200
    a = np.array([0.0, 0.2, 1.0])[:, None] + rng.normal(scale=0.01, size=(3, n_real))
    b = np.array([1.0, 0.2, 0.0])[:, None] + rng.normal(scale=0.01, size=(3, n_real))
    knees = tuning.bootstrap_knee(a, b, rng=rng, n_boot=100)
    assert knees.shape == (100,)
    assert np.all(knees == 1)


def test_bootstrap_is_reproducible_and_validates():
    a = np.random.default_rng(1).random((4, 30))
    b = np.random.default_rng(2).random((4, 30))
    first = tuning.bootstrap_knee(a, b, rng=np.random.default_rng(3), n_boot=20)
    second = tuning.bootstrap_knee(a, b, rng=np.random.default_rng(3), n_boot=20)
    np.testing.assert_array_equal(first, second)
    with pytest.raises(ValueError, match="n_boot"):
        tuning.bootstrap_knee(a, b, rng=np.random.default_rng(3), n_boot=0)
    with pytest.raises(ValueError, match="shape"):
        tuning.bootstrap_knee(a, b[:, :5], rng=np.random.default_rng(3))
    with pytest.raises(ValueError, match="cost_a"):
        tuning.pareto_front([1.0, np.nan], [1.0, 2.0])
