"""How many nodes one core of the live receiver sustains in real time (issue 27).

Run from the repository root (BROAD trials in ``$WSNLIB_BROAD_DIR``; ``make`` sets it)::

    .venv/bin/python benchmarks/bench_stream.py            # 2,000 nodes for 10 s over UDP, ~1 min
    .venv/bin/python benchmarks/bench_stream.py --quick    # 200 nodes for 3 s
    .venv/bin/python benchmarks/bench_stream.py --nodes 4000 --seconds 20

Data: one BROAD trial (``02_undisturbed_slow_rotation_B``) at 50 Hz, each node a different
stretch of it (16 offsets), 6 samples per packet with magnetometer (140 bytes), Gilbert–Elliott
10 % loss (mean burst 3 packets, one seeded chain per node): the lost packets are never sent.

1. **Real time over UDP loopback** (the target): a sender process on one core sends every node's
   packets when their last sample is taken (nodes staggered over the packet period); this
   process, pinned to the other core, runs the receiver as the command line does
   (:func:`wsnlib.stream.udp.serve`'s loop: read every waiting datagram, decode, filter, declare
   overdue packets lost with the receiver's clock, output to memory), at latency 0 without
   redundancy.  Measured: the receiver's CPU time over the wall time (utilisation; below 1: it
   keeps up on one core), datagrams sent and read, samples output, and every sample's delay
   against its deadline (the latency plus the reorder window plus one packet, ``(reorder + 1) × 6``
   samples at latency 0, after it was taken — by the sender's clock as it actually ran: a sender
   slowed by other load shifts the samples' times, and its lag is reported).
   Nodes per core = nodes / utilisation.
2. **In process, no network** (decode + filter + output per sample, the same datagrams fed as the
   loop gets them, in 5 ms batches of their schedule with the clock at each batch's end): µs per
   sample, nodes per core at 50 Hz, and deadline misses with the receiver's own timing (what the
   algorithm guarantees when nothing else takes its core), for the headline setting and the
   others — latency 25 samples (0.5 s), redundancy K = 4 (doubling, 12 bits) with and without it.

Prints PASS/MISS for the target, ≥ 2,000 nodes per core in real time (≥ 100,000 samples/s end to
end), every sample within its deadline, in two lines: the receiver's capability (CPU per sample in
the real-time run, nothing dropped or missing, deadlines met with its own timing), and the
deadlines of the real-time run on this machine, which other load on a shared machine can break
(the load average is printed).  Always exits 0: a measurement, not a test.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import platform
import sys
import time

import numpy as np

TRIAL = "02_undisturbed_slow_rotation_B"
FS = 50.0
SPP = 6
TARGET_NODES = 2000
OFFSETS = 16


def load_signals(n_samples: int, signals=None):
    """The trial at 50 Hz (or ``signals``, gyr, acc, mag at 50 Hz), repeated (forward, then time-mirrored)
    to ``n_samples``."""
    if signals is None:
        from wsnlib.io.broad import load_broad
        from wsnlib.io.resample import resample_broad

        rec = resample_broad(load_broad(TRIAL), FS)
        signals = (rec.gyr, rec.acc, rec.mag)
    fwd = [np.asarray(x, dtype=float) for x in signals]
    bwd = [-fwd[0][::-1], fwd[1][::-1], fwd[2][::-1]]
    parts, n = [], 0
    while n < n_samples:
        parts.append(fwd if len(parts) % 2 == 0 else bwd)
        n += fwd[0].shape[0]
    return [np.concatenate([p[i] for p in parts])[:n_samples] for i in range(3)]


def packets(n_nodes: int, seconds: float, *, redundancy: int = 0, seed: int = 27, signals=None):
    """Every node's sent datagrams in sending order: ``(data (D, width), lengths (D,), times_s (D,), samples
    per node, lost share)``; node n's packet p is sent at ``(p + 1) S / fs + n/N · S/fs``."""
    from wsnlib.loss import gilbert_elliott
    from wsnlib.stream import encode_stream, node_stream

    n_samples = int(round(seconds * FS))
    stride = 400
    gyr, acc, mag = load_signals(n_samples + stride * OFFSETS, signals)
    streams = [node_stream(gyr[o:o + n_samples], acc[o:o + n_samples], mag[o:o + n_samples], fs=FS,
                           redundancy=redundancy, bits=12, layout="doubling")
               for o in range(0, stride * OFFSETS, stride)]
    rngs = np.random.default_rng(seed).spawn(n_nodes)
    datagrams, times, lost = [], [], 0
    for n in range(n_nodes):
        stream = streams[n % OFFSETS]
        sent = gilbert_elliott(stream.n_packets, 0.10, 3.0, rng=rngs[n])
        sent[0] = True
        index = np.flatnonzero(sent)
        lost += stream.n_packets - index.size
        datagrams += encode_stream(stream, node=n, packets=index)
        times.append((index + 1) * SPP / FS + n / n_nodes * SPP / FS)
    times = np.concatenate(times)
    order = np.argsort(times, kind="stable")
    width = max(len(d) for d in datagrams)
    data = np.zeros((len(datagrams), width), np.uint8)
    lengths = np.zeros(len(datagrams), np.int64)
    for row, i in enumerate(order):
        data[row, : len(datagrams[i])] = np.frombuffer(datagrams[i], np.uint8)
        lengths[row] = len(datagrams[i])
    return data, lengths, times[order], n_samples, lost / (lost + len(datagrams))


