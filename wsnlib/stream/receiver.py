"""The live receiver: :class:`Receiver` turns datagrams into one orientation per sample and node.

Rules (the compiled code is :mod:`wsnlib.stream._receiver_kernels`):

* **One filter per node**: the gap-aware Kalman filter of :mod:`wsnlib.orientation`, its compiled
  step on the named state of :func:`~wsnlib.orientation.kalman_initial_state` (``state.bias``,
  ``state.P``; :meth:`Receiver.filter_state` returns a node's as a :class:`~wsnlib.orientation.KalmanState`).
  A node's stream starts with the first valid packet the receiver gets from it (an earlier
  packet arriving after it is late); its first sample initialises the filter (TRIAD), as
  ``kalman_orientation(q0=None)``.
* **Order**: packets reach a node's filter in sequence order (16-bit, wrapping).  A packet that
  arrives ahead of the next expected one waits in a reorder window of ``reorder`` packets: the
  receiver waits for a missing packet until a packet ``reorder`` sequence numbers after it has
  arrived, then declares it lost (``reorder=1``: no reordering tolerated).  A packet already
  released is a *duplicate* if it was received, *late* if it had been declared lost (both dropped
  and counted); one that arrives after a later one but in time is *reordered*.
* **Loss**: every missing sequence number is a packet of lost samples (as many as the node's
  packets hold): the filter predicts through them (``gap``, ``replay``), and they are output with
  ``received`` False.  Lost packets at the very end of a stream (no later packet) are unknowable
  and not output.
* **Output** (:class:`ReceiverOutput`): ``(node, sample, quaternion, received)`` for every sample,
  per node in sample order.  With ``latency = 0`` a sample is output when it is filtered; with
  ``latency = L`` samples, once sample ``t + L`` has been filtered, smoothed over that window by
  the fixed-lag RTS smoother of :mod:`wsnlib.orientation.fixed_lag`.  A sample in packet ``p`` is
  filtered when ``p`` arrives, or when ``p + reorder`` arrives (declared lost); so every sample is
  output no later than ``latency`` samples plus the reorder window plus one packet after it was
  sampled, if packets arrive when their last sample is taken — also in a burst of losses, when
  no packet arrives at all, if the receiver's clock is given (``now`` of :meth:`Receiver.receive`,
  and :meth:`Receiver.expire` called now and then): each node's sample clock runs at ``fs`` from
  the earliest its packets' arrivals allow (a late arrival does not delay it), and a packet is
  declared lost when the one ``reorder`` after it is due.
  :meth:`Receiver.flush` ends the stream: what is held is released.  So does a packet with fewer
  samples than the node's packets hold (a sender's last packet): no sample follows it, so the
  samples held for the latency are output when it is released, smoothed up to its last sample.
* **Redundancy** (``bridge``): a packet whose summary (:class:`~wsnlib.stream.packet.Summary`)
  covers lost packets just before it bridges the gap: the filter is re-run from its state at the
  gap's start, turned on each covered lost sample by the measured rotation
  (:func:`wsnlib.orientation.bridging.bridge_step`) instead of a prediction.  What was already
  output stays (the causal output of a lost sample is the prediction); with a latency at least
  as long as the burst, the lost samples are output from the bridged, smoothed estimates.
  Rotations are recovered per layout: *consecutive* entries are the lost packets' own; a
  *doubling* entry ``j`` covers the ``2^j`` packets before, so consecutive entries differ by a
  segment (``S_j ⊗ S_{j−1}⁻¹``), and a segment that starts before the gap gives the gap's part
  when the packets before the gap are known (received, or bridged before).  A segment turns at
  a constant rate whose product over its samples is exactly the summarised rotation; a turn of
  more than 180° is taken in the direction of the rates before and after the gap.  The rate's
  error std is the quantisation's (``rotation_scale / √12`` per component, √2 × for a
  difference of two entries) over the segment's duration.
* **Counters** per node (:attr:`Receiver.counters`): packets received, lost, duplicate,
  reordered, corrupt (a rejected datagram naming the node, or a valid one contradicting its
  stream: another rate, magnetometer, more samples per packet, a first sample that does not
  follow from its sequence number), late; and datagrams rejected per reason
  (:attr:`Receiver.rejected`, :data:`wsnlib.stream.packet.REJECT_REASONS`).

Online equals batch: without redundancy, with ``latency=0``, the output equals
:func:`~wsnlib.orientation.kalman_orientation` on the dequantised samples with the same
``received`` mask, whatever the order of the packets inside the reorder window (tested to 1e-9;
gaps up to :data:`~wsnlib.orientation.gaps.LONGEST_AR_REPLAY_S` s, the live state's rate
history).  With a latency at least the stream's length it equals
:func:`~wsnlib.orientation.smooth_orientation` with ``interpolate_gaps=False``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from wsnlib._validation import check_count, check_positive
from wsnlib.orientation import KalmanState, gaps, kalman_initial_state
from wsnlib.orientation._kalman_kernels import STATE_DTYPE, WORK_DTYPE
from wsnlib.orientation.fixed_lag import RING_DTYPE, new_scratch
from wsnlib.stream import _kernels as PK
from wsnlib.stream import _receiver_kernels as RK
from wsnlib.stream.packet import MAX_PACKET_SIZE, REJECT_REASONS

#: Default reorder window (packets).
DEFAULT_REORDER = 3
#: Default time (s) after which :meth:`Receiver.expire` stops predicting a silent node (a burst of losses
#: this long is rare; a node that stopped is predicted this long).
DEFAULT_SILENCE_S = 10.0
#: Rows of a node's ring of recent packet rotations (a doubling summary of 8 entries spans 128).
ROTATION_RING = 256
COUNTERS = RK.COUNTERS


@dataclasses.dataclass(frozen=True)
class ReceiverOutput:
    """Samples output by a :class:`Receiver`: ``node`` (E,), ``sample`` (E,) index in the node's stream,
    ``quat`` (E, 4) ENU (body → earth) estimate, ``received`` (E,) whether the sample arrived.
    Per node, samples come in increasing order."""

    node: np.ndarray
    sample: np.ndarray
    quat: np.ndarray
    received: np.ndarray

    def __len__(self) -> int:
        return int(self.sample.shape[0])

    def to_frame(self) -> pd.DataFrame:
        """Columns ``node, sample, received, w, x, y, z`` (the command line's CSV)."""
        return pd.DataFrame({"node": self.node, "sample": self.sample, "received": self.received.astype(np.int8),
                             "w": self.quat[:, 0], "x": self.quat[:, 1], "y": self.quat[:, 2], "z": self.quat[:, 3]})

    @staticmethod
    def concatenate(parts) -> ReceiverOutput:
        parts = list(parts)
        if not parts:
            return _empty_output()
        return ReceiverOutput(*(np.concatenate([getattr(p, f.name) for p in parts])
                                for f in dataclasses.fields(ReceiverOutput)))


def _empty_output() -> ReceiverOutput:
    return ReceiverOutput(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0, bool))


