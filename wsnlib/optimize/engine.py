"""The error engine of paper 002's search: PE of every (subset, k, p_s) at once, vectorised.

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition", Section 5.  :func:`search` gives the position error PE (eq. (11), cm) of every
setting of a :class:`~wsnlib.optimize.data.SearchGrid`, per user and movement, for one
target; :func:`evaluate_setting` the per-sample view of one setting.

What is searched (defaults = the paper's grid)
----------------------------------------------
* deterministic kNN (eqs. (1)–(2)): every non-empty anchor subset (127 for 7 anchors) ×
  distance {Euclidean, Manhattan} × ``k`` ∈ 1..5 × Shepard exponent ``p_s`` ∈ 1..6.  With
  ``k = 1`` the estimate is the nearest fingerprint position whatever ``p_s`` (Section 3.1),
  so ``k = 1`` is evaluated once per (subset, distance) and reported with ``p_s`` missing
  (``<NA>`` in the results, "—" in the tables): 127 × 2 × (1 + 4 × 6) = 6,350 settings;
* probabilistic p-kNN (eqs. (3)–(4)): subset × ``k`` ∈ 1..5: 635 settings.

How (no fit per setting)
------------------------
Per user and target the estimators are fitted once
(:meth:`~wsnlib.optimize.data.SearchData.fitted`); the per-anchor distance terms
(:meth:`~wsnlib.radio.KNNFingerprint.anchor_terms`, one array per distance) and
log-likelihoods (:meth:`~wsnlib.radio.ProbabilisticKNN.anchor_log_likelihoods`) are
computed once; :func:`~wsnlib.radio.grid.knn_grid_from_terms` /
:func:`~wsnlib.radio.grid.pknn_grid_from_loglik` turn them into the radio estimates of every
(subset, k, p_s) of a chunk of subsets; the hybrid correction and the PE of all those
estimates follow as array operations, and the PE is averaged per movement with one matrix
product.  Subsets are processed in chunks so that no array exceeds about ``chunk_elements``
numbers.

The hybrid correction
---------------------
Exactly :func:`wsnlib.posture.recursive_chain` for one segment, applied to each movement
separately: heading ψ of the radio estimate ``D̂`` about the proximal joint ``A`` (eq. (8)),
``D̄ = A + d′ (cos θ cos ψ, cos θ sin ψ, sin θ)`` (eq. (9)) with the accelerometer pitch θ.
Where ψ is undefined (``D̂`` straight above or below ``A``, which happens whenever a ``k = 1``
estimate is Table 1's P1 or P2 for target 1) the heading of the latest earlier sample *of the
same movement* is held, or ψ = 0 at the movement's start — :func:`~wsnlib.posture.recursive_chain`
run on each movement.  Rows of one movement must therefore be contiguous and in time order.
``estimate="radio"`` scores the radio estimate itself (no pitch, no chain) for comparison.

PE of a (user, movement, setting) is eq. (11): the mean over the movement's samples of the
Euclidean error, reported in **centimetres** (``pe_cm``; inputs are metres) as in the
paper's tables.  :func:`search` keeps one row per user (leave-one-user-out needs them).

Settings are numbered (``config``) in this order: subset size (fewest anchors first), subsets
of one size lexicographically by anchor number, distance in ``grid.metrics`` order (Euclidean
first), ``k`` ascending, ``p_s`` ascending (``k = 1``, without ``p_s``, first) — the tie-break
order of :mod:`wsnlib.optimize.selection`.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from wsnlib._validation import check_type
from wsnlib.optimize.data import (
    APPROACHES,
    SearchData,
    SearchGrid,
    Setting,
    _as_users,
    _check_choices,
    _check_estimate,
    format_subset,
)
from wsnlib.posture import DEFAULT_HEADING_TOL_M
from wsnlib.radio.grid import knn_from_terms, knn_grid_from_terms, pknn_from_loglik, pknn_grid_from_loglik

#: Default bound on the numbers held by one array of a subset chunk.
DEFAULT_CHUNK_ELEMENTS = 1 << 18  # ~2 MB per float array: stays in cache


# --------------------------------------------------------------------------------------
# Vectorised hybrid correction and PE
# --------------------------------------------------------------------------------------


def _run_starts(movement: np.ndarray) -> np.ndarray:
    """Index of the first row of each row's run of equal movement labels, shape (n,)."""
    n = movement.size
    start = np.ones(n, dtype=bool)
    start[1:] = movement[1:] != movement[:-1]
    return np.maximum.accumulate(np.where(start, np.arange(n), 0))


