"""Notebook 05's reading of the study: paper 001's options on BROAD, beside Fusion and VQF.

The study runs :func:`~wsnlib.studies.loss_tolerance.registry.paper001_methods` under
:func:`~wsnlib.studies.loss_tolerance.registry.paper001_profiles`, tuned leave-one-trial-out
without loss (:func:`~wsnlib.studies.loss_tolerance.evaluate` with ``headline="lossless"``);
the functions here turn its tables into notebook 05's: how each filter's gain was chosen
(:func:`tuning_summary`), what the paper's bursts add (:func:`burst_table`), and the "paper vs
ours" findings, every sentence generated from the numbers (:func:`findings`, :func:`summary_text`).
BROAD's trials are also grouped by their own names (slow rotation, fast motion, magnet:
:func:`trial_groups`); on other recordings the groups are empty and the sentences speak of all
trials (a "trial" is a study unit: a BROAD trial, or one node of a recording file).
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping

import numpy as np
import pandas as pd
import vqf

from wsnlib import loto, stats
from wsnlib.io.broad import broad_trial_numbers
from wsnlib.orientation import fusion_orientation
from wsnlib.sim import arm_extension, arm_kinematics
from wsnlib.studies.loss_tolerance.recordings import all_broad
from wsnlib.studies.loss_tolerance.summary import trial_table
from wsnlib.studies.loss_tolerance.tables import median_rate_deg_s

#: The filters whose gain is tuned, the method standing for each (the Madgwick options share
#: Madgwick's β, so hold_last's choice is Madgwick's) and the name of the tuned setting.
TUNED = {"Madgwick": ("hold_last", "beta", "β (rad/s)"), "Fusion": ("Fusion", "gain", "gain"),
         "VQF": ("VQF", "tauAcc", "tauAcc (s)")}
#: Paper 001's options on Madgwick's filter, in display order.
OUR_OPTIONS = ("hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid")
#: The filters that differ without loss (every option of ours is plain Madgwick then, and each
#: peer's hybrid is the peer).
DISTINCT_WITHOUT_LOSS = ("hold_last", "single frame", "Fusion", "VQF")
#: Paper 001's sampling rate (Hz, Section IV): the rate its movement is simulated at here.
PAPER_FS = 50.0
#: The burst profile and the measures of the error a burst adds (columns of the study's table).
BURST = "paper burst"
BURST_MEASURES = {"mean_increase_deg": "mean increase (°)", "peak_increase_deg": "peak increase (°)",
                  "recovered_share": "recovered within window", "recovery_s": "recovery (s)",
                  "gap_end_step_deg": "gap-end step (°)", "jitter_deg_s3": "jitter (°/s³)"}


def library_defaults() -> dict[str, float]:
    """The peers' own defaults of the tuned setting: Fusion's gain and VQF's ``tauAcc`` (Madgwick's β has none)."""
    return {"Fusion": float(inspect.signature(fusion_orientation).parameters["gain"].default),
            "VQF": float(vqf.VQF(1.0 / PAPER_FS).params["tauAcc"])}  # the defaults do not depend on the rate


def tuning_summary(tuning: pd.DataFrame, choices: pd.DataFrame, methods: Mapping,
                   groups: Mapping | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """How each filter's gain was chosen without loss, and the setting each trial is scored with.

    Parameters
    ----------
    tuning, choices : pandas.DataFrame
        ``result.tuning`` and ``result.choices`` of :func:`~wsnlib.studies.loss_tolerance.evaluate`.
    methods : mapping name → Method
    groups : mapping trial → recording, optional
        The recording each trial belongs to (``result.units["recording"]``): the trials of one
        recording are held out together, as in the study.  Default: each trial its own.

    Returns
    -------
    summary : pandas.DataFrame
        Index filter; setting, grid, the leave-one-trial-out choices with their counts, the
        in-sample choice (tuned on all trials: the optimistic reading), and the median
        lossless RMSE over trials with each trial's leave-one-trial-out setting, the in-sample
        one and the library's default (NaN where the default is not in the grid, or none).
    loto_settings : pandas.DataFrame
        Index trial; per filter the setting that trial is scored with.

    Raises
    ------
    ValueError
        ``tuning`` is empty: a study of a single recording, which runs every filter at its
        default (there is no leave-one-out choice to summarise).
    """
    if tuning.empty:
        raise ValueError("tuning is empty: the study ran a single recording, every filter at its default; the "
                         "tuning summary needs at least two recordings (leave-one-recording-out)")
    defaults = library_defaults()
    rows, chosen = [], {}
    for filter_name, (method, key, label) in TUNED.items():
        grid = [s[key] for s in methods[method].grid]
        scores = tuning[tuning["method"] == method].pivot(index="setting_index", columns="trial",
                                                            values="rmse_total")
        trials = list(dict.fromkeys(choices["trial"]))
        scores = scores[trials].to_numpy()
        labels = None if groups is None else [groups[t] for t in trials]
        in_sample = loto.in_sample_choice(scores)
        picks = choices[choices["method"] == method].set_index("trial").loc[trials, "setting_index"]
        chosen[f"{filter_name}: {label}"] = pd.Series(np.asarray(grid)[picks.to_numpy()], index=trials)
        default = defaults.get(filter_name)
        counts = chosen[f"{filter_name}: {label}"].value_counts().sort_index()
        rows.append({"filter": filter_name, "setting": label, "grid": ", ".join(f"{g:g}" for g in grid),
                     "chosen leave-one-trial-out (× trials)": ", ".join(f"{v:g} ×{n}" for v, n in counts.items()),
                     "in-sample choice": grid[in_sample],
                     "median RMSE, leave-one-trial-out (°)": float(np.median(loto.leave_one_out_scores(scores,
                                                                                                         labels))),
                     "median RMSE, in-sample choice (°)": float(np.median(scores[in_sample])),
                     "median RMSE, library default (°)": (float(np.median(scores[grid.index(default)]))
                                                          if default in grid else np.nan)})
    return pd.DataFrame(rows).set_index("filter"), pd.DataFrame(chosen).rename_axis("trial")


def burst_table(per_trial: pd.DataFrame) -> pd.DataFrame:
    """Per trial and method, what the paper's bursts add (:data:`BURST_MEASURES`, medians over the bursts)."""
    rows = per_trial[per_trial["profile"] == BURST]
    if rows.empty:
        raise ValueError(f"per_trial has no rows at {BURST!r}")
    return rows[["trial", "method", "n_gaps_scored", *BURST_MEASURES]].rename(columns=BURST_MEASURES)


