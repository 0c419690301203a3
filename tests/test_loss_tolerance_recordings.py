"""The loss-tolerance study on your own recordings (issue 24): recording files in, any node, any rate."""

import dataclasses

import numpy as np
import pandas as pd
import pytest
from _study_cli import run_as_module, run_here

from wsnlib import metrics
from wsnlib.io.recording import read_recording, write_recording
from wsnlib.loss import LossProfile
from wsnlib.orientation import estimate_orientation, vqf_orientation
from wsnlib.sim import reach_and_flex, simulate_recording
from wsnlib.studies import loss_tolerance as lt
from wsnlib.studies.loss_tolerance import summary as lts

LOSSLESS = (lt.PROFILES[0],)


def _simulated(path, fs=50.0, seed=0, duration_s=10.0, **changes):
    """A two-node arm recording (humerus, forearm) written to ``path``; returns it as read back."""
    rec = simulate_recording(reach_and_flex(fs=fs, duration_s=duration_s), rng=np.random.default_rng(seed))
    rec = dataclasses.replace(rec, **changes) if changes else rec
    return read_recording(write_recording(rec, path))


def _methods(*names, budget=1):
    return lt.with_budget({name: lt.default_methods()[name] for name in names}, budget)


def test_a_recording_file_becomes_one_unit_per_node_with_a_reference(tmp_path):
    quat = simulate_recording(reach_and_flex(fs=50.0, duration_s=4.0), rng=np.random.default_rng(0)).quat_true.copy()
    quat[1] = np.nan                    # the forearm has no reference at all: not a unit
    quat[0, 10:20] = np.nan             # the humerus loses it for 10 samples
    rec = _simulated(tmp_path / "walk.csv", duration_s=4.0, quat_true=quat)
    units = lt.load_recordings([tmp_path / "walk.csv"], progress=False)
    assert list(units) == ["walk/humerus"]
    unit = units["walk/humerus"]
    assert (unit.source, unit.node, unit.fs) == ("walk", "humerus", 50.0)
    np.testing.assert_array_equal(unit.gyr, rec.gyr[0])
    # Without a movement column, every sample with a reference is scored.
    expected = np.ones(rec.n_samples, bool)
    expected[10:20] = False
    np.testing.assert_array_equal(unit.movement, expected)
    np.testing.assert_array_equal(unit.reference_valid, expected)
    # With one, the file's movement (per node) is scored.
    movement = np.zeros((2, rec.n_samples), bool)
    movement[:, 50:150] = True
    _simulated(tmp_path / "run.csv", duration_s=4.0, movement=movement)
    units = lt.load_recordings([str(tmp_path / "run.json")], progress=False)  # the sidecar names the CSV too
    assert list(units) == ["run/humerus", "run/forearm"]
    np.testing.assert_array_equal(units["run/forearm"].movement, movement[1])


def test_the_loader_refuses_what_it_cannot_study(tmp_path):
    rec = _simulated(tmp_path / "a.csv", duration_s=2.0)
    (tmp_path / "b").mkdir()
    _simulated(tmp_path / "b" / "a.csv", duration_s=2.0)
    with pytest.raises(ValueError, match=r"\['a/forearm', 'a/humerus'\] twice"):
        lt.load_recordings([tmp_path / "a.csv", tmp_path / "b" / "a.csv"], progress=False)
    with pytest.raises(ValueError, match="no reference orientation"):
        lt.from_recording(dataclasses.replace(rec, quat_true=None), "x")
    with pytest.raises(ValueError, match="at least one"):
        lt.load_recordings([], progress=False)


def test_irregular_time_stamps_are_refused_with_a_pointer_to_resampling():
    rec = simulate_recording(reach_and_flex(fs=50.0, duration_s=2.0), rng=np.random.default_rng(0))
    time_s = rec.time_s.copy()
    time_s[40:] += 0.02             # one sample dropped: a 40 ms step at sample 39
    jittered = dataclasses.replace(rec, time_s=time_s)
    with pytest.raises(ValueError, match=r"not regular at fs = 50 Hz: the step after sample 39 is 0\.04 s.*"
                                         r"wsnlib\.io\.resample_timestamps"):
        lt.from_recording(jittered, "x")
    time_s = rec.time_s * 1.01      # a clock 1 % fast: within the tolerance
    assert list(lt.from_recording(dataclasses.replace(rec, time_s=time_s), "x")) == ["x/humerus", "x/forearm"]


