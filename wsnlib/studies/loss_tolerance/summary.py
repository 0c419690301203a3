"""Summaries of the loss-tolerance study: means with bootstrap intervals, rankings, the issue's targets.

Inputs are the tidy ``per_trial`` table of :func:`wsnlib.studies.loss_tolerance.evaluate`; a
trial's value under a profile is the mean over its loss draws.  Every interval is a bootstrap
from :mod:`wsnlib.stats` (paired: all methods are resampled with the same units): over trials,
or, with ``groups`` (trial → group, e.g. BROAD's kinds of motion), over groups *and* loss draws
(:func:`wsnlib.stats.grouped_bootstrap_ci`: near-duplicate trials are not independent units;
with fewer than 2 groups, e.g. the nodes of a single recording, over trials).
Every sentence is generated from the numbers.

Targets (issue 11, at the headline profile, GE 10 %)
----------------------------------------------------
1. best causal estimator's mean total RMSE ≤ 0.5 × the best peer's;
2. offline smoother's ≤ 0.25 × the best peer's;
3. lossless: the best causal estimator's mean total RMSE ≤ VQF's (its authors' defaults) + 1°.

"Best" is the lowest mean total RMSE at the headline profile among the causal methods without
latency (kind ``"causal"``, latency ``"none"``), among the peers, and among the offline methods.
Targets 1 and 2 are stated twice (issue 25): against the best peer *with the same gap handling*
as ours (:data:`~wsnlib.studies.loss_tolerance.GAP_HANDLING_OF`: what the filter contributes),
and against the best of the peers *as users run them today*
(:data:`~wsnlib.studies.loss_tolerance.AS_USERS_RUN_THEM`: their authors' defaults).
A target PASSes when the point estimate meets it; the interval says how sure that is.

The ablation (:func:`ablation_table`) lays out filter × gap handling
(:data:`~wsnlib.studies.loss_tolerance.ABLATION`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnlib import loto, stats
from wsnlib.studies.loss_tolerance.evaluation import AFTER_GAP_S
from wsnlib.studies.loss_tolerance.registry import ABLATION, AS_USERS_RUN_THEM, GAP_HANDLING_OF, GAP_HANDLINGS, HEADLINE

#: Metrics summarised by :func:`summary_table` by default.
SUMMARY_METRICS = ("rmse_total", "rmse_heading", "rmse_inclination", "rms_lost", "rms_after_gap", "rms_steady",
                   "peak_increase_deg", "recovery_s", "burst_before_deg", "burst_peak_increase_deg",
                   "burst_recovery_s", "burst_recovered", "burst_level_recovery_s", "burst_level_recovered")

#: The issue's targets: name → (kind of comparison, target value, ours (a key of
#: :func:`best_methods`), the peer it is compared with (a key of :func:`best_methods`)).
TARGETS = {"best causal / best peer, same gap handling (GE 10 %)": ("ratio", 0.5, "causal", "peer, same gap (causal)"),
           "best causal / best peer as users run them (GE 10 %)": ("ratio", 0.5, "causal", "peer, as users run them"),
           "smoother / best peer, same gap handling (GE 10 %)": ("ratio", 0.25, "offline",
                                                                  "peer, same gap (offline)"),
           "smoother / best peer as users run them (GE 10 %)": ("ratio", 0.25, "offline", "peer, as users run them"),
           "lossless: best causal − VQF (defaults), °": ("difference", 1.0, "causal", "lossless reference")}

#: The peer whose authors' defaults are the lossless reference.
LOSSLESS_REFERENCE = "VQF (defaults)"


def trial_table(per_trial: pd.DataFrame, profile: str, metric: str) -> pd.DataFrame:
    """Trials × methods of ``metric`` at ``profile``, the mean over each trial's loss draws (methods
    in the table's order, trials sorted)."""
    rows = per_trial[per_trial["profile"] == profile]
    if rows.empty:
        raise ValueError(f"no rows at profile {profile!r}")
    order = list(dict.fromkeys(rows["method"]))
    return rows.groupby(["trial", "method"])[metric].mean().unstack("method")[order]


