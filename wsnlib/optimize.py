"""Exhaustive parameter search of paper 002's Tables 2 and 3 (Section 5), vectorised.

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition".  The paper picks, for each target node, the fingerprinting parameters that
minimise the position error PE (eq. (11)) of its *hybrid* estimate — radio heading
(eq. (8)) + accelerometer pitch, device at its offset along the segment (eq. (9)) — averaged
over five users: per movement (Table 2, a best case) and one setting for all movements
(Table 3).  This module evaluates every setting of the grid at once.

What is searched (:class:`SearchGrid`, defaults = the paper's grid)
--------------------------------------------------------------------
* deterministic kNN (eqs. (1)–(2)): every non-empty anchor subset (127 for 7 anchors) ×
  distance {Euclidean, Manhattan} × ``k`` ∈ 1..5 × Shepard exponent ``p_s`` ∈ 1..6.  With
  ``k = 1`` the estimate is the nearest fingerprint position whatever ``p_s`` (Section 3.1),
  so ``k = 1`` is evaluated once per (subset, distance) and reported with ``p_s`` missing
  (``<NA>`` in the results, "—" in the tables): 127 × 2 × (1 + 4 × 6) = 6,350 settings;
* probabilistic p-kNN (eqs. (3)–(4)): subset × ``k`` ∈ 1..5: 635 settings.

How (no fit per setting)
------------------------
Per user and target the estimators are fitted once (:meth:`SearchData.fitted`); the
per-anchor distance terms (:meth:`~wsnlib.fingerprint.KNNFingerprint.anchor_terms`, one
array per distance) and log-likelihoods
(:meth:`~wsnlib.fingerprint.ProbabilisticKNN.anchor_log_likelihoods`) are computed once;
:func:`~wsnlib.fingerprint.knn_grid_from_terms` / :func:`~wsnlib.fingerprint.pknn_grid_from_loglik`
turn them into the radio estimates of every (subset, k, p_s) of a chunk of subsets; the
hybrid correction and the PE of all those estimates follow as array operations, and the PE
is averaged per movement with one matrix product.  Subsets are processed in chunks so that
no array exceeds about ``chunk_elements`` numbers.

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

Target 2 depends on target 1 (the coupling)
-------------------------------------------
Target 2's proximal joint is the elbow *as estimated from target 1* (eq. (10)), so its PE
depends on which target-1 setting is used.  :func:`paper_tables` therefore searches target 1
first, selects its settings, computes each user's elbow with them
(:func:`proximal_from_selection`) and only then searches target 2:

* Table 2 (per movement): the rows of movement m use the elbow of target 1's best setting
  *for movement m*;
* Table 3 (global): all rows use the elbow of target 1's single global setting;
* each approach uses its own target-1 setting (deterministic target 2 rides on the
  deterministic elbow, probabilistic on the probabilistic one);
* with ``estimate="radio"`` target 2 does not use the elbow, and there is one search.

So target 2 is optimised *given* target 1's choice (sequential, as the recursive process of
Section 3.3 runs), not jointly over both targets' settings; the joint optimum could only be
lower.  The paper does not say how it handled this.

Averaging, selection and ties
-----------------------------
PE of a (user, movement, setting) is eq. (11): the mean over the movement's samples of the
Euclidean error, reported in **centimetres** (``pe_cm``; inputs are metres) as in the
paper's tables.  The users' PEs are then averaged with equal weight per user (the users
that have the movement), and the parameters minimise that average (Section 5: "chosen as
the ones which jointly maximize the average performance of all the users").  Global
(Table 3) selection minimises the mean over movements of the users' average, each movement
weighted equally — the paper's "average PE" rows are such plain means of table rows.
:func:`search` keeps one row per user (leave-one-user-out needs them);
:func:`average_over_users` gives the users-average table the selections work on.

Ties: settings whose PE is within :data:`TIE_TOL_CM` of the minimum are equal, and the one
with the lowest ``config`` number wins.  Settings are numbered in this order: subset size
(fewest anchors first), subsets of one size lexicographically by anchor number, distance
in ``grid.metrics`` order (Euclidean first), ``k`` ascending, ``p_s`` ascending (``k = 1``,
without ``p_s``, first).  So among equally good settings the one with the fewest anchors
and the simplest parameters is reported; a superset of an optimal subset that does equally
well is never chosen over it.

Anchors are numbered from 1 in tables and ``anchors`` tuples, as in the paper ("{1, 5, 6}");
boolean masks and column indices are 0-based.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import numbers
from collections.abc import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd
from sklearn.base import clone
from sklearn.utils.validation import check_is_fitted
from tqdm.auto import tqdm

from wsnlib._validation import as_float_array
from wsnlib.fingerprint import (
    METRICS,
    KNNFingerprint,
    ProbabilisticKNN,
    anchor_subsets,
    knn_from_terms,
    knn_grid_from_terms,
    pknn_from_loglik,
    pknn_grid_from_loglik,
)
from wsnlib.posture import DEFAULT_HEADING_TOL_M, ArmChain

APPROACHES = ("deterministic", "probabilistic")
ESTIMATES = ("hybrid", "radio")

#: PEs (cm) within this of the minimum count as ties (broken by the lowest ``config``).
TIE_TOL_CM = 1e-9

#: Default bound on the numbers held by one array of a subset chunk.
DEFAULT_CHUNK_ELEMENTS = 1 << 18  # ~2 MB per float array: stays in cache

_DISTANCE_LABELS = {"euclidean": "Euclidean", "manhattan": "Manhattan"}
_SETTING_COLUMNS = ["config", "subset", "anchors", "n_anchors", "metric", "k", "p_s"]


# --------------------------------------------------------------------------------------
# Parameters, settings and data
# --------------------------------------------------------------------------------------


def _int_tuple(values, name: str, *, positive: bool = True) -> tuple[int, ...]:
    values = tuple(np.atleast_1d(np.asarray(values, dtype=object)).tolist())
    if not values:
        raise ValueError(f"{name} must hold at least one value (empty grid)")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) or (positive and v < 1):
            raise ValueError(f"{name} must hold positive integers, got {v!r}")
    if len(set(values)) != len(values):
        raise ValueError(f"{name} holds duplicate values: {list(values)}")
    return tuple(sorted(int(v) for v in values))


@dataclasses.dataclass(frozen=True)
class SearchGrid:
    """The settings searched; defaults are the paper's grid (Section 5).

    Parameters
    ----------
    subsets : None or array_like of bool, shape (S, A)
        Anchor subsets as boolean masks; None = all ``2**A − 1`` non-empty subsets
        (:func:`wsnlib.fingerprint.anchor_subsets`, fewest anchors first).  Given masks are
        reordered into that order (size, then lexicographic), which the tie-break relies on.
    metrics : sequence of {"euclidean", "manhattan"}
        kNN distances, in tie-break order.
    knn_neighbors : sequence of int
        ``k`` of the deterministic kNN.
    powers : sequence of int or float
        Shepard exponents ``p_s`` (> 0), used for ``k > 1``.
    pknn_neighbors : sequence of int
        ``k`` of the p-kNN.
    """

    subsets: np.ndarray | None = None
    metrics: tuple[str, ...] = METRICS
    knn_neighbors: tuple[int, ...] = (1, 2, 3, 4, 5)
    powers: tuple[float, ...] = (1, 2, 3, 4, 5, 6)
    pknn_neighbors: tuple[int, ...] = (1, 2, 3, 4, 5)

    def __post_init__(self):
        metrics = tuple(np.atleast_1d(np.asarray(self.metrics, dtype=object)).tolist())
        if not metrics:
            raise ValueError("metrics must hold at least one distance (empty grid)")
        for m in metrics:
            if m not in METRICS:
                raise ValueError(f"metrics must be among {METRICS}, got {m!r}")
        if len(set(metrics)) != len(metrics):
            raise ValueError(f"metrics holds duplicates: {list(metrics)}")
        powers = tuple(np.atleast_1d(np.asarray(self.powers, dtype=object)).tolist())
        if not powers:
            raise ValueError("powers must hold at least one value (empty grid)")
        for p in powers:
            if isinstance(p, bool) or not isinstance(p, numbers.Real) or not math.isfinite(p) or p <= 0:
                raise ValueError(f"powers must hold positive finite numbers, got {p!r}")
        if len(set(powers)) != len(powers):
            raise ValueError(f"powers holds duplicate values: {list(powers)}")
        object.__setattr__(self, "metrics", metrics)
        object.__setattr__(self, "powers", tuple(sorted(powers)))
        object.__setattr__(self, "knn_neighbors", _int_tuple(self.knn_neighbors, "knn_neighbors"))
        object.__setattr__(self, "pknn_neighbors", _int_tuple(self.pknn_neighbors, "pknn_neighbors"))
        if self.subsets is not None:
            masks = np.asarray(self.subsets)
            if masks.dtype != np.bool_ or masks.ndim != 2 or masks.shape[0] == 0 or masks.shape[1] == 0:
                raise ValueError(f"subsets must be a non-empty boolean array (n_subsets, n_anchors), got "
                                 f"dtype {masks.dtype}, shape {masks.shape}")
            if not np.all(masks.any(axis=1)):
                raise ValueError(f"subsets row {int(np.argmin(masks.any(axis=1)))} selects no anchor")
            if np.unique(masks, axis=0).shape[0] != masks.shape[0]:
                raise ValueError("subsets holds duplicate rows")
            order = sorted(range(masks.shape[0]), key=lambda i: (int(masks[i].sum()), tuple(np.flatnonzero(masks[i]))))
            masks = masks[order].copy()
            masks.setflags(write=False)
            object.__setattr__(self, "subsets", masks)

    def subset_masks(self, n_anchors: int) -> np.ndarray:
        """Boolean masks ``(S, n_anchors)`` of the subsets searched, in tie-break order."""
        if self.subsets is None:
            return anchor_subsets(n_anchors)
        if self.subsets.shape[1] != n_anchors:
            raise ValueError(f"grid.subsets has {self.subsets.shape[1]} anchors, the data {n_anchors}")
        return self.subsets

    def knn_configs(self) -> list[tuple[int, int | float | None]]:
        """``(k, p_s)`` per (subset, distance), in order; ``p_s`` is None for ``k = 1``."""
        out = []
        for k in self.knn_neighbors:
            out += [(k, None)] if k == 1 else [(k, p) for p in self.powers]
        return out

    def n_settings(self, n_anchors: int, approach: str) -> int:
        """Number of settings of one approach for ``n_anchors`` anchors."""
        n_subsets = self.subset_masks(n_anchors).shape[0]
        if _check_approach(approach) == "deterministic":
            return n_subsets * len(self.metrics) * len(self.knn_configs())
        return n_subsets * len(self.pknn_neighbors)


def format_subset(anchors) -> str:
    """Paper notation of a subset of 1-based anchor numbers: ``(1, 5, 6)`` → ``"{1, 5, 6}"``."""
    return "{" + ", ".join(str(int(a)) for a in anchors) + "}"


def parse_subset(value) -> tuple[int, ...]:
    """1-based anchor numbers from ``"{1, 5, 6}"``, a tuple/list of numbers, or a boolean mask."""
    if isinstance(value, str):
        body = value.strip().strip("{}()[]").strip()
        if not body:
            raise ValueError(f"empty anchor subset {value!r}")
        try:
            anchors = tuple(int(part) for part in body.split(","))
        except ValueError as exc:
            raise ValueError(f"cannot read an anchor subset from {value!r}") from exc
    else:
        arr = np.asarray(value)
        if arr.dtype == np.bool_:
            anchors = tuple(int(i) + 1 for i in np.flatnonzero(arr))
        else:
            anchors = tuple(int(a) for a in np.atleast_1d(arr))
    if not anchors or min(anchors) < 1 or len(set(anchors)) != len(anchors):
        raise ValueError(f"an anchor subset must hold distinct anchor numbers >= 1, got {value!r}")
    return tuple(sorted(anchors))


def _check_approach(approach) -> str:
    if approach not in APPROACHES:
        raise ValueError(f"approach must be one of {APPROACHES}, got {approach!r}")
    return approach


def _check_estimate(estimate) -> str:
    if estimate not in ESTIMATES:
        raise ValueError(f"estimate must be one of {ESTIMATES}, got {estimate!r}")
    return estimate


@dataclasses.dataclass(frozen=True)
class Setting:
    """One fingerprinting setting.

    Parameters
    ----------
    approach : {"deterministic", "probabilistic"}
    anchors : tuple of int
        1-based anchor numbers (the paper's "anchors subset").
    k : int
    metric : {"euclidean", "manhattan"} or None
        Deterministic only.
    p_s : number or None
        Shepard exponent; deterministic with ``k > 1`` only.
    """

    approach: str
    anchors: tuple[int, ...]
    k: int
    metric: str | None = None
    p_s: float | None = None

    def __post_init__(self):
        _check_approach(self.approach)
        object.__setattr__(self, "anchors", parse_subset(self.anchors))
        if isinstance(self.k, bool) or not isinstance(self.k, numbers.Integral) or self.k < 1:
            raise ValueError(f"k must be a positive integer, got {self.k!r}")
        p_s = None if self.p_s is None or pd.isna(self.p_s) else self.p_s
        if self.approach == "deterministic":
            if self.metric not in METRICS:
                raise ValueError(f"metric must be one of {METRICS} for the deterministic approach, got {self.metric!r}")
            if self.k > 1 and p_s is None:
                raise ValueError("p_s is required for the deterministic approach with k > 1")
            if self.k == 1:
                p_s = None
        else:
            if self.metric is not None and not pd.isna(self.metric):
                raise ValueError("the probabilistic approach takes no metric")
            object.__setattr__(self, "metric", None)
            p_s = None
        object.__setattr__(self, "k", int(self.k))
        object.__setattr__(self, "p_s", p_s)

    @classmethod
    def from_row(cls, row) -> Setting:
        """From a row (mapping / Series) with ``approach``, ``anchors`` or ``subset``, ``k``, ``metric``, ``p_s``."""
        anchors = row["anchors"] if "anchors" in row else row["subset"]
        metric = row.get("metric") if hasattr(row, "get") else row["metric"]
        p_s = row.get("p_s") if hasattr(row, "get") else row["p_s"]
        return cls(row["approach"], anchors, int(row["k"]),
                   None if metric is None or pd.isna(metric) else metric,
                   None if p_s is None or pd.isna(p_s) else p_s)  # fmt: skip

    @property
    def subset(self) -> str:
        """``"{1, 5, 6}"``."""
        return format_subset(self.anchors)

    def mask(self, n_anchors: int) -> np.ndarray:
        """Boolean mask ``(n_anchors,)`` of the anchors."""
        if max(self.anchors) > n_anchors:
            raise ValueError(f"setting uses anchor {max(self.anchors)} but the data have {n_anchors} anchors")
        mask = np.zeros(n_anchors, dtype=bool)
        mask[np.asarray(self.anchors) - 1] = True
        return mask


def _is_fitted(estimator) -> bool:
    try:
        check_is_fitted(estimator, "radio_map_")
    except Exception:  # noqa: BLE001 - NotFittedError or a non-estimator
        return False
    return True


@dataclasses.dataclass(frozen=True, eq=False)
class SearchData:
    """One user's online phase for one target node, and what the estimators are fitted on.

    Parameters
    ----------
    online_rss : array_like, shape (n, A)
        Online vectors (dBm), complete (no NaN; fill first, see :mod:`wsnlib.fingerprint`).
    movement : array_like of int, shape (n,)
        Movement index of each row (1..8 in the paper).  The rows of one movement must be
        contiguous and in time order (the held heading of eq. (8) runs along them).
    true_positions : array_like, shape (n, 3)
        True device positions (m), shoulder frame (x right, y forward, z up).
    pitch : array_like, shape (n,)
        Accelerometer pitch θ of the segment (rad, in [−π/2, π/2]), e.g.
        :func:`wsnlib.posture.pitch_from_acc`.  Unused with ``estimate="radio"``.
    chain : ArmChain
        The user's arm; ``segment`` picks this target's segment length d and device offset d′.
    segment : int
        0 for target 1 (upper arm), 1 for target 2 (forearm), …
    proximal : None or array_like, shape (3,) or (n, 3)
        Proximal joint ``A`` of the segment (m): None = the origin (the shoulder, target 1);
        for target 2 the elbow estimated from target 1 (:func:`proximal_from_selection`).
    training_rss, training_positions : array_like, shapes (m, A) and (m, 3), optional
        Training vectors (dBm, NaN = missing reading) and their fingerprint positions (m).
        Needed unless both estimators are given fitted.
    knn : KNNFingerprint, optional
        Fitted (used as is, its ``metric``/``k``/``power``/``anchors`` ignored) or a template
        fitted on the training data; default ``KNNFingerprint()``.
    pknn : ProbabilisticKNN, optional
        Likewise; default ``ProbabilisticKNN()`` (histogram PMFs, the paper's).
    """

    online_rss: np.ndarray
    movement: np.ndarray
    true_positions: np.ndarray
    pitch: np.ndarray
    chain: ArmChain
    segment: int = 0
    proximal: np.ndarray | None = None
    training_rss: np.ndarray | None = None
    training_positions: np.ndarray | None = None
    knn: KNNFingerprint | None = None
    pknn: ProbabilisticKNN | None = None

    def __post_init__(self):
        rss = as_float_array(self.online_rss, "online_rss", min_ndim=2)
        if rss.ndim != 2 or rss.shape[0] == 0 or rss.shape[1] == 0:
            raise ValueError(f"online_rss must have shape (n, n_anchors) with both > 0, got {rss.shape}")
        n = rss.shape[0]
        movement = np.asarray(self.movement)
        if movement.shape != (n,):
            raise ValueError(f"movement must have shape ({n},) like online_rss's rows, got {movement.shape}")
        if movement.dtype == np.bool_ or not np.issubdtype(movement.dtype, np.integer):
            if not (np.issubdtype(movement.dtype, np.floating) and np.all(movement == np.round(movement))):
                raise ValueError(f"movement must hold integer movement indices, got dtype {movement.dtype}")
        movement = movement.astype(np.int64)
        true = as_float_array(self.true_positions, "true_positions", last_dim=3)
        if true.shape != (n, 3):
            raise ValueError(f"true_positions must have shape ({n}, 3), got {true.shape}")
        pitch = as_float_array(self.pitch, "pitch")
        if pitch.shape != (n,):
            raise ValueError(f"pitch must have shape ({n},), got {pitch.shape}")
        if np.any(np.abs(pitch) > math.pi / 2 + 1e-9):
            raise ValueError("pitch must lie in [-pi/2, pi/2] rad (eq. (7))")
        pitch = np.clip(pitch, -math.pi / 2, math.pi / 2)
        if not isinstance(self.chain, ArmChain):
            raise ValueError(f"chain must be an ArmChain, got {type(self.chain).__name__}")
        seg = self.segment
        if isinstance(seg, bool) or not isinstance(seg, numbers.Integral) or not 0 <= seg < self.chain.n_segments:
            raise ValueError(f"segment must be an integer in 0..{self.chain.n_segments - 1}, got {seg!r}")
        if self.proximal is None:
            proximal = np.zeros((n, 3))
        else:
            proximal = as_float_array(self.proximal, "proximal", last_dim=3)
            if proximal.shape not in ((3,), (n, 3)):
                raise ValueError(f"proximal must have shape (3,) or ({n}, 3), got {proximal.shape}")
            proximal = np.broadcast_to(proximal, (n, 3)).copy()
        training_rss, training_positions = self.training_rss, self.training_positions
        if (training_rss is None) != (training_positions is None):
            raise ValueError("give both training_rss and training_positions, or neither")
        if training_rss is not None:
            training_rss = np.asarray(training_rss, dtype=float)
            training_positions = as_float_array(training_positions, "training_positions", last_dim=3)
            if training_rss.ndim != 2 or training_rss.shape[1] != rss.shape[1]:
                raise ValueError(f"training_rss must have shape (m, {rss.shape[1]}) like online_rss's anchors, "
                                 f"got {training_rss.shape}")
            if training_positions.shape != (training_rss.shape[0], 3):
                raise ValueError(f"training_positions must have shape ({training_rss.shape[0]}, 3), "
                                 f"got {training_positions.shape}")
        for name, cls in (("knn", KNNFingerprint), ("pknn", ProbabilisticKNN)):
            est = getattr(self, name)
            if est is not None and not isinstance(est, cls):
                raise ValueError(f"{name} must be a {cls.__name__}, got {type(est).__name__}")
            if est is not None and _is_fitted(est) and est.n_features_in_ != rss.shape[1]:
                raise ValueError(f"{name} was fitted with {est.n_features_in_} anchors, online_rss has {rss.shape[1]}")
        for name, value in (("online_rss", rss), ("movement", movement), ("true_positions", true),
                            ("pitch", pitch), ("proximal", proximal), ("segment", int(seg)),
                            ("training_rss", training_rss), ("training_positions", training_positions)):
            object.__setattr__(self, name, value)

    @property
    def n_anchors(self) -> int:
        """A."""
        return self.online_rss.shape[1]

    @property
    def device_offset_m(self) -> float:
        """d′ of this target's segment (m)."""
        return self.chain.device_offsets_m[self.segment]

    @property
    def segment_length_m(self) -> float:
        """d of this target's segment (m)."""
        return self.chain.segment_lengths_m[self.segment]

    def fitted(self, approaches=APPROACHES) -> SearchData:
        """A copy whose estimators for ``approaches`` are fitted (each fitted once, here)."""
        approaches = _check_approaches(approaches)
        changes = {}
        for approach, name, default in (("deterministic", "knn", KNNFingerprint),
                                        ("probabilistic", "pknn", ProbabilisticKNN)):
            est = getattr(self, name)
            if approach not in approaches or (est is not None and _is_fitted(est)):
                continue
            if self.training_rss is None:
                raise ValueError(f"the {approach} approach needs a fitted {name} or training_rss/training_positions")
            template = default() if est is None else clone(est)
            template.set_params(n_neighbors=1, anchors=None)  # irrelevant to the per-anchor terms
            changes[name] = template.fit(self.training_rss, self.training_positions)
        return dataclasses.replace(self, **changes) if changes else self

    def with_proximal(self, proximal) -> SearchData:
        """A copy with another proximal joint ``(n, 3)`` (keeps fitted estimators)."""
        return dataclasses.replace(self, proximal=proximal)


def _check_approaches(approaches) -> tuple[str, ...]:
    if isinstance(approaches, str):
        approaches = (approaches,)
    approaches = tuple(approaches)
    if not approaches:
        raise ValueError("approaches must name at least one approach")
    for a in approaches:
        _check_approach(a)
    return tuple(a for a in APPROACHES if a in approaches)


def _as_users(data) -> tuple[list, list[SearchData]]:
    if isinstance(data, SearchData):
        labels, users = [1], [data]
    elif isinstance(data, Mapping):
        labels, users = list(data.keys()), list(data.values())
    elif isinstance(data, Sequence) and not isinstance(data, str):
        labels, users = list(range(1, len(data) + 1)), list(data)
    else:
        raise ValueError(f"data must be a SearchData, a sequence or a mapping of them, got {type(data).__name__}")
    if not users:
        raise ValueError("data holds no user")
    for u in users:
        if not isinstance(u, SearchData):
            raise ValueError(f"every user's data must be a SearchData, got {type(u).__name__}")
    n_anchors = {u.n_anchors for u in users}
    if len(n_anchors) != 1:
        raise ValueError(f"all users must have the same number of anchors, got {sorted(n_anchors)}")
    return labels, users


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
        counts = np.bincount(inverse)
        self.weights = np.zeros((data.movement.size, self.movements.size))
        self.weights[np.arange(data.movement.size), inverse] = 1.0 / counts[inverse]  # mean per movement
        self.counts = counts
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
            return (pe @ self.weights)[None]
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
            out[v] = ex @ self.weights
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


def _knn_rows_per_subset(grid: SearchGrid) -> int:
    """Estimates per subset in the largest kNN array of a chunk, (K · P) of knn_grid_from_terms."""
    return len(grid.knn_neighbors) * len(grid.powers)


def _chunk_size(n_rows_per_subset: int, n_vectors: int, chunk_elements: int) -> int:
    return max(1, int(chunk_elements) // max(1, n_rows_per_subset * n_vectors * 3))


def _user_pe(data: SearchData, approach: str, grid: SearchGrid, masks: np.ndarray, ctx: _Context,
             chunk_elements: int, bar) -> np.ndarray:
    """Mean PE (m) per (variant, setting, movement) of one user: ``(V, C, M)``."""
    n = data.online_rss.shape[0]
    if approach == "deterministic":
        est = data.knn
        positions = est.positions_
        knn_cfg = grid.knn_configs()
        per = len(knn_cfg)
        # (k index, p index) of each unique setting per (subset, metric): k = 1 once, at p index 0
        k_idx = np.array([grid.knn_neighbors.index(k) for k, _ in knn_cfg])
        p_idx = np.array([0 if p is None else grid.powers.index(p) for _, p in knn_cfg])
        terms = {}
        for metric in grid.metrics:
            est_m = copy.copy(est)
            est_m.metric = metric
            terms[metric] = est_m.anchor_terms(data.online_rss)
        n_metrics = len(grid.metrics)
        out = np.empty((ctx.n_variants, masks.shape[0] * n_metrics * per, ctx.movements.size))
        step = _chunk_size(_knn_rows_per_subset(grid), n, chunk_elements)
        for start in range(0, masks.shape[0], step):
            chunk = np.arange(start, min(start + step, masks.shape[0]))
            for mi, metric in enumerate(grid.metrics):
                grid_est = knn_grid_from_terms(terms[metric], masks[chunk], positions, grid.knn_neighbors,
                                               grid.powers, metric, coordinates_first=True)  # (3, s, K, P, n)
                radio = grid_est[:, :, k_idx, p_idx].reshape(3, -1, n)                     # (3, s·per, n)
                ids = ((chunk[:, None] * n_metrics + mi) * per + np.arange(per)).ravel()
                out[:, ids] = ctx.movement_pe(radio)
            bar.update(1)
        return out
    est = data.pknn
    loglik = est.anchor_log_likelihoods(data.online_rss)
    per = len(grid.pknn_neighbors)
    out = np.empty((ctx.n_variants, masks.shape[0] * per, ctx.movements.size))
    step = _chunk_size(per, n, chunk_elements)
    for start in range(0, masks.shape[0], step):
        chunk = np.arange(start, min(start + step, masks.shape[0]))
        radio = pknn_grid_from_loglik(loglik, masks[chunk], est.positions_, grid.pknn_neighbors,
                                      coordinates_first=True)                            # (3, s, K, n)
        ids = (chunk[:, None] * per + np.arange(per)).ravel()
        out[:, ids] = ctx.movement_pe(radio.reshape(3, -1, n))
        bar.update(1)
    return out


def _n_chunks(grid: SearchGrid, n_subsets: int, n_vectors: int, approach: str, chunk_elements: int) -> int:
    if approach == "deterministic":
        step = _chunk_size(_knn_rows_per_subset(grid), n_vectors, chunk_elements)
    else:
        step = _chunk_size(len(grid.pknn_neighbors), n_vectors, chunk_elements)
    return -(-n_subsets // step)


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
    total = sum(_n_chunks(grid, masks.shape[0], u.online_rss.shape[0], a, chunk_elements)
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
    approaches = _check_approaches(approaches)
    estimate = _check_estimate(estimate)
    grid = SearchGrid() if grid is None else grid
    if not isinstance(grid, SearchGrid):
        raise ValueError(f"grid must be a SearchGrid, got {type(grid).__name__}")
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
    if not isinstance(setting, Setting):
        raise ValueError(f"setting must be a Setting, got {type(setting).__name__}")
    if not isinstance(data, SearchData):
        raise ValueError(f"data must be a SearchData, got {type(data).__name__}")
    estimate = _check_estimate(estimate)
    data = data.fitted(setting.approach)
    mask = setting.mask(data.n_anchors)
    if setting.approach == "deterministic":
        est = copy.copy(data.knn)
        est.metric = setting.metric
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
        pe = self.pe if users is None else self.pe[..., users]
        count = np.sum(~np.isnan(pe), axis=-1)
        total = np.nansum(pe, axis=-1)
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)

    @staticmethod
    def movement_mean(pe: np.ndarray, movements=None) -> np.ndarray:
        """Equal-weight mean over ``movements`` (indices; default all) of ``(C, M)``: ``(C,)``."""
        pe = pe if movements is None else pe[:, movements]
        count = np.sum(~np.isnan(pe), axis=-1)
        return np.where(count > 0, np.nansum(pe, axis=-1) / np.maximum(count, 1), np.nan)


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
    record = {"config": int(cube.configs[index])}
    record.update(cube.settings.iloc[index].to_dict())
    return record


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

    def average_pe(self) -> pd.DataFrame:
        """The tables' last rows: mean PE (cm) over both targets' rows, per approach and table."""
        out = {}
        for name, sel in (("Table 2", self.selection2), ("Table 3", self.selection3)):
            out[name] = sel.groupby("approach", sort=False)["pe_cm"].mean()
        return pd.DataFrame(out)


def paper_tables(target1, target2, *, approaches=APPROACHES, estimate: str = "hybrid",
                 grid: SearchGrid | None = None, progress: bool = False,
                 chunk_elements: int = DEFAULT_CHUNK_ELEMENTS) -> PaperTables:
    """Tables 2 and 3: search target 1, derive the elbows, search target 2 (see the module docstring).

    Parameters
    ----------
    target1, target2 : sequence or mapping of SearchData
        Per user, the same users in the same order/keys; ``target2``'s ``proximal`` is
        ignored (replaced by the elbows from target 1), its ``segment`` should be 1.
    approaches, estimate, grid, progress, chunk_elements
        As in :func:`search`.
    """
    approaches = _check_approaches(approaches)
    estimate = _check_estimate(estimate)
    grid = SearchGrid() if grid is None else grid
    labels1, users1 = _as_users(target1)
    labels2, users2 = _as_users(target2)
    if labels1 != labels2:
        raise ValueError(f"target1 and target2 must hold the same users, got {labels1} and {labels2}")
    for u1, u2 in zip(users1, users2, strict=True):
        if u1.online_rss.shape[0] != u2.online_rss.shape[0] or not np.array_equal(u1.movement, u2.movement):
            raise ValueError("target1 and target2 must have the same online rows (movement) per user, "
                             "since target 2's elbow comes from target 1's row")
    users1 = [u.fitted(approaches) for u in users1]
    users2 = [u.fitted(approaches) for u in users2]

    prox1 = [{a: u.proximal[None] for a in approaches} for u in users1]
    res1 = _search(labels1, users1, approaches, estimate, grid, prox1, progress, chunk_elements)[0]
    sel1_mov = select_settings(res1, per_movement=True)
    sel1_glob = select_settings(res1, per_movement=False)

    if estimate == "radio":
        prox2 = [{a: u.proximal[None] for a in approaches} for u in users2]
        res2 = _search(labels2, users2, approaches, estimate, grid, prox2, progress, chunk_elements)[0]
        res2_mov = res2_glob = res2
    else:
        prox2 = [{a: np.stack([proximal_from_selection(u1, sel1_mov, approach=a),
                               proximal_from_selection(u1, sel1_glob, approach=a)]) for a in approaches}
                 for u1 in users1]  # fmt: skip
        res2_mov, res2_glob = _search(labels2, users2, approaches, estimate, grid, prox2, progress, chunk_elements)
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


# --------------------------------------------------------------------------------------
# Beyond the paper: how optimistic is picking the best of thousands of settings?
# --------------------------------------------------------------------------------------


def held_out_gap(results: pd.DataFrame, *, first=(1, 2, 3, 4), second=(5, 6, 7, 8),
                 by_fold: bool = False) -> pd.DataFrame:
    """In-sample vs out-of-sample PE of the selected settings (not in the paper), one fold per split.

    Superseded by :func:`selection_regret` (both repetition folds, regret against the test
    data's own best, standard errors) and :func:`coupled_selection_regret` (target 2 without
    the leak described below); kept for comparison.  Its ``gap_cm`` compares in-sample PE on
    one half with out-of-sample PE on the *other* half in a single unswapped fold, so a harder
    first half makes it negative.

    Two splits, each with the global (Table 3) and the per-movement (Table 2) selection:

    * ``"repetition"``: select on movements ``first`` (the first repetition of the
      sequence) and score on ``second`` (the repetition); per movement, ``first[i]``'s
      setting is scored on ``second[i]``.  Users averaged as in the paper.
    * ``"leave-one-user-out"``: select on all users but one (their average), score on the
      held-out user; every user in turn (needs a ``user`` column and ≥ 2 users).

    Parameters
    ----------
    results : DataFrame
        From :func:`search` (per user), one target.  For target 2 the elbow comes from
        target 1's setting, itself chosen on all the data; this function does not redo that.
    first, second : sequences of movement labels, equal length
    by_fold : bool
        Return one row per fold (a held-out user) instead of the mean over folds.

    Returns
    -------
    pandas.DataFrame
        Rows ``(approach, split, selection)`` [``fold``]; columns ``in_sample_cm`` (the
        minimised PE on the selection data), ``out_of_sample_cm`` (the chosen setting on the
        test data), ``gap_cm`` (out − in, the optimism), ``oracle_cm`` (best setting chosen on
        the test data itself), ``grid_mean_cm`` (mean over all settings on the test data, what
        a setting picked at random would give), ``n_folds``.
    """
    first, second = tuple(first), tuple(second)
    if len(first) != len(second) or not first:
        raise ValueError(f"first and second must be non-empty and of equal length, got {first} and {second}")
    if set(first) & set(second):
        raise ValueError(f"first and second overlap: {sorted(set(first) & set(second))}")
    rows = []
    for approach, cube in _cubes(results).items():
        mov_index = {m: i for i, m in enumerate(cube.movements.tolist())}
        missing = [m for m in first + second if m not in mov_index]
        if missing:
            raise ValueError(f"results have no movement {missing} (have {cube.movements.tolist()})")
        fi = np.array([mov_index[m] for m in first])
        si = np.array([mov_index[m] for m in second])
        mean = cube.user_mean()
        rows += _gap_rows(approach, "repetition", "global", "movements " + format_subset(first),
                          mean[:, fi], mean[:, si])
        rows += _gap_rows(approach, "repetition", "per_movement", "movements " + format_subset(first),
                          mean[:, fi], mean[:, si], paired=True)
        if "user" in results.columns and cube.users.size >= 2:
            everyone = np.arange(cube.users.size)
            for u, label in enumerate(cube.users):
                train = cube.user_mean(np.delete(everyone, u))
                test = cube.pe[..., u]
                for selection in ("global", "per_movement"):
                    rows += _gap_rows(approach, "leave-one-user-out", selection, f"user {label}", train, test,
                                      paired=selection == "per_movement")
    folds = pd.DataFrame(rows)
    if by_fold:
        return folds.set_index(["approach", "split", "selection", "fold"])
    keys = ["approach", "split", "selection"]
    summary = folds.groupby(keys, sort=False)[["in_sample_cm", "out_of_sample_cm", "gap_cm", "oracle_cm",
                                              "grid_mean_cm"]].mean()
    summary["n_folds"] = folds.groupby(keys, sort=False).size()
    return summary


def _gap_rows(approach, split, selection, fold, train: np.ndarray, test: np.ndarray, paired: bool = False) -> list:
    """One fold: ``train``/``test`` are (C, M′) PE arrays over the same or paired movements."""
    if paired:  # per movement: column j of train selects for column j of test
        picks = [_argbest(train[:, j]) for j in range(train.shape[1])]
        cols = [j for j in range(train.shape[1]) if not np.isnan(test[picks[j], j])]
        if not cols:
            return []
        in_sample = np.mean([train[picks[j], j] for j in cols])
        out = np.mean([test[picks[j], j] for j in cols])
        oracle = np.mean([np.nanmin(test[:, j]) for j in cols])
        grid_mean = np.mean([np.nanmean(test[:, j]) for j in cols])
    else:
        train_g = _Cube.movement_mean(train)
        test_g = _Cube.movement_mean(test)
        if np.all(np.isnan(test_g)):
            return []
        pick = _argbest(train_g)
        in_sample, out = train_g[pick], test_g[pick]
        oracle, grid_mean = np.nanmin(test_g), np.nanmean(test_g)
    return [{"approach": approach, "split": split, "selection": selection, "fold": fold,
             "in_sample_cm": float(in_sample), "out_of_sample_cm": float(out), "gap_cm": float(out - in_sample),
             "oracle_cm": float(oracle), "grid_mean_cm": float(grid_mean)}]


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


def _check_splits(splits) -> tuple[str, ...]:
    if isinstance(splits, str):
        splits = (splits,)
    splits = tuple(splits)
    if not splits:
        raise ValueError("splits must name at least one split")
    for s in splits:
        if s not in SPLITS:
            raise ValueError(f"splits must be among {SPLITS}, got {s!r}")
    return splits


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


def _nanmean(values: np.ndarray, axis) -> np.ndarray:
    count = np.sum(~np.isnan(values), axis=axis)
    total = np.nansum(values, axis=axis)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _fold_picks(cube: _Cube, fold: _Fold) -> dict[str, np.ndarray]:
    """Settings chosen on the fold's selection data: ``global`` (1,) and ``per_movement`` (M′,)."""
    train = cube.user_mean(fold.train_users)[:, fold.train_movements]              # (C, M')
    return {"global": np.array([_argbest(_Cube.movement_mean(train))]),
            "per_movement": np.array([_argbest(train[:, j]) for j in range(train.shape[1])])}


def _fold_units(cube: _Cube, fold: _Fold, selection: str, picks: np.ndarray) -> list[dict]:
    """Per test unit (user) of one fold: in-sample, out-of-sample and oracle PE (cm)."""
    train = cube.user_mean(fold.train_users)[:, fold.train_movements]              # (C, M')
    test = cube.pe[:, fold.test_movements][:, :, fold.test_users]                   # (C, M', U')
    test_mean = _nanmean(test, axis=-1)                                            # (C, M')
    in_units = None
    if np.array_equal(fold.train_users, fold.test_users):  # the units are in the selection data too
        in_units = cube.pe[:, fold.train_movements][:, :, fold.test_users]
    if selection == "global":
        pick = int(picks[0])
        oracle = _argbest(_Cube.movement_mean(test_mean))
        out_u = _nanmean(test[pick], axis=0)                                        # (U',)
        oracle_u = _nanmean(test[oracle], axis=0)
        in_u = (_nanmean(in_units[pick], axis=0) if in_units is not None
                else np.full(out_u.shape, _Cube.movement_mean(train)[pick]))
    else:
        cols = np.arange(test.shape[1])
        oracles = np.array([_argbest(test_mean[:, j]) if not np.all(np.isnan(test_mean[:, j])) else 0 for j in cols])
        out_u = _nanmean(test[picks, cols], axis=0)                                 # (M', U') → (U',)
        oracle_u = _nanmean(test[oracles, cols], axis=0)
        in_u = (_nanmean(in_units[picks, cols], axis=0) if in_units is not None
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
    summary = summary.sort_index(key=lambda level: level.map(position[level.name]) if level.name in position
                                 else level)
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
    equals the regret and is ≥ 0; what one unswapped fold reports (:func:`held_out_gap`) is
    not.

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
    splits = _check_splits(splits)
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
    approaches = _check_approaches(approaches)
    grid = SearchGrid() if grid is None else grid
    if not isinstance(grid, SearchGrid):
        raise ValueError(f"grid must be a SearchGrid, got {type(grid).__name__}")
    first, second = _check_halves(first, second)
    splits = _check_splits(splits)
    labels1, users1 = _as_users(target1)
    labels2, users2 = _as_users(target2)
    if labels1 != labels2:
        raise ValueError(f"target1 and target2 must hold the same users, got {labels1} and {labels2}")
    for u1, u2 in zip(users1, users2, strict=True):
        if u1.online_rss.shape[0] != u2.online_rss.shape[0] or not np.array_equal(u1.movement, u2.movement):
            raise ValueError("target1 and target2 must have the same online rows (movement) per user")
    users1 = [u.fitted(approaches) for u in users1]
    users2 = [u.fitted(approaches) for u in users2]
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
        res_glob, res_mov = _search(labels2, users2, approaches, "hybrid", grid, prox2, progress, chunk_elements)
        for selection, res in (("global", res_glob), ("per_movement", res_mov)):
            for approach, cube2 in _cubes(res).items():
                fold2 = _folds(cube2, first, second, splits)[index]
                picks2 = _fold_picks(cube2, fold2)
                rows2 += [{"approach": approach, **r} for r in _fold_units(cube2, fold2, selection, picks2[selection])]
    units = pd.concat([pd.DataFrame(rows1).assign(target=1), pd.DataFrame(rows2).assign(target=2)],
                      ignore_index=True)
    if by_unit:
        return units
    return _summarise_units(units, ["target", "approach", "split", "selection"])
