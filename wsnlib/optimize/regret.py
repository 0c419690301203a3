"""Beyond paper 002: how optimistic is picking the best of thousands of settings?

Tables 2 and 3 of Giuberti, Martalò, Ferrari (Section 5) report the minimised PE (eq. (11))
on the very data the settings were chosen on.  Here the choice is made on one part of the
data and scored on another:

* :func:`selection_regret`: swapped folds (repetition: movements 1–4 vs 5–8; and
  leave-one-user-out), regret against the test data's own best, optimism against the
  in-sample figure, standard errors over users;
* :func:`coupled_selection_regret`: the same for both targets, target 2's elbow (eq. (10))
  chosen on the selection data only (no leak from target 1's all-data choice).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from wsnlib._validation import check_type
from wsnlib.optimize.data import APPROACHES, SearchGrid, _check_choices, _paired_users, format_subset
from wsnlib.optimize.engine import DEFAULT_CHUNK_ELEMENTS, _search
from wsnlib.optimize.selection import _argbest, _Cube, _cubes, _nan_mean, _setting_record, proximal_from_selection

# --------------------------------------------------------------------------------------
# Selection regret with swapped folds and standard errors; target 2 without the leak
# --------------------------------------------------------------------------------------

#: Splits of :func:`selection_regret` and :func:`coupled_selection_regret`.
SPLITS = ("repetition", "leave-one-user-out")

#: Columns of :func:`selection_regret` (summary rows).
REGRET_COLUMNS = ("in_sample_cm", "out_of_sample_cm", "oracle_cm", "regret_cm", "regret_se_cm",
                  "optimism_cm", "optimism_se_cm", "n_folds", "n_units")


@dataclasses.dataclass(frozen=True)
class _Fold:
    """Selection data (``train_*``) and test data (``test_*``) of one fold: movement and user indices.

    Movement ``train_movements[j]`` selects for ``test_movements[j]`` (per-movement selection).
    """

    split: str
    name: str
    train_movements: np.ndarray
    test_movements: np.ndarray
    train_users: np.ndarray
    test_users: np.ndarray


def _check_halves(first, second) -> tuple[tuple, tuple]:
    first, second = tuple(first), tuple(second)
    if len(first) != len(second) or not first:
        raise ValueError(f"first and second must be non-empty and of equal length, got {first} and {second}")
    if set(first) & set(second):
        raise ValueError(f"first and second overlap: {sorted(set(first) & set(second))}")
    return first, second


def _folds(cube: _Cube, first, second, splits) -> list[_Fold]:
    mov_index = {m: i for i, m in enumerate(cube.movements.tolist())}
    everyone = np.arange(cube.users.size)
    folds = []
    if "repetition" in splits:
        missing = [m for m in first + second if m not in mov_index]
        if missing:
            raise ValueError(f"results have no movement {missing} (have {cube.movements.tolist()})")
        fi = np.array([mov_index[m] for m in first])
        si = np.array([mov_index[m] for m in second])
        folds.append(_Fold("repetition", f"select on movements {format_subset(first)}", fi, si, everyone, everyone))
        folds.append(_Fold("repetition", f"select on movements {format_subset(second)}", si, fi, everyone, everyone))
    if "leave-one-user-out" in splits:
        if cube.users.size < 2:
            raise ValueError("leave-one-user-out needs at least 2 users (a 'user' column)")
        all_mov = np.arange(cube.movements.size)
        for u, label in enumerate(cube.users):
            folds.append(_Fold("leave-one-user-out", f"hold out user {label}", all_mov, all_mov,
                               np.delete(everyone, u), np.array([u])))
    return folds


def _fold_picks(cube: _Cube, fold: _Fold) -> dict[str, np.ndarray]:
    """Settings chosen on the fold's selection data: ``global`` (1,) and ``per_movement`` (M′,)."""
    train = cube.user_mean(fold.train_users)[:, fold.train_movements]              # (C, M')
    return {"global": np.array([_argbest(_Cube.movement_mean(train))]),
            "per_movement": np.array([_argbest(train[:, j]) for j in range(train.shape[1])])}


