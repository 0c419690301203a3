"""A real-time receiver for packet-lossy body sensor networks (issue 27).

Paper 001's setting is a live network: nodes send packets of 6 samples over a lossy radio, and a
receiver must show the orientation *now*.  This package is that receiver, built on the gap-aware
Kalman filter of :mod:`wsnlib.orientation` (its compiled step on a named state):

* :mod:`.packet` — the versioned binary packet (a table in its docstring and in
  ``data/raw/README.md``): :func:`encode_packet`, :func:`decode_packet`, CRC-16/CCITT-FALSE, the
  optional redundancy block (:class:`Summary`);
* :mod:`.sender` — a recording as the packets a node sends (:func:`node_stream`,
  :func:`encode_stream`);
* :mod:`.receiver` — :class:`Receiver`: one filter per node, reorder window, duplicates, loss,
  fixed-lag smoothing (``latency``), bridging bursts with the packets' summaries, counters;
* :mod:`.simulation` — the receiver's output on a whole recording at several latencies at once
  (:func:`receiver_output`), and the send-twice baseline's loss (:func:`packets_sent_twice`);
* :mod:`.udp` and ``python -m wsnlib.stream send / receive`` — packets over UDP.

The compiled code (:mod:`._kernels`, :mod:`._receiver_kernels`) is cached by numba below the
cache folder of :mod:`wsnlib.orientation`'s sources, in a sub-folder named by this package's
compiled sources, so an edit of either is never run from stale machine code.

This package's door gathers the public names: ``from wsnlib.stream import Receiver``.
"""

from pathlib import Path

from wsnlib._files import sources_digest
from wsnlib.orientation import _numba_cache

#: SHA-256 of this package's compiled sources (``_*kernels.py``) when it was imported.
SOURCES_DIGEST = sources_digest(Path(__file__).parent, "_*kernels.py")

with _numba_cache.caching_into_this_version(f"stream-{SOURCES_DIGEST[:16]}"):
    from wsnlib.stream import _kernels, _receiver_kernels  # noqa: F401
    from wsnlib.stream.packet import (
        LAYOUTS,
        MAX_REDUNDANCY,
        MAX_SAMPLES_PER_PACKET,
        PACKET_VERSION,
        REDUNDANCY_BITS,
        REJECT_REASONS,
        Packet,
        PacketError,
        Summary,
        crc16_ccitt_false,
        decode_packet,
        encode_packet,
    )
    from wsnlib.stream.receiver import COUNTERS, DEFAULT_REORDER, Receiver, ReceiverOutput
    from wsnlib.stream.sender import NodeStream, encode_stream, node_stream
    from wsnlib.stream.simulation import packets_sent_twice, receiver_output

__all__ = ["COUNTERS", "DEFAULT_REORDER", "LAYOUTS", "MAX_REDUNDANCY", "MAX_SAMPLES_PER_PACKET", "PACKET_VERSION",
           "REDUNDANCY_BITS", "REJECT_REASONS", "NodeStream", "Packet", "PacketError", "Receiver",
           "ReceiverOutput", "Summary", "crc16_ccitt_false", "decode_packet", "encode_packet", "encode_stream",
           "node_stream", "packets_sent_twice", "receiver_output"]