def in_process(data, lengths, times, n_samples: int, *, latency: int, batch_s: float = 0.005) -> dict:
    """Decode + filter + output of the datagrams fed as the receiving loop gets them (``batch_s`` batches of
    their schedule, the clock given at each batch's end, overdue packets expired): CPU µs per sample
    output, and every sample's delay against its deadline with this timing (no other load interferes)."""
    from wsnlib.stream import Receiver

    warm = Receiver(FS, latency=latency)
    warm.receive_array(data[:50], lengths[:50], 0.0)
    n_nodes = int(np.max(data[:, 4].astype(int) * 256 + data[:, 5])) + 1
    receiver = Receiver(FS, latency=latency, capacity=n_nodes)
    stagger = np.arange(n_nodes) / n_nodes * SPP / FS
    deadline = ((receiver.reorder + 1) * SPP + latency) / FS
    clock = np.arange(0.0, times[-1] + 2 * deadline, batch_s)
    edges = np.searchsorted(times, clock, side="right")
    cpu, outputs, late, worst, lo = 0.0, 0, 0, -np.inf, 0
    for now, hi in zip(clock, edges, strict=True):
        began = time.process_time()
        out = receiver.receive_array(data[lo:hi], lengths[lo:hi], float(now))
        cpu += time.process_time() - began
        lo = hi
        exists = out.sample < n_samples
        if np.any(exists):
            delay = now - (stagger[out.node[exists]] + (out.sample[exists] + 1) / FS)
            outputs += int(exists.sum())
            late += int(np.sum(delay > deadline + 1e-9))
            worst = max(worst, float(delay.max()))
    return {"us_per_sample": 1e6 * cpu / outputs, "samples": outputs, "nodes_per_core": outputs / cpu / FS,
            "late": late, "worst_delay_s": worst, "deadline_s": deadline}


def _sender(port, data, lengths, times, start, done):
    """The sender process: every datagram at ``start + times[i]`` (shared monotonic clock), all those due
    in one tight loop; puts the actual sending times on ``done``."""
    import socket

    rows = [row[:n].tobytes() for row, n in zip(data, lengths, strict=True)]
    sent_at = np.empty(len(rows))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        target, i = ("127.0.0.1", port), 0
        while i < len(rows):
            now = time.monotonic()
            due = np.searchsorted(times, now - start, side="right")
            if due <= i:
                time.sleep(max(0.0, min(0.002, start + times[i] - now)))
                continue
            for j in range(i, due):
                sock.sendto(rows[j], target)
            sent_at[i:due] = time.monotonic() - start
            i = due
    done.put(sent_at)


def _udp_receive_errors() -> int:
    """The kernel's count of UDP datagrams dropped for a full receive buffer (all sockets), or -1."""
    try:
        lines = [line.split() for line in open("/proc/net/snmp") if line.startswith("Udp:")]
        return int(lines[1][lines[0].index("RcvbufErrors")])
    except (OSError, ValueError, IndexError):
        return -1


