"""Draw helpers for :func:`wsnlib.interactive.explore`: one knob setting → one panel.

Each ``draw_*`` function has the signature ``draw_*(ax, data..., *, knobs..., settings...)``:
the notebook binds the data it has already computed and its fixed settings *by keyword* with
:func:`functools.partial` (``partial(views.draw_loss_recovery, recording=rec, loss_start=80)``),
and :func:`~wsnlib.interactive.explore` passes the Axes and the knob values.  Each reruns the
wsnlib computation behind one notebook figure for the given values (nothing new: the same calls
as the notebook) and draws it with :mod:`wsnlib.plotting` (or pandas), in under a second on
the notebooks' recordings.

========================================  =========  ============================================
helper                                    notebook   knobs
========================================  =========  ============================================
:func:`draw_loss_recovery`                01         Madgwick's β, loss length
:func:`draw_hybrid_vs_fusion`             02         the hybrid's ρ and τ, loss length, blend
:func:`draw_static_fingerprinting`        06         kNN's k and Shepard exponent p_s, anchors
========================================  =========  ============================================
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnlib import fingerprint, loss, metrics, plotting
from wsnlib.orientation import estimate_orientation, madgwick, triad

_NOTE = {"ha": "right", "va": "top", "fontsize": plotting.ANNOTATION_FONT_PT}


def _burst(n_samples: int, loss_start: int, loss_packets: int, samples_per_packet: int):
    """Loss mask of one burst, its first lost sample and the first received sample after it."""
    received = loss.burst_mask(n_samples, loss_start, loss_packets, samples_per_packet)
    lost = np.flatnonzero(~received)
    if lost.size == 0:
        return received, None, None
    return received, int(lost[0]), int(lost[-1]) + 1


def _recovery_text(name: str, error, received, first_lost, first_after, fs, threshold_deg) -> str:
    if first_lost is None:
        return f"{name}: no loss"
    peak = float(metrics.max_abs_error(error, start=first_lost, where=received))
    if first_after >= error.shape[-1]:
        return f"{name}: max {peak:.1f}° after the loss began"
    recovery = float(metrics.recovery_time_s(error, threshold_deg, fs, start=first_after))
    if recovery == 0.0:
        return f"{name}: max {peak:.1f}°, never above {threshold_deg:g}° after the gap"
    recovered = "not within the record" if np.isinf(recovery) else f"{recovery:.1f} s after the gap"
    return f"{name}: max {peak:.1f}°, under {threshold_deg:g}° {recovered}"


def draw_loss_recovery(ax, recording, *, beta, loss_packets, loss_start, node="humerus", samples_per_packet=6,
                       threshold_deg=5.0, before_s=1.0):
    """|Pitch error| of one node after a burst loss: data fusion (Madgwick, β) vs single frame (notebook 01).

    Runs :func:`wsnlib.orientation.madgwick` on the node with and without the loss (one batched
    call) and TRIAD held over the gap, and plots the absolute pitch error of each against
    time from ``before_s`` before the loss to the end, with the loss shaded and the
    threshold dotted.  The note gives data fusion's largest error on received samples after
    the loss began and its recovery time (:func:`wsnlib.metrics.recovery_time_s`).

    Parameters
    ----------
    ax : matplotlib Axes
    recording : wsnlib.datasets.Recording
        With ground truth (``quat_true``); ``recording.fs`` is the sampling rate.
    beta : float
        Madgwick's gain (rad/s).
    loss_packets : int
        Packets lost in a row (0: none).
    loss_start : int
        The burst starts at the first packet after this many samples (:func:`wsnlib.loss.burst_mask`).
    node : str
        The node that loses packets.
    samples_per_packet : int
    threshold_deg : float
        Error threshold (°) of the recovery time.
    before_s : float
        Seconds shown before the loss.
    """
    i = recording.node_index(node)
    n_samples = recording.time_s.size
    received, first_lost, first_after = _burst(n_samples, loss_start, loss_packets, samples_per_packet)
    gyr, acc, mag = recording.gyr[i], recording.acc[i], recording.mag[i]
    masks = np.stack([received, np.ones(n_samples, dtype=bool)])                       # lossy, lossless
    pitch_true = metrics.segment_pitch_deg(recording.quat_true[i])
    quat_df = madgwick(gyr, acc, mag, fs=recording.fs, beta=beta, received=masks)
    error_df = metrics.segment_pitch_deg(quat_df) - pitch_true
    error_sf = metrics.segment_pitch_deg(loss.hold_last(triad(acc, mag), received)) - pitch_true
    t = recording.time_s
    plotting.plot_angle_traces(t, {"data fusion": np.abs(error_df[0]), "single frame": np.abs(error_sf)}, ax=ax,
                               ylabel=f"|{node} pitch error| (°)", loss_spans=plotting.loss_spans(t, received))
    ax.plot(t, np.abs(error_df[1]), color="0.55", lw=0.8, label="data fusion, no loss")
    ax.axhline(threshold_deg, color="0.3", ls=":", lw=0.8)
    ax.legend(loc="center right", fontsize=plotting.ANNOTATION_FONT_PT)
    shown_from = t[first_lost] - before_s if first_lost is not None else t[0]
    ax.set_xlim(max(t[0], shown_from), t[-1])
    ax.text(0.98, 0.97, _recovery_text("data fusion", error_df[0], received, first_lost, first_after,
                                       recording.fs, threshold_deg), transform=ax.transAxes, **_NOTE)
    return ax


def draw_hybrid_vs_fusion(ax, recording, *, rho, tau, loss_packets, beta, loss_start, lossy_node="humerus",
                          other_node="forearm", samples_per_packet=6, schedule="decay", blend="output",
                          hold_window=None, threshold_deg=5.0, before_s=0.5, after_s=3.0):
    """Elbow angle of data fusion and of the hybrid (eq. (4)) after a loss on one node (notebook 02).

    The node ``lossy_node`` loses ``loss_packets`` packets after ``loss_start`` samples; the
    other node loses nothing, so both estimators give it the same orientation (μ = 1 without
    a loss) and it is estimated once.  ``lossy_node`` runs
    :func:`wsnlib.orientation.estimate_orientation` with ``method="hold_last"`` (data fusion)
    and ``method="hybrid"`` (ρ, τ, ``schedule``, ``blend``).  Plotted: the true elbow angle
    (dashed) and both estimates from ``before_s`` before the loss to ``after_s`` after it;
    the note gives each one's largest elbow error on received samples after the loss began
    and its recovery time to ``threshold_deg``.

    Parameters
    ----------
    ax : matplotlib Axes
    recording : wsnlib.datasets.Recording
        Two nodes with ground truth; the elbow angle is forearm pitch minus humerus pitch
        (:func:`wsnlib.metrics.elbow_angle_deg`).
    rho, tau : float
        Eq. (3) of paper 001 (μ = ρ / (λ/τ + ρ)).
    loss_packets : int
        Packets lost in a row (0: none).
    beta : float
        Madgwick's gain (rad/s).
    loss_start : int
        Samples received before the burst (:func:`wsnlib.loss.burst_mask`).
    schedule, blend, hold_window
        As in :func:`~wsnlib.orientation.estimate_orientation`.
    """
    h, f = recording.node_index(lossy_node), recording.node_index(other_node)
    n_samples = recording.time_s.size
    received, first_lost, first_after = _burst(n_samples, loss_start, loss_packets, samples_per_packet)
    signals = {node: (recording.gyr[node], recording.acc[node], recording.mag[node]) for node in (h, f)}
    common = dict(fs=recording.fs, beta=beta, rho=rho, tau=tau)
    q_other = estimate_orientation(*signals[f], method="hold_last", **common)
    hybrid = dict(method="hybrid", schedule=schedule, blend=blend,
                  hold_window=hold_window if schedule == "hold" else None)
    elbow = {name: metrics.elbow_angle_deg(estimate_orientation(*signals[h], received=received, **common, **options),
                                           q_other)
             for name, options in (("data fusion", dict(method="hold_last")), ("hybrid", hybrid))}
    truth = metrics.elbow_angle_deg(recording.quat_true[h], recording.quat_true[f])
    t = recording.time_s
    plotting.plot_angle_traces(t, {"truth": truth, **elbow}, ax=ax, ylabel="elbow angle (°)",
                               loss_spans=plotting.loss_spans(t, received))
    ax.legend(loc="center right", fontsize=plotting.ANNOTATION_FONT_PT)
    if first_lost is not None:
        ax.set_xlim(t[first_lost] - before_s, min(t[-1], t[first_lost] + after_s))
    notes = [_recovery_text(name, value - truth, received, first_lost, first_after, recording.fs, threshold_deg)
             for name, value in elbow.items()]
    ax.text(0.98, 0.97, "\n".join(notes), transform=ax.transAxes, **_NOTE)
    return ax


def draw_static_fingerprinting(ax, train, online, *, n_neighbors, power, anchors, metric="euclidean"):
    """Mean position error per posture and target of kNN on the online static session (notebook 06).

    Fits :class:`wsnlib.fingerprint.KNNFingerprint` (k = ``n_neighbors``, Shepard exponent
    ``power``, the chosen anchors) per user and target
    (:func:`wsnlib.fingerprint.fit_predict_by_group`), localises every online vector and
    draws the mean position error (cm, eq. (11)) per posture as bars, one colour per target;
    the note gives the mean over all vectors of each target.

    Parameters
    ----------
    ax : matplotlib Axes
    train, online : wsnlib.rss.RssVectors
        Training vectors (NaN allowed) and complete online vectors, with ``user``, ``target``,
        ``label`` (posture) and ``position`` (m).
    n_neighbors : int
        k (≤ the number of postures).
    power : float
        Shepard exponent p_s (eq. (2)).
    anchors : sequence of str or int
        Anchor names (from ``train.anchors``) or column indices; empty: nothing is drawn
        but a note.
    metric : {"euclidean", "manhattan"}
    """
    anchors = list(anchors)
    if not anchors:
        ax.text(0.5, 0.5, "choose at least one anchor", transform=ax.transAxes, ha="center", va="center")
        return ax
    names = list(train.anchors)
    columns = [a if isinstance(a, int | np.integer) else names.index(a) for a in anchors]
    estimator = fingerprint.KNNFingerprint(n_neighbors, metric=metric, power=power, anchors=columns)
    estimate = fingerprint.fit_predict_by_group(estimator, train.rss, train.position, _groups(train),
                                                online.rss, _groups(online))
    error_cm = 100 * metrics.position_error(estimate, online.position)
    table = (pd.DataFrame({"posture": online.label, "target": online.target, "PE": error_cm})
             .groupby(["posture", "target"])["PE"].mean().unstack("target"))
    table.plot.bar(ax=ax, rot=0, width=0.75)
    ax.set_xlabel("posture")
    ax.set_ylabel("mean position error (cm)")
    ax.legend(title=None, loc="upper left", fontsize=plotting.ANNOTATION_FONT_PT)
    by_target = pd.Series(error_cm).groupby(np.asarray(online.target)).mean()
    ax.text(0.98, 0.97, "mean: " + ", ".join(f"{t} {v:.1f} cm" for t, v in by_target.items()),
            transform=ax.transAxes, **_NOTE)
    return ax


def _groups(vectors) -> np.ndarray:
    """``"user/target"`` per vector: fingerprinting is per user and target node (paper 002, Sec. 4.1)."""
    return np.char.add(np.asarray(vectors.user).astype(str), "/" + np.asarray(vectors.target).astype(str))
