"""The loss-tolerance study (issue 11): registry, loss profiles, leave-one-trial-out tuning, summaries."""

import dataclasses
import functools
import types

import numpy as np
import pandas as pd
import pytest
from _recordings import turning_recording

from wsnlib import loss, loto, plotting, stats
from wsnlib.orientation import KalmanSettings
from wsnlib.studies import loss_tolerance as lt
from wsnlib.studies.loss_tolerance import summary as lts

#: Rate of the test recordings (Hz).
FS = 50.0


def _recording(seed, n=600):
    gyr, acc, mag, quat = turning_recording(n=n, seed=seed, noise=0.01)
    ref = quat.copy()
    ref[100:110] = np.nan  # optical markers lost for a moment
    movement = np.ones(n, bool)
    movement[:25] = False
    return types.SimpleNamespace(gyr=gyr, acc=acc, mag=mag, quat_ref=ref, movement=movement, n_samples=n, fs=FS)


def _small_methods():
    """Five methods with small grids near their defaults (the registry's grids span the physical
    bounds: their first settings are extreme)."""
    methods = lt.default_methods()
    kalman = ({}, {"acc_noise_density": 0.02, "mag_noise_density": 0.02})
    grids = {"hold_last": ({"beta": 0.041},), "constant_rate": ({"beta": 0.041},), "Kalman": kalman,
             "smoother": kalman[:1], "VQF (defaults)": methods["VQF (defaults)"].grid}
    return {name: dataclasses.replace(methods[name], grid=grid) for name, grid in grids.items()}


@pytest.fixture(scope="module")
def small_study():
    recordings = {f"trial{i}": _recording(i) for i in range(3)}
    result = lt.evaluate(recordings, rng=np.random.default_rng(7), methods=_small_methods(), progress=False)
    return recordings, result


def test_registry_grids_kinds_and_colours():
    methods = lt.default_methods()
    assert {"hold_last", "constant_rate", "gyro_interpolation", "Kalman", "smoother", "Fusion", "VQF"} <= set(methods)
    for name, method in methods.items():
        assert len(method.grid) == (lt.DEFAULT_BUDGET * max(1, len(method.designs)) if method.space else 1)
        assert method.kind in lt.KINDS and method.latency in lt.LATENCY_RULES
        plotting.method_style(name)  # every method has a colour and marker
    assert methods["gyro_interpolation"].latency == "none" and methods["smoother"].kind == "offline"
    with pytest.raises(ValueError, match="grid"):
        lt.Method("x", "causal", (), print)
    with pytest.raises(ValueError, match="Range or a Choice"):
        lt.Method("x", "causal", ({},), print, space={"beta": (0.1, 1.0)})
    with pytest.raises(ValueError, match="kind"):
        lt.Method("x", "ours", ({},), print)


def test_a_setting_the_method_does_not_use_is_refused():
    """Issue 23: an option the chosen method ignores (rho for the Kalman filter) was accepted silently."""
    rec = types.SimpleNamespace(gyr=np.zeros((10, 3)), acc=np.zeros((10, 3)), mag=np.zeros((10, 3)))
    received = np.ones((1, 10), dtype=bool)
    for method in lt.default_methods().values():
        with pytest.raises(ValueError, match=r"setting\(s\) \['rho'\] are not used by this method"):
            method.run(rec, {**method.grid[0], "rho": 1.0}, received)


def test_a_budget_gives_every_method_the_same_number_of_settings_from_bound_to_bound():
    methods = lt.default_methods()
    for budget in (2, 12, 30):
        budgeted = lt.with_budget(methods, budget)
        again = lt.default_methods(budget)  # one way to define what is tuned: the space
        assert {name: m.grid for name, m in budgeted.items()} == {name: m.grid for name, m in again.items()}
        for name, method in budgeted.items():
            if not method.space:  # VQF with its authors' setting: nothing to tune
                assert method.grid == methods[name].grid
                continue
            size = budget * max(1, len(method.designs))  # ours with their design chosen in the fold: × designs
            assert len(method.grid) == size and len({repr(s) for s in method.grid}) == size
            for key, axis in method.space.items():
                values = [setting[key] for setting in method.grid]
                assert axis.low <= min(values) and max(values) <= axis.high
                if budget >= 12:  # every axis gets at least 3 values: both bounds are in the grid
                    assert min(values) == axis.low and max(values) == axis.high
    # Pairs compared with and without an option, and the filter and its smoother, get the same settings.
    budgeted = lt.with_budget(methods, 12)
    for a, b in lt.GATING_PAIRS + lt.GAP_PREDICTION_PAIRS + (("Kalman", "smoother"),):
        if methods[a].space == methods[b].space:
            assert budgeted[a].grid == budgeted[b].grid
    for setting in budgeted["Kalman"].grid:
        KalmanSettings(**setting)
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="budget"):
            lt.with_budget(methods, bad)
    with pytest.raises(ValueError, match="low < high"):
        lt.Range(1.0, 1.0)
    with pytest.raises(ValueError, match="low > 0"):
        lt.Range(0.0, 1.0)


def test_the_study_gives_the_same_tables_on_one_process_local_processes_and_a_dask_cluster(small_study):
    from distributed import LocalCluster

    recordings, result = small_study  # local worker processes (the default)
    runs = {"one process": {"n_jobs": 1}}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        runs["Dask cluster, 2 workers"] = {"scheduler": cluster.scheduler_address}
        for where, options in runs.items():
            other = lt.evaluate(recordings, rng=np.random.default_rng(7), methods=_small_methods(), progress=False,
                                **options)
            for table in ("per_trial", "tuning", "choices"):
                pd.testing.assert_frame_equal(getattr(other, table), getattr(result, table), obj=f"{where}: {table}")
            for name, trace in result.traces.items():
                for method, error in trace["lossless"].items():
                    np.testing.assert_array_equal(other.traces[name]["lossless"][method], error)
            assert set(other.seconds.index) == set(result.seconds.index) and (other.seconds > 0).all()


def test_a_budget_beyond_one_job_is_scored_setting_by_setting_as_in_a_small_grid():
    """With more settings than SETTINGS_PER_JOB a method's tuning is split over jobs; each
    setting's score is still the one it gets on its own."""
    recordings = {f"trial{i}": _recording(i, n=300) for i in range(2)}
    profiles = [p for p in lt.PROFILES if p.name in ("lossless", lt.HEADLINE)]
    method = lt.with_budget({"hold_last": lt.default_methods()["hold_last"]}, lt.SETTINGS_PER_JOB + 3)["hold_last"]
    tail = dataclasses.replace(method, grid=method.grid[lt.SETTINGS_PER_JOB:])
    runs = [lt.evaluate(recordings, rng=np.random.default_rng(5), methods={"hold_last": m}, profiles=profiles,
                        n_jobs=2, progress=False).tuning for m in (method, tail)]
    whole = runs[0][runs[0]["setting_index"] >= lt.SETTINGS_PER_JOB].reset_index(drop=True)
    pd.testing.assert_frame_equal(whole.drop(columns="setting_index"), runs[1].drop(columns="setting_index"))
    assert len(runs[0]) == (lt.SETTINGS_PER_JOB + 3) * 2


