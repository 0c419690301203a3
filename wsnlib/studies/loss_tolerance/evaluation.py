"""Running the loss-tolerance study: masks, leave-one-recording-out tuning, scoring (:func:`evaluate`).

What is run and why: the package docstring (:mod:`wsnlib.studies.loss_tolerance`).  Every
recording is run, masked, scored and traced at its own rate (``recording.fs``).
"""

from __future__ import annotations

import dataclasses
import functools
import time
import zlib
from collections.abc import Mapping

import numpy as np
import pandas as pd

from wsnlib import loto, metrics, parallel
from wsnlib._validation import check_count, check_positive, check_rng
from wsnlib.orientation import SingleFrameGate, single_frame_trusted
from wsnlib.studies.loss_tolerance.registry import HEADLINE, PROFILES, BurstPositions, Method, default_methods

#: Length of the "after a gap" phase of :func:`wsnlib.metrics.error_by_phase` (s).
AFTER_GAP_S = 2.0
#: Recovery: the error increase over the lossless run back below this (°) for the window's rest.
RECOVERY_THRESHOLD_DEG = 2.0
#: Window after each gap in which the error increase and recovery are measured (s): after a burst
#: of a repeated burst profile 4 s; random gaps come closer (2 s).
BURST_RESPONSE_WINDOW_S, GAP_RESPONSE_WINDOW_S = 4.0, 2.0
#: Where each recording's setting comes from (:attr:`LossToleranceResult.setting_source`): tuned on
#: the other recordings, or on the other groups (``groups`` of :func:`evaluate`), or, with a
#: single recording, every method's default.
SETTING_SOURCES = ("leave-one-recording-out", "defaults (one recording)", "leave-one-group-out")
#: Columns of :meth:`LossToleranceResult.rmse_table`.
RMSE_TABLE_COLUMNS = ("recording", "node", "method", "profile", "draw", "rmse_total_deg", "rmse_inclination_deg",
                      "rmse_heading_deg", "setting_source", "setting")


def response_window_s(profile) -> float:
    """The window of the gap response: a :class:`BurstPositions` profile's own ``window_s``,
    :data:`BURST_RESPONSE_WINDOW_S` for another burst profile, else :data:`GAP_RESPONSE_WINDOW_S`."""
    if profile.model == BurstPositions.model:
        return profile.window_s
    return BURST_RESPONSE_WINDOW_S if profile.model == "burst" else GAP_RESPONSE_WINDOW_S


#: Columns of the one-burst response (:func:`wsnlib.metrics.single_burst_response`), NaN under the
#: other profiles: the error before the burst, its peak and mean increase over it (°), and the
#: recoveries (s, censored at the window) back within :data:`RECOVERY_THRESHOLD_DEG` of it and below
#: :data:`RECOVERY_LEVEL_DEG`, with 1/0 for recovered within the window.
BURST_COLUMNS = ("burst_before_deg", "burst_peak_increase_deg", "burst_mean_increase_deg", "burst_recovery_s",
                 "burst_recovered", "burst_level_recovery_s", "burst_level_recovered")
#: The absolute level of the one-burst recovery (°): paper 001's hybrid stays "≈ 10°" after its loss.
RECOVERY_LEVEL_DEG = 10.0


def _burst_columns(total, received, profile, fs) -> dict:
    """:data:`BURST_COLUMNS` of one run (``total``: error (°) per sample, NaN without reference)."""
    if profile.model != BurstPositions.model:
        return dict.fromkeys(BURST_COLUMNS, np.nan)
    r = metrics.single_burst_response(total, received, fs, before_s=profile.before_s, window_s=profile.window_s,
                                      threshold_deg=RECOVERY_THRESHOLD_DEG, level_deg=RECOVERY_LEVEL_DEG)
    out = {"burst_before_deg": float(r["before_deg"]), "burst_peak_increase_deg": float(r["peak_increase_deg"]),
           "burst_mean_increase_deg": float(r["mean_increase_deg"])}
    for key, recovered in (("burst_recovery_s", "burst_recovered"),
                           ("burst_level_recovery_s", "burst_level_recovered")):
        seconds = float(r[key.removeprefix("burst_")])
        out[key] = min(seconds, profile.window_s)
        out[recovered] = np.nan if np.isnan(seconds) else float(np.isfinite(seconds))
    return {key: out[key] for key in BURST_COLUMNS}


