"""The receiver's compiled core: per node, packets in order, the filter, the output.

:mod:`wsnlib.stream.receiver` holds the rules in words (and the Python class); this is them in
numba.  A node is a slot ``i`` of the arrays of :class:`Nodes` (one bookkeeping record
:data:`NODE_DTYPE`, the Kalman filter's records, a reorder buffer, the rotations of its recent
packets, a checkpoint of the filter at the start of the current gap, and the fixed-lag ring of
:mod:`wsnlib.orientation.fixed_lag`).  Every sample goes through :func:`_step` (the compiled
Kalman step of :mod:`wsnlib.orientation`, or :func:`~wsnlib.orientation.bridging.bridge_step` on
a lost sample whose rotation a later packet summarised) and then :func:`_output` (emit it, or
record it in the ring and emit the sample ``latency`` samples back).  Packets reach a node's
filter only in sequence order, through :func:`release_received` and :func:`release_lost`; the
network side (:func:`receive`) parses datagrams, finds the node and keeps the reorder window; a
simulation of a whole recording (:func:`run_node`) releases packets straight in order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wsnlib.orientation import _kalman_kernels as KK
from wsnlib.orientation import gaps
from wsnlib.orientation._scalar_kernels import (
    COMPILE,
    PARALLEL_SIN_TOL,
    PLAIN_FALSE,
    PLAIN_TRUE,
    PLAIN_ZERO,
    cross3,
    quat_conjugate,
    quat_exp,
    quat_log,
    quat_multiply,
    quat_normalize,
    tilt,
    triad,
    vec_norm,
)
from wsnlib.orientation.bridging import bridge_step
from wsnlib.orientation.fixed_lag import backward, overwrite_path, record
from wsnlib.stream import _kernels as PK

#: Per node: its id; whether it sends a magnetometer; whether its filter started (first received
#: sample); samples per packet (from its first packet); the next packet to release (sequence
#: number, unwrapped) and its first sample; the highest sequence number seen; the stream's first
#: sample; the next sample to output; the newest sample filtered; the last 62 released packets
#: (bit j: packet ``next_seq − 1 − j`` was received); lost packets since the last received one;
#: the counters (:data:`COUNTERS`); the receiver's clock (s) when the last packet arrived, and when, by
#: that clock, the node's sample 0 was taken (its *origin*; NaN: no clock given).
NODE_DTYPE = np.dtype([
    ("id", "i8"), ("has_mag", "?"), ("started", "?"), ("spp", "i8"), ("next_seq", "i8"), ("next_sample", "i8"),
    ("max_seq", "i8"), ("first_sample", "i8"), ("emitted", "i8"), ("newest", "i8"), ("recent", "i8"),
    ("gap_packets", "i8"), ("counts", "i8", (6,)), ("clock_s", "f8"), ("clock_origin", "f8"),
])
#: Counter names, in the order of ``NODE_DTYPE["counts"]``.
COUNTERS = ("received", "lost", "duplicate", "reordered", "corrupt", "late")
N_RECEIVED, N_LOST, N_DUPLICATE, N_REORDERED, N_CORRUPT, N_LATE = range(6)
RECENT_BITS = 62
#: State of a packet's rotation in a node's ring of recent rotations (numpy scalars, not literals: one
#: compiled :func:`_remember_rotation`, see ``PLAIN_ZERO``).
ROT_UNKNOWN, ROT_RECEIVED, ROT_BRIDGED = np.int64(0), np.int64(1), np.int64(2)
#: Configuration (``cfg``, int64): reorder window (packets), latency (samples), bridge (0/1), whether
#: the ring is used, longest gap (samples) a summary may bridge.
CFG_REORDER, CFG_LATENCY, CFG_BRIDGE, CFG_RING, CFG_LONGEST_BRIDGE = range(5)


# ------------------------------------------------------------------------------------------
# Output
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def _append(out, book, sample, q, received):
    """Append ``(node, sample, q, received)`` to the output arrays ``out``."""
    out_node, out_sample, out_q, out_rx, count = out[0], out[1], out[2], out[3], out[4]
    j = count[0]
    out_node[j] = book.id
    out_sample[j] = sample
    for a in range(4):
        out_q[j, a] = q[a]
    out_rx[j] = received
    count[0] = j + 1


@njit(**COMPILE)
def _output(i, nodes, cfg, c, sample, received, out, dense, lags, scratch, live):
    """After sample ``sample`` was filtered: with latency 0, emit it; else record it in the ring and,
    when ``live``, emit the sample ``latency`` back (``dense`` (n_lags, T, 4) non-empty: a
    simulation, which keeps every lag of ``lags`` instead)."""
    book, st, work, ring = nodes[0][i], nodes[1][i], nodes[3][i], nodes[18][i]
    book.newest = sample
    if cfg[CFG_RING] == 0:
        if live:
            _append(out, book, sample, st.q, received)
            book.emitted = sample + 1
        return
    record(ring, st, work, c, sample, received, scratch[0])
    if not live:
        return
    rows = scratch[1]
    if dense.shape[1] > 0:
        n = backward(ring, sample, lags[lags.shape[0] - 1], book.first_sample, rows)
        for li in range(lags.shape[0]):
            if lags[li] < n and sample - lags[li] < dense.shape[1]:  # (a lost last packet may run past the end)
                for a in range(4):
                    dense[li, sample - lags[li], a] = rows[lags[li], a]
        return
    latency = cfg[CFG_LATENCY]
    if sample - latency >= book.emitted:
        backward(ring, sample, latency, book.first_sample, rows)
        e = ring[(sample - latency) % ring.shape[0]]
        _append(out, book, sample - latency, rows[latency], e.received)
        book.emitted = sample - latency + 1


@njit(**COMPILE)
def flush_output(i, nodes, cfg, out, dense, lags, scratch):
    """Emit the samples still held for the latency (smoothed up to the newest sample)."""
    book, ring = nodes[0][i], nodes[18][i]
    if cfg[CFG_RING] == 0 or book.emitted > book.newest or not book.started:
        return
    rows = scratch[1]
    newest = book.newest
    depth = min(newest - book.emitted, rows.shape[0] - 1)
    n = backward(ring, newest, depth, book.first_sample, rows)
    for lag in range(n - 1, -1, -1):
        k = newest - lag
        if dense.shape[1] > 0:
            for li in range(lags.shape[0]):
                if lags[li] > lag and k < dense.shape[1]:  # no sample lags[li] later: the latest estimate
                    for a in range(4):
                        dense[li, k, a] = rows[lag, a]
        else:
            _append(out, book, k, rows[lag], ring[k % ring.shape[0]].received)
    book.emitted = newest + 1


# ------------------------------------------------------------------------------------------
# One sample through the filter
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def _initialise(st, gs, history, work, c, values):
    """The first received sample: TRIAD (tilt without magnetometer) as in ``kalman_orientation(q0=None)``."""
    a_norm = vec_norm((values[3], values[4], values[5]))
    a = (values[3] / a_norm, values[4] / a_norm, values[5] / a_norm)
    q = tilt(a)
    if c.has_mag:
        m_norm = vec_norm((values[6], values[7], values[8]))
        m = (values[6] / m_norm, values[7] / m_norm, values[8] / m_norm)
        if vec_norm(cross3(a, m)) >= PARALLEL_SIN_TOL:
            q = triad(a, m)
    KK.initial_state(st, c, np.array(q))
    gaps.gap_received(gs, history, (values[0], values[1], values[2]))
    KK._keep_prediction(st, work, c)


@njit(**COMPILE)
def _step(i, nodes, cfg, c, bc, sample, received, values, rate, rate_sigma, run):
    """Filter one sample of node ``i``: received (``values`` gyr, acc, mag), lost, or bridged (``rate``
    rad/s, raw, with ``rate_sigma``; ``run`` samples since the last received one).  A gap's replay
    path goes into the ring (as the smoother's records)."""
    book, st, gs, work, history, ring = nodes[0][i], nodes[1][i], nodes[2][i], nodes[3][i], nodes[4][i], nodes[18][i]
    if not book.started:
        _initialise(st, gs, history, work, c, values)
        book.started = True
        return
    n_lost = gs.lost
    replaying = cfg[CFG_RING] != 0 and c.replay and n_lost > 0 and gs.n > n_lost and (received or rate_sigma >= 0.0)
    path = np.empty((n_lost if replaying else 0, 4))
    if received or rate_sigma < 0.0:  # (the readings as tuples, as kalman_stream passes them: one compiled step)
        KK.kalman_step(st, gs, history, work, c, (values[0], values[1], values[2]), (values[3], values[4], values[5]),
                       (values[6], values[7], values[8]), received, path)
    else:
        bridge_step(st, gs, history, work, c, bc, rate, rate_sigma, run, path)
    if replaying:
        overwrite_path(ring, sample - n_lost, path, n_lost)


# ------------------------------------------------------------------------------------------
# Packets in order
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def _constants(book, consts):
    return consts[1] if book.has_mag else consts[0]


@njit(**COMPILE)
def _remember_rotation(nodes, i, seq, state, q):
    rot_q, rot_state, rot_seq = nodes[15][i], nodes[16][i], nodes[17][i]
    r = seq % rot_state.shape[0]
    rot_state[r], rot_seq[r] = state, seq
    for a in range(4):
        rot_q[r, a] = q[a]


@njit(**COMPILE)
def _end_of_stream_packet(i, nodes, cfg, out, dense, lags, scratch):
    """Node ``i``'s packet just released held fewer samples than its packets do (a sender's last
    packet): the next packet's first sample is not the one after it, so the smoother's window ends
    here.  Emit the samples held for the latency now (within their deadline), smoothed up to this
    packet's last sample, and go on from the next packet's first sample."""
    flush_output(i, nodes, cfg, out, dense, lags, scratch)
    nodes[0][i].emitted = nodes[0][i].next_sample


@njit(**COMPILE)
def release_lost(i, nodes, cfg, consts, bconsts, out, dense, lags, scratch):
    """The next packet of node ``i`` is lost: its samples are predicted (and output)."""
    book = nodes[0][i]
    if book.gap_packets == 0:  # the filter after the last received sample: where a bridge starts again
        nodes[5][i] = nodes[1][i]
        nodes[6][i] = nodes[2][i]
        nodes[7][i] = nodes[3][i]
    c = _constants(book, consts)
    bc = bconsts[1] if book.has_mag else bconsts[0]
    nothing = np.zeros(9)
    for s in range(book.spp):
        sample = book.next_sample + s
        _step(i, nodes, cfg, c, bc, sample, PLAIN_FALSE, nothing, (0.0, 0.0, 0.0), -1.0, PLAIN_ZERO)
        _output(i, nodes, cfg, c, sample, PLAIN_FALSE, out, dense, lags, scratch, PLAIN_TRUE)
    _remember_rotation(nodes, i, book.next_seq, ROT_UNKNOWN, (1.0, 0.0, 0.0, 0.0))
    book.counts[N_LOST] += 1
    book.gap_packets += 1
    book.recent = (book.recent << 1) & ((1 << RECENT_BITS) - 1)
    book.next_seq += 1
    book.next_sample += book.spp


@njit(**COMPILE)
def _gap_segments(i, nodes, b, seg_q, seg_sigma):
    """Which lost packets of the current gap the buffered packet ``b`` summarises, as segments: for lost
    packet ``p`` of the gap (0-based), ``seg_sigma[p]`` ≥ 0 is its segment's rotation error std per
    component (rad; −1: not covered) and ``seg_q[p]`` the rotation of its segment's part inside the gap
    (the same for every packet of a segment; segments are maximal runs of equal ``seg_q``).  Returns
    whether any packet is covered."""
    book = nodes[0][i]
    n_gap = book.gap_packets
    k, layout, sigma, rot = nodes[11][i, b], nodes[12][i, b], nodes[13][i, b], nodes[14][i, b]
    rot_q, rot_state, rot_seq = nodes[15][i], nodes[16][i], nodes[17][i]
    e = book.next_seq  # this packet; the gap is packets e − n_gap … e − 1
    for p in range(n_gap):
        seg_sigma[p] = -1.0
    covered = False
    span_prev = (1.0, 0.0, 0.0, 0.0)
    for j in range(k):
        if layout == PK.CONSECUTIVE:
            lo = hi = e - 1 - j
            segment = quat_exp((rot[j, 0], rot[j, 1], rot[j, 2]))
            error = sigma
        else:
            span = quat_exp((rot[j, 0], rot[j, 1], rot[j, 2]))
            lo, hi = e - (1 << j), e - 1 - (0 if j == 0 else 1 << (j - 1))
            segment = quat_normalize(quat_multiply(span, quat_conjugate(span_prev)))  # span_j ⊗ span_{j−1}⁻¹
            error = sigma if j == 0 else sigma * math.sqrt(2.0)
            span_prev = span
        if hi < e - n_gap:
            break  # entirely before the gap
        if lo < e - n_gap:  # packets before the gap in this segment: their rotation must be known
            before = (1.0, 0.0, 0.0, 0.0)
            known = True
            for p in range(lo, e - n_gap):
                r = p % rot_state.shape[0]
                if rot_seq[r] != p or rot_state[r] == ROT_UNKNOWN:
                    known = False
                    break
                before = quat_normalize(quat_multiply(before, (rot_q[r, 0], rot_q[r, 1], rot_q[r, 2], rot_q[r, 3])))
            if not known:
                break
            segment = quat_normalize(quat_multiply(quat_conjugate(before), segment))
            lo = e - n_gap
        for p in range(lo, hi + 1):
            at = p - (e - n_gap)
            for a in range(4):
                seg_q[at, a] = segment[a]
            seg_sigma[at] = error
        covered = True
        if lo == e - n_gap:
            break
    return covered


@njit(**COMPILE)
def _fit_segment(rates, first, stop, q, dt):
    """Correct the rates ``rates[first:stop]`` (rad/s) so that ``Π Exp(ω Δt)`` over them is the rotation
    ``q`` exactly: with ``R`` their product now and ``c = Log(R⁻¹ ⊗ q)`` the correction, the path
    becomes ``R_k ⊗ Exp(u_k c)`` (``R_k`` the product up to sample k, ``u_k`` its share of the
    segment), and each rate the step between consecutive points of that path."""
    n = stop - first
    c = quat_log(quat_multiply(quat_conjugate(PK.integrated_rotation(rates, first, stop, dt)), q))
    path = (1.0, 0.0, 0.0, 0.0)
    previous = path
    for k in range(first, stop):
        path = quat_normalize(quat_multiply(path, quat_exp((rates[k, 0] * dt, rates[k, 1] * dt, rates[k, 2] * dt))))
        u = (k - first + 1.0) / n
        target = quat_normalize(quat_multiply(path, quat_exp((u * c[0], u * c[1], u * c[2]))))
        step = quat_log(quat_multiply(quat_conjugate(previous), target))
        for a in range(3):
            rates[k, a] = step[a] / dt
        previous = target


@njit(inline="always", **COMPILE)  # one caller: no library of its own to compile
def _bridge(i, nodes, b, cfg, c, bc, out, dense, lags, scratch):
    """Re-run the current gap from the checkpoint with the rotations packet ``b`` summarises (the
    outputs already given stay; the ring's records of the gap are replaced).

    The rates on the covered lost samples: linear between the raw rates of the last sample before the
    gap and the first after it, each segment shifted by a constant so that it turns by exactly the
    summarised rotation (:func:`_fit_segment`); their error std: the segment's quantisation error over
    its duration."""
    book, ck_gap, ck_state = nodes[0][i], nodes[6][i], nodes[5][i]
    n_gap, spp = book.gap_packets, book.spp
    if n_gap * spp > cfg[CFG_LONGEST_BRIDGE]:
        return
    seg_q = np.zeros((n_gap, 4))
    seg_sigma = np.empty(n_gap)
    if not _gap_segments(i, nodes, b, seg_q, seg_sigma):
        return
    n = n_gap * spp
    after = nodes[10][i, b, 0]
    rates = np.empty((n, 3))
    for k in range(n):
        u = (k + 1.0) / (n + 1.0)
        for a in range(3):
            rates[k, a] = (1.0 - u) * (ck_gap.last_rate[a] + ck_state.bias[a]) + u * after[a]
    p = 0
    while p < n_gap:
        last = p
        while last + 1 < n_gap and seg_sigma[last + 1] >= 0.0 and np.all(seg_q[last + 1] == seg_q[p]):
            last += 1
        if seg_sigma[p] >= 0.0:
            _fit_segment(rates, p * spp, (last + 1) * spp, (seg_q[p, 0], seg_q[p, 1], seg_q[p, 2], seg_q[p, 3]),
                         c.dt)
        p = last + 1
    nodes[1][i] = nodes[5][i]
    nodes[2][i] = nodes[6][i]
    nodes[3][i] = nodes[7][i]
    nothing = np.zeros(9)
    first = book.next_sample - n
    run = 0
    for p in range(n_gap):
        count = 1
        while p - count >= 0 and seg_sigma[p - count] >= 0.0 and np.all(seg_q[p - count] == seg_q[p]):
            count += 1
        last = p
        while last + 1 < n_gap and seg_sigma[last + 1] >= 0.0 and np.all(seg_q[last + 1] == seg_q[p]):
            last += 1
        rate_sigma = seg_sigma[p] / ((last - p + count) * spp * c.dt) if seg_sigma[p] >= 0.0 else -1.0
        for s in range(spp):
            k = p * spp + s
            run += 1
            _step(i, nodes, cfg, c, bc, first + k, PLAIN_FALSE, nothing, (rates[k, 0], rates[k, 1], rates[k, 2]),
                  rate_sigma, run)
            _output(i, nodes, cfg, c, first + k, PLAIN_FALSE, out, dense, lags, scratch, PLAIN_FALSE)
        if seg_sigma[p] >= 0.0:
            _remember_rotation(nodes, i, book.next_seq - n_gap + p, ROT_BRIDGED,
                               PK.integrated_rotation(rates, p * spp, (p + 1) * spp, c.dt))


@njit(**COMPILE)
def release_received(i, nodes, b, cfg, consts, bconsts, out, dense, lags, scratch):
    """The next packet of node ``i`` is in buffer slot ``b``: bridge the gap before it (if it summarises
    it), then filter and output its samples."""
    book = nodes[0][i]
    c = _constants(book, consts)
    bc = bconsts[1] if book.has_mag else bconsts[0]
    if book.gap_packets > 0 and cfg[CFG_BRIDGE] != 0 and nodes[11][i, b] > 0:
        _bridge(i, nodes, b, cfg, c, bc, out, dense, lags, scratch)
    n = nodes[9][i, b]
    values = nodes[10][i, b]
    for s in range(n):
        sample = book.next_sample + s
        _step(i, nodes, cfg, c, bc, sample, PLAIN_TRUE, values[s], (0.0, 0.0, 0.0), -1.0, PLAIN_ZERO)
        _output(i, nodes, cfg, c, sample, PLAIN_TRUE, out, dense, lags, scratch, PLAIN_TRUE)
    _remember_rotation(nodes, i, book.next_seq, ROT_RECEIVED, PK.integrated_rotation(values, PLAIN_ZERO, n, c.dt))
    nodes[8][i, b] = False
    book.counts[N_RECEIVED] += 1
    book.gap_packets = 0
    book.recent = ((book.recent << 1) | 1) & ((1 << RECENT_BITS) - 1)
    book.next_seq += 1
    book.next_sample += book.spp
    if n < book.spp:
        _end_of_stream_packet(i, nodes, cfg, out, dense, lags, scratch)


# ------------------------------------------------------------------------------------------
# A whole recording, packets released in order (the studies' simulation of the receiver)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def run_node(nodes, cfg, consts, bconsts, values, packet_received, summaries, k, layout, sigma, lags, dense, scratch,
             out):
    """Node 0 of ``nodes`` (fresh, ``book.spp`` and ``has_mag`` set) through the packets of a recording:
    ``values`` (T, 9), ``packet_received`` (P,), per packet the summary ``summaries`` (P, K, 3), ``k``
    (P,), ``sigma`` (P,) (``layout`` one code).  The first received packet starts the stream; every lost
    packet after it is declared lost in turn (as the receiver's clock declares them)."""
    book = nodes[0][0]
    spp = book.spp
    n_t = values.shape[0]
    first = 0
    while first < packet_received.shape[0] and not packet_received[first]:
        first += 1
    book.next_seq = first
    book.next_sample = book.first_sample = book.emitted = first * spp
    for p in range(first, packet_received.shape[0]):
        if packet_received[p]:
            n = min(spp, n_t - p * spp)
            nodes[8][0, 0] = True
            nodes[9][0, 0] = n
            for s in range(n):
                for a in range(9):
                    nodes[10][0, 0, s, a] = values[p * spp + s, a]
            nodes[11][0, 0], nodes[12][0, 0], nodes[13][0, 0] = k[p], layout, sigma[p]
            for j in range(k[p]):
                for a in range(3):
                    nodes[14][0, 0, j, a] = summaries[p, j, a]
            release_received(PLAIN_ZERO, nodes, PLAIN_ZERO, cfg, consts, bconsts, out, dense, lags, scratch)
        else:  # (also after the last received packet: the receiver's clock declares those)
            release_lost(PLAIN_ZERO, nodes, cfg, consts, bconsts, out, dense, lags, scratch)
    flush_output(PLAIN_ZERO, nodes, cfg, out, dense, lags, scratch)


