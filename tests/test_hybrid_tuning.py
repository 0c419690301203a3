"""Notebook 03's study of the hybrid (wsnlib.studies.hybrid_tuning): sweep, candidates, recommendation."""

import numpy as np
import pandas as pd
import pytest

from wsnlib import tuning
from wsnlib.studies import hybrid_tuning
from wsnlib.studies.hybrid_tuning import hybrid_options, mu_options


def test_recommendation_round_trip(output_dir):
    with pytest.raises(FileNotFoundError, match="03"):
        hybrid_tuning.read_recommendation()
    hybrid_tuning.write_recommendation({"schedule": "decay", "blend": "feedback", "rho": 2.0, "tau": 6.0})
    assert hybrid_tuning.read_recommendation() == {"schedule": "decay", "blend": "feedback", "rho": 2.0, "tau": 6.0}
    with pytest.raises(ValueError, match="tau"):
        hybrid_tuning.write_recommendation({"schedule": "decay", "blend": "feedback", "rho": 2.0})


def test_hybrid_options_pass_hold_window_only_for_hold():
    from wsnlib.orientation import estimate_orientation

    setting = {"schedule": "decay", "blend": "output", "rho": 2, "tau": 6, "hold_window": 50}
    assert mu_options(setting) == {"rho": 2.0, "tau": 6.0, "schedule": "decay"}
    assert hybrid_options(setting) == {"blend": "output", "rho": 2.0, "tau": 6.0, "schedule": "decay"}
    held = {**setting, "schedule": "hold"}
    assert hybrid_options(held) == {"blend": "output", "rho": 2.0, "tau": 6.0, "schedule": "hold", "hold_window": 50}
    assert mu_options(held)["hold_window"] == 50 and "blend" not in mu_options(held)
    # ... keywords estimate_orientation takes: the hybrid's, and adaptive β's (μ only)
    n = 60
    gyr, acc, mag = np.zeros((n, 3)), np.tile([0.0, 0.0, 9.8], (n, 1)), np.tile([0.0, 20.0, -30.0], (n, 1))
    received = np.arange(n) % 7 != 3
    for options in (hybrid_options(setting), hybrid_options(held), {"method": "adaptive_beta", **mu_options(held)}):
        assert estimate_orientation(gyr, acc, mag, fs=50.0, beta=0.041, received=received, **options).shape == (n, 4)
    with pytest.raises(ValueError, match="rho"):  # μ alone is not a method: no keyword is silently ignored
        estimate_orientation(gyr, acc, mag, fs=50.0, beta=0.041, received=received, **mu_options(setting))


@pytest.fixture(scope="module")
def small_trials():
    from wsnlib.loss import LossProfile
    from wsnlib.sim import movement_set
    from wsnlib.sim.trials import arm_loss_trials

    movements = dict(list(movement_set(fs=50.0, duration_s=4.0).items())[:2])
    return arm_loss_trials(movements, [LossProfile.burst(60 / 50.0, 4), LossProfile.gilbert_elliott(0.2)], 2,
                           rng=np.random.default_rng(11))


def test_hybrid_sweep_shapes_and_only_the_product_matters(small_trials):
    rho_grid, tau_grid = [1.0, 2.0, 4.0], [2.0, 1.0]
    foms, references = hybrid_tuning.hybrid_sweep(small_trials, rho_grid, tau_grid, beta=0.041, hold_window=50,
                                           threshold_deg=5.0, configurations=[("decay", "feedback")])
    n_trials = len(small_trials.labels)
    error = foms["decay", "feedback"][hybrid_tuning.CANDIDATE_COLUMNS["mean max error (°)"]]
    assert error.shape == (3, 2, n_trials)
    # (ρ, τ) = (1, 2) and (2, 1) have the same product, (4, 1) another one.
    assert np.allclose(error[0, 0], error[1, 1], atol=1e-6)
    assert not np.allclose(error[0, 0], error[2, 1])
    assert set(references) == {"data fusion", "single frame"}
    assert references["data fusion"][hybrid_tuning.CANDIDATE_COLUMNS["mean max error (°)"]].shape == (n_trials,)


