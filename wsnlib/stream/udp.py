"""Packets over UDP: sending a node's packets on their schedule, and a receiving loop.

:func:`send_datagrams` sends each datagram at its time (the time its last sample is taken, at
``speed`` times real time, or as fast as possible); :func:`serve` receives datagrams in batches
(all that are waiting, up to :data:`BATCH`), feeds them to a :class:`~wsnlib.stream.Receiver`
with the receiver's clock, declares overdue packets lost (:meth:`~wsnlib.stream.Receiver.expire`)
and hands every output to a sink.  The command line (``python -m wsnlib.stream``) and the
benchmark (``benchmarks/bench_stream.py``) run these.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import numpy as np

from wsnlib.stream.packet import MAX_PACKET_SIZE, PacketError, decode_packet

#: Datagrams read per batch at most.
BATCH = 4096
#: Receive buffer asked of the kernel (bytes): datagrams that come while the receiver is not scheduled wait
#: here (a kernel datagram takes ~1–2 kB: 64 MB hold a few seconds of 2,000 nodes).
RECEIVE_BUFFER = 1 << 26
#: The sender sleeps only when it is this far (s) ahead of its schedule.
SLEEP_MIN_S = 0.001
#: How long one wait for datagrams lasts (s): the loop checks its clock, the idle exit and expiry this often.
POLL_S = 0.005
#: One pass of the receiving loop lasts at least this (s): datagrams are handled in batches, at most this late.
MIN_PERIOD_S = 0.005


def receiving_socket(port: int, host: str = "127.0.0.1") -> socket.socket:
    """A UDP socket bound to ``host:port`` (port 0: the kernel picks a free one; ``getsockname()`` tells)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:  # beyond the system's limit (net.core.rmem_max) where allowed (root)
        sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_RCVBUFFORCE", 33), RECEIVE_BUFFER)
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
    sock.bind((host, int(port)))
    return sock


def send_datagrams(datagrams, times_s, port: int, *, speed: float | None = 1.0, host: str = "127.0.0.1",
                   clock: Callable[[], float] = time.monotonic,
                   should_stop: Callable[[], bool] = lambda: False) -> float:
    """Send ``datagrams`` (bytes) to ``host:port``, datagram ``i`` at ``times_s[i] / speed`` seconds after
    the start (``times_s`` non-decreasing; ``speed`` None: at once, as fast as possible), until
    ``should_stop()`` (asked before each datagram) says so; returns the seconds it took."""
    times = np.asarray(times_s, dtype=float)
    if times.shape != (len(datagrams),) or np.any(np.diff(times) < 0):
        raise ValueError("times_s must be one non-decreasing time per datagram")
    if speed is not None and not speed > 0:
        raise ValueError(f"speed must be > 0 or None, got {speed!r}")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        target = (host, int(port))
        start = clock()
        for datagram, t in zip(datagrams, times, strict=True):
            if should_stop():
                break
            if speed is not None:
                wait = start + t / speed - clock()
                if wait > SLEEP_MIN_S:  # shorter sleeps cost more than they wait: send a little early
                    time.sleep(wait)
            sock.sendto(datagram, target)
        return clock() - start


class Batches:
    """Reads every waiting datagram into one array (rows of :data:`~wsnlib.stream.packet.MAX_PACKET_SIZE`
    + 1 bytes: a longer datagram is cut, and rejected as such)."""

    def __init__(self, size: int = BATCH):
        self.data = np.zeros((size, MAX_PACKET_SIZE + 1), np.uint8)
        self.lengths = np.zeros(size, np.int64)
        self._views = [memoryview(row) for row in self.data]

    def read(self, sock: socket.socket, timeout_s: float) -> int:
        """Wait up to ``timeout_s`` for a datagram, then take all that are waiting; returns how many."""
        sock.settimeout(timeout_s)
        try:
            self.lengths[0] = sock.recv_into(self._views[0])
        except (TimeoutError, BlockingIOError):
            return 0
        sock.setblocking(False)
        n = 1
        try:
            while n < len(self._views):
                self.lengths[n] = sock.recv_into(self._views[n])
                n += 1
        except BlockingIOError:
            pass
        return n


def first_rate(data: np.ndarray, lengths: np.ndarray) -> float | None:
    """The sampling rate of the first valid packet among the rows, or None."""
    for row, n in zip(data, lengths, strict=True):
        try:
            return decode_packet(row[:n].tobytes()).fs
        except PacketError:
            continue
    return None


def serve(sock: socket.socket, make_receiver: Callable[[float], object], sink: Callable, *,
          idle_exit_s: float | None = None, should_stop: Callable[[], bool] = lambda: False,
          clock: Callable[[], float] | None = time.monotonic, batches: Batches | None = None):
    """Receive on ``sock`` until no datagram has come for ``idle_exit_s`` seconds after the first one (None:
    never) or ``should_stop()`` (asked every :data:`POLL_S`) says so.

    The receiver is made by ``make_receiver(fs)`` from the first valid packet's rate; every output
    (:class:`~wsnlib.stream.ReceiverOutput`) goes to ``sink``.  ``clock`` (s) is the receiver's clock at
    each arrival, by which it declares overdue packets lost; ``None``: no clock, packets are declared lost
    by sequence only — for a recording replayed faster than real time, whose arrival times say nothing
    about when its samples were taken (the loop's own waits use ``time.monotonic``).  Returns
    ``(receiver or None, datagrams rejected before the receiver existed, "idle" or "stopped")``; the
    caller flushes the receiver.
    """
    batches = batches or Batches()
    receiver, early_rejects, last = None, 0, None
    while True:
        began = time.monotonic()
        n = batches.read(sock, POLL_S)
        now = time.monotonic()
        arrival = None if clock is None else clock()
        if n:
            last = now
            data, lengths = batches.data[:n], batches.lengths[:n]
            if receiver is None:
                fs = first_rate(data, lengths)
                if fs is None:
                    early_rejects += n
                    continue
                receiver = make_receiver(fs)
            sink(receiver.receive_array(data, lengths, arrival))  # (with the clock: overdue packets expire too)
        elif receiver is not None and arrival is not None:
            sink(receiver.expire(arrival))
        if should_stop():
            return receiver, early_rejects, "stopped"
        if idle_exit_s is not None and last is not None and now - last >= idle_exit_s:
            return receiver, early_rejects, "idle"
        rest = began + MIN_PERIOD_S - time.monotonic()
        if rest > 0:  # gather datagrams for a while: one call per batch costs less than one per datagram
            time.sleep(rest)
