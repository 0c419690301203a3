"""Plot style and figure saving shared by every notebook.

:func:`use_style` must be called explicitly (importing this module changes nothing global).
:func:`savefig` is the one way figures are written: PNG and PDF into the figures folder with
fixed metadata, so that running the batch twice gives byte-identical files.

Legibility: every text of a saved figure must be at least :data:`MIN_FONT_PT` tall as a student
sees it in a notebook, where a figure wider than :data:`DISPLAY_WIDTH_IN` is shrunk to that
width (:func:`effective_font_sizes`).  :func:`savefig` checks it: in the batch
(``WSNLIB_BATCH=1``) a too-small text is a ``ValueError``, interactively a warning.
"""

from __future__ import annotations

import os
import unittest.mock
import warnings
from pathlib import Path

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.text import Text

from wsnlib import paths
from wsnlib._files import atomic_path

#: The Okabe–Ito palette (colour-blind safe): the only colours of the notebooks' figures, plus
#: ``"grey"`` for references and context.  :func:`use_style` makes it matplotlib's colour cycle.
OKABE_ITO = {
    "blue": "#0072B2",
    "orange": "#E69F00",
    "bluish green": "#009E73",
    "vermillion": "#D55E00",
    "sky blue": "#56B4E9",
    "reddish purple": "#CC79A7",
    "yellow": "#F0E442",
    "black": "#000000",
    "grey": "#999999",
}

#: Colours per estimator, used consistently across notebooks (colour-blind safe, Okabe–Ito).
#: With more methods than colours, a colour is reused across papers (never within a figure's
#: notebook for two methods); :data:`METHOD_MARKERS` tells them apart.  :func:`method_style`
#: gives both.
METHOD_COLORS = {
    "truth": "#000000",
    "data fusion": "#0072B2",
    "single frame": "#D55E00",
    "hybrid": "#009E73",
    "humerus": "#D55E00",
    "forearm": "#0072B2",
    "elbow": "#000000",
    # Loss-handling options (notebooks 04-05); hold_last is plain data fusion.
    "hold_last": "#0072B2",
    "dt_extension": "#56B4E9",
    "gyro_interpolation": "#E69F00",
    "adaptive_beta": "#CC79A7",
    # Peer filters (notebook 05): one colour per library, the hybrid variants told apart by
    # marker (and, in notebook 05's figures, line style).
    "Fusion": OKABE_ITO["grey"],
    "Fusion + hybrid (output)": OKABE_ITO["grey"],
    "Fusion + hybrid (feedback)": OKABE_ITO["grey"],
    "VQF": OKABE_ITO["black"],
    "VQF + hybrid (output)": OKABE_ITO["black"],
    "VQF + hybrid (feedback)": OKABE_ITO["black"],
    # Paper 002 (notebooks 06-09): fingerprinting approaches, estimates and the baseline.
    "deterministic": OKABE_ITO["blue"],            # kNN (Shepard-weighted)
    "probabilistic": OKABE_ITO["orange"],          # p-kNN
    "kinect": OKABE_ITO["reddish purple"],         # Kinect-like optical baseline
    "radio only": OKABE_ITO["sky blue"],           # position from the fingerprint alone
    # Accelerometer pitch (notebook 07): raw eq. (6), the paper's gravity gate, a low-pass.
    "none": OKABE_ITO["grey"],
    "gating": OKABE_ITO["vermillion"],
    "lowpass": OKABE_ITO["blue"],
    # Targets of paper 002: target 1 sits on the upper arm (elbow), target 2 on the forearm (wrist).
    "T1": OKABE_ITO["vermillion"],
    "T2": OKABE_ITO["blue"],
}

#: Marker per estimator (lines get it every few points, scatters on every point); the second
#: channel besides colour, so a figure survives greyscale printing.
METHOD_MARKERS = {
    "truth": "",
    "data fusion": "o",
    "single frame": "s",
    "hybrid": "D",
    # Loss-handling options and peer filters (notebooks 04-05); a peer's hybrid variants share
    # its colour and differ in marker.
    "hold_last": "o",
    "dt_extension": ">",
    "gyro_interpolation": "<",
    "adaptive_beta": "d",
    "Fusion": "v",
    "Fusion + hybrid (output)": "p",
    "Fusion + hybrid (feedback)": "h",
    "VQF": "^",
    "VQF + hybrid (output)": "p",
    "VQF + hybrid (feedback)": "h",
    "deterministic": "o",
    "probabilistic": "s",
    "kinect": "^",
    "radio only": "v",
    "none": "x",
    "gating": "o",
    "lowpass": "s",
    "T1": "o",
    "T2": "s",
}


