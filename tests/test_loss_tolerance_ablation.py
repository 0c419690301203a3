"""Issue 25 in the loss-tolerance study: one budget from physical bounds, edge flags, the ablation
(filter × gap handling) and its ratios, one burst per run at many positions, distinct line colours."""

import dataclasses
import types

import numpy as np
import pandas as pd
import pytest

from wsnlib import loto
from wsnlib.orientation import KalmanSettings
from wsnlib.studies import loss_tolerance as lt
from wsnlib.studies.loss_tolerance import summary, tables

# --- one budget, from physical bounds -----------------------------------------------------------------


def test_range_levels_run_from_bound_to_bound_on_a_log_scale():
    beta = lt.Range(0.001, 1.0, unit="rad/s", why="because")
    assert beta.levels(4) == (0.001, 0.01, 0.1, 1.0)
    assert beta.levels(1) == (pytest.approx(0.0316, rel=1e-3),)  # one value: the middle of the range
    assert lt.Range(1, 1000, integer=True).levels(3) == (1, 32, 1000)
    assert lt.Range(0.0, 10.0, log=False).levels(3) == (0.0, 5.0, 10.0)
    with pytest.raises(ValueError, match="not distinct"):
        lt.Range(1, 3, integer=True).levels(5)
    with pytest.raises(ValueError, match="rounded"):
        lt.Range(0.12345, 1.0)  # a bound the grid could not hold exactly
    assert lt.Choice((True, False)).levels(7) == (True, False)


def test_space_grid_splits_one_budget_over_the_settings():
    one = {"beta": lt.Range(0.001, 1.0)}
    two = {"a": lt.Range(0.1, 100.0), "b": lt.Range(0.1, 100.0)}
    three = {**two, "c": lt.Range(1, 1000, integer=True)}
    assert len(lt.space_grid(one, 12)) == 12
    grid = lt.space_grid(two, 12)  # 4 × 3: the first setting gets the extra value
    assert len(grid) == 12 and sorted({s["a"] for s in grid}) == [0.1, 1.0, 10.0, 100.0]
    assert sorted({s["b"] for s in grid}) == [0.1, 3.16, 100.0]
    assert len(lt.space_grid(three, 12)) == 12  # 3 × 2 × 2
    assert len(lt.space_grid(two, 13)) == 12  # 4 × 3 rather than 13 × 1: every setting gets as many as fit
    assert len({s["c"] for s in lt.space_grid(three, 16)}) == 2  # 4 × 2 × 2 = 16, not 4 × 4 × 1
    assert len({s["b"] for s in lt.space_grid(three, 4)}) == 2  # 2 × 2 × 1, not 4 × 1 × 1
    assert len(lt.space_grid(two, 1000)) == 32 * 31
    choice = {"replay": lt.Choice((True, False)), **one}
    grid = lt.space_grid(choice, 12)  # every value of a choice, the range gets the rest
    assert len(grid) == 12 and {s["replay"] for s in grid} == {True, False} and len({s["beta"] for s in grid}) == 6
    with pytest.raises(ValueError, match="choices"):
        lt.space_grid({"x": lt.Choice((1, 2, 3))}, 2)
    with pytest.raises(ValueError, match="at least one"):
        lt.space_grid({}, 12)


def test_the_registry_writes_its_bounds_beside_each_grid():
    methods = lt.default_methods()
    spaces = tables.space_table(methods)
    assert {key for key, _ in spaces.index} == {key for m in methods.values() for key in m.space}
    assert spaces["why these bounds"].str.len().min() > 20  # every bound has its reason
    for method in methods.values():
        for key, axis in method.space.items():
            bounds = f"{axis.low:g} – {axis.high:g}"
            assert method.name in spaces.loc[(key, bounds), "methods"]
    # Fusion's rejection is tuned; every hybrid tunes its filter's gain × ρτ.
    assert set(methods["Fusion"].space) == {"gain", "rejection_deg"}
    for name, gain in (("hybrid (feedback)", "beta"), ("Fusion + hybrid (feedback)", "gain"),
                       ("VQF + hybrid (feedback)", "tauAcc")):
        assert set(methods[name].space) == {gain, "rho_tau"}
    sentence = tables.budget_sentence(methods)
    assert f"**{lt.DEFAULT_BUDGET} settings**" in sentence and "4 beta × 3 rho_tau for `hybrid (feedback)`" in sentence
    assert "`VQF (defaults)`" in sentence.split("Nothing to tune")[1]


