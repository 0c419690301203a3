"""What a filter does in a gap: the angular rate it turns by, and the replay at the gap's end.

The loss vocabulary of :mod:`wsnlib.orientation` (``gap``, ``replay``) for any filter that runs
sample by sample with a step that turns its state by an angular rate: Madgwick's filter
(:mod:`._kernels`) and the Kalman filter (:mod:`._kalman_kernels`) call these compiled
functions from their loops, and the same functions serve a live receiver one packet at a time;
the peer filters driven from Python (:mod:`wsnlib.orientation.peers`) get a whole gap's rates
from them at once (:func:`gap_rates`).
A filter gives the gap module the rate it used on every received sample (raw for Madgwick,
bias-corrected for the Kalman filter) and asks it, on every lost sample, for the rate to turn
by; at the first received sample after a gap, with ``replay``, it restores the state it had at
the gap's start (the filter's own save/restore) and re-runs the gap with the rates
:func:`replay_rate` gives, then updates as usual.

Rates in a gap (``gap``)
------------------------
* ``"hold"`` (:data:`HOLD`): 0 — the state stays.
* ``"constant_rate"`` (:data:`CONSTANT_RATE`): the last received rate, times ``factor`` per lost
  sample (``factor = exp(−Δt/τ)`` for a decay time constant τ, 1 for a constant rate).
* ``"ar"`` (:data:`AR`): linear prediction — a per-axis autoregressive model of order ``p``
  fitted by ridge-regularised least squares at the gap's start on the last ``window`` rates
  (:func:`ar_fit`) and run on its own outputs, ``ω_k = Σ_i c_i ω_{k−p+i}`` (norm capped at the
  window's largest, :func:`ar_predict`): an arm's swing is a damped oscillation, which a short
  linear predictor follows for a fraction of a period, while a held rate overshoots it.  With
  less than a window of rates before the gap (or fewer than ``3p`` samples in the window) it
  falls back to ``"constant_rate"``.

Replay (``replay``)
-------------------
At the first received sample ``t`` after a gap of ``L`` samples, with measured rate ``ω_t``, the
k-th lost sample's rate is re-estimated now that both ends are known: with the AR prediction,
the predicted rate plus ``w_k`` times the predictor's error at ``t`` (measured − predicted),
``w_k`` the Gaussian conditional expectation of the k-th step's prediction error given the last
one under the fitted model (:func:`ar_end_weights`: a linear ramp for a slowly varying rate,
following the oscillation for a swing); otherwise linear between the last received rate and
``ω_t`` (paper 001's gyroscope interpolation).  The replay is causal: it changes the state from
the gap's end on, never what was output on the lost samples.

State
-----
:data:`GAP_DTYPE` is a structured record (one per stream) holding the gap's bookkeeping, and a
rate history ``(H, 3)`` (a ring: sample ``k`` at row ``k mod H``) the AR fit and the replay
read.  ``H`` must hold a window plus the longest gap to replay with its predicted rates
(:func:`history_length`); a longer gap is replayed with the linear ramp.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wsnlib.orientation._scalar_kernels import COMPILE

#: Codes of ``gap`` in the compiled kernels.
HOLD, CONSTANT_RATE, AR = 0, 1, 2
#: ``gap`` names, in code order.
GAP_CODES = {"hold": HOLD, "constant_rate": CONSTANT_RATE, "ar": AR}
#: Largest order of the AR predictor.
MAX_ORDER = 64
#: Longest gap (s) replayed with the AR prediction's own rates (a longer one: the linear ramp); it
#: sizes a filter's rate history (:func:`history_length`).
LONGEST_AR_REPLAY_S = 10.0
#: Ridge of the AR fit, relative to the mean squared rate of the window (and at least this in
#: (rad/s)²): keeps a window of near rest from fitting its noise.
AR_RIDGE = 1e-3

#: One stream's gap bookkeeping.  ``mode`` ``factor`` ``order`` ``window`` are the settings;
#: ``n`` samples seen so far (received or not) since the history started; ``lost`` samples lost
#: in a row; ``last_rate`` the rate of the last received sample; ``rate`` the rate used on the
#: current lost sample; ``predicting`` whether this gap's rates come from the AR fit, whose
#: coefficients ``coef`` and largest window rate ``largest`` it holds.
GAP_DTYPE = np.dtype([
    ("mode", "i8"), ("factor", "f8"), ("order", "i8"), ("window", "i8"),
    ("n", "i8"), ("lost", "i8"), ("last_rate", "f8", (3,)), ("rate", "f8", (3,)),
    ("predicting", "?"), ("largest", "f8"), ("coef", "f8", (3, MAX_ORDER)),
])


def new_gap_state(mode: int, factor: float, order: int, window: int) -> np.ndarray:
    """A fresh gap record (shape ``(1,)``) for the settings ``mode`` (a code), ``factor``, ``order``, ``window``."""
    if not 1 <= order <= MAX_ORDER:
        raise ValueError(f"the AR order must lie in [1, {MAX_ORDER}], got {order}")
    gs = np.zeros(1, GAP_DTYPE)
    gs["mode"], gs["factor"], gs["order"], gs["window"] = mode, factor, order, window
    return gs


@njit(**COMPILE)
def history_length(window, longest_replay):
    """Rows of a rate history for a ``window`` and AR replays of gaps up to ``longest_replay`` samples."""
    return window + longest_replay + 2


@njit(**COMPILE)
def _row(history, k):
    return history[k % history.shape[0]]


@njit(**COMPILE)
def gap_received(gs, history, rate):
    """A received sample used ``rate`` (3-tuple): record it, and end the gap."""
    row = _row(history, gs.n)
    for a in range(3):
        row[a] = rate[a]
        gs.last_rate[a] = rate[a]
    gs.n += 1
    gs.lost = 0


@njit(**COMPILE)
def gap_lost(gs, history, work_A, work_r):
    """A lost sample: the rate (3-tuple) to turn the state by, recorded in the history.

    At a gap's first sample the AR predictor is fitted if ``mode`` is :data:`AR` and a full
    window of rates precedes it (``work_A`` (3, MAX_ORDER, MAX_ORDER + 1) and ``work_r``
    (3, MAX_ORDER + 1) are scratch, :func:`ar_fit`'s ``A`` and ``r``).
    """
    order, window = gs.order, gs.window
    if gs.lost == 0:
        gs.predicting = gs.mode == AR and gs.n >= window and window >= 3 * order
        if gs.predicting:
            gs.largest = ar_fit(history, gs.n, window, order, gs.coef, work_A, work_r)
        for a in range(3):
            gs.rate[a] = gs.last_rate[a]
    if gs.predicting:
        ar_predict(history, gs.n, order, gs.coef, gs.largest, gs.rate)
    elif gs.mode == HOLD:
        for a in range(3):
            gs.rate[a] = 0.0
    else:
        for a in range(3):
            gs.rate[a] *= gs.factor
    row = _row(history, gs.n)
    for a in range(3):
        row[a] = gs.rate[a]
    gs.n += 1
    gs.lost += 1
    return gs.rate[0], gs.rate[1], gs.rate[2]


@njit(**COMPILE)
def replay_weights(gs, history, measured, weights, impulse, predicted):
    """Prepare the replay of the gap that ends at the current sample (rate ``measured``).

    Fills ``weights`` (3, ≥ L) with the end-correction weights (AR) and ``predicted`` (3,) with
    the predictor's rate at this sample; returns True when the AR replay applies (the gap was
    predicted and its rates are still in the history), else False (linear ramp).  ``impulse``
    (≥ L + 1,) is scratch.
    """
    n_lost = gs.lost
    if not (gs.predicting and n_lost + gs.order + 1 <= history.shape[0]):
        return False
    ar_predict(history, gs.n, gs.order, gs.coef, gs.largest, predicted)
    for a in range(3):
        ar_end_weights(gs.coef, a, gs.order, n_lost + 1, impulse, weights[a])
    return True


@njit(**COMPILE)
def replay_rate(gs, history, k, measured, use_ar, weights, predicted):
    """Rate (3-tuple) of the k-th lost sample (1 … L) of the gap ending now, at rate ``measured``.

    ``use_ar``, ``weights``, ``predicted`` from :func:`replay_weights`; the gap's last received
    rate is ``gs.last_rate`` and its k-th predicted rate the history's row ``n − L − 1 + k``.
    """
    n_lost = gs.lost
    if use_ar:
        row = _row(history, gs.n - n_lost - 1 + k)
        return (row[0] + weights[0, k - 1] * (measured[0] - predicted[0]),
                row[1] + weights[1, k - 1] * (measured[1] - predicted[1]),
                row[2] + weights[2, k - 1] * (measured[2] - predicted[2]))
    frac = k / (n_lost + 1.0)
    last = gs.last_rate
    return (last[0] + frac * (measured[0] - last[0]), last[1] + frac * (measured[1] - last[1]),
            last[2] + frac * (measured[2] - last[2]))


# ------------------------------------------------------------------------------------------
# The autoregressive predictor
# ------------------------------------------------------------------------------------------


@njit(inline="always", **COMPILE)
def axpy(y, y0, x, x0, n, alpha):
    """``y[y0 + j] += alpha · x[x0 + j]`` for ``j < n`` (1-D arrays, offsets ≥ 0).

    The offsets and the counter are unsigned, so numba emits no negative-index wraparound and
    LLVM vectorises the loop; each element still gets exactly the scalar loop's operations.
    """
    y_start, x_start = np.uint64(y0), np.uint64(x0)
    for j in range(np.uint64(n)):
        y[y_start + j] += alpha * x[x_start + j]


@njit(inline="always", **COMPILE)
def _copy(y, y0, x, x0, n):
    """``y[y0 + j] = x[x0 + j]`` for ``j < n`` (as :func:`axpy`: unsigned indices, vectorised)."""
    y_start, x_start = np.uint64(y0), np.uint64(x0)
    for j in range(np.uint64(n)):
        y[y_start + j] = x[x_start + j]


@njit(inline="always", **COMPILE)
def _rotate(u, v, start, c, s):
    """``(u, v) ← (c u + s v, c v − s u)`` from index ``start`` on (a Givens rotation; vectorised as :func:`axpy`)."""
    for j in range(np.uint64(start), np.uint64(u.shape[0])):
        uj, vj = u[j], v[j]
        u[j] = c * uj + s * vj
        v[j] = c * vj - s * uj


@njit(inline="always", **COMPILE)
def _rotate_hyperbolic(u, v, start, c, s):
    """``u ← c u − s v``, then ``v ← (v − s u)/c`` (= ``c v − s u_old``, c² − s² = 1: a hyperbolic
    rotation in the stabler "mixed" form) from index ``start`` on."""
    inv_c = 1.0 / c
    for j in range(np.uint64(start), np.uint64(u.shape[0])):
        uj = c * u[j] - s * v[j]
        u[j] = uj
        v[j] = (v[j] - s * uj) * inv_c


@njit(**COMPILE)
def ar_fit(rates, end, window, order, coef, A, r):
    """Fit the linear predictor of the rate on the rows ``end − window … end − 1``; returns its largest norm.

    Per axis ``a``, least squares for ``ω_a[k] ≈ Σ_i c_ai ω_a[k − order + i]`` over the window
    (an autoregressive model of order ``p = order``: a sum of damped oscillations, which is what
    an arm's swing looks like over a fraction of a second), with ridge ``λ = AR_RIDGE ·
    max(1, tr(XᵀX)/p)`` on the normal equations ``(XᵀX + λI) c = Xᵀy``.

    They are solved in O(window · p + p²), not the O(p³) of a Cholesky factorisation, from
    their structure: the extended matrix ``M = [X y]ᵀ[X y] + λ (I_p ⊕ 0)`` ((p + 1) × (p + 1);
    ``E_ij = Σ_{k<n} x[k + i] x[k + j]``, n = window − p equations) changes along its diagonals
    only by the samples entering and leaving the window, ``E_ij − E_{i−1,j−1} = x[n+i−1] x[n+j−1]
    − x[i−1] x[j−1]``, so ``M − Z M Zᵀ = G J Gᵀ`` (Z the down-shift) with four generator columns
    ``G = [m₀/√M₀₀, w | m̃₀/√M₀₀, h]``, ``J = diag(1, 1, −1, −1)``: ``m₀`` M's first row, ``m̃₀`` it
    with its first entry 0, ``w = (0, x[n], …, x[n+p−1])``, ``h = (0, x[0], …, x[p−1])`` (and
    ``−λ e_p e_pᵀ``, which only M's last diagonal entry sees).  The generalized Schur algorithm
    (T. Kailath and A. H. Sayed, "Displacement structure: theory and applications", SIAM Review
    37(3):297–386, 1995, Sec. 4) then gives the Cholesky factor ``M = L Lᵀ`` column by column: at
    step k a J-unitary transformation (a rotation within the positive columns, one within the
    negative ones, and a hyperbolic rotation between them) leaves one non-zero in the
    generator's row k; its first column is then L's column k, and shifted down by one it is the
    next step's.  L's last row is z with ``L_p z = Xᵀy`` (L_p the leading p × p block), and
    ``L_pᵀ c = z`` gives the coefficients.

    The factorisations run axis by axis, their rotations vectorised loops over the generator's
    rows; the back-substitutions run in lockstep, the three axes' sums side by side in one loop:
    each sum is a chain of dependent additions (in index order, so that the result does not
    depend on how the loop is compiled), and three independent chains overlap in the processor
    instead of waiting for each other.  Every number gets exactly the operations, in the same
    order, of one axis after the other.  (The factorisations in lockstep too, one fused pass
    over the three axes' rows per step, were faster only where ``order`` and ``window`` were
    compile-time constants; with the run-time values of the filters their loops no longer
    vectorise, and the smoother got slower.)

    ``rates`` is the ring history (row ``k mod H``) of the rates the filter used; ``coef``
    (3, ≥ order) receives the coefficients; ``A`` (3, ≥ order, ≥ order + 1) and ``r``
    (3, ≥ order + 1) are scratch (``A[a]``'s row k: axis a's column k of L; ``r[a]``: M's first row).
    """
    lo = end - window
    size = rates.shape[0]
    xs = np.empty((3, window))  # the window in time order, per axis (the history is a ring)
    largest_squared = 0.0
    row = lo % size
    for k in range(window):
        x0, x1, x2 = rates[row, 0], rates[row, 1], rates[row, 2]
        xs[0, k], xs[1, k], xs[2, k] = x0, x1, x2
        largest_squared = max(largest_squared, x0 * x0 + x1 * x1 + x2 * x2)
        row += 1
        if row == size:
            row = 0
    largest = math.sqrt(largest_squared)  # = the largest of the norms: √ is monotonic (and correctly rounded)
    p = order
    n = window - p  # equations: k = 0 … n − 1 predict x[k + p] from x[k … k + p − 1]
    generator = np.empty((4, p + 1))
    for a in range(3):
        x, first_row, L = xs[a], r[a], A[a]
        # M's first row, E_0j = Σ_{k<n} x[k] x[k + j], over the lags j in a vectorised loop that adds
        # four terms k … k + 3 at a time (in that order: each sum's order stays k = 0, 1, …; a quarter
        # of the loops and of the row's loads and stores of one axpy per k), then tr(XᵀX) from E's
        # diagonal by the same shift.
        for j in range(p + 1):
            first_row[j] = 0.0
        k = 0
        while k + 4 <= n:
            x0, x1, x2, x3 = x[k], x[k + 1], x[k + 2], x[k + 3]
            for j in range(np.uint64(p + 1)):
                e = first_row[j]
                e += x0 * x[k + j]
                e += x1 * x[k + 1 + j]
                e += x2 * x[k + 2 + j]
                e += x3 * x[k + 3 + j]
                first_row[j] = e
            k += 4
        while k < n:
            axpy(first_row, 0, x, k, p + 1, x[k])
            k += 1
        diagonal = trace = first_row[0]
        for i in range(1, p):
            diagonal = diagonal - x[i - 1] * x[i - 1] + x[n + i - 1] * x[n + i - 1]
            trace += diagonal
        first_row[0] += AR_RIDGE * max(1.0, trace / p)
        plus, plus2, minus, minus2 = generator[0], generator[1], generator[2], generator[3]
        scale = 1.0 / math.sqrt(first_row[0])
        for j in range(p + 1):
            plus[j] = first_row[j] * scale
            minus[j] = first_row[j] * scale
        minus[0] = 0.0
        plus2[0] = minus2[0] = 0.0
        for j in range(1, p + 1):
            plus2[j] = x[n + j - 1]
            minus2[j] = x[j - 1]
        for k in range(p):
            # Row k to proper form: (plus, plus2) → (·, 0) and (minus, minus2) → (·, 0) by rotations,
            # then (plus, minus) → (·, 0) by a hyperbolic one (|plus_k| > |minus_k| as M is positive definite).
            if plus2[k] != 0.0:
                radius = math.sqrt(plus[k] * plus[k] + plus2[k] * plus2[k])
                _rotate(plus, plus2, k, plus[k] / radius, plus2[k] / radius)
            if minus2[k] != 0.0:
                radius = math.sqrt(minus[k] * minus[k] + minus2[k] * minus2[k])
                _rotate(minus, minus2, k, minus[k] / radius, minus2[k] / radius)
            if minus[k] != 0.0:
                ratio = minus[k] / plus[k]
                cosh = 1.0 / math.sqrt((1.0 - ratio) * (1.0 + ratio))
                _rotate_hyperbolic(plus, minus, k, cosh, ratio * cosh)
            column = L[k]  # L's column k (rows k … p), and the generator's first column shifted down by one (Z)
            _copy(column, k, plus, k, p + 1 - k)
            _copy(plus, k + 1, column, k, p - k)
            plus[k] = 0.0
    # L_pᵀ c = z (backward), z = L's row p, for the three axes side by side (each sum in index order).
    L_0, L_1, L_2 = A[0], A[1], A[2]
    c_0, c_1, c_2 = coef[0], coef[1], coef[2]
    for i in range(p - 1, -1, -1):
        u_0, u_1, u_2 = L_0[i], L_1[i], L_2[i]
        sum_0 = sum_1 = sum_2 = 0.0
        for j in range(np.uint64(i + 1), np.uint64(p)):
            sum_0 += u_0[j] * c_0[j]
            sum_1 += u_1[j] * c_1[j]
            sum_2 += u_2[j] * c_2[j]
        c_0[i] = (u_0[p] - sum_0) / u_0[i]
        c_1[i] = (u_1[p] - sum_1) / u_1[i]
        c_2[i] = (u_2[p] - sum_2) / u_2[i]
    return largest


@njit(**COMPILE)
def ar_predict(rates, t, order, coef, largest, out):
    """One step of the linear predictor: ``out[a] = Σ_i coef[a, i] rates[t − order + i, a]``,
    its norm capped at ``largest`` (the window's largest rate: an unstable fit cannot run away)."""
    size = rates.shape[0]
    first = (t - order) % size  # the ring's row of sample t − order; rows then wrap at most once
    v0 = v1 = v2 = 0.0
    row = first
    for i in range(order):
        v0 += coef[0, i] * rates[row, 0]
        v1 += coef[1, i] * rates[row, 1]
        v2 += coef[2, i] * rates[row, 2]
        row += 1
        if row == size:
            row = 0
    out[0], out[1], out[2] = v0, v1, v2
    norm = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
    if norm > largest:
        for a in range(3):
            out[a] *= largest / norm


@njit(**COMPILE)
def ar_end_weights(coef, axis, order, n, h, weights):
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


# ------------------------------------------------------------------------------------------
# A whole gap at once (filters driven from Python: the peers of :mod:`wsnlib.orientation.peers`)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def gap_rates(rates, n_lost, measured, mode, factor, order, window):
    """The rates of a gap of ``n_lost`` samples: ``(predicted, replayed)``, each ``(n_lost, 3)`` (rad/s).

    ``rates`` ``(n, 3)``: the stream's rate history from its start to the gap's last received
    sample (the rates the filter used on received samples, and on earlier gaps' lost samples
    the rates this module gave), ``n ≥ 1``; ``measured`` (3,): the rate of the first received
    sample after the gap (any value when the gap ends the recording: ``replayed`` is then
    unused).  ``predicted`` are :func:`gap_lost`'s rates, ``replayed`` :func:`replay_rate`'s,
    for the settings ``mode`` (a code), ``factor``, ``order``, ``window`` (:func:`new_gap_state`):
    exactly what a compiled filter's loop gets sample by sample.
    """
    n = rates.shape[0]
    records = np.zeros(1, GAP_DTYPE)
    gs = records[0]
    gs.mode, gs.factor, gs.order, gs.window = mode, factor, order, window
    history = np.zeros((history_length(window, n_lost), 3))
    for k in range(max(0, n - history.shape[0]), n):  # the ring's rows of the last samples
        row = _row(history, k)
        for a in range(3):
            row[a] = rates[k, a]
    gs.n = n - 1
    gap_received(gs, history, (rates[n - 1, 0], rates[n - 1, 1], rates[n - 1, 2]))
    work_A = np.empty((3, MAX_ORDER, MAX_ORDER + 1))
    work_r = np.empty((3, MAX_ORDER + 1))
    predicted = np.empty((n_lost, 3))
    for k in range(n_lost):
        predicted[k, 0], predicted[k, 1], predicted[k, 2] = gap_lost(gs, history, work_A, work_r)
    replayed = np.empty((n_lost, 3))
    if n_lost > 0:
        weights = np.empty((3, n_lost + 1))
        impulse = np.empty(n_lost + 1)
        ahead = np.empty(3)
        use_ar = replay_weights(gs, history, measured, weights, impulse, ahead)
        for k in range(1, n_lost + 1):
            replayed[k - 1, 0], replayed[k - 1, 1], replayed[k - 1, 2] = replay_rate(gs, history, k, measured,
                                                                                     use_ar, weights, ahead)
    records[0] = gs  # keep the record's array alive to here
    return predicted, replayed