# ------------------------------------------------------------------------------------------
# Datagrams from the network
# ------------------------------------------------------------------------------------------

#: Status of :func:`receive`: done; stopped for a new node (grow the node arrays); stopped for room in
#: the output (drain or grow it).
DONE, NEED_NODES, NEED_OUTPUT = 0, 1, 2


@njit(**COMPILE)
def _new_node(slot, nodes, node_id, ints, templates):
    book = nodes[0][slot]
    has_mag = ints[PK.I_HAS_MAG] != 0
    book.id, book.has_mag, book.started, book.spp = node_id, has_mag, False, ints[PK.I_N]
    book.next_seq = book.max_seq = ints[PK.I_SEQ]
    book.next_sample = book.first_sample = book.emitted = book.newest = ints[PK.I_FIRST]
    book.recent, book.gap_packets = 0, 0
    book.clock_s, book.clock_origin = np.nan, np.nan
    for a in range(6):
        book.counts[a] = 0
    m = 1 if has_mag else 0
    nodes[1][slot] = templates[0][m]
    nodes[2][slot] = templates[1][m]
    nodes[3][slot] = templates[2][m]
    nodes[4][slot][:, :] = 0.0
    nodes[8][slot][:] = False
    nodes[16][slot][:] = ROT_UNKNOWN
    nodes[17][slot][:] = -1
    nodes[18][slot]["sample"][:] = -1