def test_candidate_table_and_recommendation_follow_the_costs(small_trials):
    rho_grid, tau_grid = [0.5, 4.0], [1.0, 6.0]
    configurations = [("hold", "output"), ("decay", "feedback")]
    foms, _ = hybrid_tuning.hybrid_sweep(small_trials, rho_grid, tau_grid, beta=0.041, hold_window=50,
                                         threshold_deg=5.0, configurations=configurations)
    candidates, costs = hybrid_tuning.candidate_table(foms, rho_grid, tau_grid, configurations)
    assert len(candidates) == 8 and list(candidates.columns[:4]) == ["schedule", "blend", "rho", "tau"]
    for column in hybrid_tuning.CANDIDATE_COLUMNS:
        assert costs[column].shape == (8, len(small_trials.labels))
        assert np.allclose(candidates[column], costs[column].mean(axis=1))
    assert candidates.loc[4, "schedule"] == "decay" and candidates.loc[4, "rho"] == 0.5
    recommendation, knee, boot = hybrid_tuning.recommend_hybrid(candidates, costs, rng=np.random.default_rng(0),
                                                                n_boot=20, beta=0.041)
    assert hybrid_tuning.RECOMMENDATION_COST == "mean jitter (°/s³)"       # issue 26: jitter, not the whole-record jerk
    assert knee == tuning.knee_point(candidates["mean max error (°)"], candidates["mean jitter (°/s³)"])
    assert candidates["pareto"].equals(pd.Series(tuning.pareto_front(candidates["mean max error (°)"],
                                                                     candidates["mean jitter (°/s³)"])))
    assert boot.shape == (20,)
    row = candidates.iloc[knee]
    assert (recommendation["schedule"], recommendation["rho"], recommendation["beta"]) == (
        row["schedule"], row["rho"], 0.041)
    assert recommendation["rho_tau_ci_low"] <= recommendation["rho_tau_ci_high"]


def _toy_candidates():
    """Four candidates: jitter and error trade off (the whole-record jerk would pick another knee); the gap-end
    step prefers another setting."""
    import pandas as pd

    return pd.DataFrame({"schedule": ["hold", "hold", "decay", "decay"], "blend": ["output"] * 2 + ["feedback"] * 2,
                         "rho": [1.0, 4.0, 1.0, 4.0], "tau": [6.0, 6.0, 6.0, 6.0],
                         "mean max error (°)": [1.0, 3.0, 2.0, 4.0], "mean jerk (°/s³)": [0.5, 1.0, 2.0, 9.0],
                         "mean gap-end step (°)": [0.1, 5.0, 5.0, 5.0], "mean jitter (°/s³)": [9.0, 1.0, 2.0, 0.5],
                         "mean time above (s)": [0.1, 0.2, 0.3, 0.4]})


def _toy_references(df_error, sf_error, df_jitter=1.0):
    def foms(error, jitter):
        values = {"mean max error (°)": error, "mean jerk (°/s³)": 0.0, "mean gap-end step (°)": 0.0,
                  "mean jitter (°/s³)": jitter, "mean time above (s)": 1.0}
        return {hybrid_tuning.CANDIDATE_COLUMNS[column]: np.array([value, value]) for column, value in values.items()}
    return {"data fusion": foms(df_error, df_jitter), "single frame": foms(sf_error, 50.0)}


def _toy_recommendation(candidates, knee):
    row = candidates.iloc[knee]
    return {"schedule": row["schedule"], "blend": row["blend"], "rho": row["rho"], "tau": row["tau"],
            "rho_tau": row["rho"] * row["tau"], "rho_tau_ci_low": 6.0, "rho_tau_ci_high": 24.0,
            "share_of_bootstrap_same_configuration": 0.75}


def test_knee_settings_and_agreement_sentence():
    candidates = _toy_candidates()
    knees = hybrid_tuning.knee_settings(candidates)
    assert list(knees.index) == [label for label, *_ in hybrid_tuning.SMOOTHNESS_CRITERIA.values()]
    jitter_knee = tuning.knee_point(candidates["mean max error (°)"], candidates["mean jitter (°/s³)"])
    assert jitter_knee != tuning.knee_point(candidates["mean max error (°)"], candidates["mean jerk (°/s³)"])
    assert knees.iloc[0]["rho_tau"] == candidates.iloc[jitter_knee]["rho"] * 6.0
    assert knees.loc["mean step at gap ends (°)", "schedule"] == "hold"  # row 0 beats all on error and step
    sentence = hybrid_tuning.knee_agreement_sentence(knees, _toy_recommendation(candidates, jitter_knee))
    assert "— a different setting." in sentence and "keeps the jitter criterion" in sentence
    same = knees.copy()
    same.iloc[1:] = same.iloc[0].to_numpy()
    agreeing = hybrid_tuning.knee_agreement_sentence(same, _toy_recommendation(candidates, jitter_knee))
    assert agreeing.endswith("Both criteria agree on the recommendation.")
    with pytest.raises(ValueError, match="column"):
        hybrid_tuning.knee_settings(candidates.drop(columns="mean jitter (°/s³)"))