def _fold_units(cube: _Cube, fold: _Fold, selection: str, picks: np.ndarray) -> list[dict]:
    """Per test unit (user) of one fold: in-sample, out-of-sample and oracle PE (cm)."""
    train = cube.user_mean(fold.train_users)[:, fold.train_movements]              # (C, M')
    test = cube.pe[:, fold.test_movements][:, :, fold.test_users]                   # (C, M', U')
    test_mean = _nan_mean(test, axis=-1)                                            # (C, M')
    in_units = None
    if np.array_equal(fold.train_users, fold.test_users):  # the units are in the selection data too
        in_units = cube.pe[:, fold.train_movements][:, :, fold.test_users]
    if selection == "global":
        pick = int(picks[0])
        oracle = _argbest(_Cube.movement_mean(test_mean))
        out_u = _nan_mean(test[pick], axis=0)                                        # (U',)
        oracle_u = _nan_mean(test[oracle], axis=0)
        in_u = (_nan_mean(in_units[pick], axis=0) if in_units is not None
                else np.full(out_u.shape, _Cube.movement_mean(train)[pick]))
    else:
        cols = np.arange(test.shape[1])
        oracles = np.array([_argbest(test_mean[:, j]) if not np.all(np.isnan(test_mean[:, j])) else 0 for j in cols])
        out_u = _nan_mean(test[picks, cols], axis=0)                                 # (M', U') → (U',)
        oracle_u = _nan_mean(test[oracles, cols], axis=0)
        in_u = (_nan_mean(in_units[picks, cols], axis=0) if in_units is not None
                else np.full(out_u.shape, np.nanmean(train[picks, cols])))
    rows = []
    for k, u in enumerate(fold.test_users):
        if np.isnan(out_u[k]):
            continue
        rows.append({"split": fold.split, "selection": selection, "fold": fold.name, "unit": cube.users[u],
                     "in_sample_cm": float(in_u[k]), "out_of_sample_cm": float(out_u[k]),
                     "oracle_cm": float(oracle_u[k]), "regret_cm": float(out_u[k] - oracle_u[k]),
                     "optimism_cm": float(out_u[k] - in_u[k])})
    return rows