@njit(**COMPILE)
def _store(nodes, slot, b, ints, floats, raw, summary):
    """The parsed packet into buffer slot ``b``: readings × scale, the summary's rotation vectors and
    their quantisation std (scale/√12 per component)."""
    n, has_mag, k = ints[PK.I_N], ints[PK.I_HAS_MAG] != 0, ints[PK.I_K]
    values = nodes[10][slot, b]
    for s in range(n):
        for a in range(3):
            values[s, a] = raw[s, a] * floats[PK.F_GYR]
            values[s, 3 + a] = raw[s, 3 + a] * floats[PK.F_ACC]
            values[s, 6 + a] = raw[s, 6 + a] * floats[PK.F_MAG] if has_mag else 0.0
    nodes[8][slot, b] = True
    nodes[9][slot, b] = n
    nodes[11][slot, b], nodes[12][slot, b] = k, ints[PK.I_LAYOUT]
    nodes[13][slot, b] = floats[PK.F_ROT] / math.sqrt(12.0)
    for j in range(k):
        for a in range(3):
            nodes[14][slot, b, j, a] = summary[j, a] * floats[PK.F_ROT]


#: How fast (s per s) a node's clock origin may move later: a sender clock slower than the receiver's.
CLOCK_DRIFT = 1e-3