def method_style(name: str, **overrides) -> dict:
    """Keyword arguments for ``Axes.plot``/``scatter`` drawing method ``name`` in its colour and marker.

    Parameters
    ----------
    name : str
        A key of :data:`METHOD_COLORS` (e.g. ``"deterministic"``, ``"hybrid"``, ``"kinect"``).
    **overrides
        Replace or add keyword arguments (e.g. ``ls="--"``, ``label="ours"``).

    Returns
    -------
    dict
        ``color``, ``marker`` (may be ``""``) and ``label`` (``name``), updated with ``overrides``.

    Raises
    ------
    ValueError
        ``name`` has no colour: add it to :data:`METHOD_COLORS` rather than falling back on the
        colour cycle, so that one method keeps one colour in every notebook.
    """
    if name not in METHOD_COLORS:
        raise ValueError(f"name must be a key of METHOD_COLORS ({', '.join(METHOD_COLORS)}), got {name!r}")
    style = {"color": METHOD_COLORS[name], "marker": METHOD_MARKERS.get(name, ""), "label": name}
    style.update(overrides)
    return style

_STYLE = {
    "figure.figsize": (7.0, 3.6),
    "figure.dpi": 100,
    "savefig.dpi": 150,
    "savefig.bbox": "tight",
    # Every text at least 8 pt (MIN_FONT_PT) in a figure up to DISPLAY_WIDTH_IN wide.
    "font.size": 10,
    "axes.titlesize": 10,
    "axes.labelsize": 10,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
    "legend.fontsize": 9,
    "legend.title_fontsize": 9,
    "figure.titlesize": 11,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "legend.frameon": False,
    "lines.linewidth": 1.4,
    # Embed fonts as Type 42 so PDFs are portable; hash salt fixed for reproducible SVG ids.
    "pdf.fonttype": 42,
    "svg.hashsalt": "wsn-motion",
    # Unnamed series cycle through the Okabe–Ito colours, never matplotlib's tab10.
    "axes.prop_cycle": mpl.cycler(color=[OKABE_ITO[name] for name in (
        "blue", "orange", "bluish green", "vermillion", "sky blue", "reddish purple", "yellow", "black")]),
}

# Matplotlib writes a creation date and version into files unless told otherwise.
_PNG_METADATA = {"Software": None}
_PDF_METADATA = {"Creator": None, "Producer": None, "CreationDate": None, "ModDate": None}


#: Width (inches) at which a notebook shows a figure at 100 % zoom: a wider figure is shrunk to it.
DISPLAY_WIDTH_IN = 7.5

#: Smallest legible text (points) as displayed in a notebook.
MIN_FONT_PT = 8.0

#: Font size (points) of in-plot notes: numbers in heatmap cells, labels next to points.
ANNOTATION_FONT_PT = 8.0

#: Environment variable that marks an unattended (batch) run (the same as wsnlib.interactive's).
_BATCH_ENV_VAR = "WSNLIB_BATCH"


def use_style() -> None:
    """Apply the project's plot style to matplotlib's rcParams (call once per notebook)."""
    mpl.rcParams.update(_STYLE)


def savefig(fig: mpl.figure.Figure, name: str, formats: tuple[str, ...] = ("png", "pdf")) -> list[Path]:
    """Save ``fig`` as ``<figures>/<name>.<fmt>`` for each format, reproducibly.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    name : str
        File stem, e.g. ``"a01_fig02_humerus_pitch"``; letters, digits, ``_`` and ``-`` only.
    formats : tuple of str
        Any of ``"png"``, ``"pdf"`` (a single string is one format).  Every format is checked
        before anything is written; each file is written to a temporary file in the figures
        folder and renamed into place, so an interrupted save leaves the old file or none.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    ValueError
        A bad ``name`` or ``formats``; in the batch (``WSNLIB_BATCH=1``), also a text of ``fig``
        smaller than :data:`MIN_FONT_PT` as a notebook shows it (:func:`effective_font_sizes`),
        which interactively is a warning instead.  Nothing is written then.
    """
    if not name or not all(ch.isalnum() or ch in "_-" for ch in name):
        raise ValueError(f"name must be a plain file stem (letters, digits, _ or -), got {name!r}")
    if isinstance(formats, str):
        formats = (formats,)
    formats = tuple(formats)
    metadata = {"png": _PNG_METADATA, "pdf": _PDF_METADATA}
    bad = [fmt for fmt in formats if fmt not in metadata]
    if bad or not formats:  # checked before anything is written
        raise ValueError(f"formats may contain 'png' and 'pdf' (at least one), got {formats!r}")
    _check_legibility(fig, name)
    written = []
    for fmt in dict.fromkeys(formats):
        path = paths.figures() / f"{name}.{fmt}"
        with atomic_path(path) as tmp:  # a killed batch leaves the old figure or none, never half
            fig.savefig(tmp, format=fmt, metadata=metadata[fmt])
        written.append(path)
    return written


