"""Notebook 04's study (wsnlib.studies.loss_alternatives): options, figures, winners and the generated guidance."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from wsnlib import metrics
from wsnlib.loss import LossProfile
from wsnlib.studies import loss_alternatives
from wsnlib.studies.hybrid_tuning import RECOMMENDED_HYBRID


@pytest.fixture(scope="module")
def small_run():
    from wsnlib.sim import movement_set
    from wsnlib.sim.trials import arm_loss_trials

    movements = dict(list(movement_set(fs=50.0, duration_s=4.0).items())[:2])
    rates = [0.0, 0.2]
    profiles = [LossProfile.gilbert_elliott(rate, 3.0) for rate in rates]
    trials = arm_loss_trials(movements, profiles, 3, rng=np.random.default_rng(5))
    options = loss_alternatives.loss_options(RECOMMENDED_HYBRID, beta=0.041, beta_max_factor=10.0)
    errors, seconds = loss_alternatives.run_options(trials, options, beta=0.041)
    return trials, rates, profiles, options, errors, seconds


def test_options_run_on_the_same_trials_and_agree_without_loss(small_run):
    trials, rates, profiles, options, errors, seconds = small_run
    assert list(options) == ["hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid"]
    assert list(errors) == [*options, "single frame"] and set(seconds) == set(errors)
    n_trials, n_samples = trials.received.shape[0], trials.received.shape[-1]
    assert all(error.shape == (n_trials, n_samples) for error in errors.values())
    results, per_trial = loss_alternatives.option_figures(trials, errors, rates, profiles, threshold_deg=5.0)
    assert len(results) == len(errors) * len(rates)
    no_loss = results[results["loss rate"] == 0].set_index("option")
    np.testing.assert_allclose(no_loss.loc[list(options), metrics.MEAN_ERROR],
                               no_loss.loc["hold_last", metrics.MEAN_ERROR])
    lossy = results[results["loss rate"] == 0.2].set_index("option")
    assert lossy.loc["gyro_interpolation", metrics.MEAN_ERROR] != lossy.loc["hold_last", metrics.MEAN_ERROR]
    pick = (trials.labels["profile"] == profiles[1].name).to_numpy()
    assert lossy.loc["hybrid", metrics.JITTER] == pytest.approx(per_trial["hybrid"][metrics.JITTER][pick].mean())
    with pytest.raises(ValueError, match="pair up"):
        loss_alternatives.option_figures(trials, errors, rates[:1], profiles, threshold_deg=5.0)
    with pytest.raises(ValueError, match="beta_max_factor"):
        loss_alternatives.loss_options(RECOMMENDED_HYBRID, beta=0.041, beta_max_factor=1.0)


def _fake(per_option: dict, n_per_rate: int = 40):
    """Trials of two loss rates (0 and 0.1) and per-trial figures: each option's value = its mean + noise."""
    rng = np.random.default_rng(3)
    profiles = [LossProfile.gilbert_elliott(0.0, 3.0), LossProfile.gilbert_elliott(0.1, 3.0)]
    labels = pd.DataFrame({"profile": [p.name for p in profiles for _ in range(n_per_rate)]})
    noise = rng.normal(0.0, 0.1, 2 * n_per_rate)
    per_trial = {name: {figure: mean + noise + 0.01 * rng.normal(size=noise.size) for figure in (metrics.MEAN_ERROR,)}
                 for name, mean in per_option.items()}
    return per_trial, SimpleNamespace(labels=labels), [0.0, 0.1], profiles


def test_winners_name_the_leader_and_its_ties_and_skip_rate_zero():
    per_trial, trials, rates, profiles = _fake({"a": 1.0, "b": 1.0, "c": 3.0})
    winners, rankings = loss_alternatives.winners_by_loss_rate(per_trial, trials, rates, profiles,
                                                               rng=np.random.default_rng(0),
                                                               figures=(metrics.MEAN_ERROR,), n_boot=200)
    assert list(winners.index) == [0.1] and list(rankings) == [(0.1, metrics.MEAN_ERROR)]
    assert set(winners.loc[0.1, metrics.MEAN_ERROR].removesuffix(" (tie)").split(" = ")) == {"a", "b"}
    assert winners.loc[0.1, metrics.MEAN_ERROR].endswith(" (tie)")
    per_trial, trials, rates, profiles = _fake({"a": 1.0, "b": 2.0, "c": 3.0})
    winners, _ = loss_alternatives.winners_by_loss_rate(per_trial, trials, rates, profiles,
                                                        rng=np.random.default_rng(0), figures=(metrics.MEAN_ERROR,),
                                                        n_boot=200)
    assert winners.loc[0.1, metrics.MEAN_ERROR] == "a"
    sentence = loss_alternatives.least_accurate_sentence(per_trial, trials, rates, profiles, rate=0.1,
                                                         figure=metrics.MEAN_ERROR, simulator="toy simulator",
                                                         rng=np.random.default_rng(0), n_boot=200)
    assert sentence.startswith("on the toy simulator, c (3.0° [") and "above the next, b (2.0°" in sentence
    with pytest.raises(ValueError, match="not one of"):
        loss_alternatives.least_accurate_sentence(per_trial, trials, rates, profiles, rate=0.3,
                                                  figure=metrics.MEAN_ERROR, simulator="x",
                                                  rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="no lossy rate"):
        loss_alternatives.winners_by_loss_rate(per_trial, trials, [0.0, 0.0], profiles, rng=np.random.default_rng(0))


def test_guidance_joins_loss_rates_and_says_when_simulators_agree():
    index = pd.Index([0.05, 0.1, 0.2], name="loss rate")
    clean = pd.DataFrame({"err": ["a = b (tie)", "a = b (tie)", "c"], "smooth": ["h", "h", "h"]}, index=index)
    calibrated = pd.DataFrame({"err": ["c", "c", "c"], "smooth": ["h", "h", "h"]}, index=index)
    text = loss_alternatives.guidance({"clean": clean, "calibrated": calibrated},
                                      {"err": "You care about errors", "smooth": "You care about smoothness"})
    assert text.splitlines() == ["* **You care about errors:**",
                                 "    * clean: 5–10 %: a = b (tie); 20 %: c.",
                                 "    * calibrated: c at every loss rate.",
                                 "* **You care about smoothness:** h at every loss rate, on every simulator."]
    # The same tie written in another order is the same winner.
    reordered = clean.assign(err=["b = a (tie)", "a = b (tie)", "c"])
    assert "on every simulator" in loss_alternatives.guidance({"x": clean, "y": reordered}, {"err": "E"})
    with pytest.raises(ValueError, match="no column"):
        loss_alternatives.guidance({"clean": clean}, {"other": "?"})
    sentence = loss_alternatives.leaders_sentence({"clean": clean, "calibrated": calibrated}, ["err"], what="errors")
    assert sentence == ("On errors, the options that lead (alone or tied) at some loss rate are: clean — a, b, c; "
                        "calibrated — c. Leading on the clean only: a, b.")