@njit(**COMPILE)
def _set_clock(book, now, last_sample, fs):
    """A packet whose last sample is ``last_sample`` arrived at ``now``: sample 0 was taken at most
    ``now − (last_sample + 1)/fs``.  The origin is the earliest such bound (a delayed arrival only makes
    it later), allowed to move later by :data:`CLOCK_DRIFT` per second."""
    bound = now - (last_sample + 1) / fs
    if np.isnan(book.clock_origin):
        book.clock_origin = bound
    else:
        book.clock_origin = min(book.clock_origin + CLOCK_DRIFT * max(now - book.clock_s, 0.0), bound)
    book.clock_s = now


@njit(**COMPILE)
def _release_through(slot, nodes, last, cfg, consts, bconsts, out, dense, lags, scratch):
    """Release the packets of node ``slot`` in order up to sequence ``last``: buffered ones as received,
    the others as lost."""
    book, present = nodes[0][slot], nodes[8][slot]
    window = present.shape[0]
    while book.next_seq <= last:
        b = book.next_seq % window
        if present[b]:
            release_received(slot, nodes, b, cfg, consts, bconsts, out, dense, lags, scratch)
        else:
            release_lost(slot, nodes, cfg, consts, bconsts, out, dense, lags, scratch)


@njit(**COMPILE)
def receive(data, lengths, start, lookup, nodes, n_used, cfg, consts, bconsts, templates, fs, rejects, parse_buffers,
            out, scratch, now, silence_s):
    """Datagrams ``data[d, :lengths[d]]`` from ``d = start`` on, in arrival order, then (``now`` not NaN: the
    receiver's clock, s, at their arrival) :func:`expire`; returns ``(d, status)``: where to resume (a
    datagram, or ``D`` + the node slot of the expiry) and :data:`DONE`, :data:`NEED_NODES` or :data:`NEED_OUTPUT`.

    ``lookup`` (65536,): node id → slot (−1: none yet); ``n_used`` (1,): slots in use; ``rejects``
    (6,): datagrams rejected per reason code (1–5, :mod:`._kernels`).  A rejected datagram whose
    bytes 4–5 name a known node also counts as that node's ``corrupt``; so does a valid packet that
    contradicts its node's stream (another rate, magnetometer presence, more samples per packet, a
    first sample that does not follow from its sequence number).
    """
    ints, floats, raw, summary = parse_buffers
    dense = np.zeros((0, 0, 4))
    lags = np.zeros(1, dtype=np.int64)
    window = cfg[CFG_REORDER]
    out_room = out[0].shape[0]
    for d in range(start, data.shape[0]):
        n = lengths[d]
        code = PK.parse(data[d], n, ints, floats, raw, summary)
        if code != PK.OK:
            rejects[code] += 1
            if n >= 6:
                known = lookup[(np.int64(data[d, 4]) << 8) | np.int64(data[d, 5])]
                if known >= 0:
                    nodes[0][known].counts[N_CORRUPT] += 1
            continue
        node_id = ints[PK.I_NODE]
        slot = lookup[node_id]
        if slot < 0:
            if n_used[0] == nodes[0].shape[0]:
                return d, NEED_NODES
            slot = n_used[0]
            n_used[0] += 1
            lookup[node_id] = slot
            _new_node(slot, nodes, node_id, ints, templates)
        book = nodes[0][slot]
        dseq = (ints[PK.I_SEQ] - book.next_seq) & 0xFFFF
        if dseq >= 32768:
            dseq -= 65536
        follows = (ints[PK.I_FIRST] - book.next_sample - dseq * book.spp) & 0xFFFFFFFF == 0
        if (abs(floats[PK.F_FS] - fs) > 1e-6 * fs or (ints[PK.I_HAS_MAG] != 0) != book.has_mag
                or ints[PK.I_N] > book.spp or not follows):
            rejects[PK.BAD_FIELD] += 1
            book.counts[N_CORRUPT] += 1
            continue
        if dseq < 0:
            back = -dseq - 1
            if back < RECENT_BITS and (book.recent >> back) & 1:
                book.counts[N_DUPLICATE] += 1
            else:
                book.counts[N_LATE] += 1
            continue
        if out[4][0] + (max(dseq - window + 1, 0) + window) * book.spp + cfg[CFG_LATENCY] > out_room:
            return d, NEED_OUTPUT
        seq = book.next_seq + dseq
        last_sample = book.next_sample + dseq * book.spp + ints[PK.I_N] - 1
        if dseq >= window:
            _release_through(slot, nodes, seq - window, cfg, consts, bconsts, out, dense, lags, scratch)
        b = seq % window
        if nodes[8][slot, b]:
            book.counts[N_DUPLICATE] += 1
            continue
        _store(nodes, slot, b, ints, floats, raw, summary)
        if seq < book.max_seq:
            book.counts[N_REORDERED] += 1
        else:
            book.max_seq = seq
        if not np.isnan(now):
            _set_clock(book, now, last_sample, fs)
        while nodes[8][slot, book.next_seq % window]:
            release_received(slot, nodes, book.next_seq % window, cfg, consts, bconsts, out, dense, lags, scratch)
    if np.isnan(now):
        return data.shape[0], DONE
    slot, status = expire(max(start - data.shape[0], 0), nodes, n_used, cfg, consts, bconsts, out, scratch, fs, now,
                          silence_s)
    return data.shape[0] + slot, status


