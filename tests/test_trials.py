import numpy as np
import pytest

from wsnlib.loss import LossProfile
from wsnlib.sim import arm_extension
from wsnlib.sim.trials import arm_loss_trials


def _movements():
    return {"a": arm_extension(duration_s=4.0, rise_s=1.5), "b": arm_extension(duration_s=4.0, rise_s=3.0)}


def test_shapes_labels_and_profiles(rng):
    profiles = [LossProfile.none(), LossProfile.burst(80 / 50.0, 4), LossProfile.gilbert_elliott(0.2, 3.0)]
    trials = arm_loss_trials(_movements(), profiles, 5, rng=rng)
    n = 2 * 3 * 5
    assert trials.gyr.shape == (n, 2, 200, 3)
    assert trials.quat_true.shape == (n, 2, 200, 4)
    assert trials.received.shape == (n, 2, 200)
    assert list(trials.labels.columns) == ["movement", "profile", "repetition"]
    by_profile = {p: trials.received[(trials.labels.profile == p).to_numpy()] for p in trials.labels.profile.unique()}
    assert by_profile["no loss"].all()
    burst = by_profile["burst 4 packets"]
    assert burst[:, 1].all() and (~burst[:, 0]).sum(axis=-1).tolist() == [24] * 10
    ge = by_profile["GE 20 %"]
    assert 0.05 < 1 - ge.mean() < 0.4          # loose: 200 samples is a short record
    assert not np.array_equal(ge[:, 0], ge[:, 1])  # independent nodes


def test_same_seed_same_trials():
    profiles = [LossProfile.gilbert_elliott(0.1)]
    a = arm_loss_trials(_movements(), profiles, 2, rng=np.random.default_rng(4))
    b = arm_loss_trials(_movements(), profiles, 2, rng=np.random.default_rng(4))
    np.testing.assert_array_equal(a.gyr, b.gyr)
    np.testing.assert_array_equal(a.received, b.received)


def test_select_keeps_the_chosen_trials_in_order(rng):
    trials = arm_loss_trials(_movements(), [LossProfile.none(), LossProfile.gilbert_elliott(0.2)], 3, rng=rng)
    keep = np.zeros(len(trials.labels), dtype=bool)
    keep[[1, 4, 9]] = True
    kept = trials.select(keep)
    for name in ("gyr", "acc", "mag", "quat_true", "received"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(trials, name)[[1, 4, 9]])
    assert kept.labels.index.tolist() == [0, 1, 2]
    assert kept.labels.to_dict("records") == trials.labels.iloc[[1, 4, 9]].to_dict("records")
    assert kept.fs == trials.fs
    assert len(trials.select(np.ones(len(trials.labels), dtype=bool)).labels) == len(trials.labels)
    with pytest.raises(ValueError, match="boolean"):
        trials.select([1, 4, 9])
    with pytest.raises(ValueError, match="shape"):
        trials.select(keep[:-1])


def test_bad_inputs(rng):
    with pytest.raises(ValueError, match="n_repetitions"):
        arm_loss_trials(_movements(), [LossProfile.none()], 0, rng=rng)
    with pytest.raises(ValueError, match="share"):
        arm_loss_trials({"a": arm_extension(duration_s=4.0), "b": arm_extension(duration_s=5.0)},
                        [LossProfile.none()], 1, rng=rng)
    assert LossProfile.gilbert_elliott(0.0).model == "none"
