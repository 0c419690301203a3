"""Figures of the live receiver (notebook 11): the latency curve, the redundancy trade-off, burst
coverage, and the live view's frame (an orientation as a body frame, and the error as it goes)."""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion as Q
from wsnlib.plotting.style import OKABE_ITO

#: One colour per number of summary entries K (doubling), markers per latency.
K_COLORS = {1: OKABE_ITO["sky blue"], 2: OKABE_ITO["bluish green"], 3: OKABE_ITO["yellow"], 4: OKABE_ITO["orange"],
            5: OKABE_ITO["vermillion"], 6: OKABE_ITO["reddish purple"], 7: OKABE_ITO["blue"], 8: OKABE_ITO["black"]}
LATENCY_MARKERS = ("o", "s", "^", "D")
BASELINE_STYLE = {"no redundancy": dict(marker="X", color=OKABE_ITO["black"]),
                  "send twice": dict(marker="P", color=OKABE_ITO["grey"])}


def plot_latency_curve(curve, *, ax, schemes=None):
    """Mean error against latency (s) per scheme, its interval as a band; the offline smoother and the
    lossless receiver as horizontal references, the causal receiver (latency 0) marked.

    ``curve``: :func:`wsnlib.studies.streaming.curve_means` (scheme, latency_s, rmse_total, low, high;
    references with ``latency_s`` inf)."""
    finite = curve[np.isfinite(curve["latency_s"])]
    colors = [OKABE_ITO["black"], OKABE_ITO["vermillion"], OKABE_ITO["blue"], OKABE_ITO["bluish green"]]
    for color, scheme in zip(colors, schemes or list(dict.fromkeys(finite["scheme"])), strict=False):
        rows = finite[finite["scheme"] == scheme].sort_values("latency_s")
        ax.fill_between(rows["latency_s"], rows["low"], rows["high"], color=color, alpha=0.15, lw=0)
        ax.plot(rows["latency_s"], rows["rmse_total"], "-o", color=color, ms=4, label=scheme)
        first = rows.iloc[0]
        ax.plot([first["latency_s"]], [first["rmse_total"]], marker="s", ms=9, mfc="none", color=color)
    x_max = float(finite["latency_s"].max())
    for (name, row), style in zip(curve[~np.isfinite(curve["latency_s"])].set_index("scheme").iterrows(),
                                  ("--", ":"), strict=False):
        ax.axhspan(row["low"], row["high"], color=OKABE_ITO["grey"], alpha=0.12, lw=0)
        ax.axhline(row["rmse_total"], ls=style, color=OKABE_ITO["grey"], lw=1.2, label=name)
    ax.set_xlim(-0.05, x_max + 0.05)
    ax.set_xlabel("latency (s): each sample output this long after it was taken (+ reorder window)")
    ax.set_ylabel("total RMSE (°), mean over trials")
    ax.annotate("causal (latency 0)", (0.0, float(finite[finite["latency_s"] == 0.0]["rmse_total"].max())),
                xytext=(8, 8), textcoords="offset points", fontsize=8)
    ax.legend(fontsize=8, loc="upper right")
    return ax


def plot_redundancy_tradeoff(table, *, axes, loss_rates, latencies):
    """Error against overhead (bytes per packet) for every scheme, one panel per loss rate: summaries
    coloured by K, one marker per latency, the baselines as crosses, the Pareto front per latency as
    a line.  ``table``: :func:`wsnlib.studies.streaming.pareto_table`."""
    if len(axes) != len(loss_rates):
        raise ValueError(f"axes must hold one Axes per loss rate ({len(loss_rates)}), got {len(axes)}")
    for ax, rate in zip(axes, loss_rates, strict=True):
        rows = table[table["loss_rate"] == rate]
        for marker, latency in zip(LATENCY_MARKERS, latencies, strict=False):
            at = rows[rows["latency_s"] == latency]
            summaries = at[~at["scheme"].isin(list(BASELINE_STYLE))]
            k = summaries["scheme"].str.extract(r"K=(\d+)")[0].astype(int)
            ax.scatter(summaries["overhead_bytes"], summaries["rmse_total"], c=[K_COLORS.get(v, "grey") for v in k],
                       marker=marker, s=22, edgecolor="black", linewidths=0.3, zorder=3)
            for name, style in BASELINE_STYLE.items():
                base = at[at["scheme"] == name]
                ax.scatter(base["overhead_bytes"], base["rmse_total"], marker=style["marker"], color=style["color"],
                           s=70, edgecolor="black", linewidths=0.5, zorder=4)
            front = at[at["pareto"]].sort_values("overhead_bytes")
            ax.plot(front["overhead_bytes"], front["rmse_total"], color="black", lw=0.8,
                    ls="-" if latency == latencies[0] else "--", zorder=2)
        ax.set_title(f"GE {rate:.0%}")
        ax.set_xlabel("overhead (bytes per packet)")
        ax.set_yscale("log")
    axes[0].set_ylabel("total RMSE (°), mean over trials")
    handles = [axes[0].scatter([], [], marker=m, color="white", edgecolor="black", label=f"latency {lat:g} s")
               for m, lat in zip(LATENCY_MARKERS, latencies, strict=False)]
    handles += [axes[0].scatter([], [], marker="o", color=c, label=f"K = {k}") for k, c in K_COLORS.items()
                if (table["scheme"].str.contains(f"K={k},")).any()]
    handles += [axes[0].scatter([], [], marker=s["marker"], color=s["color"], edgecolor="black", label=name)
                for name, s in BASELINE_STYLE.items()]
    axes[-1].legend(handles=handles, fontsize=8, loc="upper right", ncol=2)
    return axes