@dataclasses.dataclass
class LossToleranceResult:
    """What :func:`evaluate` returns.

    Attributes
    ----------
    per_trial : pandas.DataFrame
        One row per method × profile × trial (columns in :func:`evaluate`); a "trial" is one
        study unit (a BROAD trial, or one node of a recording file).
    tuning : pandas.DataFrame
        Headline RMSE (°, mean over the masks tuned on, ``tuning_draws`` of :func:`evaluate`) of
        every setting on every trial, for the methods with more than one setting:
        method, setting_index, setting, trial, rmse_total, rmse_heading, rmse_inclination
        (no rows without tuning, :attr:`setting_source` ``"defaults (one recording)"``).
    choices : pandas.DataFrame
        The setting each trial is scored with, per method: method, trial, setting_index (in
        the method's grid; -1 for a default that is not in it), setting.
    traces : dict
        ``traces[trial]``: ``fs`` (Hz, the trial's rate), ``time_s``, ``received`` and
        ``burst_ends`` of one run of the burst profile (of a :class:`~wsnlib.studies.
        loss_tolerance.BurstPositions` profile, the position whose angular rate over the lost
        samples is the median of the positions': a typical burst, picked without looking at any
        error), ``error`` (method → total error (°) per sample under it, NaN where the reference
        is missing) and ``lossless`` (the same without loss).
    seconds : pandas.Series
        Run time per method (s, tuning and scoring), summed over its jobs wherever they ran
        (compute time, not wall-clock time).
    methods : dict[str, Method]
    profiles : tuple of LossProfile
    units : pandas.DataFrame
        Index trial; columns recording (the source), group (held out together: the recording,
        or ``groups`` of :func:`evaluate`), node, fs_hz, n_samples.
    setting_source : str
        One of :data:`SETTING_SOURCES`: tuned leave-one-recording-out or leave-one-group-out at
        the headline, or, with a single recording, every method's default
        (:meth:`Method.untuned_setting`).
    """

    per_trial: pd.DataFrame
    tuning: pd.DataFrame
    choices: pd.DataFrame
    traces: dict
    seconds: pd.Series
    methods: dict
    profiles: tuple
    units: pd.DataFrame
    setting_source: str

    def rmse_table(self) -> pd.DataFrame:
        """One row per recording, node, method, profile and draw: BROAD's three RMSEs (°) and the setting.

        Columns :data:`RMSE_TABLE_COLUMNS`: the recording (file stem or BROAD trial) and node of
        each trial, method, profile, draw; rmse_total_deg, rmse_inclination_deg,
        rmse_heading_deg (movement samples with a reference, :func:`wsnlib.metrics.broad_rmse_deg`);
        setting_source (:attr:`setting_source`: ``"leave-one-recording-out"``,
        ``"leave-one-group-out"``, or ``"defaults (one recording)"`` when there was nothing to
        tune on) and the setting used.  In the
        order of :attr:`per_trial`'s rows.
        """
        rows = self.per_trial
        units = self.units.loc[rows["trial"]]
        return pd.DataFrame({"recording": units["recording"].to_numpy(), "node": units["node"].to_numpy(),
                             "method": rows["method"].to_numpy(), "profile": rows["profile"].to_numpy(),
                             "draw": rows["draw"].to_numpy(), "rmse_total_deg": rows["rmse_total"].to_numpy(),
                             "rmse_inclination_deg": rows["rmse_inclination"].to_numpy(),
                             "rmse_heading_deg": rows["rmse_heading"].to_numpy(),
                             "setting_source": self.setting_source, "setting": rows["setting"].to_numpy()},
                            columns=list(RMSE_TABLE_COLUMNS))


