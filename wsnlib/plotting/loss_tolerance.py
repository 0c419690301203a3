"""Figures of the loss-tolerance study (notebook 10, :mod:`wsnlib.studies.loss_tolerance`).

The study's methods get their colours and markers in :mod:`wsnlib.plotting.style`.
"""

from __future__ import annotations

import matplotlib as mpl
import numpy as np

from wsnlib.plotting.style import METHOD_COLORS, OKABE_ITO, method_style
from wsnlib.plotting.traces import loss_spans


def plot_error_vs_loss_rate(loss_rates, bands, groups, *, axes, ylabel="total RMSE (°)", logy=True):
    """Mean error against loss rate per method, with its interval as a band; one panel per group.

    Parameters
    ----------
    loss_rates : mapping profile → loss rate (fraction)
        The x positions, in plotting order (e.g. lossless 0, GE 5 % 0.05, …).
    bands : pandas.DataFrame
        Index ``(profile, method)``; columns ``mean``, ``ci_low``, ``ci_high`` (same unit as the
        y axis), e.g. from :func:`wsnlib.studies.loss_tolerance_summary.summary_table`.
    groups : mapping title → list of method names
        One panel per entry (few lines each); methods need a colour in :data:`METHOD_COLORS`.
    axes : sequence of matplotlib Axes
        As many as ``groups``.
    """
    if len(axes) != len(groups):
        raise ValueError(f"axes must hold one Axes per group ({len(groups)}), got {len(axes)}")
    profiles = list(loss_rates)
    x = 100.0 * np.asarray([loss_rates[p] for p in profiles], dtype=float)
    for ax, (title, methods) in zip(axes, groups.items(), strict=True):
        colors = _distinct_colors(methods)
        for method in methods:
            rows = bands.loc[[(p, method) for p in profiles]]
            ax.fill_between(x, rows["ci_low"], rows["ci_high"], color=colors[method], alpha=0.15, lw=0)
            ax.plot(x, rows["mean"], **method_style(method, ms=5, color=colors[method]))
        ax.set_title(title)
        ax.set_xlabel("packets lost (%)")
        if logy:
            ax.set_yscale("log")
        ax.legend(fontsize=8, loc="upper left")
    axes[0].set_ylabel(ylabel)
    return axes


def _distinct_colors(methods) -> dict[str, str]:
    """A colour per method for lines that sit together in one panel: each method's own colour
    (:data:`METHOD_COLORS`), except that a method whose colour an earlier one already took (a
    variant shares its base method's colour) gets the first Okabe–Ito colour not yet in the panel
    (never grey or yellow, which are hard to see as lines).  Markers still tell the variants apart."""
    spare = [OKABE_ITO[name] for name in ("blue", "orange", "bluish green", "vermillion", "sky blue",
                                          "reddish purple", "black")]
    taken, out = set(), {}
    for method in methods:
        color = METHOD_COLORS[method]
        if color in taken:
            free = [c for c in spare if c not in taken and c not in {METHOD_COLORS[m] for m in methods}]
            free = free or [c for c in spare if c not in taken]
            if not free:
                raise ValueError(f"more methods in one panel than distinct colours: {list(methods)}")
            color = free[0]
        taken.add(color)
        out[method] = color
    return out


def plot_burst_traces(time_s, errors, received, *, ax, title=None, reference=None):
    """Error traces of several methods around a loss burst, lost samples shaded.

    Parameters
    ----------
    time_s : array_like, shape (T,)
    errors : mapping method → array_like (T,)
        Error (°) per sample; NaN (no reference) leaves a gap in the line.
    received : array_like of bool, shape (T,)
    ax : matplotlib Axes
    title : str, optional
    reference : (label, array_like (T,)), optional
        A context trace drawn thin and dotted in grey (e.g. a method without loss).
    """
    for start, end in loss_spans(time_s, received):
        ax.axvspan(start, end, color="0.85", lw=0, label=None)
    if reference is not None:
        label, trace = reference
        ax.plot(time_s, trace, color=OKABE_ITO["grey"], ls=":", lw=1.0, label=label)
    colors = _distinct_colors(list(errors))
    for method, trace in errors.items():
        ax.plot(time_s, trace, **method_style(method, marker="", lw=1.3, color=colors[method]))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("total error (°)")
    if title:
        ax.set_title(title)
    return ax


def plot_per_trial_dots(values, bands, *, ax, xlabel, logx=True):
    """One dot per trial and method, with each method's mean and its interval as a bar.

    Parameters
    ----------
    values : pandas.DataFrame
        Rows = trials, columns = methods (each with a colour in :data:`METHOD_COLORS`).
    bands : pandas.DataFrame
        Index = methods; columns ``mean``, ``ci_low``, ``ci_high``.
    ax : matplotlib Axes
    xlabel : str
    """
    offsets = np.linspace(-0.3, 0.3, len(values)) if len(values) > 1 else np.zeros(1)
    methods = list(values.columns)
    for row, method in enumerate(methods):
        ax.plot(values[method].to_numpy(), row + offsets, **method_style(method, ls="none", ms=4, alpha=0.7,
                                                                          label=None))
        band = bands.loc[method]
        ax.errorbar(band["mean"], row, xerr=[[band["mean"] - band["ci_low"]], [band["ci_high"] - band["mean"]]],
                    fmt="|", color="black", ms=14, capsize=3, lw=1.2)
    ax.set_yticks(range(len(methods)), methods)
    ax.invert_yaxis()
    if logx:
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(mpl.ticker.ScalarFormatter())
    ax.set_xlabel(xlabel)
    return ax
