"""Old home of the explore panels; computation and drawing now live apart.

The computations are studies (:mod:`wsnlib.studies.burst_loss`,
:mod:`wsnlib.studies.static_fingerprinting`) that return arrays in small dataclasses, and
:mod:`wsnlib.plotting` draws them.  New code passes both to :func:`wsnlib.interactive.explore`
(``explore(plotting.plot_burst_recovery, knobs, compute=partial(burst_loss.burst_recovery,
recording=...))``).  The ``draw_*(ax, data..., *, knobs...)`` functions below keep the old
calls working: each runs its study and draws the result on ``ax``.
"""

from __future__ import annotations

from wsnlib import plotting
from wsnlib.studies import burst_loss
from wsnlib.studies.static_fingerprinting import static_fingerprinting

__all__ = ["draw_hybrid_vs_fusion", "draw_loss_recovery", "draw_static_fingerprinting"]


def draw_loss_recovery(ax, recording, *, beta, loss_packets, loss_start, node="humerus", samples_per_packet=6,
                       threshold_deg=5.0, before_s=1.0):
    """:func:`wsnlib.studies.burst_loss.burst_recovery` drawn by :func:`wsnlib.plotting.plot_burst_recovery`."""
    result = burst_loss.burst_recovery(recording, beta=beta, loss_packets=loss_packets, loss_start=loss_start,
                                       node=node, samples_per_packet=samples_per_packet, threshold_deg=threshold_deg)
    return plotting.plot_burst_recovery(result, ax=ax, before_s=before_s)


def draw_hybrid_vs_fusion(ax, recording, *, rho, tau, loss_packets, beta, loss_start, lossy_node="humerus",
                          other_node="forearm", samples_per_packet=6, schedule="decay", blend="output",
                          hold_window=None, threshold_deg=5.0, before_s=0.5, after_s=3.0):
    """:func:`wsnlib.studies.burst_loss.hybrid_vs_fusion` drawn by :func:`wsnlib.plotting.plot_hybrid_vs_fusion`."""
    result = burst_loss.hybrid_vs_fusion(recording, rho=rho, tau=tau, loss_packets=loss_packets, beta=beta,
                                         loss_start=loss_start, lossy_node=lossy_node, other_node=other_node,
                                         samples_per_packet=samples_per_packet, schedule=schedule, blend=blend,
                                         hold_window=hold_window, threshold_deg=threshold_deg)
    return plotting.plot_hybrid_vs_fusion(result, ax=ax, before_s=before_s, after_s=after_s)


def draw_static_fingerprinting(ax, train, online, *, n_neighbors, power, anchors, metric="euclidean"):
    """:func:`wsnlib.studies.static_fingerprinting.static_fingerprinting` drawn by
    :func:`wsnlib.plotting.plot_static_fingerprinting`; with no anchor chosen, a note instead."""
    anchors = list(anchors)
    if not anchors:
        ax.text(0.5, 0.5, "choose at least one anchor", transform=ax.transAxes, ha="center", va="center")
        return ax
    result = static_fingerprinting(train, online, n_neighbors=n_neighbors, power=power, anchors=anchors,
                                   metric=metric)
    return plotting.plot_static_fingerprinting(result, ax=ax)
