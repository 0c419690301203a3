"""Time series of angles and errors (paper 001): traces with lost samples shaded, bands, trade-offs."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from wsnlib.plotting.style import ANNOTATION_FONT_PT, METHOD_COLORS


def _axes(ax):
    if ax is None:
        _, ax = plt.subplots()
    return ax


def plot_angle_traces(time_s, traces: dict, *, ax=None, ylabel="angle (°)", loss_spans=(), title=None):
    """Plot several angle traces (degrees) against time, shading lost intervals.

    Parameters
    ----------
    time_s : array_like, shape (T,)
    traces : dict[str, array_like (T,)]
        Label → trace; colours come from :data:`METHOD_COLORS` when the label is known.
    loss_spans : iterable of (start_s, end_s)
        Intervals drawn as grey bands (e.g. from :func:`loss_spans`).
    """
    ax = _axes(ax)
    for start, end in loss_spans:
        ax.axvspan(start, end, color="0.8", alpha=0.6, lw=0, label=None)
    for label, trace in traces.items():
        style = {"ls": "--"} if label == "truth" else {}
        ax.plot(time_s, trace, label=label, color=METHOD_COLORS.get(label), **style)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.legend(loc="best")
    return ax


def plot_trace_panels(time_s, panels: dict, received, *, ylabel: str, window=None, suptitle=None,
                      panel_height_in: float = 2.5):
    """Stacked panels of angle traces (shared axes), one per case, each with its own lost interval shaded.

    Paper 001's Figs. 2 and 3 for several loss lengths: one panel per loss.

    Parameters
    ----------
    time_s : array_like, shape (T,)
    panels : dict title → dict label → array_like (T,)
        One entry per panel, drawn by :func:`plot_angle_traces` (colours by label).
    received : array_like of bool, shape (len(panels), T)
        Each panel's loss mask.
    ylabel : str
    window : array_like of bool, shape (T,), optional
        Samples shown (default all).
    suptitle : str, optional
    panel_height_in : float

    Returns
    -------
    matplotlib.figure.Figure
    """
    time_s = np.asarray(time_s, dtype=float)
    received = np.asarray(received, dtype=bool)
    if received.shape != (len(panels), time_s.size):
        raise ValueError(f"received must have shape ({len(panels)}, {time_s.size}), got {received.shape}")
    window = np.ones(time_s.size, bool) if window is None else np.asarray(window, dtype=bool)
    fig, axes = plt.subplots(len(panels), 1, sharex=True, sharey=True, squeeze=False,
                             figsize=(7.5, panel_height_in * len(panels)), layout="constrained")
    for ax, (title, traces), mask in zip(axes[:, 0], panels.items(), received, strict=True):
        plot_angle_traces(time_s[window], {label: np.asarray(trace)[window] for label, trace in traces.items()},
                          ax=ax, ylabel=ylabel, title=title, loss_spans=loss_spans(time_s[window], mask[window]))
    for ax in axes[:-1, 0]:
        ax.set_xlabel("")
    if suptitle:
        fig.suptitle(suptitle)
    return fig


def loss_spans(time_s, received) -> list[tuple[float, float]]:
    """Intervals ``(start_s, end_s)`` of consecutive lost samples in a 1-D ``received`` mask.

    Each span runs from the first lost sample's time to the next received sample's time.
    """
    time_s = np.asarray(time_s, dtype=float)
    lost = ~np.asarray(received, dtype=bool)
    if lost.ndim != 1 or lost.shape != time_s.shape:
        raise ValueError("received must be 1-D and match time_s")
    edges = np.diff(np.concatenate([[0], lost.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    dt = time_s[1] - time_s[0] if time_s.size > 1 else 0.0
    return [(float(time_s[s]), float(time_s[e]) if e < time_s.size else float(time_s[-1] + dt))
            for s, e in zip(starts, ends, strict=True)]


def break_at_gaps(x, *ys, max_step=None):
    """Insert a NaN row wherever ``x`` jumps by more than ``max_step``, so plotted lines break there.

    Matplotlib joins consecutive points with a line whatever lies between them; across a gap in
    the data (rejected samples, two recordings put end to end) that line shows data that do not
    exist.  A NaN breaks it.

    Parameters
    ----------
    x : array_like, shape (N,)
        Increasing abscissa (e.g. time, s).
    *ys : array_like, shape (N,) or (N, ...)
        Series to break at the same places; NaN values already in them break lines too.
    max_step : float, optional
        Largest step of ``x`` still drawn as a line; default 1.5 × the median step.

    Returns
    -------
    tuple of numpy.ndarray
        ``(x, *ys)`` with one NaN row after every gap (``x`` is NaN there too).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"x must be 1-D, got shape {x.shape}")
    columns = [np.asarray(y, dtype=float) for y in ys]
    for y in columns:
        if y.shape[:1] != x.shape:
            raise ValueError(f"every series must have x's length {x.size} on axis 0, got shape {y.shape}")
    steps = np.diff(x)
    if np.any(steps < 0):
        raise ValueError("x must be increasing (sort the samples first)")
    if max_step is None:
        max_step = 1.5 * float(np.median(steps)) if steps.size else np.inf
    elif not max_step > 0:
        raise ValueError(f"max_step must be positive, got {max_step!r}")
    gaps = np.flatnonzero(steps > max_step) + 1
    return (np.insert(x, gaps, np.nan), *(np.insert(y, gaps, np.nan, axis=0) for y in columns))