def test_configuration_and_recommendation_comparisons():
    candidates = _toy_candidates()
    references = _toy_references(df_error=5.0, sf_error=0.5)
    table = hybrid_tuning.configuration_comparison(candidates, references, [("hold", "output"), ("decay", "feedback")])
    assert list(table.index) == ["hybrid, hold, output", "hybrid, decay, feedback", "data fusion", "single frame"]
    own = candidates[candidates["schedule"] == "decay"]
    knee = own.iloc[tuning.knee_point(own["mean max error (°)"], own["mean jitter (°/s³)"])]
    assert table.loc["hybrid, decay, feedback", "rho"] == knee["rho"]
    assert table.loc["data fusion", "mean max error (°)"] == 5.0 and np.isnan(table.loc["single frame", "tau"])
    with pytest.raises(ValueError, match="schedule"):
        hybrid_tuning.configuration_comparison(candidates, references, [("decay", "output")])
    clean = (_toy_recommendation(candidates, 2), candidates, 2, references)
    realistic = (_toy_recommendation(candidates, 3), candidates, 3, _toy_references(df_error=3.0, sf_error=20.0,
                                                                                     df_jitter=0.1))
    both = hybrid_tuning.recommendation_comparison({"clean": clean, "realistic": realistic})
    assert list(both.columns) == ["clean simulator", "realistic simulator"]
    assert both.loc["ρτ (samples)", "realistic simulator"] == 24.0
    assert both.loc["single frame: mean max error (°)", "realistic simulator"] == 20.0
    assert both.loc["knee: mean jitter (°/s³)", "clean simulator"] == 2.0
    sentence = hybrid_tuning.realistic_shift_sentence(clean, realistic, largest_product=24.0)
    assert "grows from 0.5° on the clean trials to 20.0°" in sentence
    assert "to decay/feedback with ρτ = 24" in sentence and "largest product on the grid (24)" in sentence
    assert "does not beat data fusion's; the lowest of any candidate is 1.0°" in sentence
    assert "Data fusion alone beats every hybrid candidate" not in sentence  # row 0 has a lower error
    assert sentence.endswith("its correction after a gap gains.")
    unmoved = hybrid_tuning.realistic_shift_sentence(clean, clean, largest_product=96.0)
    assert "The knee does not move." in unmoved and "beats data fusion's" in unmoved


def test_hybrids_against_data_fusion_counts_settings_and_gives_a_paired_interval():
    candidates = _toy_candidates()                     # mean max error 1, 3, 2, 4; jitter 9, 1, 2, 0.5
    offsets = np.array([-0.2, 0.0, 0.2])               # three trials around each candidate's mean
    costs = {column: candidates[column].to_numpy()[:, None] + offsets for column in hybrid_tuning.CANDIDATE_COLUMNS}
    references = _toy_references(df_error=2.5, sf_error=0.5, df_jitter=0.25)
    for key in references["data fusion"]:
        references["data fusion"][key] = references["data fusion"][key][0] + offsets
    table = hybrid_tuning.hybrids_against_data_fusion(candidates, costs, references, rng=np.random.default_rng(0),
                                                      n_boot=200)
    error, jitter = table.loc["mean max error (°)"], table.loc["mean jitter (°/s³)"]
    assert (error["hybrids below data fusion"], jitter["hybrids below data fusion"]) == (2, 0)
    assert error["best hybrid"] == 1.0 and error["best hybrid setting"] == "hold/output, ρτ = 6"
    assert error["difference"] == pytest.approx(-1.5) and error["ci_high"] < 0 and error["trials"] == 3
    sentence = hybrid_tuning.data_fusion_sentence("the toy simulator", table)
    assert sentence.startswith("On the toy simulator, 2 of the 4 hybrid settings have a lower mean max elbow error")
    assert "difference -1.5° [" in sentence and "a tie" not in sentence and "— and none a lower mean jitter" in sentence
    # Data fusion better on both: the sentence says so, and names a tie when the error interval holds 0.
    worse = {column: value + 10.0 for column, value in costs.items()}
    worse["mean max error (°)"] = costs["mean max error (°)"] + 1.5 + np.array([[0.3, -0.3, 0.0]])
    candidates_worse = candidates.assign(**{column: worse[column].mean(axis=1) for column in worse})
    table = hybrid_tuning.hybrids_against_data_fusion(candidates_worse, worse, references,
                                                      rng=np.random.default_rng(0), n_boot=200)
    sentence = hybrid_tuning.data_fusion_sentence("the toy simulator", table)
    assert "data fusion alone has a lower mean max elbow error and a lower mean jitter than every one of the 4" \
        in sentence
    assert "the interval holds 0, a tie" in sentence                    # 2.5 ± noise against 2.5
    assert table.loc["mean max error (°)", "hybrids below data fusion"] == 0
    with pytest.raises(ValueError, match="same trials"):
        hybrid_tuning.hybrids_against_data_fusion(candidates, {k: v[:, :2] for k, v in costs.items()}, references,
                                                  rng=np.random.default_rng(0))
