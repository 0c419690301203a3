"""Radio fingerprinting: radio map, kNN with Shepard weights, probabilistic kNN (p-kNN).

Paper 002 (M. Giuberti, M. Martalò, G. Ferrari, "A hybrid radio/accelerometric approach to
arm posture recognition"), Section 3.1, eqs. (1)–(4), and the Parzen-window / Gaussian
mixture PMFs its Section 5 proposes as extensions.

Conventions
-----------
* ``X`` (training or online RSS vectors): shape ``(n, A)`` in dBm, one column per anchor
  (7 anchors in the paper, 12 receivers in PABR).  Every training reading (and ``floor_rss``)
  must lie in :data:`RSS_RANGE_DBM` = [−130, 20] dBm, the span of any radio's RSS report: a
  value outside it is a glitch or a unit error and raises ``ValueError`` naming ``X`` and the
  index (so one −1e9 glitch cannot ask for a giant PMF grid); so does training data with no
  reading at all (every entry NaN) or whose readings are all ≥ 0 (linear power such as mW,
  not dBm: convert with ``10·log10(P / 1 mW)``).  Online vectors are not range-checked: the
  p-kNN clips them to ``grid_``, the kNN measures their distance as it is.
* Online vectors are processed in chunks of at most about 4 million (vector, fingerprint,
  anchor) values (32 MB per intermediate array), so ``predict`` of 100,000 vectors needs a
  few hundred MB at most, with results identical to an unchunked computation.
* ``y`` (positions): shape ``(n, D)``, normally ``D = 3`` metres (any coordinates work; the
  estimate is a weighted mean of them).  Training vectors whose rows of ``y`` are equal form
  one *fingerprint position*; positions are numbered in order of first appearance
  (``positions_[l]``), so the result does not depend on sorting.
* **Missing readings in training.**  ``NaN`` in ``X`` passed to ``fit`` means "this anchor
  did not report in this vector".  It is left out of that anchor's mean (radio map) and of
  its PMF; the other anchors of the same vector still count.  ``n_readings_[l, a]`` says how
  many readings each (position, anchor) cell got.  A cell with no reading at all gets the
  mean ``floor_rss`` (default −100 dBm, a "not heard" level) and, in
  :class:`ProbabilisticKNN`, a PMF that is a point mass at ``round(floor_rss)`` (before the
  floor probability is applied).  So an anchor that never hears a position looks, to both
  estimators, like an anchor that reads ``floor_rss`` there.
* **Online vectors must be complete**: ``NaN`` in ``predict`` (and the other online
  methods) raises ``ValueError``.  Fill missing readings first with the same "not heard"
  level, e.g. ``np.where(np.isnan(X), est.floor_rss, X)`` (or
  :func:`wsnlib.pabr.pabr_vectors` with ``fill=-100.0``).
* ``anchors`` (both estimators): ``None`` (all), integer column indices, or a boolean mask of
  length ``A``.  It selects the anchors used for the distances / likelihoods; ``X`` always
  keeps all ``A`` columns, and the learned radio map and PMFs cover all anchors, so the
  per-anchor methods (:meth:`KNNFingerprint.anchor_terms`,
  :meth:`ProbabilisticKNN.anchor_log_likelihoods`) return every anchor and the module
  functions :func:`knn_from_terms` / :func:`pknn_from_loglik` evaluate many anchor subsets
  from one fit (exhaustive subset searches: see :func:`anchor_subsets`), and
  :func:`knn_grid_from_terms` / :func:`pknn_grid_from_loglik` every ``k`` (and Shepard
  exponent) of a grid at once, from one sort of the neighbours (:mod:`wsnlib.optimize`).
* Ties (equal distances or posteriors) are broken in favour of the lower fingerprint index.

Deterministic kNN, eqs. (1)–(2)
-------------------------------
Distance (Euclidean or Manhattan, over the selected anchors) from the online vector to every
radio-map row; the ``k`` nearest fingerprints; Shepard weights
``w_i = 1 / (d_i**p + 0.0001)``; estimate ``Σ w_i s_i / Σ w_j``.  With ``k = 1`` the nearest
fingerprint's position is returned exactly (``p`` irrelevant).  Should every ``d_i**p``
overflow to ``inf`` (absurd ``p``), the weights' limit, the nearest position, is returned.

Probabilistic kNN, eqs. (3)–(4)
-------------------------------
Per position ``l`` and anchor ``a``, a PMF over integer dBm values (1-dBm bins): readings are
rounded half up (``floor(r + 0.5)``), so bin ``g`` holds ``[g − 0.5, g + 0.5)``.  The grid
``grid_`` spans every training reading and ``floor_rss``, widened by ``grid_margin_db`` on
each side; online readings outside it are clipped to its edge bins.  Likelihood of an online
vector = product over the selected anchors of the PMF values of its readings (anchors taken
as independent given the position); uniform prior ``1/L``; posterior by Bayes (eq. (4)); the
``k`` positions of largest posterior, weighted by their posteriors (eq. (3)).  Everything is
computed in log space: sums of log-PMFs, normalised with log-sum-exp, so 7 or 12 anchors (or
any number) never underflow.

PMF estimators (``pmf=``):

* ``"histogram"`` (the paper): the normalised histogram of the rounded training readings.
* ``"parzen"``: Gaussian kernels of standard deviation ``h`` (dB) centred on the rounded
  readings; the PMF of bin ``g`` is the kernel mass in ``[g − 0.5, g + 0.5)``.  ``h`` is
  ``bandwidth_db`` if given, else Silverman's rule per (position, anchor),
  ``h = 0.9 · min(σ, IQR/1.34) · m**(-1/5)`` (``σ`` alone when the IQR is 0), never below
  ``min_bandwidth_db`` (0.5 dB: a zero-variance cell, which the paper observed, gets a kernel
  half a bin wide rather than a spike).  ``bandwidth_`` holds the values used.
* ``"gmm"``: a 1-D :class:`sklearn.mixture.GaussianMixture` per (position, anchor) with
  ``min(n_components, number of distinct readings)`` components, fitted to the unrounded
  readings with ``reg_covar = min_bandwidth_db**2`` (so no component is narrower than about
  ``min_bandwidth_db``), seeded from ``random_state``; the PMF of bin ``g`` is the mixture
  mass in ``[g − 0.5, g + 0.5)``.  A cell with one distinct value gets one Gaussian of
  standard deviation ``min_bandwidth_db`` there.  This loops over the ``L·A`` cells (2–5 s for
  PABR's 81 × 12 cells).

**Floor probability** (all three): every bin of every PMF is raised to at least
``floor_probability`` (ε, default 1e-4) and the PMF is then renormalised over the grid, so
no log 0 ever occurs: a reading never seen at a position costs about ``log ε`` instead of
ruling the position out.  With ``k = 1`` the MAP fingerprint position is returned.
"""