def plot_band(x, samples, *, ax=None, label=None, color=None, quantiles=(0.1, 0.9)):
    """Median line and a quantile band of Monte Carlo ``samples`` (runs along axis 0) over ``x``."""
    ax = _axes(ax)
    samples = np.asarray(samples, dtype=float)
    lo, med, hi = np.quantile(samples, [quantiles[0], 0.5, quantiles[1]], axis=0)
    (line,) = ax.plot(x, med, marker="o", ms=3, label=label, color=color)
    ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
    return ax


def plot_tradeoff(x, y, labels, *, ax=None, xlabel=None, ylabel=None, color=None, logy=False):
    """Scatter of a trade-off (e.g. recovery time vs jerk), each point annotated with its label.

    Parameters
    ----------
    x, y : array_like, shape (N,)
    labels : sequence of str, length N
        Text written next to each point (e.g. ``"β=0.1"``).
    """
    ax = _axes(ax)
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if not (x.shape == y.shape == (len(labels),)):
        raise ValueError("x, y and labels must have the same length")
    ax.plot(x, y, "o-", color=color)
    for xi, yi, text in zip(x, y, labels, strict=True):
        ax.annotate(text, (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=ANNOTATION_FONT_PT)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel or "")
    ax.set_ylabel(ylabel or "")
    return ax


def plot_arm_angles(time_s, humerus_pitch, forearm_pitch, elbow, *, axes=None, received=None, title=None,
                    truth_pitch=None):
    """The paper's arm figure (001, Figs. 1, 6–8): segment pitches on top, elbow angle below.

    Parameters
    ----------
    time_s : array_like, shape (T,)
    humerus_pitch, forearm_pitch, elbow : array_like, shape (T,)
        Degrees.
    axes : pair of matplotlib Axes, optional
        Created (two rows, shared time axis) when not given.
    received : array_like of bool, shape (T,), optional
        Loss mask of the humerus node; lost intervals are shaded.
    truth_pitch : array_like, shape (T,), optional
        True humerus pitch, drawn dashed.

    Returns
    -------
    (Axes, Axes)
    """
    if axes is None:
        _, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    ax_pitch, ax_elbow = axes
    spans = loss_spans(time_s, received) if received is not None else ()
    traces = {"humerus": humerus_pitch, "forearm": forearm_pitch}
    if truth_pitch is not None:
        traces["truth"] = truth_pitch
    plot_angle_traces(time_s, traces, ax=ax_pitch, ylabel="pitch (°)", loss_spans=spans, title=title)
    plot_angle_traces(time_s, {"elbow": elbow}, ax=ax_elbow, ylabel="elbow angle (°)", loss_spans=spans)
    ax_pitch.set_xlabel("")
    return ax_pitch, ax_elbow
