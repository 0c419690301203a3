"""Choosing parameters from Monte Carlo sweeps: Pareto fronts, a knee point, bootstrap intervals.

Used to tune the hybrid's (ρ, τ) of paper 001, eq. (3), where lower error and lower jerk pull
in opposite directions, so there is no single best point: we report the Pareto front and
recommend its *knee* — the point closest to the ideal corner once both costs are scaled to
[0, 1] over the front — with a bootstrap interval over the Monte Carlo realisations.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from wsnlib._validation import as_float_array


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
    if not isinstance(n_boot, int | np.integer) or n_boot < 1:
        raise ValueError(f"n_boot must be a positive integer, got {n_boot!r}")
    n_real = a.shape[1]
    knees = np.empty(n_boot, dtype=int)
    for i in tqdm(range(n_boot), desc="bootstrap", disable=not progress):
        pick = rng.integers(0, n_real, size=n_real)
        knees[i] = knee_point(a[:, pick].mean(axis=1), b[:, pick].mean(axis=1))
    return knees


#: The hybrid setting notebook 03 recommends in full mode (the knee of its Pareto front):
#: later notebooks use this constant, so that each runs on its own; notebook 03 asserts that
#: its own full-mode run still recommends it.
RECOMMENDED_HYBRID = {"schedule": "decay", "blend": "feedback", "rho": 3.0, "tau": 6.0}

#: File (in the processed-data folder) where notebook 03 stores its recommended hybrid setting.
RECOMMENDATION_FILE = "a03_recommended_hybrid.csv"


def write_recommendation(setting: dict) -> None:
    """Store the recommended hybrid setting (one row: schedule, blend, rho, tau, …) for later notebooks."""
    import pandas as pd

    from wsnlib import paths

    required = {"schedule", "blend", "rho", "tau"}
    missing = required - set(setting)
    if missing:
        raise ValueError(f"setting lacks {sorted(missing)}")
    from wsnlib._files import write_csv

    write_csv(pd.DataFrame([setting]), paths.data_processed() / RECOMMENDATION_FILE, index=False)


def read_recommendation() -> dict:
    """The hybrid setting recommended by notebook 03 (``schedule``, ``blend``, ``rho``, ``tau``, …).

    Raises
    ------
    FileNotFoundError
        If notebook 03 has not run yet in this output folder.
    """
    import pandas as pd

    from wsnlib import paths

    path = paths.data_processed() / RECOMMENDATION_FILE
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: run notebook 03_slerp_tuning first "
                                "(python -m wsnlib.reproduce --only 03)")
    row = pd.read_csv(path).iloc[0].to_dict()
    return {key: (value.item() if hasattr(value, "item") else value) for key, value in row.items()}


def hybrid_options(setting: dict) -> dict:
    """Keyword arguments of :func:`wsnlib.orientation.estimate_orientation` for a recommended setting.

    ``hold_window`` is passed only with the ``"hold"`` schedule (the only one that uses it).
    """
    options = {"method": "hybrid", "rho": float(setting["rho"]), "tau": float(setting["tau"]),
               "schedule": setting["schedule"], "blend": setting["blend"]}
    if setting["schedule"] == "hold":
        options["hold_window"] = int(setting["hold_window"])
    return options