def realtime(data, lengths, times, n_nodes: int, n_samples: int, *, latency: int = 0) -> dict:
    """The receiver (this process, pinned to one core) against a sender process sending in real time."""
    from wsnlib.stream import Receiver
    from wsnlib.stream.udp import MIN_PERIOD_S, POLL_S, Batches, receiving_socket

    warm = Receiver(FS, latency=latency)  # load the compiled code before the clock runs
    warm.receive_array(data[:50], lengths[:50], 0.0)
    warm.expire(1.0)
    receiver = Receiver(FS, latency=latency, capacity=n_nodes)
    sock = receiving_socket(0)
    port = sock.getsockname()[1]
    stagger = np.arange(n_nodes) / n_nodes * SPP / FS
    deadline_s = ((receiver.reorder + 1) * SPP + latency) / FS  # latency + reorder window + one packet
    batches, done = Batches(), multiprocessing.Queue()
    start = time.monotonic() + 1.0
    sender = multiprocessing.Process(target=_sender, args=(port, data, lengths, times, start, done), daemon=True)
    sender.start()
    read = outputs = late = 0
    worst, examples = -np.inf, []
    while time.monotonic() < start:
        time.sleep(0.01)
    drops0 = _udp_receive_errors()
    cpu0, wall0 = time.process_time(), time.monotonic()
    sent_at, chunks = None, []
    while True:  # the loop of wsnlib.stream.udp.serve, until the sender is done and the deadline has passed
        began = time.monotonic()
        n = batches.read(sock, POLL_S)
        now = time.monotonic()
        if n:
            read += n
            chunks.append((now, receiver.receive_array(batches.data[:n], batches.lengths[:n], now)))
        else:
            chunks.append((now, receiver.expire(now)))
        if sent_at is None and not done.empty():
            sent_at = done.get()
        if sent_at is not None and now > start + sent_at[-1] + 2 * deadline_s:
            break
        rest = began + MIN_PERIOD_S - time.monotonic()
        if rest > 0:
            time.sleep(rest)
    cpu, wall = time.process_time() - cpu0, time.monotonic() - wall0
    drops = _udp_receive_errors() - drops0 if drops0 >= 0 else -1
    chunks.append((time.monotonic(), receiver.flush()))
    sender.join(timeout=30)
    sock.close()
    # A sample is taken when the sender's clock says: its nominal time plus the sender's lag then (the
    # lag of the datagrams sent around it), so a sender slowed by other load does not count against the
    # receiver; the lag itself is reported.
    lag = sent_at - times
    for now, out in chunks:
        exists = out.sample < n_samples  # (after its last packet a node is predicted until silent too long)
        if np.any(exists):
            nominal = stagger[out.node[exists]] + (out.sample[exists] + 1) / FS
            delay = now - (start + nominal + np.interp(nominal, times, lag))
            outputs += int(exists.sum())
            late += int(np.sum(delay > deadline_s))
            worst = max(worst, float(delay.max()))
            for i in np.flatnonzero(delay > deadline_s)[:2]:
                examples.append((int(out.node[exists][i]), int(out.sample[exists][i]),
                                 bool(out.received[exists][i]), round(float(delay[i]), 3), round(now - start, 3)))
    utilisation = cpu / wall
    return {"nodes": n_nodes, "wall_s": wall, "cpu_s": cpu, "utilisation": utilisation, "sent": int(data.shape[0]),
            "read": read, "dropped_by_kernel": drops, "samples": outputs, "late": late, "worst_delay_s": worst,
            "deadline_s": deadline_s, "sender_lag_p99_s": float(np.percentile(lag, 99)),
            "sender_lag_max_s": float(lag.max()), "nodes_per_core": n_nodes / utilisation,
            "counters": receiver.counters.sum().to_dict(), "late_examples": examples[:10]}


