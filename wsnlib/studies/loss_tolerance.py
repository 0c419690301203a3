"""Loss-tolerant orientation on real recordings: methods, loss profiles, fair tuning, metrics (issue 11).

The study behind notebook 10 and ``benchmarks/eval_loss_tolerance.py``.  Every BROAD trial
given (resampled to :data:`FS`) is run through every method of a registry under every loss
profile, and scored against the optical reference; :mod:`wsnlib.studies.loss_tolerance_summary`
turns the tidy tables into means with bootstrap intervals, rankings and the issue's targets.

Fair tuning
-----------
Each method has a grid of at most :data:`MAX_SETTINGS` settings (the same budget for the
peers and for ours).  Tuning happens **once**, at the headline profile (:data:`HEADLINE`,
Gilbert–Elliott 10 %, mean burst 3 packets of 6 samples): every setting is scored by the
trial's total RMSE over movement samples, and leave-one-trial-out
(:func:`wsnlib.loto.leave_one_out_choice`) gives each trial the setting with the lowest mean
score over the *other* trials.  Under every other profile, each trial is scored with the
setting chosen for it at the headline profile — so a setting is never tuned on the trial it is
scored on, and the other profiles show how a setting tuned for one loss pattern carries over.

Loss profiles
-------------
Lossless; the paper's burst (4 packets of 6 samples, :func:`wsnlib.loss.burst_train`, one
burst every 8 s from 4 s on: no randomness); Gilbert–Elliott 5/10/20 % with a mean burst of 3
packets of 6 samples; and GE 10 % with 1- and 12-sample packets (mean burst 3 *packets*, so the
gaps scale with the packet).  Masks are drawn from a child of the ``rng`` passed in, one per
trial (:meth:`numpy.random.Generator.spawn`), so a trial's masks do not depend on how many
trials run, and every method sees the same masks (paired comparison).  One draw per trial and
profile.

Two options, two questions
--------------------------
The registry holds two options as methods of their own, so that they are tuned with the same
budget and scored on the same masks as what they modify: the *gated* hybrid (ours and Fusion's
wrapped in it), which applies the single frame only where
:class:`wsnlib.orientation.SingleFrameGate` trusts it, and the peers predicting at the last
received rate in a gap (``gap="constant_rate"``) instead of holding.  :data:`GATING_PAIRS` and
:data:`GAP_PREDICTION_PAIRS` name the pairs;
:func:`wsnlib.studies.loss_tolerance_summary.paired_comparisons` answers "does it help?".

The grids are module constants (:data:`KALMAN_GRID`, :data:`SMOOTHER_GRID`, ...) built with
:func:`settings_grid`; ``default_methods(grids={...})`` replaces any of them.

Latency
-------
Causal filters output each sample when it arrives (0 s).  Gyro interpolation fills a gap's
angular rate with the first sample *after* it, so its state for the gap is final only then:
latency up to the gap's length (reported as the trial's longest gap; its output on lost
samples is the held estimate).  The smoother needs the whole recording (latency = duration).

Modules
-------
:mod:`wsnlib.studies.loss_tolerance_registry` holds the methods (:func:`default_methods`, the grids)
and the loss profiles (:data:`PROFILES`); this module runs and scores them (:func:`evaluate`).  Every
name of the registry is re-exported here.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping

import numpy as np
import pandas as pd

from wsnlib import loss, loto, metrics

# Names marked F401 are re-exported: the registry's, and those earlier versions imported here.
from wsnlib.orientation import (  # noqa: F401
    KalmanSettings,
    SingleFrameGate,
    estimate_orientation,
    fusion_ahrs,
    kalman_orientation,
    single_frame_trusted,
    smooth_orientation,
    vqf_orientation,
)
from wsnlib.studies.loss_tolerance_registry import (  # noqa: F401
    BETA_GRID,
    FS,
    FUSION_GRID,
    FUSION_HYBRID_GRID,
    GAP_PREDICTION_PAIRS,
    GATING_PAIRS,
    HEADLINE,
    HYBRID_GRID,
    KALMAN_GRID,
    KINDS,
    LATENCY_RULES,
    MADGWICK_BETA,
    MAX_SETTINGS,
    PROFILES,
    SMOOTHER_GRID,
    VQF_GRID,
    VQF_HYBRID_GRID,
    LossProfile,
    Method,
    default_methods,
    quick_methods,
    settings_grid,
)

#: Length of the "after a gap" phase of :func:`wsnlib.metrics.error_by_phase` (s).
AFTER_GAP_S = 2.0
#: Recovery: the error increase over the lossless run back below this (°) for the window's rest.
RECOVERY_THRESHOLD_DEG = 2.0


@dataclasses.dataclass
class LossToleranceResult:
    """What :func:`evaluate` returns.

    Attributes
    ----------
    per_trial : pandas.DataFrame
        One row per method × profile × trial (columns in :func:`evaluate`).
    tuning : pandas.DataFrame
        Headline total RMSE (°) of every setting on every trial: method, setting index,
        setting, trial, rmse_total.
    choices : pandas.DataFrame
        Leave-one-trial-out choice per method and trial: method, trial, setting index, setting.
    traces : dict
        ``traces[trial]``: ``time_s``, ``received`` and ``burst_ends`` of the paper-burst
        profile, ``error`` (method → total error (°) per sample under it, NaN where the
        reference is missing) and ``lossless`` (the same without loss).
    seconds : pandas.Series
        Run time per method (s, tuning and scoring).
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