def test_run_jobs_keeps_the_jobs_order_and_checks_its_arguments():
    from wsnlib.parallel import run_jobs

    jobs = [(n, 3) for n in range(7, -1, -1)]
    assert run_jobs(pow, jobs, n_jobs=2, in_process_first=3) == [n**3 for n in range(7, -1, -1)]
    assert run_jobs(pow, jobs, n_jobs=1) == [n**3 for n in range(7, -1, -1)] and run_jobs(pow, [], n_jobs=2) == []
    for bad in (0, -2, 1.5, True):
        with pytest.raises(ValueError, match="n_jobs"):
            run_jobs(pow, jobs, n_jobs=bad)
    with pytest.raises(ValueError, match="in_process_first"):
        run_jobs(pow, jobs, in_process_first=-1)
    with pytest.raises(ValueError, match="scheduler"):
        run_jobs(pow, jobs, scheduler=8786)


def test_local_workers_counts_what_run_jobs_starts():
    import joblib

    from wsnlib.parallel import local_workers

    assert local_workers(-1) == joblib.cpu_count() and local_workers(3) == 3
    for bad in (0, -2, 1.5, True):
        with pytest.raises(ValueError, match="n_jobs"):
            local_workers(bad)


def test_settings_grid():
    grid = lt.settings_grid({"mag_norm_gate": 0.05}, replay=(True, False), acc_innovation_gate=(13.8, 6.0))
    assert grid == ({"mag_norm_gate": 0.05, "replay": True, "acc_innovation_gate": 13.8},
                    {"mag_norm_gate": 0.05, "replay": True, "acc_innovation_gate": 6.0},
                    {"mag_norm_gate": 0.05, "replay": False, "acc_innovation_gate": 13.8},
                    {"mag_norm_gate": 0.05, "replay": False, "acc_innovation_gate": 6.0})
    with pytest.raises(ValueError, match="replay"):
        lt.settings_grid(replay=())


def test_registry_options_and_side_question_pairs():
    methods = lt.default_methods()
    # Every Kalman/smoother setting is a valid KalmanSettings (a typo would raise here, not mid-study).
    for name in ("Kalman", "smoother", "Kalman, hold"):
        assert len(methods[name].grid) == lt.DEFAULT_BUDGET
        for setting in methods[name].grid:
            KalmanSettings(**setting)
    for without, with_ in lt.GATING_PAIRS + lt.GAP_PREDICTION_PAIRS:
        assert methods[without].kind == methods[with_].kind and methods[without].grid == methods[with_].grid
    # The ablation names methods of the registry, each in one cell; the pairs ask each filter about each gap handling.
    cells = [m for row in lt.ABLATION.values() for m in row.values()]
    assert len(cells) == len(set(cells)) and set(cells) <= set(methods)
    assert all(gap in lt.GAP_HANDLINGS for row in lt.ABLATION.values() for gap in row)
    assert len(lt.GAP_PREDICTION_PAIRS) == len(cells) - len(lt.ABLATION)
    assert set(lt.AS_USERS_RUN_THEM) <= set(methods) and all(len(methods[m].grid) == 1 for m in lt.AS_USERS_RUN_THEM)
    assert lt.GAP_HANDLING_OF["Kalman"] == lt.GAP_HANDLING_OF["VQF, AR + replay"] == "AR + replay"