@njit(**COMPILE)
def flush(nodes, n_used, cfg, consts, bconsts, out, scratch):
    """End of the stream: every node releases what it holds (missing packets up to the highest sequence
    number seen as lost) and outputs the samples held for the latency."""
    dense = np.zeros((0, 0, 4))
    lags = np.zeros(1, dtype=np.int64)
    for slot in range(n_used[0]):
        book = nodes[0][slot]
        _release_through(slot, nodes, book.max_seq, cfg, consts, bconsts, out, dense, lags, scratch)
        flush_output(slot, nodes, cfg, out, dense, lags, scratch)


@njit(inline="always", **COMPILE)  # one caller: no library of its own to compile
def expire(start, nodes, n_used, cfg, consts, bconsts, out, scratch, fs, now, silence_s):
    """Declare lost every packet whose deadline has passed at the receiver's clock ``now`` (s), from node
    slot ``start`` on; returns ``(slot, status)`` as :func:`receive`.

    A node's sample clock runs at ``fs`` from its origin (:func:`_set_clock`: sample ``t`` is taken at
    ``origin + (t + 1)/fs``, estimated from the earliest arrivals, so late arrivals do not delay it).
    Packet ``q`` (first sample ``f_q``) is due when its last sample is taken; it is declared lost once
    the packet ``reorder`` after it is due too (sample ``f_q + (reorder + 1)·spp − 1``), as
    :func:`receive` declares it when that packet arrives.  A node silent for longer than
    ``silence_s`` is not predicted further (it may have stopped); its next packet resumes it.
    """
    dense = np.zeros((0, 0, 4))
    lags = np.zeros(1, dtype=np.int64)
    window = cfg[CFG_REORDER]
    for slot in range(start, n_used[0]):
        book = nodes[0][slot]
        elapsed = now - book.clock_s
        if not (elapsed >= 0.0) or elapsed > silence_s:  # no clock yet (NaN), or silent too long
            continue
        current = np.int64(math.floor((now - book.clock_origin) * fs + 1e-6)) - 1  # (1e-6: 0.12 s × 50 Hz is 5.99…)
        overdue = (current - (window + 1) * book.spp + 1 - book.next_sample) // book.spp  # packets past next_seq
        if overdue < 0:
            continue
        if out[4][0] + (overdue + 1) * book.spp + cfg[CFG_LATENCY] > out[0].shape[0]:
            return slot, NEED_OUTPUT
        _release_through(slot, nodes, book.next_seq + overdue, cfg, consts, bconsts, out, dense, lags, scratch)
    return n_used[0], DONE
