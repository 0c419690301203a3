"""Fixed-lag RTS smoothing for a live receiver: the Kalman filter's records in a ring, the backward pass.

The receiver of :mod:`wsnlib.stream` runs the gap-aware Kalman filter one sample at a time
(:func:`wsnlib.orientation._kalman_kernels.kalman_step`).  With a latency of ``L`` samples it
outputs sample ``t`` once sample ``t + L`` has been filtered, smoothed over that window: the
Rauch–Tung–Striebel pass of :mod:`wsnlib.orientation.smoothing` (same error-state equations),
run backward from the newest sample ``n`` over the last ``L`` samples only,

    C_k = P⁺_k F_{k+1}ᵀ (P⁻_{k+1})⁻¹,
    δ_k = C_k [Log(q^s_{k+1} ⊗ q⁻*_{k+1}),  b^s_{k+1} − b⁻_{k+1},  v^s_{k+1} − v⁻_{k+1}],
    q^s_k = Exp(δθ_k) ⊗ q⁺_k,   b^s_k = b⁺_k + δb_k,   v^s_k = v⁺_k + δv_k,

starting from the filter at ``n`` (``q^s_n = q⁺_n``).  ``L = 0`` is the causal filter; for ``L``
at least the recording's length it is :func:`~wsnlib.orientation.smooth_orientation` with
``interpolate_gaps=False`` (the smoother's records, its replayed gaps included).  The gain
``C_k`` depends only on the filter, so it is computed once, when sample ``k + 1`` is filtered
(one Cholesky factorisation of ``P⁻_{k+1}``, nine solves); a backward step is then a 9 × 9
product and two quaternion operations, and emitting a sample costs ``L`` of them.

What a ring entry holds (:data:`RING_DTYPE`, one per sample, the newest ``capacity`` samples,
sample ``t`` at row ``t mod capacity``): the filtered ``q⁺``, ``b⁺``, ``v⁺``; the prediction
``q⁻``, ``v⁻`` and the packed ``P⁻``, ``P⁺`` (:func:`~._kalman_kernels.pack_upper`); ``R(q⁻)``
and ``a_E``, which define ``F`` (:func:`~._kalman_kernels.transition_matrix`); and the gain
``C`` of this sample (set when the next one is recorded).  As in the smoother, when a gap's
replay (the ``replay`` option) re-runs the gap at its end, the replayed estimates replace both
``q⁺`` and ``q⁻`` of the gap's samples still in the ring (:func:`overwrite_path`), their
covariances stay those of the original prediction.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wsnlib.orientation._kalman_kernels import NP, NX, pack_upper, small_rotation, transition_matrix, unpack_upper
from wsnlib.orientation._scalar_kernels import (
    COMPILE,
    quat_conjugate,
    quat_log,
    quat_multiply,
    quat_normalize,
)
from wsnlib.orientation.smoothing import cholesky_factor, solve_factored

#: One sample of the ring (module docstring).  ``sample`` −1: empty; ``has_gain``: ``gain`` is set.
RING_DTYPE = np.dtype([
    ("sample", "i8"), ("received", "?"), ("q", "f8", (4,)), ("bias", "f8", (3,)), ("velocity", "f8", (3,)),
    ("q_pred", "f8", (4,)), ("vel_pred", "f8", (3,)), ("P_pred", "f8", (NP,)), ("P_post", "f8", (NP,)),
    ("R", "f8", (3, 3)), ("a_e", "f8", (3,)), ("gain", "f8", (NX, NX)), ("has_gain", "?"),
])


@njit(**COMPILE)
def record(ring, st, work, c, sample, received, scratch):
    """Store the filter after ``sample`` (``st``, and the prediction ``work`` kept with ``c.record``)
    and the previous sample's gain; ``scratch`` from :func:`new_scratch`."""
    capacity = ring.shape[0]
    e = ring[sample % capacity]
    e.sample, e.received = sample, received
    for a in range(4):
        e.q[a] = st.q[a]
        e.q_pred[a] = work.q_pred[a]
    for a in range(3):
        e.bias[a] = st.bias[a]
        e.velocity[a] = st.velocity[a]
        e.vel_pred[a] = work.vel_pred[a]
        e.a_e[a] = work.a_e[a]
        for b in range(3):
            e.R[a, b] = work.R[a, b]
    pack_upper(work.P_pred, e.P_pred)
    pack_upper(st.P, e.P_post)
    e.has_gain = False
    prev = ring[(sample - 1) % capacity]
    if capacity > 1 and prev.sample == sample - 1:
        P_post, F, FP, chol, inv_diag = scratch
        unpack_upper(prev.P_post, P_post)
        transition_matrix(e.R, e.a_e, c.vel_decay, c.dt, F)
        for a in range(NX):  # F P⁺
            for b in range(NX):
                s = 0.0
                for m in range(NX):
                    s += F[a, m] * P_post[m, b]
                FP[a, b] = s
        cholesky_factor(work.P_pred, chol, inv_diag)  # P⁻ (e.P_pred packed)
        for b in range(NX):  # column b of (P⁻)⁻¹ F P⁺ = row b of C (P⁺, P⁻ symmetric)
            solve_factored(chol, inv_diag, FP[:, b], prev.gain[b])
        prev.has_gain = True


