"""Old home of radio fingerprinting; the code now lives in the :mod:`wsnlib.radio` package.

Every public name is re-exported here (the same objects), so ``wsnlib.fingerprint.*`` keeps
working.  New code imports from :mod:`wsnlib.radio` (estimators:
:mod:`wsnlib.radio.estimators`; the grid engine of the parameter search:
:mod:`wsnlib.radio.grid`).  The chunk bound ``_CHUNK_ELEMENTS`` is read from
:mod:`wsnlib.radio._checks`, so lower it there, not here.
"""

from wsnlib.radio._checks import _CHUNK_ELEMENTS, METRICS, PMF_METHODS, RSS_RANGE_DBM  # noqa: F401
from wsnlib.radio.estimators import KNNFingerprint, ProbabilisticKNN, fit_predict_by_group
from wsnlib.radio.grid import (
    SHEPARD_EPS,
    anchor_subsets,
    knn_from_terms,
    knn_grid_from_terms,
    pknn_from_loglik,
    pknn_grid_from_loglik,
)

__all__ = [
    "anchor_subsets",
    "fit_predict_by_group",
    "KNNFingerprint",
    "knn_from_terms",
    "knn_grid_from_terms",
    "METRICS",
    "PMF_METHODS",
    "pknn_from_loglik",
    "pknn_grid_from_loglik",
    "ProbabilisticKNN",
    "RSS_RANGE_DBM",
    "SHEPARD_EPS",
]
