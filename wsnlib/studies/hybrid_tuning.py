"""Notebook 03's study: tuning paper 001's hybrid (ρ, τ, λ schedule, blend) over Monte Carlo trials.

:func:`hybrid_sweep` runs the hybrid over a ρ × τ grid on simulated trials for each (schedule,
blend) pair and scores it (figures of merit of :mod:`wsnlib.metrics`); :func:`candidate_table`
and :func:`recommend_hybrid` turn that into the Pareto front of error against jitter
(:data:`RECOMMENDATION_COST`) and its knee (:mod:`wsnlib.tuning`) with a bootstrap interval;
:data:`RECOMMENDED_HYBRID` is the setting notebooks 04, 05 and 10 use (notebook 03 checks in full
mode that it still recommends it), and
:func:`mu_options` / :func:`hybrid_options` turn a setting into keywords of
:func:`wsnlib.orientation.estimate_orientation`.  The sentences notebook 03 prints are generated
here from the numbers.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from wsnlib import loss, metrics, paths, stats
from wsnlib._files import write_csv
from wsnlib.orientation import estimate_orientation, triad
from wsnlib.tuning import bootstrap_knee, knee_point, pareto_front

#: The (λ schedule, blend mode) pairs of the hybrid that notebook 03 compares.
HYBRID_CONFIGURATIONS = (("hold", "output"), ("hold", "feedback"), ("decay", "output"), ("decay", "feedback"))


def hybrid_sweep(trials, rho_grid, tau_grid, *, beta: float, hold_window: int, threshold_deg: float,
                 configurations=HYBRID_CONFIGURATIONS, progress: bool = False) -> tuple[dict, dict]:
    """Figures of merit of the hybrid over a ρ × τ grid, per (schedule, blend), and of its two references.

    One batched filter pass per (schedule, blend): ``rho`` has shape ``(n_ρ, 1, 1, 1)`` and
    ``tau`` ``(1, n_τ, 1, 1)``, so with trials ``(R, 2, T, 3)`` the output is
    ``(n_ρ, n_τ, R, 2, T, 4)``.  The error is the elbow angle's (:func:`wsnlib.metrics.elbow_angle_deg`)
    against the truth; the figures are :func:`wsnlib.metrics.loss_figures_of_merit` (extended)
    on the samples both nodes received.

    Parameters
    ----------
    trials : wsnlib.sim.trials.Trials
    rho_grid, tau_grid : sequence of float
        ρ and τ of eq. (3).
    beta : float
        Madgwick gain (rad/s).
    hold_window : int
        Samples, for schedule ``"hold"``.
    threshold_deg : float
        Error threshold (°) of the time-above figure.
    configurations : sequence of (str, str)
        (schedule, blend) pairs.
    progress : bool
        Show a progress bar.

    Returns
    -------
    foms : dict
        (schedule, blend) → figures of merit, each ``(n_ρ, n_τ, R)``.
    references : dict
        ``"data fusion"`` (Madgwick, hold last) and ``"single frame"`` (TRIAD, hold last) →
        figures of merit, each ``(R,)``.
    """
    rho = np.asarray(rho_grid, dtype=float)[:, None, None, None]
    tau = np.asarray(tau_grid, dtype=float)[None, :, None, None]
    fs = trials.fs
    elbow_true = metrics.elbow_angle_deg(trials.quat_true[:, 0], trials.quat_true[:, 1])      # (R, T)
    both_received = trials.received.all(axis=1)                                              # (R, T)

    def figures(quat):
        """Figures of merit of the elbow angle's error, from quaternions ``(..., R, 2, T, 4)``."""
        error = metrics.elbow_angle_deg(quat[..., 0, :, :], quat[..., 1, :, :]) - elbow_true
        return metrics.loss_figures_of_merit(error, fs=fs, received=both_received, threshold_deg=threshold_deg,
                                             extended=True)

    foms = {}
    for schedule, blend in tqdm(configurations, desc="(schedule, blend)", disable=not progress):
        foms[schedule, blend] = figures(estimate_orientation(
            trials.gyr, trials.acc, trials.mag, fs=fs, beta=beta, received=trials.received, rho=rho, tau=tau,
            schedule=schedule, blend=blend, hold_window=hold_window if schedule == "hold" else None))
    quat_df = estimate_orientation(trials.gyr, trials.acc, trials.mag, fs=fs, beta=beta, received=trials.received)
    quat_sf = loss.hold_last(triad(trials.acc, trials.mag), trials.received)
    return foms, {"data fusion": figures(quat_df), "single frame": figures(quat_sf)}