def allocate_nodes(capacity: int, window: int, history_rows: int, ring_rows: int) -> tuple:
    """The per-node arrays of :mod:`._receiver_kernels` for ``capacity`` nodes, in its index order."""
    shapes = [((capacity,), RK.NODE_DTYPE), ((capacity,), STATE_DTYPE), ((capacity,), gaps.GAP_DTYPE),
              ((capacity,), WORK_DTYPE), ((capacity, history_rows, 3), float), ((capacity,), STATE_DTYPE),
              ((capacity,), gaps.GAP_DTYPE), ((capacity,), WORK_DTYPE), ((capacity, window), bool),
              ((capacity, window), np.int64), ((capacity, window, PK.MAX_SAMPLES, 9), float),
              ((capacity, window), np.int64), ((capacity, window), np.int64), ((capacity, window), float),
              ((capacity, window, PK.MAX_REDUNDANCY, 3), float), ((capacity, ROTATION_RING, 4), float),
              ((capacity, ROTATION_RING), np.int64), ((capacity, ROTATION_RING), np.int64),
              ((capacity, ring_rows), RING_DTYPE)]
    arrays = tuple(np.empty(shape, dtype) for shape, dtype in shapes)
    for arr in arrays:  # zeros, written now: every page is there before packets wait for it
        arr.view(np.uint8)[...] = 0
    arrays[17][...] = -1  # no packet's rotation yet
    arrays[18]["sample"] = -1  # an empty ring
    return arrays


