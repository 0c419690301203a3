"""Radio-fingerprinting estimators (scikit-learn style): :class:`KNNFingerprint` (kNN with
Shepard weights, eqs. (1)–(2)), :class:`ProbabilisticKNN` (p-kNN with histogram, Parzen or GMM
PMFs, eqs. (3)–(4)), and :func:`fit_predict_by_group` (one radio map per user and target).

Paper 002, Section 3.1.  ``__init__`` stores parameters only, ``fit`` returns ``self``,
learned attributes end in ``_``.  Conventions (units, missing readings, anchors, ties): the
:mod:`wsnlib.radio` docstring.  The batch maths is shared with the grid engine
(:mod:`wsnlib.radio.grid`).
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp, ndtr
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from wsnlib._validation import check_choice, check_count, check_positive
from wsnlib.radio import _checks
from wsnlib.radio._checks import (
    PMF_METHODS,
    RSS_RANGE_DBM,
    _check_metric,
    _check_n_neighbors,
    _check_online_missing,
    _check_power,
    _check_training,
    _group_positions,
    _resolve_anchors,
)
from wsnlib.radio.grid import _knn_batch, _pknn_batch, _subset_sums

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
        _check_online_missing(self.online_missing)
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

    def _check_online(self, X, *, selected: bool = False) -> np.ndarray:
        """The online vectors as a float array (n, A), checked.  NaN (a missing reading) raises, or with
        ``online_missing="skip"`` stays; then every vector needs a reading on some anchor (``selected``:
        on some selected anchor), else there is nothing to compare."""
        check_is_fitted(self, "radio_map_")
        try:
            X = np.asarray(X, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"X must be a numeric array, got {type(X).__name__}") from exc
        if X.ndim != 2:
            raise ValueError(f"X must have shape (n_vectors, n_anchors); got {X.shape} (one vector: X.reshape(1, -1))")
        if X.shape[1] != self.n_features_in_:
            raise ValueError(f"X has vectors of length {X.shape[1]}, the estimator was fitted with "
                             f"{self.n_features_in_} anchors")
        missing = np.isnan(X)
        if np.any(missing) and _check_online_missing(self.online_missing) == "raise":
            bad = tuple(int(i) for i in np.argwhere(missing)[0])
            raise ValueError(f"X contains NaN (a missing reading, first at index {bad}); online vectors must be "
                             "complete: fill missing readings first, e.g. "
                             f"np.where(np.isnan(X), {self.floor_rss!r}, X) (the floor_rss level) or with the "
                             "anchor's last reading, or leave them out with online_missing='skip'")
        if np.any(np.isinf(X)):
            raise ValueError("X contains inf")
        heard = ~missing[:, self.anchor_mask_] if selected else ~missing
        if X.shape[0] and not np.all(heard.any(axis=1)):
            row = int(np.argmin(heard.any(axis=1)))
            raise ValueError(f"X row {row} has no reading on any {'selected ' if selected else ''}anchor (all NaN): "
                             "with online_missing='skip' a vector needs at least one reading")
        return X

    def _query_chunks(self, n_vectors: int) -> list[slice]:
        """Slices of at most ``_CHUNK_ELEMENTS // (L·A)`` online vectors (one empty slice for none)."""
        n_fp, n_anchors = self.radio_map_.shape
        step = max(1, _checks._CHUNK_ELEMENTS // (n_fp * n_anchors))
        return [slice(start, min(start + step, n_vectors)) for start in range(0, n_vectors, step)] or [slice(0, 0)]

    def _neighbors(self, X):
        """Estimates, neighbour scores and indices of the checked online vectors, chunk by chunk."""
        X = self._check_online(X, selected=True)
        k = _check_n_neighbors(self.n_neighbors, self.positions_.shape[0])
        parts = [self._neighbors_chunk(X[chunk], k) for chunk in self._query_chunks(X.shape[0])]
        return tuple(np.concatenate(arrays) for arrays in zip(*parts, strict=True))

# --------------------------------------------------------------------------------------
# Deterministic kNN, eqs. (1)-(2)
# --------------------------------------------------------------------------------------


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
    online_missing : {"raise", "skip"}
        A missing reading (NaN) in an online vector: ``"raise"`` (default; fill it first) or
        ``"skip"``: the distance of that vector sums the terms of the anchors it has readings
        from only (the same anchors for every fingerprint, so the ranking stays fair).

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

    def __init__(self, n_neighbors=3, metric="euclidean", power=1, anchors=None, floor_rss=-100.0,
                 online_missing="raise"):
        self.n_neighbors = n_neighbors
        self.metric = metric
        self.power = power
        self.anchors = anchors
        self.floor_rss = floor_rss
        self.online_missing = online_missing

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
        A skipped reading (``online_missing="skip"``) has the term 0 at every fingerprint.
        """
        return self._terms(self._check_online(X))

    def _terms(self, X: np.ndarray) -> np.ndarray:
        diff = X[:, None, :] - self.radio_map_[None, :, :]
        terms = np.abs(diff) if _check_metric(self.metric) == "manhattan" else diff * diff
        missing = np.isnan(X)
        if np.any(missing):  # online_missing="skip" (checked): the anchor adds nothing for that vector
            terms[np.broadcast_to(missing[:, None, :], terms.shape)] = 0.0
        return terms

    def _neighbors_chunk(self, X: np.ndarray, k: int):
        terms = self._terms(X)
        est, dist, idx = _knn_batch(terms, self.anchor_mask_[None, :], self.positions_, k, _check_power(self.power),
                                    self.metric)
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
    online_missing : {"raise", "skip"}
        A missing reading (NaN) in an online vector: ``"raise"`` (default; fill it first) or
        ``"skip"``: that anchor is left out of that vector's likelihood (marginalised: its
        log-PMF term is 0 at every position).

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

    def __init__(self, n_neighbors=3, pmf="histogram", floor_probability=1e-4, bandwidth_db=None, min_bandwidth_db=0.5,
                 n_components=2, anchors=None, floor_rss=-100.0, grid_margin_db=10, random_state=None,
                 online_missing="raise"):
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
        self.online_missing = online_missing

    def _check_params(self):
        check_choice(self.pmf, "pmf", PMF_METHODS)
        eps = check_positive(self.floor_probability, "floor_probability")
        if eps >= 1.0:
            raise ValueError(f"floor_probability must be < 1, got {self.floor_probability!r}")
        if self.bandwidth_db is not None:
            check_positive(self.bandwidth_db, "bandwidth_db")
        check_positive(self.min_bandwidth_db, "min_bandwidth_db")
        check_count(self.n_components, "n_components")
        check_count(self.grid_margin_db, "grid_margin_db", 0)
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
        from sklearn import config_context
        from sklearn.mixture import GaussianMixture
        from threadpoolctl import threadpool_limits

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
        cells = []  # cells to fit: (position, anchor, readings, components)
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
                cells.append((pos, anchor, values, n_comp))

        # One thread (OpenMP and BLAS) for these tiny 1-D fits: the threads of their k-means start
        # cost far more than they save (on two busy cores, 72 s instead of 6 s for PABR's 81 x 12
        # cells of 300 two-packet means), and one thread gives the same bits on every machine.
        with config_context(assume_finite=True, skip_parameter_validation=True), threadpool_limits(limits=1):
            for pos, anchor, values, n_comp in cells:  # the readings are checked
                gmm = GaussianMixture(n_components=n_comp, covariance_type="spherical", reg_covar=min_bw**2,
                                      random_state=int(seeds[pos, anchor])).fit(values[:, None])
                means[pos, anchor, :n_comp] = gmm.means_[:, 0]
                sigmas[pos, anchor, :n_comp] = np.sqrt(gmm.covariances_)
                weights[pos, anchor, :n_comp] = gmm.weights_
        offset = self.grid_[None, None, :, None] - means[:, :, None, :]  # (L, A, G, C)
        mass = _bin_mass(offset, sigmas[:, :, None, :])
        return np.einsum("lagc,lac->lag", mass, weights)

    def anchor_log_likelihoods(self, X) -> np.ndarray:
        """``log P(r_a | s_l)`` per online vector, fingerprint position and anchor, shape (n, L, A).

        Every anchor is returned (``anchors`` ignored); a subset's log-likelihood is the sum
        of its columns.  Readings are rounded to 1 dBm and clipped to ``grid_``.  A skipped
        reading (``online_missing="skip"``) has the term 0 (log 1) at every position.
        """
        return self._loglik(self._check_online(X))

    def _loglik(self, X: np.ndarray) -> np.ndarray:
        missing = np.isnan(X)
        rounded = _round_db(np.where(missing, self.grid_[0], X))
        bins = np.clip(rounded - self.grid_[0], 0, self.grid_.size - 1).astype(np.intp)  # (n, A)
        anchor_idx = np.arange(X.shape[1])
        loglik = np.transpose(self.log_pmf_[:, anchor_idx[None, :], bins], (1, 0, 2))
        if np.any(missing):  # online_missing="skip" (checked): marginalised out
            loglik[np.broadcast_to(missing[:, None, :], loglik.shape)] = 0.0
        return loglik

    def _neighbors_chunk(self, X: np.ndarray, k: int):
        est, lp, idx = _pknn_batch(self._loglik(X), self.anchor_mask_[None, :], self.positions_, k)
        return est[0], lp[0], idx[0]

    def predict_log_proba(self, X) -> np.ndarray:
        """Log posterior ``log P(s_l | r)`` (eq. (4), uniform prior), shape (n, L), over the selected anchors."""
        X = self._check_online(X, selected=True)
        out = np.empty((X.shape[0], self.positions_.shape[0]))
        for chunk in self._query_chunks(X.shape[0]):
            loglik = _subset_sums(self.anchor_mask_[None, :], self._loglik(X[chunk]))[0]  # as kneighbors sums
            out[chunk] = loglik - logsumexp(loglik, axis=-1, keepdims=True)
        return out

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
