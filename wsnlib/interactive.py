"""Knobs a student can move: a live widget panel in Jupyter, a static figure in the batch.

:func:`explore` is the one entry point.  It holds no science: the caller passes a study of
wsnlib (``compute``, e.g. from :mod:`wsnlib.studies`) that recomputes a result for given knob
values and a function of :mod:`wsnlib.plotting` (``draw``) that draws it on a matplotlib Axes
— or a single ``draw(ax, **values)`` that does both.  This module only decides how the knobs
are shown:

* in a live kernel, an :class:`ipywidgets.interactive` panel — a slider or a drop-down per
  knob — whose output area is redrawn (``draw`` called again) whenever a knob moves; knob
  values the study refuses with ``ValueError`` (e.g. no anchor chosen) show its message in
  place of the panel;
* in the batch (:func:`wsnlib.paths.in_batch`: ``WSNLIB_BATCH=1``, set by :mod:`wsnlib.reproduce`
  for the kernel), a static small-multiples figure over a few knob settings, returned so the
  notebook can save it with :func:`wsnlib.plotting.savefig`.

A notebook cell therefore reads::

    view = interactive.explore(plotting.plot_burst_recovery, {"beta": [...], ...},
                               compute=functools.partial(burst_loss.burst_recovery, recording=...))
    if paths.in_batch():
        plotting.savefig(view, "a01_explore_beta")
    view

The figures are :class:`matplotlib.figure.Figure` objects not registered with pyplot, so
they are shown once (as the cell's value) and never left open behind the notebook's back.
"""

from __future__ import annotations

import numbers
import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from matplotlib.figure import Figure

from wsnlib import paths
from wsnlib._validation import check_count

#: Size (inches) of one panel of the static figure (narrower when ``ncols`` panels would be wider
#: than a notebook shows a figure, :data:`wsnlib.plotting.DISPLAY_WIDTH_IN`), and of the live figure.
PANEL_SIZE = (3.7, 2.7)
LIVE_SIZE = (7.0, 3.6)

_TITLE_WIDTH = 48  # characters per title line before wrapping
_SMALL_PT = 8.0  # panel titles and legends (wsnlib.plotting.MIN_FONT_PT)


@dataclass(frozen=True)
class _Knob:
    """One knob: its name, its choices (label, value) if known, its starting value, or a widget."""

    name: str
    choices: tuple[tuple[str, object], ...] | None  # None for a caller-made widget
    initial: object
    widget: object = None  # the caller's ipywidgets ValueWidget, if one was given

    @property
    def values(self) -> list:
        return [value for _, value in self.choices]

    def label(self, value) -> str:
        for label, choice in self.choices or ():
            if _same(choice, value):
                return label
        return _format(value)


def explore(draw: Callable, knobs: Mapping, *, compute: Callable | None = None, static=None, start=None,
            ncols: int = 2, sharey: bool = True):
    """Explore how a result changes with a few knobs: widgets live, a static figure in the batch.

    Parameters
    ----------
    draw : callable ``draw(result, ax=ax)``, or ``draw(ax, **values)`` without ``compute``
        Draws one panel on the matplotlib Axes ``ax``: the result ``compute`` returned for
        the knob values, or, without ``compute``, for the knob values ``values`` (one
        keyword per knob) — then it should recompute what it shows itself.  If it leaves the
        title empty, the knob values become the title.
    compute : callable ``compute(**values)``, optional
        Recomputes the result for the knob values (one keyword per knob), so that moving a
        knob reruns the wsnlib computation; keep it under a second.  Bind the data and fixed
        settings by keyword with :func:`functools.partial`.
    knobs : mapping of str to knob specification
        Knob name (a keyword of ``draw``) to one of

        * a list (or tuple, range, 1-D array) of values: a slider over them when they are
          increasing numbers, else a drop-down; it starts at the middle value of a slider and
          at the first value of a drop-down (see ``start``);
        * a dict label → value: a drop-down showing the labels, starting at the first;
        * an ipywidgets value widget (e.g. ``ipywidgets.SelectMultiple`` for a choice of
          several items), used as given; ``draw`` gets its ``value``.
    static : list of dict, optional
        The knob settings of the static figure (batch only), one panel each, in order.  A
        setting may leave knobs out: they take their starting value.  Values of list and
        dict knobs must be among the knob's values.  Default: for each knob in turn, its
        first, middle and last value (a widget: its value, and a numeric slider's min and
        max) with the other knobs at their starting values, repeated settings dropped.
    start : dict, optional
        Starting values of some list or dict knobs (e.g. the notebook's parameters), each
        among the knob's values; a widget starts at its own ``value``.
    ncols : int
        Panels per row of the static figure (two fit a notebook's width at full panel size).
    sharey : bool
        Share the y axis between the static panels (compare magnitudes at a glance); they
        always share the x axis.

    Returns
    -------
    matplotlib.figure.Figure or ipywidgets.interactive
        In the batch (:func:`wsnlib.paths.in_batch`): the static figure, one Axes per setting, with the
        legend of the first panel only (every panel draws the same series).  Otherwise the
        widget panel, not displayed (make it the cell's value to show it).

    Raises
    ------
    ValueError
        Bad knobs (empty, a name that is not an identifier, an empty or unusable
        specification), a bad ``static`` or ``start`` (empty, unknown knob, value not among
        the knob's values) or ``ncols`` < 1.
    TypeError
        ``draw`` or ``compute`` is not callable.
    """
    if not callable(draw):
        raise TypeError(f"draw must be callable as draw(ax, **values), got {type(draw).__name__}")
    if compute is not None:
        if not callable(compute):
            raise TypeError(f"compute must be callable as compute(**values), got {type(compute).__name__}")
        draw = _computed_panel(compute, draw)
    parsed = _with_start(_parse_knobs(knobs), start)
    check_count(ncols, "ncols")
    settings = _static_settings(parsed, static)
    if paths.in_batch():
        return _static_figure(draw, parsed, settings, int(ncols), sharey)
    return _live_panel(draw, parsed)