def draw_values(per_trial: pd.DataFrame, profile: str, metric: str, trials=None) -> tuple[list[str], np.ndarray]:
    """``metric`` at ``profile`` as an array ``(n_trials, n_draws, n_methods)`` (trials sorted, or in
    the order of ``trials``), and the methods' names (in the table's order)."""
    rows = per_trial[per_trial["profile"] == profile]
    if rows.empty:
        raise ValueError(f"no rows at profile {profile!r}")
    methods = list(dict.fromkeys(rows["method"]))
    table = rows.pivot_table(index=["trial", "draw"], columns="method", values=metric, aggfunc="first",
                             dropna=False)[methods]
    trials = sorted(set(rows["trial"])) if trials is None else list(trials)
    draws = table.groupby(level="trial").size()
    if draws.nunique() != 1:
        raise ValueError(f"every trial needs the same number of draws at {profile!r}, got {draws.to_dict()}")
    table = table.loc[trials]
    return methods, table.to_numpy().reshape(len(trials), int(draws.iloc[0]), len(methods))


def _group_labels(groups, trials) -> np.ndarray | None:
    """One label per trial; None when ``groups`` is None or gives fewer than 2 groups (a single
    recording's nodes): the intervals are then over trials."""
    if groups is None:
        return None
    missing = [t for t in trials if t not in groups]
    if missing:
        raise ValueError(f"groups has no label for trial(s) {missing}")
    labels = np.array([str(groups[t]) for t in trials])
    return labels if len(set(labels)) >= 2 else None


def summary_table(per_trial: pd.DataFrame, *, rng: np.random.Generator, metrics=SUMMARY_METRICS,
                  n_boot: int = 2000, groups=None) -> pd.DataFrame:
    """Mean over trials with a 95 % bootstrap interval, per metric, profile and method.

    Undefined values (NaN) are handled explicitly: a trial on which the metric is undefined for
    every method (e.g. no gap whose response could be scored) is left out, then a method still
    undefined on some trial is left out of that profile and metric (e.g. error on lost samples
    without loss); a profile left with fewer than 2 trials has no row.

    With ``groups`` (mapping trial → group), the intervals are over groups and loss draws
    (:func:`wsnlib.stats.grouped_bootstrap_ci`, percentile); where some draw lacks the metric, over
    groups and trials, each trial's value the mean over its draws that have it.

    Returns
    -------
    pandas.DataFrame
        Columns metric, profile, method, kind, mean, ci_low, ci_high, n_trials (units of the
        metric: ° or s).
    """
    kinds = per_trial.drop_duplicates("method").set_index("method")["kind"]
    rows = []
    for metric in metrics:
        for profile in dict.fromkeys(per_trial["profile"]):
            table = trial_table(per_trial, profile, metric).dropna(axis=0, how="all").dropna(axis=1)
            if table.shape[0] < 2 or table.shape[1] == 0:
                continue
            labels = _group_labels(groups, table.index)
            if labels is None:
                ci = stats.bootstrap_ci(table.to_numpy(), rng=rng, n_boot=n_boot)
            else:
                names, values = draw_values(per_trial, profile, metric, trials=table.index)
                values = values[..., [names.index(m) for m in table.columns]]
                if not np.isfinite(values).all():  # a draw without the metric (no gap in it, no reference):
                    values = table.to_numpy()[:, None, :]  # each trial's mean over the draws that have it
                ci = stats.grouped_bootstrap_ci(values, labels, rng=rng, n_boot=n_boot)
            for k, method in enumerate(table.columns):
                rows.append({"metric": metric, "profile": profile, "method": method, "kind": kinds[method],
                             "mean": float(ci.estimate[k]), "ci_low": float(ci.low[k]), "ci_high": float(ci.high[k]),
                             "n_trials": table.shape[0]})
    return pd.DataFrame(rows)


def ranking(per_trial: pd.DataFrame, *, rng: np.random.Generator, profile: str = HEADLINE,
            metric: str = "rmse_total", n_boot: int = 2000, groups=None) -> pd.DataFrame:
    """Methods ranked by mean ``metric`` at ``profile``; a tie where the paired difference's interval holds 0
    (over trials, or with ``groups`` over groups and loss draws)."""
    labels = _group_labels(groups, sorted(set(per_trial.loc[per_trial["profile"] == profile, "trial"])))
    if labels is None:
        return stats.rank_with_ties(trial_table(per_trial, profile, metric), rng=rng, n_boot=n_boot)
    names, values = draw_values(per_trial, profile, metric)
    return stats.rank_with_ties({m: values[..., k] for k, m in enumerate(names)}, rng=rng, n_boot=n_boot,
                                groups=labels)