def run(quick: bool = False, nodes: int | None = None, seconds: float | None = None, log=print, signals=None) -> dict:
    """The measurements; ``signals`` (gyr, acc, mag at 50 Hz) replace the BROAD trial (the tests' data)."""
    n_nodes = nodes or (200 if quick else TARGET_NODES)
    seconds = seconds or (3.0 if quick else 10.0)
    log(f"encoding {n_nodes} nodes x {seconds:g} s at {FS:g} Hz (GE 10 %) ...")
    data, lengths, times, n_samples, lost_share = packets(n_nodes, seconds, signals=signals)
    log(f"{data.shape[0]:,} datagrams ({lost_share:.1%} of the packets lost); real time over UDP ...")
    live = realtime(data, lengths, times, n_nodes, n_samples)
    log("in process, per setting ...")
    settings = {"latency 0, no redundancy": (0, 0), "latency 25 (0.5 s), no redundancy": (25, 0),
                "latency 0, redundancy K=4 doubling 12 bits": (0, 4),
                "latency 25 (0.5 s), redundancy K=4 doubling 12 bits": (25, 4)}
    offline, encoded = {}, {0: (data, lengths, times)}
    for name, (latency, k) in settings.items():
        if k not in encoded:
            d, ln, t, *_ = packets(n_nodes, seconds, redundancy=k, signals=signals)
            encoded[k] = (d, ln, t)
        offline[name] = in_process(*encoded[k], n_samples, latency=latency)
    headline = offline["latency 0, no redundancy"]
    complete = live["samples"] == n_nodes * n_samples  # every sample of every node output, once
    capable = (live["nodes_per_core"] >= TARGET_NODES and n_nodes >= TARGET_NODES and live["utilisation"] < 1.0
               and complete and live["read"] == live["sent"] and headline["late"] == 0)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"quick": quick, "nodes": n_nodes, "seconds": seconds, "lost_share": lost_share, "live": live,
            "offline": offline, "machine": f"{platform.machine()} {platform.processor()}".strip(),
            "python": platform.python_version(), "cpus": os.cpu_count(), "load": load,
            "targets": {
                f">= {TARGET_NODES:,} nodes per core (receiver CPU in the real-time run), every sample output, "
                f"none dropped, every deadline met with the receiver's own timing": capable,
                f"... and every deadline met in the real-time run on this machine (load average {load:.1f})":
                    capable and live["late"] == 0}}


def report(results: dict) -> str:
    live = results["live"]
    lines = ["", f"{results['nodes']:,} nodes x {results['seconds']:g} s at {FS:g} Hz, 6 samples/packet, GE 10 % "
             f"({results['lost_share']:.1%} of the packets lost); {results['machine']}, Python {results['python']}, "
             f"{results['cpus']} CPUs", "", "real time over UDP loopback (receiver on one core, latency 0):",
             f"  receiver CPU / wall          {live['cpu_s']:.2f} s / {live['wall_s']:.2f} s = "
             f"{live['utilisation']:.1%} of a core",
             f"  datagrams sent / read        {live['sent']:,} / {live['read']:,} (kernel drops, all UDP "
             f"sockets: {live['dropped_by_kernel']})",
             f"  samples output               {live['samples']:,} ({live['samples'] / live['wall_s']:,.0f} per s)",
             f"  late samples / worst delay   {live['late']:,} / {live['worst_delay_s'] * 1e3:.0f} ms "
             f"(deadline {live['deadline_s'] * 1e3:.0f} ms)",
             f"  sender's lag, p99 / max      {live['sender_lag_p99_s'] * 1e3:.1f} / "
             f"{live['sender_lag_max_s'] * 1e3:.1f} ms (deadlines count from the sender's actual clock)",
             f"  nodes per core (nodes / utilisation)  {live['nodes_per_core']:,.0f}", "",
             f"{'in process (decode + filter + output), per setting':<56}{'us/sample':>10}{'nodes/core':>12}"
             f"{'late':>8}{'worst delay':>13}"]
    lines += [f"  {name:<54}{v['us_per_sample']:>10.2f}{v['nodes_per_core']:>12,.0f}{v['late']:>8,}"
              f"{v['worst_delay_s'] * 1e3:>8.0f} ms / {v['deadline_s'] * 1e3:.0f}"
              for name, v in results["offline"].items()]
    note = "  (quick mode: fewer nodes; indicative only)" if results["quick"] else ""
    lines += [""] + [f"{'PASS' if ok else 'MISS'}  {what}{note}" for what, ok in results["targets"].items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="200 nodes for 3 s")
    parser.add_argument("--nodes", type=int, default=None, help=f"nodes (default {TARGET_NODES:,})")
    parser.add_argument("--seconds", type=float, default=None, help="seconds of packets (default 10)")
    args = parser.parse_args(argv)
    print(report(run(quick=args.quick, nodes=args.nodes, seconds=args.seconds)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
