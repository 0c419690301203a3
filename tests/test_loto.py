"""Leave-one-out choice of settings (wsnlib.loto)."""

import numpy as np
import pytest

from wsnlib.loto import in_sample_choice, leave_one_out_choice, leave_one_out_scores


def test_planted_example_where_in_sample_and_leave_one_out_differ():
    # Setting 0 is perfect on units 0 and 1 and bad on unit 2; setting 1 is mediocre everywhere.
    scores = np.array([[0.0, 0.0, 10.0],
                       [2.0, 2.0, 2.0]])
    assert in_sample_choice(scores) == 1  # mean 2 < 10/3
    # Without unit 2, setting 0 looks perfect; without unit 0 or 1, setting 0 averages 5.
    np.testing.assert_array_equal(leave_one_out_choice(scores), [1, 1, 0])
    held_out = leave_one_out_scores(scores)
    np.testing.assert_array_equal(held_out, [2.0, 2.0, 10.0])
    # Honest held-out error is worse than the in-sample optimum.
    assert held_out.mean() > scores[in_sample_choice(scores)].mean()


def test_matches_brute_force_on_random_scores():
    rng = np.random.default_rng(3)
    scores = rng.gamma(2.0, size=(5, 9))
    choice = leave_one_out_choice(scores)
    for unit in range(scores.shape[1]):
        rest = np.delete(scores, unit, axis=1)
        assert choice[unit] == np.argmin(rest.mean(axis=1))
    np.testing.assert_array_equal(leave_one_out_scores(scores), scores[choice, np.arange(scores.shape[1])])


def test_equal_means_go_to_the_lowest_setting_index():
    scores = np.array([[1.0, 3.0, 2.0],
                       [3.0, 1.0, 2.0],
                       [2.0, 2.0, 2.0]])
    # Without unit 2 all three settings average 2: the first one wins.
    assert leave_one_out_choice(scores)[2] == 0
    assert in_sample_choice(scores) == 0


def test_a_failed_setting_marked_inf_is_not_chosen_where_it_failed():
    scores = np.array([[0.1, 0.1, np.inf],
                       [1.0, 1.0, 1.0]])
    # Setting 0 failed on unit 2: chosen only for unit 2 (tuned on units 0 and 1), which then scores inf.
    np.testing.assert_array_equal(leave_one_out_choice(scores), [1, 1, 0])
    assert np.isinf(leave_one_out_scores(scores)[2])
    assert in_sample_choice(scores) == 1


def test_every_setting_infinite_on_the_training_units_raises():
    scores = np.array([[np.inf, np.inf, 1.0],
                       [np.inf, 2.0, 1.0]])
    with pytest.raises(ValueError, match="every setting has an infinite score"):
        leave_one_out_choice(scores)


@pytest.mark.parametrize("scores, message", [
    (np.ones((3, 1)), "at least 2 units"),
    (np.ones(4), r"shape \(n_settings, n_units\)"),
    (np.ones((0, 3)), "at least one setting"),
    (np.array([[1.0, np.nan], [1.0, 2.0]]), "NaN at"),
    (np.array([[1.0, -np.inf], [1.0, 2.0]]), "-inf"),
])
def test_bad_scores_raise(scores, message):
    for function in (leave_one_out_choice, leave_one_out_scores, in_sample_choice):
        with pytest.raises(ValueError, match=message):
            function(scores)


def test_groups_are_held_out_together():
    """Two nodes of one recording are not independent: the choice for one never sees the other."""
    # Units 0 and 1 are the nodes of recording "a" and prefer setting 0; unit 2 (recording "b") prefers 1.
    scores = np.array([[1.0, 1.0, 3.0],
                       [4.0, 4.0, 1.0]])
    np.testing.assert_array_equal(leave_one_out_choice(scores), [0, 0, 0])  # each node sees its twin
    np.testing.assert_array_equal(leave_one_out_choice(scores, groups=["a", "a", "b"]), [1, 1, 0])
    np.testing.assert_array_equal(leave_one_out_scores(scores, groups=["a", "a", "b"]), [4.0, 4.0, 3.0])
    np.testing.assert_array_equal(leave_one_out_choice(scores, groups=[0, 1, 2]), leave_one_out_choice(scores))
    with pytest.raises(ValueError, match="at least 2 distinct"):
        leave_one_out_choice(scores, groups=["a", "a", "a"])
    with pytest.raises(ValueError, match="one label per unit"):
        leave_one_out_choice(scores, groups=["a", "b"])
