"""The live receiver in a notebook: a node sending in the background, the orientation as it arrives.

:func:`live_view` is the one entry point (notebook 11).  A *session* replays one recording
(:class:`~wsnlib.studies.loss_tolerance.StudyRecording`, with its optical reference) as a node's
packets over UDP loopback, at real time, through a Gilbert–Elliott channel
(:func:`wsnlib.stream.node_stream`, :func:`wsnlib.stream.encode_stream`), and receives them with
:class:`wsnlib.stream.Receiver` as the command line does (:func:`wsnlib.stream.udp.serve`):
three threads, the sender, the receiver and — live — the drawing.  How it is shown follows the
project's widget rule (:mod:`wsnlib.interactive`):

* in a live kernel: a panel with a loss-rate slider and latency and redundancy drop-downs, and a
  frame (:class:`wsnlib.plotting.streaming.LiveFigure`: the body frame of the estimate and of the
  optical reference, the error of the last seconds with lost samples marked) redrawn
  :data:`FRAMES_PER_S` times a second while packets flow, with a status line (frames drawn and
  their rate over the last 25, the receiver's counters).  Moving a control starts a new session; the recording
  starts over when it ends; the panel stops after ``seconds`` (or with its Stop button);
* in the batch (:func:`wsnlib.paths.in_batch`): the same threads with the sender as fast as
  possible (no waiting for real time), for the recording's first ``seconds``, and a static
  figure of what the receiver output, returned so the notebook can save it.  The receiver then
  runs without a clock (packets are declared lost by sequence only) and reads every datagram
  sent before it stops, so the figure is the same on every run, however busy the machine.
"""

from __future__ import annotations

import select
import threading
import time

import numpy as np
from matplotlib.figure import Figure

from wsnlib import metrics, paths
from wsnlib.loss import gilbert_elliott
from wsnlib.plotting.streaming import LiveFigure, plot_body_frame, plot_live_error
from wsnlib.stream import Receiver, encode_stream, node_stream, packets_sent_twice
from wsnlib.stream.udp import Batches, receiving_socket, send_datagrams, serve
from wsnlib.studies.streaming import MEAN_BURST_PACKETS, Scheme

#: How often the live frame is redrawn (per s).
FRAMES_PER_S = 12.0