def _computed_panel(compute: Callable, plot: Callable) -> Callable:
    """``draw(ax, **values)`` that draws ``plot(compute(**values), ax=ax)``."""

    def draw(ax, **values):
        return plot(compute(**values), ax=ax)

    return draw


# --------------------------------------------------------------------------------------
# Knob specifications
# --------------------------------------------------------------------------------------


def _parse_knobs(knobs) -> list[_Knob]:
    if not isinstance(knobs, Mapping) or not knobs:
        raise ValueError(f"knobs must be a non-empty dict of knob name → values, got {knobs!r}")
    return [_parse_knob(name, spec) for name, spec in knobs.items()]


def _with_start(knobs: list[_Knob], start) -> list[_Knob]:
    if start is None:
        return knobs
    if not isinstance(start, Mapping):
        raise ValueError(f"start must be a dict of knob name → starting value, got {start!r}")
    by_name = {knob.name: knob for knob in knobs}
    unknown = set(start) - set(by_name)
    if unknown:
        raise ValueError(f"start names unknown knobs {sorted(map(str, unknown))}; knobs are {sorted(by_name)}")
    for name, value in start.items():
        knob = by_name[name]
        if knob.widget is not None:
            raise ValueError(f"knob {name!r} is a widget: set its value instead of start")
        _check_among(knob, value, "start")
        by_name[name] = replace(knob, initial=next(v for v in knob.values if _same(v, value)))
    return [by_name[knob.name] for knob in knobs]


def _check_among(knob: _Knob, value, what: str) -> None:
    if knob.choices is not None and not any(_same(value, v) for v in knob.values):
        raise ValueError(f"{what} value {value!r} of knob {knob.name!r} is not among its values {knob.values!r}")


def _parse_knob(name, spec) -> _Knob:
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"knob names must be Python identifiers (keywords of draw), got {name!r}")
    if _is_widget(spec):
        return _Knob(name, None, spec.value, widget=spec)
    if isinstance(spec, Mapping):
        if not spec:
            raise ValueError(f"knob {name!r}: the dict of label → value is empty")
        choices = tuple((str(label), value) for label, value in spec.items())
        return _Knob(name, choices, choices[0][1])
    if isinstance(spec, np.ndarray):
        if spec.ndim != 1:
            raise ValueError(f"knob {name!r}: an array of values must be 1-D, got shape {spec.shape}")
        spec = spec.tolist()
    if isinstance(spec, str | bytes) or not isinstance(spec, Sequence | range):
        raise ValueError(f"knob {name!r}: expected a list of values, a dict label → value or an ipywidgets "
                         f"value widget, got {spec!r}")
    values = list(spec)
    if not values:
        raise ValueError(f"knob {name!r} has no values")
    for i, value in enumerate(values):
        if any(_same(value, other) for other in values[:i]):
            raise ValueError(f"knob {name!r} lists the value {value!r} twice")
    choices = tuple((_format(value), value) for value in values)
    initial = values[len(values) // 2] if _is_numeric_ramp(values) else values[0]
    return _Knob(name, choices, initial)


def _is_widget(spec) -> bool:
    """An ipywidgets value widget (imported only when ipywidgets is already loaded or needed)."""
    if not hasattr(spec, "observe") or not hasattr(spec, "value"):
        return False
    from ipywidgets import ValueWidget

    return isinstance(spec, ValueWidget)


def _is_numeric_ramp(values) -> bool:
    """Two or more real numbers (not booleans), strictly increasing: a slider's values."""
    numeric = all(isinstance(v, numbers.Real) and not isinstance(v, bool | np.bool_) for v in values)
    return numeric and len(values) >= 2 and all(a < b for a, b in zip(values, values[1:], strict=False))


def _same(a, b) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object)))
    except (TypeError, ValueError):
        return a == b


def _format(value) -> str:
    if isinstance(value, bool | np.bool_):
        return str(bool(value))
    if isinstance(value, numbers.Real):
        return f"{value:g}"
    if isinstance(value, tuple | list | np.ndarray):
        return ",".join(_format(v) for v in value) if len(value) else "(none)"
    return str(value)