def listed(names) -> str:
    """Trials for a sentence: BROAD's by their numbers (``"02, 07"``), others by name (`` `walk/wrist` ``)."""
    names = [str(name) for name in names]
    if not names:
        return "none"
    return broad_trial_numbers(names) if all_broad(names) else ", ".join(f"`{name}`" for name in names)


def trial_labels(names) -> list[str]:
    """Short labels for figures: BROAD's names without their number (``"undisturbed_slow_rotation_B"``),
    other names as they are."""
    names = [str(name) for name in names]
    return [name.split("_", 1)[1] for name in names] if all_broad(names) else names


def trial_groups(names) -> dict[str, list[str]]:
    """BROAD's trials grouped by their names: slow rotation, fast motion (rotation or translation), magnet
    (empty groups for names that are not BROAD's)."""
    names = list(names)
    if not all_broad(names):
        return {"slow rotation": [], "fast": [], "magnet": []}
    return {"slow rotation": [t for t in names if "slow_rotation" in t],
            "fast": [t for t in names if "_fast_" in t],
            "magnet": [t for t in names if "magnet" in t]}


def _paper_rate_deg_s() -> float:
    """Median angular rate (°/s) while moving of the paper's movement, notebooks 01–02's 90° arm extension."""
    extension = arm_kinematics(arm_extension(fs=PAPER_FS, duration_s=8.0, start_s=1.0, rise_s=4.0))
    rate = np.linalg.norm(extension.gyr[0], axis=-1)
    return float(np.degrees(np.median(rate[rate > 0.05 * rate.max()])))


