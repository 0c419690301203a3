"""Notebook 04's figure: the loss options' error against their smoothness, one line per option over loss rates."""

from __future__ import annotations

from wsnlib.plotting.style import ANNOTATION_FONT_PT, method_style


def plot_option_tradeoffs(results, *, axes, error_columns, smoothness_columns: dict):
    """Each option's mean error against its mean smoothness cost, one line over the loss rates.

    Parameters
    ----------
    results : pandas.DataFrame
        One row per (option, loss rate): columns ``option``, ``loss rate`` and the figures named
        below (e.g. :func:`wsnlib.studies.loss_alternatives.option_figures`); rows of rate 0 are
        left out (without loss the Madgwick-based options are one filter and have no gap end).
        Every option needs a colour in :data:`wsnlib.plotting.METHOD_COLORS`.
    axes : 2-D array of matplotlib Axes
        ``len(smoothness_columns)`` rows × ``len(error_columns)`` columns, x shared per column and
        y per row (e.g. ``plt.subplots(2, 2, sharex="col", sharey="row")``).
    error_columns : sequence of str
        Figures on the x axes, one per column (their names label the axes).
    smoothness_columns : dict column → label
        Figures on the (log) y axes, one per row.

    Returns
    -------
    The axes; each line's last point is labelled with its loss rate.
    """
    if axes.shape != (len(smoothness_columns), len(error_columns)):
        raise ValueError(f"axes must be {len(smoothness_columns)} × {len(error_columns)}, got {axes.shape}")
    lossy = results[results["loss rate"] > 0]
    if lossy.empty:
        raise ValueError("results hold no loss rate above 0")
    for row, (smoothness_column, smoothness_label) in zip(axes, smoothness_columns.items(), strict=True):
        for ax, error_column in zip(row, error_columns, strict=True):
            for name, group in lossy.groupby("option", sort=False):
                ax.plot(group[error_column], group[smoothness_column], "-", ms=4, **method_style(name))
                ax.annotate(f"{group['loss rate'].iloc[-1]:.0%}",
                            (group[error_column].iloc[-1], group[smoothness_column].iloc[-1]),
                            fontsize=ANNOTATION_FONT_PT, xytext=(3, 3), textcoords="offset points")
            ax.set_yscale("log")
        row[0].set_ylabel(smoothness_label)
    for ax, error_column in zip(axes[-1], error_columns, strict=True):
        ax.set_xlabel(error_column)
    return axes