def best_methods(per_trial: pd.DataFrame, profile: str = HEADLINE, *, exclude=()) -> dict[str, str | None]:
    """Best (lowest mean total RMSE at ``profile``) method of each pool.

    ``exclude``: methods that may not be "ours" in a pool, e.g. those designed on the scored trials
    (:data:`~wsnlib.studies.loss_tolerance.DESIGNED_ON_BROAD` on BROAD: their ``", design in
    fold"`` entries stand for them).

    Returns
    -------
    dict
        ``"causal"`` (causal without latency), ``"peer"`` (any peer), ``"offline"``; ``"peer, same
        gap (causal)"`` and ``"peer, same gap (offline)"``: the best peer with the gap handling of
        the best causal, resp. offline, method (:data:`~wsnlib.studies.loss_tolerance.
        GAP_HANDLING_OF`; None when that method has none there or no such peer ran);
        ``"peer, as users run them"`` (:data:`~wsnlib.studies.loss_tolerance.AS_USERS_RUN_THEM`;
        None when none ran); ``"lossless reference"``: :data:`LOSSLESS_REFERENCE` (None when it
        did not run).
    """
    rows = per_trial[per_trial["profile"] == profile]
    means = rows.groupby("method")["rmse_total"].mean()
    info = rows.drop_duplicates("method").set_index("method")
    info = info[~info.index.isin(list(exclude))]
    pools = {"causal": info.index[(info["kind"] == "causal") & (info["latency_rule"] == "none")],
             "peer": info.index[info["kind"] == "peer"], "offline": info.index[info["kind"] == "offline"]}
    missing = [kind for kind, pool in pools.items() if len(pool) == 0]
    if missing:
        raise ValueError(f"per_trial has no method of kind {missing} at profile {profile!r}")
    best = {kind: str(means[pool].idxmin()) for kind, pool in pools.items()}

    def best_of(pool):
        return str(means[list(pool)].idxmin()) if len(pool) else None

    for kind in ("causal", "offline"):
        gap = GAP_HANDLING_OF.get(best[kind])
        best[f"peer, same gap ({kind})"] = best_of([m for m in pools["peer"] if gap and GAP_HANDLING_OF.get(m) == gap])
    best["peer, as users run them"] = best_of([m for m in pools["peer"] if m in AS_USERS_RUN_THEM])
    best["lossless reference"] = LOSSLESS_REFERENCE if LOSSLESS_REFERENCE in info.index else None
    return best


def targets_table(per_trial: pd.DataFrame, *, rng: np.random.Generator, n_boot: int = 2000,
                  groups=None, exclude=()) -> pd.DataFrame:
    """The issue's targets (:data:`TARGETS`): measured value with a 95 % paired bootstrap interval, PASS/MISS, margin.

    With ``groups`` (mapping trial → group) the intervals are over groups and loss draws.  A
    target whose peer did not run (e.g. no peer with the same gap handling) has no row.
    ``exclude``: methods left out of the pools (:func:`best_methods`).

    Returns
    -------
    pandas.DataFrame
        Index target; columns compares (which methods), measured, ci_low, ci_high, target,
        verdict (PASS when ``measured <= target``), margin (``measured − target``; negative =
        met with room), ci_meets (the whole interval meets the target).
    """
    best = best_methods(per_trial, exclude=exclude)
    if best["lossless reference"] is None:
        raise ValueError(f"per_trial lacks the lossless reference method {LOSSLESS_REFERENCE!r}")
    trials = sorted(set(per_trial.loc[per_trial["profile"] == HEADLINE, "trial"]))
    labels = _group_labels(groups, trials)
    rows = {}
    for name, (comparison, target, ours, peer) in TARGETS.items():
        if best[peer] is None:
            continue
        a_name, b_name = best[ours], best[peer]
        profile = "lossless" if comparison == "difference" else HEADLINE
        sign = " − " if comparison == "difference" else " / "
        if labels is not None:
            names, values = draw_values(per_trial, profile, "rmse_total", trials=trials)
            va, vb = (values[..., names.index(m)] for m in (a_name, b_name))
            ci = (stats.grouped_ratio_ci(va, vb, labels, rng=rng, n_boot=n_boot) if comparison == "ratio" else
                  stats.grouped_bootstrap_ci(va - vb, labels, rng=rng, n_boot=n_boot))
        else:
            table = trial_table(per_trial, profile, "rmse_total").loc[trials]
            a, b = table[a_name].to_numpy(), table[b_name].to_numpy()
            ci = (stats.ratio_of_means_ci(a, b, rng=rng, n_boot=n_boot) if comparison == "ratio" else
                  stats.paired_difference_ci(a, b, rng=rng, n_boot=n_boot))
        measured = float(ci.estimate)
        rows[name] = {"compares": f"{a_name}{sign}{b_name}", "measured": measured, "ci_low": float(ci.low),
                      "ci_high": float(ci.high), "target": target,
                      "verdict": "PASS" if measured <= target else "MISS", "margin": measured - target,
                      "ci_meets": bool(ci.high <= target)}
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("target")