def _gap_response(error, lossless, received, window_s, fs) -> dict:
    """Result columns: medians over the gaps of the peak and mean error increase (°), of the recovery
    (s, censored at the window), the recovered share and the number of gaps scored (NaN and 0 without
    a gap scored); ``fs`` (Hz) the recording's rate."""
    ends = np.flatnonzero(metrics.gap_end_mask(received))
    response = metrics.burst_response(error, lossless, ends, fs, window_s=window_s,
                                      threshold_deg=RECOVERY_THRESHOLD_DEG)
    recovery = response["recovery_s"]
    values = (np.nan, np.nan, np.nan, np.nan, 0) if response["kept"].size == 0 else (
        float(np.median(response["peak_increase_deg"])), float(np.median(response["mean_increase_deg"])),
        float(np.median(np.minimum(recovery, window_s))), float(np.mean(np.isfinite(recovery))),
        int(response["kept"].size))
    return dict(zip(("peak_increase_deg", "mean_increase_deg", "recovery_s", "recovered_share", "n_gaps_scored"),
                    values, strict=True))


def _score_rows(name, method, rows, setting, rec, masks, quat):
    """One result row per mask (``rows``: its profile and draw); the total error per sample."""
    errors = metrics.broad_errors_deg(quat, rec.quat_ref)
    rmse = metrics.rmse_of_errors_deg(errors, rec.movement)
    total = errors["total"]
    moving = np.where(rec.movement, total, np.nan)
    phases = metrics.error_by_phase(moving, masks, rec.fs, after_s=AFTER_GAP_S)
    steps = metrics.quat_gap_end_steps_deg(quat, masks)
    jitter = metrics.angular_jerk_rms_deg(quat, rec.fs, masks)
    out = []
    for k, (profile, draw) in enumerate(rows):
        latency = {"none": 0.0, "offline": rec.n_samples / rec.fs}[method.latency]
        out.append({"trial": name, "method": method.name, "kind": method.kind, "profile": profile.name,
                    "draw": draw, "setting": str(setting), "lost_share": float(1.0 - masks[k].mean()),
                    **{f"rmse_{key}": float(v[k]) for key, v in rmse.items()},
                    **{f"rms_{ph}": float(phases[ph][k]) for ph in metrics.PHASES},
                    **{f"n_{ph}": int(phases[f"n_{ph}"][k]) for ph in metrics.PHASES},
                    **_gap_response(moving[k], moving[0], masks[k], response_window_s(profile), rec.fs),
                    "gap_end_step_deg": float(steps["mean_deg"][k]) if steps["n_gaps"][k] else np.nan,
                    "jitter_deg_s3": float(jitter[k]), **_burst_columns(total[k], masks[k], profile, rec.fs),
                    "latency_s": latency, "latency_rule": method.latency})
    return out, total


#: Settings per tuning job: the default budget makes one job per method and trial.
SETTINGS_PER_JOB = 12


def _tuning_job(method, rec, received, settings):
    """Headline RMSE (total, heading, inclination; mean over the masks ``received``) of each of
    ``settings`` on one trial ``(len(settings), 3)``, and the seconds it took."""
    start = time.perf_counter()
    scores = np.empty((len(settings), 3))
    for i, setting in enumerate(settings):
        rmse = metrics.broad_rmse_deg(method.run(rec, setting, received), rec.quat_ref, rec.movement)
        scores[i] = [np.mean(rmse[key]) for key in ("total", "heading", "inclination")]
    return scores, time.perf_counter() - start


def _scoring_job(name, method, rec, masks, rows, setting, burst):
    """Result rows of one method on one trial under every mask; its total error without loss and
    under the burst profile (row ``burst``, or None) for the traces; the seconds it took."""
    start = time.perf_counter()
    quat = method.run(rec, setting, masks)
    new_rows, total = _score_rows(name, method, rows, setting, rec, masks, quat)
    return new_rows, total[0], None if burst is None else total[burst], time.perf_counter() - start