def test_gap_prediction_and_gate_change_nothing_without_loss_but_act_under_loss():
    rec = _recording(0, n=400)
    masks = np.stack([np.ones(400, bool), loss.LossProfile.burst(2.0, 4, period_s=3.0).mask(400, FS, None)])
    methods = lt.default_methods()
    for without, with_ in lt.GAP_PREDICTION_PAIRS:
        setting = methods[without].grid[len(methods[without].grid) // 2]
        hold, predict = methods[without].run(rec, setting, masks), methods[with_].run(rec, setting, masks)
        np.testing.assert_allclose(hold[0], predict[0], atol=1e-12)  # no gap: the same filter
        lost = ~masks[1]
        assert np.abs(hold[1][lost] - predict[1][lost]).max() > 1e-3  # in a gap: predicting moves on
    setting = {"beta": 0.041, "rho_tau": 6}
    plain = methods["hybrid (feedback)"].run(rec, setting, masks)
    gated = methods["gated hybrid (feedback)"].run(rec, setting, masks)
    assert plain.shape == gated.shape == (2, 400, 4) and np.isfinite(gated).all()


def test_registry_runs_the_filters_with_the_loss_vocabulary():
    """The registry's methods are the orientation filters with the keywords of their names."""
    from wsnlib.orientation import estimate_orientation, fusion_orientation, kalman_orientation, madgwick

    rec = _recording(1, n=300)
    masks = np.stack([loss.LossProfile.burst(2.0, 4, period_s=3.0).mask(300, FS, None), np.arange(300) % 9 != 4])
    methods = lt.default_methods()
    args = (rec.gyr, rec.acc, rec.mag)
    beta = {"beta": 0.041}
    expected = {"hold_last": madgwick(*args, fs=FS, beta=0.041, received=masks),
                "constant_rate": estimate_orientation(*args, fs=FS, beta=0.041, received=masks, gap="constant_rate"),
                "gyro_interpolation": estimate_orientation(*args, fs=FS, beta=0.041, received=masks, replay=True)}
    for name, quat in expected.items():
        np.testing.assert_array_equal(methods[name].run(rec, beta, masks), quat)
    setting = {"acc_noise_density": 0.02, "mag_noise_density": 0.01}
    kalman = {"Kalman": {}, "Kalman, AR": {"replay": False}, "Kalman, hold": {"gap": "hold", "replay": False},
              "Kalman, constant rate": {"gap": "constant_rate", "replay": False, "gap_time_constant": np.inf}}
    for name, options in kalman.items():
        np.testing.assert_array_equal(methods[name].run(rec, setting, masks),
                                      kalman_orientation(*args, fs=FS, received=masks,
                                                         settings=KalmanSettings(**setting), **options))
    assert not np.array_equal(methods["Kalman"].run(rec, setting, masks),
                              methods["Kalman, AR"].run(rec, setting, masks))
    setting = {"beta": 0.1, "rho_tau": 6}
    np.testing.assert_array_equal(methods["hybrid (feedback)"].run(rec, setting, masks),
                                  estimate_orientation(*args, fs=FS, beta=0.1, received=masks, blend="feedback",
                                                       rho=1.0, tau=6))
    setting = {"gain": 0.5, "rho_tau": 6}
    signals = [np.broadcast_to(x, masks.shape + (3,)) for x in args]
    np.testing.assert_array_equal(methods["Fusion + hybrid (feedback)"].run(rec, setting, masks),
                                  fusion_orientation(*signals, fs=FS, received=masks, gain=0.5, blend="feedback",
                                                     rho=1.0, tau=6))
    # Fusion's rejection: one angle for the acceleration and the magnetic rejection, with a timeout.
    rejection = {"acceleration_rejection": 10.0, "magnetic_rejection": 10.0, "rejection_timeout": 5.0}
    np.testing.assert_array_equal(methods["Fusion"].run(rec, {"gain": 0.5, "rejection_deg": 10.0}, masks),
                                  fusion_orientation(*signals, fs=FS, received=masks, gain=0.5, settings=rejection))
    np.testing.assert_array_equal(methods["Fusion (defaults)"].run(rec, {"gain": 0.5}, masks),
                                  fusion_orientation(*signals, fs=FS, received=masks, gain=0.5))


def test_single_frame_trust_falls_under_acceleration():
    calm = _recording(1)
    shaken = types.SimpleNamespace(**vars(calm))
    shaken.acc = calm.acc.copy()
    shaken.acc[300:] += np.array([15.0, 0.0, 0.0])  # 1.5 g of linear acceleration on the second half
    trust = lt.single_frame_trust({"calm": calm, "shaken": shaken})
    assert list(trust.index) == ["calm", "shaken"] and trust["trusted_share"].between(0, 1).all()
    assert trust.loc["shaken", "trusted_share"] < trust.loc["calm", "trusted_share"] - 0.4
    still = types.SimpleNamespace(**vars(calm))
    still.movement = np.zeros(calm.n_samples, bool)
    with pytest.raises(ValueError, match="movement"):
        lt.single_frame_trust({"still": still})


def test_paired_comparisons_verdicts_and_sentences():
    rows = []
    for j, (base, better, worse, mixed) in enumerate([(10, 8, 12, 9), (12, 9, 15, 13), (11, 9, 14, 10),
                                                       (13, 10, 16, 14), (9, 7, 11, np.nan)]):
        for method, value in (("base", base), ("better", better), ("worse", worse), ("mixed", mixed)):
            rows.append({"trial": f"t{j}", "method": method, "profile": lt.HEADLINE, "rmse_total": value})
    per_trial = pd.DataFrame(rows)
    table = lts.paired_comparisons(per_trial, [("base", "better"), ("base", "worse"), ("base", "mixed")],
                                   rng=np.random.default_rng(0), question="q", n_boot=500)
    assert list(table.columns) == list(lts.COMPARISON_COLUMNS)
    assert list(table["verdict"]) == ["helps", "hurts", "tie"]
    assert table.loc[0, "difference"] == pytest.approx(-2.4) and table.loc[0, "n_better"] == 5
    assert table.loc[2, "n_trials"] == 4 and table.loc[2, "n_better"] == 2  # the NaN trial left out
    assert table["difference"].between(table["ci_low"], table["ci_high"]).all()
    sentences = lts.comparison_sentences(table)
    assert "**better**" in sentences[0] and "**worse**" in sentences[1] and "**a tie**" in sentences[2]
    assert "lower on 5 of 5 trials" in sentences[0]
    with pytest.raises(ValueError, match="nobody"):
        lts.paired_comparisons(per_trial, [("base", "nobody")], rng=np.random.default_rng(0))


def test_profiles_masks():
    n, fs = 3000, FS
    by_name = {p.name: p for p in lt.PROFILES}
    assert by_name["lossless"].mask(n, fs, np.random.default_rng(0)).all()
    movement = np.ones(n, bool)
    movement[:1000] = False  # bursts fall in the movement, with 0.5 s before and 4 s after them
    bursts = by_name["paper burst"].masks(movement, fs)
    assert bursts.shape == (8, n)
    for mask in bursts:
        runs = loss.burst_lengths(mask)
        assert runs.size == 1 and runs[0] == 24  # one 4-packet burst per run
        start = np.flatnonzero(~mask)[0]
        assert 1000 <= start and start + 24 + 4 * fs <= n
    starts = by_name["paper burst"].starts(movement, fs)
    assert np.all(np.diff(starts) > 0) and starts[0] < 1300 and starts[-1] > 2300  # spread over the movement
    ge = by_name[lt.HEADLINE]
    a, b = ge.mask(n, fs, np.random.default_rng(3)), ge.mask(n, fs, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    long = ge.mask(200_000, fs, np.random.default_rng(4))
    assert abs(1 - long.mean() - 0.10) < 0.01
    twelve = by_name["GE 10 %, 12-sample packets"].mask(n, fs, np.random.default_rng(5))
    assert (loss.burst_lengths(twelve[:2988]) % 12 == 0).all()


def test_evaluate_tables_and_tuning_never_on_the_scored_trial(small_study):
    recordings, result = small_study
    table = result.per_trial
    burst = lt.PROFILES[1]
    assert len(table) == 5 * (len(lt.PROFILES) - 1 + burst.positions) * 3
    for method, rows in result.tuning.groupby("method", sort=False):
        scores = rows.pivot(index="setting_index", columns="trial", values="rmse_total")[list(recordings)]
        chosen = result.choices[result.choices["method"] == method].set_index("trial")["setting_index"]
        np.testing.assert_array_equal(chosen[list(recordings)].to_numpy(), loto.leave_one_out_choice(scores))
    # Every profile uses the setting chosen at the headline profile for that trial.
    assert (table.groupby(["method", "trial"])["setting"].nunique() == 1).all()
    lossless = table[table["profile"] == "lossless"]
    assert (lossless["n_lost"] == 0).all() and lossless["rms_lost"].isna().all()
    assert lossless["peak_increase_deg"].isna().all() and (lossless["n_gaps_scored"] == 0).all()
    lossy = table[table["profile"] != "lossless"]
    assert np.isfinite(lossy["rmse_total"]).all()
    # A short trial's draw may lose no movement sample with a reference: rms_lost is NaN there.
    assert np.isfinite(lossy["rms_lost"]).mean() > 0.9
    scored = lossy["n_gaps_scored"] > 0  # a gap whose response window runs past the end is not scored
    assert scored.mean() > 0.5
    assert np.isfinite(lossy.loc[scored, ["peak_increase_deg", "recovery_s", "recovered_share"]].to_numpy()).all()
    assert lossy.loc[~scored, "peak_increase_deg"].isna().all()
    assert (lossy["n_lost"] > 0).mean() > 0.9  # see rms_lost above
    # Without loss, holding and predicting the output in a gap are the same filter (same β, 0.01).
    same = lossless.pivot(index="trial", columns="method", values="rmse_total")
    np.testing.assert_allclose(same["hold_last"], same["constant_rate"])
    headline = table[table["profile"] == lt.HEADLINE].pivot(index="trial", columns="method", values="rmse_total")
    assert (headline["constant_rate"] != headline["hold_last"]).all()
    latency = table.set_index("method")["latency_s"]
    assert (latency.loc["Kalman"] == 0).all() and (latency.loc["smoother"] == 600 / FS).all()
    assert set(result.traces) == set(recordings) and set(result.traces["trial0"]["error"]) == set(result.methods)
    # One burst per run: its response against the error just before it, only under the burst profile.
    bursts = table[table["profile"] == burst.name]
    assert (bursts.groupby(["method", "trial"])["draw"].nunique() == burst.positions).all()
    scored = bursts[["burst_before_deg", "burst_peak_increase_deg", "burst_recovery_s"]].to_numpy()
    assert np.isfinite(scored).mean() > 0.9
    assert table.loc[table["profile"] != burst.name, list(lt.evaluation.BURST_COLUMNS)].isna().all().all()
    assert bursts["burst_recovery_s"].max() <= burst.window_s
    # The traced run is the burst during which the sensor turns at the median rate of the trial's bursts.
    rec, trace = recordings["trial0"], result.traces["trial0"]
    assert trace["burst_ends"].size == 1
    rate = np.linalg.norm(rec.gyr, axis=-1)
    during = [rate[~mask].mean() for mask in burst.masks(rec.movement, FS)]
    assert rate[~trace["received"]].mean() == sorted(during)[(burst.positions - 1) // 2]


def test_evaluate_is_reproducible_and_checks_its_inputs(small_study):
    recordings, result = small_study
    again = lt.evaluate(recordings, rng=np.random.default_rng(7), methods=_small_methods(), progress=False)
    pd.testing.assert_frame_equal(result.per_trial, again.per_trial)
    # One recording runs untuned (tests/test_loss_tolerance_recordings.py); none is refused.
    with pytest.raises(ValueError, match="at least one recording"):
        lt.evaluate({}, rng=np.random.default_rng(0), progress=False)
    with pytest.raises(ValueError, match="headline"):
        lt.evaluate(recordings, rng=np.random.default_rng(0), headline="GE 50 %", methods=_small_methods(),
                    progress=False)
    with pytest.raises(ValueError, match="rng"):
        lt.evaluate(recordings, rng=0, progress=False)


def test_the_filter_and_smoother_beat_holding_under_loss(small_study):
    _, result = small_study
    headline = result.per_trial[result.per_trial["profile"] == lt.HEADLINE].groupby("method")["rmse_total"].mean()
    assert headline["smoother"] < headline["Kalman"] < headline["hold_last"]


def _synthetic_per_trial(causal, peer, offline, lossless_causal, lossless_vqf):
    rows = []
    for j in range(len(causal)):
        for profile, values in ((lt.HEADLINE, (causal[j], peer[j], offline[j], peer[j] + 5)),
                                ("lossless", (lossless_causal[j], 1.0, 1.0, lossless_vqf[j]))):
            for (method, kind, latency), value in zip(
                    [("Kalman", "causal", "none"), ("VQF, AR + replay", "peer", "none"),
                     ("smoother", "offline", "offline"),
                     ("VQF (defaults)", "peer", "none")], values, strict=True):
                rows.append({"trial": f"t{j}", "method": method, "kind": kind, "latency_rule": latency,
                             "profile": profile, "rmse_total": value,
                             "n_lost": 10, "n_after_gap": 30, "n_steady": 60,
                             "rms_lost": 3.0 * value, "rms_after_gap": value, "rms_steady": 0.5 * value})
    return pd.DataFrame(rows)


def test_targets_table_ratios_verdicts_and_sentences():
    per_trial = _synthetic_per_trial(causal=[4.0, 6.0, 5.0, 5.0], peer=[10.0, 10.0, 10.0, 10.0],
                                     offline=[3.0, 3.0, 3.0, 3.0], lossless_causal=[2.0, 2.5, 3.0, 2.5],
                                     lossless_vqf=[2.0, 2.0, 2.0, 2.0])
    targets = lts.targets_table(per_trial, rng=np.random.default_rng(0), n_boot=500)
    # Against the peer with the same gap handling (VQF, AR + replay: 10°) and the peers as users run
    # them (VQF (defaults): 15°).
    assert list(targets.index) == list(lts.TARGETS)
    assert list(targets["compares"]) == ["Kalman / VQF, AR + replay", "Kalman / VQF (defaults)",
                                         "smoother / VQF, AR + replay", "smoother / VQF (defaults)",
                                         "Kalman − VQF (defaults)"]
    np.testing.assert_allclose(targets["measured"], [0.5, 1 / 3, 0.3, 0.2, 0.5])
    assert list(targets["verdict"]) == ["PASS", "PASS", "MISS", "PASS", "PASS"]
    assert targets["margin"].iloc[2] == pytest.approx(0.05)
    assert (targets["ci_low"] <= targets["measured"]).all() and (targets["measured"] <= targets["ci_high"]).all()
    sentences = lts.target_sentences(targets)
    assert "MISS, by 0.05 (20 % of the target)" in sentences[2] and "PASS" in sentences[0]
    assert "PASS" in lts.format_targets(targets)
    # Without a peer of the same gap handling, those targets have no row (never a silent other peer).
    other = per_trial.replace({"VQF, AR + replay": "VQF"})
    assert list(lts.targets_table(other, rng=np.random.default_rng(0), n_boot=200)["compares"]) == [
        "Kalman / VQF (defaults)", "smoother / VQF (defaults)", "Kalman − VQF (defaults)"]


def test_error_budget_shares():
    per_trial = _synthetic_per_trial([4.0, 6.0], [10.0, 10.0], [3.0, 3.0], [2.0, 2.0], [2.0, 2.0])
    budget = lts.error_budget(per_trial, "Kalman")
    shares = budget[["share_lost", "share_after_gap", "share_steady"]]
    assert shares.sum() == pytest.approx(1.0)
    # 10 samples at 3x, 30 at 1x, 60 at 0.5x: squared weights 90, 30, 15.
    assert budget["share_lost"] == pytest.approx(90 / 135)
    assert "Kalman" in lts.diagnosis_sentence(per_trial, "Kalman")
    with pytest.raises(ValueError, match="no rows"):
        lts.error_budget(per_trial, "nobody")


def test_summary_and_ranking(small_study):
    _, result = small_study
    summary = lts.summary_table(result.per_trial, rng=np.random.default_rng(0), n_boot=200,
                                metrics=("rmse_total", "rms_lost"))
    assert (summary["ci_low"] <= summary["mean"]).all() and (summary["mean"] <= summary["ci_high"]).all()
    assert summary[(summary["metric"] == "rms_lost") & (summary["profile"] == "lossless")].empty
    ranking = lts.ranking(result.per_trial, rng=np.random.default_rng(0), n_boot=200)
    assert ranking.index[0] == "smoother" and set(ranking.index) == set(result.methods)


def test_ratio_of_means_ci():
    a, b = np.array([1.0, 2.0, 3.0, 4.0]), np.array([2.0, 4.0, 5.0, 9.0])
    ci = stats.ratio_of_means_ci(a, b, rng=np.random.default_rng(0), n_boot=1000)
    assert float(ci.estimate) == pytest.approx(0.5) and ci.low <= 0.5 <= ci.high and ci.method == "percentile"
    with pytest.raises(ValueError, match="b must be > 0"):
        stats.ratio_of_means_ci(a, -b, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="same shape"):
        stats.ratio_of_means_ci(a, b[:3], rng=np.random.default_rng(0))


def test_on_real_broad_trials():
    from wsnlib.io.broad import broad_trials

    names = broad_trials(present_only=True)[:2]
    if len(names) < 2:
        pytest.skip("needs two BROAD trials in $WSNLIB_BROAD_DIR")
    recordings = lt.load_recordings(names, progress=False)
    methods = lt.with_budget({m: lt.default_methods()[m] for m in ("hold_last", "Kalman", "smoother",
                                                                   "VQF (defaults)")}, 1)
    profiles = [p for p in lt.PROFILES if p.name in ("lossless", lt.HEADLINE)]
    result = lt.evaluate(recordings, rng=np.random.default_rng(0), methods=methods, profiles=profiles,
                         progress=False)
    headline = result.per_trial[result.per_trial["profile"] == lt.HEADLINE].set_index(["method", "trial"])
    # On real motion with GE 10 % loss, holding the output is far worse than our filter on every trial.
    assert (headline.loc["hold_last", "rmse_total"] > 2 * headline.loc["Kalman", "rmse_total"]).all()
    lossless = result.per_trial[result.per_trial["profile"] == "lossless"]
    assert (lossless["rmse_total"] < 10).all()


def test_gain_after_gap_exercise_checker():
    from wsnlib import exercises

    def right(p, s, n, fs, r):
        grown = p + (s * n / fs) ** 2
        return grown / (grown + r)

    assert exercises.check_gain_after_gap(right, rng=np.random.default_rng(0), n_cases=50).n_cases == 50
    with pytest.raises(AssertionError, match="expected"):  # the variance grown linearly, as a random walk
        exercises.check_gain_after_gap(lambda p, s, n, fs, r: (p + s**2 * n / fs) / (p + s**2 * n / fs + r),
                                       rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="rng"):
        exercises.check_gain_after_gap(right, rng=1)


# --- tables, selections and sentences of notebook 10 (wsnlib.studies.loss_tolerance_tables) ---------------------

def test_weight_vs_gap_reads_the_kalman_settings():
    from wsnlib.orientation import KalmanSettings
    from wsnlib.studies.loss_tolerance import tables as ltt

    weights = ltt.weight_vs_gap([0, 6, 24, 96], fs=50.0, prior_std_deg=1.0, rho=1.0, tau=6.0)
    paper = weights["paper: μ(λ), ρ = 1, τ = 6"].to_numpy()
    kalman = weights[ltt.KALMAN_WEIGHT_COLUMN].to_numpy()
    np.testing.assert_allclose(paper, 6.0 / (np.array([0, 6, 24, 96]) + 6.0))
    np.testing.assert_allclose(weights["gap (s)"], [0, 0.12, 0.48, 1.92])
    settings = KalmanSettings()
    prior = np.radians(1.0) ** 2
    grown = prior + (settings.gap_rate_noise * 24 / 50.0) ** 2
    mag_var = settings.mag_noise_density ** 2 * 50.0  # one sample's variance at 50 Hz
    assert kalman[2] == pytest.approx(mag_var / (grown + mag_var))
    assert np.all(np.diff(kalman) < 0) and paper[0] == 1.0
    # Noisier prediction in a gap: the first measurement after it is trusted more.
    noisy = ltt.weight_vs_gap([24], settings=dataclasses.replace(settings, gap_rate_noise=1.0))
    assert noisy[ltt.KALMAN_WEIGHT_COLUMN].iloc[0] < kalman[2]
    with pytest.raises(ValueError, match="lost_samples"):
        ltt.weight_vs_gap([-1, 6])
    with pytest.raises(ValueError, match="fs"):
        ltt.weight_vs_gap([6], fs=0.0)


def test_method_and_profile_tables_and_figure_inputs():
    from wsnlib.studies.loss_tolerance import tables as ltt

    methods = _small_methods()
    table = ltt.method_table(methods)
    assert list(table.index) == list(methods) and table.loc["Kalman", "settings"] == 2
    assert table.loc["hold_last", "grid"] == "beta: 0.041"
    assert table.loc["Kalman", "grid"] == "acc_noise_density: 0.02; mag_noise_density: 0.02"
    profiles = ltt.profile_table(lt.PROFILES)
    assert len(profiles) == len(lt.PROFILES)
    assert np.isnan(profiles.loc["paper burst", "mean burst (packets)"])
    assert profiles.loc["paper burst", "model"] == "burst positions"
    assert profiles.loc[lt.HEADLINE, "mean burst (packets)"] == 3.0
    means = pd.DataFrame({"profile": ["lossless", lt.HEADLINE], "method": ["Kalman", "Kalman"], "mean": [1.0, 2.0]})
    rates, bands, groups = ltt.error_vs_loss_rate_inputs(lt.PROFILES, means, ["Kalman", "VQF"])
    assert rates == {"lossless": 0.0, "GE 5 %": 0.05, lt.HEADLINE: 0.10, "GE 20 %": 0.20}
    assert bands.loc[(lt.HEADLINE, "Kalman"), "mean"] == 2.0
    assert groups["ours: hybrid, Kalman, smoother"] == ["Kalman"] and groups["peers"] == []


def test_slow_and_fast_trials_prefer_undisturbed():
    from wsnlib.studies.loss_tolerance import tables as ltt

    rates = pd.Series({"a_undisturbed": 30.0, "b_undisturbed": 90.0, "c_disturbed": 5.0, "d_disturbed": 200.0})
    assert ltt.slow_and_fast_trials(rates) == {"slowest": "a_undisturbed", "fastest": "b_undisturbed"}
    assert ltt.slow_and_fast_trials(rates.drop("b_undisturbed")) == {"slowest": "c_disturbed",
                                                                     "fastest": "d_disturbed"}
    rec = types.SimpleNamespace(gyr=np.tile(np.radians([[0.0, 0.0, 10.0]]), (5, 1)),
                                movement=np.array([True, True, True, False, False]))
    rec.gyr[3:] = 1.0  # not movement: ignored
    assert ltt.median_rate_deg_s({"x": rec})["x"] == pytest.approx(10.0)


def test_worst_burst_end_and_window():
    """Notebook 05 shows the burst worst for holding (a repeated burst); notebook 10 a neutral one."""
    from wsnlib.studies.loss_tolerance import tables as ltt

    n, fs = 400, 50.0
    received = np.ones(n, bool)
    received[100:124] = False
    received[300:324] = False
    lossless = np.full(n, 1.0)
    error = lossless.copy()
    error[124:140] += 3.0   # the first burst adds 3°
    error[324:330] += 8.0   # the second 8°
    error[330] = np.nan     # NaN counts as no increase
    trace = {"fs": fs, "time_s": np.arange(n) / fs, "received": received, "burst_ends": np.array([124, 324]),
             "error": {"m": error}, "lossless": {"m": lossless}}
    assert ltt.worst_burst_end(trace, "m") == 324
    window = ltt.burst_window(trace, 324, before_s=1.5, after_s=4.0)
    assert (window.start, window.stop) == (300 - 75, n)  # clipped at the record's end
    assert ltt.burst_window(trace, 124, before_s=4.0, after_s=1.0) == slice(0, 174)
    with pytest.raises(ValueError, match="burst"):
        ltt.worst_burst_end({**trace, "burst_ends": np.array([], int)}, "m")


def test_headline_tables_from_the_study(small_study):
    from wsnlib.studies.loss_tolerance import tables as ltt

    _, result = small_study
    per_trial = result.per_trial
    methods = list(result.methods)
    values = lts.trial_table(per_trial, lt.HEADLINE, "rmse_total")[methods]
    assert list(values.columns) == methods and len(values) == 3
    kalman_rows = per_trial[(per_trial["profile"] == lt.HEADLINE) & (per_trial["method"] == "Kalman")]
    assert values["Kalman"].mean() == pytest.approx(kalman_rows["rmse_total"].mean())
    phases = ltt.phase_table(per_trial)
    columns = list(ltt.PHASE_COLUMNS.values())
    columns.insert(columns.index("jitter (°/s³)") + 1, ltt.LOSSLESS_JITTER_COLUMN)
    assert list(phases.columns) == columns and list(phases.index) == methods
    assert phases.loc["Kalman", "lost samples (°)"] == pytest.approx(kalman_rows["rms_lost"].mean())
    lossless = per_trial[(per_trial["profile"] == "lossless") & (per_trial["method"] == "Kalman")]
    assert phases.loc["Kalman", ltt.LOSSLESS_JITTER_COLUMN] == pytest.approx(lossless["jitter_deg_s3"].mean())
    jitter = ltt.jitter_sentence(phases, {"causal": "Kalman"})
    assert f"{phases.loc['Kalman', 'jitter (°/s³)']:.0f} °/s³ against" in jitter and "hold_last" in jitter
    budgets = ltt.error_budgets(per_trial, methods)
    np.testing.assert_allclose(budgets[["share_lost", "share_after_gap", "share_steady"]].sum(axis=1), 1.0)
    best = {"causal": "Kalman", "offline": "smoother"}
    sentence = ltt.why_missed_sentence(per_trial, best, values)
    assert f"`{values['Kalman'].idxmax()}`" in sentence and f"{values['Kalman'].max():.1f}°" in sentence
    with pytest.raises(ValueError, match="profile"):
        ltt.phase_table(per_trial, profile="nope")


def test_paper_vs_ours_and_sentences():
    from wsnlib import paper_values
    from wsnlib.studies.loss_tolerance import tables as ltt

    shown = ["hold_last", "hybrid (feedback)", "Kalman", "smoother", "VQF"]
    rows = [{"profile": "paper burst", "metric": metric, "method": m, "mean": 10.0 * (i + 1) + k,
             "ci_low": 10.0 * (i + 1) + k - 1, "ci_high": 10.0 * (i + 1) + k + 1}
            for i, m in enumerate(shown) for k, metric in enumerate(ltt.PAPER_VS_OURS_COLUMNS)]
    table = ltt.paper_vs_ours(pd.DataFrame(rows), "VQF")
    assert list(table.index) == shown
    assert table.loc["Kalman", "peak increase (°)"] == 31.0 and table.loc["Kalman", "back within 2° (s) high"] == 33.0
    assert table.loc["VQF", "paper (Sec. IV, simulated arm)"] == "—"
    assert table.loc["hybrid (feedback)", "paper (Sec. IV, simulated arm)"] == \
        paper_values.PAPER001_SECTION4_AFTER_LOSS["hybrid"]["words"]
    peaks = pd.DataFrame([{"without": "hold_last", "with": "hybrid (feedback)", "difference": 10.0, "ci_low": 4.0,
                           "ci_high": 16.0, "verdict": "hurts", "n_better": 1, "n_trials": 7}])
    sentence = ltt.paper_vs_ours_sentence(table, peaks, positions=8)
    assert "21.0° [20.0, 22.0] to the hybrid's error and 11.0° [10.0, 12.0] to holding's" in sentence
    assert "**higher than holding's**" in sentence and "the hybrid's lower on 1 of 7 trials" in sentence
    assert "8 positions" in sentence and "after 22.00 s" in sentence
    tie = ltt.paper_vs_ours_sentence(table, peaks.assign(verdict="tie"))
    assert "a tie with holding's" in tie and "one burst per run" in tie
    # The method with the lower error before the burst comes back within 2° of it later: said so.
    recovery = ltt.recovery_sentence(table.assign(**{"error before (°)": [20.0, 5.0, 2.0, 1.0, 3.0],
                                                     "back within 2° (s)": [0.5, 1.0, 2.0, 0.1, 1.0]}))
    assert "Kalman's error was 2.0° and hold_last's 20.0°" in recovery and "closer, in degrees" in recovery
    trust = pd.DataFrame({"trusted_share": [0.2, 0.5, 0.9]}, index=pd.Index(["a", "b", "c"], name="trial"))
    assert "50 %" in ltt.trust_sentence(trust) and "20 % on `a`" in ltt.trust_sentence(trust)


def test_summary_bullets(small_study):
    from wsnlib.studies.loss_tolerance import tables as ltt

    _, result = small_study
    per_trial = result.per_trial
    targets = pd.DataFrame({"verdict": ["PASS", "MISS"]}, index=["first target", "second target"])
    comparison = pd.DataFrame([{"question": "q", "without": "hold_last", "with": "constant_rate", "metric": metric,
                                "profile": lt.HEADLINE, "mean_without": 10.0, "mean_with": 8.0, "difference": -2.0,
                                "ci_low": -3.0, "ci_high": -1.0, "verdict": "helps", "n_better": 3, "n_trials": 3}
                               for metric in ("rmse_total", "rms_lost")])
    bullets = ltt.summary_bullets(per_trial, ranking_sentence="R.", targets=targets,
                                  best={"causal": "Kalman", "offline": "smoother"},
                                  comparisons={"Does it help?": comparison}, ablation=["A.", "B."])
    assert bullets[0] == f"* **Ranking at {lt.HEADLINE}.** R."
    assert bullets[1] == "* **Targets.** first target: PASS; second target: MISS."
    assert bullets[2].endswith(lts.diagnosis_sentence(per_trial, "Kalman"))
    assert bullets[3] == "* **What the filter and the gap handling contribute.** A. B."
    assert bullets[4] == "* **Does it help?** " + " ".join(lts.comparison_sentences(comparison.iloc[:1]))
    assert len(bullets) == 5


# --- draws, notebook 05's registry and reading, the command line -----------------------------------


def test_draws_are_rows_and_summaries_average_them():
    recordings = {f"trial{i}": _recording(i, n=400) for i in range(3)}
    methods = {name: m for name, m in _small_methods().items() if name in ("hold_last", "Kalman")}
    profiles = [lt.PROFILES[0], loss.LossProfile.gilbert_elliott(0.2, name="GE 20 %"), lt.BurstPositions(positions=1)]
    one = lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=profiles,
                      headline="GE 20 %", progress=False)
    three = lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=profiles,
                        headline="GE 20 %", draws=3, progress=False)
    rows = three.per_trial
    assert sorted(rows.loc[rows["profile"] == "GE 20 %", "draw"].unique()) == [0, 1, 2]
    assert (rows.loc[rows["profile"] != "GE 20 %", "draw"] == 0).all()  # deterministic profiles: one mask
    # The first draw is the single draw's mask (the same generator), later ones differ.
    first = rows[(rows["profile"] == "GE 20 %") & (rows["draw"] == 0)].reset_index(drop=True)
    single = one.per_trial[one.per_trial["profile"] == "GE 20 %"].reset_index(drop=True)
    pd.testing.assert_series_equal(first["lost_share"], single["lost_share"])
    assert rows.loc[(rows["profile"] == "GE 20 %"), "lost_share"].nunique() > 3
    # Summaries read the mean over a trial's draws; tuning scores the mean over the headline's draws.
    table = lts.trial_table(rows, "GE 20 %", "rmse_total")
    expected = rows[rows["profile"] == "GE 20 %"].groupby(["trial", "method"])["rmse_total"].mean().unstack()
    pd.testing.assert_frame_equal(table, expected[table.columns], check_names=False)
    assert {"rmse_heading", "rmse_inclination"} <= set(three.tuning.columns)
    with pytest.raises(ValueError, match="draws"):
        lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=profiles,
                    headline="GE 20 %", draws=0)
    # Draws per profile: more where the settings are tuned, the first draws the same masks.
    five = loss.LossProfile.gilbert_elliott(0.05, name="GE 5 %")
    mapped = lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=[*profiles, five],
                         headline="GE 20 %", draws={"GE 20 %": 3}, progress=False).per_trial
    assert mapped.groupby("profile")["draw"].nunique().to_dict() == {"GE 20 %": 3, "GE 5 %": 1, "lossless": 1,
                                                                    "paper burst": 1}
    pd.testing.assert_frame_equal(mapped[mapped["profile"] == "GE 20 %"].reset_index(drop=True),
                                  rows[rows["profile"] == "GE 20 %"].reset_index(drop=True))
    for bad, match in (({"GE 50 %": 2}, "unknown profiles"), ({"GE 20 %": 0}, "GE 20 %")):
        with pytest.raises(ValueError, match=match):
            lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=profiles,
                        headline="GE 20 %", draws=bad)
    # Tuned on the first draw only: the tuning and the choices of the single-draw study, scored on all three.
    first_only = lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=profiles,
                             headline="GE 20 %", draws=3, tuning_draws=1, progress=False)
    assert len(one.tuning) and not one.tuning.equals(three.tuning)
    pd.testing.assert_frame_equal(first_only.tuning, one.tuning)
    pd.testing.assert_frame_equal(first_only.choices, one.choices)
    assert first_only.per_trial.groupby("profile")["draw"].nunique()["GE 20 %"] == 3
    for bad, match in ((4, "exceeds the headline's draws"), (0, "tuning_draws")):
        with pytest.raises(ValueError, match=match):
            lt.evaluate(recordings, rng=np.random.default_rng(3), methods=methods, profiles=profiles,
                        headline="GE 20 %", draws=3, tuning_draws=bad)


