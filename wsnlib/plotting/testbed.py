"""Paper 002's testbed as we assume it: the body, the arm's postures and the anchors (its Fig. 4).

The paper's Fig. 4 shows where the seven anchors were; the text does not say, so the sites
of :mod:`wsnlib.sim.body` are our choice.  :func:`plot_anchor_layout` draws them, numbered
as in the anchor subsets of Tables 2 and 3 (A1 … A7 → 1 … 7).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Circle, Ellipse, Rectangle

from wsnlib.plotting.style import ANNOTATION_FONT_PT, METHOD_COLORS, OKABE_ITO
from wsnlib.testbed import ANCHOR_NAMES, ANCHOR_WORN, POSTURES, TARGET_NAMES

_BODY = {"facecolor": "0.88", "edgecolor": "0.45", "lw": 0.8, "zorder": 1}
_WORN_STYLE = {"marker": "o", "color": OKABE_ITO["bluish green"], "label": "worn anchor"}
_ROOM_STYLE = {"marker": "s", "color": OKABE_ITO["vermillion"], "label": "room anchor"}


def _body(ax, body, view: str) -> None:
    """The body solids (:class:`wsnlib.sim.body.BodyShape`) in the x–z ("front") or y–z ("side") plane."""
    centre, half, legs_half, arm_x = ((body.torso_center_x_m, body.torso_half_width_m, body.legs_half_width_m,
                                       2 * body.torso_center_x_m) if view == "front"
                                      else (0.0, body.torso_half_depth_m, body.legs_half_depth_m, 0.0))
    ax.add_patch(Rectangle((centre - legs_half, body.floor_z_m), 2 * legs_half,
                           body.torso_bottom_z_m - body.floor_z_m, **_BODY))
    ax.add_patch(Rectangle((centre - half, body.torso_bottom_z_m), 2 * half,
                           body.torso_top_z_m - body.torso_bottom_z_m, **_BODY))
    ax.add_patch(Rectangle((centre - body.neck_radius_m, body.torso_top_z_m), 2 * body.neck_radius_m,
                           body.neck_length_m, **_BODY))
    ax.add_patch(Circle((centre, body.head_center_z_m), body.head_radius_m, **_BODY))
    # the left arm hangs beside the torso (its shoulder mirrors the right one about the torso's centre)
    ax.add_patch(Rectangle((arm_x - body.upper_arm_radius_m, -body.left_arm_length_m),
                           2 * body.upper_arm_radius_m, body.left_arm_length_m, **{**_BODY, "zorder": 0.5}))


def _body_top(ax, body) -> None:
    """Torso and head seen from above, in the x–y plane."""
    cx = body.torso_center_x_m
    ax.add_patch(Ellipse((cx, 0.0), 2 * body.torso_half_width_m, 2 * body.torso_half_depth_m, **_BODY))
    ax.add_patch(Circle((cx, 0.0), body.head_radius_m, **{**_BODY, "facecolor": "0.8"}))


#: The three panels: title, (horizontal, vertical) coordinate of the shoulder frame, axis labels.
_VIEWS = (("front view", (0, 2), "x (m, to the user's right: leftwards)", "z (m, up)"),
          ("side view (from the user's right)", (1, 2), "y (m, forward)", "z (m, up)"),
          ("floor plan (from above)", (0, 1), "x (m, to the user's right)", "y (m, forward)"))


def plot_anchor_layout(user=None, *, axes=None):
    """Our assumed layout of paper 002's testbed (its Fig. 4): front and side views, floor plan.

    Parameters
    ----------
    user : wsnlib.sim.body.User, optional
        Whose body and anchor sites to draw; default a 1.75 m user at the nominal sites
        (:func:`wsnlib.sim.body.user_from_height`).
    axes : three matplotlib Axes, optional
        Front view (x–z, seen from the front: the user's right on the left), side view (y–z,
        from the user's right, facing right) and floor plan (x–y, from above, the user facing
        up).  Default: a new figure.

    Draws, in the shoulder frame (m; :mod:`wsnlib.sim.body`): the body solids, the right arm's
    five trained postures P1–P5 (straight lines from the shoulder, Table 1's directions) with
    the two targets on each, and the anchors numbered 1–7 as in Tables 2–3: the worn ones
    (circles) in the two body views, the room ones (squares) on the floor plan with their height
    above the floor.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from wsnlib.sim.body import REFERENCE_HEIGHT_M, user_from_height

    user = user_from_height("nominal", REFERENCE_HEIGHT_M) if user is None else user
    if axes is None:
        fig, axes = plt.subplots(1, 3, figsize=(7.5, 3.9), layout="constrained",
                                 gridspec_kw={"width_ratios": (1.0, 0.85, 1.5)})
    else:
        fig = axes[0].figure
    front, side, top = axes
    body = user.body
    _body(front, body, "front")
    _body(side, body, "side")
    _body_top(top, body)
    arm_length = user.upper_arm_m + user.forearm_m
    for posture in POSTURES:
        targets = user.target_positions(posture)
        end = arm_length * targets[1] / user.target_distances_m[1]
        for ax, (_, (i, j), _, _) in zip(axes, _VIEWS, strict=True):
            ax.plot([0.0, end[i]], [0.0, end[j]], color="0.3", lw=1.0, zorder=2)
            for name, position in zip(TARGET_NAMES, targets, strict=True):
                ax.plot(position[i], position[j], ls="", marker=".", ms=5, color=METHOD_COLORS[name], zorder=3,
                        label=f"target {name}" if posture == POSTURES[0] else None)
            if np.hypot(end[i], end[j]) > 0.15:  # an arm seen end-on has no room for its label
                ax.annotate(posture, (end[i], end[j]), textcoords="offset points", xytext=(1, 3),
                            fontsize=ANNOTATION_FONT_PT, color="0.3")
    floor_z = body.floor_z_m
    for index, name in enumerate(ANCHOR_NAMES):
        worn = ANCHOR_WORN[name]
        style = _WORN_STYLE if worn else _ROOM_STYLE
        position = user.anchor_positions_m[index]
        for ax, (_, (i, j), _, _) in zip(axes, _VIEWS, strict=True):
            if worn == (ax is top):  # worn anchors in the two body views, room anchors on the floor plan
                continue
            ax.plot(position[i], position[j], ls="", ms=11, mec="white", zorder=4,
                    **{**style, "label": style["label"] if name in ("A1", "A2") else None})
            ax.annotate(str(index + 1), (position[i], position[j]), ha="center", va="center", color="white",
                        fontsize=ANNOTATION_FONT_PT, zorder=5)
            if not worn:
                ax.annotate(f"{position[2] - floor_z:.2f} m high", (position[i], position[j]),
                            textcoords="offset points", xytext=(0, -12), ha="center", fontsize=ANNOTATION_FONT_PT)
    for ax, (title, _, xlabel, ylabel) in zip(axes, _VIEWS, strict=True):
        ax.set_title(title)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, lw=0.3, alpha=0.5)
    front.invert_xaxis()
    handles, labels = [], []
    for ax in (front, top):
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label not in labels:
                handles.append(handle)
                labels.append(label)
    fig.legend(handles, labels, loc="outside lower center", ncol=4, fontsize=ANNOTATION_FONT_PT)
    return fig
