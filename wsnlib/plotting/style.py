"""Plot style, palette and figure saving shared by every notebook.

:func:`use_style` must be called explicitly (importing this module changes nothing global).
:func:`savefig` is the one way figures are written: PNG and PDF into the figures folder with
fixed metadata, so that running the batch twice gives byte-identical files.

The palette (:data:`OKABE_ITO`, :data:`METHOD_COLORS`, :data:`METHOD_MARKERS`) lives here and
only here: every figure module of :mod:`wsnlib.plotting` reads these same dictionaries.

Legibility: every text of a saved figure must be at least :data:`MIN_FONT_PT` tall as a student
sees it in a notebook, where a figure wider than :data:`DISPLAY_WIDTH_IN` is shrunk to that
width (:func:`effective_font_sizes`).  :func:`savefig` checks it: in the batch
(``WSNLIB_BATCH=1``) a too-small text is a ``ValueError``, interactively a warning.
"""

from __future__ import annotations

import contextlib
import unittest.mock
from pathlib import Path

import matplotlib as mpl
import numpy as np
from matplotlib.scale import LogScale
from matplotlib.text import Text

from wsnlib import paths
from wsnlib._files import atomic_path
from wsnlib._user_warnings import warn_user

#: The Okabe–Ito palette (colour-blind safe): the only colours of the notebooks' figures, plus
#: ``"grey"`` for references and context.  :func:`use_style` makes it matplotlib's colour cycle.
OKABE_ITO = {"blue": "#0072B2", "orange": "#E69F00", "bluish green": "#009E73", "vermillion": "#D55E00",
             "sky blue": "#56B4E9", "reddish purple": "#CC79A7", "yellow": "#F0E442", "black": "#000000",
             "grey": "#999999"}

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

#: Colours and markers of the loss-tolerance study's methods (:mod:`wsnlib.studies.loss_tolerance`);
#: ``hold_last``, ``gyro_interpolation`` and the peers keep notebook 05's.
METHOD_COLORS.update({"constant_rate": OKABE_ITO["sky blue"], "hybrid (feedback)": OKABE_ITO["bluish green"],
                      "Kalman": OKABE_ITO["vermillion"], "smoother": OKABE_ITO["reddish purple"],
                      "VQF (defaults)": OKABE_ITO["black"]})
# Variants keep their base method's colour and differ in marker.
METHOD_COLORS.update({"gated hybrid (feedback)": METHOD_COLORS["hybrid (feedback)"],
                      "Fusion + gated hybrid (feedback)": METHOD_COLORS["Fusion + hybrid (feedback)"],
                      "Fusion, constant rate": METHOD_COLORS["Fusion"], "VQF, constant rate": METHOD_COLORS["VQF"],
                      "offline VQF": METHOD_COLORS["VQF"], "VQF forward-backward": METHOD_COLORS["VQF"],
                      "RIANN": OKABE_ITO["yellow"], "Fusion, AR + replay": METHOD_COLORS["Fusion"],
                      "VQF, AR + replay": METHOD_COLORS["VQF"], "Kalman, hold": METHOD_COLORS["Kalman"],
                      "Kalman, constant rate": METHOD_COLORS["Kalman"], "Kalman, AR": METHOD_COLORS["Kalman"],
                      "Fusion, AR": METHOD_COLORS["Fusion"], "VQF, AR": METHOD_COLORS["VQF"],
                      "Fusion (defaults)": METHOD_COLORS["Fusion"],
                      "Fusion (defaults), constant rate": METHOD_COLORS["Fusion"],
                      "VQF (defaults), constant rate": METHOD_COLORS["VQF"],
                      "Madgwick, AR": METHOD_COLORS["hold_last"], "Madgwick, AR + replay": METHOD_COLORS["hold_last"],
                      "Kalman, design in fold": METHOD_COLORS["Kalman"],
                      "smoother, design in fold": METHOD_COLORS["smoother"]})
METHOD_MARKERS.update({"constant_rate": ">", "hybrid (feedback)": "D", "Kalman": "*", "smoother": "P",
                       "VQF (defaults)": "X"})