def _unit_heading(rx: np.ndarray, ry: np.ndarray, proximal: np.ndarray, run_start: np.ndarray):
    """Unit horizontal direction ``(cos ψ, sin ψ)`` of eq. (8), each ``(c, n)``.

    ``rx``, ``ry`` are the radio estimates' x and y ``(c, n)``; undefined headings are held
    within the movement (or ψ = 0 at its start).
    """
    ux = rx - proximal[:, 0]
    uy = ry - proximal[:, 1]
    h = ux * ux
    h += uy * uy
    np.sqrt(h, out=h)
    defined = h > DEFAULT_HEADING_TOL_M
    with np.errstate(invalid="ignore", divide="ignore"):  # undefined rows are replaced below
        np.divide(1.0, h, out=h)
        ux *= h
        uy *= h
    if not defined.all():
        rows = np.flatnonzero(~defined.all(axis=-1))
        n = defined.shape[-1]
        idx = np.where(defined[rows], np.arange(n), -1)
        np.maximum.accumulate(idx, axis=-1, out=idx)
        ok = idx >= run_start
        src = np.maximum(idx, 0)
        ux[rows] = np.where(ok, np.take_along_axis(ux[rows], src, axis=-1), 1.0)
        uy[rows] = np.where(ok, np.take_along_axis(uy[rows], src, axis=-1), 0.0)
    return ux, uy


class _Context:
    """Per-user arrays of the PE computation (built once per user and target)."""

    def __init__(self, data: SearchData, estimate: str, proximals: np.ndarray):
        self.estimate = estimate
        self.true = data.true_positions
        self.run_start = _run_starts(data.movement)
        self.movements, inverse = np.unique(data.movement, return_inverse=True)
        self.rows = [np.flatnonzero(inverse == m) for m in range(self.movements.size)]
        self.counts = np.bincount(inverse)
        self.proximals = proximals                                          # (V, n, 3)
        offset = data.device_offset_m
        self.b = offset * np.cos(data.pitch)                                # horizontal reach d′ cos θ
        a = proximals - self.true                                           # A − T
        a[..., 2] += offset * np.sin(data.pitch)
        self.ax, self.ay, self.az2 = a[..., 0], a[..., 1], a[..., 2] ** 2

    @property
    def n_variants(self) -> int:
        return 1 if self.estimate == "radio" else self.proximals.shape[0]

    def movement_pe(self, radio: np.ndarray) -> np.ndarray:
        """Mean PE (m) per movement of radio estimates ``(3, c, n)`` (coordinate first): ``(V, c, M)``."""
        if self.estimate == "radio":
            pe = np.zeros(radio.shape[1:])
            for d in range(3):
                err = radio[d] - self.true[:, d]
                err *= err
                pe += err
            np.sqrt(pe, out=pe)
            return self._movement_mean(pe)[None]
        out = np.empty((self.n_variants, radio.shape[1], self.movements.size))
        for v in range(self.n_variants):
            ux, uy = _unit_heading(radio[0], radio[1], self.proximals[v], self.run_start)
            ex = ux
            ex *= self.b
            ex += self.ax[v]                                               # D̄ − T, eq. (9)
            ey = uy
            ey *= self.b
            ey += self.ay[v]
            ex *= ex
            ey *= ey
            ex += ey
            ex += self.az2[v]
            np.sqrt(ex, out=ex)                                            # eq. (11) per sample
            out[v] = self._movement_mean(ex)
        return out

    def _movement_mean(self, pe: np.ndarray) -> np.ndarray:
        """Mean over each movement's rows of ``pe`` (c, n): ``(c, M)``, in a fixed order of additions.

        Each movement's values are gathered into a contiguous block and summed along it, so
        the order of additions (numpy's pairwise tree over that block) depends only on the
        movement's number of rows: not on how many settings a chunk holds, nor on the BLAS
        kernel a matrix product would pick for the chunk's shape and the CPU.
        """
        out = np.empty((pe.shape[0], self.movements.size))
        for m, rows in enumerate(self.rows):
            out[:, m] = np.ascontiguousarray(pe[:, rows]).sum(axis=-1) / rows.size
        return out


