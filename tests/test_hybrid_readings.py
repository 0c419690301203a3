"""Notebook 02's readings over movements (wsnlib.studies.hybrid_readings): errors, ranking and the practical tie."""

import dataclasses

import numpy as np
import pytest

from wsnlib.loss import LossProfile
from wsnlib.studies import hybrid_readings


@pytest.fixture(scope="module")
def movement_trials():
    from wsnlib.sim import movement_set
    from wsnlib.sim.trials import arm_loss_trials

    movements = dict(list(movement_set(fs=50.0, duration_s=4.0).items())[:3])
    return arm_loss_trials(movements, [LossProfile.burst(60 / 50.0, 4)], 3, rng=np.random.default_rng(2))


def test_readings_mean_error_averages_from_the_first_loss(movement_trials):
    readings = {"hybrid, instant, output": ("instant", "output"), "hybrid, decay, feedback": ("decay", "feedback")}
    errors = hybrid_readings.readings_mean_error(movement_trials, beta=0.041, rho=1.0, tau=6.0, hold_window=50,
                                                 readings=readings)
    n_trials = movement_trials.received.shape[0]
    assert set(errors) == set(readings) and all(e.shape == (n_trials,) and np.all(e > 0) for e in errors.values())
    # The literal reading is data fusion; a lingering λ with feedback corrects the lag after the gap.
    assert np.all(errors["hybrid, decay, feedback"].mean() < errors["hybrid, instant, output"].mean())
    lossless = dataclasses.replace(movement_trials, received=np.ones_like(movement_trials.received))
    with pytest.raises(ValueError, match="lose at least one sample"):
        hybrid_readings.readings_mean_error(lossless, beta=0.041, rho=1.0, tau=6.0, hold_window=50)


def test_per_movement_groups_trials_and_refuses_unequal_groups():
    values = np.arange(6.0)
    grouped, names = hybrid_readings.per_movement(values, ["a", "b", "a", "b", "a", "b"])
    assert list(names) == ["a", "b"] and grouped.tolist() == [[0.0, 2.0, 4.0], [1.0, 3.0, 5.0]]
    with pytest.raises(ValueError, match="same number"):
        hybrid_readings.per_movement(values, ["a", "a", "a", "a", "b", "b"])
    means = hybrid_readings.movement_means({"x": values}, ["a", "b"] * 3)
    assert means.loc["x", "a"] == 2.0 and means.loc["x", "b"] == 3.0


def _errors(offset_b, spread=0.01, n_runs=30):
    """Two readings on four movements of different difficulty; b = a + offset_b (+ noise)."""
    rng = np.random.default_rng(4)
    movements = np.repeat(["m1", "m2", "m3", "m4"], n_runs)
    base = np.repeat([1.0, 2.0, 4.0, 8.0], n_runs) + rng.normal(0.0, 0.1, movements.size)
    return {"a": base, "b": base + offset_b + rng.normal(0.0, spread, movements.size)}, movements


@pytest.mark.parametrize(("offset", "verdict"), [
    (0.02, "are a practical tie on mean |elbow error|: their difference stays below 0.1° although its interval "
           "excludes 0"),
    (0.5, "`a` has the lowest mean |elbow error|, ahead of `b` beyond the interval"),
])
def test_leader_sentence_tells_a_practical_tie_from_a_lead(offset, verdict):
    errors, movements = _errors(offset)
    ranking = hybrid_readings.rank_readings(errors, movements, rng=np.random.default_rng(0), n_boot=300)
    assert list(ranking.index) == ["a", "b"] and ranking["n_units"].iloc[0] == 4
    sentence = hybrid_readings.leader_sentence(ranking, errors, movements, margin=0.1, rng=np.random.default_rng(1),
                                               n_boot=300)
    assert verdict in sentence, sentence
    assert "95 % intervals over 4 movements" in sentence


def test_leader_sentence_says_when_the_two_cannot_be_told_apart():
    errors, movements = _errors(0.0, spread=2.0)     # noisy differences around 0, wider than the margin
    ranking = hybrid_readings.rank_readings(errors, movements, rng=np.random.default_rng(0), n_boot=300)
    sentence = hybrid_readings.leader_sentence(ranking, errors, movements, margin=0.1, rng=np.random.default_rng(1),
                                               n_boot=300)
    assert "cannot be told apart" in sentence, sentence
    with pytest.raises(ValueError, match="margin"):
        hybrid_readings.leader_sentence(ranking, errors, movements, margin=0.0, rng=np.random.default_rng(1))