# --------------------------------------------------------------------------------------
# Static settings and figure (batch)
# --------------------------------------------------------------------------------------


def _few_values(knob: _Knob) -> list:
    if knob.widget is None:
        values = knob.values
        return [values[0], values[len(values) // 2], values[-1]]
    widget = knob.widget
    low, high = getattr(widget, "min", None), getattr(widget, "max", None)
    if isinstance(low, numbers.Real) and isinstance(high, numbers.Real) and isinstance(widget.value, numbers.Real):
        return [low, widget.value, high]
    return [widget.value]


def _static_settings(knobs: list[_Knob], static) -> list[dict]:
    baseline = {knob.name: knob.initial for knob in knobs}
    if static is None:
        settings = []
        for knob in knobs:
            for value in _few_values(knob):
                setting = {**baseline, knob.name: value}
                if not any(all(_same(setting[k], s[k]) for k in setting) for s in settings):
                    settings.append(setting)
        return settings
    if isinstance(static, Mapping) or not isinstance(static, Sequence) or not static:
        raise ValueError(f"static must be a non-empty list of dicts of knob values, got {static!r}")
    by_name = {knob.name: knob for knob in knobs}
    settings = []
    for entry in static:
        if not isinstance(entry, Mapping):
            raise ValueError(f"each static setting must be a dict of knob values, got {entry!r}")
        unknown = set(entry) - set(by_name)
        if unknown:
            raise ValueError(f"static setting {dict(entry)!r} names unknown knobs {sorted(map(str, unknown))}; "
                             f"knobs are {sorted(by_name)}")
        for name, value in entry.items():
            _check_among(by_name[name], value, "static")
        settings.append({**baseline, **entry})
    return settings


def _title(knobs: list[_Knob], values: dict) -> str:
    text = ", ".join(f"{knob.name}={knob.label(values[knob.name])}" for knob in knobs)
    return "\n".join(textwrap.wrap(text, _TITLE_WIDTH))


def _draw_panel(draw, knobs, ax, values) -> None:
    draw(ax, **values)
    if not ax.get_title():
        ax.set_title(_title(knobs, values), fontsize=_SMALL_PT)


def _static_figure(draw, knobs, settings, ncols, sharey) -> Figure:
    ncols = min(ncols, len(settings))
    nrows = -(-len(settings) // ncols)
    from wsnlib.plotting import DISPLAY_WIDTH_IN

    # No wider than a notebook shows it, so that its texts are not shrunk below legibility.
    panel_width = min(PANEL_SIZE[0], DISPLAY_WIDTH_IN / ncols)
    fig = Figure(figsize=(panel_width * ncols, PANEL_SIZE[1] * nrows), layout="constrained")
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=sharey, squeeze=False).ravel()
    for ax in axes[len(settings):]:
        fig.delaxes(ax)
    n_panels = len(settings)
    for i, (ax, values) in enumerate(zip(axes, settings, strict=False)):
        _draw_panel(draw, knobs, ax, values)
        legend = ax.get_legend()
        if legend is not None:
            if i:
                legend.remove()
            else:
                for text in legend.get_texts():
                    text.set_fontsize(_SMALL_PT)
        # Axis labels on the outer panels only: the bottom panel of each column (rows may be
        # incomplete) and, with a shared y axis, the first column.
        has_panel_below = i + ncols < n_panels
        ax.tick_params(labelbottom=not has_panel_below)
        if has_panel_below:
            ax.set_xlabel("")
        if sharey and i % ncols:
            ax.tick_params(labelleft=False)
            ax.set_ylabel("")
    return fig


# --------------------------------------------------------------------------------------
# Live panel (Jupyter)
# --------------------------------------------------------------------------------------


def _widget(knob: _Knob):
    import ipywidgets

    if knob.widget is not None:
        return knob.widget
    style = {"description_width": "initial"}
    if _is_numeric_ramp(knob.values):
        return ipywidgets.SelectionSlider(options=list(knob.choices), value=knob.initial, description=knob.name,
                                          continuous_update=False, style=style, layout=ipywidgets.Layout(width="28em"))
    return ipywidgets.Dropdown(options=list(knob.choices), value=knob.initial, description=knob.name, style=style)


def _live_panel(draw, knobs):
    import ipywidgets
    from IPython.display import display

    def redraw(**values):
        fig = Figure(figsize=LIVE_SIZE, layout="constrained")
        ax = fig.subplots()
        try:
            _draw_panel(draw, knobs, ax, values)
        except ValueError as error:  # knob values the study refuses (e.g. no anchor chosen): say so
            ax.clear()
            ax.set_axis_off()
            ax.text(0.5, 0.5, "\n".join(textwrap.wrap(str(error), _TITLE_WIDTH)), transform=ax.transAxes,
                    ha="center", va="center")
        display(fig)

    return ipywidgets.interactive(redraw, **{knob.name: _widget(knob) for knob in knobs})