#: Columns of :func:`candidate_table` → figure of merit of :func:`wsnlib.metrics.loss_figures_of_merit`.
CANDIDATE_COLUMNS = {"mean max error (°)": metrics.MAX_ERROR, "mean jerk (°/s³)": metrics.JERK,
                     "mean gap-end step (°)": metrics.GAP_STEP_MEAN, "mean jitter (°/s³)": metrics.JITTER,
                     "mean time above (s)": metrics.TIME_ABOVE}

#: The smoothness cost the recommendation trades against the mean max error: the jitter (RMS jerk
#: with the jerk windows around gap ends left out, :func:`wsnlib.metrics.angle_jerk_rms_deg`).  The
#: RMS jerk of the whole record, the criterion before issue 26, is dominated by the one step at
#: each gap's end (notebook 02), which :data:`SMOOTHNESS_CRITERIA` shows on its own.
RECOMMENDATION_COST = "mean jitter (°/s³)"


def candidate_table(foms: dict, rho_grid, tau_grid, configurations=HYBRID_CONFIGURATIONS):
    """Every (schedule, blend, ρ, τ) with its mean figures of merit, and the per-trial costs.

    Parameters
    ----------
    foms : dict
        From :func:`hybrid_sweep`.
    rho_grid, tau_grid : sequence of float
    configurations : sequence of (str, str)

    Returns
    -------
    candidates : pandas.DataFrame
        Columns ``schedule``, ``blend``, ``rho``, ``tau``, the :data:`CANDIDATE_COLUMNS` (means
        over trials) and ``pareto`` (on mean max error vs :data:`RECOMMENDATION_COST`).
    costs : dict[str, numpy.ndarray]
        Column name → per-trial costs ``(n_candidates, R)``, rows in the table's order.
    """
    candidates = pd.DataFrame([{"schedule": s, "blend": b, "rho": r, "tau": t}
                               for s, b in configurations for r in rho_grid for t in tau_grid])
    costs = {}
    for column, key in CANDIDATE_COLUMNS.items():
        per_trial = [foms[c][key].reshape(len(rho_grid) * len(tau_grid), -1) for c in configurations]
        costs[column] = np.concatenate(per_trial)
        candidates[column] = costs[column].mean(axis=1)
    candidates["pareto"] = pareto_front(candidates["mean max error (°)"], candidates[RECOMMENDATION_COST])
    return candidates, costs


def recommend_hybrid(candidates, costs: dict, *, rng: np.random.Generator, n_boot: int, progress: bool = False,
                     **extra) -> tuple[dict, int, np.ndarray]:
    """The knee of mean max error vs :data:`RECOMMENDATION_COST` (jitter), with a bootstrap interval of its ρτ.

    Parameters
    ----------
    candidates, costs
        From :func:`candidate_table`.
    rng : numpy.random.Generator
        For :func:`bootstrap_knee`.
    n_boot : int
    progress : bool
    **extra
        Copied into the recommendation (e.g. ``hold_window``, ``beta``).

    Returns
    -------
    recommendation : dict
        ``schedule``, ``blend``, ``rho``, ``tau``, ``rho_tau``, ``rho_tau_ci_low``,
        ``rho_tau_ci_high`` (2.5–97.5 % over resamples),
        ``share_of_bootstrap_same_configuration``, then ``extra``.
    knee : int
        Row of the recommended candidate.
    boot : numpy.ndarray of int, shape (n_boot,)
        Knee row of each resample.
    """
    knee = knee_point(candidates["mean max error (°)"], candidates[RECOMMENDATION_COST])
    boot = bootstrap_knee(costs["mean max error (°)"], costs[RECOMMENDATION_COST], rng=rng, n_boot=n_boot,
                          progress=progress)
    picked = candidates.iloc[boot]
    recommended = candidates.iloc[knee]
    product_interval = np.quantile(picked["rho"] * picked["tau"], [0.025, 0.975])
    recommendation = {
        "schedule": recommended["schedule"], "blend": recommended["blend"],
        "rho": float(recommended["rho"]), "tau": float(recommended["tau"]),
        "rho_tau": float(recommended["rho"] * recommended["tau"]),
        "rho_tau_ci_low": float(product_interval[0]), "rho_tau_ci_high": float(product_interval[1]),
        "share_of_bootstrap_same_configuration": float(np.mean(
            (picked["schedule"] == recommended["schedule"]) & (picked["blend"] == recommended["blend"]))),
        **extra,
    }
    return recommendation, knee, boot