def target_sentences(targets: pd.DataFrame) -> list[str]:
    """One sentence per target, e.g. "… 0.55 [0.53, 0.56] against ≤ 0.50: MISS, by 0.05 (10 % of the target)."."""
    out = []
    for name, row in targets.iterrows():
        value = f"{row['measured']:.2f} [{row['ci_low']:.2f}, {row['ci_high']:.2f}]"
        head = f"**{name}** ({row['compares']}): {value} against ≤ {row['target']:.2f}"
        if row["verdict"] == "PASS":
            sure = "the whole interval meets it" if row["ci_meets"] else "but the interval reaches above it"
            out.append(f"{head}: PASS with {-row['margin']:.2f} to spare ({sure}).")
        else:
            out.append(f"{head}: MISS, by {row['margin']:.2f} ({100 * row['margin'] / row['target']:.0f} % of the "
                       f"target).")
    return out


def error_budget(per_trial: pd.DataFrame, method: str, profile: str = HEADLINE) -> pd.Series:
    """Share of the squared total error (movement samples, all trials pooled) per phase, and the phases' RMS.

    Returns
    -------
    pandas.Series
        ``share_<phase>`` (fraction of Σ error², sums to 1), ``rms_<phase>`` (° pooled over
        trials) and ``samples_<phase>`` (fraction of samples) for the phases lost, after_gap,
        steady.
    """
    rows = per_trial[(per_trial["profile"] == profile) & (per_trial["method"] == method)]
    if rows.empty:
        raise ValueError(f"no rows for method {method!r} at profile {profile!r}")
    phases = ("lost", "after_gap", "steady")
    counts = {ph: rows[f"n_{ph}"].to_numpy(float) for ph in phases}
    squares = {ph: np.nansum(counts[ph] * rows[f"rms_{ph}"].to_numpy(float) ** 2) for ph in phases}
    total_sq, total_n = sum(squares.values()), sum(c.sum() for c in counts.values())
    out = {}
    for ph in phases:
        n = counts[ph].sum()
        out[f"share_{ph}"] = squares[ph] / total_sq
        out[f"rms_{ph}"] = float(np.sqrt(squares[ph] / n)) if n else float("nan")
        out[f"samples_{ph}"] = n / total_n
    return pd.Series(out, name=method)


def diagnosis_sentence(per_trial: pd.DataFrame, method: str, profile: str = HEADLINE) -> str:
    """Where ``method``'s error is at ``profile``: a sentence from :func:`error_budget`."""
    b = error_budget(per_trial, method, profile)
    return (f"Where the error of {method} is ({profile}, all trials pooled): lost samples are "
            f"{100 * b['samples_lost']:.0f} % of the samples and hold {100 * b['share_lost']:.0f} % of the squared "
            f"error (RMS {b['rms_lost']:.1f}°); the {AFTER_GAP_S:g} s after each gap "
            f"{100 * b['samples_after_gap']:.0f} % and "
            f"{100 * b['share_after_gap']:.0f} % (RMS {b['rms_after_gap']:.1f}°); the rest "
            f"{100 * b['samples_steady']:.0f} % and {100 * b['share_steady']:.0f} % (RMS {b['rms_steady']:.1f}°).")


def format_targets(targets: pd.DataFrame) -> str:
    """Plain-text lines for the CLI: one per target with PASS/MISS and margin."""
    return "\n".join(f"  {name:44s} {row['measured']:7.3f}  [{row['ci_low']:7.3f}, {row['ci_high']:7.3f}]  "
                     f"target <= {row['target']:.2f}: {row['verdict']}  (margin {row['margin']:+.3f})  "
                     f"[{row['compares']}]" for name, row in targets.iterrows())