def test_paper001_registry_and_profiles():
    from wsnlib.studies.hybrid_tuning import RECOMMENDED_HYBRID
    from wsnlib.studies.loss_tolerance import paper001

    methods = lt.paper001_methods(RECOMMENDED_HYBRID, [0.01, 0.1], [0.5, 1.0], [1.5, 3.0])
    assert list(methods)[:6] == [*paper001.OUR_OPTIONS, "single frame"]
    assert methods["gyro_interpolation"].latency == "none" and methods["VQF + hybrid (output)"].kind == "peer"
    for name in methods:
        plotting.method_style(name)
    profiles = lt.paper001_profiles((0.1,), burst_packets=4, burst_period_s=8.0)
    assert [p.name for p in profiles] == ["lossless", paper001.BURST, "GE 10 %"]
    # Without loss every option of ours is plain Madgwick and the peers' hybrids are the peers.
    rec = _recording(1, n=300)
    rx = np.ones((1, 300), bool)
    plain = methods["hold_last"].run(rec, {"beta": 0.1}, rx)
    for name in paper001.OUR_OPTIONS:
        np.testing.assert_array_equal(methods[name].run(rec, {"beta": 0.1}, rx), plain)
    np.testing.assert_array_equal(methods["Fusion + hybrid (feedback)"].run(rec, {"gain": 0.5}, rx),
                                  methods["Fusion"].run(rec, {"gain": 0.5}, rx))
    # Under the paper's burst they differ.
    burst = profiles[1].mask(300, FS, None, shape=(1,))
    assert not np.allclose(methods["hybrid"].run(rec, {"beta": 0.1}, burst), plain)


