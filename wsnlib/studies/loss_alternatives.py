"""Notebook 04's study: the ways to live with packet loss that paper 001 only names (Section V).

Every option is a keyword set of :func:`wsnlib.orientation.estimate_orientation` run on the same
Monte Carlo trials (:func:`wsnlib.sim.trials.arm_loss_trials`, Gilbert–Elliott loss at several
rates), scored on the elbow angle's error (paper 001, Figs. 1 and 6–8):

* :func:`loss_options` — the options: hold last (plain Madgwick), Δt extension ("the sampling
  period increased to (1 + λ)Δt", Sec. V), gyro interpolation (Sec. V), adaptive β (Sec. V) and
  the hybrid of eqs. (3)–(4); :func:`run_options` runs them and single frame (TRIAD);
* :func:`option_figures` — the figures of merit per trial and their means per loss rate;
* :func:`winners_by_loss_rate` — per loss rate and figure, a ranking with paired bootstrap
  intervals (:func:`wsnlib.stats.rank_with_ties`) and its leaders' tie group;
* :func:`guidance` — "which to use when", generated from the winners of one or more simulators
  (the clean one and the BROAD-calibrated one, :data:`wsnlib.sim.disturbance.UNDISTURBED_BROAD`),
  :func:`leaders_sentence`, which options lead anywhere on each, and :func:`least_accurate_sentence`,
  which option is the worst at one loss rate.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from wsnlib import loss, metrics, stats
from wsnlib.orientation import estimate_orientation, triad
from wsnlib.studies.hybrid_tuning import hybrid_options, mu_options

__all__ = ["RANKED_FIGURES", "guidance", "leaders_sentence", "least_accurate_sentence", "loss_options",
           "option_figures", "run_options", "winners_by_loss_rate"]

#: Figures of merit ranked per loss rate (:func:`wsnlib.metrics.loss_figures_of_merit`, extended).
RANKED_FIGURES = (metrics.P95_ERROR, metrics.MEAN_ERROR, metrics.TIME_ABOVE, metrics.GAP_STEP_MEAN, metrics.JITTER)


def loss_options(hybrid_setting: dict, *, beta: float, beta_max_factor: float) -> dict[str, dict]:
    """Keyword arguments of :func:`~wsnlib.orientation.estimate_orientation` per option.

    Parameters
    ----------
    hybrid_setting : dict
        ``schedule``, ``blend``, ``rho``, ``tau`` (e.g.
        :data:`wsnlib.studies.hybrid_tuning.RECOMMENDED_HYBRID`); adaptive β shares its μ.
    beta : float
        Madgwick's gain (rad/s).
    beta_max_factor : float
        Adaptive β rises after long gaps to this multiple of ``beta`` (> 1).

    Returns
    -------
    dict
        ``hold_last``, ``dt_extension``, ``gyro_interpolation``, ``adaptive_beta``, ``hybrid``.
    """
    if not beta > 0 or not beta_max_factor > 1:
        raise ValueError(f"beta must be > 0 and beta_max_factor > 1, got {beta!r} and {beta_max_factor!r}")
    return {"hold_last": {}, "dt_extension": {"method": "dt_extension"}, "gyro_interpolation": {"replay": True},
            "adaptive_beta": {**mu_options(hybrid_setting), "method": "adaptive_beta",
                              "beta_max": beta_max_factor * beta},
            "hybrid": hybrid_options(hybrid_setting)}


def run_options(trials, options: dict[str, dict], *, beta: float) -> tuple[dict, dict]:
    """The elbow angle's error of every option and of single frame (TRIAD, held over gaps).

    Parameters
    ----------
    trials : wsnlib.sim.trials.Trials
    options : dict name → keywords
        From :func:`loss_options`.
    beta : float
        Madgwick's gain (rad/s).

    Returns
    -------
    errors : dict name → numpy.ndarray (R, T)
        Estimated minus true elbow angle (°), options then ``"single frame"``.
    seconds : dict name → float
        Wall-clock time of each batched run (machine-dependent: show it, do not save it).
    """
    truth = metrics.elbow_angle_deg(trials.quat_true[:, 0], trials.quat_true[:, 1])
    errors, seconds = {}, {}
    for name in [*options, "single frame"]:
        started = time.perf_counter()
        if name == "single frame":
            quat = loss.hold_last(triad(trials.acc, trials.mag), trials.received)
        else:
            quat = estimate_orientation(trials.gyr, trials.acc, trials.mag, fs=trials.fs, beta=beta,
                                        received=trials.received, **options[name])
        seconds[name] = time.perf_counter() - started
        errors[name] = metrics.elbow_angle_deg(quat[:, 0], quat[:, 1]) - truth
    return errors, seconds


def option_figures(trials, errors: dict, loss_rates, profiles, *, threshold_deg: float) -> tuple[pd.DataFrame, dict]:
    """Figures of merit per trial and their means per loss rate.

    Parameters
    ----------
    trials : wsnlib.sim.trials.Trials
    errors : dict name → (R, T)
        From :func:`run_options`.
    loss_rates : sequence of float
        The loss rate of each profile, in the order of ``profiles``.
    profiles : sequence of wsnlib.loss.LossProfile
        The trials' profiles (``trials.labels["profile"]`` holds their names).
    threshold_deg : float
        Of the time-above figure (°).

    Returns
    -------
    results : pandas.DataFrame
        One row per (option, loss rate): ``option``, ``loss rate`` and the mean over its trials
        of every figure of :func:`wsnlib.metrics.loss_figures_of_merit` (extended), on the
        samples both nodes received.
    per_trial : dict name → dict figure → numpy.ndarray (R,)
    """
    if len(loss_rates) != len(profiles):
        raise ValueError(f"loss_rates ({len(loss_rates)}) and profiles ({len(profiles)}) must pair up")
    both_received = trials.received.all(axis=1)
    rows, per_trial = [], {}
    for name, error in errors.items():
        foms = metrics.loss_figures_of_merit(error, fs=trials.fs, received=both_received, threshold_deg=threshold_deg,
                                             extended=True)
        per_trial[name] = foms
        for rate, pick in zip(loss_rates, _profile_masks(trials, profiles), strict=True):
            rows.append({"option": name, "loss rate": rate, **{k: float(v[pick].mean()) for k, v in foms.items()}})
    return pd.DataFrame(rows), per_trial


def _profile_masks(trials, profiles) -> list[np.ndarray]:
    masks = [(trials.labels["profile"] == profile.name).to_numpy() for profile in profiles]
    empty = [profile.name for profile, mask in zip(profiles, masks, strict=True) if not mask.any()]
    if empty:
        raise ValueError(f"no trial has the profile(s) {empty}")
    return masks


def winners_by_loss_rate(per_trial: dict, trials, loss_rates, profiles, *, rng: np.random.Generator,
                         figures=RANKED_FIGURES, n_boot: int = 1000) -> tuple[pd.DataFrame, dict]:
    """Per lossy rate and figure: the ranking of the options and its leaders.

    Each ranking is :func:`wsnlib.stats.rank_with_ties` over the rate's trials (paired: an option
    ties with the leader when the interval of their paired difference contains 0).

    Parameters
    ----------
    per_trial : dict
        From :func:`option_figures`.
    trials, loss_rates, profiles
        As in :func:`option_figures`; rates of 0 are skipped (every Madgwick-based option is then
        the same filter).
    rng : numpy.random.Generator
    figures : sequence of str
        Figures of merit to rank (lower is better).
    n_boot : int

    Returns
    -------
    winners : pandas.DataFrame
        Index ``loss rate``, one column per figure: the leader's tie group joined by ``" = "``,
        with ``" (tie)"`` when it has more than one member.
    rankings : dict (loss rate, figure) → pandas.DataFrame
        The :func:`~wsnlib.stats.rank_with_ties` table (best first); ``pd.concat(rankings,
        names=["loss rate", "figure"])`` stacks them into one table.
    """
    winners, tables = {}, {}
    for rate, pick in zip(loss_rates, _profile_masks(trials, profiles), strict=True):
        if rate == 0:
            continue
        for figure in figures:
            ranking = stats.rank_with_ties({name: foms[figure][pick] for name, foms in per_trial.items()}, rng=rng,
                                           n_boot=n_boot)
            tables[rate, figure] = ranking
            leaders = list(ranking.index[ranking["tie_group"] == 1])
            winners.setdefault(figure, {})[rate] = " = ".join(leaders) + (" (tie)" if len(leaders) > 1 else "")
    if not tables:
        raise ValueError("no lossy rate to rank: every loss rate is 0")
    return pd.DataFrame(winners).rename_axis("loss rate"), tables


def _runs_of_rates(column: pd.Series) -> str:
    """``"gyro_interpolation at every loss rate"`` or ``"5–10 %: a; 15 %: b = c (tie)"``: consecutive
    loss rates with the same leaders joined into one span."""
    spans = []
    for rate, leaders in column.items():
        if spans and spans[-1][2] == leaders:
            spans[-1][1] = rate
        else:
            spans.append([rate, rate, leaders])
    if len(spans) == 1:
        return f"{spans[0][2]} at every loss rate"
    return "; ".join((f"{100 * lo:g} %" if lo == hi else f"{100 * lo:g}–{100 * hi:g} %") + f": {leaders}"
                     for lo, hi, leaders in spans)


def guidance(winners: dict[str, pd.DataFrame], purposes: dict[str, str]) -> str:
    """"Which to use when", one Markdown bullet per purpose, generated from winners tables.

    Parameters
    ----------
    winners : dict simulator name → pandas.DataFrame
        From :func:`winners_by_loss_rate` (e.g. ``{"clean simulator": …, "BROAD-calibrated
        simulator": …}``), with the same loss rates and figures.
    purposes : dict figure → str
        What a user who cares about that figure wants, e.g. ``"You care about the worst moments"``.

    Returns
    -------
    str
        One bullet per purpose: the leaders per span of loss rates, once when every simulator
        agrees, else one sub-bullet per simulator.
    """
    if not winners:
        raise ValueError("winners holds no simulator")
    lines = []
    for figure, purpose in purposes.items():
        missing = [name for name, table in winners.items() if figure not in table.columns]
        if missing:
            raise ValueError(f"winners of {missing} have no column {figure!r}")
        columns = {name: table[figure] for name, table in winners.items()}
        first = next(iter(columns.values()))
        if all(list(column.index) == list(first.index)
               and all(_leaders([a]) == _leaders([b]) for a, b in zip(column, first, strict=True))
               for column in columns.values()):
            lines.append(f"* **{purpose}:** {_runs_of_rates(first)}"
                         + (", on every simulator." if len(columns) > 1 else "."))
        else:
            lines.append(f"* **{purpose}:**")
            lines += [f"    * {name}: {_runs_of_rates(column)}." for name, column in columns.items()]
    return "\n".join(lines)


def _leaders(column: pd.Series) -> set[str]:
    """Every option named in a winners column (``"a = b (tie)"`` names a and b)."""
    return {name.strip() for cell in column for name in cell.removesuffix(" (tie)").split(" = ")}


def leaders_sentence(winners: dict[str, pd.DataFrame], figures, *, what: str) -> str:
    """Which options lead, alone or tied, on any of ``figures`` at some loss rate, per simulator.

    Parameters
    ----------
    winners : dict simulator name → pandas.DataFrame
        From :func:`winners_by_loss_rate`.
    figures : sequence of str
        Columns of the winners tables (e.g. the error figures).
    what : str
        Names the figures in the sentence, e.g. ``"the error figures"``.

    Returns
    -------
    str
        E.g. ``"On the error figures, the leaders at some loss rate are: clean simulator —
        hybrid, single frame; calibrated — single frame. Leading on clean simulator only:
        hybrid."``
    """
    if not winners:
        raise ValueError("winners holds no simulator")
    led = {name: set().union(*(_leaders(table[figure]) for figure in figures)) for name, table in winners.items()}
    text = (f"On {what}, the options that lead (alone or tied) at some loss rate are: "
            + "; ".join(f"{name} — {', '.join(sorted(options))}" for name, options in led.items()) + ".")
    for name, options in led.items():
        only = options.difference(*(other for other_name, other in led.items() if other_name != name))
        if only and len(led) > 1:
            text += f" Leading on the {name} only: {', '.join(sorted(only))}."
    return text


def least_accurate_sentence(per_trial: dict, trials, loss_rates, profiles, *, rate: float, figure: str, simulator: str,
                            rng: np.random.Generator, n_boot: int = 1000) -> str:
    """Which option has the highest mean of ``figure`` at one loss rate, and whether it is alone there.

    The options are ranked from the highest mean down (:func:`wsnlib.stats.rank_with_ties`,
    paired over the rate's trials); the options tied with the highest are named with it.

    Parameters
    ----------
    per_trial, trials, loss_rates, profiles
        As in :func:`winners_by_loss_rate`.
    rate : float
        One of ``loss_rates``.
    figure : str
        A figure of merit in degrees (e.g. :data:`wsnlib.metrics.MEAN_ERROR`).
    simulator : str
        Names the trials in the sentence.
    rng : numpy.random.Generator
    n_boot : int

    Returns
    -------
    str
        E.g. ``"on the clean simulator, hold_last (26.3° [24.9, 27.8]), above the next,
        adaptive_beta (22.3° [21.0, 23.6]), beyond the paired interval"``.
    """
    rates = list(loss_rates)
    if rate not in rates:
        raise ValueError(f"rate {rate!r} is not one of loss_rates {rates}")
    pick = _profile_masks(trials, profiles)[rates.index(rate)]
    ranking = stats.rank_with_ties({name: foms[figure][pick] for name, foms in per_trial.items()}, rng=rng,
                                   n_boot=n_boot, lower_is_better=False)

    def described(name):
        row = ranking.loc[name]
        return f"{name} ({row['estimate']:.1f}° [{row['ci_low']:.1f}, {row['ci_high']:.1f}])"

    worst = list(ranking.index[ranking["tie_group"] == 1])
    if len(worst) > 1:
        return (f"on the {simulator}, {', '.join(described(name) for name in worst)} cannot be told apart "
                "(paired intervals)")
    return f"on the {simulator}, {described(worst[0])}, above the next, {described(ranking.index[1])}, beyond the " \
           "paired interval"