def _hybrid_positions(radio: np.ndarray, data: SearchData, proximal: np.ndarray) -> dict[str, np.ndarray]:
    """Eqs. (8)–(10) for one setting: devices and distal joints ``(n, 3)``."""
    ux, uy = _unit_heading(radio[None, :, 0], radio[None, :, 1], proximal, _run_starts(data.movement))
    cos_pitch = np.cos(data.pitch)
    direction = np.stack([cos_pitch * ux[0], cos_pitch * uy[0], np.sin(data.pitch)], axis=-1)
    return {"devices": proximal + data.device_offset_m * direction,
            "joints": proximal + data.segment_length_m * direction}  # fmt: skip


# --------------------------------------------------------------------------------------
# The search
# --------------------------------------------------------------------------------------


def _settings_table(grid: SearchGrid, masks: np.ndarray, approach: str) -> pd.DataFrame:
    """One row per setting of ``approach``, index = config number (tie-break order)."""
    anchors = [tuple(int(i) + 1 for i in np.flatnonzero(m)) for m in masks]
    rows = []
    if approach == "deterministic":
        for a in anchors:
            for metric in grid.metrics:
                rows += [(a, metric, k, p) for k, p in grid.knn_configs()]
    else:
        for a in anchors:
            rows += [(a, None, k, None) for k in grid.pknn_neighbors]
    table = pd.DataFrame(rows, columns=["anchors", "metric", "k", "p_s"])
    table.insert(0, "subset", [format_subset(a) for a in table["anchors"]])
    table.insert(2, "n_anchors", [len(a) for a in table["anchors"]])
    table["p_s"] = pd.array([pd.NA if p is None else p for p in table["p_s"]],
                            dtype="Int64" if all(float(p).is_integer() for p in grid.powers) else "Float64")
    table.index.name = "config"
    return table