def test_paper001_tables_and_findings():
    from wsnlib.studies.hybrid_tuning import RECOMMENDED_HYBRID
    from wsnlib.studies.loss_tolerance import paper001

    names = ["02_undisturbed_slow_rotation_B", "07_undisturbed_fast_rotation_B", "30_disturbed_stationary_magnet_C"]
    recordings = {name: _recording(i, n=500) for i, name in enumerate(names)}
    methods = lt.paper001_methods(RECOMMENDED_HYBRID, [0.01, 0.1], [0.5, 1.0], [1.5, 3.0])
    result = lt.evaluate(recordings, rng=np.random.default_rng(5), methods=methods,
                         profiles=lt.paper001_profiles((0.1,), burst_period_s=4.0), headline="lossless",
                         progress=False)
    summary, settings = paper001.tuning_summary(result.tuning, result.choices, methods)
    assert list(summary.index) == list(paper001.TUNED) and list(settings.index) == names
    assert np.isnan(summary.loc["Madgwick", "median RMSE, library default (°)"])   # β has no default
    assert np.isfinite(summary.loc["Fusion", "median RMSE, library default (°)"])  # 0.5 is in the grid
    bursts = paper001.burst_table(result.per_trial)
    assert set(bursts["method"]) == set(methods) and (bursts["n_gaps_scored"] > 0).all()
    assert paper001.trial_groups(names) == {"slow rotation": names[:1], "fast": names[1:2], "magnet": names[2:]}
    found = paper001.findings(result.per_trial, recordings, {"Fusion": 1.0, "VQF": 2.0, "Fusion default": 1.5},
                              rng=np.random.default_rng(0), n_boot=200)
    assert found["closest trial"] in names and (found["triad factor"].index == names).all()
    assert "What carries over" in found["text"] and "(at its default: 1.5°)" in found["text"]