#: Columns of :func:`paired_comparisons`.
COMPARISON_COLUMNS = ("question", "without", "with", "metric", "profile", "mean_without", "mean_with", "difference",
                      "ci_low", "ci_high", "verdict", "n_better", "n_trials")


def paired_comparisons(per_trial: pd.DataFrame, pairs, *, rng: np.random.Generator, question: str = "",
                       profile: str = HEADLINE, metrics=("rmse_total",), n_boot: int = 2000) -> pd.DataFrame:
    """Does an option help? Paired difference (with − without) over trials, 95 % bootstrap interval.

    Parameters
    ----------
    per_trial : pandas.DataFrame
        From :func:`wsnlib.studies.loss_tolerance.evaluate`.
    pairs : sequence of (str, str)
        ``(without, with)`` method names, e.g.
        :data:`wsnlib.studies.loss_tolerance.GATING_PAIRS`.
    rng : numpy.random.Generator
    question : str
        Label copied to every row (e.g. ``"gating"``).
    profile : str
    metrics : sequence of str
        Columns of ``per_trial`` (lower is better).  Trials where either method's value is
        undefined (NaN) are left out of that comparison (``n_trials`` says how many remain).
    n_boot : int

    Returns
    -------
    pandas.DataFrame
        Columns :data:`COMPARISON_COLUMNS`: the means of both (unit of the metric), the mean
        paired difference ``with − without`` and its interval (:func:`wsnlib.stats.
        paired_difference_ci`), verdict ``"helps"`` (interval below 0), ``"hurts"`` (above 0)
        or ``"tie"`` (holds 0), and on how many trials ``with`` was lower.
    """
    rows = []
    for without, with_ in pairs:
        for metric in metrics:
            table = trial_table(per_trial, profile, metric)
            missing = [m for m in (without, with_) if m not in table]
            if missing:
                raise ValueError(f"pairs name methods not in per_trial at {profile!r}: {missing}")
            both = table[[without, with_]].dropna()
            if len(both) < 2:
                raise ValueError(f"{metric} of {without!r} and {with_!r} at {profile!r} is defined on fewer than "
                                 f"2 trials ({len(both)})")
            a, b = both[with_].to_numpy(), both[without].to_numpy()
            ci = stats.paired_difference_ci(a, b, rng=rng, n_boot=n_boot)
            verdict = "helps" if ci.high < 0 else "hurts" if ci.low > 0 else "tie"
            rows.append({"question": question, "without": without, "with": with_, "metric": metric,
                         "profile": profile, "mean_without": float(b.mean()), "mean_with": float(a.mean()),
                         "difference": float(ci.estimate), "ci_low": float(ci.low), "ci_high": float(ci.high),
                         "verdict": verdict, "n_better": int(np.sum(a < b)), "n_trials": len(both)})
    return pd.DataFrame(rows, columns=list(COMPARISON_COLUMNS))


#: How :func:`comparison_sentences` names the metrics.
METRIC_WORDS = {"rmse_total": "mean total RMSE", "rms_lost": "mean RMS error on lost samples",
                "rms_after_gap": f"mean RMS error in the {AFTER_GAP_S:g} s after a gap",
                "rms_steady": "mean RMS error on the other samples",
                "mean_increase_deg": "mean error a gap adds (over the window after it)",
                "peak_increase_deg": "peak error a gap adds",
                "burst_peak_increase_deg": "peak error one burst adds (over the error just before it)"}


def comparison_sentences(comparisons: pd.DataFrame, unit: str = "°") -> list[str]:
    """One sentence per row of :func:`paired_comparisons`, its verdict taken from the interval.

    E.g. "gated hybrid (feedback) against hybrid (feedback), mean total RMSE at GE 10 %: 50.7°
    vs 36.9°, difference +13.8° [+8.0, +20.1]: **worse** (the interval excludes 0), lower on 2 of
    17 trials."
    """
    words = {"helps": "**better** (the interval lies below 0)", "hurts": "**worse** (the interval lies above 0)",
             "tie": "**a tie** (the interval holds 0)"}
    out = []
    for _, row in comparisons.iterrows():
        what = METRIC_WORDS.get(row["metric"], row["metric"])
        out.append(f"{row['with']} against {row['without']}, {what} at {row['profile']}: "
                   f"{row['mean_with']:.1f}{unit} vs {row['mean_without']:.1f}{unit}, difference "
                   f"{row['difference']:+.1f}{unit} [{row['ci_low']:+.1f}, {row['ci_high']:+.1f}]: "
                   f"{words[row['verdict']]}, lower on {row['n_better']} of {row['n_trials']} trials.")
    return out