class FilterSetup:
    """What every node's filter shares: constants (without and with magnetometer), the initial records,
    the configuration array and scratch (:mod:`._receiver_kernels`)."""

    def __init__(self, fs, settings, *, latency, reorder, bridge, gap, replay, gap_time_constant, dense_lags=None):
        self.fs = check_positive(fs, "fs")
        self.latency = check_count(latency, "latency", 0)
        self.reorder = check_count(reorder, "reorder", 1)
        if not isinstance(bridge, bool):
            raise ValueError(f"bridge must be True or False, got {bridge!r}")
        starts = [kalman_initial_state(fs=self.fs, settings=settings, has_mag=m, gap=gap, replay=replay,
                                       gap_time_constant=gap_time_constant) for m in (False, True)]
        depth = self.latency if dense_lags is None else int(np.max(dense_lags))
        use_ring = depth > 0 or dense_lags is not None
        self.consts = np.concatenate([s.constants for s in starts])
        self.consts["record"] = use_ring
        self.bridge_consts = self.consts.copy()
        self.templates = (np.concatenate([s.record for s in starts]), np.concatenate([s.gap for s in starts]),
                          np.concatenate([s.work for s in starts]))
        self.history_rows = starts[0].history.shape[0]
        window = int(self.consts["ar_window"][0])
        self.ring_rows = depth + 1 if use_ring else 1
        self.cfg = np.zeros(5, np.int64)
        self.cfg[RK.CFG_REORDER], self.cfg[RK.CFG_LATENCY], self.cfg[RK.CFG_BRIDGE] = self.reorder, self.latency, bridge
        self.cfg[RK.CFG_RING] = use_ring
        self.cfg[RK.CFG_LONGEST_BRIDGE] = self.history_rows - window - 2
        self.scratch = (new_scratch(), np.zeros((self.ring_rows, 4)))

    def allocate(self, capacity: int) -> tuple:
        return allocate_nodes(capacity, self.reorder, self.history_rows, self.ring_rows)

    def state(self, nodes: tuple, slot: int) -> KalmanState:
        book = nodes[0][slot]
        m = 1 if book["has_mag"] else 0
        consts = self.consts[m:m + 1].copy()
        return KalmanState(consts, nodes[1][slot:slot + 1].copy(), nodes[2][slot:slot + 1].copy(),
                           nodes[4][slot].copy(), nodes[3][slot:slot + 1].copy(), started=bool(book["started"]))


