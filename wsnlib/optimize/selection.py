"""Selection of paper 002's settings: per movement (Table 2) and global (Table 3).

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition", Section 5.  From the per-user results of :func:`~wsnlib.optimize.engine.search`:
:func:`average_over_users` (the users-average table the selections work on),
:func:`select_settings` (the best setting per approach, per movement or global), and
:func:`evaluate_selection` / :func:`proximal_from_selection`, which evaluate a selection on
one user's data — the latter gives the elbow of eq. (10) that target 2's search is measured
from (see :mod:`wsnlib.optimize.tables`) — and :func:`evaluate_chain`, both targets of one
user along the chain (target 2 from target 1's estimated elbow).

Averaging, selection and ties
-----------------------------
The users' PEs (eq. (11), cm) are averaged with equal weight per user (the users that have
the movement), and the parameters minimise that average (Section 5: "chosen as the ones
which jointly maximize the average performance of all the users").  Global (Table 3)
selection minimises the mean over movements of the users' average, each movement weighted
equally — the paper's "average PE" rows are such plain means of table rows.

Ties: settings whose PE is within :data:`TIE_TOL_CM` of the minimum are equal, and the one
with the lowest ``config`` number wins.  Settings are numbered in this order: subset size
(fewest anchors first), subsets of one size lexicographically by anchor number, distance
in ``grid.metrics`` order (Euclidean first), ``k`` ascending, ``p_s`` ascending (``k = 1``,
without ``p_s``, first).  So among equally good settings the one with the fewest anchors
and the simplest parameters is reported; a superset of an optimal subset that does equally
well is never chosen over it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnlib._validation import check_type
from wsnlib.optimize.data import APPROACHES, SearchData, Setting, _check_approach, _check_paired_rows
from wsnlib.optimize.engine import evaluate_setting

#: PEs (cm) within this of the minimum count as ties (broken by the lowest ``config``).
TIE_TOL_CM = 1e-9

_SETTING_COLUMNS = ["config", "subset", "anchors", "n_anchors", "metric", "k", "p_s"]


# --------------------------------------------------------------------------------------
# Selection (Tables 2 and 3)
# --------------------------------------------------------------------------------------


def _check_results(results) -> pd.DataFrame:
    if not isinstance(results, pd.DataFrame):
        raise ValueError(f"results must be a DataFrame from search(), got {type(results).__name__}")
    missing = {"approach", "config", "movement", "pe_cm", *_SETTING_COLUMNS} - set(results.columns)
    if missing:
        raise ValueError(f"results lacks the columns {sorted(missing)} (expected the output of search())")
    if results.empty:
        raise ValueError("results is empty")
    return results


class _Cube:
    """PE of one approach as an array ``(C, M, U)`` (NaN where a user lacks a movement)."""

    def __init__(self, frame: pd.DataFrame):
        self.settings = frame.drop_duplicates("config").set_index("config")[
            [c for c in _SETTING_COLUMNS if c != "config"] + ["approach"]].sort_index()
        self.configs = self.settings.index.to_numpy()
        self.movements = np.unique(frame["movement"].to_numpy())
        users = frame["user"] if "user" in frame.columns else pd.Series(0, index=frame.index)
        self.users = pd.unique(users)
        ci = np.searchsorted(self.configs, frame["config"].to_numpy())
        mi = np.searchsorted(self.movements, frame["movement"].to_numpy())
        ui = pd.Index(self.users).get_indexer(users)
        self.pe = np.full((self.configs.size, self.movements.size, self.users.size), np.nan)
        self.pe[ci, mi, ui] = frame["pe_cm"].to_numpy(dtype=float)

    def user_mean(self, users=None) -> np.ndarray:
        """Mean over ``users`` (indices; default all) of the PE: ``(C, M)``, NaN where nobody has it."""
        return _nan_mean(self.pe if users is None else self.pe[..., users])

    @staticmethod
    def movement_mean(pe: np.ndarray, movements=None) -> np.ndarray:
        """Equal-weight mean over ``movements`` (indices; default all) of ``(C, M)``: ``(C,)``."""
        return _nan_mean(pe if movements is None else pe[:, movements])


def _nan_mean(pe: np.ndarray, axis: int = -1) -> np.ndarray:
    """Mean over ``axis`` of the values that are not NaN (NaN where there are none)."""
    count = np.sum(~np.isnan(pe), axis=axis)
    return np.where(count > 0, np.nansum(pe, axis=axis) / np.maximum(count, 1), np.nan)


def _argbest(values: np.ndarray) -> int:
    """Index of the minimum; values within TIE_TOL_CM of it tie, the lowest index wins."""
    if np.all(np.isnan(values)):
        raise ValueError("no setting has a PE to select from")
    best = np.nanmin(values)
    return int(np.flatnonzero(values <= best + TIE_TOL_CM)[0])


def _cubes(results: pd.DataFrame) -> dict[str, _Cube]:
    results = _check_results(results)
    if "estimate" in results.columns and results["estimate"].nunique() > 1:
        raise ValueError("results mixes hybrid and radio estimates; select one first")
    return {a: _Cube(results[results["approach"] == a]) for a in APPROACHES if (results["approach"] == a).any()}


def _setting_record(cube: _Cube, index: int) -> dict:
    return {"config": int(cube.configs[index]), **cube.settings.iloc[index].to_dict()}


def average_over_users(results: pd.DataFrame) -> pd.DataFrame:
    """Users-average PE per (approach, setting, movement): what Tables 2 and 3 select from.

    Returns
    -------
    pandas.DataFrame
        One row per (approach, setting, movement), in ``config`` order: ``approach``, the
        setting columns, ``movement``, ``pe_cm`` (mean over the users that have the
        movement, each user weighted equally; cm), ``n_users``.
    """
    parts = []
    for approach, cube in _cubes(results).items():
        mean = cube.user_mean()
        n_users = np.sum(~np.isnan(cube.pe), axis=-1)
        n_set, n_mov = mean.shape
        part = cube.settings.drop(columns="approach").iloc[np.repeat(np.arange(n_set), n_mov)].reset_index()
        part.insert(0, "approach", approach)
        part["movement"] = np.tile(cube.movements, n_set)
        part["pe_cm"] = mean.ravel()
        part["n_users"] = n_users.ravel()
        parts.append(part[part["n_users"] > 0])
    return pd.concat(parts, ignore_index=True)


def select_settings(results: pd.DataFrame, *, per_movement: bool) -> pd.DataFrame:
    """The best setting per approach (and per movement), tidy.

    ``per_movement=True`` minimises each movement's users-average PE (Table 2);
    ``False`` the mean over movements of the users-average PE (Table 3).  Ties: see the
    module docstring.

    Returns
    -------
    pandas.DataFrame
        One row per approach (× movement): ``approach``, [``movement``], ``pe_cm`` (users
        average; for the global selection the mean over movements), ``n_users``, and the
        setting columns ``config``, ``subset``, ``anchors``, ``n_anchors``, ``metric``,
        ``k``, ``p_s``.
    """
    rows = []
    for approach, cube in _cubes(results).items():
        mean = cube.user_mean()
        n_users = np.sum(~np.isnan(cube.pe), axis=-1)
        if per_movement:
            for j, movement in enumerate(cube.movements):
                i = _argbest(mean[:, j])
                rows.append({"approach": approach, "movement": movement, "pe_cm": mean[i, j],
                             "n_users": int(n_users[i, j]), **_setting_record(cube, i)})
        else:
            overall = cube.movement_mean(mean)
            i = _argbest(overall)
            rows.append({"approach": approach, "pe_cm": overall[i], "n_users": int(cube.users.size),
                         **_setting_record(cube, i)})
    out = pd.DataFrame(rows)
    out["p_s"] = out["p_s"].astype(results["p_s"].dtype)
    return out


# --------------------------------------------------------------------------------------
# Evaluating a selection; the elbow of eq. (10)
# --------------------------------------------------------------------------------------


def evaluate_selection(data: SearchData, selection, *, approach: str | None = None) -> dict[str, np.ndarray]:
    """:func:`evaluate_setting` under a selection: one setting, or one per movement (Table 2).

    Parameters
    ----------
    data : SearchData
        One user's data for one target.
    selection : Setting, or DataFrame from :func:`select_settings`
        A single setting (global, Table 3), or per-movement rows (Table 2): each row of
        ``data`` then uses the setting chosen for its movement.  With a DataFrame, rows of
        ``approach`` are used (needed when it holds several approaches).
    approach : str, optional

    Returns
    -------
    dict
        As :func:`evaluate_setting`, each row evaluated with its movement's setting.
    """
    if isinstance(selection, Setting):
        return evaluate_setting(data, selection)
    if not isinstance(selection, pd.DataFrame) or selection.empty:
        raise ValueError("selection must be a Setting or a non-empty select_settings() DataFrame")
    if approach is not None:
        selection = selection[selection["approach"] == _check_approach(approach)]
    if selection["approach"].nunique() != 1:
        raise ValueError("selection must hold one approach (pass approach=...)")
    if "movement" not in selection.columns:
        if len(selection) != 1:
            raise ValueError("a global selection must have one row per approach")
        return evaluate_setting(data, Setting.from_row(selection.iloc[0]))
    chosen = {m: Setting.from_row(row) for m, row in selection.set_index("movement", drop=False).iterrows()}
    missing = sorted(set(np.unique(data.movement).tolist()) - set(chosen))
    if missing:
        raise ValueError(f"selection has no setting for movements {missing}")
    out: dict[str, np.ndarray] = {}
    cache: dict[Setting, dict] = {}
    for movement, setting in chosen.items():
        rows = data.movement == movement
        if not rows.any():
            continue
        if setting not in cache:
            cache[setting] = evaluate_setting(data, setting)
        for key, values in cache[setting].items():
            out.setdefault(key, np.full(values.shape, np.nan))[rows] = values[rows]
    return out


def proximal_from_selection(data: SearchData, selection, *, approach: str | None = None) -> np.ndarray:
    """Distal joint (the elbow, eq. (10)) of ``data``'s segment per row, under a selection.

    ``selection`` and ``approach`` as in :func:`evaluate_selection`.  Returns ``(n, 3)`` (m),
    to pass as target 2's ``proximal``.
    """
    return evaluate_selection(data, selection, approach=approach)["joints"]


def evaluate_chain(target1: SearchData, target2: SearchData, selection1, selection2=None, *,
                   approach: str | None = None) -> dict[str, dict[str, np.ndarray]]:
    """Both targets of one user along the arm chain: target 2 measured from target 1's elbow.

    Paper 002's recursive process (Section 3.3, eq. (10)): the upper arm (target 1) is
    estimated from the shoulder, its distal joint — the *estimated* elbow — is the proximal
    joint of the forearm (target 2), whose hybrid estimate then starts there.  So target 2's
    error includes target 1's elbow error.  This is the one place that wires the chain for an
    evaluation; the searches (:func:`~wsnlib.optimize.paper_tables`,
    :func:`~wsnlib.optimize.coupled_selection_regret`) take the same elbow from
    :func:`proximal_from_selection` and search target 2 over the grid with it.

    Parameters
    ----------
    target1, target2 : SearchData
        One user's paired rows of the two targets (the same number of rows and the same
        ``movement`` per row); ``target2.proximal`` is ignored (replaced by the elbow).
    selection1 : Setting, or DataFrame from :func:`select_settings`
        Target 1's setting(s), as in :func:`evaluate_selection`.
    selection2 : Setting, or DataFrame from :func:`select_settings`, optional
        Target 2's setting(s); default ``selection1``.
    approach : str, optional
        Rows of DataFrame selections to use, as in :func:`evaluate_selection`.

    Returns
    -------
    dict
        ``"T1"``, ``"T2"``: each target's :func:`evaluate_selection` output — ``"radio"``
        (n, 3) radio estimate (m), ``"devices"`` (n, 3) hybrid estimate (m), ``"joints"``
        (n, 3) distal joint (m; ``"T1"``'s is the elbow target 2 starts from, ``"T2"``'s the
        wrist), ``"pe_m"`` (n,) hybrid error (m) — plus ``"radio_pe_m"`` (n,), the error of
        the radio estimate alone (m).

    Raises
    ------
    ValueError
        ``target1`` or ``target2`` is not a :class:`SearchData`, or their rows are not paired.
    """
    check_type(target1, SearchData, "target1")
    check_type(target2, SearchData, "target2")
    _check_paired_rows(target1, target2)
    selection2 = selection1 if selection2 is None else selection2
    first = evaluate_selection(target1, selection1, approach=approach)
    second = evaluate_selection(target2.with_proximal(first["joints"]), selection2, approach=approach)
    return {key: {**result, "radio_pe_m": np.linalg.norm(result["radio"] - data.true_positions, axis=-1)}
            for key, result, data in (("T1", first, target1), ("T2", second, target2))}