METHOD_MARKERS.update({"gated hybrid (feedback)": "d", "Fusion + gated hybrid (feedback)": "H",
                       "Fusion, constant rate": "1", "VQF, constant rate": "2", "offline VQF": "<",
                       "VQF forward-backward": "8", "RIANN": "p", "Fusion, AR + replay": "3",
                       "VQF, AR + replay": "4", "Kalman, hold": "o", "Kalman, constant rate": ">", "Kalman, AR": "s",
                       "Fusion, AR": "s", "VQF, AR": "s", "Fusion (defaults)": "X",
                       "Fusion (defaults), constant rate": "x", "VQF (defaults), constant rate": "x",
                       "Madgwick, AR": "s", "Madgwick, AR + replay": "4", "Kalman, design in fold": "v",
                       "smoother, design in fold": "^"})


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



def use_style() -> None:
    """Apply the project's plot style (call once per notebook): matplotlib's rcParams, and log axes
    labelled with plain numbers (:class:`PlainLogScale`)."""
    mpl.rcParams.update(_STYLE)
    mpl.scale.register_scale(PlainLogScale)


def plain_number(value: float) -> str:
    """``value`` as a plain decimal number, at most 3 significant digits: 0.02, 6, 60, 20000 (never 6×10¹)."""
    return np.format_float_positional(float(value), precision=3, unique=True, fractional=False, trim="-")


class PlainLogFormatter(mpl.ticker.LogFormatter):
    """Matplotlib's log-axis labels (the same ticks get a label) written as plain numbers (:func:`plain_number`)."""

    def _num_to_string(self, x, vmin, vmax):
        return plain_number(x)


class PlainLogScale(LogScale):
    """Matplotlib's ``"log"`` scale with :class:`PlainLogFormatter` on its major and minor ticks.

    :func:`use_style` registers it under the name ``"log"``, so every log axis drawn afterwards —
    ``set_yscale("log")`` in a notebook, pandas' ``logy``, the helpers of :mod:`wsnlib.plotting` —
    reads "60", not "6×10¹".
    """

    def __init__(self, *, base=10, subs=None, nonpositive="clip"):   # no ``axis``: matplotlib ≥ 3.11's signature
        super().__init__(None, base=base, subs=subs, nonpositive=nonpositive)

    def set_default_locators_and_formatters(self, axis):
        super().set_default_locators_and_formatters(axis)
        axis.set_major_formatter(PlainLogFormatter(self.base))
        axis.set_minor_formatter(PlainLogFormatter(self.base, labelOnlyBase=self.subs is not None))


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

    The figure is laid out once (its layout engine runs, at ``savefig.dpi``) and cropped to one
    tight box (``savefig.bbox: tight``, padded by ``savefig.pad_inches``); every file is drawn
    from that layout, once.  Matplotlib's own ``savefig`` lays the figure out and measures its
    tight box anew for each file; the PNG is the same bytes.  ``fig`` keeps its layout engine and
    dpi.  In a notebook (the inline backend), the cell shows the saved PNG file rather than a
    drawing of ``fig`` made again after the cell (:func:`_show_saved_png`).

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
    # One layout and one tight box for every format (matplotlib's savefig would redo both per file).
    with _laid_out_once(fig, mpl.rcParams["savefig.dpi"]) as (drawn, tight):
        _check_legibility(fig, name, drawn, tight.width)  # before anything is written
        box = tight.padded(mpl.rcParams["savefig.pad_inches"]) if mpl.rcParams["savefig.bbox"] == "tight" else None
        written = []
        for fmt in dict.fromkeys(formats):
            path = paths.figures() / f"{name}.{fmt}"
            with atomic_path(path) as tmp:  # a killed batch leaves the old figure or none, never half
                fig.savefig(tmp, format=fmt, metadata=metadata[fmt], bbox_inches=box)
            written.append(path)
    if "png" in formats:
        _show_saved_png(fig, paths.figures() / f"{name}.png", box.width if box is not None else fig.get_figwidth())
    return written


def _show_saved_png(fig: mpl.figure.Figure, png: Path, width_in: float) -> None:
    """In a notebook, show the saved PNG file instead of letting the inline backend draw ``fig`` again.

    The inline backend draws every pyplot figure made in a cell once more after the cell (a PNG at
    the figure's dpi, ``bbox_inches="tight"``), a whole drawing more.  Here the
    saved file itself is shown, at the width that drawing would have had (``width_in`` × the
    figure's dpi, in pixels), and pyplot forgets the figure, so the backend does not draw it.  So a
    notebook shows exactly what ``figures/`` holds.  Elsewhere (another backend, no IPython, a
    figure pyplot does not manage, such as :func:`wsnlib.interactive.explore`'s static figure,
    which its cell shows as its value) nothing changes.
    """
    if fig.canvas.manager is None or "backend_inline" not in mpl.get_backend():
        return
    from IPython import get_ipython
    from IPython.display import Image, display
    from matplotlib import pyplot as plt

    if get_ipython() is None:
        return
    display(Image(data=png.read_bytes(), format="png", width=round(width_in * fig.dpi)))
    plt.close(fig)