def findings(per_trial: pd.DataFrame, recordings: Mapping, loto_rmse: Mapping, *, rng: np.random.Generator,
             n_boot: int = 2000) -> dict:
    """The numbers behind notebook 05's "paper vs ours", and its sentences (``"text"``, Markdown).

    Every sentence is generated from the numbers; BROAD's trial groups (:func:`trial_groups`)
    are named where the trials are BROAD's, and otherwise the sentences speak of every trial.

    Parameters
    ----------
    per_trial : pandas.DataFrame
        From :func:`~wsnlib.studies.loss_tolerance.evaluate` with the paper-001 registry.
    recordings : mapping trial → recording
        For the measured angular rates (and each trial's ``source``: how many nodes a recording has).
    loto_rmse : mapping filter → float
        Each peer's median lossless RMSE with the leave-one-trial-out setting (and, under
        ``"<filter> default"``, at its library default; NaN when not in the grid).
    rng : numpy.random.Generator
        For the bootstrap interval of the hybrid's peak increase against holding's.
    """
    increase = trial_table(per_trial, BURST, "mean_increase_deg").T          # methods × trials
    peak = trial_table(per_trial, BURST, "peak_increase_deg")
    lossless = trial_table(per_trial, "lossless", "rmse_total").T
    hold = increase.loc["hold_last"]
    groups = trial_groups(increase.columns)
    every = list(hold.index)
    remedy_pool, guess_pool = groups["slow rotation"] or every, groups["fast"] or every
    rate = median_rate_deg_s(recordings)
    paper_rate = _paper_rate_deg_s()
    out = {
        "holding adds error": [t for t in hold.index if hold[t] > 0],
        "remedies work": [t for t in remedy_pool if increase.loc["hybrid", t] < 0.5 * hold[t]
                          and increase.loc["gyro_interpolation", t] < 0.5 * hold[t]],
        "guessing fails": [t for t in guess_pool if increase.loc["gyro_interpolation", t] > hold[t]
                           and increase.loc["dt_extension", t] > hold[t]],
        "hybrid worse": [t for t in hold.index if increase.loc["hybrid", t] > hold[t]],
        "hybrid better on magnet": [t for t in groups["magnet"] if increase.loc["hybrid", t] < hold[t]],
        "triad factor": lossless.loc["single frame"] / lossless.loc["hold_last"],
        "peer effect": {lib: increase.loc[f"{lib} + hybrid (feedback)"] - increase.loc[lib]
                        for lib in ("Fusion", "VQF")},
        "closest trial": str((rate - paper_rate).abs().idxmin()), "paper rate": paper_rate, "rate": rate,
        "groups": groups, "remedy pool": remedy_pool, "guess pool": guess_pool,
    }
    change = stats.paired_difference_ci(peak["hybrid"], peak["hold_last"], rng=rng, n_boot=n_boot,
                                        statistic="median")
    out["peak change"] = change
    broad = all_broad(every)
    hybrid_worse, magnet, slow, fast = out["hybrid worse"], groups["magnet"], groups["slow rotation"], groups["fast"]
    verdict = ("larger than holding's" if change.low > 0 else "smaller than holding's" if change.high < 0
               else "not distinguishable from holding's (the interval contains 0)")
    worse_note = (f" (trials where holding itself adds at most {hold[hybrid_worse].max():.1f}°)"
                  if hybrid_worse else "")
    tuned = "; ".join(f"{f} {loto_rmse[f]:.1f}°" + (f" (at its default: {loto_rmse[f + ' default']:.1f}°)"
                                                       if np.isfinite(loto_rmse.get(f + " default", np.nan)) else "")
                      for f in ("Fusion", "VQF"))
    effect = out["peer effect"]
    factor = out["triad factor"]
    remedies = (f"; the slow-rotation trials ({listed(slow)}) run at {', '.join(f'{rate[t]:.0f}' for t in slow)} "
                f"°/s. The hybrid and gyro interpolation each remove more than half of the added error on "
                f"{listed(out['remedies work'])} of them." if slow else
                f". The hybrid and gyro interpolation each remove more than half of the added error on "
                f"{listed(out['remedies work'])} of the {len(every)} trials.")
    guessing = (f"On the fast trials ({listed(fast)}), Δt extension and gyro interpolation add more error than doing "
                f"nothing on {listed(out['guessing fails'])}: they assume the motion through the gap was uniform or "
                f"smooth, and fast back-and-forth motion is neither — the failure the paper itself anticipates in "
                f"Section V." if fast else
                f"Δt extension and gyro interpolation add more error than doing nothing on "
                f"{listed(out['guessing fails'])} of the {len(every)} trials"
                + (": there the motion through the gap was not uniform or smooth, as they assume — the failure the "
                   "paper itself anticipates in Section V." if out["guessing fails"] else "."))
    if (factor > 1).all() and broad:
        triad = ("Single frame (TRIAD) is not the clean fallback it is in simulation: real accelerometers see linear "
                 "acceleration (translation, tapping, vibration) and real magnetometers see disturbances"
                 + (" (the magnet trials)" if magnet else "") + f", so its lossless RMSE is "
                 f"{factor.min():.1f}–{factor.max():.0f} times data fusion's.")
    elif (factor > 1).all():
        triad = (f"Single frame (TRIAD) is worse than data fusion without loss on every trial: its lossless RMSE is "
                 f"{factor.min():.1f}–{factor.max():.1f} times data fusion's (it takes every sample at face value, "
                 f"linear acceleration and field disturbances included).")
    else:
        triad = (f"Single frame's (TRIAD's) lossless RMSE is {factor.min():.1f}–{factor.max():.1f} times data "
                 f"fusion's; it is the better estimate without loss on {listed(factor.index[factor < 1])}.")
    magnet_note = (f", and magnetic disturbance alone does not decide it: on the magnet trials ({listed(magnet)}) the "
                   f"hybrid adds less error than holding on {listed(out['hybrid better on magnet'])}." if magnet
                   else ".")
    sources = [str(getattr(recordings[t], "source", t)) for t in every]
    if len(set(sources)) == len(sources):
        nodes = ("BROAD has no arm and no second node" if broad else "These recordings have one node each")
        cannot = (f"{nodes}, so the elbow-angle figures of the paper have no counterpart here; errors are for one "
                  f"rigid IMU.")
    else:
        cannot = ("Errors are per node; the paper's elbow-angle figures would need the angle between two nodes, "
                  "which this study does not compute.")
    out["text"] = f"""
* **What carries over.** In {len(out['holding adds error'])} of {len(hold)} trials holding the last estimate
  through a burst adds error to data fusion ({hold.min():.1f}–{hold.max():.1f}° over the 4 s after a burst,
  median over the bursts), and it decays over seconds at a pace set by the filter's gain — the mechanism of
  Section II, now measured against {'optical truth' if broad else 'the reference'}. The trial nearest the paper's
  movement by measured angular rate (median |ω| while moving; our 90° extension of notebooks 01–02 runs at
  {paper_rate:.0f} °/s) is {listed([out['closest trial']])} at {rate[out['closest trial']]:.0f} °/s{remedies}
* **What does not.** {guessing} {triad} The hybrid, which leans on
  it after every burst, adds more error than holding on {listed(hybrid_worse)}{worse_note} and less on the
  other {len(hold) - len(hybrid_worse)}. Per trial,
  the hybrid's peak increase minus holding's has a median of {float(change.estimate):.1f}°
  [{float(change.low):.1f}, {float(change.high):.1f}] (95 % bootstrap interval over trials): the hybrid's peak is
  {verdict}.
* **The peers**, tuned like Madgwick (median lossless RMSE over trials with each trial's leave-one-trial-out
  setting: {tuned}). Wrapping a peer in the hybrid (feedback) raises its burst error on
  {listed(effect['Fusion'].index[effect['Fusion'] > 0])} (Fusion) and
  {listed(effect['VQF'].index[effect['VQF'] > 0])} (VQF), and lowers it on the other trials, as for
  our own hybrid. Whether the hybrid is worth adding depends on how trustworthy single frame is in the
  application{magnet_note}
* **What we cannot say.** {cannot}
"""
    return out