def plot_burst_coverage(coverage, *, ax, spans=(1, 2, 4, 8, 16, 32)):
    """Share of the lost packets in bursts of at most n packets, per loss rate (bars) and in the channel
    model (line).  ``coverage``: :func:`wsnlib.studies.streaming.burst_coverage`."""
    x = np.arange(len(spans))
    width = 0.8 / max(len(coverage), 1)
    colors = [OKABE_ITO["sky blue"], OKABE_ITO["blue"], OKABE_ITO["reddish purple"]]
    for i, (_, row) in enumerate(coverage.iterrows()):
        ax.bar(x + (i - (len(coverage) - 1) / 2) * width, [100 * row[f"<= {n}"] for n in spans], width,
               color=colors[i % len(colors)], label=f"GE {row['loss_rate']:.0%} (drawn)")
    ax.plot(x, [100 * coverage.iloc[0][f"<= {n} (model)"] for n in spans], "k--o", ms=4, label="channel model")
    ax.set_xticks(x, [f"≤ {n}\n(K = {int(np.log2(n)) + 1})" for n in spans])
    ax.set_xlabel("burst length (packets); doubling entries that bridge it whole")
    ax.set_ylabel("lost packets in such bursts (%)")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=8, loc="lower right")
    return ax


_AXES_COLORS = (OKABE_ITO["vermillion"], OKABE_ITO["bluish green"], OKABE_ITO["blue"])
#: The live view's camera: ENU seen from the south-east, a little above (a fixed orthographic projection).
_CAMERA = np.array([[0.7071, 0.7071, 0.0], [-0.3536, 0.3536, 0.8660]])