class Session:
    """One replay of ``unit`` through the channel and the receiver (module docstring); ``start()`` runs
    it in the background, ``stop()`` ends it.  ``quat`` (T, 4), ``received`` (T,) and ``output`` (T,)
    fill as the receiver outputs samples; ``counters`` is the receiver's table."""

    def __init__(self, unit, *, loss_rate: float, latency_s: float, scheme: Scheme, seed: int,
                 speed: float | None = 1.0, seconds: float | None = None):
        n = unit.n_samples if seconds is None else min(unit.n_samples, int(round(seconds * unit.fs)))
        self.unit, self.fs, self.n = unit, unit.fs, n
        self.stream = node_stream(unit.gyr[:n], unit.acc[:n], unit.mag[:n], fs=unit.fs, redundancy=scheme.redundancy,
                                  bits=scheme.bits, layout=scheme.layout)
        slots = np.ones(self.stream.n_packets + 1, bool)
        if loss_rate > 0:
            slots = gilbert_elliott(slots.size, loss_rate, MEAN_BURST_PACKETS, rng=np.random.default_rng(seed))
        slots[0] = True  # the stream starts with a received packet
        spp = self.stream.samples_per_packet
        packets = np.arange(self.stream.n_packets)
        sent, times = [packets[slots[:-1]]], [(packets[slots[:-1]] + 1) * spp / unit.fs]
        if scheme.twice:  # the copy one slot later on the same channel
            sent.append(packets[slots[1:]])
            times.append((packets[slots[1:]] + 2) * spp / unit.fs)
        order = np.argsort(np.concatenate(times), kind="stable")
        index = np.concatenate(sent)[order]
        self.delivered = packets_sent_twice(slots) if scheme.twice else slots[:-1]
        datagrams = encode_stream(self.stream, packets=index)
        self.datagrams, self.times = datagrams, np.concatenate(times)[order]
        self.latency = int(round(latency_s * unit.fs))
        self.speed = speed
        self.quat = np.full((n, 4), np.nan)
        self.received = np.zeros(n, bool)
        self.output = np.zeros(n, bool)
        self.newest = -1
        self.receiver = None
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self.sock = receiving_socket(0)
        self.sent, self.sent_at = threading.Event(), 0.0
        self.done = threading.Event()

    def _sink(self, out) -> None:
        keep = out.sample < self.n
        with self.lock:
            s = out.sample[keep]
            self.quat[s], self.received[s], self.output[s] = out.quat[keep], out.received[keep], True
            if s.size:
                self.newest = max(self.newest, int(s.max()))

    def _receive(self) -> None:
        def make(fs):
            self.receiver = Receiver(fs, latency=self.latency)
            return self.receiver

        linger = 0.5 + 2 * self.latency / self.fs  # after the last datagram: the latency's samples still come

        def finished():
            if self._stop.is_set():
                return True
            if not self.sent.is_set() or time.monotonic() - self.sent_at <= linger:
                return False
            return not select.select([self.sock], [], [], 0)[0]  # and every datagram sent is read

        # Sent as fast as possible, arrival times say nothing about the samples' times: no receiver clock,
        # so a busy machine (a late thread) cannot make the receiver declare packets lost that came.
        clock = time.monotonic if self.speed is not None else None
        receiver, _, _ = serve(self.sock, make, self._sink, should_stop=finished, clock=clock, batches=Batches(256))
        if receiver is not None:
            self._sink(receiver.flush())
        self.sock.close()
        self.done.set()

    def _send(self) -> None:
        send_datagrams(self.datagrams, self.times, self.sock.getsockname()[1], speed=self.speed,
                       should_stop=self._stop.is_set)
        self.sent_at = time.monotonic()
        self.sent.set()

    def start(self) -> Session:
        self.threads = [threading.Thread(target=self._receive, daemon=True),
                        threading.Thread(target=self._send, daemon=True)]
        for thread in self.threads:
            thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()

    def errors(self, upto: int | None = None) -> np.ndarray:
        """Total error (°) per output sample so far (NaN where nothing is output yet or no reference)."""
        with self.lock:
            quat, out = self.quat.copy(), self.output.copy()
        quat[~out] = [1.0, 0.0, 0.0, 0.0]
        error = metrics.broad_errors_deg(quat, self.unit.quat_ref[: self.n])["total"]
        error[~out] = np.nan
        return error


def _static_view(unit, *, loss_rate, latency_s, scheme, seed, seconds) -> Figure:
    session = Session(unit, loss_rate=loss_rate, latency_s=latency_s, scheme=scheme, seed=seed, speed=None,
                      seconds=seconds).start()
    if not session.done.wait(timeout=120):
        session.stop()
        raise RuntimeError("the live view's replay did not end within 120 s")
    error = session.errors()
    time_s = np.arange(session.n) / session.fs
    fig = Figure(figsize=(7.5, 3.6), layout="constrained")
    grid = fig.add_gridspec(1, 3)
    frame = fig.add_subplot(grid[0, 0], projection="3d")
    ax = fig.add_subplot(grid[0, 1:])
    # Up to the last delivered packet's last sample: lost packets after it are never known to the receiver
    # (no later packet), so nothing after it is output.
    spp = session.stream.samples_per_packet
    last = min(int(np.flatnonzero(session.delivered)[-1] + 1) * spp, session.n) - 1
    plot_body_frame(session.quat[last], ax=frame, reference=session.unit.quat_ref[last],
                    title=f"at {time_s[last]:.1f} s: estimate (solid),\noptical reference (dashed)")
    plot_live_error(time_s[: last + 1], error[: last + 1], session.received[: last + 1], ax=ax,
                    window_s=float(time_s[last]) + 1.0 / session.fs)
    fig.suptitle(f"The receiver's output over UDP (sent as fast as possible): {scheme.name},\nGE "
                 f"{loss_rate:.0%} ({int((~session.delivered).sum())} of {session.delivered.size} packets lost), "
                 f"latency {latency_s:g} s", fontsize=9)
    return fig