def summary_text(found: Mapping, n_trials: int) -> str:
    """Notebook 05's closing summary (Markdown) from :func:`findings` (``found``) over ``n_trials`` trials."""
    groups, works, fails = found["groups"], found["remedies work"], found["guessing fails"]
    remedy_where = (f"{len(groups['slow rotation'])} slow-rotation trials run" if groups["slow rotation"]
                    else f"{len(found['remedy pool'])} trials")
    guess_where = f"{len(groups['fast'])} fast trials run" if groups["fast"] else f"{len(found['guess pool'])} trials"
    return f"""
* On these recordings the loss mechanism is the one the paper describes: holding the last estimate through a burst
  adds error on {len(found['holding adds error'])} of {n_trials} trials. The remedies that assume something
  about the motion (smooth, uniform) or about single frame (accurate) remove more than half of it on
  {len(works)} of the {remedy_where}; guessing the motion adds more error than holding on {len(fails)} of the
  {guess_where}, and leaning on TRIAD adds more than holding on {len(found['hybrid worse'])} trials.
* Tuned the same way as ours (leave-one-recording-out, the same number of settings), the peers are ranked against
  Madgwick in the RMSE table, with ties where the intervals over trials overlap; the hybrid's worth on top of a peer
  depends on the trial, as it does for ours.

Then try the exercises below.
"""
