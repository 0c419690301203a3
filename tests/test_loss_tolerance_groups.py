"""Leave-one-group-out in the loss-tolerance study (issue 25): groups, masks per profile, optimism, edge picks."""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from wsnlib.io.broad import broad_motion_group
from wsnlib.io.recording import write_recording
from wsnlib.sim import reach_and_flex, simulate_recording
from wsnlib.studies import loss_tolerance as lt
from wsnlib.studies.loss_tolerance import summary

LOSSLESS = (lt.PROFILES[0],)


def _units(tmp_path, n=4):
    for k in range(n):
        rec = simulate_recording(reach_and_flex(fs=50.0, duration_s=6.0), rng=np.random.default_rng(k))
        write_recording(rec, tmp_path / f"r{k}.csv")
    return lt.load_recordings(sorted(tmp_path.glob("*.csv")), progress=False)


def test_broad_motion_groups_are_issue_25s_seven_on_the_shared_trials():
    shared = ["02_undisturbed_slow_rotation_B", "04_undisturbed_slow_rotation_with_breaks_A",
              "05_undisturbed_slow_rotation_with_breaks_B", "07_undisturbed_fast_rotation_B",
              "09_undisturbed_fast_rotation_with_breaks_B", "11_undisturbed_slow_translation_B",
              "14_undisturbed_slow_translation_with_breaks_B", "16_undisturbed_fast_translation_B",
              "25_disturbed_tapping_B", "27_disturbed_phone_vibration_B", "29_disturbed_stationary_magnet_B",
              "30_disturbed_stationary_magnet_C", "31_disturbed_stationary_magnet_D",
              "33_disturbed_attached_magnet_2cm",
              "34_disturbed_attached_magnet_3cm", "35_disturbed_attached_magnet_4cm",
              "36_disturbed_attached_magnet_5cm"]
    groups = pd.Series({t: broad_motion_group(t) for t in shared})
    members = {g: sorted(t[:2] for t in ts) for g, ts in groups.groupby(groups).groups.items()}
    assert members == {"slow rotation": ["02", "04", "05"], "fast rotation": ["07", "09"],
                       "slow translation": ["11", "14"], "fast translation": ["16"],
                       "tapping and vibration": ["25", "27"], "stationary magnet": ["29", "30", "31"],
                       "attached magnet": ["33", "34", "35", "36"]}
    assert broad_motion_group(22) == "fast combined"
    with pytest.raises(ValueError, match="unknown BROAD trial"):
        broad_motion_group("not_a_trial")


def test_leave_one_group_out_tunes_each_trial_on_the_other_groups(tmp_path):
    units = _units(tmp_path)
    names = list(units)
    groups = {name: "r0, r1" if name.split("/")[0] in ("r0", "r1") else "r2, r3" for name in names}
    methods = lt.with_budget({"hold_last": lt.default_methods()["hold_last"]}, 4)
    result = lt.evaluate(units, rng=np.random.default_rng(0), methods=methods, profiles=LOSSLESS,
                         headline="lossless", groups=groups, n_jobs=1, progress=False)
    assert result.setting_source == "leave-one-group-out"
    assert list(result.units["group"]) == [groups[n] for n in names]
    scores = result.tuning.pivot(index="setting_index", columns="trial", values="rmse_total")[names].to_numpy()
    for name in names:
        others = [k for k, other in enumerate(names) if groups[other] != groups[name]]
        chosen = result.choices.set_index("trial").loc[name, "setting_index"]
        assert chosen == int(np.argmin(scores[:, others].mean(axis=1)))
    optimism = summary.optimism_table(result.tuning, result.choices).loc["hold_last"]
    best_overall = scores.mean(axis=1).min()
    assert np.isclose(optimism["in_sample"], best_overall) and optimism["held_out"] >= best_overall - 1e-12
    assert np.isclose(optimism["optimism"], optimism["held_out"] - best_overall)


def test_groups_must_label_every_trial_and_keep_recordings_whole(tmp_path):
    units = _units(tmp_path, n=2)
    names = list(units)  # "r0/humerus", "r0/forearm", …: two nodes per recording
    methods = {"hold_last": lt.default_methods()["hold_last"]}
    run = dict(rng=np.random.default_rng(0), methods=lt.with_budget(methods, 1), profiles=LOSSLESS,
               headline="lossless", n_jobs=1, progress=False)
    with pytest.raises(ValueError, match="no label"):
        lt.evaluate(units, groups={names[0]: "a"}, **run)
    split = {name: str(k) for k, name in enumerate(names)}
    with pytest.raises(ValueError, match="held out whole"):
        lt.evaluate(units, groups=split, **run)


def test_a_profiles_masks_do_not_depend_on_the_other_profiles(tmp_path):
    units = _units(tmp_path, n=1)
    headline = lt.PROFILES[3]
    methods = lt.with_budget({"hold_last": lt.default_methods()["hold_last"]}, 1)
    run = dict(methods=methods, headline="lossless", draws=2, n_jobs=1, progress=False)
    full = lt.evaluate(units, rng=np.random.default_rng(7), profiles=lt.PROFILES, **run).per_trial
    subset = lt.evaluate(units, rng=np.random.default_rng(7), profiles=(lt.PROFILES[0], headline), **run).per_trial
    columns = ["trial", "draw", "lost_share", "rmse_total"]
    pd.testing.assert_frame_equal(full[full["profile"] == headline.name][columns].reset_index(drop=True),
                                  subset[subset["profile"] == headline.name][columns].reset_index(drop=True))
    other = lt.evaluate(units, rng=np.random.default_rng(8), profiles=(lt.PROFILES[0], headline), **run).per_trial
    assert not np.array_equal(other["rmse_total"].to_numpy(), subset["rmse_total"].to_numpy())


def test_edge_picks_tell_a_bound_from_a_narrow_grid():
    method = lt.Method("m", "causal", lt.settings_grid(beta=(0.01, 0.1, 1.0)), lambda *a: None,
                       space={"beta": lt.Range(0.01, 10.0)})
    choices = pd.DataFrame({"method": "m", "trial": ["a", "b", "c"], "setting_index": [0, 2, 2]})
    table = summary.edge_picks({"m": method}, choices).set_index("edge")
    assert table.loc["low", "verdict"] == "at a bound of the space" and table.loc["low", "n_trials"] == 1
    assert table.loc["high", "verdict"] == "grid too narrow" and table.loc["high", "n_trials"] == 2
    single = dataclasses.replace(method, grid=({"beta": 0.1},))
    assert summary.edge_picks({"m": single}, choices.assign(setting_index=0)).empty
