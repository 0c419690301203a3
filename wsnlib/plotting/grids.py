"""Grids and trade-off planes of parameter searches: annotated heatmaps and Pareto fronts."""

from __future__ import annotations

import numpy as np

from wsnlib.plotting.style import ANNOTATION_FONT_PT, METHOD_COLORS
from wsnlib.plotting.traces import _axes


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
    image = _annotated_image(ax, values, row_values, col_values, xlabel=xlabel, ylabel=ylabel, title=title, fmt=fmt,
                             middle=np.nanmean(values), blank_nan=False, xrotation=xrotation, cmap=cmap)
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
    image = None
    for ax, (title, values) in zip(flat_axes[:len(grids)], grids.items(), strict=True):
        image = _annotated_image(ax, values, row_values, col_values, xlabel=xlabel, ylabel=ylabel, title=title,
                                 fmt=fmt, middle=0.5 * (vmin + vmax), blank_nan=True, cmap=cmap, vmin=vmin, vmax=vmax)
    for ax in flat_axes[len(grids):]:
        ax.set_visible(False)
    return flat_axes[0].figure.colorbar(image, ax=list(flat_axes[:len(grids)]), label=colorbar_label)


def _annotated_image(ax, values, row_values, col_values, *, xlabel, ylabel, title, fmt, middle, blank_nan,
                     xrotation=0, **imshow):
    """``values`` as an image on ``ax`` (``imshow`` keywords: colour map and scale), ticks labelled
    with the row and column values, every cell annotated (NaN cells left blank with ``blank_nan``)
    in white below ``middle`` and in black above; returns the image."""
    image = ax.imshow(values, origin="lower", aspect="auto", **imshow)
    ax.set_xticks(range(len(col_values)), [_tick_label(v) for v in col_values], rotation=xrotation,
                  ha="right" if xrotation else "center")
    ax.set_yticks(range(len(row_values)), [_tick_label(v) for v in row_values])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(False)
    if title:
        ax.set_title(title)
    for (i, j), value in np.ndenumerate(values):
        if np.isfinite(value) or not blank_nan:
            ax.text(j, i, fmt.format(value), ha="center", va="center", fontsize=ANNOTATION_FONT_PT,
                    color="white" if value < middle else "black")
    return image


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