#: The hybrid setting notebook 03 recommends in full mode (the knee of its Pareto front of mean
#: max error against :data:`RECOMMENDATION_COST`; the whole-record jerk, the criterion before issue
#: 26, picked the same setting): later notebooks use this constant, so that each runs on its own;
#: notebook 03 asserts that its own full-mode run still recommends it.
#:
#: It is the knee on the *clean* simulator.  Notebook 03 also sweeps trials of the simulator
#: calibrated to BROAD (:data:`wsnlib.sim.disturbance.UNDISTURBED_BROAD`), where the knee moves to
#: the ``output`` blend at the grid's largest ρτ and data fusion alone has a lower mean error and
#: jitter than every hybrid setting (the hybrid stops helping on the elbow-angle criterion; notebook
#: 03's :func:`hybrids_against_data_fusion`); that knee is not adopted, because the criterion
#: cannot see heading, which is what the ``feedback`` blend repairs on real recordings: on the 17
#: BROAD trials at GE 10 % (β = 0.041, 3 loss draws per trial; measured once, November 2026, by a
#: script outside the repository) the realistic knee (decay/output, ρτ = 192) gave a mean total
#: RMSE of 77° — as bad as hold-last Madgwick, 78° — against 38° for this setting.
RECOMMENDED_HYBRID = {"schedule": "decay", "blend": "feedback", "rho": 3.0, "tau": 6.0}

#: File (in the processed-data folder) where notebook 03 stores its recommended hybrid setting.
RECOMMENDATION_FILE = "a03_recommended_hybrid.csv"


def write_recommendation(setting: dict) -> None:
    """Store the recommended hybrid setting (one row: schedule, blend, rho, tau, …) for later notebooks."""
    required = {"schedule", "blend", "rho", "tau"}
    missing = required - set(setting)
    if missing:
        raise ValueError(f"setting lacks {sorted(missing)}")
    write_csv(pd.DataFrame([setting]), paths.data_processed() / RECOMMENDATION_FILE, index=False)


def read_recommendation() -> dict:
    """The hybrid setting recommended by notebook 03 (``schedule``, ``blend``, ``rho``, ``tau``, …).

    Raises
    ------
    FileNotFoundError
        If notebook 03 has not run yet in this output folder.
    """
    path = paths.data_processed() / RECOMMENDATION_FILE
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: run notebook 03_slerp_tuning first "
                                "(python -m wsnlib.reproduce --only 03)")
    row = pd.read_csv(path).iloc[0].to_dict()
    return {key: (value.item() if hasattr(value, "item") else value) for key, value in row.items()}


def mu_options(setting: dict) -> dict:
    """μ's keywords (eq. (3): ``rho``, ``tau``, ``schedule``, and ``hold_window`` with the
    ``"hold"`` schedule only) of :func:`wsnlib.orientation.estimate_orientation` for a setting;
    what the hybrid and adaptive β share."""
    options = {"rho": float(setting["rho"]), "tau": float(setting["tau"]), "schedule": setting["schedule"]}
    if setting["schedule"] == "hold":
        options["hold_window"] = int(setting["hold_window"])
    return options


def hybrid_options(setting: dict) -> dict:
    """Keyword arguments of :func:`wsnlib.orientation.estimate_orientation` for a recommended
    hybrid setting: its ``blend`` and :func:`mu_options`."""
    return {"blend": setting["blend"], **mu_options(setting)}


# --- Tables and sentences of notebook 03 ------------------------------------------------------------------------

#: Smoothness costs of notebook 03's Pareto figures: candidate column → (label, figure of merit, log scale).
#: The first is the recommendation criterion (:data:`RECOMMENDATION_COST`, the jitter); the second is
#: the other half of the old whole-record jerk, the step at gap ends.
SMOOTHNESS_CRITERIA = {RECOMMENDATION_COST: ("jitter, gap ends excluded (°/s³)", metrics.JITTER, True),
                       "mean gap-end step (°)": ("mean step at gap ends (°)", metrics.GAP_STEP_MEAN, False)}