def test_at_40_hz_the_study_gives_what_the_method_gives_at_40_hz(tmp_path):
    """Issue 24: the study's rate was a constant (50 Hz), so a 40 Hz recording ran with a wrong
    time step and silently wrong errors.  Each recording now runs at its own rate."""
    rec = _simulated(tmp_path / "slow.csv", fs=40.0, duration_s=12.0)
    units = lt.load_recordings([tmp_path / "slow.csv"], progress=False)
    assert {u.fs for u in units.values()} == {40.0}
    result = lt.evaluate(units, rng=np.random.default_rng(0), methods=_methods("VQF (defaults)", "hold_last"),
                         profiles=LOSSLESS, headline="lossless", n_jobs=1, progress=False)
    got = result.per_trial.set_index(["method", "trial"])["rmse_total"]
    everything = np.ones(rec.n_samples, bool)
    for fs in (40.0, 50.0):
        direct = {"VQF (defaults)": vqf_orientation(rec.gyr, rec.acc, rec.mag, fs=fs),
                  "hold_last": estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=fs, beta=lt.MADGWICK_BETA)}
        for method, quat in direct.items():
            for i, node in enumerate(rec.nodes):
                want = metrics.broad_rmse_deg(quat[i], rec.quat_true[i], everything)["total"]
                if fs == 40.0:
                    assert got[(method, f"slow/{node}")] == pytest.approx(want, rel=1e-9)
                else:  # the old code's answer: far off
                    assert abs(got[(method, f"slow/{node}")] - want) > 2.0
    assert result.traces["slow/humerus"]["fs"] == 40.0
    np.testing.assert_allclose(np.diff(result.traces["slow/humerus"]["time_s"]), 1 / 40.0)


def test_masks_and_latency_use_each_recordings_rate(tmp_path):
    """Loss profiles are in seconds and packets of samples: the paper's burst (4 packets of 6
    samples, repeated every 8 s from 4 s on) starts at the first packet boundary from 4 s on, sample 162
    at 40 Hz (4 s = sample 160), 204 at 50 Hz (sample 200), and lasts 24 samples."""
    _simulated(tmp_path / "forty.csv", fs=40.0, duration_s=10.0, seed=1)
    _simulated(tmp_path / "fifty.csv", fs=50.0, duration_s=10.0, seed=2)
    units = lt.load_recordings([tmp_path / "forty.csv", tmp_path / "fifty.csv"], progress=False)
    profiles = (lt.PROFILES[0], LossProfile.burst(4.0, 4, period_s=8.0, name="paper burst, repeated"))
    result = lt.evaluate(units, rng=np.random.default_rng(0), methods=_methods("smoother"), profiles=profiles,
                         headline="paper burst, repeated", n_jobs=1, progress=False)
    assert result.traces["forty/humerus"]["burst_ends"][0] == 162 + 24
    assert result.traces["fifty/humerus"]["burst_ends"][0] == 204 + 24
    latency = result.per_trial.set_index("trial")["latency_s"]  # the smoother waits for the whole recording
    assert (latency.loc["forty/humerus"] == 400 / 40.0).all() and (latency.loc["fifty/humerus"] == 500 / 50.0).all()


def test_leave_one_recording_out_holds_out_all_nodes_of_a_file(tmp_path):
    for k in range(3):
        _simulated(tmp_path / f"r{k}.csv", duration_s=6.0, seed=k)
    units = lt.load_recordings(sorted(tmp_path.glob("*.csv")), progress=False)
    methods = lt.with_budget({"hold_last": lt.default_methods()["hold_last"]}, 4)
    result = lt.evaluate(units, rng=np.random.default_rng(0), methods=methods, profiles=LOSSLESS,
                         headline="lossless", n_jobs=1, progress=False)
    assert result.setting_source == "leave-one-recording-out"
    scores = result.tuning.pivot(index="setting_index", columns="trial", values="rmse_total")[list(units)].to_numpy()
    sources = [u.source for u in units.values()]
    for j, name in enumerate(units):
        others = [k for k, source in enumerate(sources) if source != sources[j]]
        want = int(np.argmin(scores[:, others].mean(axis=1)))
        chosen = result.choices.set_index("trial").loc[name, "setting_index"]
        assert chosen == want
    assert list(result.units.columns) == ["recording", "group", "node", "fs_hz", "n_samples"]
    assert list(result.units["recording"]) == sources