def test_edge_picks_flag_a_bound_and_catch_a_grid_narrower_than_its_bounds():
    method = lt.default_methods(4)["hold_last"]  # β: 4 values from bound to bound
    choices = pd.DataFrame({"method": "hold_last", "trial": ["a", "b", "c"], "setting_index": [3, 3, 1]})
    table = summary.edge_picks({"hold_last": method}, choices)
    assert len(table) == 1 and table.iloc[0]["verdict"] == "at a bound of the space"
    assert table.iloc[0]["value"] == method.space["beta"].high and table.iloc[0]["n_trials"] == 2
    narrow = dataclasses.replace(method, grid=lt.settings_grid(beta=(0.01, 0.1, 0.8)))  # the old hand-picked edge
    assert summary.edge_picks({"hold_last": narrow}, choices.assign(setting_index=2)).iloc[0]["verdict"] == \
        "grid too narrow"
    sentence = tables.optimism_sentence(pd.DataFrame({"held_out": [2.0], "in_sample": [1.5], "optimism": [0.5]},
                                                     index=["hold_last"]), table)
    assert "At a physical bound" in sentence and "beta = 4.53 (high bound, 2 of 3 trials)" in sentence


# --- one burst per run, at many positions -------------------------------------------------------------


def test_burst_positions_fall_in_the_movement_and_need_room():
    profile = lt.BurstPositions(positions=4, before_s=0.5, window_s=2.0)
    fs = 50.0
    movement = np.zeros(1000, bool)
    movement[200:400] = movement[700:800] = True
    starts = profile.starts(movement, fs)
    assert len(starts) == 4 and movement[starts].all() and np.all(np.diff(starts) > 0)
    masks = profile.masks(movement, fs)
    assert masks.shape == (4, 1000) and ((~masks).sum(axis=1) == 24).all()
    still = profile.starts(np.zeros(1000, bool), fs)  # no movement: spread over the whole record
    assert still[0] >= 25 and still[-1] <= 1000 - 30 - 100
    with pytest.raises(ValueError, match="too short"):
        profile.starts(np.ones(120, bool), fs)
    with pytest.raises(ValueError, match="positions"):
        lt.BurstPositions(positions=0)
    assert [p.positions for p in lt.study_profiles(3) if isinstance(p, lt.BurstPositions)] == [3]


# --- the ablation -------------------------------------------------------------------------------------


def _per_trial(values: dict, n_trials=6, draws=2, profile=lt.HEADLINE):
    """Rows of method → mean total RMSE, each trial and draw a little off it (deterministic)."""
    rows = []
    for j in range(n_trials):
        for d in range(draws):
            for k, (method, value) in enumerate(values.items()):
                rows.append({"trial": f"t{j}", "draw": d, "method": method, "profile": profile, "kind": "peer",
                             "rmse_total": value * (1 + 0.05 * ((j + d + k) % 3 - 1))})
    return pd.DataFrame(rows)


