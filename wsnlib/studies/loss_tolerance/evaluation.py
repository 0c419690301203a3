"""Running the loss-tolerance study: masks, leave-one-trial-out tuning, scoring (:func:`evaluate`).

What is run and why: the package docstring (:mod:`wsnlib.studies.loss_tolerance`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from wsnlib import loss, loto, metrics, parallel
from wsnlib._validation import check_count, check_rng
from wsnlib.io.broad import load_broad
from wsnlib.io.resample import resample_broad
from wsnlib.orientation import SingleFrameGate, single_frame_trusted
from wsnlib.studies.loss_tolerance.registry import FS, HEADLINE, PROFILES, Method, default_methods

#: Length of the "after a gap" phase of :func:`wsnlib.metrics.error_by_phase` (s).
AFTER_GAP_S = 2.0
#: Recovery: the error increase over the lossless run back below this (°) for the window's rest.
RECOVERY_THRESHOLD_DEG = 2.0
#: Window after each gap in which the error increase and recovery are measured (s): the paper's
#: bursts come every 8 s (4 s fit between them); random gaps come closer (2 s).
BURST_RESPONSE_WINDOW_S, GAP_RESPONSE_WINDOW_S = 4.0, 2.0


def response_window_s(profile) -> float:
    """:data:`BURST_RESPONSE_WINDOW_S` for a burst profile, else :data:`GAP_RESPONSE_WINDOW_S`."""
    return BURST_RESPONSE_WINDOW_S if profile.model == "burst" else GAP_RESPONSE_WINDOW_S


@dataclasses.dataclass
class LossToleranceResult:
    """What :func:`evaluate` returns.

    Attributes
    ----------
    per_trial : pandas.DataFrame
        One row per method × profile × trial (columns in :func:`evaluate`).
    tuning : pandas.DataFrame
        Headline RMSE (°, mean over the headline's draws) of every setting on every trial:
        method, setting_index, setting, trial, rmse_total, rmse_heading, rmse_inclination.
    choices : pandas.DataFrame
        Leave-one-trial-out choice per method and trial: method, trial, setting index, setting.
    traces : dict
        ``traces[trial]``: ``time_s``, ``received`` and ``burst_ends`` of the paper-burst
        profile, ``error`` (method → total error (°) per sample under it, NaN where the
        reference is missing) and ``lossless`` (the same without loss).
    seconds : pandas.Series
        Run time per method (s, tuning and scoring), summed over its jobs wherever they ran
        (compute time, not wall-clock time).
    methods : dict[str, Method]
    profiles : tuple of LossProfile
    """

    per_trial: pd.DataFrame
    tuning: pd.DataFrame
    choices: pd.DataFrame
    traces: dict
    seconds: pd.Series
    methods: dict
    profiles: tuple


def _gap_response(error, lossless, received, window_s) -> dict:
    """Result columns: medians over the gaps of the peak and mean error increase (°), of the recovery
    (s, censored at the window), the recovered share and the number of gaps scored (NaN and 0 without
    a gap scored)."""
    ends = np.flatnonzero(metrics.gap_end_mask(received))
    response = metrics.burst_response(error, lossless, ends, FS, window_s=window_s,
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
    rmse = metrics.broad_rmse_deg(quat, rec.quat_ref, rec.movement)
    total = metrics.broad_errors_deg(quat, rec.quat_ref)["total"]
    moving = np.where(rec.movement, total, np.nan)
    phases = metrics.error_by_phase(moving, masks, FS, after_s=AFTER_GAP_S)
    steps = metrics.quat_gap_end_steps_deg(quat, masks)
    jitter = metrics.angular_jerk_rms_deg(quat, FS, masks)
    out = []
    for k, (profile, draw) in enumerate(rows):
        longest_gap = int(loss.lost_run_length(masks[k]).max(initial=0))
        latency = {"none": 0.0, "gap": longest_gap / FS, "offline": rec.n_samples / FS}[method.latency]
        out.append({"trial": name, "method": method.name, "kind": method.kind, "profile": profile.name,
                    "draw": draw, "setting": str(setting), "lost_share": float(1.0 - masks[k].mean()),
                    **{f"rmse_{key}": float(v[k]) for key, v in rmse.items()},
                    **{f"rms_{ph}": float(phases[ph][k]) for ph in metrics.PHASES},
                    **{f"n_{ph}": int(phases[f"n_{ph}"][k]) for ph in metrics.PHASES},
                    **_gap_response(moving[k], moving[0], masks[k], response_window_s(profile)),
                    "gap_end_step_deg": float(steps["mean_deg"][k]) if steps["n_gaps"][k] else np.nan,
                    "jitter_deg_s3": float(jitter[k]),
                    "latency_s": latency, "latency_rule": method.latency})
    return out, total


#: Settings per tuning job: a budget of 8 makes one job per method and trial.
SETTINGS_PER_JOB = 8


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


def _masks(profiles, n_samples: int, rng: np.random.Generator, draws: int):
    """Masks ``(K, T)`` of every profile (``draws`` of each random one) and each row's (profile, draw)."""
    masks, rows = [], []
    for profile in profiles:
        n = draws if profile.model == "gilbert_elliott" else 1
        masks.append(profile.mask(n_samples, FS, rng, shape=(n,)))
        rows += [(profile, d) for d in range(n)]
    return np.concatenate(masks), rows


def evaluate(recordings: Mapping, *, rng: np.random.Generator, methods: Mapping[str, Method] | None = None,
             profiles=PROFILES, headline: str = HEADLINE, draws: int = 1, n_jobs: int = -1, scheduler=None,
             progress: bool = True) -> LossToleranceResult:
    """Tune every method leave-one-trial-out at ``headline`` and score it under every profile.

    Every run of a method on a trial is a job of :func:`wsnlib.parallel.run_jobs` (up to
    :data:`SETTINGS_PER_JOB` settings per tuning job); the results do not depend on where
    the jobs ran.

    Parameters
    ----------
    recordings : mapping name → recording
        At least 2 trials (leave-one-trial-out), each with ``gyr``, ``acc``, ``mag`` ``(T, 3)``
        sampled at :data:`FS`, ``quat_ref`` ``(T, 4)`` (NaN rows allowed), ``movement``
        ``(T,)`` bool and ``n_samples`` (e.g. :func:`load_recordings`).
    rng : numpy.random.Generator
        Spawns one child per trial, which draws that trial's loss masks.
    methods : mapping name → Method, optional
        Default :func:`~wsnlib.studies.loss_tolerance.default_methods`.
    profiles : sequence of wsnlib.loss.LossProfile
        The first must be lossless (the reference of the gap response); one named ``headline``.
    headline : str
        Profile at which the settings are tuned.
    draws : int
        Masks drawn per trial for each random (Gilbert–Elliott) profile, ≥ 1.
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
        :func:`wsnlib.metrics.angular_jerk_rms_deg` given the mask); latency_s and latency_rule (package
        docstring).
    """
    check_rng(rng)
    check_count(draws, "draws")
    methods = default_methods() if methods is None else dict(methods)
    profiles = tuple(profiles)
    names = list(recordings)
    if len(names) < 2:
        raise ValueError(f"recordings must hold at least 2 trials for leave-one-trial-out, got {len(names)}")
    if profiles[0].model != "none":
        raise ValueError("the first profile must be lossless (model 'none'): it is the gap response's reference")
    profile_names = [p.name for p in profiles]
    if headline not in profile_names:
        raise ValueError(f"headline must be one of the profiles {profile_names}, got {headline!r}")
    masks, rows = {}, {}
    for name, trial_rng in zip(names, rng.spawn(len(names)), strict=True):
        masks[name], rows[name] = _masks(profiles, recordings[name].n_samples, trial_rng, draws)
    seconds = dict.fromkeys(methods, 0.0)
    # Tuning jobs, one per method, trial and SETTINGS_PER_JOB settings.  Without a cluster, each
    # method's first job runs in this process first: each kernel is compiled once, into numba's
    # on-disk cache, which the local workers then read.
    where = [(m, j, first) for j in range(len(names)) for m, method in methods.items()
             for first in range(0, len(method.grid), SETTINGS_PER_JOB)]
    where.sort(key=lambda job: (job[1], job[2]) != (0, 0))
    at_headline = {name: [k for k, (profile, _) in enumerate(rows[name]) if profile.name == headline]
                   for name in names}
    jobs = [(methods[m], recordings[names[j]], masks[names[j]][at_headline[names[j]]],
             methods[m].grid[first:first + SETTINGS_PER_JOB]) for m, j, first in where]
    scores = {m: np.empty((len(methods[m].grid), len(names), 3)) for m in methods}  # total, heading, inclination
    warm_up = len(methods) if scheduler is None else 0
    done = parallel.run_jobs(_tuning_job, jobs, n_jobs=n_jobs, scheduler=scheduler, in_process_first=warm_up,
                             progress=progress, desc=f"tuning at {headline}")
    for (m, j, first), (score, elapsed) in zip(where, done, strict=True):
        scores[m][first:first + len(score), j] = score
        seconds[m] += elapsed
    choice = {m: loto.leave_one_out_choice(scores[m][..., 0]) for m in methods}
    tuning = pd.DataFrame([{"method": m, "setting_index": i, "setting": str(s), "trial": name,
                            "rmse_total": scores[m][i, j, 0], "rmse_heading": scores[m][i, j, 1],
                            "rmse_inclination": scores[m][i, j, 2]}
                           for m, method in methods.items() for i, s in enumerate(method.grid)
                           for j, name in enumerate(names)])
    choices = pd.DataFrame([{"method": m, "trial": name, "setting_index": int(choice[m][j]),
                             "setting": str(methods[m].grid[choice[m][j]])}
                            for m in methods for j, name in enumerate(names)])
    bursts = {name: next((k for k, (profile, _) in enumerate(rows[name]) if profile.model == "burst"), None)
              for name in names}
    jobs = [(name, method, recordings[name], masks[name], rows[name], method.grid[choice[m][j]], bursts[name])
            for j, name in enumerate(names) for m, method in methods.items()]
    done = iter(parallel.run_jobs(_scoring_job, jobs, n_jobs=n_jobs, scheduler=scheduler, progress=progress,
                                  desc="scoring every profile"))
    results, traces = [], {}
    for name in names:
        trace = {"time_s": np.arange(recordings[name].n_samples) / FS, "error": {}, "lossless": {}}
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
    return LossToleranceResult(per_trial=pd.DataFrame(results), tuning=tuning, choices=choices, traces=traces,
                               seconds=pd.Series(seconds, name="seconds"), methods=methods, profiles=profiles)


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
        trusted = single_frame_trusted(rec.gyr, rec.acc, rec.mag, fs=FS, single_frame_gate=SingleFrameGate())
        movement = np.asarray(rec.movement, dtype=bool)
        if not movement.any():
            raise ValueError(f"recording {name!r} has no movement sample")
        rows[name] = {"trusted_share": float(trusted[movement].mean())}
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("trial")


def load_recordings(names, *, fs: float = FS, download: bool = False, progress: bool = True) -> dict:
    """BROAD trials by name, loaded (:func:`wsnlib.io.broad.load_broad`; from ``$WSNLIB_BROAD_DIR``,
    downloaded and hash-checked only with ``download``) and resampled to ``fs`` (Hz)."""
    return {name: resample_broad(load_broad(name, download=download), fs)
            for name in tqdm(list(names), desc="load + resample", disable=not progress)}