def _summarise_units(units: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Mean over folds per unit, then mean and standard error over units."""
    figures = ["in_sample_cm", "out_of_sample_cm", "oracle_cm", "regret_cm", "optimism_cm"]
    per_unit = units.groupby(keys + ["unit"], sort=False)[figures].mean()
    grouped = per_unit.groupby(level=keys, sort=False)
    summary = grouped.mean()
    n_units = grouped.size()
    for figure in ("regret_cm", "optimism_cm"):
        se = grouped[figure].std(ddof=1) / np.sqrt(n_units)
        summary[figure.replace("_cm", "_se_cm")] = se.where(n_units >= 2)
    summary["n_folds"] = units.groupby(keys, sort=False)["fold"].nunique()
    summary["n_units"] = n_units
    order = {"split": SPLITS, "selection": ("global", "per_movement"), "approach": APPROACHES}
    position = {key: {v: i for i, v in enumerate(values)} for key, values in order.items()}
    summary = summary.sort_index(key=lambda level: level.map(position[level.name]) if level.name in position else level)
    return summary[list(REGRET_COLUMNS)]


def selection_regret(results: pd.DataFrame, *, first=(1, 2, 3, 4), second=(5, 6, 7, 8), splits=SPLITS,
                     by_unit: bool = False) -> pd.DataFrame:
    """Regret and optimism of selecting settings on part of the data, with swapped folds (not in the paper).

    Each fold selects on one part of the data (Table 3's global rule, or Table 2's
    per-movement rule) and scores the choice on the other part:

    * ``"repetition"``: two folds, swapped — select on movements ``first`` and score on
      ``second`` (``first[i]``'s per-movement choice scored on ``second[i]``), then the
      reverse.  Users averaged as in the paper.
    * ``"leave-one-user-out"``: select on all users but one (their average), score on the
      held-out user; every user in turn.

    Per fold and test unit (a user):

    * ``out_of_sample_cm``: PE of the chosen setting on the test data;
    * ``oracle_cm``: PE on the test data of the setting that is best *on the test data*
      (the test part's own selection, users averaged);
    * ``regret_cm`` = out-of-sample − oracle: what choosing on other data costs.  Averaged
      over a fold's units it is ≥ 0 by construction; a single unit can be below 0;
    * ``in_sample_cm``: the minimised PE on the selection data (for the repetition split the
      unit's own PE on the first half; for leave-one-user-out the other users' average);
    * ``optimism_cm`` = out-of-sample − in-sample: by how much a table's in-sample number
      understates a new session or user.  Unlike the regret it can be negative in one fold
      (the halves differ in difficulty); swapping the folds cancels that difference on average.

    With swapped folds, the mean in-sample PE equals the mean oracle PE (each half is once
    selection data and once test data), so averaged over both repetition folds the optimism
    equals the regret and is ≥ 0; what one unswapped fold reports is not.

    Units are users: each user's values are averaged over the folds it is tested in (two for
    the repetition split, one for leave-one-user-out); the summary gives their mean and the
    standard error over users, ``std(ddof=1) / √n_units`` (NaN with a single unit, where it
    is undefined; ``n_units`` says so).

    Parameters
    ----------
    results : DataFrame
        From :func:`search` (per user), one target.  For target 2 use
        :func:`coupled_selection_regret` instead: the elbow in target-2 results comes from a
        target-1 setting chosen on all the data.
    first, second : sequences of movement labels, equal length
    splits : str or sequence of :data:`SPLITS`
    by_unit : bool
        Return one row per (fold, unit) instead of the summary.

    Returns
    -------
    pandas.DataFrame
        Index ``(approach, split, selection)``; columns :data:`REGRET_COLUMNS`.  With
        ``by_unit``: columns ``approach``, ``split``, ``selection``, ``fold``, ``unit`` and the
        five PE figures.
    """
    first, second = _check_halves(first, second)
    splits = _check_choices(splits, SPLITS, "splits")
    rows = []
    for approach, cube in _cubes(results).items():
        for fold in _folds(cube, first, second, splits):
            picks = _fold_picks(cube, fold)
            for selection in ("global", "per_movement"):
                rows += [{"approach": approach, **r} for r in _fold_units(cube, fold, selection, picks[selection])]
    units = pd.DataFrame(rows)
    if by_unit:
        return units
    return _summarise_units(units, ["approach", "split", "selection"])


def _selection_frame(cube: _Cube, assignment: dict) -> pd.DataFrame:
    """Per-movement selection rows (as :func:`select_settings`) from ``{movement label: config index}``."""
    return pd.DataFrame([{"movement": m, **_setting_record(cube, i)} for m, i in assignment.items()])


def coupled_selection_regret(target1, target2, *, approaches=APPROACHES, grid: SearchGrid | None = None,
                             first=(1, 2, 3, 4), second=(5, 6, 7, 8), splits=SPLITS,
                             results1: pd.DataFrame | None = None, by_unit: bool = False, progress: bool = False,
                             chunk_elements: int = DEFAULT_CHUNK_ELEMENTS) -> pd.DataFrame:
    """:func:`selection_regret` for both targets, target 2's elbow chosen on the selection data only.

    Target 2's position is measured from the elbow estimated with target 1 (eq. (10)), so
    target 2's held-out figures are honest only if target 1's setting, too, is chosen on the
    fold's selection data.  In :func:`paper_tables` target 1's setting is chosen on all the
    data — fine for Tables 2 and 3, which are in-sample anyway, but a leak when target 2 is
    then "held out".  Here, for every fold:

    1. target 1's setting is selected on the fold's selection data (global rule, and the
       per-movement rule: movement ``first[i]``'s choice also serves ``second[i]``'s rows;
       movements in neither half get the global choice);
    2. every user's elbow is computed with it (:func:`proximal_from_selection`);
    3. target 2 is searched with those elbows (one search per fold, both rules at once) and
       its selection scored exactly as in :func:`selection_regret`.

    That is one target-2 search per fold: 2 for the repetition split, one per user for
    leave-one-user-out.

    Parameters
    ----------
    target1, target2 : sequence or mapping of SearchData
        As in :func:`paper_tables`.
    approaches, grid, progress, chunk_elements
        As in :func:`search`.
    first, second, splits, by_unit
        As in :func:`selection_regret`.
    results1 : DataFrame, optional
        :func:`search` results of ``target1`` with the same grid (e.g.
        ``PaperTables.target1``), to save a search.

    Returns
    -------
    pandas.DataFrame
        As :func:`selection_regret`, with an outer index level ``target`` (1, 2), or a
        ``target`` column with ``by_unit``.
    """
    approaches = _check_choices(approaches, APPROACHES, "approaches")
    grid = check_type(SearchGrid() if grid is None else grid, SearchGrid, "grid")
    first, second = _check_halves(first, second)
    splits = _check_choices(splits, SPLITS, "splits")
    labels1, users1, users2 = _paired_users(target1, target2, approaches)
    if results1 is None:
        prox1 = [{a: u.proximal[None] for a in approaches} for u in users1]
        results1 = _search(labels1, users1, approaches, "hybrid", grid, prox1, progress, chunk_elements)[0]
    results1 = results1[results1["approach"].isin(approaches)]
    if "estimate" in results1.columns and set(results1["estimate"]) != {"hybrid"}:
        raise ValueError("results1 must hold hybrid estimates")
    if list(pd.unique(results1["user"])) != labels1:
        raise ValueError(f"results1 must hold the users {labels1}, got {list(pd.unique(results1['user']))}")
    cubes1 = _cubes(results1)

    rows1, rows2 = [], []
    reference = next(iter(cubes1.values()))
    for index, fold in enumerate(_folds(reference, first, second, splits)):
        prox2 = [{} for _ in users1]
        for approach, cube1 in cubes1.items():
            picks = _fold_picks(cube1, fold)
            for selection in ("global", "per_movement"):
                rows1 += [{"approach": approach, **r} for r in _fold_units(cube1, fold, selection, picks[selection])]
            movements = cube1.movements
            global_pick = int(picks["global"][0])
            per_movement = {m: global_pick for m in movements.tolist()}
            for j, (a, b) in enumerate(zip(fold.train_movements, fold.test_movements, strict=True)):
                per_movement[movements[a].item()] = per_movement[movements[b].item()] = int(picks["per_movement"][j])
            glob = _selection_frame(cube1, {m: global_pick for m in movements.tolist()})
            mov = _selection_frame(cube1, per_movement)
            for k, u1 in enumerate(users1):
                prox2[k][approach] = np.stack([proximal_from_selection(u1, glob), proximal_from_selection(u1, mov)])
        res_glob, res_mov = _search(labels1, users2, approaches, "hybrid", grid, prox2, progress, chunk_elements)
        for selection, res in (("global", res_glob), ("per_movement", res_mov)):
            for approach, cube2 in _cubes(res).items():
                fold2 = _folds(cube2, first, second, splits)[index]
                picks2 = _fold_picks(cube2, fold2)
                rows2 += [{"approach": approach, **r} for r in _fold_units(cube2, fold2, selection, picks2[selection])]
    units = pd.concat([pd.DataFrame(rows1).assign(target=1), pd.DataFrame(rows2).assign(target=2)], ignore_index=True)
    if by_unit:
        return units
    return _summarise_units(units, ["target", "approach", "split", "selection"])
