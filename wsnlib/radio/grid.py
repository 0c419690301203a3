"""The grid engine of radio fingerprinting: kNN and p-kNN estimates for many anchor subsets,
``k`` and Shepard exponents at once, from per-anchor terms computed by one fit.

Paper 002, eqs. (1)–(4).  The estimators (:mod:`wsnlib.radio.estimators`) compute the
per-anchor terms (:meth:`~wsnlib.radio.KNNFingerprint.anchor_terms`,
:meth:`~wsnlib.radio.ProbabilisticKNN.anchor_log_likelihoods`); the functions here sum them
over anchor subsets (:func:`anchor_subsets`) and rank the fingerprints, which is what the
exhaustive parameter search (:mod:`wsnlib.optimize`) evaluates.  The estimators' own
``predict`` runs through the same batch functions, so both agree bit for bit.  Conventions:
the :mod:`wsnlib.radio` docstring.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.special import logsumexp

from wsnlib._validation import check_count
from wsnlib.radio import _checks
from wsnlib.radio._checks import (
    _as_subset_masks,
    _check_grid_ints,
    _check_metric,
    _check_n_neighbors,
    _check_power,
    _check_terms,
)

#: The constant in the denominator of the Shepard weights, eq. (2).
SHEPARD_EPS = 1e-4


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
    check_count(n_anchors, "n_anchors")
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
# kNN, eqs. (1)-(2)
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
    step = max(1, _checks._CHUNK_ELEMENTS // max(1, n_vectors * n_fp))
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
        Per-anchor distance terms from :meth:`~wsnlib.radio.KNNFingerprint.anchor_terms` (``|Δ|`` for
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
        Per-anchor distance terms from :meth:`~wsnlib.radio.KNNFingerprint.anchor_terms`.
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


# --------------------------------------------------------------------------------------
# p-kNN, eqs. (3)-(4)
# --------------------------------------------------------------------------------------


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
        ``log P(r_a | s_l)`` from :meth:`~wsnlib.radio.ProbabilisticKNN.anchor_log_likelihoods`.
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
    loglik, positions = _check_terms(loglik, "loglik", positions, log_pmf=True)
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
        ``log P(r_a | s_l)`` from :meth:`~wsnlib.radio.ProbabilisticKNN.anchor_log_likelihoods`.
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
    loglik, positions = _check_terms(loglik, "loglik", positions, log_pmf=True)
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
