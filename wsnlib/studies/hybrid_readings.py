"""Notebook 02's comparison of the hybrid's readings, replicated over movements and speeds (paper 001, eqs. (3)–(4)).

Paper 001 leaves open how λ behaves once reception resumes and whether the SLERP blend feeds back
into Madgwick's state; :data:`READINGS` names the six readings (λ schedule × blend) that
:func:`wsnlib.orientation.estimate_orientation` offers.  On one trajectory the readings are
ranked over sensor-noise runs only, which separates differences far too small to matter.  Here:

* :func:`readings_mean_error` runs every reading on Monte Carlo trials of several movements
  (:func:`wsnlib.sim.trials.arm_loss_trials`) and returns each trial's mean |elbow error| from
  the first lost sample on;
* :func:`rank_readings` ranks them with 95 % intervals over the *movements*: a two-stage
  bootstrap (movements, then their noise runs; :func:`wsnlib.stats.rank_with_ties` with groups);
* :func:`leader_sentence` says whether the leader is ahead of the runner-up by more than a
  practical margin — within it, the two are a practical tie even when the interval of their
  difference excludes 0.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnlib import metrics, stats
from wsnlib.orientation import estimate_orientation

__all__ = ["READINGS", "leader_sentence", "movement_means", "per_movement", "rank_readings", "readings_mean_error"]

#: The hybrid's readings: name → (λ schedule, blend) of :func:`~wsnlib.orientation.estimate_orientation`.
READINGS = {f"hybrid, {schedule}, {blend}": (schedule, blend)
            for schedule in ("instant", "hold", "decay") for blend in ("output", "feedback")}


def readings_mean_error(trials, *, beta: float, rho: float, tau: float, hold_window: int,
                        readings=READINGS) -> dict[str, np.ndarray]:
    """Each reading's mean |elbow error| (°) per trial, from the first sample either node lost on.

    Parameters
    ----------
    trials : wsnlib.sim.trials.Trials
        Every trial loses at least one sample (e.g. the paper's burst).
    beta : float
        Madgwick's gain (rad/s).
    rho, tau : float
        Eq. (3).
    hold_window : int
        Samples, for the ``"hold"`` schedule.
    readings : dict name → (schedule, blend)

    Returns
    -------
    dict name → numpy.ndarray, shape (R,)
    """
    both_received = trials.received.all(axis=1)                                      # (R, T)
    after_loss = np.cumsum(~both_received, axis=-1) > 0
    if not after_loss.any(axis=-1).all():
        raise ValueError("every trial must lose at least one sample: the error is averaged from the first loss on")
    truth = metrics.elbow_angle_deg(trials.quat_true[:, 0], trials.quat_true[:, 1])
    out = {}
    for name, (schedule, blend) in readings.items():
        quat = estimate_orientation(trials.gyr, trials.acc, trials.mag, fs=trials.fs, beta=beta,
                                    received=trials.received, rho=rho, tau=tau, schedule=schedule, blend=blend,
                                    hold_window=hold_window if schedule == "hold" else None)
        error = np.abs(metrics.elbow_angle_deg(quat[:, 0], quat[:, 1]) - truth)
        out[name] = np.sum(np.where(after_loss, error, 0.0), axis=-1) / after_loss.sum(axis=-1)
    return out


def per_movement(values, movements) -> tuple[np.ndarray, np.ndarray]:
    """Trials regrouped by movement: ``(n_movements, n_runs)`` values and the movement names.

    Parameters
    ----------
    values : array_like, shape (R,)
    movements : array_like of str, shape (R,)
        Each trial's movement (``trials.labels["movement"]``); every movement has the same
        number of trials.
    """
    values = np.asarray(values, dtype=float)
    movements = np.asarray(movements)
    if values.shape != movements.shape or values.ndim != 1:
        raise ValueError(f"values and movements must be 1-D of equal length, got {values.shape} and {movements.shape}")
    names = list(dict.fromkeys(movements.tolist()))
    rows = [values[movements == name] for name in names]
    if len({row.size for row in rows}) != 1:
        raise ValueError("every movement must have the same number of trials")
    return np.stack(rows), np.asarray(names)


def movement_means(errors: dict, movements) -> pd.DataFrame:
    """Each reading's mean over the trials of each movement: rows readings, columns movements."""
    columns = {}
    for name, values in errors.items():
        grouped, names = per_movement(values, movements)
        columns[name] = pd.Series(grouped.mean(axis=1), index=names)
    return pd.DataFrame(columns).T.rename_axis(index="reading", columns="movement")


def rank_readings(errors: dict, movements, *, rng: np.random.Generator, n_boot: int = 1000) -> pd.DataFrame:
    """Readings ranked by mean error, with 95 % intervals over the movements and their noise runs.

    Parameters
    ----------
    errors : dict name → array_like (R,)
        From :func:`readings_mean_error`.
    movements : array_like of str, shape (R,)
        Each trial's movement; at least 2 movements.
    rng : numpy.random.Generator
    n_boot : int

    Returns
    -------
    pandas.DataFrame
        :func:`wsnlib.stats.rank_with_ties` with ``groups`` (the movements): best first,
        ``estimate``, ``ci_low``, ``ci_high``, ``tie_group`` …, ``n_units`` = movements.
    """
    samples, names = {}, None
    for name, values in errors.items():
        samples[name], names = per_movement(values, movements)
    return stats.rank_with_ties(samples, rng=rng, n_boot=n_boot, groups=names)


def leader_sentence(ranking, errors: dict, movements, *, margin: float, rng: np.random.Generator,
                    n_boot: int = 1000, what: str = "mean |elbow error|", unit: str = "°") -> str:
    """Whether the leader of :func:`rank_readings` is ahead of the runner-up by more than ``margin``.

    The paired difference runner-up − leader gets its own 95 % interval over the movements and
    their noise runs (:func:`wsnlib.stats.grouped_bootstrap_ci`).  Three outcomes:

    * the interval lies below ``margin``: a *practical tie* (even if it excludes 0);
    * it lies above 0 and reaches ``margin`` or more: the leader is ahead;
    * otherwise (it holds 0 and reaches ``margin``): the two cannot be told apart.

    Parameters
    ----------
    ranking : pandas.DataFrame
        From :func:`rank_readings`.
    errors, movements
        As given to :func:`rank_readings`.
    margin : float
        The smallest difference worth having, in the unit of ``errors`` (> 0).
    rng, n_boot
    what, unit : str
        Name and unit of the quantity in the sentence.
    """
    if not margin > 0:
        raise ValueError(f"margin must be positive, got {margin!r}")
    leader, runner = ranking.index[0], ranking.index[1]
    a, names = per_movement(errors[runner], movements)
    b, _ = per_movement(errors[leader], movements)
    difference = stats.grouped_bootstrap_ci(a - b, names, rng=rng, n_boot=n_boot)
    d, low, high = float(difference.estimate), float(difference.low), float(difference.high)

    def described(name):
        row = ranking.loc[name]
        return f"`{name}` {row['estimate']:.2f} [{row['ci_low']:.2f}, {row['ci_high']:.2f}]{unit}"

    scope = (f"95 % intervals over {len(names)} movements with their noise runs; "
             f"difference {d:+.3f} [{low:+.3f}, {high:+.3f}]{unit}")
    if high < margin:
        verdict = (f"`{leader}` and `{runner}` are a practical tie on {what}: their difference stays below "
                   f"{margin:g}{unit}" + (" although its interval excludes 0" if low > 0 else ""))
    elif low > 0:
        verdict = f"`{leader}` has the lowest {what}, ahead of `{runner}` beyond the interval"
    else:
        verdict = f"`{leader}` and `{runner}` cannot be told apart on {what}"
    return f"{verdict}: {described(leader)} and {described(runner)} ({scope})."