def lost_share_band(profile, n_samples: int, n_std: float = 4.0) -> tuple[float, float]:
    """Where the mean lost share of a Gilbert–Elliott ``profile`` over ``n_samples`` samples (all
    trials and draws together) falls but for a ``n_std``-standard-deviation fluke: ``(low, high)``.

    A two-state chain with stationary loss rate ``p`` and mean burst ``b`` packets loses a share
    of ``n`` packets whose variance is ``p (1 − p) (2 b (1 − p) − 1) / n`` (its lag correlation
    sums to that factor); ``n = n_samples / samples_per_packet``.  A sanity check of the masks,
    not a test of the channel model.
    """
    if profile.model != "gilbert_elliott":
        raise ValueError(f"profile must be a Gilbert-Elliott profile, got model {profile.model!r}")
    p, b = profile.loss_rate, profile.mean_burst_packets
    n_packets = n_samples / profile.samples_per_packet
    spread = n_std * float(np.sqrt(p * (1 - p) * max(2 * b * (1 - p) - 1, 1.0) / n_packets))
    return p - spread, p + spread


def optimism_table(tuning: pd.DataFrame, choices: pd.DataFrame) -> pd.DataFrame:
    """What choosing on the trials that are scored would have claimed: held-out vs in-sample tuning.

    Per method with a choice to make (rows of ``tuning``): the mean headline RMSE over trials
    when each trial is scored with the setting chosen without its group (``choices``, the
    outer folds: the honest number), and when every trial is scored with the one setting best
    on *all* trials (the design on all trials, :func:`wsnlib.loto.in_sample_choice`).  Their
    difference is the optimism of tuning on the scored trials.

    Parameters
    ----------
    tuning, choices : pandas.DataFrame
        :attr:`~wsnlib.studies.loss_tolerance.LossToleranceResult.tuning` and ``.choices``.

    Returns
    -------
    pandas.DataFrame
        Index method; columns held_out (°), in_sample (°), optimism (°, held_out − in_sample),
        in_sample_setting, n_settings.
    """
    rows = {}
    for method, scores in tuning.groupby("method", sort=False):
        table = scores.pivot(index="setting_index", columns="trial", values="rmse_total")
        chosen = choices[choices["method"] == method].set_index("trial")["setting_index"]
        held_out = float(np.mean([table.loc[chosen[t], t] for t in table.columns]))
        best = int(loto.in_sample_choice(table.to_numpy()))
        in_sample = float(table.iloc[best].mean())
        setting = scores.loc[scores["setting_index"] == table.index[best], "setting"].iloc[0]
        rows[method] = {"held_out": held_out, "in_sample": in_sample, "optimism": held_out - in_sample,
                        "in_sample_setting": setting, "n_settings": table.shape[0]}
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("method")


def edge_picks(methods, choices: pd.DataFrame) -> pd.DataFrame:
    """Chosen values at the edge of their grid: at a bound of the search space, or a grid too narrow.

    For every method and numeric setting taking at least three values in its grid: on how many trials the
    chosen value is the grid's lowest or highest, and whether that edge is a bound of the
    method's search space (:attr:`~wsnlib.studies.loss_tolerance.Method.space`, written beside
    each grid: not to be chased past) or lies inside it (then the grid is too narrow: widen it).

    Returns
    -------
    pandas.DataFrame
        Columns method, setting, edge ("low" or "high"), value, n_trials (chosen there),
        n_total, verdict ("at a bound of the space", "grid too narrow" or "no space declared").
    """
    rows = []
    for name, method in methods.items():
        chosen = choices[choices["method"] == name]["setting_index"].to_numpy()
        for key in dict.fromkeys(k for setting in method.grid for k in setting):
            values = [setting.get(key) for setting in method.grid]
            if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values) or len(set(values)) < 3:
                continue  # with two values every pick is an edge: nothing to learn from it
            picked = np.array([values[i] for i in chosen if i >= 0])
            for edge, value in (("low", min(values)), ("high", max(values))):
                n = int(np.sum(picked == value))
                if n == 0:
                    continue
                space = method.space.get(key)
                if space is None or not hasattr(space, "low"):
                    verdict = "no space declared"
                else:
                    bound = space.low if edge == "low" else space.high
                    verdict = "at a bound of the space" if np.isclose(value, bound, rtol=0.02) else "grid too narrow"
                rows.append({"method": name, "setting": key, "edge": edge, "value": value, "n_trials": n,
                             "n_total": len(chosen), "verdict": verdict})
    return pd.DataFrame(rows, columns=["method", "setting", "edge", "value", "n_trials", "n_total", "verdict"])


