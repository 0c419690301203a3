"""Exhaustive parameter search of paper 002's Tables 2 and 3 (Section 5), vectorised.

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition".  The paper picks, for each target node, the fingerprinting parameters that
minimise the position error PE (eq. (11)) of its *hybrid* estimate — radio heading
(eq. (8)) + accelerometer pitch, device at its offset along the segment (eq. (9)) — averaged
over five users: per movement (Table 2, a best case) and one setting for all movements
(Table 3).  This package evaluates every setting of the grid at once.

Modules, in the order they build on each other:

* :mod:`.data` — the data model: :class:`SearchGrid` (what is searched, the paper's grid by
  default), :class:`Setting` (one grid point), :class:`SearchData` (one user's online phase
  for one target, with its estimators), :func:`format_subset` / :func:`parse_subset`;
* :mod:`.engine` — the error engine: :func:`search`, the PE (eq. (11)) of every
  (subset, distance, k, p_s) with the hybrid correction of eqs. (8)–(9), vectorised over
  subset chunks; :func:`evaluate_setting`, the per-sample view of one setting;
* :mod:`.selection` — users averaging, per-movement (Table 2) and global (Table 3)
  selection with its tie-break (:data:`TIE_TOL_CM`), the elbow of eq. (10) under a
  selection (:func:`proximal_from_selection`) and both targets along the chain, target 2
  from target 1's estimated elbow (:func:`evaluate_chain`);
* :mod:`.tables` — the paper's Table 2/3 layout, the deployable anchor set
  (:func:`union_of_subsets`) and :func:`paper_tables`, which searches target 1, derives
  the elbows and searches target 2 (the T1 → T2 coupling);
* :mod:`.regret` — beyond the paper: how optimistic the in-sample tables are
  (:func:`selection_regret`, :func:`coupled_selection_regret`).

Everything public is importable from ``wsnlib.optimize`` directly.

Anchors are numbered from 1 in tables and ``anchors`` tuples, as in the paper ("{1, 5, 6}");
boolean masks and column indices are 0-based.
"""

from wsnlib.optimize.data import APPROACHES, ESTIMATES, SearchData, SearchGrid, Setting, format_subset, parse_subset
from wsnlib.optimize.engine import DEFAULT_CHUNK_ELEMENTS, evaluate_setting, search
from wsnlib.optimize.regret import REGRET_COLUMNS, SPLITS, coupled_selection_regret, selection_regret
from wsnlib.optimize.selection import (
    TIE_TOL_CM,
    average_over_users,
    evaluate_chain,
    evaluate_selection,
    proximal_from_selection,
    select_settings,
)
from wsnlib.optimize.tables import PaperTables, best_global, best_per_movement, paper_tables, union_of_subsets

__all__ = ["APPROACHES", "DEFAULT_CHUNK_ELEMENTS", "ESTIMATES", "REGRET_COLUMNS", "SPLITS", "TIE_TOL_CM", "PaperTables",
           "SearchData", "SearchGrid", "Setting", "average_over_users", "best_global", "best_per_movement",
           "coupled_selection_regret", "evaluate_chain", "evaluate_selection", "evaluate_setting", "format_subset",
           "paper_tables", "parse_subset", "proximal_from_selection", "search", "select_settings", "selection_regret",
           "union_of_subsets"]