def knee_settings(candidates, criteria=SMOOTHNESS_CRITERIA):
    """The knee of mean max error against each smoothness cost.

    Parameters
    ----------
    candidates : pandas.DataFrame
        From :func:`candidate_table`.
    criteria : mapping column → (label, ...)
        Smoothness columns of ``candidates``; the label names the row.

    Returns
    -------
    pandas.DataFrame
        One row per criterion (index: its label): ``schedule``, ``blend``, ``rho``, ``tau``,
        ``rho_tau`` of the knee.
    """
    rows = {}
    for column, (label, *_) in criteria.items():
        if column not in candidates:
            raise ValueError(f"criteria names column {column!r}, which candidates does not have")
        knee = knee_point(candidates["mean max error (°)"], candidates[column])
        row = candidates.iloc[knee]
        rows[label] = {"schedule": row["schedule"], "blend": row["blend"], "rho": row["rho"], "tau": row["tau"],
                       "rho_tau": row["rho"] * row["tau"]}
    return pd.DataFrame.from_dict(rows, orient="index")


def knee_agreement_sentence(knees, recommendation: dict) -> str:
    """Whether the knees on the other smoothness figures pick the recommended setting.

    ``knees`` is :func:`knee_settings` (first row: the recommendation criterion);
    ``recommendation`` is from :func:`recommend_hybrid`.
    """
    recommended = (recommendation["schedule"], recommendation["blend"], recommendation["rho_tau"])
    same = [(row["schedule"], row["blend"], row["rho_tau"]) == recommended for _, row in knees.iterrows()]
    return (f"The knee on the recommendation criterion is {recommendation['schedule']}/{recommendation['blend']} "
            f"with ρτ = {recommendation['rho_tau']:g}. "
            + " ".join(f"On error vs {label} the knee is {row['schedule']}/{row['blend']} with ρτ = {row['rho_tau']:g}"
                       + (" — the same setting." if agrees else " — a different setting.")
                       for (label, row), agrees in list(zip(knees.iterrows(), same, strict=True))[1:])
            + (" Both criteria agree on the recommendation." if all(same)
               else " The recommendation keeps the jitter criterion (see above); the other front shows where a user "
                    "who weighs the steps at gap ends instead would land."))


def configuration_comparison(candidates, reference_foms: dict, configurations=HYBRID_CONFIGURATIONS):
    """The knee of each (schedule, blend) on its own, beside the reference estimators.

    Parameters
    ----------
    candidates : pandas.DataFrame
        From :func:`candidate_table`.
    reference_foms : dict name → figures of merit
        From :func:`hybrid_sweep` (data fusion, single frame).
    configurations : sequence of (str, str)

    Returns
    -------
    pandas.DataFrame
        Index estimator; ``rho``, ``tau`` (NaN for the references) and the means over trials of
        max error (°), time above the threshold (s), gap-end step (°) and jitter (°/s³); the
        hybrids at the knee of max error vs :data:`RECOMMENDATION_COST`.
    """
    figures = ("mean max error (°)", "mean time above (s)", "mean gap-end step (°)", "mean jitter (°/s³)")
    rows = []
    for schedule, blend in configurations:
        own = candidates[(candidates["schedule"] == schedule) & (candidates["blend"] == blend)]
        if own.empty:
            raise ValueError(f"candidates has no row for schedule {schedule!r}, blend {blend!r}")
        best = own.iloc[knee_point(own["mean max error (°)"], own[RECOMMENDATION_COST])]
        rows.append({"estimator": f"hybrid, {schedule}, {blend}", "rho": best["rho"], "tau": best["tau"],
                     **{column: best[column] for column in figures}})
    for name, f in reference_foms.items():
        rows.append({"estimator": name, "rho": np.nan, "tau": np.nan,
                     **{column: f[CANDIDATE_COLUMNS[column]].mean() for column in figures}})
    return pd.DataFrame(rows).set_index("estimator")