from __future__ import annotations

import itertools
import numbers

import numpy as np
from scipy.special import logsumexp, ndtr
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from ._validation import check_nonnegative, check_positive

#: The constant in the denominator of the Shepard weights, eq. (2).
SHEPARD_EPS = 1e-4

METRICS = ("euclidean", "manhattan")
PMF_METHODS = ("histogram", "parzen", "gmm")

#: Largest number of (subset, vector, fingerprint) distances held in memory at once by the
#: batch functions (they process anchor subsets in chunks of this size), and of (vector,
#: fingerprint, anchor) values by the estimators' online methods (they process vectors in
#: chunks of this size).
_CHUNK_ELEMENTS = 1 << 22

#: Plausible range (dBm) of an RSS reading and of ``floor_rss``: below any receiver's
#: sensitivity floor (about −100 dBm for IEEE 802.15.4 radios; the CC2420's 8-bit register
#: reads down to −128 dBm, see :data:`wsnlib.rss.RSS_RANGE_DBM`) up to a transmitter's
#: maximum output power (+20 dBm).  Values outside are glitches or unit errors.
RSS_RANGE_DBM: tuple[float, float] = (-130.0, 20.0)


# --------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------


def _check_n_neighbors(n_neighbors, n_fingerprints: int | None = None) -> int:
    if isinstance(n_neighbors, bool) or not isinstance(n_neighbors, numbers.Integral) or n_neighbors < 1:
        raise ValueError(f"n_neighbors must be a positive integer, got {n_neighbors!r}")
    if n_fingerprints is not None and n_neighbors > n_fingerprints:
        raise ValueError(
            f"n_neighbors={n_neighbors} is larger than the number of fingerprint positions ({n_fingerprints})"
        )
    return int(n_neighbors)


def _check_metric(metric) -> str:
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")
    return metric


def _check_power(power) -> float:
    return check_positive(power, "power")


def _resolve_anchors(anchors, n_anchors: int) -> np.ndarray:
    """Boolean mask ``(A,)`` from ``None``, integer indices or a boolean mask; never empty."""
    if anchors is None:
        return np.ones(n_anchors, dtype=bool)
    arr = np.asarray(anchors)
    if arr.dtype == np.bool_:
        if arr.shape != (n_anchors,):
            raise ValueError(f"anchors as a boolean mask must have shape ({n_anchors},), got {arr.shape}")
        mask = arr.copy()
    else:
        if arr.ndim != 1:
            raise ValueError(f"anchors must be a 1-D list of anchor indices or a boolean mask, got shape {arr.shape}")
        if arr.size and not np.issubdtype(arr.dtype, np.integer):
            raise ValueError(f"anchors must hold integer indices or booleans, got dtype {arr.dtype}")
        arr = arr.astype(np.intp)
        if np.any((arr < 0) | (arr >= n_anchors)):
            raise ValueError(f"anchors holds indices outside 0..{n_anchors - 1}: {arr.tolist()}")
        if np.unique(arr).size != arr.size:
            raise ValueError(f"anchors holds duplicate indices: {arr.tolist()}")
        mask = np.zeros(n_anchors, dtype=bool)
        mask[arr] = True
    if not mask.any():
        raise ValueError("anchors selects no anchor (empty subset)")
    return mask


