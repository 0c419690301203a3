"""Command line: replay a recording as packets over UDP, and receive them (two terminals, or a script).

::

    python -m wsnlib.stream receive --port 5005 --out out.csv [--latency SAMPLES] [--idle-exit SECONDS]
    python -m wsnlib.stream send RECORDING --port 5005 --loss ge:0.1:3 --seed 1 [--fs HZ] [--speed 1|max]
                                 [--redundancy K] [--dump sent.npz]

``send`` reads a BROAD ``.mat`` file (by path; resampled to ``--fs``, default 50 Hz) or a recording
file of :mod:`wsnlib.io.recording` (``.csv`` or its ``.json``; every node, node ids from
``--node`` on; at its own rate unless ``--fs`` says otherwise), cuts it into packets
(:func:`wsnlib.stream.node_stream`), drops those a Gilbert–Elliott channel loses
(``--loss ge:RATE[:MEAN_BURST]`` packets, seeded by ``--seed``; ``none``), and sends the others to
127.0.0.1, each when its last sample is taken (``--speed 1``; ``2`` twice as fast; ``max`` at
once).  ``--dump`` writes what the receiver should reconstruct: ``gyr``, ``acc``, ``mag`` (T, 3)
as dequantised from the packets, ``received`` (T,) the loss mask applied, ``fs`` (and ``node``;
with several nodes the arrays get a leading node axis; ``quat_ref`` where the recording has a
reference).

``receive`` listens on 127.0.0.1 (``--port 0``: a free port, printed), takes the sampling rate
from the first valid packet, and writes one row per sample, ``node,sample,received,w,x,y,z``, as
they are output (:class:`wsnlib.stream.Receiver`); ``--idle-exit`` ends it once no packet has
arrived for that long (after the first); Ctrl-C ends it cleanly, everything so far written.  At exit it prints the
counters per node and the datagrams rejected per reason.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

import numpy as np

from wsnlib._arguments import positive_number, whole_number
from wsnlib.loss import SAMPLES_PER_PACKET, gilbert_elliott, packets_to_samples
from wsnlib.stream.packet import LAYOUTS, MAX_REDUNDANCY, MAX_SAMPLES_PER_PACKET, REDUNDANCY_BITS
from wsnlib.stream.receiver import DEFAULT_REORDER, Receiver, ReceiverOutput
from wsnlib.stream.sender import encode_stream, node_stream
from wsnlib.stream.udp import receiving_socket, send_datagrams, serve

#: Rate (Hz) a BROAD trial is sent at by default: paper 001's 50 Hz.
BROAD_SEND_FS = 50.0


def loss_spec(spec: str) -> tuple[float, float] | None:
    """``--loss``: ``none`` → None; ``ge:RATE[:MEAN_BURST]`` → (rate, mean burst in packets, default 3)."""
    kind, *fields = spec.strip().split(":")
    if kind == "none" and not fields:
        return None
    try:
        numbers = [float(f) for f in fields]
    except ValueError:
        numbers = []
    if kind == "ge" and 1 <= len(numbers) <= 2:
        rate, burst = (numbers + [3.0])[:2]
        if 0.0 <= rate < 1.0 and burst >= 1.0:
            return rate, burst
    raise argparse.ArgumentTypeError(f"{spec!r} is not a loss: expected 'none' or 'ge:RATE[:MEAN_BURST]' with "
                                     f"0 <= RATE < 1 and MEAN_BURST >= 1 (packets)")


def _speed(text: str) -> float | None:
    """``--speed``: a number > 0 (× real time), or ``max`` (as fast as possible: None)."""
    if text == "max":
        return None
    try:
        return positive_number(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text!r}: needs a number > 0, or 'max'") from None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.stream",
                                     description="Replay a recording as packets over UDP, and receive them.")
    commands = parser.add_subparsers(dest="command", required=True)
    send = commands.add_parser("send", help="replay a recording as packets to 127.0.0.1:PORT")
    send.add_argument("recording", type=Path, help="a BROAD .mat file, or a recording .csv/.json (wsnlib.io.recording)")
    send.add_argument("--port", type=whole_number(1, 65535), required=True)
    send.add_argument("--loss", type=loss_spec, default=None, help="'none' or 'ge:RATE[:MEAN_BURST]' (default none)")
    send.add_argument("--seed", type=int, default=0, help="seed of the loss draw (default 0)")
    send.add_argument("--fs", type=positive_number, default=None,
                      help=f"rate to send at (Hz; default {BROAD_SEND_FS:g} for BROAD, else the recording's own)")
    send.add_argument("--speed", type=_speed, default=1.0, help="1 real time (default), 2 twice as fast, 'max'")
    send.add_argument("--redundancy", type=int, default=0, choices=range(MAX_REDUNDANCY + 1), metavar="K",
                      help=f"summary entries per packet, 0-{MAX_REDUNDANCY} (default 0)")
    send.add_argument("--bits", type=int, default=12, choices=range(REDUNDANCY_BITS[0], REDUNDANCY_BITS[1] + 1),
                      metavar="BITS", help="bits per summary value (default 12)")
    send.add_argument("--layout", choices=LAYOUTS, default="doubling", help="summary layout (default doubling)")
    send.add_argument("--node", type=whole_number(0, 65535), default=0,
                      help="id of the (first) node, 0-65535 (default 0)")
    send.add_argument("--samples-per-packet", type=whole_number(1, MAX_SAMPLES_PER_PACKET), default=SAMPLES_PER_PACKET,
                      metavar="N",
                      help=f"samples per packet, 1-{MAX_SAMPLES_PER_PACKET} (default {SAMPLES_PER_PACKET})")
    send.add_argument("--dump", type=Path, default=None, help="write what the receiver should reconstruct (.npz)")
    receive = commands.add_parser("receive", help="receive on 127.0.0.1:PORT, one CSV row per sample")
    receive.add_argument("--port", type=whole_number(0, 65535), required=True, help="0: a free port (printed)")
    receive.add_argument("--out", type=Path, required=True)
    receive.add_argument("--latency", type=whole_number(0), default=0,
                         help="samples of fixed-lag smoothing (default 0)")
    receive.add_argument("--reorder", type=whole_number(1), default=DEFAULT_REORDER,
                         help=f"reorder window in packets (default {DEFAULT_REORDER})")
    receive.add_argument("--idle-exit", type=positive_number, default=None, metavar="SECONDS",
                         help="exit once no packet has arrived for this long (after the first)")
    return parser


def load_signals(path: Path, fs: float | None):
    """``(fs, [(gyr, acc, mag or None, quat_ref or None), …])`` per node of a BROAD .mat or a recording file."""
    from wsnlib.io.resample import resample_signal

    if path.suffix == ".mat":
        from wsnlib.io.broad import load_broad
        from wsnlib.io.resample import resample_broad

        trial = resample_broad(load_broad(path.stem, path.parent, download=False), fs or BROAD_SEND_FS)
        return trial.fs, [(trial.gyr, trial.acc, trial.mag, trial.quat_ref)]
    from wsnlib.io.recording import read_recording

    rec = read_recording(path)
    rate = rec.fs if fs is None else float(fs)
    nodes = []
    for n in range(len(rec.nodes)):
        signals = [rec.gyr[n], rec.acc[n], rec.mag[n]]
        if rate != rec.fs:
            signals = [resample_signal(x, rec.fs, rate) for x in signals]
        reference = rec.quat_true[n] if rec.quat_true is not None and rate == rec.fs else None
        nodes.append((*signals, reference))
    return rate, nodes


def run_send(args) -> int:
    if not args.recording.is_file():
        raise SystemExit(f"{args.recording}: no such file")
    try:
        fs, nodes = load_signals(args.recording, args.fs)
    except ValueError as exc:  # not a BROAD trial, not a recording file, or a rate it cannot be resampled to
        message = str(exc)
        raise SystemExit(message if str(args.recording) in message else f"{args.recording}: {message}") from None
    if args.node + len(nodes) - 1 > 0xFFFF:
        raise SystemExit(f"--node {args.node}: the recording's {len(nodes)} nodes need ids up to 65535")
    rngs = np.random.default_rng(args.seed).spawn(len(nodes))
    datagrams, times, dump = [], [], {"fs": fs, "node": np.arange(args.node, args.node + len(nodes))}
    per_node = {key: [] for key in ("gyr", "acc", "mag", "received", "quat_ref")}
    for i, (gyr, acc, mag, reference) in enumerate(nodes):
        stream = node_stream(gyr, acc, mag, fs=fs, samples_per_packet=args.samples_per_packet,
                             redundancy=args.redundancy, bits=args.bits, layout=args.layout)
        packets = np.ones(stream.n_packets, bool)
        if args.loss is not None:
            packets = gilbert_elliott(stream.n_packets, *args.loss, rng=rngs[i])
        sent = np.flatnonzero(packets)
        datagrams += encode_stream(stream, node=args.node + i, packets=sent)
        spp = stream.samples_per_packet
        times += list(np.minimum((sent + 1) * spp, stream.n_samples) / fs)  # when the packet's last sample is taken
        per_node["gyr"].append(stream.gyr)
        per_node["acc"].append(stream.acc)
        per_node["mag"].append(stream.mag if mag is not None else np.zeros_like(stream.gyr))
        per_node["received"].append(packets_to_samples(packets, spp, stream.n_samples))
        if reference is not None:
            per_node["quat_ref"].append(reference)
    order = np.argsort(np.asarray(times), kind="stable")
    if args.dump is not None:
        for key, arrays in per_node.items():
            if arrays and (key != "quat_ref" or len(arrays) == len(nodes)):
                dump[key] = arrays[0] if len(nodes) == 1 else np.stack(arrays)
        np.savez(args.dump, **dump)
    seconds = send_datagrams([datagrams[i] for i in order], np.asarray(times)[order], args.port, speed=args.speed)
    print(f"sent {len(datagrams)} packets of {len(nodes)} node(s) at {fs:g} Hz in {seconds:.2f} s to "
          f"127.0.0.1:{args.port}")
    return 0


class CsvSink:
    """Appends output rows to a CSV (header first), flushed after every batch."""

    FORMAT = ["%d", "%d", "%d", "%.9g", "%.9g", "%.9g", "%.9g"]

    def __init__(self, path: Path):
        self.handle = open(path, "w", encoding="utf-8", newline="\n")  # noqa: SIM115 (closed by close())
        self.handle.write("node,sample,received,w,x,y,z\n")
        self.rows = 0

    def __call__(self, out: ReceiverOutput) -> None:
        if len(out):
            table = np.column_stack([out.node, out.sample, out.received, out.quat])
            np.savetxt(self.handle, table, fmt=self.FORMAT, delimiter=",")
            self.handle.flush()
            self.rows += len(out)

    def close(self) -> None:
        self.handle.close()


def _report(receiver, early_rejects: int, sink: CsvSink, how: str) -> None:
    print(f"{how}: wrote {sink.rows} rows")
    if receiver is None:
        print(f"no valid packet received ({early_rejects} datagrams rejected)")
        return
    print(receiver.counters.to_string())
    rejected = receiver.rejected
    print("rejected datagrams: " + ", ".join(f"{reason} {count}" for reason, count in rejected.items())
          + (f" (+ {early_rejects} before the first valid packet)" if early_rejects else ""))


def run_receive(args) -> int:
    sock = receiving_socket(args.port)
    sink = CsvSink(args.out)
    print(f"listening on 127.0.0.1:{sock.getsockname()[1]}", flush=True)
    stop = []  # Ctrl-C (SIGINT) or SIGTERM: finish the batch in hand, then stop

    def on_signal(signum, frame):
        stop.append(signum)

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        receiver, early, how = serve(sock, lambda fs: Receiver(fs, latency=args.latency, reorder=args.reorder),
                                     sink, idle_exit_s=args.idle_exit, should_stop=lambda: bool(stop))
        if receiver is not None:
            sink(receiver.flush())
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        sock.close()
        sink.close()
    _report(receiver, early, sink, how)
    return 0


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "send":
        return run_send(args)
    return run_receive(args)


if __name__ == "__main__":
    sys.exit(main())
