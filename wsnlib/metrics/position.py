"""Localisation accuracy and precision (paper 002, Section 4.2)."""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array


def position_error(est, true) -> np.ndarray:
    """Euclidean distance between estimated and true positions, eq. (11) of paper 002.

    ``d_E(ŝ_t, s_t)``, ``(..., 3) → (...)``, in the unit of the inputs; the paper's PE is its
    mean over the samples of a movement, ``position_error(est, true).mean(axis=-1)``.
    ``est`` and ``true`` broadcast together.
    """
    est = as_float_array(est, "est", last_dim=3)
    true = as_float_array(true, "true", last_dim=3)
    try:
        np.broadcast_shapes(est.shape, true.shape)
    except ValueError as exc:
        raise ValueError(f"est {est.shape} and true {true.shape} do not broadcast") from exc
    return np.linalg.norm(est - true, axis=-1)


def precision_at_accuracy(errors, accuracies) -> np.ndarray:
    """Precision as a function of accuracy (paper 002, Section 4.2): the errors' empirical CDF.

    Precision at accuracy ``a`` is the fraction of ``errors`` that are ``<= a`` ("a precision
    of 60 % with an accuracy of 10 cm means that 60 % of the estimation errors … are lower than
    or equal to 10 cm").

    Parameters
    ----------
    errors : array_like, any shape
        Position errors (e.g. :func:`position_error`), all pooled; finite, at least one.
    accuracies : array_like, any shape
        Accuracy values, same unit as ``errors``.

    Returns
    -------
    numpy.ndarray, shape of ``accuracies``
        Fractions in ``[0, 1]``, non-decreasing in the accuracy.
    """
    errors = np.sort(as_float_array(errors, "errors", min_ndim=0).ravel())
    if errors.size == 0:
        raise ValueError("errors must hold at least one value")
    accuracies = np.asarray(accuracies, dtype=float)
    if np.any(np.isnan(accuracies)):
        raise ValueError("accuracies contains NaN")
    return np.searchsorted(errors, accuracies, side="right") / errors.size
