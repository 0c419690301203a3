"""Paper 002's Tables 2 and 3: their layout, the T1 → T2 coupling, the deployable anchor set.

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition", Section 5.  :func:`best_per_movement` / :func:`best_global` lay a selection
out as Table 2 / Table 3; :func:`union_of_subsets` gives Section 5's deployable
configuration; :func:`paper_tables` computes the whole of both tables for both targets.

Target 2 depends on target 1 (the coupling)
-------------------------------------------
Target 2's proximal joint is the elbow *as estimated from target 1* (eq. (10)), so its PE
depends on which target-1 setting is used.  :func:`paper_tables` therefore searches target 1
first, selects its settings, computes each user's elbow with them
(:func:`~wsnlib.optimize.selection.proximal_from_selection`) and only then searches target 2:

* Table 2 (per movement): the rows of movement m use the elbow of target 1's best setting
  *for movement m*;
* Table 3 (global): all rows use the elbow of target 1's single global setting;
* each approach uses its own target-1 setting (deterministic target 2 rides on the
  deterministic elbow, probabilistic on the probabilistic one);
* with ``estimate="radio"`` target 2 does not use the elbow, and there is one search.

So target 2 is optimised *given* target 1's choice (sequential, as the recursive process of
Section 3.3 runs), not jointly over both targets' settings; the joint optimum could only be
lower.  The paper does not say how it handled this.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Iterable

import numpy as np
import pandas as pd

from wsnlib.optimize.data import (
    APPROACHES,
    SearchGrid,
    _check_approach,
    _check_choices,
    _check_estimate,
    _paired_users,
    format_subset,
    parse_subset,
)
from wsnlib.optimize.engine import DEFAULT_CHUNK_ELEMENTS, _search
from wsnlib.optimize.selection import proximal_from_selection, select_settings

_DISTANCE_LABELS = {"euclidean": "Euclidean", "manhattan": "Manhattan"}


# --------------------------------------------------------------------------------------
# Table layout and the deployable anchor set
# --------------------------------------------------------------------------------------


def _paper_layout(selection: pd.DataFrame, index_cols: list[str], target) -> pd.DataFrame:
    blocks = {}
    for approach, part in selection.groupby("approach", sort=False):
        part = part.set_index(index_cols) if index_cols else part.reset_index(drop=True)
        block = pd.DataFrame(index=part.index)
        block["PE [cm]"] = part["pe_cm"].astype(float)
        block["N"] = part["n_anchors"].astype(int)
        block["anchors subset"] = part["subset"]
        if approach == "deterministic":
            block["distance"] = part["metric"].map(_DISTANCE_LABELS)
            block["k"] = part["k"].astype(int)
            block["p_s"] = ["—" if pd.isna(p) else (int(p) if float(p).is_integer() else float(p)) for p in part["p_s"]]
        else:
            block["k"] = part["k"].astype(int)
        blocks[approach] = block
    table = pd.concat(blocks, axis=1)
    if target is not None:
        table = pd.concat({target: table}, names=["target"])
    elif not index_cols:
        table.index = pd.Index(["all"], name="movements")
    return table


def best_per_movement(results: pd.DataFrame, *, target=None) -> pd.DataFrame:
    """Table 2 layout: the best setting of each movement, per approach.

    Parameters
    ----------
    results : DataFrame
        From :func:`search` (per user; users are averaged here) for one target.
    target : optional
        Label (e.g. ``"Target 1"``) added as an outer index level, for ``pd.concat``.

    Returns
    -------
    pandas.DataFrame
        Index ``movement`` (or ``(target, movement)``); columns ``(approach, field)`` with the
        paper's fields: deterministic "PE [cm]", "N", "anchors subset", "distance", "k",
        "p_s" ("—" for k = 1); probabilistic "PE [cm]", "N", "anchors subset", "k".
    """
    return _paper_layout(select_settings(results, per_movement=True), ["movement"], target)


def best_global(results: pd.DataFrame, *, target=None) -> pd.DataFrame:
    """Table 3 layout: one setting per approach minimising the mean PE over all movements.

    One row (index ``"all"``, or ``target`` if given); columns as :func:`best_per_movement`.
    """
    table = _paper_layout(select_settings(results, per_movement=False), [], target)
    if target is not None:
        table.index = pd.Index([target], name="target")
    return table


def union_of_subsets(*selections, approach: str = "deterministic") -> tuple[int, ...]:
    """Section 5's deployable configuration: the smallest anchor set containing every chosen subset.

    Parameters
    ----------
    *selections : DataFrame or iterable of subsets
        Tables from :func:`best_per_movement` / :func:`best_global` (paper layout), tidy
        selections from :func:`select_settings`, or plain subsets ("{1, 5}", (1, 5), masks) —
        typically one per target.
    approach : {"deterministic", "probabilistic"}
        Which approach's subsets to take from tables.

    Returns
    -------
    tuple of int
        Sorted 1-based anchor numbers (format with :func:`format_subset`), e.g. Table 3's
        deterministic {3, 5, 6, 7} ∪ {2, 3, 6} = (2, 3, 5, 6, 7).
    """
    approach = _check_approach(approach)
    if not selections:
        raise ValueError("give at least one table or subset")
    union: set[int] = set()
    for sel in selections:
        if isinstance(sel, pd.DataFrame):
            if isinstance(sel.columns, pd.MultiIndex):
                if (approach, "anchors subset") not in sel.columns:
                    raise ValueError(f"table has no {approach!r} anchors subset column")
                subsets = sel[(approach, "anchors subset")]
            elif "anchors" in sel.columns and "approach" in sel.columns:
                subsets = sel.loc[sel["approach"] == approach, "anchors"]
            else:
                raise ValueError("a DataFrame must be a paper-layout table or a select_settings() selection")
            if len(subsets) == 0:
                raise ValueError(f"table holds no {approach!r} setting")
            for s in subsets:
                union.update(parse_subset(s))
        elif isinstance(sel, str | np.ndarray) or not isinstance(sel, Iterable):
            union.update(parse_subset(sel))
        else:
            items = list(sel)
            if items and all(isinstance(i, numbers.Integral) and not isinstance(i, bool) for i in items):
                union.update(parse_subset(items))
            else:
                for s in items:
                    union.update(parse_subset(s))
    return tuple(sorted(union))


# --------------------------------------------------------------------------------------
# T1 → T2 coupling and the whole of Tables 2 and 3
# --------------------------------------------------------------------------------------


@dataclasses.dataclass
class PaperTables:
    """Everything behind Tables 2 and 3 (see :func:`paper_tables`).

    Attributes
    ----------
    target1 : DataFrame
        :func:`search` results of target 1 (per user).
    target2_per_movement : DataFrame
        Target 2 with, for each movement, the elbow of target 1's best setting for that
        movement (same approach) — what Table 2 selects from.
    target2_global : DataFrame
        Target 2 with the elbow of target 1's global setting — what Table 3 selects from.
    selection2, selection3 : DataFrame
        Tidy selections (:func:`select_settings`) with a ``target`` column (1, 2).
    table2, table3 : DataFrame
        Paper layouts, index ``(target, movement)`` / ``target`` ("Target 1", "Target 2").
    deployable : DataFrame
        Index approach, columns "Table 2", "Table 3": :func:`union_of_subsets` over both
        targets (and all movements), formatted "{…}".
    """

    target1: pd.DataFrame
    target2_per_movement: pd.DataFrame
    target2_global: pd.DataFrame
    selection2: pd.DataFrame
    selection3: pd.DataFrame
    table2: pd.DataFrame
    table3: pd.DataFrame
    deployable: pd.DataFrame


def paper_tables(target1, target2, *, approaches=APPROACHES, estimate: str = "hybrid", grid: SearchGrid | None = None,
                 progress: bool = False, chunk_elements: int = DEFAULT_CHUNK_ELEMENTS) -> PaperTables:
    """Tables 2 and 3: search target 1, derive the elbows, search target 2 (see the module docstring).

    Parameters
    ----------
    target1, target2 : sequence or mapping of SearchData
        Per user, the same users in the same order/keys; ``target2``'s ``proximal`` is
        ignored (replaced by the elbows from target 1), its ``segment`` should be 1.
    approaches, estimate, grid, progress, chunk_elements
        As in :func:`search`.
    """
    approaches = _check_choices(approaches, APPROACHES, "approaches")
    estimate = _check_estimate(estimate)
    grid = SearchGrid() if grid is None else grid
    labels1, users1, users2 = _paired_users(target1, target2, approaches)

    prox1 = [{a: u.proximal[None] for a in approaches} for u in users1]
    res1 = _search(labels1, users1, approaches, estimate, grid, prox1, progress, chunk_elements)[0]
    sel1_mov = select_settings(res1, per_movement=True)
    sel1_glob = select_settings(res1, per_movement=False)

    if estimate == "radio":
        prox2 = [{a: u.proximal[None] for a in approaches} for u in users2]
        res2 = _search(labels1, users2, approaches, estimate, grid, prox2, progress, chunk_elements)[0]
        res2_mov = res2_glob = res2
    else:
        prox2 = [{a: np.stack([proximal_from_selection(u1, sel1_mov, approach=a),
                               proximal_from_selection(u1, sel1_glob, approach=a)]) for a in approaches}
                 for u1 in users1]  # fmt: skip
        res2_mov, res2_glob = _search(labels1, users2, approaches, estimate, grid, prox2, progress, chunk_elements)
    sel2_mov = select_settings(res2_mov, per_movement=True)
    sel2_glob = select_settings(res2_glob, per_movement=False)

    selection2 = pd.concat([sel1_mov.assign(target=1), sel2_mov.assign(target=2)], ignore_index=True)
    selection3 = pd.concat([sel1_glob.assign(target=1), sel2_glob.assign(target=2)], ignore_index=True)
    table2 = pd.concat([_paper_layout(sel1_mov, ["movement"], "Target 1"),
                        _paper_layout(sel2_mov, ["movement"], "Target 2")])
    table3 = pd.concat([best_global(res1, target="Target 1"), best_global(res2_glob, target="Target 2")])
    deployable = pd.DataFrame(
        {name: {a: format_subset(union_of_subsets(sel, approach=a)) for a in approaches}
         for name, sel in (("Table 2", selection2), ("Table 3", selection3))})
    deployable.index.name = "approach"
    return PaperTables(res1, res2_mov, res2_glob, selection2, selection3, table2, table3, deployable)
