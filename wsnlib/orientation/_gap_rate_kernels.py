"""Compiled kernels of the gap's linear prediction of the angular rate (``gap_rate_prediction``).

Fit of the per-axis autoregressive predictor on the rates before a gap
(:func:`gap_rate_fit`), one step of it (:func:`gap_rate_predict`) and the weights of the end
correction that spreads its error at the first received sample over the gap
(:func:`gap_rate_end_weights`).  Used by the Kalman filter's loop
(:mod:`._kalman_kernels`) and by the smoother's curves across gaps
(:mod:`wsnlib.orientation.smoothing`).
"""

from __future__ import annotations

import math

from numba import njit

from wsnlib.orientation._kernels import COMPILE

#: Ridge of the gap's linear-prediction fit, relative to the mean squared rate of the window
#: (and at least this in (rad/s)²): keeps a window of near rest from fitting its noise.
AR_RIDGE = 1e-3


# ------------------------------------------------------------------------------------------
# Gap: linear prediction of the angular rate (gap_rate_prediction)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def gap_rate_fit(rates, end, window, order, coef, A, r):
    """Fit the linear predictor of the rate on ``rates[end − window : end]``; returns its largest norm.

    Per axis ``a``, least squares for ``ω_a[k] ≈ Σ_i c_ai ω_a[k − order + i]`` over the window
    (an autoregressive model of order ``order``: a sum of damped oscillations, which is what
    an arm's swing looks like over a fraction of a second), with ridge ``AR_RIDGE ·
    max(1, tr(XᵀX)/order)`` on the normal equations, solved by Cholesky.  ``rates`` (T, 3)
    holds the bias-corrected rates the filter used; ``coef`` (3, order) receives the
    coefficients; ``A`` (order, order) and ``r`` (order,) are scratch.
    """
    lo = end - window
    for a in range(3):
        for i in range(order):
            r[i] = 0.0
            for j in range(order):
                A[i, j] = 0.0
        for k in range(lo, end - order):
            y = rates[k + order, a]
            for i in range(order):
                xi = rates[k + i, a]
                r[i] += xi * y
                for j in range(i + 1):
                    A[i, j] += xi * rates[k + j, a]
        trace = 0.0
        for i in range(order):
            trace += A[i, i]
        ridge = AR_RIDGE * max(1.0, trace / order)
        for i in range(order):  # in-place Cholesky of the lower triangle: A = L Lᵀ
            A[i, i] += ridge
            for j in range(i + 1):
                acc_ij = A[i, j]
                for k in range(j):
                    acc_ij -= A[i, k] * A[j, k]
                A[i, j] = math.sqrt(acc_ij) if i == j else acc_ij / A[j, j]
        for i in range(order):  # L y = r, then Lᵀ c = y
            acc_i = r[i]
            for k in range(i):
                acc_i -= A[i, k] * coef[a, k]
            coef[a, i] = acc_i / A[i, i]
        for i in range(order - 1, -1, -1):
            acc_i = coef[a, i]
            for k in range(i + 1, order):
                acc_i -= A[k, i] * coef[a, k]
            coef[a, i] = acc_i / A[i, i]
    largest = 0.0
    for k in range(lo, end):
        largest = max(largest, math.sqrt(rates[k, 0] ** 2 + rates[k, 1] ** 2 + rates[k, 2] ** 2))
    return largest


@njit(**COMPILE)
def gap_rate_predict(rates, t, order, coef, largest, out):
    """One step of the linear predictor: ``out[a] = Σ_i coef[a, i] rates[t − order + i, a]``,
    its norm capped at ``largest`` (the window's largest rate: an unstable fit cannot run away)."""
    for a in range(3):
        v = 0.0
        for i in range(order):
            v += coef[a, i] * rates[t - order + i, a]
        out[a] = v
    norm = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
    if norm > largest:
        for a in range(3):
            out[a] *= largest / norm


@njit(**COMPILE)
def gap_rate_end_weights(coef, axis, order, n, h, weights):
    """Weights ``w_k`` (k = 1..n) of the end correction of the gap's predicted rates, one axis.

    The predictor is an autoregressive model ``ω[j] = Σ_i c_i ω[j − order + i] + e[j]`` with
    white innovations ``e``; the prediction error at the k-th step after the gap's start is
    ``Σ_{i=1..k} h[k − i] e[i]`` (``h`` the model's impulse response, ``h[0] = 1``).  Knowing the
    error at step ``n`` (the first received sample after the gap, measured minus predicted),
    the conditional expectation of the error at step ``k`` is ``w_k`` times it, with

        w_k = Σ_{i=1..k} h[k − i] h[n − i] / Σ_{j=0..n−1} h[j]²

    (Gaussian conditioning; ``w_n = 1``).  For a slowly varying rate (``h ≈ 1``) this is the
    linear ramp ``k/n``; for an oscillation it follows the oscillation instead of ramping
    across it.  If the impulse response grows beyond 1e50 (an unstable fit over a long gap),
    the linear ramp is used.  ``h``, ``weights`` (≥ n,) are written.
    """
    h[0] = 1.0
    unstable = False
    for j in range(1, n):
        v = 0.0
        for i in range(order):
            lag = j - order + i  # h at a negative index is 0
            if lag >= 0:
                v += coef[axis, i] * h[lag]
        h[j] = v
        if abs(v) > 1e50:
            unstable = True
            break
    if unstable:
        for k in range(1, n + 1):
            weights[k - 1] = k / n
        return
    den = 0.0
    for j in range(n):
        den += h[j] * h[j]
    for k in range(1, n + 1):
        cov = 0.0
        for i in range(1, k + 1):
            cov += h[k - i] * h[n - i]
        weights[k - 1] = cov / den