def recommendation_comparison(runs: dict):
    """Recommendations of several sweeps side by side (e.g. the clean and the realistic simulator).

    Parameters
    ----------
    runs : dict name → (recommendation, candidates, knee, reference_foms)
        From :func:`recommend_hybrid`, :func:`candidate_table` and :func:`hybrid_sweep`.

    Returns
    -------
    pandas.DataFrame
        One column per run (``"<name> simulator"``): schedule, blend, ρτ (samples) with its
        2.5–97.5 % bootstrap interval, the share of resamples on the same (schedule, blend), and
        the mean max error (°) of the knee, data fusion and single frame, the knee's mean jitter (°/s³).
    """
    return pd.DataFrame({
        f"{name} simulator": {
            "schedule": rec["schedule"], "blend": rec["blend"], "ρτ (samples)": rec["rho_tau"],
            "ρτ 2.5 %": rec["rho_tau_ci_low"], "ρτ 97.5 %": rec["rho_tau_ci_high"],
            "share of resamples, same (schedule, blend)": rec["share_of_bootstrap_same_configuration"],
            "knee: mean max error (°)": candidates.iloc[knee]["mean max error (°)"],
            "data fusion: mean max error (°)": refs["data fusion"][metrics.MAX_ERROR].mean(),
            "single frame: mean max error (°)": refs["single frame"][metrics.MAX_ERROR].mean(),
            "knee: mean jitter (°/s³)": candidates.iloc[knee][RECOMMENDATION_COST],
        } for name, (rec, candidates, knee, refs) in runs.items()})


def realistic_shift_sentence(clean: tuple, realistic: tuple, largest_product: float) -> str:
    """What changes from the clean to the realistic simulator, from the numbers.

    Parameters
    ----------
    clean, realistic : (recommendation, candidates, knee, reference_foms)
        As in :func:`recommendation_comparison`.
    largest_product : float
        The grid's largest ρτ (samples).
    """
    recommendation, _, _, refs = clean
    rec_real, cand_real, knee_real, refs_real = realistic
    clean_sf = refs["single frame"][metrics.MAX_ERROR].mean()
    real_sf = refs_real["single frame"][metrics.MAX_ERROR].mean()
    real_df = refs_real["data fusion"][metrics.MAX_ERROR].mean()
    knee_error = cand_real.iloc[knee_real]["mean max error (°)"]
    best_error = cand_real["mean max error (°)"].min()
    same_setting = all(recommendation[key] == rec_real[key] for key in ("schedule", "blend", "rho_tau"))
    return (
        f"Single frame's mean max elbow error grows from {clean_sf:.1f}° on the clean trials to "
        f"{real_sf:.1f}° on the realistic ones (data fusion: {real_df:.1f}°). "
        + ("The knee does not move. " if same_setting else
           f"The knee moves from {recommendation['schedule']}/{recommendation['blend']} with ρτ = "
           f"{recommendation['rho_tau']:g} to {rec_real['schedule']}/{rec_real['blend']} "
           f"with ρτ = {rec_real['rho_tau']:g} (bootstrap interval "
           f"{rec_real['rho_tau_ci_low']:g}–{rec_real['rho_tau_ci_high']:g}). ")
        + (f"That is the largest product on the grid ({largest_product:g}): the least single frame the grid allows. "
           if rec_real["rho_tau"] == largest_product else "")
        + f"Its mean max error, {knee_error:.1f}°, "
        + ("beats" if knee_error < real_df else "does not beat")
        + f" data fusion's; the lowest of any candidate is {best_error:.1f}°. "
        + ("With TRIAD as wrong as on BROAD, trading elbow error against jitter favours single frame much less: "
           "its jitter costs more than its correction after a gap gains."
           if rec_real["rho_tau"] > recommendation["rho_tau"] else ""))