def test_command_line_runs_on_two_broad_trials(tmp_path, capsys, monkeypatch):
    """The BROAD study's command line, ``--quick``: the tables, a verdict per target, the per-trial CSV."""
    import os
    from pathlib import Path

    from _study_cli import run_here

    from wsnlib import paths

    shared = paths.ROOT.parent / "shared" / "data" / "broad"
    folder = os.environ.get("WSNLIB_BROAD_DIR") or (str(shared) if shared.is_dir() else "")
    if not folder or len(list(Path(folder).glob("*.mat"))) < 2:
        pytest.skip("needs two BROAD trials (set WSNLIB_BROAD_DIR; `make test` does on CI)")
    monkeypatch.setenv("WSNLIB_BROAD_DIR", folder)
    out = tmp_path / "per_trial.csv"
    # In this process (its kernels are loaded); test_loss_tolerance_recordings runs the module's own interpreter.
    status, stdout, stderr = run_here(capsys, "--quick", "--budget", "1", "--jobs", "1", "--out", out)
    assert status == 0, stderr[-3000:]
    assert "1 settings per method, on 1 local job(s)" in stdout
    verdicts = [line for line in stdout.splitlines() if ": PASS" in line or ": MISS" in line]
    assert len(verdicts) == len(lts.TARGETS), stdout[-3000:]
    table = pd.read_csv(out)
    assert table["trial"].nunique() == 2 and set(table["profile"]) == {p.name for p in lt.PROFILES}
    status, stdout, stderr = run_here(capsys, "--quick", "--jobs", "1", "--methods", "VQF (defaults)")
    assert status == 0, stderr[-3000:]
    assert "  VQF (defaults) " in stdout and "  Kalman " not in stdout
    assert "Targets and diagnosis: not computed" in stdout and ": PASS" not in stdout
    status, _, stderr = run_here(capsys, "--quick", "--scheduler", "nowhere")
    assert status != 0 and "scheduler" in stderr