def effective_font_sizes(fig: mpl.figure.Figure, display_width_in: float = DISPLAY_WIDTH_IN) -> list[tuple[str, float]]:
    """Every visible, non-empty text of ``fig`` with its size (points) as shown in a notebook.

    A figure wider than ``display_width_in`` is shrunk to that width, and its texts with it:
    effective size = font size × min(1, display_width_in / figure width), the figure width
    being that of the saved image (``savefig.bbox: tight`` crops or extends the canvas).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    display_width_in : float
        Width of the notebook's output area, inches (:data:`DISPLAY_WIDTH_IN`).

    Returns
    -------
    list of (str, float)
        Text and effective size in points, smallest first.
    """
    if not display_width_in > 0:
        raise ValueError(f"display_width_in must be positive, got {display_width_in!r}")
    drawn = []
    original_draw = Text.draw

    def record(text, renderer):
        if text.get_visible() and text.get_text().strip():
            drawn.append(text)
        return original_draw(text, renderer)

    # Draw once, noting every text matplotlib actually draws (not hidden tick labels, axes
    # turned off, or tick labels outside the view).
    with unittest.mock.patch.object(Text, "draw", record):
        fig.draw_without_rendering()
    if mpl.rcParams["savefig.bbox"] == "tight":
        width_in = fig.get_tightbbox().width
    else:
        width_in = fig.get_size_inches()[0]
    scale = min(1.0, display_width_in / float(width_in))
    sizes = [(text.get_text(), float(text.get_fontsize()) * scale) for text in dict.fromkeys(drawn)]
    return sorted(sizes, key=lambda item: item[1])


def _too_small(fig: mpl.figure.Figure) -> list[tuple[str, float]]:
    return [(text, size) for text, size in effective_font_sizes(fig) if size < MIN_FONT_PT - 1e-9]


def _check_legibility(fig: mpl.figure.Figure, name: str) -> None:
    """Raise (in the batch) or warn (interactively) when a text of ``fig`` is below :data:`MIN_FONT_PT`."""
    small = _too_small(fig)
    if not small:
        return
    shown = ", ".join(f"{text!r} {size:.1f} pt" for text, size in small[:5])
    message = (f"figure {name!r}: {len(small)} text(s) smaller than {MIN_FONT_PT:g} pt at a notebook width of "
               f"{DISPLAY_WIDTH_IN:g} in ({shown}{', …' if len(small) > 5 else ''}); use larger fonts or a "
               "narrower figure")
    if os.environ.get(_BATCH_ENV_VAR) == "1":
        raise ValueError(message)
    warnings.warn(message, stacklevel=3)


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
    return [
        (float(time_s[s]), float(time_s[e]) if e < time_s.size else float(time_s[-1] + dt))
        for s, e in zip(starts, ends, strict=True)
    ]


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


def plot_heatmap(values, row_values, col_values, *, ax=None, xlabel="", ylabel="", title=None, fmt="{:.2g}",
                 cmap="viridis", xrotation=0):
    """Heatmap of a 2-D grid of results, each cell annotated with its value.

    Parameters
    ----------
    values : array_like, shape (n_rows, n_cols)
    row_values, col_values : sequence
        Values or names along rows (y axis) and columns (x axis), shown as tick labels.
    xrotation : float
        Rotation (degrees) of the column labels, for long names.
    fmt : str
        Format of the cell annotations.
    """
    ax = _axes(ax)
    values = np.asarray(values, dtype=float)
    if values.shape != (len(row_values), len(col_values)):
        raise ValueError(f"values has shape {values.shape}, expected ({len(row_values)}, {len(col_values)})")
    image = ax.imshow(values, origin="lower", aspect="auto", cmap=cmap)
    ax.set_xticks(range(len(col_values)), [_tick_label(v) for v in col_values], rotation=xrotation,
                  ha="right" if xrotation else "center")
    ax.set_yticks(range(len(row_values)), [_tick_label(v) for v in row_values])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(False)
    if title:
        ax.set_title(title)
    middle = np.nanmean(values)
    for (i, j), value in np.ndenumerate(values):
        ax.text(j, i, fmt.format(value), ha="center", va="center", fontsize=ANNOTATION_FONT_PT,
                color="white" if value < middle else "black")
    ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    return ax