def _masks(profiles, recording, fs: float, rng: np.random.Generator, draws: Mapping[str, int]):
    """Masks ``(K, T)`` of every profile (``draws[name]`` of each random one, one per position of a
    :class:`BurstPositions`) at ``fs`` (Hz), and each row's (profile, draw).  Each profile draws from
    its own generator, keyed by ``rng``'s seed and the profile's name, so a profile's masks do not
    depend on which other profiles are run (a second study of a subset of the methods and profiles
    sees the same masks)."""
    seed = rng.bit_generator.seed_seq
    if not isinstance(seed, np.random.SeedSequence):
        raise ValueError("rng must be a numpy.random.Generator seeded from a SeedSequence (np.random.default_rng(...))")
    n_samples = recording.n_samples
    masks, rows = [], []
    for profile in profiles:
        if profile.model == BurstPositions.model:
            masks.append(profile.masks(np.asarray(recording.movement, dtype=bool), fs))
        else:
            n = draws[profile.name] if profile.model == "gilbert_elliott" else 1
            key = zlib.crc32(profile.name.encode())
            profile_rng = np.random.default_rng(np.random.SeedSequence(seed.entropy,
                                                                       spawn_key=(*seed.spawn_key, key)))
            masks.append(profile.mask(n_samples, fs, profile_rng, shape=(n,)))
        rows += [(profile, d) for d in range(len(masks[-1]))]
    return np.concatenate(masks), rows


