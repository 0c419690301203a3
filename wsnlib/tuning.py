"""Choosing parameters from Monte Carlo sweeps: Pareto fronts, a knee point, bootstrap intervals.

Used to tune the hybrid's (ρ, τ) of paper 001, eq. (3), where lower error and lower jerk pull
in opposite directions, so there is no single best point: we report the Pareto front and
recommend its *knee* — the point closest to the ideal corner once both costs are scaled to
[0, 1] over the front — with a bootstrap interval over the Monte Carlo realisations
(notebook 03's study of the hybrid: :mod:`wsnlib.studies.hybrid_tuning`).
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from wsnlib._validation import as_float_array, check_count


def pareto_front(cost_a, cost_b) -> np.ndarray:
    """Boolean mask of the points that no other point beats on both costs (lower is better).

    Parameters
    ----------
    cost_a, cost_b : array_like, shape (N,)

    Returns
    -------
    numpy.ndarray of bool, shape (N,)
        True where no point has ``a' <= a`` and ``b' <= b`` with at least one strict.
    """
    a = as_float_array(cost_a, "cost_a")
    b = as_float_array(cost_b, "cost_b")
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"cost_a and cost_b must be 1-D of equal length, got {a.shape} and {b.shape}")
    no_worse = (a[None, :] <= a[:, None]) & (b[None, :] <= b[:, None])
    better = (a[None, :] < a[:, None]) | (b[None, :] < b[:, None])
    return ~np.any(no_worse & better, axis=1)


def knee_point(cost_a, cost_b) -> int:
    """Index of the Pareto point nearest the ideal corner, each cost min–max scaled over the front.

    Ties go to the lowest index.  With a single Pareto point, that point.
    """
    a = as_float_array(cost_a, "cost_a")
    b = as_float_array(cost_b, "cost_b")
    front = pareto_front(a, b)
    scaled = []
    for cost in (a, b):
        low, high = cost[front].min(), cost[front].max()
        scaled.append((cost - low) / (high - low) if high > low else np.zeros_like(cost))
    distance = np.where(front, np.hypot(*scaled), np.inf)
    return int(np.argmin(distance))


def bootstrap_knee(cost_a, cost_b, *, rng: np.random.Generator, n_boot: int = 1000,
                   progress: bool = False) -> np.ndarray:
    """Knee indices over bootstrap resamples of the realisations.

    Parameters
    ----------
    cost_a, cost_b : array_like, shape (N, R)
        Cost of each of N candidate settings in each of R Monte Carlo realisations (the same
        realisations for every setting, so resampling is paired).
    rng : numpy.random.Generator
    n_boot : int
        Number of resamples.
    progress : bool
        Show a progress bar.

    Returns
    -------
    numpy.ndarray of int, shape (n_boot,)
        The knee index of each resample's mean costs; quantiles of the corresponding
        parameter values give a confidence interval for the recommendation.
    """
    a = as_float_array(cost_a, "cost_a", min_ndim=2)
    b = as_float_array(cost_b, "cost_b", min_ndim=2)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"cost_a and cost_b must both have shape (N, R), got {a.shape} and {b.shape}")
    check_count(n_boot, "n_boot")
    n_real = a.shape[1]
    knees = np.empty(n_boot, dtype=int)
    for i in tqdm(range(n_boot), desc="bootstrap", disable=not progress):
        pick = rng.integers(0, n_real, size=n_real)
        knees[i] = knee_point(a[:, pick].mean(axis=1), b[:, pick].mean(axis=1))
    return knees