def test_one_recording_runs_every_method_with_its_default_and_says_so(tmp_path):
    _simulated(tmp_path / "only.csv", duration_s=6.0)
    units = lt.load_recordings([tmp_path / "only.csv"], progress=False)
    methods = lt.default_methods()
    result = lt.evaluate(units, rng=np.random.default_rng(0), methods=methods, profiles=LOSSLESS, headline="lossless",
                         n_jobs=1, progress=False)
    assert result.setting_source == "defaults (one recording)" and result.tuning.empty
    used = result.per_trial.drop_duplicates("method").set_index("method")["setting"]
    assert used["hold_last"] == str({"beta": 0.041}) and used["Kalman"] == "{}" and used["VQF"] == "{}"
    assert used["Fusion"] == str({"gain": 0.5})
    assert used["hybrid (feedback)"] == str({"beta": 0.041, "rho_tau": 18})   # notebook 03's ρ = 3 × τ = 6
    assert used["VQF (defaults)"] == str(methods["VQF (defaults)"].grid[0])
    table = result.rmse_table()
    assert (table["setting_source"] == "defaults (one recording)").all()
    # Without a default, a method with several settings cannot run untuned.
    bare = {"x": dataclasses.replace(methods["hold_last"], default=None)}
    with pytest.raises(ValueError, match="'hold_last' has 12 settings and no default"):
        lt.evaluate(units, rng=np.random.default_rng(0), methods=bare, profiles=LOSSLESS, headline="lossless",
                    progress=False)


def test_rmse_table_rows_and_columns(tmp_path):
    for k in range(2):
        _simulated(tmp_path / f"r{k}.csv", duration_s=6.0, seed=k)
    units = lt.load_recordings(sorted(tmp_path.glob("*.csv")), progress=False)
    profiles = (lt.PROFILES[0], LossProfile.gilbert_elliott(0.2))
    result = lt.evaluate(units, rng=np.random.default_rng(0), methods=_methods("hold_last", "Kalman"),
                         profiles=profiles, headline="GE 20 %", draws=2, n_jobs=1, progress=False)
    table = result.rmse_table()
    assert list(table.columns) == list(lt.RMSE_TABLE_COLUMNS)
    assert len(table) == 2 * 2 * 2 * (1 + 2)  # recordings × nodes × methods × (lossless + 2 draws)
    assert set(table["recording"]) == {"r0", "r1"} and set(table["node"]) == {"humerus", "forearm"}
    assert not table.duplicated(["recording", "node", "method", "profile", "draw"]).any()
    row = table[(table["recording"] == "r1") & (table["node"] == "forearm") & (table["method"] == "Kalman")
                & (table["profile"] == "GE 20 %") & (table["draw"] == 1)]
    source = result.per_trial[(result.per_trial["trial"] == "r1/forearm") & (result.per_trial["method"] == "Kalman")
                              & (result.per_trial["profile"] == "GE 20 %") & (result.per_trial["draw"] == 1)]
    assert row["rmse_heading_deg"].item() == source["rmse_heading"].item()
    assert np.isfinite(table[["rmse_total_deg", "rmse_inclination_deg", "rmse_heading_deg"]].to_numpy()).all()
    assert (table["setting_source"] == "leave-one-recording-out").all()
    pd.testing.assert_series_equal(table["rmse_total_deg"], result.per_trial["rmse_total"], check_names=False)


# --- from a recording file to the printed table; the command line ----------------------------------------------

#: What a user writes to study their own recordings (issue 24: at most 20 lines, quick settings).
USER_CODE = """
import numpy as np
from wsnlib.loss import LossProfile
from wsnlib.studies import loss_tolerance as study

units = study.load_recordings(["walk.csv", "run.csv"])       # one unit per node with a reference
methods = study.with_budget(study.default_methods(), 1)       # quick: one setting per method
profiles = [LossProfile.none("lossless"), LossProfile.gilbert_elliott(0.10)]
result = study.evaluate(units, rng=np.random.default_rng(0), methods=methods, profiles=profiles,
                        headline="GE 10 %", n_jobs=1)
print(result.rmse_table().to_string(index=False))
"""