def _chunk_size(grid: SearchGrid, approach: str, n_vectors: int, chunk_elements: int) -> int:
    """Subsets per chunk: estimates per subset in the largest array of a chunk (kNN: K · P of
    knn_grid_from_terms; p-kNN: K) × ``n_vectors`` × 3 coordinates stay within ``chunk_elements``."""
    per = len(grid.knn_neighbors) * len(grid.powers) if approach == "deterministic" else len(grid.pknn_neighbors)
    return max(1, int(chunk_elements) // max(1, per * n_vectors * 3))


def _user_pe(data: SearchData, approach: str, grid: SearchGrid, masks: np.ndarray, ctx: _Context,
             chunk_elements: int, bar) -> np.ndarray:
    """Mean PE (m) per (variant, setting, movement) of one user: ``(V, C, M)``."""
    n = data.online_rss.shape[0]
    if approach == "deterministic":
        est = data.knn
        knn_cfg = grid.knn_configs()
        # (k index, p index) of each unique setting per (subset, metric): k = 1 once, at p index 0
        k_idx = np.array([grid.knn_neighbors.index(k) for k, _ in knn_cfg])
        p_idx = np.array([0 if p is None else grid.powers.index(p) for _, p in knn_cfg])
        terms = {m: copy.copy(est).set_params(metric=m).anchor_terms(data.online_rss) for m in grid.metrics}
        n_metrics, per = len(grid.metrics), len(knn_cfg)

        def estimates(chunk):  # radio estimates (3, s·per, n) of a chunk of subsets, per metric
            for metric in grid.metrics:
                grid_est = knn_grid_from_terms(terms[metric], masks[chunk], est.positions_, grid.knn_neighbors,
                                               grid.powers, metric, coordinates_first=True)  # (3, s, K, P, n)
                yield grid_est[:, :, k_idx, p_idx].reshape(3, -1, n)
    else:
        est = data.pknn
        loglik = est.anchor_log_likelihoods(data.online_rss)
        n_metrics, per = 1, len(grid.pknn_neighbors)

        def estimates(chunk):
            yield pknn_grid_from_loglik(loglik, masks[chunk], est.positions_, grid.pknn_neighbors,
                                        coordinates_first=True).reshape(3, -1, n)            # (3, s, K, n)
    out = np.empty((ctx.n_variants, masks.shape[0] * n_metrics * per, ctx.movements.size))
    step = _chunk_size(grid, approach, n, chunk_elements)
    for start in range(0, masks.shape[0], step):
        chunk = np.arange(start, min(start + step, masks.shape[0]))
        for mi, radio in enumerate(estimates(chunk)):
            ids = ((chunk[:, None] * n_metrics + mi) * per + np.arange(per)).ravel()
            out[:, ids] = ctx.movement_pe(radio)
        bar.update(1)
    return out


def _check_fitted_positions(users: list[SearchData], approach: str, grid: SearchGrid) -> None:
    for u in users:
        est = u.knn if approach == "deterministic" else u.pknn
        n_fp = est.positions_.shape[0]
        ks = grid.knn_neighbors if approach == "deterministic" else grid.pknn_neighbors
        if max(ks) > n_fp:
            raise ValueError(f"the grid's k goes up to {max(ks)} but there are only {n_fp} fingerprint positions")
        if est.positions_.shape[1] != 3:
            raise ValueError(f"fingerprint positions must be 3-D (x, y, z), got {est.positions_.shape[1]} coordinates")


def _search(labels, users, approaches, estimate, grid, proximals, progress, chunk_elements) -> list[pd.DataFrame]:
    """Per-user results for each proximal variant: list (V) of long DataFrames."""
    n_anchors = users[0].n_anchors
    masks = grid.subset_masks(n_anchors)
    n_variants = 1 if estimate == "radio" else proximals[0][approaches[0]].shape[0]
    total = sum(-(-masks.shape[0] // _chunk_size(grid, a, u.online_rss.shape[0], chunk_elements))
                for u in users for a in approaches)
    frames: list[list[pd.DataFrame]] = [[] for _ in range(n_variants)]
    with tqdm(total=total, desc="subset chunks", unit="chunk", disable=not progress) as bar:
        for approach in approaches:
            _check_fitted_positions(users, approach, grid)
            settings = _settings_table(grid, masks, approach)
            for label, data, prox in zip(labels, users, proximals, strict=True):
                ctx = _Context(data, estimate, prox[approach])
                pe = _user_pe(data, approach, grid, masks, ctx, chunk_elements, bar)      # (V, C, M) m
                n_set, n_mov = pe.shape[1], pe.shape[2]
                for v in range(n_variants):
                    frame = settings.iloc[np.repeat(np.arange(n_set), n_mov)].reset_index()
                    frame.insert(0, "approach", approach)
                    frame.insert(1, "estimate", estimate)
                    frame["user"] = label
                    frame["movement"] = np.tile(ctx.movements, n_set)
                    frame["pe_cm"] = 100.0 * pe[v].ravel()
                    frame["n_samples"] = np.tile(ctx.counts, n_set)
                    frames[v].append(frame)
    return [pd.concat(f, ignore_index=True) for f in frames]


def search(data, *, approaches=APPROACHES, estimate: str = "hybrid", grid: SearchGrid | None = None,
           progress: bool = False, chunk_elements: int = DEFAULT_CHUNK_ELEMENTS) -> pd.DataFrame:
    """PE of every setting of the grid, per user and movement (one target).

    Parameters
    ----------
    data : SearchData, or a sequence (users 1, 2, …) or mapping (label → data) of them
        One entry per user, all for the same target.  Estimators are fitted here if needed
        (once per user; call :meth:`SearchData.fitted` first to reuse fits across calls).
    approaches : str or sequence of {"deterministic", "probabilistic"}
    estimate : {"hybrid", "radio"}
        Score the hybrid estimate of eqs. (8)–(9) (default) or the radio estimate itself.
    grid : SearchGrid, optional
        Default: the paper's grid.
    progress : bool
        Show a tqdm bar over the subset chunks.
    chunk_elements : int
        Bound on the numbers in one chunk's estimate array (memory).

    Returns
    -------
    pandas.DataFrame
        One row per (approach, setting, user, movement): ``approach``, ``estimate``,
        ``config`` (setting number within the approach, the tie-break order), ``subset``
        ("{1, 5, 6}"), ``anchors`` (tuple of 1-based anchor numbers), ``n_anchors`` (N),
        ``metric`` (None for p-kNN), ``k``, ``p_s`` (nullable; <NA> for ``k = 1`` and p-kNN),
        ``user``, ``movement``, ``pe_cm`` (eq. (11), **cm**), ``n_samples`` (rows averaged).
    """
    approaches = _check_choices(approaches, APPROACHES, "approaches")
    estimate = _check_estimate(estimate)
    grid = check_type(SearchGrid() if grid is None else grid, SearchGrid, "grid")
    labels, users = _as_users(data)
    users = [u.fitted(approaches) for u in users]
    proximals = [{a: u.proximal[None] for a in approaches} for u in users]
    return _search(labels, users, approaches, estimate, grid, proximals, progress, chunk_elements)[0]


def evaluate_setting(data: SearchData, setting: Setting, *, estimate: str = "hybrid") -> dict[str, np.ndarray]:
    """Estimates and errors of one setting for one user (the per-sample view of a table row).

    Returns
    -------
    dict
        ``"radio"`` (n, 3) radio estimate (m); ``"devices"`` (n, 3) scored estimate (the
        hybrid ``D̄`` of eq. (9), or the radio estimate with ``estimate="radio"``);
        ``"joints"`` (n, 3) distal joint of eq. (10) (hybrid only, else NaN); ``"pe_m"`` (n,)
        the Euclidean error per sample (m) — its mean per movement is the table's PE.
    """
    check_type(setting, Setting, "setting")
    check_type(data, SearchData, "data")
    estimate = _check_estimate(estimate)
    data = data.fitted(setting.approach)
    mask = setting.mask(data.n_anchors)
    if setting.approach == "deterministic":
        est = copy.copy(data.knn).set_params(metric=setting.metric)
        radio = knn_from_terms(est.anchor_terms(data.online_rss), mask, est.positions_, setting.k,
                               1 if setting.p_s is None else setting.p_s, setting.metric)
    else:
        est = data.pknn
        radio = pknn_from_loglik(est.anchor_log_likelihoods(data.online_rss), mask, est.positions_, setting.k)
    if estimate == "radio":
        devices, joints = radio, np.full_like(radio, np.nan)
    else:
        hybrid = _hybrid_positions(radio, data, data.proximal)
        devices, joints = hybrid["devices"], hybrid["joints"]
    return {"radio": radio, "devices": devices, "joints": joints,
            "pe_m": np.linalg.norm(devices - data.true_positions, axis=-1)}  # fmt: skip