def hybrids_against_data_fusion(candidates, costs: dict, reference_foms: dict, *, rng: np.random.Generator,
                                n_boot: int = 1000):
    """How every hybrid setting fares against data fusion alone, on the recommendation's two costs.

    Parameters
    ----------
    candidates, costs
        From :func:`candidate_table`.
    reference_foms : dict
        From :func:`hybrid_sweep` (``"data fusion"``: figures of merit per trial).
    rng : numpy.random.Generator
        For the bootstrap interval.
    n_boot : int

    Returns
    -------
    pandas.DataFrame
        One row per cost (``"mean max error (°)"``, :data:`RECOMMENDATION_COST`): ``data fusion``
        and ``best hybrid`` (means over trials; the best is the hybrid setting with the lowest
        mean), ``best hybrid setting`` (schedule/blend, ρτ), ``hybrids below data fusion`` (how
        many settings have a lower mean), ``hybrid settings``, and ``difference`` (best hybrid −
        data fusion) with ``ci_low``, ``ci_high``: its 95 % bootstrap interval paired over the
        ``trials`` (:func:`wsnlib.stats.paired_difference_ci`).
    """
    rows = {}
    for column in ("mean max error (°)", RECOMMENDATION_COST):
        per_trial = costs[column]                                                    # (n_candidates, R)
        reference = np.asarray(reference_foms["data fusion"][CANDIDATE_COLUMNS[column]], dtype=float)
        if per_trial.shape[1:] != reference.shape:
            raise ValueError(f"costs[{column!r}] has {per_trial.shape[1:]} trials per candidate, data fusion "
                             f"{reference.shape}: they must come from the same trials")
        best = int(np.argmin(candidates[column].to_numpy()))
        row = candidates.iloc[best]
        difference = stats.paired_difference_ci(per_trial[best], reference, rng=rng, n_boot=n_boot)
        rows[column] = {"data fusion": float(reference.mean()), "best hybrid": float(per_trial[best].mean()),
                        "best hybrid setting": f"{row['schedule']}/{row['blend']}, ρτ = {row['rho'] * row['tau']:g}",
                        "hybrids below data fusion": int(np.sum(candidates[column].to_numpy() < reference.mean())),
                        "hybrid settings": len(candidates), "trials": reference.size,
                        "difference": float(difference.estimate), "ci_low": float(difference.low),
                        "ci_high": float(difference.high)}
    return pd.DataFrame.from_dict(rows, orient="index")


def _difference_text(row, unit: str, decimals: int) -> str:
    """``"−1.2° [−1.5, −0.9]"``: a :func:`hybrids_against_data_fusion` row's difference and interval."""
    return f"{row['difference']:+,.{decimals}f}{unit} [{row['ci_low']:+,.{decimals}f}, {row['ci_high']:+,.{decimals}f}]"


def _how_many(count: int, total: int, *, again: bool = False) -> str:
    """``"none of the 256"``, ``"every one of the 256"``, ``"3 of the 256"``; again: ``"none"``, ``"all"``, ``"3"``."""
    if again:
        return "none" if count == 0 else "all" if count == total else f"{count}"
    return f"none of the {total}" if count == 0 else f"every one of the {total}" if count == total else \
        f"{count} of the {total}"


def data_fusion_sentence(simulator: str, comparison) -> str:
    """What :func:`hybrids_against_data_fusion` says, as one sentence, generated from its numbers.

    Parameters
    ----------
    simulator : str
        Names the trials, e.g. ``"the BROAD-calibrated simulator"``.
    comparison : pandas.DataFrame
        From :func:`hybrids_against_data_fusion`.
    """
    error, jitter = comparison.loc["mean max error (°)"], comparison.loc[RECOMMENDATION_COST]
    n = int(error["hybrid settings"])
    scope = f"95 % intervals paired over {int(error['trials'])} trials"
    below_error, below_jitter = int(error["hybrids below data fusion"]), int(jitter["hybrids below data fusion"])
    error_tie = error["ci_low"] <= 0.0 <= error["ci_high"]
    error_part = (f"the best, {error['best hybrid setting']}, has {error['best hybrid']:.1f}° against data fusion's "
                  f"{error['data fusion']:.1f}° (difference {_difference_text(error, '°', 1)}"
                  + (": the interval holds 0, a tie)" if error_tie else ")"))
    jitter_part = (f"the smoothest, {jitter['best hybrid setting']}, has {jitter['best hybrid']:,.0f} °/s³ against "
                   f"data fusion's {jitter['data fusion']:,.0f} "
                   f"(difference {_difference_text(jitter, '', 0)}; {scope})")
    if below_error == 0 and below_jitter == 0:
        return (f"On {simulator}, data fusion alone has a lower mean max elbow error and a lower mean jitter than "
                f"every one of the {n} hybrid settings: on the error, {error_part}; on the jitter, {jitter_part}.")
    verb = "has" if below_error in (0, n) else "have"
    return (f"On {simulator}, {_how_many(below_error, n)} hybrid settings {verb} a lower mean max elbow error than "
            f"data fusion — {error_part} — and {_how_many(below_jitter, n, again=True)} a lower mean jitter — "
            f"{jitter_part}.")