def test_from_a_recording_file_to_the_printed_table_in_at_most_20_lines(tmp_path, monkeypatch, capsys):
    recordings = {name: _simulated(tmp_path / f"{name}.csv", duration_s=8.0, seed=k)
                  for k, name in enumerate(("walk", "run"))}
    lines = [line for line in USER_CODE.splitlines() if line.strip()]
    assert len(lines) <= 20
    monkeypatch.chdir(tmp_path)
    exec(USER_CODE, {})
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].split() == list(lt.RMSE_TABLE_COLUMNS)
    assert len(printed) == 1 + 2 * 2 * len(lt.default_methods()) * 2  # recordings × nodes × methods × profiles
    # The row of VQF with its authors' defaults, without loss, on run's forearm: what VQF gives directly.
    run = recordings["run"]
    quat = vqf_orientation(run.gyr[1], run.acc[1], run.mag[1], fs=run.fs)
    want = metrics.broad_rmse_deg(quat, run.quat_true[1], np.ones(run.n_samples, bool))
    row = next(line for line in map(" ".join, map(str.split, printed))
               if line.startswith("run forearm VQF (defaults) lossless"))
    values = row.split("lossless")[1].split()
    assert int(values[0]) == 0 and values[4] == "leave-one-recording-out"
    np.testing.assert_allclose([float(v) for v in values[1:4]], [want["total"], want["inclination"], want["heading"]],
                               rtol=1e-5)


def test_loss_specs_of_the_command_line():
    from wsnlib.studies.loss_tolerance.__main__ import loss_profile

    ge = loss_profile("ge:0.10:3")
    assert (ge.name, ge.model, ge.loss_rate, ge.mean_burst_packets, ge.samples_per_packet) == \
        ("ge:0.10:3", "gilbert_elliott", 0.10, 3.0, 6)
    assert loss_profile("ge:0.2").mean_burst_packets == 3.0 and loss_profile("ge:0.2:5:12").samples_per_packet == 12
    paper = loss_profile("burst:4:4:8")  # paper 001's burst, every 8 s
    np.testing.assert_array_equal(paper.mask(3000, 40.0, None),
                                  LossProfile.burst(4.0, 4, period_s=8.0).mask(3000, 40.0, None))
    assert loss_profile("burst:2:3").burst_period_s is None and loss_profile("none").model == "none"
    import argparse
    for bad in ("ge:1.5", "ge:0.1:0.5", "ge:0.1:3:2.5", "burst:4", "burst:4:0", "gilbert:0.1", "ge:ten"):
        with pytest.raises(argparse.ArgumentTypeError, match=bad):
            loss_profile(bad)


def test_command_line_on_recording_files(tmp_path, capsys):
    for k, name in enumerate(("walk", "run")):
        _simulated(tmp_path / f"{name}.csv", fs=40.0 + 10 * k, duration_s=6.0, seed=k)
    out = tmp_path / "results.csv"
    # (Every method of the registry runs on recording files in test_notebook_10_runs_on_recording_files.)
    run = run_as_module(tmp_path / "walk.csv", tmp_path / "run.json", "--loss", "ge:0.10:3", "--loss", "burst:2:4",
                        "--draws", "2", "--budget", "1", "--jobs", "1", "--methods", "VQF", "smoother", "--out", out)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "2 recording(s), 4 node(s) with a reference, at 40, 50 Hz" in run.stdout
    assert "tuned leave-one-recording-out at ge:0.10:3" in run.stdout
    table = pd.read_csv(out)
    assert list(table.columns) == list(lt.RMSE_TABLE_COLUMNS)
    # the smoother runs with the filter's setting: it brings "Kalman"; the registry's order
    chosen = {"Kalman", "smoother", "VQF"}
    assert list(dict.fromkeys(table["method"])) == [m for m in lt.default_methods() if m in chosen]
    assert len(table) == 2 * 2 * 3 * (1 + 2 + 1)  # 2 files × 2 nodes × 3 methods × (lossless, 2 GE draws, the burst)
    assert list(dict.fromkeys(table["profile"])) == ["lossless", "ge:0.10:3", "burst:2:4"]
    assert set(table["setting_source"]) == {"leave-one-recording-out"}
    printed = run.stdout.splitlines()
    header = next(i for i, line in enumerate(printed) if line.split()[:2] == ["recording", "node"])
    assert len(printed[header + 1].split()) >= 9 and "Mean total RMSE" in run.stdout
    # One file: nothing to tune on, and the table says so.
    status, stdout, stderr = run_here(capsys, tmp_path / "walk.csv", "--loss", "ge:0.2", "--budget", "1", "--jobs",
                                       "1", "--methods", "Kalman", "--out", out)
    assert status == 0, stderr[-3000:]
    assert "one recording: every method with its default setting" in stdout
    assert set(pd.read_csv(out)["setting_source"]) == {"defaults (one recording)"}
    # What the command line refuses.
    refusals = {"not both": (tmp_path / "walk.csv", "--trials", "02_undisturbed_slow_rotation_B"),
                "not a loss profile": (tmp_path / "walk.csv", "--loss", "gilbert:0.1"),
                "--loss applies to recording files": ("--loss", "ge:0.1"),
                "--methods: no method 'kalman'; the registry has 'hold_last'": (tmp_path / "walk.csv", "--methods",
                                                                                "Kalman", "kalman"),
                "argument --jobs: '0': needs a whole number >= 1, or -1 (one per core)": (tmp_path / "walk.csv",
                                                                                           "--jobs", "0"),
                "argument --draws: '0': needs a whole number >= 1": (tmp_path / "walk.csv", "--draws", "0")}
    for said, args in refusals.items():
        status, _, stderr = run_here(capsys, *args)
        assert status != 0 and said in stderr, (args, stderr)