def new_scratch():
    """Scratch arrays of :func:`record`: P⁺, F, F P⁺, the Cholesky factor of P⁻ (9 × 9) and its
    inverted diagonal (9,)."""
    return np.empty((NX, NX)), np.empty((NX, NX)), np.empty((NX, NX)), np.empty((NX, NX)), np.empty(NX)


@njit(**COMPILE)
def overwrite_path(ring, first, path, n):
    """The replayed estimates ``path[:n]`` of samples ``first … first + n − 1`` replace ``q⁺`` and ``q⁻``
    of those still in the ring."""
    capacity = ring.shape[0]
    for k in range(n):
        e = ring[(first + k) % capacity]
        if e.sample == first + k:
            for a in range(4):
                e.q[a] = path[k, a]
                e.q_pred[a] = path[k, a]


@njit(**COMPILE)
def backward(ring, newest, depth, oldest, out):
    """Smoothed quaternions of samples ``newest, newest − 1, …`` into ``out[0], out[1], …`` (≤ ``depth`` + 1
    rows, never below sample ``oldest``); returns how many rows were written.  ``out[0]`` is the filter at
    ``newest``; row ℓ is the fixed-lag estimate of sample ``newest − ℓ`` with lag ℓ."""
    capacity = ring.shape[0]
    e = ring[newest % capacity]
    qs = (e.q[0], e.q[1], e.q[2], e.q[3])
    bs = (e.bias[0], e.bias[1], e.bias[2])
    vs = (e.velocity[0], e.velocity[1], e.velocity[2])
    for a in range(4):
        out[0, a] = qs[a]
    delta = np.empty(NX)
    y = np.empty(NX)
    written = 1
    for lag in range(1, depth + 1):
        k = newest - lag
        if k < oldest:
            break
        nxt = ring[(k + 1) % capacity]
        e = ring[k % capacity]
        if e.sample != k or not e.has_gain:
            break
        d = quat_log(quat_multiply(qs, quat_conjugate((nxt.q_pred[0], nxt.q_pred[1], nxt.q_pred[2], nxt.q_pred[3]))))
        for a in range(3):
            delta[a] = d[a]
            delta[3 + a] = bs[a] - e.bias[a]  # b⁻_{k+1} = b⁺_k
            delta[6 + a] = vs[a] - nxt.vel_pred[a]
        for a in range(NX):
            s = 0.0
            for b in range(NX):
                s += e.gain[a, b] * delta[b]
            y[a] = s
        qs = quat_normalize(quat_multiply(small_rotation((y[0], y[1], y[2])), (e.q[0], e.q[1], e.q[2], e.q[3])))
        bs = (e.bias[0] + y[3], e.bias[1] + y[4], e.bias[2] + y[5])
        vs = (e.velocity[0] + y[6], e.velocity[1] + y[7], e.velocity[2] + y[8])
        for a in range(4):
            out[lag, a] = qs[a]
        written += 1
    return written
