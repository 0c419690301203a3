"""A real-time receiver for packet-lossy body sensor networks (issue 27).

Paper 001's setting is a live network: nodes send packets of 6 samples over a lossy radio, and a
receiver must show the orientation *now*.  This package is that receiver, built on the gap-aware
Kalman filter of :mod:`wsnlib.orientation` (its compiled step on a named state):

* :mod:`.packet` — the versioned binary packet (a table in its docstring and in
  ``data/raw/README.md``): :func:`encode_packet`, :func:`decode_packet`, CRC-16/CCITT-FALSE, the
  optional redundancy block (:class:`Summary`);

This package's door gathers the public names: ``from wsnlib.stream import decode_packet``.
"""

from wsnlib.orientation import _numba_cache

with _numba_cache.caching_into_this_version():  # see wsnlib/stream/_kernels.py
    from wsnlib.stream import _kernels  # noqa: F401
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

__all__ = ["LAYOUTS", "MAX_REDUNDANCY", "MAX_SAMPLES_PER_PACKET", "PACKET_VERSION", "REDUNDANCY_BITS",
           "REJECT_REASONS", "Packet", "PacketError", "Summary", "crc16_ccitt_false", "decode_packet", "encode_packet"]