def _progress(iterable, desc, enabled):
    if not enabled:
        return iterable
    from tqdm.auto import tqdm

    return tqdm(iterable, desc=desc)


def _gap_response(error, lossless, received, window_s):
    """Median peak increase (°), median recovery (s, censored at the window) and recovered share."""
    ends = np.flatnonzero(metrics.gap_end_mask(received))
    if ends.size == 0:
        return np.nan, np.nan, np.nan, 0
    response = metrics.burst_response(error, lossless, ends, FS, window_s=window_s,
                                      threshold_deg=RECOVERY_THRESHOLD_DEG)
    if response["kept"].size == 0:
        return np.nan, np.nan, np.nan, 0
    recovery = response["recovery_s"]
    return (float(np.median(response["peak_increase_deg"])), float(np.median(np.minimum(recovery, window_s))),
            float(np.mean(np.isfinite(recovery))), int(response["kept"].size))


def _score_rows(name, method, profiles, setting, rec, masks, quat):
    rmse = metrics.broad_rmse_deg(quat, rec.quat_ref, rec.movement)
    total = metrics.broad_errors_deg(quat, rec.quat_ref)["total"]
    moving = np.where(rec.movement, total, np.nan)
    phases = metrics.error_by_phase(moving, masks, FS, after_s=AFTER_GAP_S)
    rows = []
    for p, profile in enumerate(profiles):
        longest_gap = int(loss.lost_run_length(masks[p]).max(initial=0))
        latency = {"none": 0.0, "gap": longest_gap / FS, "offline": rec.n_samples / FS}[method.latency]
        peak, recovery, recovered, n_gaps = _gap_response(moving[p], moving[0], masks[p], profile.response_window_s)
        rows.append({"trial": name, "method": method.name, "kind": method.kind, "profile": profile.name,
                     "setting": str(setting), "lost_share": float(1.0 - masks[p].mean()),
                     **{f"rmse_{k}": float(v[p]) for k, v in rmse.items()},
                     **{f"rms_{ph}": float(phases[ph][p]) for ph in metrics.PHASES},
                     **{f"n_{ph}": int(phases[f"n_{ph}"][p]) for ph in metrics.PHASES},
                     "peak_increase_deg": peak, "recovery_s": recovery, "recovered_share": recovered,
                     "n_gaps_scored": n_gaps, "latency_s": latency, "latency_rule": method.latency})
    return rows, total


