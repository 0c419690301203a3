"""Dot products, norms and small matrix products with an order of additions fixed by construction.

A BLAS routine (``a @ b``, ``np.dot``, ``np.linalg.norm`` of a 1-D vector) sums in an order
chosen by the kernel OpenBLAS picks for the CPU (``OPENBLAS_CORETYPE``: Prescott, Haswell,
SkylakeX, …) and by the operands' shapes, so the same inputs can give results that differ in
the last bits from one machine, or one batch size, to another — enough to flip an exact tie in
a ranking.  The functions here add the terms one index after another (``((a₀b₀ + a₁b₁) +
a₂b₂) + …``) with elementwise numpy operations, whose results do not depend on the kernel or
on the other elements of the batch.  Use them where a result must be the same bits whatever
the machine or the shape of the batch (what :mod:`wsnlib.optimize` ranks, simulated inputs of
the tables); they are meant for short inner dimensions (3-vectors, quaternions, a handful of
features), not for large matrix products.
"""

from __future__ import annotations

import numpy as np


def dot(a, b) -> np.ndarray:
    """``Σ_i a[..., i] · b[..., i]`` added in index order; shapes broadcast, result ``(...)``."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    out = a[..., 0] * b[..., 0]
    for i in range(1, a.shape[-1]):
        out = out + a[..., i] * b[..., i]
    return out


def norm(v) -> np.ndarray:
    """Euclidean norm along the last axis, ``sqrt(dot(v, v))``: shape ``(...)``."""
    return np.sqrt(dot(v, v))


def matmul(a, b) -> np.ndarray:
    """``a @ b`` for ``a`` ``(..., n, k)`` and ``b`` ``(k, m)``, each entry summed over ``k`` in index order."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if b.ndim != 2 or a.shape[-1] != b.shape[0]:
        raise ValueError(f"matmul needs a (..., n, k) and b (k, m), got {a.shape} and {b.shape}")
    out = a[..., :, 0, None] * b[0]
    for i in range(1, b.shape[0]):
        out += a[..., :, i, None] * b[i]
    return out
