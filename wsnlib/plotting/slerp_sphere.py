"""Paper 001, Fig. 5: spherical linear interpolation drawn on the unit sphere, for students.

An orientation is drawn as the tip of one body axis on the unit sphere (default the body x axis,
which points along the arm segment: the tip is where the segment points, ENU).  The SLERP path
between single frame's and data fusion's orientation (eq. (2), computed by
:func:`wsnlib.quaternion.slerp`) is a curve on the sphere, and the hybrid's output for a weight μ
(eqs. (3)–(4)) is one point of it.  The tip shows two of the rotation's three degrees of freedom
(a turn about the axis itself does not move it).
"""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion
from wsnlib.metrics import SEGMENT_AXIS
from wsnlib.plotting.style import ANNOTATION_FONT_PT, METHOD_COLORS

__all__ = ["slerp_tips", "plot_slerp_on_sphere"]


def slerp_tips(q_single, q_fusion, mu, axis=SEGMENT_AXIS) -> np.ndarray:
    """Tips of ``axis`` (unit sphere, ENU) along SLERP(q_single, q_fusion, μ), eq. (4) of paper 001.

    Parameters
    ----------
    q_single, q_fusion : array_like, shape (4,)
        Unit quaternions [w, x, y, z], body → ENU: μ = 0 gives single frame, μ = 1 data fusion.
    mu : array_like, shape (N,)
        Weights in [0, 1].
    axis : array_like, shape (3,)
        Body-frame axis whose tip is drawn.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
    """
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    q = quaternion.slerp(np.broadcast_to(q_single, mu.shape + (4,)), np.broadcast_to(q_fusion, mu.shape + (4,)), mu)
    tips = quaternion.rotate(q, np.asarray(axis, dtype=float))
    return tips / np.linalg.norm(tips, axis=-1, keepdims=True)


def _sphere_patch(ax, centre, half_width, n_lines=9, n_points=40):
    """Grid lines of the unit sphere around ``centre``: ``n_lines`` in each of two directions."""
    e1 = np.cross(centre, [0.0, 0.0, 1.0])
    if np.linalg.norm(e1) < 1e-6:
        e1 = np.cross(centre, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(centre, e1)
    steps = np.linspace(-half_width, half_width, n_lines)
    along = np.linspace(-half_width, half_width, n_points)
    for a, b in ((e1, e2), (e2, e1)):
        for s in steps:
            points = centre + s * a + along[:, None] * b
            points /= np.linalg.norm(points, axis=-1, keepdims=True)
            ax.plot(*points.T, color="0.8", lw=0.6)


def plot_slerp_on_sphere(q_single, q_fusion, mus, *, ax, zoom: bool = False, mu_marked=None, axis=SEGMENT_AXIS,
                         title=None):
    """SLERP from single frame to data fusion on the unit sphere, the points for ``mus`` labelled.

    Parameters
    ----------
    q_single, q_fusion : array_like, shape (4,)
        Unit quaternions [w, x, y, z], body → ENU (e.g. TRIAD's and Madgwick's estimates of one
        sample).
    mus : sequence of float
        Weights in [0, 1] drawn as labelled dots (μ = 0 is single frame, μ = 1 data fusion).
    ax : matplotlib 3-D Axes
        ``fig.add_subplot(projection="3d")``.
    zoom : bool
        False: the whole sphere (a wire frame, ENU axes) with the path and the segment drawn from
        the centre to the first and last tip of ``mus``; True: a patch of the sphere around the
        path, seen from outside, with every μ labelled.
    mu_marked : (float, str), optional
        One more weight drawn as a star with its label (e.g. the hybrid's μ at this sample).
    axis : array_like, shape (3,)
        Body-frame axis whose tip is drawn (default the segment axis).
    title : str, optional

    Returns
    -------
    The Axes.
    """
    mus = np.asarray(mus, dtype=float)
    path = slerp_tips(q_single, q_fusion, np.linspace(0.0, 1.0, 101), axis)
    points = slerp_tips(q_single, q_fusion, mus, axis)
    centre = path[50] / np.linalg.norm(path[50])
    elevation = float(np.degrees(np.arcsin(np.clip(centre[2], -1.0, 1.0))))
    azimuth = float(np.degrees(np.arctan2(centre[1], centre[0])))
    if zoom:   # a patch of the sphere seen from outside, a little from the side so that it curves
        half_width = max(1.6 * float(np.max(np.linalg.norm(path - centre, axis=-1))), 0.05)
        _sphere_patch(ax, centre, half_width)
        low, high = centre - half_width, centre + half_width
        ax.set(xlim=(low[0], high[0]), ylim=(low[1], high[1]), zlim=(low[2], high[2]))
        ax.view_init(elev=float(np.clip(elevation + 20.0, -89.0, 89.0)), azim=azimuth + 20.0)
        ax.set_axis_off()
    else:      # the whole sphere, the segment drawn from the centre to each estimate's tip
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
        ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", lw=0.5)
        for tip, name in ((points[0], "single frame"), (points[-1], "data fusion")):
            ax.plot([0.0, tip[0]], [0.0, tip[1]], [0.0, tip[2]], color=METHOD_COLORS[name], lw=1.0)
        ax.set(xlim=(-1, 1), ylim=(-1, 1), zlim=(-1, 1), xticks=[-1, 0, 1], yticks=[-1, 0, 1], zticks=[-1, 0, 1])
        ax.view_init(elev=15.0, azim=azimuth - 60.0)
        ax.set_xlabel("east")
        ax.set_ylabel("north")
        ax.set_zlabel("up")
    ax.plot(*path.T, color="black", lw=1.5, label="SLERP path")
    for mu, point in zip(mus, points, strict=True):
        name = "single frame" if mu == 0 else "data fusion" if mu == 1 else None
        ax.scatter(*point, s=40 if name else 18, color=METHOD_COLORS[name] if name else "black", depthshade=False,
                   label=f"{name} (μ = {mu:g})" if name else None)
        if zoom:
            ax.text(*point, f"  μ = {mu:g}", fontsize=ANNOTATION_FONT_PT)
    if mu_marked is not None:
        mu, label = mu_marked
        ax.scatter(*slerp_tips(q_single, q_fusion, [mu], axis)[0], marker="*", s=160, color="gold",
                   edgecolor="black", depthshade=False, label=label)
    ax.set_box_aspect((1, 1, 1))
    if title:
        ax.set_title(title)
    return ax
