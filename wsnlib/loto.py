"""Leave-one-out choice of a setting: tune on the other units, score on the held-out one.

A parameter chosen on the same units it is then scored on (in-sample tuning) looks better than
it will on a new unit.  When several methods are compared, each should be tuned the same way and
with the same budget (number of candidate settings).  Leave-one-out over units (trials, users,
recordings) gives every unit a setting chosen without it:

    choice = leave_one_out_choice(scores)        # (n_units,) index of the setting per held-out unit
    held_out = leave_one_out_scores(scores)      # (n_units,) each unit's score under that setting

``scores`` has shape ``(n_settings, n_units)`` and lower is better (e.g. RMSE of a filter run with
setting ``i`` on trial ``j``).  The choice for unit ``j`` is the setting with the lowest mean
score over the *other* units; ties go to the lowest setting index.

Units that are not independent (the nodes of one recording: the same movement, the same
session) are held out together: with ``groups`` (one label per unit), the choice for unit ``j``
is tuned on the units of the *other* groups only (leave-one-group-out).

Non-finite scores: ``+inf`` marks a setting that failed on a unit (diverged, undefined); its mean
over any set of units that includes that unit is ``+inf``, so it is never chosen there unless
every setting is ``+inf`` (a ValueError).  NaN and ``-inf`` are rejected with a ValueError: a
missing score has no place in a mean, and silently skipping it would compare settings on
different units.
"""

from __future__ import annotations

import numpy as np

__all__ = ["in_sample_choice", "leave_one_out_choice", "leave_one_out_scores"]


def _check_groups(groups, n_units: int) -> np.ndarray:
    """``groups`` as an array of ``n_units`` labels with at least 2 distinct ones (None: every unit its own)."""
    if groups is None:
        return np.arange(n_units)
    labels = np.asarray(groups)
    if labels.shape != (n_units,):
        raise ValueError(f"groups must hold one label per unit ({n_units}), got shape {labels.shape}")
    distinct = sorted(set(labels.tolist()))
    if len(distinct) < 2:
        raise ValueError(f"groups must hold at least 2 distinct labels to leave one out, got {distinct}")
    return labels


def _check_scores(scores) -> np.ndarray:
    arr = np.asarray(scores, dtype=float)
    if arr.ndim != 2:
        raise ValueError(f"scores must have shape (n_settings, n_units), got shape {arr.shape}")
    n_settings, n_units = arr.shape
    if n_settings < 1:
        raise ValueError("scores must have at least one setting (row)")
    if n_units < 2:
        raise ValueError(f"scores must have at least 2 units (columns) to leave one out, got {n_units}")
    if np.isnan(arr).any():
        bad = tuple(int(i) for i in np.argwhere(np.isnan(arr))[0])
        raise ValueError(f"scores has NaN at (setting, unit) = {bad}; use +inf for a setting that failed on a unit")
    if np.isneginf(arr).any():
        bad = tuple(int(i) for i in np.argwhere(np.isneginf(arr))[0])
        raise ValueError(f"scores has -inf at (setting, unit) = {bad}")
    return arr


def _best(mean_scores: np.ndarray, which: str) -> int:
    if np.isinf(mean_scores).all():
        raise ValueError(f"every setting has an infinite score on {which}: no setting can be chosen")
    return int(np.argmin(mean_scores))


def in_sample_choice(scores) -> int:
    """Index of the setting with the lowest mean score over *all* units (in-sample tuning).

    Parameters
    ----------
    scores : array_like, shape (n_settings, n_units)
        Lower is better; ``+inf`` allowed (module docstring), NaN not.

    Returns
    -------
    int
        Row index of the chosen setting (the lowest index among equal means).

    Raises
    ------
    ValueError
        Wrong shape, fewer than 2 units, NaN or ``-inf`` in ``scores``, or every setting ``+inf``.
    """
    arr = _check_scores(scores)
    return _best(arr.mean(axis=1), "all units")


def leave_one_out_choice(scores, groups=None) -> np.ndarray:
    """For each held-out unit, the setting with the lowest mean score over the other units.

    Parameters
    ----------
    scores : array_like, shape (n_settings, n_units)
        Score of setting ``i`` on unit ``j`` (same unit for all, lower is better, e.g. RMSE in
        degrees); ``+inf`` allowed (module docstring), NaN not.
    groups : array_like, shape (n_units,), optional
        A label per unit (e.g. the recording a node belongs to): the units of the held-out
        unit's group are left out together.  Default: every unit its own group.

    Returns
    -------
    numpy.ndarray of int, shape (n_units,)
        ``choice[j]`` is the row index of the setting chosen without unit ``j`` (the lowest index
        among equal means).

    Raises
    ------
    ValueError
        ``scores`` not 2-D, fewer than 2 units (nothing is left to tune on), NaN or ``-inf`` in
        ``scores``, or every setting ``+inf`` on the units left in for some held-out unit;
        ``groups`` not one label per unit or with fewer than 2 distinct labels.
    """
    arr = _check_scores(scores)
    n_units = arr.shape[1]
    labels = _check_groups(groups, n_units)
    choice = np.empty(n_units, dtype=int)
    for held_out in range(n_units):
        others = labels != labels[held_out]
        choice[held_out] = _best(arr[:, others].mean(axis=1), f"the units other than {held_out}")
    return choice


def leave_one_out_scores(scores, groups=None) -> np.ndarray:
    """Each unit's score under the setting chosen on the other units (:func:`leave_one_out_choice`).

    Parameters
    ----------
    scores : array_like, shape (n_settings, n_units)
        As in :func:`leave_one_out_choice`.
    groups : array_like, shape (n_units,), optional
        As in :func:`leave_one_out_choice`.

    Returns
    -------
    numpy.ndarray of float, shape (n_units,)
        ``scores[choice[j], j]``, same unit as ``scores``; ``+inf`` where the chosen setting failed
        on the held-out unit.
    """
    arr = _check_scores(scores)
    choice = leave_one_out_choice(arr, groups)
    return arr[choice, np.arange(arr.shape[1])]