def plot_body_frame(quat, *, ax, reference=None, title=None):
    """The body's x, y, z axes rotated into ENU by ``quat`` (solid), and by ``reference`` (thin, dashed)
    if given, on a 3-D Axes."""
    ax.cla()
    for q, style in ((reference, dict(ls="--", lw=1.0, alpha=0.6)), (quat, dict(ls="-", lw=2.5))):
        if q is None or not np.all(np.isfinite(q)):
            continue
        for axis, color in zip(np.eye(3), _AXES_COLORS, strict=True):
            tip = Q.rotate(np.asarray(q, dtype=float), axis)
            ax.plot([0, tip[0]], [0, tip[1]], [0, tip[2]], color=color, **style)
    for limits in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        limits(-1, 1)
    ax.set_xlabel("east", labelpad=-12)
    ax.set_ylabel("north", labelpad=-12)
    ax.set_zlabel("up", labelpad=-12)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_zticks([])
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def plot_live_error(time_s, error_deg, received, *, ax, window_s=10.0, title=None):
    """The total error (°) of the last ``window_s`` seconds, lost samples marked."""
    t = np.asarray(time_s, dtype=float)
    e = np.asarray(error_deg, dtype=float)
    got = np.asarray(received, dtype=bool)
    ax.cla()
    if t.size:
        keep = t >= t[-1] - window_s
        ax.plot(t[keep], e[keep], color=OKABE_ITO["blue"], lw=1.0, label="total error")
        lost = keep & ~got
        ax.scatter(t[lost], e[lost], s=5, color=OKABE_ITO["vermillion"], zorder=3, label="lost samples")
        ax.set_xlim(max(t[-1] - window_s, 0.0), max(t[-1], window_s))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("error vs optical reference (°)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="upper left")
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def _projected(quat) -> np.ndarray:
    """Tips (3, 2) of the body's x, y, z axes rotated into ENU by ``quat``, projected by the camera."""
    return (_CAMERA @ Q.rotate(np.asarray(quat, dtype=float), np.eye(3)).T).T


class LiveFigure:
    """The live view's frame, drawn fast enough to update ten times a second: the body frame of the
    estimate (solid) and of the optical reference (dashed) as seen by a fixed camera, and the total
    error of the last ``window_s`` seconds (time axis: seconds before now) with lost samples marked.

    Artists are made once; :meth:`update` changes their data, and :meth:`png` blits them onto the
    static background (axes, ticks, legend), drawn again only when the error outgrows the y axis."""

    def __init__(self, *, window_s: float = 10.0, size=(7.5, 3.0), dpi: int = 80):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.window_s = window_s
        self.figure = Figure(figsize=size, dpi=dpi)
        self.canvas = FigureCanvasAgg(self.figure)
        frame, self.ax = self.figure.subplots(1, 2, width_ratios=[1, 2.2])
        self.figure.subplots_adjust(left=0.02, right=0.98, bottom=0.16, top=0.86, wspace=0.25)
        self.estimate = [frame.plot([0, 0], [0, 0], color=c, lw=3, animated=True)[0] for c in _AXES_COLORS]
        self.reference = [frame.plot([0, 0], [0, 0], color=c, lw=1, ls="--", animated=True)[0] for c in _AXES_COLORS]
        for axis, label in zip(np.eye(3), ("E", "N", "U"), strict=True):
            u, v = _CAMERA @ (1.15 * axis)
            frame.text(u, v, label, ha="center", va="center", fontsize=8, color=OKABE_ITO["grey"])
        frame.set_xlim(-1.25, 1.25)
        frame.set_ylim(-1.25, 1.25)
        frame.set_aspect("equal")
        frame.set_axis_off()
        self.title = self.figure.text(0.02, 0.96, "", fontsize=8, va="top", animated=True)
        (self.line,) = self.ax.plot([], [], color=OKABE_ITO["blue"], lw=1.2, label="total error", animated=True)
        self.lost = self.ax.scatter([], [], s=6, color=OKABE_ITO["vermillion"], zorder=3, label="lost samples",
                                    animated=True)
        self.ax.set_xlim(-window_s, 0.0)
        self.ax.set_ylim(0.0, 20.0)
        self.ax.set_xlabel("time before now (s)")
        self.ax.set_ylabel("error vs optical reference (°)")
        self.ax.legend(fontsize=8, loc="upper left")
        self._background = None

    def update(self, quat, reference, time_s, error_deg, received, *, title: str = ""):
        """Show the latest estimate ``quat`` and ``reference`` (or None), and the error trace (time in s)."""
        for lines, q in ((self.estimate, quat), (self.reference, reference)):
            ok = q is not None and bool(np.all(np.isfinite(q)))
            tips = _projected(q) if ok else np.zeros((3, 2))
            for line, (u, v) in zip(lines, tips, strict=True):
                line.set_data([0, u], [0, v])
                line.set_visible(ok)
        t, e, got = (np.asarray(x, dtype=float) for x in (time_s, error_deg, received))
        now = float(t[-1]) if t.size else 0.0
        keep = t >= now - self.window_s
        self.line.set_data(t[keep] - now, e[keep])
        lost = keep & (got == 0)
        self.lost.set_offsets(np.column_stack([t[lost] - now, e[lost]]) if lost.any() else np.zeros((0, 2)))
        finite = e[keep][np.isfinite(e[keep])]
        top = self.ax.get_ylim()[1]
        wanted = max(20.0, 1.2 * float(finite.max())) if finite.size else 20.0
        if wanted > top or wanted < 0.4 * top:  # rescale (and redraw the background) only now and then
            self.ax.set_ylim(0.0, wanted)
            self._background = None
        self.title.set_text(title)

    def png(self) -> bytes:
        import io

        from PIL import Image

        if self._background is None:
            self.canvas.draw()
            self._background = self.canvas.copy_from_bbox(self.figure.bbox)
        self.canvas.restore_region(self._background)
        for artist in (*self.estimate, *self.reference, self.line, self.lost, self.title):
            artist.axes.draw_artist(artist) if artist.axes is not None else self.figure.draw_artist(artist)
        buffer = io.BytesIO()
        Image.fromarray(np.asarray(self.canvas.buffer_rgba())).save(buffer, format="png", compress_level=1)
        return buffer.getvalue()
