"""The data model of paper 002's parameter search: grid, setting, one user's data.

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition", Section 5.  :class:`SearchGrid` is what is searched (defaults = the paper's
grid): every non-empty anchor subset × distance {Euclidean, Manhattan} × ``k`` × Shepard
exponent ``p_s`` for the deterministic kNN (eqs. (1)–(2)), subset × ``k`` for the
probabilistic p-kNN (eqs. (3)–(4)).  :class:`Setting` is one point of that grid (one row
of Tables 2 and 3); :class:`SearchData` one user's online phase for one target node — RSS
vectors, movements, true positions, accelerometer pitch θ (eq. (7)), the arm and the
proximal joint of eq. (9) — with the estimators it is scored with.

Anchors are numbered from 1 in tables and ``anchors`` tuples, as in the paper ("{1, 5, 6}");
boolean masks and column indices are 0-based.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from sklearn.base import clone
from sklearn.utils.validation import check_is_fitted

from wsnlib._validation import as_float_array, check_count
from wsnlib.posture import ArmChain
from wsnlib.radio import METRICS, KNNFingerprint, ProbabilisticKNN, anchor_subsets

APPROACHES = ("deterministic", "probabilistic")
ESTIMATES = ("hybrid", "radio")


def _grid_values(values, name: str, what: str, ok) -> tuple:
    """``values`` as a non-empty tuple without duplicates whose every value passes ``ok`` (a ``what``)."""
    values = tuple(np.atleast_1d(np.asarray(values, dtype=object)).tolist())
    if not values:
        raise ValueError(f"{name} must hold at least one value (empty grid)")
    for v in values:
        if not ok(v):
            raise ValueError(f"{name} must hold {what}, got {v!r}")
    if len(set(values)) != len(values):
        raise ValueError(f"{name} holds duplicate values: {list(values)}")
    return values


def _int_tuple(values, name: str) -> tuple[int, ...]:
    values = _grid_values(values, name, "positive integers",
                          lambda v: not isinstance(v, bool) and isinstance(v, numbers.Integral) and v >= 1)
    return tuple(sorted(int(v) for v in values))


@dataclasses.dataclass(frozen=True)
class SearchGrid:
    """The settings searched; defaults are the paper's grid (Section 5).

    Parameters
    ----------
    subsets : None or array_like of bool, shape (S, A)
        Anchor subsets as boolean masks; None = all ``2**A − 1`` non-empty subsets
        (:func:`wsnlib.radio.anchor_subsets`, fewest anchors first).  Given masks are
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
        metrics = _grid_values(self.metrics, "metrics", f"distances among {METRICS}", lambda m: m in METRICS)
        powers = _grid_values(self.powers, "powers", "positive finite numbers",
                              lambda p: isinstance(p, numbers.Real) and not isinstance(p, bool) and 0 < p < math.inf)
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
        check_count(self.k, "k")
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
        Online vectors (dBm), complete (no NaN; fill first, see :mod:`wsnlib.radio`).
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
        approaches = _check_choices(approaches, APPROACHES, "approaches")
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


def _check_choices(values, allowed: tuple[str, ...], name: str) -> tuple[str, ...]:
    """``values`` (one name or several) as a tuple in the order of ``allowed``; ``ValueError`` naming
    ``name`` if it is empty or holds a value not in ``allowed``."""
    values = (values,) if isinstance(values, str) else tuple(values)
    if not values:
        raise ValueError(f"{name} must name at least one of {allowed}")
    for value in values:
        if value not in allowed:
            raise ValueError(f"{name} must be among {allowed}, got {value!r}")
    return tuple(a for a in allowed if a in values)


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


def _check_paired_rows(target1: SearchData, target2: SearchData) -> None:
    """One user's two targets must have the same online rows (movement): target 2's elbow comes
    from target 1's row."""
    if target1.online_rss.shape[0] != target2.online_rss.shape[0] or not np.array_equal(target1.movement,
                                                                                       target2.movement):
        raise ValueError("target1 and target2 must have the same online rows (movement), since target 2's elbow "
                         "comes from target 1's row")


def _paired_users(target1, target2, approaches) -> tuple[list, list[SearchData], list[SearchData]]:
    """Both targets' users (:func:`_as_users`), checked to be the same users with the same
    online rows (movement) each (:func:`_check_paired_rows`), fitted for ``approaches``."""
    labels1, users1 = _as_users(target1)
    labels2, users2 = _as_users(target2)
    if labels1 != labels2:
        raise ValueError(f"target1 and target2 must hold the same users, got {labels1} and {labels2}")
    for u1, u2 in zip(users1, users2, strict=True):
        _check_paired_rows(u1, u2)
    return labels1, [u.fitted(approaches) for u in users1], [u.fitted(approaches) for u in users2]