def test_ablation_table_grid_pairs_and_ratios():
    values = {"hold_last": 30.0, "constant_rate": 28.0, "Kalman, hold": 20.0, "Kalman": 10.0, "VQF": 40.0,
              "VQF, AR + replay": 20.0, "Fusion, AR + replay": 25.0, "Fusion": 35.0}
    per_trial = _per_trial(values)
    groups = {f"t{j}": f"g{j // 2}" for j in range(6)}
    means = summary.summary_table(per_trial, rng=np.random.default_rng(0), n_boot=200, groups=groups,
                                  metrics=("rmse_total",))
    ablation = summary.ablation_table(means)
    assert list(ablation.columns) == list(summary.ABLATION_COLUMNS)
    assert list(ablation["method"]) == ["hold_last", "constant_rate", "Kalman, hold", "Kalman", "Fusion",
                                        "Fusion, AR + replay", "VQF", "VQF, AR + replay"]  # the cells that ran
    assert ablation.set_index("method").loc["Kalman", "gap_handling"] == "AR + replay"
    grid = tables.ablation_grid(ablation)
    assert list(grid.index) == ["Madgwick", "Kalman", "Fusion", "VQF"]
    assert list(grid.columns) == ["hold", "constant rate", "AR + replay"] and grid.loc["Kalman", "constant rate"] == "—"
    assert grid.loc["Kalman", "AR + replay"].startswith(f"{ablation.set_index('method').loc['Kalman', 'mean']:.1f} [")
    pairs = summary.ablation_pairs(ablation)
    # Down a column: ours against the best peer with the same gap handling; along a row: against holding.
    assert pairs["filter"] == [("Kalman, hold", "Fusion"), ("Kalman", "VQF, AR + replay")]
    assert ("constant_rate", "hold_last") in pairs["gap handling"]
    assert ("Kalman", "Kalman, hold") in pairs["gap handling"]
    assert len(pairs["gap handling"]) == 4
    ratios = summary.ratio_table(per_trial, pairs["filter"], rng=np.random.default_rng(0), question="filter",
                                 n_boot=500, groups=groups)
    assert ratios["ratio"].to_numpy() == pytest.approx([20 / 35, 10 / 20], rel=0.02)
    assert ratios["ratio"].between(ratios["ci_low"], ratios["ci_high"]).all() and set(ratios["verdict"]) == {"lower"}
    sentences = tables.ablation_sentences(ratios, ablation)
    assert sentences[1].startswith("**Filter, AR + replay:** Kalman 10.0° against the best peer with the same gap "
                                   "handling, VQF, AR + replay, 20.0°: ratio 0.50")
    with pytest.raises(ValueError, match="nobody"):
        summary.ratio_table(per_trial, [("Kalman", "nobody")], rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="unknown gap handlings"):
        summary.ablation_table(means, {"Kalman": {"teleport": "Kalman"}})
    with pytest.raises(ValueError, match="no rmse_total row"):
        summary.ablation_table(means, {"Kalman": {"hold": "nobody"}})


def test_inclination_table_puts_a_second_study_beside_the_first():
    first = _per_trial({"Kalman": 10.0, "VQF": 20.0}).assign(rmse_inclination=lambda t: t["rmse_total"] / 2)
    neural = _per_trial({"RIANN": 30.0}).assign(rmse_inclination=lambda t: t["rmse_total"] / 2)
    table = summary.inclination_table(first, neural, rng=np.random.default_rng(0), n_boot=100)
    assert set(table["method"]) == {"Kalman", "VQF", "RIANN"} and set(table["metric"]) == {"rmse_inclination"}
    with pytest.raises(ValueError, match="share method names"):
        summary.inclination_table(first, first, rng=np.random.default_rng(0))


# --- figures ------------------------------------------------------------------------------------------


def test_lines_that_sit_together_get_distinct_hues():
    from wsnlib.plotting.loss_tolerance import _distinct_colors
    from wsnlib.plotting.style import METHOD_COLORS

    colors = _distinct_colors(["VQF (defaults)", "VQF, AR + replay", "Fusion, AR + replay", "Kalman"])
    assert len(set(colors.values())) == 4
    assert colors["VQF (defaults)"] == METHOD_COLORS["VQF (defaults)"] and colors["Kalman"] == METHOD_COLORS["Kalman"]
    assert colors["VQF, AR + replay"] not in {METHOD_COLORS[m] for m in ("VQF", "Fusion", "Kalman")}
    assert _distinct_colors(["hold_last", "Kalman"]) == {m: METHOD_COLORS[m] for m in ("hold_last", "Kalman")}


# --- the design chosen in the fold ------------------------------------------------------------------


