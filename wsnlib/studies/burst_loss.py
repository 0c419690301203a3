"""One burst of lost packets on one node: how each estimator's error grows and recovers (paper 001).

Two computations on a recording with ground truth, each fast enough (well under a second on
a few seconds at 50 Hz) to rerun whenever a knob of :func:`wsnlib.interactive.explore` moves:

* :func:`burst_recovery`: data fusion (Madgwick, gain β) against single frame (TRIAD held over
  the gap) on the node's pitch, with and without the burst (paper 001, Section II);
* :func:`hybrid_vs_fusion`: the elbow angle of data fusion and of the hybrid (paper 001,
  eqs. (3)–(4)) when the upper arm loses the burst (Sections III–IV).

Both return arrays (time, loss mask, errors or angles) and the recovery figures of each
estimator in small frozen dataclasses; :func:`wsnlib.plotting.plot_burst_recovery` and
:func:`wsnlib.plotting.plot_hybrid_vs_fusion` draw them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib import loss, metrics
from wsnlib.orientation import estimate_orientation, madgwick, triad

__all__ = ["BurstRecovery", "HybridVsFusion", "RecoveryAfterBurst", "burst_recovery", "hybrid_vs_fusion"]


@dataclass(frozen=True)
class RecoveryAfterBurst:
    """How far one estimate strays after a burst begins and how soon it comes back.

    Attributes
    ----------
    peak_deg : float or None
        Largest absolute error (°) on received samples from the first lost one on
        (:func:`wsnlib.metrics.max_abs_error`); None without a loss.
    recovery_s : float or None
        Time (s) from the first received sample after the gap until the absolute error stays
        under the threshold (:func:`wsnlib.metrics.recovery_time_s`): 0 if it never exceeds it
        after the gap, ``inf`` if it does not get back under it within the record; None
        without a loss or when the gap runs to the end of the record.
    """

    peak_deg: float | None
    recovery_s: float | None


@dataclass(frozen=True)
class BurstRecovery:
    """What :func:`burst_recovery` returns.

    Attributes
    ----------
    time_s : numpy.ndarray (T,)
        Sample times (s).
    received : numpy.ndarray (T,) bool
        The node's loss mask (False: lost).
    first_lost : int or None
        Index of the first lost sample (None: no loss).
    pitch_error_deg : dict of str to numpy.ndarray (T,)
        Estimated minus true pitch of the node (°, signed): ``"data fusion"`` (with the
        loss), ``"single frame"`` (TRIAD, held over the gap) and ``"data fusion, no loss"``.
    recovery : RecoveryAfterBurst
        Of data fusion with the loss.
    node : str
        The node that loses the burst.
    threshold_deg : float
        Error threshold (°) of the recovery time.
    """

    time_s: np.ndarray
    received: np.ndarray
    first_lost: int | None
    pitch_error_deg: dict
    recovery: RecoveryAfterBurst
    node: str
    threshold_deg: float


@dataclass(frozen=True)
class HybridVsFusion:
    """What :func:`hybrid_vs_fusion` returns.

    Attributes
    ----------
    time_s : numpy.ndarray (T,)
        Sample times (s).
    received : numpy.ndarray (T,) bool
        The lossy node's loss mask (False: lost).
    first_lost : int or None
        Index of the first lost sample (None: no loss).
    elbow_deg : dict of str to numpy.ndarray (T,)
        Elbow angle (°): ``"truth"``, ``"data fusion"``, ``"hybrid"``.
    recovery : dict of str to RecoveryAfterBurst
        Of ``"data fusion"`` and ``"hybrid"`` (error = estimate minus truth).
    threshold_deg : float
        Error threshold (°) of the recovery times.
    """

    time_s: np.ndarray
    received: np.ndarray
    first_lost: int | None
    elbow_deg: dict
    recovery: dict
    threshold_deg: float


def _burst(n_samples: int, loss_start: int, loss_packets: int, samples_per_packet: int):
    """Loss mask of one burst, its first lost sample and the first received sample after it."""
    received = loss.burst_mask(n_samples, loss_start, loss_packets, samples_per_packet)
    lost = np.flatnonzero(~received)
    if lost.size == 0:
        return received, None, None
    return received, int(lost[0]), int(lost[-1]) + 1


def _recovery(error, received, first_lost, first_after, fs, threshold_deg) -> RecoveryAfterBurst:
    if first_lost is None:
        return RecoveryAfterBurst(peak_deg=None, recovery_s=None)
    peak = float(metrics.max_abs_error(error, start=first_lost, where=received))
    if first_after >= error.shape[-1]:
        return RecoveryAfterBurst(peak_deg=peak, recovery_s=None)
    return RecoveryAfterBurst(peak_deg=peak,
                              recovery_s=float(metrics.recovery_time_s(error, threshold_deg, fs, start=first_after)))


def burst_recovery(recording, *, beta, loss_packets, loss_start, node="humerus", samples_per_packet=6,
                   threshold_deg=5.0) -> BurstRecovery:
    """Pitch error of one node around a burst loss: data fusion (Madgwick, β) vs single frame.

    Runs :func:`wsnlib.orientation.madgwick` on the node with and without the loss (one
    batched call) and :func:`wsnlib.orientation.triad` held over the gap
    (:func:`wsnlib.loss.hold_last`), and returns each one's pitch error
    (:func:`wsnlib.metrics.segment_pitch_deg`) and data fusion's recovery.

    Parameters
    ----------
    recording : wsnlib.io.recording.Recording
        With ground truth (``quat_true``); ``recording.fs`` is the sampling rate (Hz).
    beta : float
        Madgwick's gain (rad/s).
    loss_packets : int
        Packets lost in a row (0: none).
    loss_start : int
        The burst starts at the first packet after this many samples
        (:func:`wsnlib.loss.burst_mask`).
    node : str
        The node that loses packets.
    samples_per_packet : int
    threshold_deg : float
        Error threshold (°) of the recovery time.

    Returns
    -------
    BurstRecovery
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
    return BurstRecovery(
        time_s=recording.time_s, received=received, first_lost=first_lost,
        pitch_error_deg={"data fusion": error_df[0], "single frame": error_sf, "data fusion, no loss": error_df[1]},
        recovery=_recovery(error_df[0], received, first_lost, first_after, recording.fs, threshold_deg),
        node=node, threshold_deg=float(threshold_deg))


