"""Panels of one burst loss and of static fingerprinting, drawn from the study layer's results.

The results come from :mod:`wsnlib.studies.burst_loss` and
:mod:`wsnlib.studies.static_fingerprinting`; these are the panels of the notebooks' explore cells.
"""

from __future__ import annotations

import numpy as np

from wsnlib.plotting.style import ANNOTATION_FONT_PT
from wsnlib.plotting.traces import _axes, loss_spans, plot_angle_traces

_CORNER_NOTE = {"ha": "right", "va": "top", "fontsize": ANNOTATION_FONT_PT}


def _recovery_note(name: str, recovery, threshold_deg: float) -> str:
    """One line on a :class:`~wsnlib.studies.burst_loss.RecoveryAfterBurst`."""
    if recovery.peak_deg is None:
        return f"{name}: no loss"
    if recovery.recovery_s is None:
        return f"{name}: max {recovery.peak_deg:.1f}° after the loss began"
    if recovery.recovery_s == 0.0:
        return f"{name}: max {recovery.peak_deg:.1f}°, never above {threshold_deg:g}° after the gap"
    recovered = ("not within the record" if np.isinf(recovery.recovery_s)
                 else f"{recovery.recovery_s:.1f} s after the gap")
    return f"{name}: max {recovery.peak_deg:.1f}°, under {threshold_deg:g}° {recovered}"


def plot_burst_recovery(result, *, ax=None, before_s=1.0):
    """|Pitch error| of data fusion and single frame around one burst loss, with the lossless reference.

    Parameters
    ----------
    result : wsnlib.studies.burst_loss.BurstRecovery
    ax : matplotlib Axes, optional
    before_s : float
        Seconds shown before the loss (the plot runs to the end of the record).

    Draws the absolute pitch error (°) of data fusion and single frame, the loss shaded, data
    fusion without the loss in grey, the threshold dotted, and a note with data fusion's
    largest error after the loss began and its recovery time.
    """
    ax = _axes(ax)
    t, errors = result.time_s, result.pitch_error_deg
    plot_angle_traces(t, {"data fusion": np.abs(errors["data fusion"]), "single frame": np.abs(errors["single frame"])},
                      ax=ax, ylabel=f"|{result.node} pitch error| (°)", loss_spans=loss_spans(t, result.received))
    ax.plot(t, np.abs(errors["data fusion, no loss"]), color="0.55", lw=0.8, label="data fusion, no loss")
    ax.axhline(result.threshold_deg, color="0.3", ls=":", lw=0.8)
    ax.legend(loc="center right", fontsize=ANNOTATION_FONT_PT)
    shown_from = t[result.first_lost] - before_s if result.first_lost is not None else t[0]
    ax.set_xlim(max(t[0], shown_from), t[-1])
    ax.text(0.98, 0.97, _recovery_note("data fusion", result.recovery, result.threshold_deg),
            transform=ax.transAxes, **_CORNER_NOTE)
    return ax


def plot_hybrid_vs_fusion(result, *, ax=None, before_s=0.5, after_s=3.0):
    """Elbow angle of the truth, data fusion and the hybrid around one burst loss.

    Parameters
    ----------
    result : wsnlib.studies.burst_loss.HybridVsFusion
    ax : matplotlib Axes, optional
    before_s, after_s : float
        Seconds shown before and after the start of the loss (all of it without a loss).

    The note gives each estimate's largest elbow error after the loss began and its recovery
    time to the threshold.
    """
    ax = _axes(ax)
    t = result.time_s
    plot_angle_traces(t, result.elbow_deg, ax=ax, ylabel="elbow angle (°)", loss_spans=loss_spans(t, result.received))
    ax.legend(loc="center right", fontsize=ANNOTATION_FONT_PT)
    if result.first_lost is not None:
        ax.set_xlim(t[result.first_lost] - before_s, min(t[-1], t[result.first_lost] + after_s))
    notes = [_recovery_note(name, recovery, result.threshold_deg) for name, recovery in result.recovery.items()]
    ax.text(0.98, 0.97, "\n".join(notes), transform=ax.transAxes, **_CORNER_NOTE)
    return ax


def plot_static_fingerprinting(result, *, ax=None):
    """Mean position error per posture as bars, one colour per target, and each target's mean.

    Parameters
    ----------
    result : wsnlib.studies.static_fingerprinting.StaticFingerprinting
    ax : matplotlib Axes, optional
    """
    ax = _axes(ax)
    result.mean_by_posture.plot.bar(ax=ax, rot=0, width=0.75)
    ax.set_xlabel("posture")
    ax.set_ylabel("mean position error (cm)")
    ax.legend(title=None, loc="upper left", fontsize=ANNOTATION_FONT_PT)
    ax.text(0.98, 0.97, "mean: " + ", ".join(f"{t} {v:.1f} cm" for t, v in result.mean_by_target.items()),
            transform=ax.transAxes, **_CORNER_NOTE)
    return ax
