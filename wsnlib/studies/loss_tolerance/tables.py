"""Tables, selections and sentences of notebook 10 (the loss-tolerance study, issue 11).

What the notebook shows beyond :mod:`wsnlib.studies.loss_tolerance` (running) and
:mod:`wsnlib.studies.loss_tolerance.summary` (intervals, rankings, targets): the paper's
weight μ(λ) beside the Kalman filter's 1 − K, the tables of methods and loss profiles, which
trials and which burst the burst figure shows, the per-phase table, the paper-vs-ours table and
the sentences built from them.  Angles in degrees, times in seconds, rates in °/s.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from wsnlib import paper_values
from wsnlib.orientation import KalmanSettings, slerp_weight
from wsnlib.studies.loss_tolerance.evaluation import AFTER_GAP_S
from wsnlib.studies.loss_tolerance.registry import HEADLINE, LATENCY_RULES, PROFILES
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


def method_table(methods: Mapping) -> pd.DataFrame:
    """One row per method: kind, number of settings, the grid written out, latency rule."""
    return pd.DataFrame([{"method": m.name, "kind": m.kind, "settings": len(m.grid),
                          "grid": "; ".join(", ".join(f"{k}={v}" for k, v in s.items()) for s in m.grid),
                          "latency": LATENCY_RULES[m.latency]} for m in methods.values()]).set_index("method")


def profile_table(profiles=PROFILES) -> pd.DataFrame:
    """One row per loss profile: model, loss rate, mean burst (packets; NaN unless Gilbert–Elliott), packet size."""
    return pd.DataFrame([{"profile": p.name, "model": p.model, "loss rate": p.loss_rate,
                          "mean burst (packets)": p.mean_burst_packets if p.model == "gilbert_elliott" else np.nan,
                          "samples per packet": p.samples_per_packet}
                         for p in profiles]).set_index("profile")


#: Panels of the error-vs-loss-rate figure: title → methods (those not run are left out).
LOSS_RATE_FIGURE_GROUPS = {"Madgwick: bridging a gap": ("hold_last", "constant_rate", "gyro_interpolation"),
                           "ours: hybrid, Kalman, smoother": ("hybrid (feedback)", "Kalman", "smoother"),
                           "peers": ("Fusion + hybrid (feedback)", "VQF", "VQF + hybrid (feedback)")}


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
                 "recovery_s": "recovery (s)", "recovered_share": "gaps recovered from", "latency_s": "latency (s)"}


def phase_table(per_trial: pd.DataFrame, profile: str = HEADLINE) -> pd.DataFrame:
    """Mean over trials, per method, of the phase RMS (°), gap response and latency at ``profile``."""
    rows = per_trial[per_trial["profile"] == profile]
    if rows.empty:
        raise ValueError(f"no rows at profile {profile!r}")
    return rows.groupby("method", sort=False)[list(PHASE_COLUMNS)].mean().rename(columns=PHASE_COLUMNS)


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


def paper_vs_ours(means: pd.DataFrame, best_peer: str, profile: str = "paper burst") -> pd.DataFrame:
    """Paper 001's words after its loss beside our mean burst response (with 95 % intervals).

    Parameters
    ----------
    means : pandas.DataFrame
        :func:`~wsnlib.studies.loss_tolerance.summary.summary_table` (with ``peak_increase_deg``
        and ``recovery_s``).
    best_peer : str
        The peer shown beside ours.
    profile : str

    Returns
    -------
    pandas.DataFrame
        Index method (hold_last, hybrid (feedback), Kalman, smoother, ``best_peer``); the
        paper's words, peak increase (°) and recovery (s) with their interval bounds.
    """
    burst_means = means[means["profile"] == profile].set_index(["metric", "method"])
    words = {"hold_last": paper_values.PAPER001_SECTION4_AFTER_LOSS["data fusion"]["words"],
             "hybrid (feedback)": paper_values.PAPER001_SECTION4_AFTER_LOSS["hybrid"]["words"]}
    rows = {}
    for method in ["hold_last", "hybrid (feedback)", "Kalman", "smoother", best_peer]:
        peak = burst_means.loc[("peak_increase_deg", method)]
        recovery = burst_means.loc[("recovery_s", method)]
        rows[method] = {"paper (Sec. IV, simulated arm)": words.get(method, "—"),
                        "ours: peak increase (°)": peak["mean"], "low": peak["ci_low"], "high": peak["ci_high"],
                        "ours: recovery (s)": recovery["mean"], "recovery low": recovery["ci_low"],
                        "recovery high": recovery["ci_high"]}
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("method")


def paper_vs_ours_sentence(table: pd.DataFrame, *, broad: bool = True) -> str:
    """The paper's hybrid after its loss against ours and our Kalman filter, from :func:`paper_vs_ours`.

    ``broad``: the trials are BROAD's (:func:`~wsnlib.studies.loss_tolerance.all_broad`), whose
    kinds of motion the sentence names; otherwise it speaks of "these recordings".
    """
    hybrid_paper = paper_values.PAPER001_SECTION4_AFTER_LOSS["hybrid"]
    hybrid, kalman = table.loc["hybrid (feedback)"], table.loc["Kalman"]
    motion = ("the trials include fast rotations, translations and magnetic disturbances (the per-trial dots above)"
              if broad else "the per-trial dots above show how these recordings differ from it")
    return (f"The paper's hybrid stays around {hybrid_paper['error_deg']:g}° for about "
            f"{hybrid_paper['duration_s']:g} s after its loss. On {'BROAD' if broad else 'these recordings'}, "
            f"the burst adds a peak of "
            f"{hybrid['ours: peak increase (°)']:.1f}° "
            f"[{hybrid['low']:.1f}, {hybrid['high']:.1f}] to the hybrid's error, back below 2° after "
            f"{hybrid['ours: recovery (s)']:.2f} s on average; our Kalman filter's peak is "
            f"{kalman['ours: peak increase (°)']:.1f}° [{kalman['low']:.1f}, {kalman['high']:.1f}] and its recovery "
            f"{kalman['ours: recovery (s)']:.2f} s. The paper's arm raise is one slow, smooth movement; {motion}.")


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
                    comparisons: Mapping[str, pd.DataFrame]) -> list[str]:
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
    """
    return ([f"* **Ranking at {HEADLINE}.** {ranking_sentence}",
             "* **Targets.** " + "; ".join(f"{name}: {row['verdict']}" for name, row in targets.iterrows()) + ".",
             f"* **Where the best causal estimator ({best['causal']}) loses.** "
             + diagnosis_sentence(per_trial, best["causal"])]
            + [f"* **{question}** " + " ".join(comparison_sentences(table[table["metric"] == "rmse_total"]))
               for question, table in comparisons.items()])


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
        text += (f" {len(bound)} chosen value(s) sit at a bound of their search space "
                 f"({', '.join(sorted(set(bound['method'])))}): flagged, not chased past it.")
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