def test_designs_cross_the_grid_and_stay_outside_the_search_space():
    space = {"acc_noise_density": lt.Range(0.002, 0.2)}
    designs = ({}, {"gyro_noise": 0.01})
    grid = lt.method_grid(space, 3, designs)
    assert grid == ({"acc_noise_density": 0.002}, {"acc_noise_density": 0.02}, {"acc_noise_density": 0.2},
                    {"gyro_noise": 0.01, "acc_noise_density": 0.002}, {"gyro_noise": 0.01, "acc_noise_density": 0.02},
                    {"gyro_noise": 0.01, "acc_noise_density": 0.2})
    methods = lt.default_methods()
    for name in ("Kalman, design in fold", "smoother, design in fold"):
        method = methods[name]
        assert method.designs == lt.KALMAN_DESIGNS and method.designs[0] == {}
        assert len(method.grid) == len(lt.KALMAN_DESIGNS) * lt.DEFAULT_BUDGET
        # The empty design's block is the designed-on-all entry's grid: the same settings, then the alternatives.
        base = name.replace(", design in fold", "")
        assert method.grid[:lt.DEFAULT_BUDGET] == methods[base].grid and method.space == methods[base].space
        for setting in method.grid:
            KalmanSettings(**setting)
    assert len(lt.with_budget(methods, 2)["Kalman, design in fold"].grid) == 2 * len(lt.KALMAN_DESIGNS)
    assert set(lt.DESIGNED_ON_BROAD) | {m for pair in lt.DESIGN_PAIRS for m in pair} <= set(methods)
    with pytest.raises(ValueError, match="outside its search space"):
        dataclasses.replace(methods["Kalman"], designs=({"acc_noise_density": 0.1},))
    sentence = tables.budget_sentence(methods)
    assert f"**{lt.DEFAULT_BUDGET} settings**" in sentence and f"{len(lt.KALMAN_DESIGNS)} designs" in sentence
    assert "designs chosen in the fold" in tables.method_table(methods).loc["Kalman, design in fold", "grid"]


def _pools_per_trial(means: dict, trials=("a", "b", "c")) -> pd.DataFrame:
    """Rows at the headline: method → (kind, mean RMSE), the same on every trial."""
    return pd.DataFrame([{"trial": t, "method": m, "kind": kind, "profile": p, "draw": 0, "rmse_total": value,
                          "latency_rule": "none" if kind != "offline" else "offline"}
                         for m, (kind, value) in means.items() for t in trials for p in ("lossless", lt.HEADLINE)])


def test_a_method_designed_on_the_scored_trials_does_not_stand_for_ours():
    per_trial = _pools_per_trial({"Kalman": ("causal", 10.0), "Kalman, design in fold": ("causal", 12.0),
                            "smoother": ("offline", 5.0), "smoother, design in fold": ("offline", 6.0),
                            "VQF, AR + replay": ("peer", 20.0), "VQF (defaults)": ("peer", 30.0)})
    assert summary.best_methods(per_trial)["causal"] == "Kalman"
    best = summary.best_methods(per_trial, exclude=lt.DESIGNED_ON_BROAD)
    assert (best["causal"], best["offline"]) == ("Kalman, design in fold", "smoother, design in fold")
    targets = summary.targets_table(per_trial, rng=np.random.default_rng(0), n_boot=100,
                                    exclude=lt.DESIGNED_ON_BROAD)
    assert targets.loc["best causal / best peer as users run them (GE 10 %)", "measured"] == pytest.approx(12 / 30)
    assert targets.loc["smoother / best peer, same gap handling (GE 10 %)", "compares"] == (
        "smoother, design in fold / VQF, AR + replay")


def test_design_choices_name_the_design_of_each_fold_and_the_sentence_its_optimism():
    method = lt.default_methods()["Kalman, design in fold"]
    n = lt.DEFAULT_BUDGET
    choices = pd.DataFrame({"method": method.name, "trial": ["a", "b", "c", "d"],
                            "setting_index": [5, n + 2, n + 7, 7 * n]})  # defaults; gyro_noise twice; mag_norm_tau_s
    table = summary.design_choices({method.name: method}, choices).set_index("design")
    assert table["n_trials"].to_dict() == {"defaults": 1, "gyro_noise=0.01": 2, "mag_norm_tau_s=20": 1}
    assert table.loc["gyro_noise=0.01", "trials"] == "b, c"
    ratios = pd.DataFrame([{"question": "design in fold", "method": method.name, "against": "Kalman", "mean": 16.0,
                            "mean_against": 15.0, "ratio": 16 / 15, "ci_low": 0.98, "ci_high": 1.2, "verdict": "tie"}])
    (sentence,) = tables.design_sentences(ratios, table.reset_index())
    assert "16.00° against 15.00°" in sentence and "flattered it by 1.00°" in sentence and "a tie" in sentence
    assert "gyro_noise=0.01 on 2; defaults on 1; mag_norm_tau_s=20 on 1" in sentence