def evaluate(recordings: Mapping, *, rng: np.random.Generator, methods: Mapping[str, Method] | None = None,
             profiles=PROFILES, headline: str = HEADLINE, progress: bool = True) -> LossToleranceResult:
    """Tune every method leave-one-trial-out at ``headline`` and score it under every profile.

    Parameters
    ----------
    recordings : mapping name → recording
        At least 2 trials (leave-one-trial-out), each with ``gyr``, ``acc``, ``mag`` ``(T, 3)``
        sampled at :data:`FS`, ``quat_ref`` ``(T, 4)`` (NaN rows allowed), ``movement``
        ``(T,)`` bool and ``n_samples`` (e.g. :func:`load_recordings`).
    rng : numpy.random.Generator
        Spawns one child per trial, which draws that trial's loss masks.
    methods : mapping name → Method, optional
        Default :func:`default_methods`.
    profiles : sequence of LossProfile
        The first must be lossless (the reference of the gap response); one named ``headline``.
    headline : str
        Profile at which the settings are tuned.
    progress : bool
        Show a tqdm progress bar over the trials.

    Returns
    -------
    LossToleranceResult
        ``per_trial`` columns: trial, method, kind, profile, setting, lost_share; rmse_total,
        rmse_heading, rmse_inclination (°, movement samples, :func:`wsnlib.metrics.broad_rmse_deg`);
        rms_lost, rms_after_gap, rms_steady and their sample counts n_* (°, total error on
        movement samples split by :func:`wsnlib.metrics.error_by_phase`, after-gap phase
        :data:`AFTER_GAP_S`; NaN with count 0 when a phase is empty, e.g. lost samples without
        loss); peak_increase_deg, recovery_s, recovered_share, n_gaps_scored (the median over
        the gaps of the error increase over the lossless run in the profile's response
        window, :func:`wsnlib.metrics.burst_response`: its peak, the time until it stays below
        :data:`RECOVERY_THRESHOLD_DEG` — a gap never recovered from counts as the whole
        window — and the share of gaps recovered from; NaN and 0 gaps without loss);
        latency_s and latency_rule (module docstring).
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
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
    h = profile_names.index(headline)
    masks = {}
    for name, trial_rng in zip(names, rng.spawn(len(names)), strict=True):
        n = recordings[name].n_samples
        masks[name] = np.stack([p.mask(n, FS, trial_rng) for p in profiles])
    seconds = dict.fromkeys(methods, 0.0)
    scores = {m: np.empty((len(methods[m].grid), len(names))) for m in methods}
    for j, name in enumerate(_progress(names, f"tuning at {headline}", progress)):
        rec = recordings[name]
        for m, method in methods.items():
            start = time.perf_counter()
            for i, setting in enumerate(method.grid):
                quat = method.run(rec, setting, masks[name][h:h + 1])
                scores[m][i, j] = metrics.broad_rmse_deg(quat, rec.quat_ref, rec.movement)["total"][0]
            seconds[m] += time.perf_counter() - start
    choice = {m: loto.leave_one_out_choice(scores[m]) for m in methods}
    tuning = pd.DataFrame([{"method": m, "setting_index": i, "setting": str(s), "trial": name,
                            "rmse_total": scores[m][i, j]}
                           for m, method in methods.items() for i, s in enumerate(method.grid)
                           for j, name in enumerate(names)])
    choices = pd.DataFrame([{"method": m, "trial": name, "setting_index": int(choice[m][j]),
                             "setting": str(methods[m].grid[choice[m][j]])}
                            for m in methods for j, name in enumerate(names)])
    rows, traces = [], {}
    burst = next((p for p, profile in enumerate(profiles) if profile.model == "burst"), None)
    for j, name in enumerate(_progress(names, "scoring every profile", progress)):
        rec = recordings[name]
        trace = {"time_s": np.arange(rec.n_samples) / FS, "error": {}, "lossless": {}}
        if burst is not None:
            trace["received"] = masks[name][burst]
            trace["burst_ends"] = np.flatnonzero(metrics.gap_end_mask(masks[name][burst]))
        for m, method in methods.items():
            start = time.perf_counter()
            setting = method.grid[choice[m][j]]
            quat = method.run(rec, setting, masks[name])
            new_rows, total = _score_rows(name, method, profiles, setting, rec, masks[name], quat)
            rows += new_rows
            trace["lossless"][m] = total[0]
            if burst is not None:
                trace["error"][m] = total[burst]
            seconds[m] += time.perf_counter() - start
        traces[name] = trace
    return LossToleranceResult(per_trial=pd.DataFrame(rows), tuning=tuning, choices=choices, traces=traces,
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
    from wsnlib.io.broad import load_broad
    from wsnlib.io.resample import resample_broad

    return {name: resample_broad(load_broad(name, download=download), fs)
            for name in _progress(list(names), "load + resample", progress)}