#: The tuning and scoring runs of :func:`_counted_madgwick`: (setting, masks) per call.
_COUNTED_RUNS = []


def _counted_madgwick(rec, setting, received, *, gap):
    _COUNTED_RUNS.append((setting["beta"], received.shape[0]))
    return lt.default_methods()[gap].run(rec, setting, received)


def test_a_run_two_methods_ask_for_is_tuned_once():
    """Two methods that run the same function on the same settings (as "Kalman" and the first design of
    "Kalman, design in fold") share each tuning job: one run per trial, the same tuning scores for both;
    a method whose function differs in an argument runs its own."""
    recordings = {f"trial{i}": _recording(i, n=300) for i in range(2)}
    base = lt.default_methods()["hold_last"]
    grid = ({"beta": 0.02}, {"beta": 0.1})
    methods = {name: dataclasses.replace(base, name=name, grid=grid,
                                         run=functools.partial(_counted_madgwick, gap=gap))
               for name, gap in (("A", "hold_last"), ("A again", "hold_last"), ("B", "constant_rate"))}
    _COUNTED_RUNS.clear()
    profiles = [p for p in lt.PROFILES if p.name in ("lossless", lt.HEADLINE)]
    result = lt.evaluate(recordings, rng=np.random.default_rng(2), methods=methods, profiles=profiles, n_jobs=1,
                         progress=False)
    tuning_runs = [masks for _, masks in _COUNTED_RUNS if masks == 1]  # one headline mask when tuning
    assert len(tuning_runs) == 2 * 2 * 2  # 2 trials × 2 settings, for "A" (shared with "A again") and "B"
    tuning = result.tuning.set_index(["method", "trial", "setting_index"])
    pd.testing.assert_frame_equal(tuning.loc["A"], tuning.loc["A again"])
    assert not tuning.loc["A"].equals(tuning.loc["B"])
    assert result.seconds["A again"] < result.seconds["A"]  # it ran the scoring only