def live_view(unit, *, schemes: dict, loss_rates, latencies_s, start: dict, seed: int = 0, seconds: float = 60.0):
    """The live receiver on ``unit`` (module docstring): an ipywidgets panel in a live kernel, a static
    Figure in the batch.

    Parameters
    ----------
    unit : StudyRecording
        A recording with its optical reference (e.g. a BROAD trial at 50 Hz).
    schemes : dict label → Scheme
        The redundancy drop-down (:class:`wsnlib.studies.streaming.Scheme`).
    loss_rates : sequence of float
        The loss-rate slider's values (fractions).
    latencies_s : sequence of float
        The latency drop-down (s).
    start : dict
        Starting ``loss_rate``, ``latency_s`` and ``scheme`` (a label of ``schemes``).
    seed : int
        Seed of the channel's loss draw.
    seconds : float
        Live: how long the panel runs; batch: how much of the recording is sent.
    """
    unknown = set(start) - {"loss_rate", "latency_s", "scheme"}
    if unknown or start.get("scheme") not in schemes:
        raise ValueError(f"start must give loss_rate, latency_s and a scheme among {list(schemes)}, got {start!r}")
    if paths.in_batch():
        return _static_view(unit, loss_rate=start["loss_rate"], latency_s=start["latency_s"],
                            scheme=schemes[start["scheme"]], seed=seed, seconds=seconds)
    return _live_panel(unit, schemes=schemes, loss_rates=list(loss_rates), latencies_s=list(latencies_s), start=start,
                       seed=seed, seconds=seconds)


def _live_panel(unit, *, schemes, loss_rates, latencies_s, start, seed, seconds):
    import ipywidgets as widgets

    loss = widgets.SelectionSlider(options=[(f"{100 * r:g} %", r) for r in loss_rates], value=start["loss_rate"],
                                   description="packets lost")
    latency = widgets.Dropdown(options=[(f"{s:g} s", s) for s in latencies_s], value=start["latency_s"],
                               description="latency")
    redundancy = widgets.Dropdown(options=list(schemes), value=start["scheme"], description="redundancy")
    stop = widgets.ToggleButton(value=False, description="Stop")
    image = widgets.Image(format="png", layout=widgets.Layout(width="100%"))
    status = widgets.Label("starting …")
    figure = LiveFigure()
    state = {"session": None, "frames": 0, "began": time.monotonic()}
    lock = threading.Lock()

    def restart(_change=None):
        with lock:
            if state["session"] is not None:
                state["session"].stop()
            state["session"] = Session(unit, loss_rate=loss.value, latency_s=latency.value,
                                       scheme=schemes[redundancy.value], seed=seed).start()

    for control in (loss, latency, redundancy):
        control.observe(restart, names="value")

    def draw_loop():
        period, drawn = 1.0 / FRAMES_PER_S, []
        while not stop.value and time.monotonic() - state["began"] < seconds:
            tick = time.monotonic()
            with lock:
                session = state["session"]
            if session.done.is_set():  # the recording ended: from the start again
                restart()
                continue
            newest = session.newest
            if newest >= 0:
                lo = max(0, newest - int(figure.window_s * session.fs))
                error = session.errors()[lo: newest + 1]
                with session.lock:
                    quat = session.quat[newest].copy()
                    got = session.received[lo: newest + 1].copy()
                figure.update(quat, session.unit.quat_ref[newest], np.arange(lo, newest + 1) / session.fs, error,
                              got, title=f"{redundancy.value}, GE {loss.value:.0%}, latency {latency.value:g} s")
                image.value = figure.png()
                state["frames"] += 1
                drawn.append(time.monotonic())
                recent = drawn[-25:]
                rate = (len(recent) - 1) / (recent[-1] - recent[0]) if len(recent) > 1 else 0.0
                counts = session.receiver.counters.sum() if session.receiver is not None else None
                status.value = (f"frames drawn: {state['frames']} ({rate:.1f} per s); sample "
                                f"{newest} ({newest / session.fs:.1f} s)" + ("" if counts is None else
                                f"; packets received {counts['received']}, lost {counts['lost']}, "
                                f"duplicate {counts['duplicate']}"))
            time.sleep(max(0.0, period - (time.monotonic() - tick)))
        with lock:
            state["session"].stop()
        status.value += " — stopped"

    restart()
    threading.Thread(target=draw_loop, daemon=True).start()
    return widgets.VBox([widgets.HBox([loss, latency, redundancy, stop]), image, status],
                        layout=widgets.Layout(width="100%"))