class Receiver:
    """One Kalman filter per node, packets in sequence order, an orientation per sample (module docstring).

    Parameters
    ----------
    fs : float
        Sampling rate (Hz) of every node; a packet that states another is counted corrupt.
    settings : KalmanSettings, optional
        The filter's settings (default ``KalmanSettings()``).
    latency : int
        Samples a sample's output waits for later samples (fixed-lag smoothing); 0: the causal filter.
    reorder : int
        Reorder window (packets, ≥ 1): a missing packet is declared lost once the packet ``reorder``
        sequence numbers after it has arrived.
    bridge : bool
        Use the redundancy blocks of packets to bridge bursts of lost packets (default True).
    gap, replay, gap_time_constant
        The filter's gap options (:func:`~wsnlib.orientation.kalman_orientation`).
    silence_s : float
        :meth:`expire` stops predicting a node silent for longer than this (s).
    capacity : int
        Nodes to allocate for up front (more are added by doubling, which takes time when thousands are).
    """

    def __init__(self, fs, settings=None, *, latency: int = 0, reorder: int = DEFAULT_REORDER, bridge: bool = True,
                 gap: str = "ar", replay: bool = True, gap_time_constant=None, silence_s: float = DEFAULT_SILENCE_S,
                 capacity: int = 16):
        self.silence_s = check_positive(silence_s, "silence_s")
        self._setup = FilterSetup(fs, settings, latency=latency, reorder=reorder, bridge=bridge, gap=gap,
                                  replay=replay, gap_time_constant=gap_time_constant)
        self._nodes = self._setup.allocate(check_count(capacity, "capacity"))
        self._lookup = np.full(65536, -1, dtype=np.int64)
        self._n_used = np.zeros(1, np.int64)
        self._rejects = np.zeros(len(REJECT_REASONS) + 1, np.int64)
        self._parse = (np.zeros(PK.N_INTS, np.int64), np.zeros(PK.N_FLOATS), np.zeros((PK.MAX_SAMPLES, 9), np.int64),
                       np.zeros((PK.MAX_REDUNDANCY, 6), np.int64))
        self._out = self._new_output(4096)
        self._no_data, self._no_lengths = np.zeros((0, 1), np.uint8), np.zeros(0, np.int64)

    fs = property(lambda self: self._setup.fs)
    latency = property(lambda self: self._setup.latency)
    reorder = property(lambda self: self._setup.reorder)

    @staticmethod
    def _new_output(rows: int) -> tuple:
        return (np.zeros(rows, np.int64), np.zeros(rows, np.int64), np.zeros((rows, 4)), np.zeros(rows, bool),
                np.zeros(1, np.int64))

    def _drain(self) -> ReceiverOutput:
        node, sample, quat, received, count = self._out
        n = int(count[0])
        part = ReceiverOutput(node[:n].copy(), sample[:n].copy(), quat[:n].copy(), received[:n].copy())
        count[0] = 0
        return part

    def _grow_nodes(self) -> None:
        old = self._nodes
        capacity = 2 * old[0].shape[0]
        new = self._setup.allocate(capacity)
        used = int(self._n_used[0])
        for a, b in zip(old, new, strict=True):
            b[:used] = a[:used]
        self._nodes = new

    def receive_array(self, data: np.ndarray, lengths: np.ndarray, now: float | None = None) -> ReceiverOutput:
        """Datagrams as rows of ``data`` (D, ≥ longest; uint8), ``lengths`` (D,) bytes each, in arrival order.

        ``now``: the receiver's clock (s, e.g. ``time.monotonic()``) at their arrival; given, it also
        declares overdue packets lost (:meth:`expire`).  Returns the samples now output."""
        data = np.ascontiguousarray(data, dtype=np.uint8)
        lengths = np.ascontiguousarray(lengths, dtype=np.int64)
        bad_lengths = lengths.size and (lengths.min() < 0 or lengths.max() > data.shape[1])
        if data.ndim != 2 or lengths.shape != (data.shape[0],) or bad_lengths:
            raise ValueError(f"data must be (D, width) bytes and lengths (D,) within the width, got {data.shape} "
                             f"and {lengths.shape}")
        clock = np.nan if now is None else float(now)
        setup = self._setup
        parts, start = [], 0
        while True:
            start, status = RK.receive(data, lengths, start, self._lookup, self._nodes, self._n_used, setup.cfg,
                                       setup.consts, setup.bridge_consts, setup.templates, setup.fs, self._rejects,
                                       self._parse, self._out, setup.scratch, clock, self.silence_s)
            if status == RK.DONE:
                break
            if status == RK.NEED_NODES:
                self._grow_nodes()
            elif int(self._out[4][0]) == 0:  # one packet needs more room than there is
                self._out = self._new_output(2 * self._out[0].shape[0])
            else:
                parts.append(self._drain())
        if not parts:
            return self._drain()
        return ReceiverOutput.concatenate(parts + [self._drain()])

    def expire(self, now: float) -> ReceiverOutput:
        """Declare lost every packet overdue at the clock ``now`` (s, the clock of :meth:`receive`): packet
        ``q`` once the packet ``reorder`` after it is due (each node's sample clock runs from its packets'
        earliest arrivals); so every sample is output within its deadline even in a burst of losses.  A node
        silent for longer than ``silence_s`` is not predicted further.  Returns the samples output."""
        return self.receive_array(self._no_data, self._no_lengths, float(now))

    def receive(self, datagrams, now: float | None = None) -> ReceiverOutput:
        """Datagrams (an iterable of bytes-like), in arrival order (``now``: as :meth:`receive_array`);
        returns the samples now output."""
        datagrams = [bytes(d) for d in datagrams]
        width = max([len(d) for d in datagrams] + [MAX_PACKET_SIZE])
        data = np.zeros((len(datagrams), width), np.uint8)
        lengths = np.zeros(len(datagrams), np.int64)
        for i, d in enumerate(datagrams):
            data[i, :len(d)] = np.frombuffer(d, np.uint8)
            lengths[i] = len(d)
        return self.receive_array(data, lengths, now)

    def flush(self) -> ReceiverOutput:
        """End of the stream: release what is held (missing packets before the last one seen as lost)
        and output every sample still waiting for the latency."""
        book = self._nodes[0][: int(self._n_used[0])]
        need = int(np.sum((book["max_seq"] - book["next_seq"] + 1).clip(0) * book["spp"])) + book.size * (
            self.latency + 1)
        if need > self._out[0].shape[0]:
            self._out = self._new_output(need)
        RK.flush(self._nodes, self._n_used, self._setup.cfg, self._setup.consts, self._setup.bridge_consts, self._out,
                 self._setup.scratch)
        return self._drain()

    @property
    def nodes(self) -> list[int]:
        """Node ids seen, in order of first arrival."""
        return [int(x) for x in self._nodes[0]["id"][: int(self._n_used[0])]]

    @property
    def counters(self) -> pd.DataFrame:
        """Per node (index ``node``), packets received, lost, duplicate, reordered, corrupt, late."""
        book = self._nodes[0][: int(self._n_used[0])]
        return pd.DataFrame(book["counts"].copy(), index=pd.Index(book["id"].copy(), name="node"),
                            columns=list(COUNTERS))

    @property
    def rejected(self) -> dict[str, int]:
        """Datagrams rejected, per reason (:data:`~wsnlib.stream.packet.REJECT_REASONS`)."""
        return {reason: int(self._rejects[code]) for code, reason in enumerate(REJECT_REASONS, start=1)}

    def filter_state(self, node: int) -> KalmanState:
        """A copy of node ``node``'s filter after its last filtered sample."""
        slot = int(self._lookup[int(node)]) if 0 <= int(node) < 65536 else -1
        if slot < 0:
            raise ValueError(f"no packet from node {node} yet; nodes: {self.nodes}")
        return self._setup.state(self._nodes, slot)
