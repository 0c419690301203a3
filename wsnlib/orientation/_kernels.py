"""Compiled loops of Madgwick's filter under loss: one recording over time, and the batch drivers.

:func:`filter_stream` is the whole of :func:`wsnlib.orientation.estimate_orientation` for one
recording (every loss-handling method is a branch of it), :func:`next_lost_run` one step of
λ_eff (:func:`wsnlib.orientation.effective_lost_run`), :func:`single_frame_check` the gated
hybrid's test of one sample (:class:`wsnlib.orientation.SingleFrameGate`).  They are built from
the scalar functions of :mod:`._scalar_kernels` (Madgwick's update, TRIAD, SLERP, quaternion
helpers), which this module re-exports for the modules that import them from here
(:mod:`._kalman_kernels`, :mod:`wsnlib.orientation.smoothing`).  The gap-aware Kalman filter's
loop is in :mod:`._kalman_kernels`.

The ``run_*`` drivers loop over a flattened batch with ``prange`` (one thread per core); which
recording, mask and parameters batch element ``b`` uses is given by index arrays, so
broadcasting (one recording, many masks or a (ρ, τ) grid) copies nothing.

Nothing here validates: the public functions in :mod:`.madgwick`, :mod:`.loss_handling`,
:mod:`.hybrid_blend` and :mod:`.triad` check their arguments (clear ``ValueError``\\ s) before
calling a kernel, and the kernels never read a lost sample.  A kernel that meets a non-finite
state (an overflow from extreme but finite parameters) reports it through its status array
instead of returning NaN.

The compiled code is cached next to this file (``__pycache__``) or under
``NUMBA_CACHE_DIR``: the first call in a fresh process loads it instead of compiling.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from wsnlib import frames
from wsnlib.orientation import gaps

# The scalar kernels this module builds on, and those the smoother imports from here.
from wsnlib.orientation._scalar_kernels import (  # noqa: F401
    COMPILE,
    PARALLEL_SIN_TOL,
    PLAIN_FALSE,
    cross3,
    is_finite4,
    madgwick_update,
    quat_conjugate,
    quat_exp,
    quat_log,
    quat_multiply,
    quat_normalize,
    slerp,
    slerp_weight,
    squared_norm3,
    tilt,
    triad,
    unit3,
)

# ------------------------------------------------------------------------------------------
# Codes (ints, so that one compiled loop serves every method)
# ------------------------------------------------------------------------------------------

#: Madgwick's update rule after a gap, in the order of :data:`wsnlib.orientation.loss_handling.METHODS`.
STANDARD, DT_EXTENSION, ADAPTIVE_BETA = range(3)
#: λ schedules, in the order of :data:`wsnlib.orientation.loss_handling.SCHEDULES`.
DECAY, HOLD, INSTANT = range(3)
#: Hybrid blends: none, output stage, feedback into the state.
NO_BLEND, OUTPUT_BLEND, FEEDBACK_BLEND = range(3)
#: Status of a batch element after a run: fine, a non-finite estimate, acc ∥ mag where TRIAD was needed.
OK, OVERFLOW, PARALLEL = 0, 1, 2


@njit(**COMPILE)
def parallel3(a, m):
    """Whether unit ``a`` and ``m`` are parallel (``|a × m|`` below TRIAD's tolerance): no heading."""
    c = cross3(a, m)
    return squared_norm3(c[0], c[1], c[2]) < PARALLEL_SIN_TOL * PARALLEL_SIN_TOL


# ------------------------------------------------------------------------------------------
# Paper 001: the λ schedules
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def next_lost_run(lam, counts_as_received, prev_lost, since, schedule, window):
    """One step of the effective λ (see :func:`wsnlib.orientation.effective_lost_run`).

    Returns ``(λ_t, lost_t, since_t)``: the new λ, whether this sample counts as lost, and
    (``"hold"``) the received samples since the last gap.
    """
    if not counts_as_received:
        return lam + 1.0, True, 0
    if schedule == DECAY:
        return (lam if prev_lost else max(lam - 1.0, 0.0)), False, since + 1
    if schedule == HOLD:
        since += 1
        return (lam if since <= window else 0.0), False, since
    return 0.0, False, since + 1  # INSTANT: the literal reading


# ------------------------------------------------------------------------------------------
# One recording
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def _vec(arr, t):
    return arr[t, 0], arr[t, 1], arr[t, 2]


@njit(**COMPILE)
def _unit_at(arr, t):
    return unit3(arr[t, 0], arr[t, 1], arr[t, 2])


@njit(**COMPILE)
def _store(out, t, q):
    out[t, 0], out[t, 1], out[t, 2], out[t, 3] = q[0], q[1], q[2], q[3]


# ------------------------------------------------------------------------------------------
# Gated hybrid: does the single frame look trustworthy? (wsnlib.orientation.SingleFrameGate)
# ------------------------------------------------------------------------------------------

#: Positions in the gate vector: tolerances of |‖a‖/g − 1|, ‖ω‖ (rad/s), |‖m‖/‖m_ref‖ − 1|,
#: |dip − dip_ref| (rad), and the reference low-pass gain 1 − exp(−Δt/τ_ref).
GATE_ACC_NORM, GATE_RATE, GATE_MAG_NORM, GATE_MAG_DIP, GATE_REF_GAIN = range(5)
GATE_SIZE = 5
#: The gravity TRIAD's accelerometer is compared with (m/s²).
_GRAVITY = frames.STANDARD_GRAVITY


@njit(**COMPILE)
def single_frame_check(a, m, g, gate, ref_norm, ref_dip):
    """Whether TRIAD of one received sample may be trusted; returns ``(trusted, ref_norm, ref_dip)``.

    ``a`` specific force (m/s²), ``m`` field (any unit), ``g`` angular rate (rad/s), raw
    3-tuples; ``gate`` the vector above; ``ref_norm`` (0: unset, the sample sets it) and
    ``ref_dip`` (rad) the field's reference norm and dip.  Trusted when ``|‖a‖/g − 1|``,
    ``‖ω‖``, ``|‖m‖/ref_norm − 1|`` and ``|dip − ref_dip|`` are all within their tolerances.
    The dip is the angle of the field below the plane normal to ``a`` (``asin(−â·m̂)``), so it
    needs no orientation estimate.  The references follow every sample by a first-order
    low-pass (the dip only while the accelerometer looks like gravity): a lasting change of
    the field becomes the reference within about τ_ref.
    """
    a_norm = math.sqrt(squared_norm3(a[0], a[1], a[2]))
    m_norm = math.sqrt(squared_norm3(m[0], m[1], m[2]))
    acc_ok = abs(a_norm / _GRAVITY - 1.0) <= gate[GATE_ACC_NORM]
    rate_ok = math.sqrt(squared_norm3(g[0], g[1], g[2])) <= gate[GATE_RATE]
    cos_am = (a[0] * m[0] + a[1] * m[1] + a[2] * m[2]) / (a_norm * m_norm)
    dip = math.asin(min(max(-cos_am, -1.0), 1.0))
    if ref_norm == 0.0:
        ref_norm, ref_dip = m_norm, dip
    mag_ok = (abs(m_norm - ref_norm) <= gate[GATE_MAG_NORM] * ref_norm
              and abs(dip - ref_dip) <= gate[GATE_MAG_DIP])
    k = gate[GATE_REF_GAIN]
    ref_norm += k * (m_norm - ref_norm)
    if acc_ok:
        ref_dip += k * (dip - ref_dip)
    return acc_ok and rate_ok and mag_ok, ref_norm, ref_dip


@njit(parallel=True, **COMPILE)
def run_single_frame_trust(gyr, acc, mag, received, i_gyr, i_acc, i_mag, i_rx, gate, out):
    """:func:`single_frame_check` on every received sample; ``out`` ``(B, T)`` bool (False when lost)."""
    for b in prange(out.shape[0]):
        g_b, a_b, m_b, rx = gyr[i_gyr[b]], acc[i_acc[b]], mag[i_mag[b]], received[i_rx[b]]
        ref_norm, ref_dip = 0.0, 0.0
        for t in range(out.shape[1]):
            ok = False
            if rx[t]:
                ok, ref_norm, ref_dip = single_frame_check(_vec(a_b, t), _vec(m_b, t), _vec(g_b, t), gate,
                                                           ref_norm, ref_dip)
            out[b, t] = ok


@njit(**COMPILE)
def filter_stream(gyr, acc, mag, use_mag, received, q0, has_q0, method, replay, blend, dt, beta, beta_max,
                  rho, tau, schedule, window, gap_settings, history_rows, gated, gate, out):
    """Madgwick's filter with the loss options over one recording; returns a status.

    ``gyr``, ``acc``, ``mag`` ``(T, 3)`` (only received samples are read), ``received`` ``(T,)``,
    ``q0`` ``(4,)`` used if ``has_q0`` (else the filter starts from TRIAD, or the tilt without
    ``mag``, of the first received sample, which then only initialises), ``out`` ``(T, 4)``.
    ``method`` the update rule (:data:`STANDARD`, :data:`DT_EXTENSION`, :data:`ADAPTIVE_BETA`).
    What happens in a gap is :mod:`wsnlib.orientation.gaps`'s, for the settings of the record
    ``gap_settings`` (:func:`~wsnlib.orientation.gaps.new_gap_state`, copied here) and a rate
    history of ``history_rows`` rows (:func:`~wsnlib.orientation.gaps.history_length`): on a
    lost sample the output is the previous output (``"hold"``), or the state turned,
    gyroscope only, by the gap module's rate (``"constant_rate"``: the last received rate,
    times the record's ``factor`` per lost sample; ``"ar"``: the autoregressive prediction).
    With ``replay`` the first received sample after a gap first re-runs the gap from the state
    at its start, gyroscope only, at the gap module's replay rates (the AR prediction corrected
    towards the measured rate, else linear between both ends).  ``blend``: the
    hybrid's SLERP (:data:`NO_BLEND`, :data:`OUTPUT_BLEND`, :data:`FEEDBACK_BLEND`); with
    ``gated`` it skips eq. (4) (μ = 1) on every sample whose TRIAD :func:`single_frame_check`
    (vector ``gate``) does not trust.  See :func:`wsnlib.orientation.estimate_orientation`.
    """
    n_t = received.shape[0]
    q = (q0[0], q0[1], q0[2], q0[3])
    m = (0.0, 0.0, 0.0)
    if not has_q0:  # start from the first received sample; before it, show that start
        for first in range(n_t):
            if received[first]:
                a = _unit_at(acc, first)
                if use_mag:
                    m = _unit_at(mag, first)
                    if parallel3(a, m):
                        return PARALLEL
                    q = triad(a, m)
                else:
                    q = tilt(a)
                break
    shown = q
    started = has_q0
    lam, prev_lost, since = 0.0, False, 0  # λ_eff schedule state
    run = 0  # samples lost since the last received one (after the start)
    last = -1  # last received sample
    q_last = q  # the state at that sample: where a replay starts
    # The gap module's record and its history of the raw rates; the AR fit's scratch.
    gap_array = gap_settings.copy()
    gs = gap_array[0]
    turns_in_gap = gs.mode != gaps.HOLD
    history = np.zeros((history_rows, 3))
    fits = gs.mode == gaps.AR
    scratch_A = np.empty((3, gaps.MAX_ORDER, gaps.MAX_ORDER + 1) if fits else (1, 1, 1))
    scratch_r = np.empty((3, gaps.MAX_ORDER + 1) if fits else (1, 2))
    predicted = np.empty(3)
    trusted, ref_norm, ref_dip = True, 0.0, 0.0  # gated hybrid: the field's reference
    for t in range(n_t):
        rx = received[t]
        # A gap before the filter starts is no gap: λ_eff counts only once it runs.
        lam, prev_lost, since = next_lost_run(lam, rx or not started, prev_lost, since, schedule, window)
        if not rx:
            if started:
                run += 1
                if last >= 0:
                    g_gap = gaps.gap_lost(gs, history, scratch_A, scratch_r)
                    if turns_in_gap:  # dead reckoning on the gap module's rate
                        q = madgwick_update(q, g_gap, g_gap, g_gap, PLAIN_FALSE, dt, 0.0)
                        shown = q
            _store(out, t, shown)
            continue
        a = _unit_at(acc, t)
        if use_mag:
            m = _unit_at(mag, t)
        if gated:  # a scalar check per received sample
            trusted, ref_norm, ref_dip = single_frame_check(_vec(acc, t), _vec(mag, t), _vec(gyr, t), gate,
                                                            ref_norm, ref_dip)
        g = _vec(gyr, t)
        if not started:  # the first received sample only initialised the filter (above)
            started, last, q_last = True, t, q
            gaps.gap_received(gs, history, g)
            _store(out, t, q)
            continue
        if replay and run > 0:
            # Replay the lost samples from the state at the gap's start, gyroscope only, at the
            # gap module's replay rates (the AR prediction corrected towards g, else linear from
            # the last received rate; for a gap at the start, the first received one).
            q = q_last
            weights = np.empty((3, run + 1))
            use_ar = fits and last >= 0 and gaps.replay_weights(gs, history, g, weights, np.empty(run + 1), predicted)
            for k in range(1, run + 1):
                g_k = gaps.replay_rate(gs, history, k, g, use_ar, weights, predicted) if last >= 0 else g
                q = madgwick_update(q, g_k, a, m, use_mag, dt, 0.0)
        dt_gyro = dt * (1.0 + run) if method == DT_EXTENSION else dt
        beta_dt = beta * dt
        if method == ADAPTIVE_BETA:  # β_eff = β + (β_max − β)(1 − μ)
            beta_dt = (beta + (beta_max - beta) * (1.0 - slerp_weight(lam, rho, tau))) * dt
        q = madgwick_update(q, g, a, m, use_mag, dt_gyro, beta_dt)
        shown = q
        if blend != NO_BLEND and lam > 0.0 and trusted:  # eq. (4): q_f = SLERP(q_s, q_d, μ)
            if parallel3(a, m):
                return PARALLEL
            q_f = slerp(triad(a, m), q, slerp_weight(lam, rho, tau))
            shown = q_f
            if blend == FEEDBACK_BLEND:
                q = q_f
        if not is_finite4(q):
            return OVERFLOW
        _store(out, t, shown)
        gaps.gap_received(gs, history, g)
        run, last, q_last = 0, t, q
    gap_array[0] = gs  # keeps the record's array alive to here
    return OK


@njit(parallel=True, **COMPILE)
def run_filter(gyr, acc, mag, use_mag, received, q0, has_q0, i_gyr, i_acc, i_mag, i_rx, i_q0,
               method, replay, blend, dt, beta, beta_max, rho, tau, schedule, window, gap_settings, history_rows,
               gated, gate, out, status):
    """:func:`filter_stream` for every batch element ``b`` of ``out`` ``(B, T, 4)``, in parallel.

    Element ``b`` reads recording ``gyr[i_gyr[b]]`` (likewise ``acc``, ``mag``), mask
    ``received[i_rx[b]]``, start ``q0[i_q0[b]]`` and parameters ``beta[b]``, ``beta_max[b]``,
    ``rho[b]``, ``tau[b]``, ``window[b]``; ``status[b]`` receives its status.
    """
    for b in prange(out.shape[0]):
        status[b] = filter_stream(gyr[i_gyr[b]], acc[i_acc[b]], mag[i_mag[b]], use_mag, received[i_rx[b]],
                                  q0[i_q0[b]], has_q0, method, replay, blend, dt, beta[b], beta_max[b], rho[b],
                                  tau[b], schedule, window[b], gap_settings, history_rows, gated, gate, out[b])


@njit(parallel=True, **COMPILE)
def run_step(q, gyr, acc, mag, use_mag, dt, beta_dt, out):
    """One Madgwick update per row: ``q`` ``(B, 4)`` unit, signals ``(B, 3)`` (acc, mag non-zero)."""
    for b in prange(q.shape[0]):
        q_b = (q[b, 0], q[b, 1], q[b, 2], q[b, 3])
        m = _unit_at(mag, b) if use_mag else (0.0, 0.0, 0.0)
        _store(out, b, madgwick_update(q_b, _vec(gyr, b), _unit_at(acc, b), m, use_mag, dt[b], beta_dt[b]))


@njit(parallel=True, **COMPILE)
def run_lost_run(received, i_rx, schedule, window, leading_gap, out):
    """Effective λ ``out`` ``(B, T)`` of mask ``received[i_rx[b]]`` (:func:`next_lost_run`)."""
    for b in prange(out.shape[0]):
        rx = received[i_rx[b]]
        lam, prev_lost, since, seen = 0.0, False, 0, leading_gap
        for t in range(out.shape[1]):
            seen = seen or rx[t]
            lam, prev_lost, since = next_lost_run(lam, rx[t] or not seen, prev_lost, since, schedule, window[b])
            out[b, t] = lam


@njit(parallel=True, **COMPILE)
def run_output_blend(quat_d, acc, mag, received, trusted, i_q, i_acc, i_mag, i_rx, i_tr, rho, tau, schedule,
                     window, leading_gap, out, status):
    """Eq. (4) as an output stage on any filter's output ``quat_d`` (unit), ``out`` ``(B, T, 4)``.

    On a received sample with λ_eff > 0: ``SLERP(TRIAD, q_d, μ)``; elsewhere on received samples
    ``q_d``; on a lost sample eq. (4) with that sample's ``q_d`` and the TRIAD and μ of the last
    received sample (the previous output when ``q_d`` is held there).  Received samples where
    ``trusted[i_tr[b], t]`` is False are not blended (the gated hybrid; all True otherwise).
    ``status[b]``: :data:`PARALLEL` where acc ∥ mag on a sample to blend (the rest of ``out[b]`` unset).
    """
    for b in prange(out.shape[0]):
        status[b] = OK
        q_d, a_b, m_b, rx = quat_d[i_q[b]], acc[i_acc[b]], mag[i_mag[b]], received[i_rx[b]]
        tr = trusted[i_tr[b]]
        lam, prev_lost, since, seen = 0.0, False, 0, leading_gap
        blended, mu = False, 1.0
        q_s = (1.0, 0.0, 0.0, 0.0)
        for t in range(out.shape[1]):
            seen = seen or rx[t]
            lam, prev_lost, since = next_lost_run(lam, rx[t] or not seen, prev_lost, since, schedule, window[b])
            q_t = (q_d[t, 0], q_d[t, 1], q_d[t, 2], q_d[t, 3])
            if rx[t]:
                blended = lam > 0.0 and tr[t]
                if blended:
                    a, m = _unit_at(a_b, t), _unit_at(m_b, t)
                    if parallel3(a, m):
                        status[b] = PARALLEL
                        break
                    q_s = triad(a, m)
                    mu = slerp_weight(lam, rho[b], tau[b])
            _store(out[b], t, slerp(q_s, q_t, mu) if blended else q_t)


@njit(**COMPILE)
def triad_rows(acc, mag, out):
    """TRIAD per row: ``acc``, ``mag`` ``(B, 3)`` unit, ``out`` ``(B, 4)``."""
    for b in range(out.shape[0]):
        _store(out, b, triad(_vec(acc, b), _vec(mag, b)))


@njit(parallel=True, **COMPILE)
def run_triad(acc, mag, out):
    """:func:`triad_rows` with the rows in parallel (for many rows only: starting the threads costs
    more than a few thousand rows)."""
    for b in prange(out.shape[0]):
        _store(out, b, triad(_vec(acc, b), _vec(mag, b)))


@njit(**COMPILE)
def first_unusable_stream(x, rx, check_zero):
    """First received sample of ``x`` ``(T, 3)`` that is not finite (kind 1) or, with
    ``check_zero``, a zero vector (kind 2): ``(t, kind)``, ``(-1, 0)`` if there is none."""
    for t in range(x.shape[0]):
        if not rx[t]:
            continue
        if not (math.isfinite(x[t, 0]) and math.isfinite(x[t, 1]) and math.isfinite(x[t, 2])):
            return t, 1
        if check_zero and x[t, 0] == 0.0 and x[t, 1] == 0.0 and x[t, 2] == 0.0:
            return t, 2
    return -1, 0


@njit(**COMPILE)
def first_unusable(arr, i_arr, received, i_rx, check_zero, out):
    """:func:`first_unusable_stream` of ``arr[i_arr[b]]`` under ``received[i_rx[b]]`` into ``out[b]``."""
    for b in range(out.shape[0]):
        out[b, 0], out[b, 1] = first_unusable_stream(arr[i_arr[b]], received[i_rx[b]], check_zero)


@njit(parallel=True, **COMPILE)
def first_unusable_parallel(arr, i_arr, received, i_rx, check_zero, out):
    """:func:`first_unusable` with the batch elements in parallel (for large batches only: a check
    reads each sample once, and for small inputs starting the threads costs more)."""
    for b in prange(out.shape[0]):
        out[b, 0], out[b, 1] = first_unusable_stream(arr[i_arr[b]], received[i_rx[b]], check_zero)


@njit(parallel=True, **COMPILE)
def run_hold_lost(out, received, i_rx):
    """Hold the output over gaps, in place: ``out[b, t] = out[b, t − 1]`` on every lost ``t > 0``.

    ``out`` ``(B, T, C)``, mask ``received[i_rx[b]]`` ``(T,)`` (``gap="hold"`` of a filter that
    predicts inside, e.g. :func:`wsnlib.orientation.kalman_orientation`).
    """
    for b in prange(out.shape[0]):
        rx = received[i_rx[b]]
        for t in range(1, out.shape[1]):
            if not rx[t]:
                for c in range(out.shape[2]):
                    out[b, t, c] = out[b, t - 1, c]