def test_the_health_check_names_the_unit_whose_field_is_disturbed(tmp_path, capsys):
    rec = simulate_recording(reach_and_flex(fs=50.0, duration_s=6.0), rng=np.random.default_rng(0))
    mag = rec.mag.copy()
    mag[1, 100:200] *= 1.5              # the forearm passes a magnet for 2 s (a third of the samples)
    _simulated(tmp_path / "walk.csv", duration_s=6.0, mag=mag)
    units = lt.load_recordings([tmp_path / "walk.csv"], progress=False)
    health = lt.units_health(units)
    assert list(health.table.index) == ["walk/humerus", "walk/forearm"]
    assert len(health.findings) == 1 and health.findings[0].startswith("walk/forearm: the magnetic field")
    assert health.table.loc["walk/forearm", "mag_disturbed_share"] == pytest.approx(1 / 3, abs=0.01)
    assert health.table.loc["walk/humerus", "mag_disturbed_share"] == 0.0
    assert (health.table["fs_nominal_hz"] == 50.0).all()
    # The command line prints it before the study.
    status, stdout, stderr = run_here(capsys, tmp_path / "walk.csv", "--loss", "none", "--jobs", "1", "--methods",
                                       "Kalman")
    assert status == 0, stderr[-3000:]
    assert "Recording health: 1 finding(s)\n- walk/forearm: the magnetic field" in stdout
    assert stdout.index("Recording health") < stdout.index("rmse_total_deg")


def test_notebook_sources_take_trials_or_recordings_not_both():
    assert lt.notebook_sources("all", ["a.csv", "b.json"], quick=True) == ["a.csv", "b.json"]  # files all kept
    assert lt.notebook_sources(["02_undisturbed_slow_rotation_B", "07_undisturbed_fast_rotation_B", "x"],
                               quick=True) == ["02_undisturbed_slow_rotation_B", "07_undisturbed_fast_rotation_B"]
    with pytest.raises(ValueError, match="not both"):
        lt.notebook_sources(["02_undisturbed_slow_rotation_B"], ["a.csv"])
    for bad in ("a.csv", []):
        with pytest.raises(ValueError, match="non-empty list of recording files"):
            lt.notebook_sources("all", bad)


def test_lost_share_band_matches_the_spread_of_gilbert_elliott_masks():
    profile = LossProfile.gilbert_elliott(0.10, 3.0)
    masks = profile.mask(6000, 50.0, np.random.default_rng(3), shape=(2000,))   # 1000 packets each
    shares = 1 - masks.mean(axis=1)
    low, high = lts.lost_share_band(profile, 6000, n_std=1.0)
    assert (high - low) / 2 == pytest.approx(shares.std(), rel=0.15)   # the chain's spread, not Bernoulli's
    assert (low + high) / 2 == pytest.approx(0.10)
    low, high = lts.lost_share_band(profile, 6000)
    assert ((shares > low) & (shares < high)).mean() > 0.99
    with pytest.raises(ValueError, match="Gilbert-Elliott"):
        lts.lost_share_band(lt.PROFILES[0], 6000)


