"""Input checks and shared constants of the radio-fingerprinting estimators and grid engine.

Private to :mod:`wsnlib.radio`: :mod:`wsnlib.radio.estimators` and :mod:`wsnlib.radio.grid`
both validate through these functions, so an argument is checked the same way whichever
entry point receives it.  The conventions are in the :mod:`wsnlib.radio` docstring.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array, check_choice, check_count, check_positive

METRICS = ("euclidean", "manhattan")
PMF_METHODS = ("histogram", "parzen", "gmm")

#: What the estimators do with a missing reading (NaN) in an online vector: ``"raise"`` a
#: ``ValueError`` (fill it first), or ``"skip"`` that anchor for that vector.
ONLINE_MISSING = ("raise", "skip")

#: Largest number of (subset, vector, fingerprint) distances held in memory at once by the
#: batch functions (they process anchor subsets in chunks of this size), and of (vector,
#: fingerprint, anchor) values by the estimators' online methods (they process vectors in
#: chunks of this size).  Read at call time (``_checks._CHUNK_ELEMENTS``), so a test can
#: lower it in this one module.
_CHUNK_ELEMENTS = 1 << 22

#: Plausible range (dBm) of an RSS reading and of ``floor_rss``: below any receiver's
#: sensitivity floor (about −100 dBm for IEEE 802.15.4 radios; the CC2420's 8-bit register
#: reads down to −128 dBm, see :data:`wsnlib.io.rss.RSS_RANGE_DBM`) up to a transmitter's
#: maximum output power (+20 dBm).  Values outside are glitches or unit errors.
RSS_RANGE_DBM: tuple[float, float] = (-130.0, 20.0)


def _check_n_neighbors(n_neighbors, n_fingerprints: int | None = None) -> int:
    check_count(n_neighbors, "n_neighbors")
    if n_fingerprints is not None and n_neighbors > n_fingerprints:
        raise ValueError(f"n_neighbors={n_neighbors} is larger than the number of fingerprint positions "
                         f"({n_fingerprints})")
    return int(n_neighbors)


def _check_metric(metric) -> str:
    return check_choice(metric, "metric", METRICS)


def _check_online_missing(online_missing) -> str:
    return check_choice(online_missing, "online_missing", ONLINE_MISSING)


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
        raise ValueError(f"X holds only readings >= 0 (from {readings.min():g} to {readings.max():g}): that is "
                         "linear power (e.g. mW), not RSS in dBm; convert with 10 * log10(P / 1 mW)")
    y = as_float_array(y, "y")
    if y.ndim != 2 or y.shape[0] != X.shape[0] or y.shape[1] == 0:
        raise ValueError(f"y must have shape ({X.shape[0]}, n_coordinates), like X's rows; got {y.shape}")
    return X, y + 0.0  # + 0.0 turns -0.0 into 0.0, so both group together


def _check_rss_range(X: np.ndarray, name: str) -> None:
    """``ValueError`` naming ``name`` and the first index of a reading outside :data:`RSS_RANGE_DBM` (NaN ignored)."""
    lo, hi = RSS_RANGE_DBM
    outside = (X < lo) | (X > hi)
    if np.any(outside):
        index = tuple(int(i) for i in np.argwhere(outside)[0])
        raise ValueError(f"{name} has an RSS of {X[index]:g} dBm at index {index}, outside the plausible range "
                         f"[{lo:g}, {hi:g}] dBm (a glitch, or not dBm?)")


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


def _check_terms(terms, name: str, positions, *, log_pmf: bool = False) -> tuple[np.ndarray, np.ndarray]:
    terms = np.asarray(terms, dtype=float)
    if terms.ndim != 3:
        raise ValueError(f"{name} must have shape (n_vectors, n_fingerprints, n_anchors), got {terms.shape}")
    positions = np.asarray(positions, dtype=float)
    if positions.ndim != 2 or positions.shape[0] != terms.shape[1]:
        raise ValueError(f"positions must have shape ({terms.shape[1]}, n_coordinates) to match {name}, "
                         f"got {positions.shape}")
    if np.any(np.isnan(terms)):
        raise ValueError(f"{name} contains NaN")
    if log_pmf and np.any(np.isinf(terms)):
        raise ValueError(f"{name} contains inf (log-PMFs must be floored)")
    return terms, positions


def _check_grid_ints(values, name: str, n_fingerprints: int) -> tuple[int, ...]:
    values = tuple(np.atleast_1d(np.asarray(values, dtype=object)).tolist())
    if not values:
        raise ValueError(f"{name} must hold at least one value")
    checked = tuple(_check_n_neighbors(v, n_fingerprints) for v in values)
    if len(set(checked)) != len(checked):
        raise ValueError(f"{name} holds duplicate values: {list(checked)}")
    return checked