def plot_heatmap_panels(panels, row_values, col_values, *, axes, xlabel="", ylabel="", fmt="{:.2g}",
                        cmap="viridis", colorbar_label=""):
    """Several heatmaps of the same grid on one shared colour scale, with one colour bar.

    Parameters
    ----------
    panels : mapping title → array_like, shape (n_rows, n_cols)
        One grid per panel, in the order of ``axes``; NaN cells are left blank.
    row_values, col_values : sequence
        Values along rows (y axis) and columns (x axis), shown as tick labels.
    axes : array of matplotlib.axes.Axes
        At least ``len(panels)`` axes of one figure; extra axes are hidden.
    fmt : str
        Format of the cell annotations.
    colorbar_label : str
        Label of the shared colour bar (quantity and unit).

    Returns
    -------
    matplotlib.colorbar.Colorbar
    """
    grids = {title: np.asarray(values, dtype=float) for title, values in panels.items()}
    flat_axes = np.asarray(axes).ravel()
    if len(grids) > flat_axes.size:
        raise ValueError(f"panels has {len(grids)} grids but axes only {flat_axes.size} axes")
    for title, values in grids.items():
        if values.shape != (len(row_values), len(col_values)):
            raise ValueError(f"panel {title!r} has shape {values.shape}, expected "
                             f"({len(row_values)}, {len(col_values)})")
    stacked = np.stack(list(grids.values()))
    if not np.isfinite(stacked).any():
        raise ValueError("panels hold no finite value")
    vmin, vmax = float(np.nanmin(stacked)), float(np.nanmax(stacked))
    middle = 0.5 * (vmin + vmax)
    image = None
    for ax, (title, values) in zip(flat_axes[:len(grids)], grids.items(), strict=True):
        image = ax.imshow(values, origin="lower", aspect="auto", cmap=cmap, vmin=vmin, vmax=vmax)
        ax.set_xticks(range(len(col_values)), [_tick_label(v) for v in col_values])
        ax.set_yticks(range(len(row_values)), [_tick_label(v) for v in row_values])
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(False)
        for (i, j), value in np.ndenumerate(values):
            if np.isfinite(value):
                ax.text(j, i, fmt.format(value), ha="center", va="center", fontsize=ANNOTATION_FONT_PT,
                        color="white" if value < middle else "black")
    for ax in flat_axes[len(grids):]:
        ax.set_visible(False)
    return flat_axes[0].figure.colorbar(image, ax=list(flat_axes[:len(grids)]), label=colorbar_label)


def _tick_label(value) -> str:
    return f"{value:g}" if isinstance(value, int | float | np.number) else str(value)


def plot_pareto(cost_x, cost_y, *, groups=None, front=None, knee=None, references=None, ax=None, xlabel="",
                ylabel="", logy=True):
    """Candidates in a two-cost plane, the Pareto front as a line, the knee and reference points marked.

    Parameters
    ----------
    cost_x, cost_y : array_like, shape (N,)
        Lower is better for both.
    groups : array_like of str, shape (N,), optional
        Group label per candidate (one colour per group).
    front : array_like of bool, shape (N,), optional
        Pareto mask (e.g. :func:`wsnlib.tuning.pareto_front`).
    knee : int, optional
        Index of the recommended candidate (star).
    references : dict[str, (float, float)], optional
        Named reference points (e.g. data fusion, single frame), drawn as crosses.
    """
    ax = _axes(ax)
    x = np.asarray(cost_x, dtype=float)
    y = np.asarray(cost_y, dtype=float)
    labels = np.asarray(groups) if groups is not None else np.full(x.shape, "candidates")
    for group in dict.fromkeys(labels):
        pick = labels == group
        ax.scatter(x[pick], y[pick], s=12, alpha=0.6, label=str(group))
    if front is not None:
        front = np.asarray(front, dtype=bool)
        order = np.argsort(x[front])
        ax.plot(x[front][order], y[front][order], color="black", lw=1.0, label="Pareto front")
    if knee is not None:
        ax.scatter([x[knee]], [y[knee]], marker="*", s=180, color="gold", edgecolor="black", zorder=5,
                   label="recommended (knee)")
    for name, (rx, ry) in (references or {}).items():
        ax.scatter([rx], [ry], marker="X", s=70, color=METHOD_COLORS.get(name, "grey"), edgecolor="black",
                   zorder=5, label=name)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(loc="best")
    return ax