def test_sentences_on_other_recordings_name_no_broad_group():
    from wsnlib.studies.loss_tolerance import paper001, tables

    broad = ["02_undisturbed_slow_rotation_B", "30_disturbed_stationary_magnet_C"]
    assert lt.all_broad(broad) and not lt.all_broad([*broad, "walk/wrist"]) and not lt.all_broad([])
    assert paper001.listed(broad) == "02, 30"
    assert paper001.listed(["walk/wrist", "run/wrist"]) == "`walk/wrist`, `run/wrist`"
    assert paper001.trial_labels(broad) == ["undisturbed_slow_rotation_B", "disturbed_stationary_magnet_C"]
    assert paper001.trial_labels(["walk/upper_arm"]) == ["walk/upper_arm"]
    assert paper001.trial_groups(["walk/slow_rotation", "run/_fast_"]) == {"slow rotation": [], "fast": [],
                                                                           "magnet": []}
    rows = [{"profile": "paper burst", "metric": metric, "method": m, "mean": 1.0, "ci_low": 0.5, "ci_high": 1.5}
            for m in ("hold_last", "hybrid (feedback)", "Kalman", "smoother", "VQF")
            for metric in tables.PAPER_VS_OURS_COLUMNS]
    table = tables.paper_vs_ours(pd.DataFrame(rows), "VQF")
    peaks = pd.DataFrame([{"without": "hold_last", "with": "hybrid (feedback)", "difference": 0.0, "ci_low": -1.0,
                           "ci_high": 1.0, "verdict": "tie", "n_better": 1, "n_trials": 2}])
    broad_text = tables.paper_vs_ours_sentence(table, peaks)
    assert "On BROAD" in broad_text and "magnetic" in broad_text
    other = tables.paper_vs_ours_sentence(table, peaks, broad=False)
    assert "On these recordings" in other and "BROAD" not in other and "magnetic" not in other


def test_notebook_05_reading_on_recording_files(tmp_path):
    from wsnlib.studies.hybrid_tuning import RECOMMENDED_HYBRID
    from wsnlib.studies.loss_tolerance import paper001

    for k, name in enumerate(("walk", "run")):
        _simulated(tmp_path / f"{name}.csv", duration_s=12.0, seed=k)
    units = lt.load_recordings([tmp_path / "walk.csv", tmp_path / "run.csv"], progress=False)
    methods = lt.paper001_methods(RECOMMENDED_HYBRID, [0.01, 0.1], [0.5, 1.0], [1.5, 3.0])
    result = lt.evaluate(units, rng=np.random.default_rng(5), methods=methods,
                         profiles=lt.paper001_profiles((0.1,), burst_period_s=4.0), headline="lossless", n_jobs=1,
                         progress=False)
    groups = result.units["recording"]
    summary, _ = paper001.tuning_summary(result.tuning, result.choices, methods, groups=groups)
    # The median leave-one-out RMSE holds out both nodes of a file: from the grid scores, by hand.
    scores = result.tuning[result.tuning["method"] == "hold_last"].pivot(index="setting_index", columns="trial",
                                                                       values="rmse_total")[list(units)].to_numpy()
    held_out = [scores[np.argmin(scores[:, [k for k in range(4) if k // 2 != j // 2]].mean(axis=1)), j]
                for j in range(4)]
    assert summary.loc["Madgwick", "median RMSE, leave-one-trial-out (°)"] == pytest.approx(np.median(held_out))
    found = paper001.findings(result.per_trial, units, {"Fusion": 1.0, "VQF": 2.0}, rng=np.random.default_rng(0),
                              n_boot=200)
    assert found["remedy pool"] == sorted(units) and found["closest trial"] in units
    for text in (found["text"], paper001.summary_text(found, len(units))):
        assert "BROAD" not in text and "magnet" not in text and "slow-rotation" not in text and "(none)" not in text
    assert "Errors are per node" in found["text"] and f"`{found['closest trial']}` at" in found["text"]
    one = lt.evaluate({k: v for k, v in units.items() if k.startswith("walk")}, rng=np.random.default_rng(5),
                      methods=methods, profiles=lt.paper001_profiles((0.1,)), headline="lossless", n_jobs=1,
                      progress=False)
    with pytest.raises(ValueError, match="single recording"):
        paper001.tuning_summary(one.tuning, one.choices, methods)
