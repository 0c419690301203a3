"""Offline orientation for recorded sessions: RTS smoothing of the gap-aware Kalman filter.

:func:`smooth_orientation` runs :func:`wsnlib.orientation.kalman.kalman_orientation`'s
error-state filter forward, then a Rauch–Tung–Striebel pass backward (H. E. Rauch, F. Tung,
C. T. Striebel, AIAA J. 3(8):1445–1450, 1965), in error-state form (Solà 2017, Sec. 7):

    C_k = P⁺_k F_{k+1}ᵀ (P⁻_{k+1})⁻¹,
    δ_k = C_k [Log(q^s_{k+1} ⊗ q⁻*_{k+1}),  b^s_{k+1} − b⁻_{k+1},  v^s_{k+1} − v⁻_{k+1}],
    q^s_k = Exp(δθ_k) ⊗ q⁺_k,   b^s_k = b⁺_k + δb_k,   v^s_k = v⁺_k + δv_k,

(``F_{k+1}`` the filter's 9-state transition matrix, with the leaky velocity), starting
from ``q^s_{T−1} = q⁺_{T−1}`` (so at the last sample the smoother equals the filter).
The forward pass is the causal filter itself — the same settings object, gap handling and
replay — so the smoother starts from what the filter knows.  Where the filter replays a gap at
its end, the replayed estimates replace those it output on the gap's lost samples (filtered =
predicted there; their covariances and transition matrices stay those of the original
prediction, an approximation of first order in the replay's correction).  Without that, a long
gap in fast motion leaves the forward pass so far off that the backward pass cannot bring it
back, and the smoother can end up worse than its own filter.
Then, across each gap with received samples ``s0`` before and ``s1`` after it, the estimate is
replaced by a cubic Hermite curve on the rotation vector relative to ``q^s_{s0}``,

    q(u) = q^s_{s0} ⊗ Exp(r(u)),  u = (t − s0)/(s1 − s0),
    r(u) = h10(u) ω0 h + h01(u) r1 + h11(u) J_r⁻¹(r1) ω1 h,
    r1 = Log(q^s_{s0}* ⊗ q^s_{s1}),  h = (s1 − s0) Δt,

with the Hermite basis ``h10 = u³ − 2u² + u``, ``h01 = 3u² − 2u³``, ``h11 = u³ − u²`` and
``ω0``, ``ω1`` the bias-corrected rates received at both ends, so orientation *and* angular
rate match at both ends (``J_r`` is the right Jacobian of SO(3)).  ``r1`` is taken as the
rotation by ``‖r1‖ + 2πn`` (n ∈ {−1, 0, 1}) closest to ``h (ω0 + ω1)/2``, so a fast turn of
more than 180° through a gap is not unwound the short way.

With ``gap="ar"`` (default) and a full window
(``gap_rate_prediction_window_s``) of samples on *both* sides of the gap, the curve is
instead built from the rates the filter's linear predictor gives from each side
(:func:`wsnlib.orientation.gaps.ar_fit`: fitted on the window before the gap
and run forward, and on the window after it read backward in time and run backward; lost
samples inside a window are linear between their received neighbours, or, for earlier gaps,
the rates of their curve), blended
``ω(u) = (1 − u) ω_fwd + u ω_bwd``; that rate is integrated forward from ``q^s_{s0}`` and
backward from ``q^s_{s1}``, and the two are blended on SO(3),
``q(u) = q_f ⊗ Exp(u Log(q_f* ⊗ q_b))``, so both ends are matched.  A cubic in time cannot
follow an arm that swings back within the gap; the predictors, fitted on the swing itself,
can.  A gap at the end is the filter's
extrapolation (nothing after it), one at the start (before the first received sample, ``q0``
None) holds the initial estimate, as the filter does.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wsnlib.orientation import _batch as B
from wsnlib.orientation import gaps
from wsnlib.orientation._kalman_kernels import (
    NP,
    NX,
    add_process_noise,
    kalman_stream,
    new_records,
    packed_index,
    propagate_covariance,
    small_rotation,
    transition_transpose_times,
    unpack_upper,
)
from wsnlib.orientation._kernels import (
    COMPILE,
    cross3,
    quat_conjugate,
    quat_log,
    quat_multiply,
    quat_normalize,
)
from wsnlib.orientation._scalar_kernels import PLAIN_FALSE, PLAIN_TRUE, PLAIN_ZERO
from wsnlib.orientation.kalman import check_finite_output, constants, prepare_inputs
from wsnlib.orientation.kalman_settings import KalmanSettings


@njit(**COMPILE)
def _inverse_right_jacobian_times(r, v):
    """``J_r⁻¹(r) v`` on SO(3): ``v + ½ r × v + (1/θ² − (1 + cos θ)/(2θ sin θ)) r × (r × v)``."""
    theta = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    if theta < 1e-6:
        c = 1.0 / 12.0
    else:
        c = 1.0 / (theta * theta) - (1.0 + math.cos(theta)) / (2.0 * theta * math.sin(theta))
    rv = cross3(r, v)
    rrv = cross3(r, rv)
    return (v[0] + 0.5 * rv[0] + c * rrv[0], v[1] + 0.5 * rv[1] + c * rrv[1], v[2] + 0.5 * rv[2] + c * rrv[2])


@njit(**COMPILE)
def _hermite_gap(out_q, s0, s1, q0, q1, w0, w1, dt):
    """Fill ``out_q[s0 + 1 : s1]`` with the cubic Hermite curve of the module docstring."""
    h = (s1 - s0) * dt
    r1 = quat_log(quat_multiply(quat_conjugate(q0), q1))
    theta = math.sqrt(r1[0] ** 2 + r1[1] ** 2 + r1[2] ** 2)
    if theta > 0.0:  # unwrap: the turn closest to the mean received rate
        guess = (0.5 * (w0[0] + w1[0]) * h, 0.5 * (w0[1] + w1[1]) * h, 0.5 * (w0[2] + w1[2]) * h)
        best, best_r = 1e300, r1
        for n in (-1, 0, 1):
            k = (theta + 2.0 * math.pi * n) / theta
            cand = (k * r1[0], k * r1[1], k * r1[2])
            dist = (cand[0] - guess[0]) ** 2 + (cand[1] - guess[1]) ** 2 + (cand[2] - guess[2]) ** 2
            if dist < best:
                best, best_r = dist, cand
        r1 = best_r
    m0 = (w0[0] * h, w0[1] * h, w0[2] * h)
    m1 = _inverse_right_jacobian_times(r1, (w1[0] * h, w1[1] * h, w1[2] * h))
    for t in range(s0 + 1, s1):
        u = (t - s0) / (s1 - s0)
        h10 = u * u * u - 2.0 * u * u + u
        h01 = 3.0 * u * u - 2.0 * u * u * u
        h11 = u * u * u - u * u
        r = (h10 * m0[0] + h01 * r1[0] + h11 * m1[0], h10 * m0[1] + h01 * r1[1] + h11 * m1[1],
             h10 * m0[2] + h01 * r1[2] + h11 * m1[2])
        q = quat_normalize(quat_multiply(q0, small_rotation(r)))
        for a in range(4):
            out_q[t, a] = q[a]


@njit(**COMPILE)
def _predicted_rates(rates, lo, order, window, n, reverse, coef, A, r, buf, out):
    """Rates over a gap of ``n`` samples by the linear predictor fitted on one side's window.

    Forward (``reverse`` False): fitted on ``rates[lo : lo + window]``, the window ending at
    the gap's first sample ``s0 = lo + window − 1``, predicting ``s0 + 1, …``.  Backward:
    fitted on the same series read backward from ``rates[lo + window − 1]`` down to
    ``rates[lo]`` (the window starting at the gap's end ``s1 = lo``), predicting
    ``s1 − 1, s1 − 2, …``.  ``out[k]`` (n, 3) is the rate at the gap's k-th sample from its
    start (forward) or from its end (backward).  ``buf`` (window + n, 3) is scratch.
    """
    for i in range(window):
        src = lo + window - 1 - i if reverse else lo + i
        for a in range(3):
            buf[i, a] = rates[src, a]
    largest = gaps.ar_fit(buf, window, window, order, coef, A, r)
    for k in range(n):
        gaps.ar_predict(buf, window + k, order, coef, largest, buf[window + k])
        for a in range(3):
            out[k, a] = buf[window + k, a]


@njit(**COMPILE)
def _predicted_gap(out_q, rates, s0, s1, q0, q1, order, window, dt):
    """Fill ``out_q[s0 + 1 : s1]`` from both sides' linear predictions (module docstring).

    The blended rates replace the linear fill of ``rates[s0 + 1 : s1]`` (gaps are filled in
    time order, so a later gap's window before it holds predicted rates)."""
    n = s1 - s0 - 1
    coef = np.zeros((3, order))
    A = np.empty((3, order, order + 1))
    r = np.empty((3, order + 1))
    buf = np.empty((window + n, 3))
    fwd = np.empty((n, 3))
    bwd = np.empty((n, 3))
    _predicted_rates(rates, s0 - window + 1, order, window, n, PLAIN_FALSE, coef, A, r, buf, fwd)
    _predicted_rates(rates, s1, order, window, n, PLAIN_TRUE, coef, A, r, buf, bwd)
    blend = np.empty((n + 1, 3))  # rate at sample s0 + 1 + k; the last row is the measured one at s1
    for k in range(n):
        u = (k + 1.0) / (n + 1.0)
        for a in range(3):
            blend[k, a] = (1.0 - u) * fwd[k, a] + u * bwd[n - 1 - k, a]
    for a in range(3):
        blend[n, a] = rates[s1, a]
    for k in range(n):  # later gaps' forward windows read these rates instead of the linear fill
        for a in range(3):
            rates[s0 + 1 + k, a] = blend[k, a]
    q = q0  # forward integration from s0, kept in out_q
    for k in range(n):
        q = quat_normalize(quat_multiply(q, small_rotation((blend[k, 0] * dt, blend[k, 1] * dt, blend[k, 2] * dt))))
        for a in range(4):
            out_q[s0 + 1 + k, a] = q[a]
    q = q1  # backward integration from s1, blended with the forward one
    for k in range(n - 1, -1, -1):
        w = blend[k + 1]
        q = quat_normalize(quat_multiply(q, small_rotation((-w[0] * dt, -w[1] * dt, -w[2] * dt))))
        u = (k + 1.0) / (n + 1.0)
        q_f = (out_q[s0 + 1 + k, 0], out_q[s0 + 1 + k, 1], out_q[s0 + 1 + k, 2], out_q[s0 + 1 + k, 3])
        d = quat_log(quat_multiply(quat_conjugate(q_f), q))
        qb = quat_normalize(quat_multiply(q_f, small_rotation((u * d[0], u * d[1], u * d[2]))))
        for a in range(4):
            out_q[s0 + 1 + k, a] = qb[a]


@njit(inline="always", **COMPILE)
def cholesky_factor(P, L, inv_diag):
    """``P = L Lᵀ`` into ``L``'s lower triangle for a symmetric positive definite ``P`` (9 × 9; its upper
    triangle is read), and ``1/L_jj`` into ``inv_diag``: the factor and the solves multiply by it,
    one division per column instead of one per entry (divisions are the long links of the
    dependent chain)."""
    for i in range(NX):
        for j in range(i + 1):
            acc_ij = P[j, i]
            for k in range(j):
                acc_ij -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = math.sqrt(acc_ij)
                inv_diag[i] = 1.0 / L[i, i]
            else:
                L[i, j] = acc_ij * inv_diag[j]


@njit(inline="always", **COMPILE)
def solve_factored(L, inv_diag, b, x):
    """``x = (L Lᵀ)⁻¹ b`` by two triangular solves (``L``, ``inv_diag`` from :func:`cholesky_factor`;
    ``b`` is read only, ``x`` may be any 1-D view)."""
    n = L.shape[0]
    for i in range(n):
        acc_i = b[i]
        for k in range(i):
            acc_i -= L[i, k] * x[k]
        x[i] = acc_i * inv_diag[i]
    for i in range(n - 1, -1, -1):
        acc_i = x[i]
        for k in range(i + 1, n):
            acc_i -= L[k, i] * x[k]
        x[i] = acc_i * inv_diag[i]


@njit(inline="always", **COMPILE)
def symmetric_times(packed, x, out):
    """``out = P x`` for the symmetric ``P`` (9 × 9) stored as its upper triangle ``packed``
    (:func:`~._kalman_kernels.pack_upper`), each entry summed over the columns in order."""
    for a in range(NX):
        acc_a = 0.0
        for b in range(NX):
            acc_a += packed[packed_index(a, b) if a <= b else packed_index(b, a)] * x[b]
        out[a] = acc_a


def new_scratch(n_slots: int, n_t: int) -> tuple:
    """Scratch of :func:`_smooth_stream` for ``n_slots`` streams at a time (one per thread), each
    ``T = n_t`` rows: b and v (smoothed in place), the gates' flags, the rates of the gaps'
    prediction, and :func:`~._kalman_kernels.new_records`' arrays; a slot is ``tuple(a[i] for a in
    scratch)``.  Allocated here by numpy, which asks the kernel for huge pages on large arrays:
    numba's allocator does not, and the 4 KB pages' faults on ~90 MB of records per 100,000
    samples cost about twice the writes themselves."""
    rows = (np.empty((n_t, 3)), np.empty((n_t, 3)), np.empty(n_t, dtype=bool), np.empty(n_t, dtype=bool),
            np.empty((n_t, 3))) + new_records(PLAIN_ZERO)
    return tuple(np.empty((n_slots, n_t) + row.shape[1:], dtype=row.dtype) for row in rows)


@njit(nogil=True, **COMPILE)
def _smooth_stream(gyr, acc, mag, received, q_init, start, init_only, c, out_q, interpolate_gaps, scratch):
    """Forward filter, RTS pass and (``interpolate_gaps``) curves across gaps for one recording;
    ``scratch``: one slot of :func:`new_scratch`."""
    n_t = out_q.shape[0]
    # The filter's q, b, v are smoothed in place: sample k is overwritten after its RTS step read it.
    smooth_b, smooth_v, acc_used, mag_used, rates = scratch[:5]
    pred_q, pred_v, post_P, pred_R, pred_a_e, pred_noise = records = scratch[5:]
    kalman_stream(gyr, acc, mag, received, q_init, start, init_only, c,
                  (out_q, smooth_b, smooth_v, np.empty((0, NX, NX)), acc_used, mag_used) + records)
    if n_t == 0:
        return
    first = start  # the first sample the filter's state exists at
    delta = np.empty(NX)
    chol = np.empty((NX, NX))
    y = np.empty(NX)
    inv_diag = np.empty(NX)
    P_pred = np.empty((NX, NX))
    dt, decay, bias_var = c.dt, c.vel_decay, c.bias_var
    # cholesky_factor, solve_factored, transition_transpose_times, symmetric_times and the prediction's
    # propagate_covariance, add_process_noise are inlined (inline="always"): the row views passed to them
    # (post_P[k], pred_R[k + 1], ...) then cost no reference counting per sample, as a call's arguments do.
    for k in range(n_t - 2, first - 1, -1):
        # correction = C_k δ = P⁺_k F_{k+1}ᵀ (P⁻_{k+1})⁻¹ δ: one solve with P⁻ (Cholesky), no inverse
        q_next = (out_q[k + 1, 0], out_q[k + 1, 1], out_q[k + 1, 2], out_q[k + 1, 3])
        q_pred = (pred_q[k + 1, 0], pred_q[k + 1, 1], pred_q[k + 1, 2], pred_q[k + 1, 3])
        d_theta = quat_log(quat_multiply(q_next, quat_conjugate(q_pred)))
        for a in range(3):
            delta[a] = d_theta[a]
            delta[3 + a] = smooth_b[k + 1, a] - smooth_b[k, a]  # b⁻_{k+1} = b⁺_k, not yet smoothed
            delta[6 + a] = smooth_v[k + 1, a] - pred_v[k + 1, a]
        # P⁻_{k+1} = F_{k+1} P⁺_k F_{k+1}ᵀ + Q_{k+1}, as the filter's prediction computed it
        unpack_upper(post_P[k], P_pred)
        propagate_covariance(P_pred, pred_R[k + 1], pred_a_e[k + 1], decay, dt)
        add_process_noise(P_pred, pred_noise[k + 1], bias_var)
        cholesky_factor(P_pred, chol, inv_diag)  # P⁻_{k+1} = L Lᵀ
        solve_factored(chol, inv_diag, delta, y)
        transition_transpose_times(pred_R[k + 1], pred_a_e[k + 1], decay, dt, y, delta)  # delta ← Fᵀ y
        symmetric_times(post_P[k], delta, y)  # y ← P⁺_k delta, the correction
        q = quat_normalize(quat_multiply(small_rotation((y[0], y[1], y[2])),
                                         (out_q[k, 0], out_q[k, 1], out_q[k, 2], out_q[k, 3])))
        for a in range(4):
            out_q[k, a] = q[a]
        for a in range(3):
            smooth_b[k, a] += y[3 + a]
            smooth_v[k, a] += y[6 + a]
    if not interpolate_gaps:
        return
    # Rates for the gaps' linear prediction: bias-corrected where received, linear between
    # the received neighbours where lost (only read inside the windows).
    order, window = c.ar_order, c.ar_window
    predict = c.gap == gaps.AR and window >= 3 * order
    if predict:
        prev = -1
        for t in range(first, n_t):
            if not received[t]:
                continue
            for a in range(3):
                rates[t, a] = gyr[t, a] - smooth_b[t, a]
            if prev >= 0:
                for k in range(prev + 1, t):
                    u = (k - prev) / (t - prev)
                    for a in range(3):
                        rates[k, a] = (1.0 - u) * rates[prev, a] + u * rates[t, a]
            prev = t
        for k in range(max(prev, first) + 1, n_t):  # after the last received: hold
            for a in range(3):
                rates[k, a] = rates[prev, a] if prev >= 0 else 0.0
    last_received = np.int64(-1)  # (not the literal -1, for which numba would compile the gap functions too)
    for t in range(first, n_t):
        if not (received[t] or t == first):
            continue
        if last_received >= 0 and t - last_received > 1:
            s0, s1 = last_received, t
            w0 = (gyr[s0, 0] - smooth_b[s0, 0], gyr[s0, 1] - smooth_b[s0, 1], gyr[s0, 2] - smooth_b[s0, 2])
            w1 = (gyr[s1, 0] - smooth_b[s1, 0], gyr[s1, 1] - smooth_b[s1, 1], gyr[s1, 2] - smooth_b[s1, 2])
            if not received[s0]:  # q0 given and nothing received before: no rate at s0
                w0 = w1
            q_a = (out_q[s0, 0], out_q[s0, 1], out_q[s0, 2], out_q[s0, 3])
            q_b = (out_q[s1, 0], out_q[s1, 1], out_q[s1, 2], out_q[s1, 3])
            if predict and received[s0] and s0 - window + 1 >= first and s1 + window <= n_t:
                _predicted_gap(out_q, rates, s0, s1, q_a, q_b, order, window, dt)
            else:
                _hermite_gap(out_q, s0, s1, q_a, q_b, w0, w1, dt)
        last_received = t


def smooth_orientation(gyr, acc, mag=None, *, fs: float, received=None, q0=None, settings=None, gap: str = "ar",
                       replay: bool = True, gap_time_constant=None, interpolate_gaps: bool = True) -> np.ndarray:
    """Offline orientation: forward Kalman filter, backward RTS pass, curves across gaps.

    Uses every received sample, also those after a sample (module docstring).  For recorded
    sessions; the output at sample ``t`` depends on later samples, so it cannot stream.

    Parameters
    ----------
    gyr, acc, mag, fs, received, q0, settings, gap, replay, gap_time_constant
        As in :func:`wsnlib.orientation.kalman.kalman_orientation`: the forward pass *is* that
        filter, with the same settings, gap handling and replay.  A replayed gap's estimates
        replace what the filter output on its lost samples (it knows them at the gap's end), so
        the backward pass starts from the filter's best path.  ``gap`` also chooses the curve
        across gaps (module docstring); every lost sample gets the smoothed estimate (no
        ``output_on_lost``).
    interpolate_gaps : bool
        Replace the smoothed estimate across each gap by the curve of the module docstring
        (both sides' linear prediction, or the cubic Hermite curve) (default); ``False`` keeps
        the RTS estimate there (for comparison).

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth), ``...`` the broadcast leading dimensions.  At the
        last sample equal to the output of the filter with the same arguments.

    Raises
    ------
    ValueError
        As :func:`~wsnlib.orientation.kalman.kalman_orientation`.
    """
    settings = KalmanSettings() if settings is None else settings  # built once: each construction checks every field
    c = constants(settings, fs, gap=gap, replay=replay, gap_time_constant=gap_time_constant, has_mag=mag is not None,
                  filter_name="smooth_orientation", record=True)
    inputs = prepare_inputs(gyr, acc, mag, received, q0, settings.gravity)
    if not isinstance(interpolate_gaps, bool):
        raise ValueError(f"interpolate_gaps must be True or False, got {interpolate_gaps!r}")
    n_batch = inputs.index.shape[0]
    n_slots = B.thread_slots(n_batch)
    # Output, plus each thread's scratch: b, v, the records (q⁻, v⁻, packed P⁺, R, a_E, Q's diagonal),
    # rates per sample.
    B.check_memory(8 * inputs.n_t * (4 * n_batch + n_slots * (6 + 7 + NP + 12 + 2 + 3)),
                   f"smooth_orientation's output for batch {inputs.batch}, T = {inputs.n_t}")
    out_q = np.empty((n_batch, inputs.n_t, 4))
    scratch = new_scratch(n_slots, inputs.n_t)

    def run_one(n, slot):
        i_gyr, i_acc, i_mag, i_rx = inputs.index[n]
        _smooth_stream(inputs.gyr[i_gyr], inputs.acc[i_acc], inputs.mag[i_mag], inputs.received[i_rx], inputs.q_init[n],
                       inputs.start[n], inputs.init_only, c[0], out_q[n], interpolate_gaps,
                       tuple(part[slot] for part in scratch))

    B.in_threads(run_one, n_batch)  # the streams side by side, each thread its slot of scratch
    return check_finite_output(out_q.reshape(inputs.batch + (inputs.n_t, 4)))