def test_the_folds_choose_a_clearly_better_design():
    """A design that spoils the filter (its gyroscope and bias trusted far less than they are) is
    chosen by no fold; the study's choice for each trial is the leave-one-out choice over the
    designs × the settings."""
    from _recordings import turning_recording

    def recording(seed):
        gyr, acc, mag, quat = turning_recording(n=400, seed=seed, noise=0.05)
        return types.SimpleNamespace(gyr=gyr, acc=acc, mag=mag, quat_ref=quat, movement=np.ones(400, bool),
                                     n_samples=400, fs=50.0)

    kalman = lt.default_methods()["Kalman, design in fold"]
    bad = {"gyro_noise": 5.0, "bias_noise": 1.0}
    method = dataclasses.replace(kalman, designs=(bad, {}), grid=lt.method_grid(kalman.space, 2, (bad, {})))
    recordings = {f"t{i}": recording(i) for i in range(3)}
    profiles = [p for p in lt.PROFILES if p.name in ("lossless", lt.HEADLINE)]
    result = lt.evaluate(recordings, rng=np.random.default_rng(1), methods={method.name: method}, profiles=profiles,
                         n_jobs=1, progress=False)
    scores = result.tuning.pivot(index="setting_index", columns="trial", values="rmse_total")
    assert scores.iloc[:2].mean(axis=1).min() > scores.iloc[2:].mean(axis=1).min()  # the bad design is worse
    chosen = result.choices.set_index("trial").loc[list(scores.columns), "setting_index"].to_numpy()
    np.testing.assert_array_equal(chosen, loto.leave_one_out_choice(scores.to_numpy(), groups=list(scores.columns)))
    assert (chosen >= 2).all()
    assert set(summary.design_choices({method.name: method}, result.choices)["design"]) == {"defaults"}


def test_the_smoother_runs_with_the_setting_chosen_for_its_filter():
    """Its forward pass is the filter: one settings object for both, not a second tuning."""
    from _recordings import turning_recording

    def recording(seed):
        gyr, acc, mag, quat = turning_recording(n=300, seed=seed, noise=0.05)
        return types.SimpleNamespace(gyr=gyr, acc=acc, mag=mag, quat_ref=quat, movement=np.ones(300, bool),
                                     n_samples=300, fs=50.0)

    registry = lt.with_budget({m: lt.default_methods()[m] for m in ("Kalman", "smoother")}, 2)
    assert registry["smoother"].setting_of == "Kalman"
    assert lt.default_methods()["smoother, design in fold"].setting_of == "Kalman, design in fold"
    recordings = {f"t{i}": recording(i) for i in range(3)}
    profiles = [p for p in lt.PROFILES if p.name in ("lossless", lt.HEADLINE)]
    result = lt.evaluate(recordings, rng=np.random.default_rng(2), methods=registry, profiles=profiles, n_jobs=1,
                         progress=False)
    chosen = result.choices.pivot(index="trial", columns="method", values="setting_index")
    assert (chosen["smoother"] == chosen["Kalman"]).all()
    assert set(result.tuning["method"]) == {"Kalman"}  # the smoother is not tuned on its own score
    scored = result.per_trial.drop_duplicates(["method", "trial"]).pivot(index="trial", columns="method",
                                                                         values="setting")
    assert (scored["smoother"] == scored["Kalman"]).all()
    with pytest.raises(ValueError, match="include 'Kalman' in methods"):
        lt.evaluate(recordings, rng=np.random.default_rng(2), methods={"smoother": registry["smoother"]},
                    profiles=profiles, n_jobs=1, progress=False)