@contextlib.contextmanager
def _laid_out_once(fig: mpl.figure.Figure, dpi):
    """Lay ``fig`` out once at ``dpi`` (``"figure"``: its own; its layout engine runs), then yield
    ``(drawn, tight)``: the texts that drawing drew and the figure's tight bounding box (inches,
    unpadded), with the layout engine switched off meanwhile, so that each save inside draws the
    laid-out figure once.  The figure gets its engine back afterwards (a notebook shows it laid out
    again, as before).

    These are the steps of matplotlib's ``savefig`` (``bbox_inches="tight"``), taken once rather
    than once per file: its PNG file comes out the same bytes.
    """
    engine, manager, original_dpi = fig.get_layout_engine(), fig.canvas.manager, fig.dpi
    fig.canvas.manager = None  # as savefig does: a window, if any, keeps its size
    try:
        if dpi != "figure":
            fig.dpi = dpi
        with _drawn_texts() as drawn:
            fig.draw_without_rendering()  # runs the layout engine
        tight = fig.get_tightbbox()
        fig.dpi = original_dpi
        # No engine (not even a placeholder, which would make savefig draw once more to no effect).
        with mpl.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
            fig.set_layout_engine(None)
        yield drawn, tight
    finally:
        fig.dpi = original_dpi
        if fig.get_layout_engine() is not engine:
            fig.set_layout_engine(engine)
        fig.canvas.manager = manager


@contextlib.contextmanager
def _drawn_texts():
    """Yield a list that collects every visible, non-empty text matplotlib draws meanwhile (not
    hidden tick labels, axes turned off, or tick labels outside the view)."""
    drawn = []
    original_draw = Text.draw

    def record(text, renderer):
        if text.get_visible() and text.get_text().strip():
            drawn.append(text)
        return original_draw(text, renderer)

    with unittest.mock.patch.object(Text, "draw", record):
        yield drawn


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
    with _drawn_texts() as drawn:
        fig.draw_without_rendering()
    return _shown_sizes(fig, drawn, display_width_in)


def _shown_sizes(fig: mpl.figure.Figure, drawn: list[Text], display_width_in: float,
                 tight_width_in: float | None = None) -> list[tuple[str, float]]:
    """:func:`effective_font_sizes` of the texts ``drawn`` in a drawing of ``fig`` just made
    (``tight_width_in``: the width of its tight bounding box, if known)."""
    if mpl.rcParams["savefig.bbox"] == "tight":
        width_in = fig.get_tightbbox().width if tight_width_in is None else tight_width_in
    else:
        width_in = fig.get_size_inches()[0]
    scale = min(1.0, display_width_in / float(width_in))
    sizes = [(text.get_text(), float(text.get_fontsize()) * scale) for text in dict.fromkeys(drawn)]
    return sorted(sizes, key=lambda item: item[1])


def _check_legibility(fig: mpl.figure.Figure, name: str, drawn: list[Text], tight_width_in: float) -> None:
    """Raise (in the batch) or warn (interactively) when a text of ``fig`` (``drawn``: the texts its
    last drawing drew; ``tight_width_in``: its tight width) is below :data:`MIN_FONT_PT`."""
    sizes = _shown_sizes(fig, drawn, DISPLAY_WIDTH_IN, tight_width_in)
    small = [(text, size) for text, size in sizes if size < MIN_FONT_PT - 1e-9]
    if not small:
        return
    shown = ", ".join(f"{text!r} {size:.1f} pt" for text, size in small[:5])
    message = (f"figure {name!r}: {len(small)} text(s) smaller than {MIN_FONT_PT:g} pt at a notebook width of "
               f"{DISPLAY_WIDTH_IN:g} in ({shown}{', …' if len(small) > 5 else ''}); use larger fonts or a "
               "narrower figure")
    if paths.in_batch():
        raise ValueError(message)
    warn_user(message)
