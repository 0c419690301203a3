"""Tables, selections and sentences of notebook 10 (the loss-tolerance study, issue 11).

What the notebook shows beyond :mod:`wsnlib.studies.loss_tolerance` (running) and
:mod:`wsnlib.studies.loss_tolerance.summary` (intervals, rankings, targets): the paper's
weight μ(λ) beside the Kalman filter's 1 − K, the tables of methods and loss profiles, which
trials the burst figure shows, the per-phase table, the search spaces, the ablation grid, the
paper-vs-ours table and the sentences built from them.  Angles in degrees, times in seconds, rates in °/s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from wsnlib import paper_values
from wsnlib.orientation import KalmanSettings, slerp_weight
from wsnlib.studies.loss_tolerance.evaluation import AFTER_GAP_S
from wsnlib.studies.loss_tolerance.registry import GAP_HANDLINGS, HEADLINE, LATENCY_RULES, PROFILES
from wsnlib.studies.loss_tolerance.summary import comparison_sentences, diagnosis_sentence, error_budget

#: Column of :func:`weight_vs_gap` holding the Kalman filter's 1 − K.
KALMAN_WEIGHT_COLUMN = "Kalman: 1 − K (heading)"


def weight_vs_gap(lost_samples, *, fs: float = 50.0, settings: KalmanSettings | None = None,
                  prior_std_deg: float = 1.0, rho: float = 1.0, tau: float = 6.0) -> pd.DataFrame:
    """The paper's eq. (3) weight μ(λ) beside the Kalman filter's 1 − K for the heading after a gap.

    The filter predicts through λ lost samples with a rate error of std ``settings.gap_rate_noise``
    (rad/s), so its heading variance grows from ``prior_std_deg``² to
    ``prior + (gap_rate_noise · λ / fs)²`` (rad²); the first magnetometer update after the gap has
    the gain ``K = P / (P + mag_noise_density² · fs)`` (one sample's variance).

    Parameters
    ----------
    lost_samples : array_like of int
        λ, samples lost in a row, >= 0.
    fs : float
        Sample rate (Hz); default paper 001's 50 Hz (an illustration: give the recordings' rate).
    settings : KalmanSettings, optional
        The filter's noise levels (``gap_rate_noise`` rad/s, ``mag_noise_density`` rad·√s); default
        :class:`~wsnlib.orientation.KalmanSettings` ().
    prior_std_deg : float
        Heading std before the gap (°).
    rho, tau : float
        ρ and τ of the paper's eq. (3).

    Returns
    -------
    pandas.DataFrame
        Index ``λ (samples)``; columns ``gap (s)``, the paper's μ(λ) (named with ρ and τ) and
        :data:`KALMAN_WEIGHT_COLUMN`.
    """
    lost = np.asarray(lost_samples)
    if lost.ndim != 1 or not np.issubdtype(lost.dtype, np.number) or np.any(~np.isfinite(lost)) or np.any(lost < 0):
        raise ValueError(f"lost_samples must be a 1-d array of finite counts >= 0, got {lost_samples!r}")
    if not fs > 0:
        raise ValueError(f"fs must be > 0 Hz, got {fs!r}")
    if not prior_std_deg >= 0:
        raise ValueError(f"prior_std_deg must be >= 0, got {prior_std_deg!r}")
    settings = KalmanSettings() if settings is None else settings
    grown = np.radians(prior_std_deg) ** 2 + (settings.gap_rate_noise * lost / fs) ** 2
    gain = grown / (grown + settings.mag_noise_density ** 2 * fs)
    return pd.DataFrame({"λ (samples)": lost, "gap (s)": lost / fs,
                         f"paper: μ(λ), ρ = {rho:g}, τ = {tau:g}": slerp_weight(lost, rho, tau),
                         KALMAN_WEIGHT_COLUMN: 1.0 - gain}).set_index("λ (samples)")


def _levels(method) -> dict[str, list]:
    """Each setting's values in ``method``'s grid, in the order they first appear (of a method with
    designs chosen in the fold, its search space's settings only)."""
    keys = dict.fromkeys(k for setting in method.grid for k in setting)
    return {key: list(dict.fromkeys(setting[key] for setting in method.grid if key in setting))
            for key in keys if not method.designs or key in method.space}


def _designs(method) -> str:
    """``"; × 12 designs chosen in the fold"`` for a method with designs (:attr:`~wsnlib.studies.
    loss_tolerance.Method.designs`), else ``""``."""
    return f"; × {len(method.designs)} designs chosen in the fold" if method.designs else ""


def _listed(values, keep: int = 3) -> str:
    """``"1, 2, 3, …, 12"``: the first ``keep`` values and the last (all when few)."""
    text = [f"{v:g}" if isinstance(v, float) else str(v) for v in values]
    return ", ".join(text) if len(text) <= keep + 1 else ", ".join(text[:keep]) + ", …, " + text[-1]


def method_table(methods: Mapping) -> pd.DataFrame:
    """One row per method: kind, number of settings, what is tuned (the grid's values per setting,
    log-spaced between the bounds of :func:`space_table`), latency rule."""
    return pd.DataFrame([{"method": m.name, "kind": m.kind, "settings": len(m.grid),
                          "grid": "; ".join(f"{key}: {_listed(values)}" for key, values in _levels(m).items())
                          + _designs(m),
                          "latency": LATENCY_RULES[m.latency]} for m in methods.values()]).set_index("method")


def space_table(methods: Mapping) -> pd.DataFrame:
    """The search spaces, one row per setting and range: its physical bounds, why, the values tried.

    Generated from the registry (:attr:`~wsnlib.studies.loss_tolerance.Method.space` of each
    method), so the table is the grid the code runs.

    Returns
    -------
    pandas.DataFrame
        Index (setting, bounds); columns unit, why (the bounds' reasons), values tried (of the
        first method using it; a setting's number of values depends on how many settings share
        the method's budget), methods (those tuning it).
    """
    rows = {}
    for method in methods.values():
        levels = _levels(method)
        for key, axis in method.space.items():
            bounds = (f"{axis.low:g} – {axis.high:g}" if hasattr(axis, "low")
                      else "one of " + ", ".join(str(v) for v in axis.values))
            row = rows.setdefault((key, bounds), {"unit": getattr(axis, "unit", ""), "why": axis.why,
                                                  "values tried": {},
                                                  "methods": []})
            row["values tried"].setdefault(len(levels.get(key, [])), _listed(levels.get(key, []), keep=4))
            row["methods"].append(method.name)
    table = pd.DataFrame([{"setting": key, "bounds": bounds, "unit": row["unit"],
                           "values tried": " or ".join(f"{n}: {text}" for n, text in row["values tried"].items()),
                           "methods": ", ".join(row["methods"]), "why these bounds": row["why"]}
                          for (key, bounds), row in rows.items()])
    return table.set_index(["setting", "bounds"])


def budget_sentence(methods: Mapping) -> str:
    """How many settings each tuned method gets, and how they split over its settings, from the grids."""
    tuned = {name: m for name, m in methods.items() if m.space}
    fixed = [name for name, m in methods.items() if not m.space]
    sizes = sorted({len(m.grid) // max(1, len(m.designs)) for m in tuned.values()})
    if not tuned:
        return "No method has a search space: every method runs its one setting."
    splits = {}
    for name, method in tuned.items():
        split = " × ".join(f"{len(values)} {key}" for key, values in _levels(method).items())
        splits.setdefault(split, []).append(name)
    size = f"{sizes[0]}" if len(sizes) == 1 else f"{sizes[0]}–{sizes[-1]}"
    text = (f"Every method with something to tune gets the same budget, **{size} settings**, log-spaced from one "
            f"physical bound of each setting to the other (both bounds included): "
            + "; ".join(f"{split} for {', '.join(f'`{n}`' for n in names)}" for split, names in splits.items()) + ".")
    designed = {name: m for name, m in tuned.items() if m.designs}
    if designed:
        text += (" " + " and ".join(f"`{n}`" for n in designed) + " cross theirs with "
                 + " and ".join(sorted({str(len(m.designs)) for m in designed.values()}))
                 + " designs (the defaults, and each alternative a default was picked against, one at a time), "
                 "chosen in the fold: "
                 + " and ".join(sorted({str(len(m.grid)) for m in designed.values()}))
                 + " settings, more than the others' budget — the price of not choosing the design on the scored "
                 "trials.")
    if fixed:
        text += f" Nothing to tune (their authors' settings): {', '.join(f'`{n}`' for n in fixed)}."
    return text


def profile_table(profiles=PROFILES) -> pd.DataFrame:
    """One row per loss profile: model, loss rate, mean burst (packets; NaN unless Gilbert–Elliott), packet size."""
    return pd.DataFrame([{"profile": p.name, "model": p.model, "loss rate": p.loss_rate,
                          "mean burst (packets)": p.mean_burst_packets if p.model == "gilbert_elliott" else np.nan,
                          "samples per packet": p.samples_per_packet}
                         for p in profiles]).set_index("profile")


#: Panels of the error-vs-loss-rate figure: title → methods (those not run are left out).
LOSS_RATE_FIGURE_GROUPS = {"Madgwick: bridging a gap": ("hold_last", "constant_rate", "gyro_interpolation"),
                           "ours: hybrid, Kalman, smoother": ("hybrid (feedback)", "Kalman", "smoother"),
                           "peers": ("VQF (defaults)", "Fusion, AR + replay", "VQF, AR + replay")}


def error_vs_loss_rate_inputs(profiles, means: pd.DataFrame, methods, groups=LOSS_RATE_FIGURE_GROUPS):
    """What :func:`wsnlib.plotting.plot_error_vs_loss_rate` needs from the study's results.

    Parameters
    ----------
    profiles : sequence of LossProfile
        The lossless profile and the Gilbert–Elliott ones with 6-sample packets are kept.
    means : pandas.DataFrame
        Rows of :func:`~wsnlib.studies.loss_tolerance.summary.summary_table` for one metric.
    methods : iterable of str
        The methods run.
    groups : mapping title → methods

    Returns
    -------
    rates : dict profile → loss rate (0 for lossless)
    bands : pandas.DataFrame indexed by (profile, method)
    groups : dict title → list of the methods run
    """
    rates = {p.name: (p.loss_rate if p.model != "none" else 0.0) for p in profiles
             if p.model == "none" or (p.model == "gilbert_elliott" and p.samples_per_packet == 6)}
    run = set(methods)
    return rates, means.set_index(["profile", "method"]), {t: [m for m in shown if m in run]
                                                           for t, shown in groups.items()}


def median_rate_deg_s(recordings: Mapping) -> pd.Series:
    """Median angular-rate norm (°/s) over each recording's movement samples, indexed by trial."""
    return pd.Series({name: float(np.degrees(np.median(np.linalg.norm(rec.gyr[rec.movement], axis=-1))))
                      for name, rec in recordings.items()})


def slow_and_fast_trials(median_rate: pd.Series) -> dict[str, str]:
    """``{"slowest": trial, "fastest": trial}`` by median rate, among the undisturbed trials when
    there are at least two of them (trial name containing ``"undisturbed"``), else among all."""
    if len(median_rate) == 0:
        raise ValueError("median_rate is empty")
    undisturbed = median_rate[[name for name in median_rate.index if "undisturbed" in name]]
    candidates = undisturbed if len(undisturbed) >= 2 else median_rate
    return {"slowest": candidates.idxmin(), "fastest": candidates.idxmax()}


def burst_figure_methods(best: Mapping[str, str]) -> list[str]:
    """Methods in the burst figure: holding, our hybrid, the best peer, our Kalman filter and smoother."""
    return list(dict.fromkeys(["hold_last", "hybrid (feedback)", best["peer"], "Kalman", "smoother"]))


def worst_burst_end(trace: Mapping, method: str, *, window_s: float = AFTER_GAP_S) -> int:
    """Sample index ending the burst after which ``method``'s error grows most over its lossless run.

    Parameters
    ----------
    trace : mapping
        One trial of :attr:`LossToleranceResult.traces` (its ``fs``, Hz, the trial's rate).
    method : str
    window_s : float
        The increase is the largest one within this long after the burst (s); NaN counts as 0.
    """
    ends = np.asarray(trace["burst_ends"])
    if ends.size == 0:
        raise ValueError("trace has no burst end")
    window = int(round(window_s * trace["fs"]))
    added = [np.max(np.nan_to_num(trace["error"][method][e:e + window] - trace["lossless"][method][e:e + window],
                                  nan=0.0)) for e in ends]
    return int(ends[int(np.argmax(added))])


def burst_window(trace: Mapping, end: int, *, before_s: float, after_s: float) -> slice:
    """Samples shown around the burst ending at ``end``: ``before_s`` (s) before the burst starts,
    ``after_s`` (s) after it ends (at the trace's ``fs``), clipped to the record."""
    fs = trace["fs"]
    received = np.asarray(trace["received"])
    start = end
    while start > 0 and not received[start - 1]:
        start -= 1
    return slice(max(start - int(before_s * fs), 0), min(end + int(after_s * fs), len(trace["time_s"])))


#: Columns of :func:`phase_table`: per_trial column → label.
PHASE_COLUMNS = {"rmse_total": "total RMSE (°)", "rms_lost": "lost samples (°)", "rms_after_gap": "2 s after a gap (°)",
                 "rms_steady": "rest (°)", "peak_increase_deg": "peak increase after a gap (°)",
                 "recovery_s": "recovery (s)", "recovered_share": "gaps recovered from",
                 "jitter_deg_s3": "jitter (°/s³)", "latency_s": "latency (s)"}
#: The column of :func:`phase_table` that gives jitter its scale: the same method without loss.
LOSSLESS_JITTER_COLUMN = "jitter without loss (°/s³)"


def phase_table(per_trial: pd.DataFrame, profile: str = HEADLINE) -> pd.DataFrame:
    """Mean over trials, per method, of the phase RMS (°), gap response, jitter and latency at ``profile``.

    Jitter (RMS angular jerk away from gap ends, °/s³) has no intuitive scale, so beside it stands
    the same method's jitter without loss (:data:`LOSSLESS_JITTER_COLUMN`, from the ``"lossless"``
    rows; NaN when there are none).
    """
    rows = per_trial[per_trial["profile"] == profile]
    if rows.empty:
        raise ValueError(f"no rows at profile {profile!r}")
    table = rows.groupby("method", sort=False)[list(PHASE_COLUMNS)].mean().rename(columns=PHASE_COLUMNS)
    lossless = per_trial[per_trial["profile"] == "lossless"].groupby("method")["jitter_deg_s3"].mean()
    table.insert(list(table.columns).index(PHASE_COLUMNS["jitter_deg_s3"]) + 1, LOSSLESS_JITTER_COLUMN,
                 lossless.reindex(table.index))
    return table


def jitter_sentence(phases: pd.DataFrame, best: Mapping[str, str]) -> str:
    """Jitter with its scale, from :func:`phase_table`: the best causal method's and holding's jitter
    under loss against their own without loss."""
    jitter = PHASE_COLUMNS["jitter_deg_s3"]
    parts = []
    for method in dict.fromkeys([best["causal"], "hold_last"]):
        if method in phases.index:
            row = phases.loc[method]
            parts.append(f"{method} {row[jitter]:.0f} °/s³ against {row[LOSSLESS_JITTER_COLUMN]:.0f} °/s³ "
                         f"without loss ({row[jitter] / row[LOSSLESS_JITTER_COLUMN]:.1f}×)")
    return ("Jitter (RMS angular jerk away from gap ends) at the headline: " + "; ".join(parts)
            + ". The same filter without loss is the scale to read the column against: what loss adds is the "
              "difference.")


def error_budgets(per_trial: pd.DataFrame, methods, profile: str = HEADLINE) -> pd.DataFrame:
    """:func:`~wsnlib.studies.loss_tolerance.summary.error_budget` of every method, one row each."""
    return pd.DataFrame({m: error_budget(per_trial, m, profile) for m in methods}).T


def trust_sentence(trust: pd.DataFrame) -> str:
    """How often the gate trusts the single frame, from
    :func:`~wsnlib.studies.loss_tolerance.evaluation.single_frame_trust`."""
    share = trust["trusted_share"]
    return (f"The gate trusts the single frame on {100 * share.median():.0f} % of the movement "
            f"samples of the median trial (from {100 * share.min():.0f} % on "
            f"`{share.idxmin()}` to {100 * share.max():.0f} % on "
            f"`{share.idxmax()}`); where it closes, the filter has to recover from a gap "
            f"with its own small gain.")


#: Columns of :func:`paper_vs_ours` from the one-burst metrics: per_trial column → label.
PAPER_VS_OURS_COLUMNS = {"burst_before_deg": "error before (°)", "burst_peak_increase_deg": "peak increase (°)",
                         "burst_recovery_s": "back within 2° (s)", "burst_recovered": "share back within 2°",
                         "burst_level_recovery_s": "back below 10° (s)"}


def paper_vs_ours(means: pd.DataFrame, best_peer: str, profile: str = "paper burst") -> pd.DataFrame:
    """Paper 001's words after its loss beside our one-burst response (means with 95 % intervals).

    Parameters
    ----------
    means : pandas.DataFrame
        :func:`~wsnlib.studies.loss_tolerance.summary.summary_table` with the one-burst metrics
        (:data:`~wsnlib.studies.loss_tolerance.evaluation.BURST_COLUMNS`) at ``profile``.
    best_peer : str
        The peer shown beside ours.
    profile : str
        A :class:`~wsnlib.studies.loss_tolerance.BurstPositions` profile.

    Returns
    -------
    pandas.DataFrame
        Index method (hold_last, hybrid (feedback), Kalman, smoother, ``best_peer``); the paper's
        words, then per :data:`PAPER_VS_OURS_COLUMNS` the mean over trials (each the mean over
        its burst positions) and, for the peak increase and the recovery, the interval bounds.
    """
    burst_means = means[means["profile"] == profile].set_index(["metric", "method"])
    words = {"hold_last": paper_values.PAPER001_SECTION4_AFTER_LOSS["data fusion"]["words"],
             "hybrid (feedback)": paper_values.PAPER001_SECTION4_AFTER_LOSS["hybrid"]["words"]}
    rows = {}
    for method in dict.fromkeys(["hold_last", "hybrid (feedback)", "Kalman", "smoother", best_peer]):
        row = {"paper (Sec. IV, simulated arm)": words.get(method, "—")}
        for metric, label in PAPER_VS_OURS_COLUMNS.items():
            value = burst_means.loc[(metric, method)]
            row[label] = value["mean"]
            if metric in ("burst_peak_increase_deg", "burst_recovery_s"):
                row[f"{label} low"], row[f"{label} high"] = value["ci_low"], value["ci_high"]
        rows[method] = row
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("method")


def paper_vs_ours_sentence(table: pd.DataFrame, peaks: pd.DataFrame, *, broad: bool = True,
                           positions: int | None = None) -> str:
    """The paper's hybrid after its loss against ours, holding and our Kalman filter.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`paper_vs_ours`.
    peaks : pandas.DataFrame
        :func:`~wsnlib.studies.loss_tolerance.summary.paired_comparisons` of ``burst_peak_increase_deg``
        with the pair (hold_last, hybrid (feedback)): whether the hybrid's peak exceeds holding's.
    broad : bool
        The trials are BROAD's, whose kinds of motion the sentence names; otherwise it speaks of
        "these recordings".
    positions : int, optional
        Bursts per trial (the profile's positions), said in the sentence.
    """
    hybrid_paper = paper_values.PAPER001_SECTION4_AFTER_LOSS["hybrid"]
    fusion_paper = paper_values.PAPER001_SECTION4_AFTER_LOSS["data fusion"]
    hybrid, hold, kalman = table.loc["hybrid (feedback)"], table.loc["hold_last"], table.loc["Kalman"]
    pair = peaks.set_index(["without", "with"]).loc[("hold_last", "hybrid (feedback)")]
    verdict = {"hurts": "**higher than holding's**, against the paper's claim that the hybrid recovers better",
               "helps": "lower than holding's, as the paper claims",
               "tie": "a tie with holding's, so the paper's advantage does not show"}[pair["verdict"]]
    peak, recovery = "peak increase (°)", "back within 2° (s)"
    where = "BROAD" if broad else "these recordings"
    motion = ("the trials include fast rotations, translations and magnetic disturbances (the per-trial dots above)"
              if broad else "the per-trial dots above show how these recordings differ from it")
    bursts = f"one burst per run at {positions} positions over each trial's movement" if positions else \
        "one burst per run"
    return (f"The paper's hybrid stays around {hybrid_paper['error_deg']:g}° for about "
            f"{hybrid_paper['duration_s']:g} s after its loss, while data fusion holding its output "
            f"{fusion_paper['words']}. On {where} ({bursts}), the burst adds a peak of "
            f"{hybrid[peak]:.1f}° [{hybrid[f'{peak} low']:.1f}, {hybrid[f'{peak} high']:.1f}] to the hybrid's error "
            f"and {hold[peak]:.1f}° [{hold[f'{peak} low']:.1f}, {hold[f'{peak} high']:.1f}] to holding's: the "
            f"hybrid's peak is {verdict} (difference {pair['difference']:+.1f}° [{pair['ci_low']:+.1f}, "
            f"{pair['ci_high']:+.1f}]; the hybrid's lower on {pair['n_better']} of {pair['n_trials']} trials). "
            f"The hybrid is "
            f"back within 2° of its error before the burst after {hybrid[recovery]:.2f} s on average, holding "
            f"after {hold[recovery]:.2f} s; our Kalman filter's peak is "
            f"{kalman[peak]:.1f}° [{kalman[f'{peak} low']:.1f}, {kalman[f'{peak} high']:.1f}] and it is back "
            f"after {kalman[recovery]:.2f} s. The paper's arm raise is one slow, smooth movement; {motion}.")


def recovery_sentence(table: pd.DataFrame, method: str = "Kalman", against: str = "hold_last") -> str:
    """Why a method with a lower error "recovers" more slowly, from :func:`paper_vs_ours`: the error
    before the burst, back within 2° of it, and back below the absolute 10°."""
    a, b = table.loc[method], table.loc[against]
    before, relative, level = "error before (°)", "back within 2° (s)", "back below 10° (s)"
    slower = a[relative] > b[relative]
    lower = a[before] < b[before]
    text = (f"Before the burst, {method}'s error was {a[before]:.1f}° and {against}'s {b[before]:.1f}°. "
            f"Back within 2° of it: {method} after {a[relative]:.2f} s, {against} after {b[relative]:.2f} s")
    if slower and lower:
        text += (f" — {method} takes longer because it has to come back closer, in degrees, to a lower error, "
                 f"not because it ends up worse")
    text += (f". Against one absolute level instead (the error back below 10°, counted as the whole "
             f"window when it does not get there): {method} after {a[level]:.2f} s, {against} after "
             f"{b[level]:.2f} s.")
    return text


def why_missed_sentence(per_trial: pd.DataFrame, best: Mapping[str, str], values: pd.DataFrame) -> str:
    """Why a target is missed: where the best causal and offline methods lose, and the worst trial.

    ``values``: trials × methods of the total RMSE (°) at the headline profile
    (:func:`~wsnlib.studies.loss_tolerance.summary.trial_table`).
    """
    causal = best["causal"]
    worst = values[causal].idxmax()
    return (f"**Why.** {diagnosis_sentence(per_trial, causal)} {diagnosis_sentence(per_trial, best['offline'])} "
            f"The worst trial for {causal} is `{worst}` ({values.loc[worst, causal]:.1f}° against a mean of "
            f"{values[causal].mean():.1f}°).")


def summary_bullets(per_trial: pd.DataFrame, *, ranking_sentence: str, targets: pd.DataFrame, best: Mapping[str, str],
                    comparisons: Mapping[str, pd.DataFrame], ablation: Sequence[str] = ()) -> list[str]:
    """The notebook's closing summary, one Markdown bullet per finding.

    Parameters
    ----------
    per_trial : pandas.DataFrame
        From :func:`~wsnlib.studies.loss_tolerance.evaluate`.
    ranking_sentence : str
        The headline ranking in words (:func:`wsnlib.stats.describe_ranking`).
    targets : pandas.DataFrame
        :func:`~wsnlib.studies.loss_tolerance.summary.targets_table`.
    best : mapping
        :func:`~wsnlib.studies.loss_tolerance.summary.best_methods`.
    comparisons : mapping question → table
        :func:`~wsnlib.studies.loss_tolerance.summary.paired_comparisons`; the total-RMSE rows are told.
    ablation : sequence of str
        :func:`ablation_sentences`, told in one bullet (none: no bullet).
    """
    return ([f"* **Ranking at {HEADLINE}.** {ranking_sentence}",
             "* **Targets.** " + "; ".join(f"{name}: {row['verdict']}" for name, row in targets.iterrows()) + ".",
             f"* **Where the best causal estimator ({best['causal']}) loses.** "
             + diagnosis_sentence(per_trial, best["causal"])]
            + (["* **What the filter and the gap handling contribute.** " + " ".join(ablation)] if ablation else [])
            + [f"* **{question}** " + " ".join(comparison_sentences(table[table["metric"] == "rmse_total"]))
               for question, table in comparisons.items()])


def design_sentences(design_ratios: pd.DataFrame, designs: pd.DataFrame) -> list[str]:
    """One sentence per pair of :func:`~wsnlib.studies.loss_tolerance.summary.ratio_table` over
    :data:`~wsnlib.studies.loss_tolerance.DESIGN_PAIRS` (design in fold / designed on all trials):
    the two means, the ratio with its interval, the optimism in degrees, and which designs the folds
    chose (``designs``: :func:`~wsnlib.studies.loss_tolerance.summary.design_choices`)."""
    out = []
    for row in design_ratios.itertuples(index=False):
        chosen = designs[designs["method"] == row.method].sort_values("n_trials", ascending=False, kind="stable")
        picks = "; ".join(f"{r.design} on {r.n_trials}" for r in chosen.itertuples(index=False))
        verdict = {"tie": "a tie", "lower": "lower with the design in the fold",
                   "higher": "higher with the design in the fold"}[row.verdict]
        out.append(f"**{row.method}**: {row.mean:.2f}° against {row.mean_against:.2f}° with the design chosen on "
                   f"all trials (`{row.against}`), ratio {row.ratio:.2f} [{row.ci_low:.2f}, {row.ci_high:.2f}], "
                   f"{verdict}: choosing the design on the scored trials "
                   + (f"flattered it by {row.mean - row.mean_against:.2f}°" if row.mean > row.mean_against else
                      f"cost it {row.mean_against - row.mean:.2f}°")
                   + f". Designs the folds chose (trials scored with each): {picks or 'none'}.")
    return out


def optimism_sentence(optimism: pd.DataFrame, edges: pd.DataFrame) -> str:
    """What tuning on the scored trials would have claimed, and which grids are too narrow.

    ``optimism``: :func:`~wsnlib.studies.loss_tolerance.summary.optimism_table`; ``edges``:
    :func:`~wsnlib.studies.loss_tolerance.summary.edge_picks`.
    """
    if optimism.empty:
        return "No method had settings to choose from: nothing was tuned, so there is no optimism to measure."
    largest = optimism["optimism"].idxmax()
    text = (f"Choosing each method's setting on all trials would have reported a mean headline RMSE "
            f"{optimism['optimism'].mean():.2f}° lower on average over the {len(optimism)} tuned methods "
            f"(most for {largest}: {optimism.loc[largest, 'held_out']:.2f}° held out against "
            f"{optimism.loc[largest, 'in_sample']:.2f}° chosen on all trials).")
    narrow = edges[edges["verdict"] == "grid too narrow"]
    bound = edges[edges["verdict"] == "at a bound of the space"]
    if narrow.empty:
        text += " No chosen value sits at a grid edge inside its search space."
    else:
        listed = "; ".join(f"{r.method} {r.setting} = {r.value:g} ({r.edge} edge, {r.n_trials} of {r.n_total} trials)"
                           for r in narrow.itertuples())
        text += f" **At a grid edge inside the search space (the grid is too narrow there):** {listed}."
    if not bound.empty:
        listed = "; ".join(f"{r.method} {r.setting} = {r.value:g} ({r.edge} bound, {r.n_trials} of {r.n_total} "
                           f"trials)" for r in bound.itertuples())
        text += (f" **At a physical bound of the search space** (flagged, not chased past it: beyond it the "
                 f"setting means something else, table of search spaces above): {listed}.")
    return text


def inclination_sentence(means: pd.DataFrame, neural: str, best: Mapping[str, str]) -> str:
    """The neural peer's inclination RMSE beside the best causal method's and the best peer's, at the
    headline and lossless (``means``: :func:`~wsnlib.studies.loss_tolerance.summary.summary_table` of
    ``rmse_inclination``)."""
    table = means.set_index(["profile", "method"])
    parts = []
    for profile in (HEADLINE, "lossless"):
        if (profile, neural) not in table.index:
            continue

        def cell(method, profile=profile):
            row = table.loc[(profile, method)]
            return f"{method} {row['mean']:.1f}° [{row['ci_low']:.1f}, {row['ci_high']:.1f}]"

        parts.append(f"{profile}: " + ", ".join(cell(m) for m in (neural, best["causal"], best["peer"])
                                                if (profile, m) in table.index))
    if not parts:
        raise ValueError(f"means has no row of {neural!r}")
    return "Mean inclination RMSE (95 % intervals) — " + "; ".join(parts) + "."


def ablation_grid(ablation_rows: pd.DataFrame) -> pd.DataFrame:
    """The ablation as a grid to read: filters × gap handlings, each cell ``"mean [low, high]"`` (°)
    (``ablation_rows``: :func:`~wsnlib.studies.loss_tolerance.summary.ablation_table`); "—" where a
    filter has no such variant."""
    cells = ablation_rows.assign(cell=[f"{r.mean:.1f} [{r.ci_low:.1f}, {r.ci_high:.1f}]"
                                       for r in ablation_rows.itertuples()])
    grid = cells.pivot(index="filter", columns="gap_handling", values="cell")
    gaps = [g for g in GAP_HANDLINGS if g in grid.columns]
    return grid.loc[list(dict.fromkeys(ablation_rows["filter"])), gaps].fillna("—")


def ablation_sentences(ratios: pd.DataFrame, ablation_rows: pd.DataFrame) -> list[str]:
    """What the filter and the gap handling contribute, from :func:`~wsnlib.studies.loss_tolerance.
    summary.ratio_table` of :func:`~wsnlib.studies.loss_tolerance.summary.ablation_pairs` (questions
    ``"filter"`` and ``"gap handling"``)."""
    gap_of = ablation_rows.set_index("method")["gap_handling"]
    filter_of = ablation_rows.set_index("method")["filter"]
    words = {"lower": "lower (the interval lies below 1)", "higher": "higher (the interval lies above 1)",
             "tie": "a tie (the interval holds 1)"}
    out = []
    for row in ratios[ratios["question"] == "filter"].itertuples():
        out.append(f"**Filter, {gap_of[row.method]}:** {row.method} {row.mean:.1f}° against the best peer with the "
                   f"same gap handling, {row.against}, {row.mean_against:.1f}°: ratio {row.ratio:.2f} "
                   f"[{row.ci_low:.2f}, {row.ci_high:.2f}], {words[row.verdict]}.")
    gaps = ratios[ratios["question"] == "gap handling"]
    for filter_name in dict.fromkeys(filter_of[gaps["method"]]):
        rows = gaps[[filter_of[m] == filter_name for m in gaps["method"]]]
        parts = [f"{gap_of[r.method]} ×{r.ratio:.2f} [{r.ci_low:.2f}, {r.ci_high:.2f}]" for r in rows.itertuples()]
        out.append(f"**Gap handling, {filter_name}** (mean RMSE against holding, {rows['mean_against'].iloc[0]:.1f}°): "
                   + "; ".join(parts) + ".")
    return out