def design_choices(methods, choices: pd.DataFrame) -> pd.DataFrame:
    """Which design each fold chose, for every method with designs chosen in the fold
    (:attr:`~wsnlib.studies.loss_tolerance.Method.designs`; its grid varies the design slowest).

    Returns
    -------
    pandas.DataFrame
        Columns method, design (``"defaults"`` for the empty design, else its settings, e.g.
        ``"gyro_noise=0.01"``), n_trials (trials scored with it), trials (their names).
    """
    rows = []
    for name, method in methods.items():
        if not method.designs:
            continue
        per_design = len(method.grid) // len(method.designs)
        chosen = choices[choices["method"] == name].set_index("trial")["setting_index"]
        picked = {trial: int(index) // per_design for trial, index in chosen.items() if index >= 0}
        for d, design in enumerate(method.designs):
            trials = [trial for trial, index in picked.items() if index == d]
            if trials:
                label = ", ".join(f"{key}={value:g}" for key, value in design.items()) or "defaults"
                rows.append({"method": name, "design": label, "n_trials": len(trials), "trials": ", ".join(trials)})
    return pd.DataFrame(rows, columns=["method", "design", "n_trials", "trials"])


#: Columns of :func:`ablation_table`.
ABLATION_COLUMNS = ("filter", "gap_handling", "method", "mean", "ci_low", "ci_high", "n_trials")


def ablation_table(means: pd.DataFrame, ablation=ABLATION, *, profile: str = HEADLINE,
                   metric: str = "rmse_total") -> pd.DataFrame:
    """Filter × gap handling: each cell's mean with its 95 % interval, from :func:`summary_table`.

    Parameters
    ----------
    means : pandas.DataFrame
        :func:`summary_table` (columns metric, profile, method, mean, ci_low, ci_high, n_trials).
    ablation : mapping filter → mapping gap handling → method
        Default :data:`~wsnlib.studies.loss_tolerance.ABLATION`.
    profile, metric : str

    Returns
    -------
    pandas.DataFrame
        Columns :data:`ABLATION_COLUMNS`, one row per cell whose method has a row in ``means``
        (filters in ``ablation``'s order, gap handlings in :data:`~wsnlib.studies.
        loss_tolerance.GAP_HANDLINGS`' order).  ``ValueError`` when no cell has one.
    """
    rows = means[(means["metric"] == metric) & (means["profile"] == profile)].set_index("method")
    out = []
    for filter_name, cells in ablation.items():
        unknown = sorted(set(cells) - set(GAP_HANDLINGS))
        if unknown:
            raise ValueError(f"ablation[{filter_name!r}] names unknown gap handlings {unknown}; known: {GAP_HANDLINGS}")
        for gap in GAP_HANDLINGS:
            method = cells.get(gap)
            if method is None or method not in rows.index:
                continue
            row = rows.loc[method]
            out.append({"filter": filter_name, "gap_handling": gap, "method": method, "mean": float(row["mean"]),
                        "ci_low": float(row["ci_low"]), "ci_high": float(row["ci_high"]),
                        "n_trials": int(row["n_trials"])})
    if not out:
        raise ValueError(f"means has no {metric} row at {profile!r} of any method of the ablation")
    return pd.DataFrame(out, columns=list(ABLATION_COLUMNS))


#: Columns of :func:`ratio_table`.
RATIO_COLUMNS = ("question", "method", "against", "mean", "mean_against", "ratio", "ci_low", "ci_high", "verdict")


def ratio_table(per_trial: pd.DataFrame, pairs, *, rng: np.random.Generator, question: str = "", n_boot: int = 2000,
                groups=None, profile: str = HEADLINE, metric: str = "rmse_total") -> pd.DataFrame:
    """Ratio of means ``method / against`` at ``profile`` for each pair, with a 95 % paired interval.

    Over groups and loss draws with ``groups`` (:func:`wsnlib.stats.grouped_ratio_ci`), else over
    trials (:func:`wsnlib.stats.ratio_of_means_ci`).  Verdict ``"lower"`` (the interval lies
    below 1), ``"higher"`` (above 1) or ``"tie"``.

    Parameters
    ----------
    pairs : sequence of (str, str)
        ``(method, against)`` names in ``per_trial``.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`RATIO_COLUMNS` (means in the metric's unit).
    """
    trials = sorted(set(per_trial.loc[per_trial["profile"] == profile, "trial"]))
    labels = _group_labels(groups, trials)
    names, values = draw_values(per_trial, profile, metric, trials=trials)
    rows = []
    for method, against in pairs:
        missing = [m for m in (method, against) if m not in names]
        if missing:
            raise ValueError(f"pairs name methods not in per_trial at {profile!r}: {missing}")
        a, b = values[..., names.index(method)], values[..., names.index(against)]
        if labels is not None:
            ci = stats.grouped_ratio_ci(a, b, labels, rng=rng, n_boot=n_boot)
        else:
            ci = stats.ratio_of_means_ci(a.mean(axis=1), b.mean(axis=1), rng=rng, n_boot=n_boot)
        verdict = "lower" if ci.high < 1 else "higher" if ci.low > 1 else "tie"
        rows.append({"question": question, "method": method, "against": against, "mean": float(a.mean()),
                     "mean_against": float(b.mean()), "ratio": float(ci.estimate), "ci_low": float(ci.low),
                     "ci_high": float(ci.high), "verdict": verdict})
    return pd.DataFrame(rows, columns=list(RATIO_COLUMNS))


def ablation_pairs(ablation_rows: pd.DataFrame, ours: str = "Kalman") -> dict[str, list[tuple[str, str]]]:
    """The two questions of the ablation as pairs for :func:`ratio_table`.

    ``"filter"``: in each gap handling where ``ours`` (a filter of the ablation) and a peer ran,
    ours against the best peer there (lowest mean, peers = the filters other than ``ours`` and
    Madgwick's); ``"gap handling"``: in each filter, every other gap handling against holding.
    ``ablation_rows``: :func:`ablation_table`.
    """
    cells = ablation_rows.set_index(["filter", "gap_handling"])
    peers = [f for f in dict.fromkeys(ablation_rows["filter"]) if f not in (ours, "Madgwick")]
    filters, gaps = [], []
    for gap in GAP_HANDLINGS:
        if (ours, gap) not in cells.index:
            continue
        there = [cells.loc[(p, gap)] for p in peers if (p, gap) in cells.index]
        if there:
            best = min(there, key=lambda row: row["mean"])
            filters.append((cells.loc[(ours, gap), "method"], best["method"]))
    for filter_name in dict.fromkeys(ablation_rows["filter"]):
        if (filter_name, "hold") not in cells.index:
            continue
        hold = cells.loc[(filter_name, "hold"), "method"]
        gaps += [(cells.loc[(filter_name, gap), "method"], hold) for gap in GAP_HANDLINGS[1:]
                 if (filter_name, gap) in cells.index]
    return {"filter": filters, "gap handling": gaps}


def inclination_table(per_trial: pd.DataFrame, neural: pd.DataFrame, *, rng: np.random.Generator, n_boot: int = 2000,
                      groups=None) -> pd.DataFrame:
    """Inclination RMSE of a second study's methods (e.g. RIANN, :func:`~wsnlib.studies.loss_tolerance.
    inclination_methods`, run on the same masks) beside the study's, at the profiles the second study ran.

    Returns
    -------
    pandas.DataFrame
        :func:`summary_table` of ``rmse_inclination`` over both studies' rows at those profiles.
    """
    profiles = list(dict.fromkeys(neural["profile"]))
    shared = sorted(set(per_trial["method"]) & set(neural["method"]))
    if shared:
        raise ValueError(f"the two studies share method names {shared}: their rows would mix")
    rows = pd.concat([per_trial[per_trial["profile"].isin(profiles)], neural], ignore_index=True)
    return summary_table(rows, rng=rng, n_boot=n_boot, groups=groups, metrics=("rmse_inclination",))
