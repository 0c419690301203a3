"""The receiver's output on a whole recording, at several latencies at once: :func:`receiver_output`.

What a study needs: the orientation :class:`~wsnlib.stream.Receiver` would output for one node's
recording (:class:`~wsnlib.stream.NodeStream`) under a given packet loss, for every latency of a
list — without sockets and without encoding bytes.  The packets go through the receiver's own
compiled code (:func:`wsnlib.stream._receiver_kernels.run_node`), released in sequence order as
the receiver releases them (reordering inside the window changes nothing, the tests show); the
fixed-lag smoother's backward pass runs once per sample to the longest latency and keeps the
estimate at each latency asked for.  Every lost packet is declared lost as the receiver's clock
declares it (:meth:`~wsnlib.stream.Receiver.expire`), also those after the last received packet.
The samples before the first received packet, which no receiver outputs (its stream has not
started), get the first output (the filter's initial estimate, as
:func:`~wsnlib.orientation.kalman_orientation` with ``q0=None``).
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import check_count
from wsnlib.stream import _receiver_kernels as RK
from wsnlib.stream.packet import LAYOUTS
from wsnlib.stream.receiver import FilterSetup
from wsnlib.stream.sender import NodeStream


def receiver_output(stream: NodeStream, packet_received, *, latencies=(0,), settings=None, bridge: bool = True,
                    gap: str = "ar", replay: bool = True, gap_time_constant=None) -> np.ndarray:
    """ENU quaternions ``(len(latencies), T, 4)`` the receiver outputs for ``stream`` when the packets
    ``packet_received`` (P,) bool arrive, at each latency (samples, ≥ 0) of ``latencies``.

    ``bridge``, ``settings`` and the gap options as :class:`~wsnlib.stream.Receiver`.  ``ValueError``
    if no packet is received or the mask does not have one entry per packet.
    """
    if not isinstance(stream, NodeStream):
        raise ValueError(f"stream must be a NodeStream (wsnlib.stream.node_stream), got {type(stream).__name__}")
    received = np.asarray(packet_received)
    if received.dtype != bool or received.shape != (stream.n_packets,):
        raise ValueError(f"packet_received must be a boolean array of {stream.n_packets} packets, got "
                         f"{received.dtype} {received.shape}")
    if not received.any():
        raise ValueError("no packet is received: the receiver outputs nothing")
    lags = np.array(sorted({check_count(int(x), "latency", 0) for x in latencies}), dtype=np.int64)
    setup = FilterSetup(stream.fs, settings, latency=int(lags[-1]), reorder=1, bridge=bridge, gap=gap,
                        replay=replay, gap_time_constant=gap_time_constant, dense_lags=lags)
    nodes = setup.allocate(1)
    book = nodes[0][0]
    m = 1 if stream.has_mag else 0
    book["spp"], book["has_mag"] = stream.samples_per_packet, stream.has_mag
    nodes[1][0], nodes[2][0], nodes[3][0] = setup.templates[0][m], setup.templates[1][m], setup.templates[2][m]
    k = stream.summary_k if bridge else np.zeros(stream.n_packets, np.int64)
    summaries = stream.summaries if stream.summary_raw.shape[1] else np.zeros((stream.n_packets, 1, 3))
    dense = np.full((lags.size, stream.n_samples, 4), np.nan)
    out = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0, bool), np.zeros(1, np.int64))
    RK.run_node(nodes, setup.cfg, setup.consts, setup.bridge_consts, np.ascontiguousarray(stream.values), received,
                np.ascontiguousarray(summaries), np.ascontiguousarray(k), LAYOUTS.index(stream.layout),
                stream.summary_sigma, lags, dense, setup.scratch, out)
    first = int(np.argmax(received)) * stream.samples_per_packet
    dense[:, :first] = dense[:, first: first + 1]
    order = {int(lag): i for i, lag in enumerate(lags)}
    return dense[[order[int(x)] for x in latencies]]


def packets_sent_twice(slot_good) -> np.ndarray:
    """Packets received when each is sent twice, the copy one slot later on the same channel: packet
    ``p`` arrives if slot ``p`` or slot ``p + 1`` is good (``slot_good`` (..., P + 1) bool, e.g. a
    Gilbert–Elliott chain over P + 1 slots); returns (..., P)."""
    good = np.asarray(slot_good, dtype=bool)
    return good[..., :-1] | good[..., 1:]