def hybrid_vs_fusion(recording, *, rho, tau, loss_packets, beta, loss_start, lossy_node="humerus",
                     other_node="forearm", samples_per_packet=6, schedule="decay", blend="output",
                     hold_window=None, threshold_deg=5.0) -> HybridVsFusion:
    """Elbow angle of data fusion and of the hybrid (paper 001, eq. (4)) after a loss on one node.

    The node ``lossy_node`` loses ``loss_packets`` packets after ``loss_start`` samples; the
    other node loses nothing, so both estimators give it the same orientation (μ = 1 without
    a loss) and it is estimated once.  ``lossy_node`` runs
    :func:`wsnlib.orientation.estimate_orientation` as plain data fusion and with the hybrid
    (``blend``, ρ, τ, ``schedule``); the elbow angle is forearm pitch
    minus humerus pitch (:func:`wsnlib.metrics.elbow_angle_deg`).

    Parameters
    ----------
    recording : wsnlib.io.recording.Recording
        Two nodes with ground truth.
    rho, tau : float
        Eq. (3) of paper 001 (μ = ρ / (λ/τ + ρ)).
    loss_packets : int
        Packets lost in a row (0: none).
    beta : float
        Madgwick's gain (rad/s).
    loss_start : int
        Samples received before the burst (:func:`wsnlib.loss.burst_mask`).
    lossy_node, other_node : str
    samples_per_packet : int
    schedule, blend, hold_window
        As in :func:`~wsnlib.orientation.estimate_orientation` (``hold_window`` is used with
        ``schedule="hold"`` only).
    threshold_deg : float
        Error threshold (°) of the recovery times.

    Returns
    -------
    HybridVsFusion
    """
    h, f = recording.node_index(lossy_node), recording.node_index(other_node)
    n_samples = recording.time_s.size
    received, first_lost, first_after = _burst(n_samples, loss_start, loss_packets, samples_per_packet)
    signals = {node: (recording.gyr[node], recording.acc[node], recording.mag[node]) for node in (h, f)}
    common = dict(fs=recording.fs, beta=beta)
    q_other = estimate_orientation(*signals[f], **common)
    hybrid = dict(blend=blend, rho=rho, tau=tau, schedule=schedule,
                  hold_window=hold_window if schedule == "hold" else None)
    elbow = {name: metrics.elbow_angle_deg(estimate_orientation(*signals[h], received=received, **common, **options),
                                           q_other)
             for name, options in (("data fusion", {}), ("hybrid", hybrid))}
    truth = metrics.elbow_angle_deg(recording.quat_true[h], recording.quat_true[f])
    recovery = {name: _recovery(value - truth, received, first_lost, first_after, recording.fs, threshold_deg)
                for name, value in elbow.items()}
    return HybridVsFusion(time_s=recording.time_s, received=received, first_lost=first_lost,
                          elbow_deg={"truth": truth, **elbow}, recovery=recovery, threshold_deg=float(threshold_deg))