def _traced_burst(recording, masks, rows) -> int | None:
    """Row of the burst traced for the figures: under the first burst profile, the one whose mean
    angular rate over its lost samples is the median of its positions' (a typical burst, chosen
    without looking at any method's error); None without a burst profile."""
    burst = [k for k, (profile, _) in enumerate(rows) if profile.model in ("burst", BurstPositions.model)]
    if not burst:
        return None
    first = [k for k in burst if rows[k][0] is rows[burst[0]][0]]
    rate = np.linalg.norm(np.asarray(recording.gyr, dtype=float), axis=-1)
    during = np.array([rate[~masks[k]].mean() for k in first])
    return first[int(np.argsort(during, kind="stable")[(len(first) - 1) // 2])]


def evaluate(recordings: Mapping, *, rng: np.random.Generator, methods: Mapping[str, Method] | None = None,
             profiles=PROFILES, headline: str = HEADLINE, draws: int | Mapping[str, int] = 1,
             groups: Mapping | None = None, tuning_draws: int | None = None,
             n_jobs: int = -1, scheduler=None, progress: bool = True) -> LossToleranceResult:
    """Tune every method leave-one-group-out at ``headline`` and score it under every profile.

    Each trial (study unit) is run, masked, scored and traced at its own rate ``fs``.  Its
    setting is the one with the lowest mean headline score over the trials of the *other*
    groups (``groups``, by default the recordings: the nodes of one recording are held out
    together, :func:`wsnlib.loto.leave_one_out_choice` with groups; a method with
    :attr:`~wsnlib.studies.loss_tolerance.Method.setting_of` runs with that method's choice); with
    a single recording there is nothing to tune on and every method runs with its default
    (:meth:`~wsnlib.studies.loss_tolerance.Method.untuned_setting`), which the result's
    ``setting_source`` says.  Every run of a method on a trial is a job of
    :func:`wsnlib.parallel.run_jobs` (up to :data:`SETTINGS_PER_JOB` settings per tuning job; two
    methods whose tuning job runs the same function on the same settings share it, e.g. ``"Kalman"``
    and the first design of ``"Kalman, design in fold"``); the results do not depend on where the
    jobs ran.

    Parameters
    ----------
    recordings : mapping name → recording
        At least one trial, each a :class:`~wsnlib.studies.loss_tolerance.StudyRecording` (e.g.
        from :func:`~wsnlib.studies.loss_tolerance.load_recordings`) or any object with its
        attributes: ``fs`` (Hz), ``gyr``, ``acc``, ``mag`` ``(T, 3)`` sampled at ``fs``,
        ``quat_ref`` ``(T, 4)`` (NaN rows allowed), ``movement`` ``(T,)`` bool, ``n_samples``
        and optionally ``source`` (the recording it belongs to; default: the trial's own name).
    rng : numpy.random.Generator
        Spawns one child per trial, which draws that trial's loss masks.
    methods : mapping name → Method, optional
        Default :func:`~wsnlib.studies.loss_tolerance.default_methods`.
    profiles : sequence of wsnlib.loss.LossProfile
        The first must be lossless (the reference of the gap response); one named ``headline``.
    headline : str
        Profile at which the settings are tuned.
    draws : int or mapping profile name → int
        Masks drawn per trial for each random (Gilbert–Elliott) profile, ≥ 1; a mapping gives
        each profile its own number (1 for a profile it does not name), e.g. more at the headline,
        where the settings are tuned and the targets scored, than elsewhere.
    groups : mapping name → str, optional
        The group each trial is held out with (leave-one-group-out: a trial's setting is tuned
        on the trials of the *other* groups), e.g.
        :func:`~wsnlib.studies.loss_tolerance.holdout_groups` (BROAD's kinds of motion).  A
        group holds whole recordings (the nodes of one recording never straddle a fold).
        Default: each trial's recording (``source``).
    tuning_draws : int, optional
        Tune on the first this many of the headline's masks (default: all of them); the scores
        use them all.  Tuning is most of the study's run time (every setting of every method on
        every trial), and a leave-one-group-out choice already averages over the other groups'
        trials, so fewer masks there cost little (the tuning table shows how flat the scores
        are over the settings).  Every method tunes on the same masks.
    n_jobs : int
        Local worker processes (-1, default: one per core; 1: none, everything in this process).
    scheduler : str or distributed.Client, optional
        Run the jobs on a Dask cluster instead (address ``"tcp://host:8786"``, or a client).
    progress : bool
        Show tqdm progress bars over the jobs.

    Returns
    -------
    LossToleranceResult
        ``per_trial`` columns: trial, method, kind, profile, draw, setting, lost_share;
        rmse_total, rmse_heading, rmse_inclination (°, movement samples,
        :func:`wsnlib.metrics.broad_rmse_deg`); rms_lost, rms_after_gap, rms_steady and their
        sample counts n_* (°, total error on movement samples split by
        :func:`wsnlib.metrics.error_by_phase`, after-gap phase :data:`AFTER_GAP_S`; NaN with
        count 0 when a phase is empty, e.g. lost samples without loss); peak_increase_deg,
        mean_increase_deg, recovery_s, recovered_share, n_gaps_scored (the median over the
        gaps of the error increase over the lossless run in the profile's response window,
        :func:`response_window_s`, :func:`wsnlib.metrics.burst_response`: its peak, its mean,
        the time until it stays below :data:`RECOVERY_THRESHOLD_DEG` — a gap never recovered
        from counts as the whole window — and the share of gaps recovered from; NaN and 0
        gaps without loss); gap_end_step_deg (mean rotation between the last output before
        and the first after a gap, :func:`wsnlib.metrics.quat_gap_end_steps_deg`; NaN without
        gaps) and jitter_deg_s3 (RMS angular jerk away from gap ends,
        :func:`wsnlib.metrics.angular_jerk_rms_deg` given the mask); :data:`BURST_COLUMNS` (under a
        :class:`~wsnlib.studies.loss_tolerance.BurstPositions` profile, one burst per run, ``draw``
        the position: :func:`wsnlib.metrics.single_burst_response` on the total error of every
        sample with a reference, against the error just before the burst; NaN under the other
        profiles); latency_s and latency_rule (package docstring).
    """
    check_rng(rng)
    methods = default_methods() if methods is None else dict(methods)
    profiles = tuple(profiles)
    names = list(recordings)
    if not names:
        raise ValueError("recordings must hold at least one recording")
    if profiles[0].model != "none":
        raise ValueError("the first profile must be lossless (model 'none'): it is the gap response's reference")
    profile_names = [p.name for p in profiles]
    if headline not in profile_names:
        raise ValueError(f"headline must be one of the profiles {profile_names}, got {headline!r}")
    draws = _check_draws(draws, profile_names)
    tuning_draws = draws[headline] if tuning_draws is None else check_count(tuning_draws, "tuning_draws")
    if tuning_draws > draws[headline]:
        raise ValueError(f"tuning_draws ({tuning_draws}) exceeds the headline's draws ({draws[headline]})")
    fs = {name: check_positive(getattr(recordings[name], "fs", None), f"recordings[{name!r}].fs") for name in names}
    sources = [str(getattr(recordings[name], "source", name)) for name in names]
    folds = sources if groups is None else _check_groups(groups, names, sources)
    tuned = len(set(folds)) >= 2
    by_recording = len(set(folds)) == len(set(sources)) == len(set(zip(folds, sources, strict=True)))
    setting_source = SETTING_SOURCES[1] if not tuned else SETTING_SOURCES[0 if by_recording else 2]
    masks, rows = {}, {}
    for name, trial_rng in zip(names, rng.spawn(len(names)), strict=True):
        masks[name], rows[name] = _masks(profiles, recordings[name], fs[name], trial_rng, draws)
    seconds = dict.fromkeys(methods, 0.0)
    if tuned:
        setting, tuning, choices, ran_here = _tune(recordings, names, folds, methods, masks, rows, headline,
                                                   tuning_draws, seconds, n_jobs=n_jobs, scheduler=scheduler,
                                                   progress=progress)
    else:
        ran_here = set()
        untuned = {m: method.untuned_setting() for m, method in methods.items()}
        setting = {m: [untuned[m]] * len(names) for m in methods}
        tuning = pd.DataFrame(columns=["method", "setting_index", "setting", "trial", "rmse_total", "rmse_heading",
                                       "rmse_inclination"])
        choices = pd.DataFrame([{"method": m, "trial": name,
                                 "setting_index": next((i for i, s in enumerate(methods[m].grid) if s == untuned[m]),
                                                       -1),
                                 "setting": str(untuned[m])} for m in methods for name in names])
    bursts = {name: _traced_burst(recordings[name], masks[name], rows[name]) for name in names}
    jobs = [(name, method, recordings[name], masks[name], rows[name], setting[m][j], bursts[name])
            for j, name in enumerate(names) for m, method in methods.items()]
    # As in the tuning: without a cluster, the first trial's job of each method the tuning did not run
    # in this process (a single setting, or another method's choice: the smoother) runs here first, so
    # that its kernels are compiled once, into numba's on-disk cache, not by every worker at once.
    first_here = [] if scheduler is not None else [k for k, m in enumerate(methods) if m not in ran_here]
    order = first_here + sorted(set(range(len(jobs))) - set(first_here))
    scored = parallel.run_jobs(_scoring_job, [jobs[k] for k in order], n_jobs=n_jobs, scheduler=scheduler,
                               in_process_first=len(first_here), progress=progress, desc="scoring every profile")
    by_job = dict(zip(order, scored, strict=True))
    done = (by_job[k] for k in range(len(jobs)))
    results, traces = [], {}
    for name in names:
        trace = {"fs": fs[name], "time_s": np.arange(recordings[name].n_samples) / fs[name], "error": {},
                 "lossless": {}}
        if bursts[name] is not None:
            trace["received"] = masks[name][bursts[name]]
            trace["burst_ends"] = np.flatnonzero(metrics.gap_end_mask(masks[name][bursts[name]]))
        for m in methods:
            new_rows, lossless, burst_error, elapsed = next(done)
            results += new_rows
            trace["lossless"][m] = lossless
            if burst_error is not None:
                trace["error"][m] = burst_error
            seconds[m] += elapsed
        traces[name] = trace
    units = pd.DataFrame({"recording": sources, "group": folds,
                          "node": [str(getattr(recordings[n], "node", "")) for n in names],
                          "fs_hz": [fs[n] for n in names], "n_samples": [recordings[n].n_samples for n in names]},
                         index=pd.Index(names, name="trial"))
    return LossToleranceResult(per_trial=pd.DataFrame(results), tuning=tuning, choices=choices, traces=traces,
                               seconds=pd.Series(seconds, name="seconds"), methods=methods, profiles=profiles,
                               units=units, setting_source=setting_source)


def _check_draws(draws, profile_names) -> dict[str, int]:
    """``draws`` (a count for every random profile, or a mapping profile name → count, 1 for a profile
    not named) as a count per profile name; ``ValueError`` for a count < 1 or an unknown name."""
    if isinstance(draws, Mapping):
        unknown = sorted(set(draws) - set(profile_names))
        if unknown:
            raise ValueError(f"draws names unknown profiles {unknown}; the profiles are {profile_names}")
        return {name: check_count(draws.get(name, 1), f"draws[{name!r}]") for name in profile_names}
    return dict.fromkeys(profile_names, check_count(draws, "draws"))


def _check_groups(groups, names, sources) -> list[str]:
    """``groups`` (mapping name → label) as one label per trial, in ``names``' order; ``ValueError`` if a
    trial has no label or one recording's trials are in two groups."""
    if not isinstance(groups, Mapping):
        raise ValueError(f"groups must map each trial name to a group label, got {type(groups).__name__}")
    missing = [name for name in names if name not in groups]
    if missing:
        raise ValueError(f"groups has no label for trial(s) {missing}")
    labels = [str(groups[name]) for name in names]
    split = sorted({s for s in sources if len({g for g, t in zip(labels, sources, strict=True) if t == s}) > 1})
    if split:
        raise ValueError(f"groups put the nodes of recording(s) {split} in different groups: a recording is held "
                         "out whole")
    return labels


def _tune(recordings, names, folds, methods, masks, rows, headline, tuning_draws, seconds, *, n_jobs, scheduler,
          progress):
    """Leave-one-group-out tuning at ``headline``'s first ``tuning_draws`` masks (``folds``: each trial's
    group): each trial's setting
    per method (``setting[m][j]``), the tuning table and the choices table (see
    :class:`LossToleranceResult`), and the methods whose first job ran in this process (none on a
    cluster); adds the run time to ``seconds``."""
    # Tuning jobs, one per method, trial and SETTINGS_PER_JOB settings.  Without a cluster, each
    # method's first job runs in this process first: each kernel is compiled once, into numba's
    # on-disk cache, which the local workers then read.  A method with a single setting has
    # nothing to choose, and one with ``setting_of`` takes another's choice: neither is run here
    # (no rows in the tuning table).
    following = {m: method.setting_of for m, method in methods.items()
                 if method.setting_of is not None and len(method.grid) > 1}
    for m, leader in following.items():
        if leader not in methods or methods[leader].grid != methods[m].grid:
            raise ValueError(f"{m!r} runs with the setting chosen for {leader!r}: include {leader!r} in methods, "
                             f"with the same grid")
    tuned = {m: method for m, method in methods.items() if len(method.grid) > 1 and m not in following}
    where = [(m, j, first) for j in range(len(names)) for m, method in tuned.items()
             for first in range(0, len(method.grid), SETTINGS_PER_JOB)]
    where.sort(key=lambda job: (job[1], job[2]) != (0, 0))
    at_headline = {name: [k for k, (profile, draw) in enumerate(rows[name])
                          if profile.name == headline and draw < tuning_draws] for name in names}
    # One job per distinct run: a method that runs the same function as another on the same settings
    # (the first design of "Kalman, design in fold" is "Kalman") takes that job's scores.
    job_of, unique = [], {}
    for m, j, first in where:
        key = (_run_key(methods[m].run), j, _settings_key(methods[m].grid[first:first + SETTINGS_PER_JOB]))
        job_of.append(unique.setdefault((m, j, first) if key[0] is None or key[2] is None else key, len(unique)))
    runs = {}  # job → its first (method, trial, first setting)
    for (m, j, first), job in zip(where, job_of, strict=True):
        runs.setdefault(job, (m, j, first))
    jobs = [(methods[m], recordings[names[j]], masks[names[j]][at_headline[names[j]]],
             methods[m].grid[first:first + SETTINGS_PER_JOB]) for m, j, first in runs.values()]
    scores = {m: np.empty((len(tuned[m].grid), len(names), 3)) for m in tuned}  # total, heading, inclination
    warm_up = sum(1 for _, j, first in runs.values() if (j, first) == (0, 0)) if scheduler is None else 0
    done = parallel.run_jobs(_tuning_job, jobs, n_jobs=n_jobs, scheduler=scheduler, in_process_first=warm_up,
                             progress=progress, desc=f"tuning at {headline}")
    counted = set()
    for (m, j, first), job in zip(where, job_of, strict=True):
        score, elapsed = done[job]
        scores[m][first:first + len(score), j] = score
        if job not in counted:  # a shared job's seconds count once, for the method that asked first
            seconds[m] += elapsed
            counted.add(job)
    choice = {m: loto.leave_one_out_choice(scores[m][..., 0], groups=folds) if m in tuned
              else np.zeros(len(names), dtype=int) for m in methods}
    choice |= {m: choice[leader] for m, leader in following.items()}
    tuning = pd.DataFrame([{"method": m, "setting_index": i, "setting": str(s), "trial": name,
                            "rmse_total": scores[m][i, j, 0], "rmse_heading": scores[m][i, j, 1],
                            "rmse_inclination": scores[m][i, j, 2]}
                           for m, method in tuned.items() for i, s in enumerate(method.grid)
                           for j, name in enumerate(names)],
                          columns=["method", "setting_index", "setting", "trial", "rmse_total", "rmse_heading",
                                   "rmse_inclination"])
    choices = pd.DataFrame([{"method": m, "trial": name, "setting_index": int(choice[m][j]),
                             "setting": str(methods[m].grid[choice[m][j]])}
                            for m in methods for j, name in enumerate(names)])
    setting = {m: [methods[m].grid[i] for i in choice[m]] for m in methods}
    return setting, tuning, choices, set(tuned) if warm_up else set()


def _run_key(run):
    """What ``run`` computes, comparable across methods: a :func:`functools.partial`'s function and
    arguments (the registry's runs are partials of module-level functions), else ``run`` itself;
    None when that cannot be compared (unhashable arguments)."""
    return _hashable((run.func, run.args, tuple(sorted(run.keywords.items())))
                     if isinstance(run, functools.partial) else run)


def _settings_key(settings):
    """The settings of a job as a hashable tuple (each a dict's sorted items), or None when a value is unhashable."""
    return _hashable(tuple(tuple(sorted(setting.items())) for setting in settings))


def _hashable(key):
    """``key``, or None when it cannot be hashed (it is then never shared)."""
    try:
        hash(key)
    except TypeError:
        return None
    return key


def single_frame_trust(recordings: Mapping) -> pd.DataFrame:
    """How often the gated hybrid's gate trusts the single frame, per trial (no loss).

    Parameters
    ----------
    recordings : mapping name → recording
        As in :func:`evaluate`.

    Returns
    -------
    pandas.DataFrame
        Index trial; column ``trusted_share``: the fraction of movement samples on which
        :func:`wsnlib.orientation.single_frame_trusted` (the defaults of
        :class:`wsnlib.orientation.SingleFrameGate`) lets TRIAD into the hybrid.
    """
    rows = {}
    for name, rec in recordings.items():
        trusted = single_frame_trusted(rec.gyr, rec.acc, rec.mag, fs=rec.fs, single_frame_gate=SingleFrameGate())
        movement = np.asarray(rec.movement, dtype=bool)
        if not movement.any():
            raise ValueError(f"recording {name!r} has no movement sample")
        rows[name] = {"trusted_share": float(trusted[movement].mean())}
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("trial")