def _check_training(X, y) -> tuple[np.ndarray, np.ndarray]:
    try:
        X = np.asarray(X, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"X must be a numeric array, got {type(X).__name__}") from exc
    if X.ndim != 2 or X.shape[0] == 0 or X.shape[1] == 0:
        raise ValueError(f"X must have shape (n_vectors, n_anchors) with both > 0, got {X.shape}")
    if np.any(np.isinf(X)):
        raise ValueError("X contains inf (use NaN for a missing reading)")
    readings = X[~np.isnan(X)]
    if readings.size == 0:
        raise ValueError("X has no reading: every entry is NaN (missing), so there is no radio map to learn")
    _check_rss_range(X, "X")
    if np.all(readings >= 0.0):
        raise ValueError(
            f"X holds only readings >= 0 (from {readings.min():g} to {readings.max():g}): that is linear power "
            "(e.g. mW), not RSS in dBm; convert with 10 * log10(P / 1 mW)"
        )
    try:
        y = np.asarray(y, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"y must be a numeric array, got {type(y).__name__}") from exc
    if y.ndim != 2 or y.shape[0] != X.shape[0] or y.shape[1] == 0:
        raise ValueError(f"y must have shape ({X.shape[0]}, n_coordinates), like X's rows; got {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("y contains NaN or inf")
    return X, y + 0.0  # + 0.0 turns -0.0 into 0.0, so both group together


def _check_rss_range(X: np.ndarray, name: str) -> None:
    """``ValueError`` naming ``name`` and the first index of a reading outside :data:`RSS_RANGE_DBM` (NaN ignored)."""
    lo, hi = RSS_RANGE_DBM
    outside = (X < lo) | (X > hi)
    if np.any(outside):
        index = tuple(int(i) for i in np.argwhere(outside)[0])
        raise ValueError(
            f"{name} has an RSS of {X[index]:g} dBm at index {index}, outside the plausible range "
            f"[{lo:g}, {hi:g}] dBm (a glitch, or not dBm?)"
        )


def _group_positions(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of ``y`` in order of first appearance, and each row's position index."""
    unique, first, inverse = np.unique(y, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return unique[order], rank[np.asarray(inverse).reshape(-1)]


def _as_subset_masks(subset_mask, n_anchors: int) -> tuple[np.ndarray, bool]:
    mask = np.asarray(subset_mask)
    if mask.dtype != np.bool_:
        raise ValueError(f"subset_mask must be a boolean array, got dtype {mask.dtype}")
    single = mask.ndim == 1
    mask = np.atleast_2d(mask)
    if mask.ndim != 2 or mask.shape[1] != n_anchors:
        raise ValueError(f"subset_mask must have shape (n_subsets, {n_anchors}) or ({n_anchors},), got {mask.shape}")
    empty = ~mask.any(axis=1)
    if np.any(empty):
        raise ValueError(f"subset_mask row {int(np.argmax(empty))} selects no anchor (empty subset)")
    return mask, single


def _check_terms(terms, name: str, positions) -> tuple[np.ndarray, np.ndarray]:
    terms = np.asarray(terms, dtype=float)
    if terms.ndim != 3:
        raise ValueError(f"{name} must have shape (n_vectors, n_fingerprints, n_anchors), got {terms.shape}")
    positions = np.asarray(positions, dtype=float)
    if positions.ndim != 2 or positions.shape[0] != terms.shape[1]:
        raise ValueError(
            f"positions must have shape ({terms.shape[1]}, n_coordinates) to match {name}, got {positions.shape}"
        )
    if np.any(np.isnan(terms)):
        raise ValueError(f"{name} contains NaN")
    return terms, positions


def anchor_subsets(n_anchors: int, sizes=None) -> np.ndarray:
    """All non-empty anchor subsets as boolean masks, shape ``(S, n_anchors)``.

    Parameters
    ----------
    n_anchors : int
        Number of anchors ``A`` (``2**A − 1`` subsets: 127 for 7 anchors, 4095 for 12).
    sizes : iterable of int, optional
        Keep only subsets with these numbers of anchors (default: every size 1..A).

    Returns
    -------
    ndarray of bool, shape (S, n_anchors)
        Ordered by size, then lexicographically by anchor indices.
    """
    if isinstance(n_anchors, bool) or not isinstance(n_anchors, numbers.Integral) or n_anchors < 1:
        raise ValueError(f"n_anchors must be a positive integer, got {n_anchors!r}")
    sizes = range(1, n_anchors + 1) if sizes is None else sorted(set(int(s) for s in sizes))
    if any(s < 1 or s > n_anchors for s in sizes):
        raise ValueError(f"sizes must lie in 1..{n_anchors}, got {list(sizes)}")
    rows = []
    for size in sizes:
        for combo in itertools.combinations(range(n_anchors), size):
            row = np.zeros(n_anchors, dtype=bool)
            row[list(combo)] = True
            rows.append(row)
    return np.array(rows, dtype=bool).reshape(-1, n_anchors)


# --------------------------------------------------------------------------------------
# Shared estimator machinery
# --------------------------------------------------------------------------------------


class _FingerprintEstimator(BaseEstimator):
    """Radio map (mean RSS per fingerprint position) and the online-vector checks."""

    def _fit_radio_map(self, X, y) -> tuple[np.ndarray, np.ndarray]:
        X, y = _check_training(X, y)
        try:
            floor = float(self.floor_rss)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"floor_rss must be a number (dBm), got {self.floor_rss!r}") from exc
        lo, hi = RSS_RANGE_DBM
        if not lo <= floor <= hi:
            raise ValueError(f"floor_rss must be a finite number in [{lo:g}, {hi:g}] dBm, got {self.floor_rss!r}")
        n_vectors, n_anchors = X.shape
        self.anchor_mask_ = _resolve_anchors(self.anchors, n_anchors)
        positions, inverse = _group_positions(y)
        n_fp = positions.shape[0]
        _check_n_neighbors(self.n_neighbors, n_fp)
        valid = ~np.isnan(X)
        cell = (inverse[:, None] * n_anchors + np.arange(n_anchors))[valid]
        counts = np.bincount(cell, minlength=n_fp * n_anchors).reshape(n_fp, n_anchors)
        sums = np.bincount(cell, weights=X[valid], minlength=n_fp * n_anchors).reshape(n_fp, n_anchors)
        self.radio_map_ = np.where(counts > 0, sums / np.maximum(counts, 1), floor)
        self.positions_ = positions
        self.n_readings_ = counts
        self.n_features_in_ = n_anchors
        return X, inverse

    def _check_online(self, X) -> np.ndarray:
        check_is_fitted(self, "radio_map_")
        try:
            X = np.asarray(X, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"X must be a numeric array, got {type(X).__name__}") from exc
        if X.ndim != 2:
            raise ValueError(f"X must have shape (n_vectors, n_anchors); got {X.shape} (one vector: X.reshape(1, -1))")
        if X.shape[1] != self.n_features_in_:
            raise ValueError(
                f"X has vectors of length {X.shape[1]}, the estimator was fitted with {self.n_features_in_} anchors"
            )
        if np.any(np.isnan(X)):
            bad = tuple(int(i) for i in np.argwhere(np.isnan(X))[0])
            raise ValueError(
                f"X contains NaN (a missing reading, first at index {bad}); online vectors must be complete: "
                f"fill missing readings first, e.g. np.where(np.isnan(X), {self.floor_rss!r}, X) (the floor_rss level)"
            )
        if np.any(np.isinf(X)):
            raise ValueError("X contains inf")
        return X

    def _query_chunks(self, n_vectors: int) -> list[slice]:
        """Slices of at most ``_CHUNK_ELEMENTS // (L·A)`` online vectors (one empty slice for none)."""
        n_fp, n_anchors = self.radio_map_.shape
        step = max(1, _CHUNK_ELEMENTS // (n_fp * n_anchors))
        return [slice(start, min(start + step, n_vectors)) for start in range(0, n_vectors, step)] or [slice(0, 0)]

    def _neighbors(self, X):
        """Estimates, neighbour scores and indices of the checked online vectors, chunk by chunk."""
        X = self._check_online(X)
        k = _check_n_neighbors(self.n_neighbors, self.positions_.shape[0])
        parts = [self._neighbors_chunk(X[chunk], k) for chunk in self._query_chunks(X.shape[0])]
        return tuple(np.concatenate(arrays) for arrays in zip(*parts, strict=True))


# --------------------------------------------------------------------------------------
# Deterministic kNN, eqs. (1)-(2)
# --------------------------------------------------------------------------------------


def _shepard_estimate(dist_k: np.ndarray, pos_k: np.ndarray, power: float) -> np.ndarray:
    """Eq. (1) with the weights of eq. (2); ``dist_k`` (..., k), ``pos_k`` (..., k, D)."""
    with np.errstate(over="ignore"):
        weights = 1.0 / (dist_k**power + SHEPARD_EPS)
    total = weights.sum(axis=-1, keepdims=True)
    overflow = total[..., 0] == 0.0
    if np.any(overflow):  # every d**p overflowed: the limit of the weights is the nearest one
        weights[overflow] = 0.0
        weights[overflow, 0] = 1.0
        total[overflow] = 1.0
    return np.einsum("...k,...kd->...d", weights / total, pos_k)


def _nearest(score: np.ndarray, k: int) -> np.ndarray:
    """Indices of the ``k`` smallest values along the last axis, ties to the lower index."""
    return np.argsort(score, axis=-1, kind="stable")[..., :k]


def _subset_chunks(n_subsets: int, n_vectors: int, n_fp: int):
    step = max(1, _CHUNK_ELEMENTS // max(1, n_vectors * n_fp))
    for start in range(0, n_subsets, step):
        yield slice(start, min(start + step, n_subsets))


def _subset_sums(masks: np.ndarray, terms: np.ndarray) -> np.ndarray:
    """``Σ_a mask[s, a] · terms[n, l, a]`` → (s, n, L), added in anchor order.

    A fixed order of additions gives every subset the same bits whatever the batch it is
    computed in (a matrix product's order depends on the shapes), so the estimators, the
    batch functions and any chunking agree exactly, ties included.
    """
    weights = masks.astype(float)
    out = np.zeros((masks.shape[0],) + terms.shape[:2])
    for a in range(terms.shape[2]):
        out += weights[:, a, None, None] * terms[:, :, a]
    return out


def _knn_batch(terms, masks, positions, k, power, metric):
    """Estimates, neighbour distances and indices for subsets ``masks`` (S, A)."""
    n_vectors, n_fp, _ = terms.shape
    n_subsets = masks.shape[0]
    est = np.empty((n_subsets, n_vectors, positions.shape[1]))
    dist_k = np.empty((n_subsets, n_vectors, k))
    idx_k = np.empty((n_subsets, n_vectors, k), dtype=np.intp)
    for chunk in _subset_chunks(n_subsets, n_vectors, n_fp):
        dist = _subset_sums(masks[chunk], terms)  # (s, n, L)
        if metric == "euclidean":
            dist = np.sqrt(np.maximum(dist, 0.0))
        idx = _nearest(dist, k)
        d = np.take_along_axis(dist, idx, axis=-1)
        est[chunk] = _shepard_estimate(d, positions[idx], power)
        dist_k[chunk], idx_k[chunk] = d, idx
    return est, dist_k, idx_k


def knn_from_terms(terms, subset_mask, positions, n_neighbors=3, power=1, metric="euclidean"):
    """kNN estimates (eqs. (1)–(2)) for a batch of anchor subsets from per-anchor terms.

    Parameters
    ----------
    terms : array_like, shape (n, L, A)
        Per-anchor distance terms from :meth:`KNNFingerprint.anchor_terms` (``|Δ|`` for
        Manhattan, ``Δ²`` for Euclidean, in dB or dB²).
    subset_mask : array_like of bool, shape (S, A) or (A,)
        Anchor subsets, one per row (e.g. :func:`anchor_subsets`).
    positions : array_like, shape (L, D)
        Fingerprint positions (``KNNFingerprint.positions_``).
    n_neighbors, power, metric
        ``k``, Shepard exponent ``p`` (> 0) and the metric the terms were computed for.

    Returns
    -------
    ndarray, shape (S, n, D) (or (n, D) for a 1-D ``subset_mask``)
        Equal to ``KNNFingerprint(k, metric, p, anchors=subset).fit(...).predict(X)`` per subset.
    """
    metric = _check_metric(metric)
    power = _check_power(power)
    terms, positions = _check_terms(terms, "terms", positions)
    masks, single = _as_subset_masks(subset_mask, terms.shape[2])
    k = _check_n_neighbors(n_neighbors, terms.shape[1])
    est = _knn_batch(terms, masks, positions, k, power, metric)[0]
    return est[0] if single else est


def _check_grid_ints(values, name: str, n_fingerprints: int) -> tuple[int, ...]:
    values = tuple(np.atleast_1d(np.asarray(values, dtype=object)).tolist())
    if not values:
        raise ValueError(f"{name} must hold at least one value")
    checked = tuple(_check_n_neighbors(v, n_fingerprints) for v in values)
    if len(set(checked)) != len(checked):
        raise ValueError(f"{name} holds duplicate values: {list(checked)}")
    return checked


def _cumulative_estimates(weights, pos_sorted, ks):
    """Weighted means of the first ``k`` neighbours for every ``k`` in ``ks``: (D, K, S, n).

    ``weights`` (kmax, S, n) and ``pos_sorted`` (D, kmax, S, n) are in neighbour order,
    nearest first, coordinates leading (long contiguous inner loops); a zero total weight
    (every weight underflowed) falls back to the nearest position.
    """
    wanted = {k: i for i, k in enumerate(ks)}
    nearest = pos_sorted[:, 0]
    out = np.empty((pos_sorted.shape[0], len(ks)) + weights.shape[1:])
    num = weights[0] * nearest
    den = weights[0].copy()
    for k in range(1, max(ks) + 1):
        if k > 1:
            num += weights[k - 1] * pos_sorted[:, k - 1]
            den += weights[k - 1]
        if k not in wanted:
            continue
        i = wanted[k]
        if k == 1:  # exactly the nearest position, as eqs. (1) and (3) reduce to
            out[:, i] = nearest
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            np.divide(num, den, out=out[:, i])
        zero = den == 0.0
        if np.any(zero):
            out[:, i][:, zero] = nearest[:, zero]
    return out


def _neighbour_first(values: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``values`` (s, n, L) at neighbour indices ``idx`` (k, s, n): (k, s, n)."""
    return np.take_along_axis(values, np.moveaxis(idx, 0, -1), axis=-1).transpose(2, 0, 1).copy()


def knn_grid_from_terms(terms, subset_mask, positions, n_neighbors=(1, 2, 3, 4, 5), powers=(1, 2, 3, 4, 5, 6),
                        metric="euclidean", *, coordinates_first=False):
    """kNN estimates (eqs. (1)–(2)) for every anchor subset × ``k`` × Shepard exponent at once.

    The neighbours of each (subset, vector) are sorted once and the estimates for all ``k``
    come from cumulative sums of the Shepard weights, one pass per exponent; the result
    equals :func:`knn_from_terms` per (``k``, ``p``) up to rounding (same neighbour order and
    ties, to the lower fingerprint index).

    Parameters
    ----------
    terms : array_like, shape (n, L, A)
        Per-anchor distance terms from :meth:`KNNFingerprint.anchor_terms`.
    subset_mask : array_like of bool, shape (S, A) or (A,)
        Anchor subsets, one per row.
    positions : array_like, shape (L, D)
        Fingerprint positions (``KNNFingerprint.positions_``).
    n_neighbors : sequence of int, length K
        The values of ``k`` (each in ``1..L``, no duplicates).
    powers : sequence of float, length P
        The Shepard exponents ``p_s`` (> 0).  With ``k = 1`` they all give the nearest
        fingerprint position (``[:, k==1, p]`` is the same for every ``p``).
    metric : {"euclidean", "manhattan"}
        The metric the terms were computed for.
    coordinates_first : bool
        Return the coordinate axis first, ``(D, S, K, P, n)`` (no transpose; for callers
        that process the coordinates separately, such as :mod:`wsnlib.optimize`).

    Returns
    -------
    ndarray, shape (S, K, P, n, D) (or (K, P, n, D) for a 1-D ``subset_mask``)
    """
    metric = _check_metric(metric)
    terms, positions = _check_terms(terms, "terms", positions)
    masks, single = _as_subset_masks(subset_mask, terms.shape[2])
    ks = _check_grid_ints(n_neighbors, "n_neighbors", terms.shape[1])
    powers = tuple(np.atleast_1d(np.asarray(powers, dtype=object)).tolist())
    if not powers:
        raise ValueError("powers must hold at least one value")
    powers = tuple(_check_power(p) for p in powers)
    kmax = max(ks)
    n_vectors, n_fp, _ = terms.shape
    out = np.empty((positions.shape[1], masks.shape[0], len(ks), len(powers), n_vectors))
    coords = np.ascontiguousarray(positions.T)                                  # (D, L)
    for chunk in _subset_chunks(masks.shape[0], n_vectors, n_fp):
        dist = _subset_sums(masks[chunk], terms)                               # (s, n, L)
        if metric == "euclidean":
            dist = np.sqrt(np.maximum(dist, 0.0))
        idx = np.moveaxis(_nearest(dist, kmax), -1, 0)                         # (kmax, s, n)
        d = _neighbour_first(dist, idx)                                        # (kmax, s, n)
        pos = coords[:, idx]                                                   # (D, kmax, s, n)
        for j, power in enumerate(powers):
            with np.errstate(over="ignore"):
                weights = 1.0 / (d**power + SHEPARD_EPS)                      # eq. (2)
            out[:, chunk, :, j] = np.moveaxis(_cumulative_estimates(weights, pos, ks), 2, 1)  # eq. (1)
    if not coordinates_first:
        out = np.moveaxis(out, 0, -1)
    return out[..., 0, :, :, :] if single and coordinates_first else (out[0] if single else out)


class KNNFingerprint(_FingerprintEstimator):
    """Deterministic fingerprinting: kNN over the radio map with Shepard weights (eqs. (1)–(2)).

    Parameters
    ----------
    n_neighbors : int
        ``k``, the number of nearest fingerprints averaged (1 = nearest neighbour).
    metric : {"euclidean", "manhattan"}
        Distance in the RSS space (dB).
    power : float
        Shepard exponent ``p_s`` (> 0; the paper uses positive integers).
    anchors : None, sequence of int, or bool mask of length A
        Anchors used for the distances (default all); ``X`` keeps all ``A`` columns.
    floor_rss : float
        Radio-map value (dBm) of an anchor with no reading at a position (default −100).

    Attributes
    ----------
    radio_map_ : ndarray (L, A)
        Mean RSS (dBm) per fingerprint position and anchor, missing readings excluded.
    positions_ : ndarray (L, D)
        Fingerprint positions, in order of first appearance in ``y``.
    n_readings_ : ndarray of int (L, A)
        Readings behind each radio-map value.
    anchor_mask_ : ndarray of bool (A,)
        The anchors in use.
    n_features_in_ : int
        ``A``.
    """

    def __init__(self, n_neighbors=3, metric="euclidean", power=1, anchors=None, floor_rss=-100.0):
        self.n_neighbors = n_neighbors
        self.metric = metric
        self.power = power
        self.anchors = anchors
        self.floor_rss = floor_rss

    def fit(self, X, y):
        """Build the radio map from training vectors ``X`` (n, A; NaN = missing) at positions ``y`` (n, D)."""
        _check_metric(self.metric)
        _check_power(self.power)
        self._fit_radio_map(X, y)
        return self

    def anchor_terms(self, X) -> np.ndarray:
        """Per-anchor distance terms, shape (n, L, A), for every anchor (``anchors`` ignored).

        ``|x_a − m_la|`` (dB) for Manhattan, ``(x_a − m_la)²`` (dB²) for Euclidean; a subset's
        Manhattan distance is the sum of its terms, its Euclidean distance the root of the sum.
        """
        return self._terms(self._check_online(X))

    def _terms(self, X: np.ndarray) -> np.ndarray:
        diff = X[:, None, :] - self.radio_map_[None, :, :]
        return np.abs(diff) if _check_metric(self.metric) == "manhattan" else diff * diff

    def _neighbors_chunk(self, X: np.ndarray, k: int):
        terms = self._terms(X)
        est, dist, idx = _knn_batch(
            terms, self.anchor_mask_[None, :], self.positions_, k, _check_power(self.power), self.metric
        )
        return est[0], dist[0], idx[0]

    def kneighbors(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Distances (dB) and fingerprint indices of the ``k`` nearest fingerprints, each (n, k), nearest first."""
        _, dist, idx = self._neighbors(X)
        return dist, idx

    def predict(self, X) -> np.ndarray:
        """Estimated positions (n, D) of the complete online vectors ``X`` (n, A), eq. (1)."""
        return self._neighbors(X)[0]


# --------------------------------------------------------------------------------------
# Probabilistic kNN, eqs. (3)-(4)
# --------------------------------------------------------------------------------------


def _round_db(values: np.ndarray) -> np.ndarray:
    """Round to the 1-dBm bin ``[g − 0.5, g + 0.5)``."""
    return np.floor(values + 0.5)


def _bin_mass(offset: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Mass of N(0, σ²) in ``[offset − 0.5, offset + 0.5)``, accurate in both tails."""
    a = np.abs(offset)
    return ndtr((0.5 - a) / sigma) - ndtr((-0.5 - a) / sigma)


def _pknn_batch(loglik, masks, positions, k):
    """Estimates, top-k log posteriors and indices for subsets ``masks`` (S, A)."""
    n_vectors, n_fp, _ = loglik.shape
    n_subsets = masks.shape[0]
    est = np.empty((n_subsets, n_vectors, positions.shape[1]))
    logpost_k = np.empty((n_subsets, n_vectors, k))
    idx_k = np.empty((n_subsets, n_vectors, k), dtype=np.intp)
    for chunk in _subset_chunks(n_subsets, n_vectors, n_fp):
        ll = _subset_sums(masks[chunk], loglik)  # (s, n, L): log P(r | s_l)
        logpost = ll - logsumexp(ll, axis=-1, keepdims=True)  # eq. (4), uniform prior cancels
        idx = _nearest(-logpost, k)
        lp = np.take_along_axis(logpost, idx, axis=-1)
        weights = np.exp(lp - logsumexp(lp, axis=-1, keepdims=True))  # eq. (3) weights, summing to 1
        est[chunk] = np.einsum("...k,...kd->...d", weights, positions[idx])
        logpost_k[chunk], idx_k[chunk] = lp, idx
    return est, logpost_k, idx_k


def pknn_from_loglik(loglik, subset_mask, positions, n_neighbors=3):
    """p-kNN estimates (eqs. (3)–(4)) for a batch of anchor subsets from per-anchor log-likelihoods.

    Parameters
    ----------
    loglik : array_like, shape (n, L, A)
        ``log P(r_a | s_l)`` from :meth:`ProbabilisticKNN.anchor_log_likelihoods`.
    subset_mask : array_like of bool, shape (S, A) or (A,)
        Anchor subsets, one per row.
    positions : array_like, shape (L, D)
        Fingerprint positions (``ProbabilisticKNN.positions_``).
    n_neighbors : int
        ``k``.

    Returns
    -------
    ndarray, shape (S, n, D) (or (n, D) for a 1-D ``subset_mask``)
        Equal to ``ProbabilisticKNN(k, ..., anchors=subset).fit(...).predict(X)`` per subset.
    """
    loglik, positions = _check_terms(loglik, "loglik", positions)
    if np.any(np.isinf(loglik)):
        raise ValueError("loglik contains inf (log-PMFs must be floored)")
    masks, single = _as_subset_masks(subset_mask, loglik.shape[2])
    k = _check_n_neighbors(n_neighbors, loglik.shape[1])
    est = _pknn_batch(loglik, masks, positions, k)[0]
    return est[0] if single else est


def pknn_grid_from_loglik(loglik, subset_mask, positions, n_neighbors=(1, 2, 3, 4, 5), *, coordinates_first=False):
    """p-kNN estimates (eqs. (3)–(4)) for every anchor subset × ``k`` at once.

    The posteriors of each (subset, vector) are ranked once and the estimates for all ``k``
    come from cumulative sums of the posterior weights; equal to :func:`pknn_from_loglik`
    per ``k`` up to rounding (same ranking and ties).

    Parameters
    ----------
    loglik : array_like, shape (n, L, A)
        ``log P(r_a | s_l)`` from :meth:`ProbabilisticKNN.anchor_log_likelihoods`.
    subset_mask : array_like of bool, shape (S, A) or (A,)
    positions : array_like, shape (L, D)
    n_neighbors : sequence of int, length K
        The values of ``k`` (each in ``1..L``, no duplicates).
    coordinates_first : bool
        Return ``(D, S, K, n)`` instead (see :func:`knn_grid_from_terms`).

    Returns
    -------
    ndarray, shape (S, K, n, D) (or (K, n, D) for a 1-D ``subset_mask``)
    """
    loglik, positions = _check_terms(loglik, "loglik", positions)
    if np.any(np.isinf(loglik)):
        raise ValueError("loglik contains inf (log-PMFs must be floored)")
    masks, single = _as_subset_masks(subset_mask, loglik.shape[2])
    ks = _check_grid_ints(n_neighbors, "n_neighbors", loglik.shape[1])
    kmax = max(ks)
    n_vectors, n_fp, _ = loglik.shape
    out = np.empty((positions.shape[1], masks.shape[0], len(ks), n_vectors))
    coords = np.ascontiguousarray(positions.T)                                  # (D, L)
    for chunk in _subset_chunks(masks.shape[0], n_vectors, n_fp):
        ll = _subset_sums(masks[chunk], loglik)                                # (s, n, L)
        logpost = ll - logsumexp(ll, axis=-1, keepdims=True)                   # eq. (4)
        idx = np.moveaxis(_nearest(-logpost, kmax), -1, 0)                     # (kmax, s, n)
        lp = _neighbour_first(logpost, idx)                                    # (kmax, s, n), best first
        weights = np.exp(lp - lp[:1])                                          # ∝ posteriors, first = 1
        out[:, chunk] = np.moveaxis(_cumulative_estimates(weights, coords[:, idx], ks), 2, 1)  # eq. (3)
    if not coordinates_first:
        out = np.moveaxis(out, 0, -1)
    return out[:, 0] if single and coordinates_first else (out[0] if single else out)


class ProbabilisticKNN(_FingerprintEstimator):
    """Probabilistic fingerprinting (p-kNN): per-anchor RSS PMFs, Bayes posterior, eqs. (3)–(4).

    Parameters
    ----------
    n_neighbors : int
        ``k``, the number of most probable positions averaged (1 = MAP position).
    pmf : {"histogram", "parzen", "gmm"}
        PMF estimator per (position, anchor); see the module docstring.
    floor_probability : float
        ε, the least probability of any 1-dBm bin before renormalisation (0 < ε < 1).
    bandwidth_db : float or None
        Parzen kernel standard deviation (dB); None = Silverman's rule per cell.
    min_bandwidth_db : float
        Least Parzen bandwidth under Silverman's rule, and ``sqrt(reg_covar)`` of the GMMs (dB).
    n_components : int
        Most Gaussian components per GMM.
    anchors : None, sequence of int, or bool mask of length A
        Anchors used for the likelihood (default all); ``X`` keeps all ``A`` columns.
    floor_rss : float
        Value (dBm) standing for an anchor with no reading at a position (default −100).
    grid_margin_db : int
        Bins added on each side of the range of training readings (and ``floor_rss``).
    random_state : None, int or numpy.random.Generator
        Seeds the GMM fits (ignored by the other PMFs).

    Attributes
    ----------
    radio_map_, positions_, n_readings_, anchor_mask_, n_features_in_
        As in :class:`KNNFingerprint`.
    grid_ : ndarray of int (G,)
        The integer dBm values the PMFs are defined on.
    pmf_ : ndarray (L, A, G)
        PMF per position and anchor (each sums to 1, every entry > 0).
    log_pmf_ : ndarray (L, A, G)
        ``log(pmf_)``.
    bandwidth_ : ndarray (L, A)
        Parzen bandwidths (dB) used; only with ``pmf="parzen"``.
    """

    def __init__(
        self,
        n_neighbors=3,
        pmf="histogram",
        floor_probability=1e-4,
        bandwidth_db=None,
        min_bandwidth_db=0.5,
        n_components=2,
        anchors=None,
        floor_rss=-100.0,
        grid_margin_db=10,
        random_state=None,
    ):
        self.n_neighbors = n_neighbors
        self.pmf = pmf
        self.floor_probability = floor_probability
        self.bandwidth_db = bandwidth_db
        self.min_bandwidth_db = min_bandwidth_db
        self.n_components = n_components
        self.anchors = anchors
        self.floor_rss = floor_rss
        self.grid_margin_db = grid_margin_db
        self.random_state = random_state

    def _check_params(self):
        if self.pmf not in PMF_METHODS:
            raise ValueError(f"pmf must be one of {PMF_METHODS}, got {self.pmf!r}")
        eps = check_positive(self.floor_probability, "floor_probability")
        if eps >= 1.0:
            raise ValueError(f"floor_probability must be < 1, got {self.floor_probability!r}")
        if self.bandwidth_db is not None:
            check_positive(self.bandwidth_db, "bandwidth_db")
        check_positive(self.min_bandwidth_db, "min_bandwidth_db")
        nc = self.n_components
        if isinstance(nc, bool) or not isinstance(nc, numbers.Integral) or nc < 1:
            raise ValueError(f"n_components must be a positive integer, got {nc!r}")
        margin = self.grid_margin_db
        if isinstance(margin, bool) or not isinstance(margin, numbers.Integral):
            raise ValueError(f"grid_margin_db must be a non-negative integer, got {margin!r}")
        check_nonnegative(margin, "grid_margin_db")
        return eps

    def fit(self, X, y):
        """Radio map and PMFs from training vectors ``X`` (n, A; NaN = missing) at positions ``y`` (n, D)."""
        eps = self._check_params()
        X, inverse = self._fit_radio_map(X, y)
        n_fp, n_anchors = self.radio_map_.shape
        floor_bin = int(_round_db(np.float64(self.floor_rss)))
        rounded = _round_db(X)
        valid = ~np.isnan(X)
        lo = min(floor_bin, int(np.min(rounded[valid]))) if valid.any() else floor_bin
        hi = max(floor_bin, int(np.max(rounded[valid]))) if valid.any() else floor_bin
        margin = int(self.grid_margin_db)
        self.grid_ = np.arange(lo - margin, hi + margin + 1)
        n_bins = self.grid_.size

        cell = (inverse[:, None] * n_anchors + np.arange(n_anchors))[valid]
        bins = (rounded[valid] - self.grid_[0]).astype(np.intp)
        counts = np.bincount(cell * n_bins + bins, minlength=n_fp * n_anchors * n_bins).astype(float)
        counts = counts.reshape(n_fp, n_anchors, n_bins)
        empty = self.n_readings_ == 0
        counts[empty, floor_bin - self.grid_[0]] = 1.0  # point mass at the floor for cells never heard

        if self.pmf == "histogram":
            pmf = counts
        elif self.pmf == "parzen":
            pmf = self._parzen(counts, empty)
        else:
            pmf = self._gmm(X, inverse)
        pmf[empty] = counts[empty]  # cells never heard: the point mass at floor_rss, whatever the method
        pmf = pmf / pmf.sum(axis=-1, keepdims=True)
        pmf = np.maximum(pmf, eps)
        self.pmf_ = pmf / pmf.sum(axis=-1, keepdims=True)
        self.log_pmf_ = np.log(self.pmf_)
        return self

    def _parzen(self, counts: np.ndarray, empty: np.ndarray) -> np.ndarray:
        n_bins = counts.shape[-1]
        m = counts.sum(axis=-1)
        min_bw = float(self.min_bandwidth_db)
        if self.bandwidth_db is not None:
            bandwidth = np.full(m.shape, float(self.bandwidth_db))
        else:
            grid = self.grid_.astype(float)
            mean = (counts * grid).sum(axis=-1) / m
            var = (counts * (grid - mean[..., None]) ** 2).sum(axis=-1) / np.maximum(m - 1.0, 1.0)
            sigma = np.sqrt(var)
            cdf = np.cumsum(counts, axis=-1) / m[..., None]
            q25 = grid[np.argmax(cdf >= 0.25, axis=-1)]
            q75 = grid[np.argmax(cdf >= 0.75, axis=-1)]
            iqr = (q75 - q25) / 1.34
            spread = np.where(iqr > 0, np.minimum(sigma, iqr), sigma)
            bandwidth = np.maximum(0.9 * spread * m**-0.2, min_bw)
        bandwidth[empty] = min_bw  # unused: those cells keep their point mass
        self.bandwidth_ = bandwidth
        reach = int(min(n_bins - 1, np.ceil(12.0 * bandwidth.max()) + 1))
        out = np.zeros_like(counts)
        for offset in range(-reach, reach + 1):
            kernel = _bin_mass(np.float64(offset), bandwidth)[..., None]
            if offset >= 0:
                out[..., offset:] += kernel * counts[..., : n_bins - offset]
            else:
                out[..., :offset] += kernel * counts[..., -offset:]
        return out

    def _gmm(self, X: np.ndarray, inverse: np.ndarray) -> np.ndarray:
        from sklearn.mixture import GaussianMixture

        n_fp, n_anchors = self.radio_map_.shape
        min_bw = float(self.min_bandwidth_db)
        n_max = int(self.n_components)
        rng = np.random.default_rng(self.random_state)
        seeds = rng.integers(0, 2**31 - 1, size=(n_fp, n_anchors))
        means = np.zeros((n_fp, n_anchors, n_max))
        sigmas = np.ones((n_fp, n_anchors, n_max))
        weights = np.zeros((n_fp, n_anchors, n_max))
        order = np.argsort(inverse, kind="stable")
        bounds = np.searchsorted(inverse[order], np.arange(n_fp + 1))
        for pos in range(n_fp):
            rows = X[order[bounds[pos] : bounds[pos + 1]]]
            for anchor in range(n_anchors):
                values = rows[:, anchor]
                values = values[~np.isnan(values)]
                if values.size == 0:  # replaced by the point mass at floor_rss in fit
                    weights[pos, anchor, 0] = 1.0
                    continue
                n_comp = min(n_max, np.unique(values).size)
                if n_comp == 1 and np.ptp(values) == 0:
                    means[pos, anchor, 0], sigmas[pos, anchor, 0], weights[pos, anchor, 0] = values[0], min_bw, 1.0
                    continue
                gmm = GaussianMixture(
                    n_components=n_comp,
                    covariance_type="spherical",
                    reg_covar=min_bw**2,
                    random_state=int(seeds[pos, anchor]),
                ).fit(values[:, None])
                means[pos, anchor, :n_comp] = gmm.means_[:, 0]
                sigmas[pos, anchor, :n_comp] = np.sqrt(gmm.covariances_)
                weights[pos, anchor, :n_comp] = gmm.weights_
        offset = self.grid_[None, None, :, None] - means[:, :, None, :]  # (L, A, G, C)
        mass = _bin_mass(offset, sigmas[:, :, None, :])
        return np.einsum("lagc,lac->lag", mass, weights)

    def anchor_log_likelihoods(self, X) -> np.ndarray:
        """``log P(r_a | s_l)`` per online vector, fingerprint position and anchor, shape (n, L, A).

        Every anchor is returned (``anchors`` ignored); a subset's log-likelihood is the sum
        of its columns.  Readings are rounded to 1 dBm and clipped to ``grid_``.
        """
        return self._loglik(self._check_online(X))

    def _loglik(self, X: np.ndarray) -> np.ndarray:
        bins = np.clip(_round_db(X) - self.grid_[0], 0, self.grid_.size - 1).astype(np.intp)  # (n, A)
        anchor_idx = np.arange(X.shape[1])
        return np.transpose(self.log_pmf_[:, anchor_idx[None, :], bins], (1, 0, 2))

    def _neighbors_chunk(self, X: np.ndarray, k: int):
        est, lp, idx = _pknn_batch(self._loglik(X), self.anchor_mask_[None, :], self.positions_, k)
        return est[0], lp[0], idx[0]

    def predict_log_proba(self, X) -> np.ndarray:
        """Log posterior ``log P(s_l | r)`` (eq. (4), uniform prior), shape (n, L), over the selected anchors."""
        X = self._check_online(X)
        weights = self.anchor_mask_.astype(float)
        out = np.empty((X.shape[0], self.positions_.shape[0]))
        for chunk in self._query_chunks(X.shape[0]):
            loglik = self._loglik(X[chunk]) @ weights
            out[chunk] = loglik - logsumexp(loglik, axis=-1, keepdims=True)
        return out

    def predict_proba(self, X) -> np.ndarray:
        """Posterior ``P(s_l | r)``, shape (n, L); rows sum to 1."""
        return np.exp(self.predict_log_proba(X))

    def kneighbors(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Log posteriors and fingerprint indices of the ``k`` most probable positions, each (n, k), best first."""
        _, lp, idx = self._neighbors(X)
        return lp, idx

    def predict(self, X) -> np.ndarray:
        """Estimated positions (n, D) of the complete online vectors ``X`` (n, A), eq. (3)."""
        return self._neighbors(X)[0]


def fit_predict_by_group(estimator, X_train, y_train, groups_train, X, groups) -> np.ndarray:
    """Fit one copy of ``estimator`` per group (e.g. per user and target) and predict that group's rows.

    Fingerprinting is per user and per target node (paper 002, Sec. 4.1): each has its own
    radio map.  This fits :func:`sklearn.base.clone` of ``estimator`` on each group's training
    vectors and predicts the online vectors of the same group.

    Parameters
    ----------
    estimator : KNNFingerprint or ProbabilisticKNN (unfitted; only its parameters are used)
    X_train : array_like, shape (n_train, A)
    y_train : array_like, shape (n_train, D)
    groups_train : array_like, shape (n_train,)
        Group key per training vector (any hashable, e.g. ``"U1/T1"``).
    X : array_like, shape (n, A)
        Online vectors (complete: no NaN).
    groups : array_like, shape (n,)
        Group key per online vector; every key must occur in ``groups_train``.

    Returns
    -------
    numpy.ndarray, shape (n, D)
    """
    from sklearn.base import clone

    X_train = np.asarray(X_train, dtype=float)
    y_train = np.asarray(y_train, dtype=float)
    groups_train = np.asarray(groups_train)
    X = np.asarray(X, dtype=float)
    groups = np.asarray(groups)
    if len(groups_train) != len(X_train) or len(y_train) != len(X_train):
        raise ValueError("X_train, y_train and groups_train must have the same length")
    if len(groups) != len(X):
        raise ValueError("X and groups must have the same length")
    missing = set(np.unique(groups)) - set(np.unique(groups_train))
    if missing:
        raise ValueError(f"groups without training vectors: {sorted(map(str, missing))}")
    out = np.empty((len(X), y_train.shape[1]))
    for key in np.unique(groups):
        rows, train_rows = groups == key, groups_train == key
        out[rows] = clone(estimator).fit(X_train[train_rows], y_train[train_rows]).predict(X[rows])
    return out
