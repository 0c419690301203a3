"""Orientation estimators: Madgwick's filter and a gap-aware Kalman filter (data fusion), TRIAD
(single frame), an offline smoother, two peer filters, their offline variants and a neural peer.

All take body-frame signals ``(..., T, 3)`` and return ENU quaternions ``(..., T, 4)``
(see :mod:`wsnlib` for the conventions), with packet loss given as a boolean ``received``
mask ``(..., T)``.  One door each:

* :func:`madgwick` — Madgwick's filter, holding its estimate over gaps (paper 001's receiver);
* :func:`estimate_orientation` — Madgwick's filter with every loss-handling option: paper
  001's hybrid SLERP (eqs. (3)–(4)) and its Sec. V alternatives (:mod:`.loss_handling`);
* :func:`kalman_orientation` — the gap-aware error-state Kalman filter (:mod:`.kalman`); the
  same filter one sample at a time for a live receiver: :func:`kalman_initial_state` and
  :func:`kalman_step` on a :class:`KalmanState`; its equations as numpy matrices:
  :class:`KalmanReference`;
* :func:`smooth_orientation` — its offline RTS smoother with curves across gaps
  (:mod:`.smoothing`);
* :func:`fusion_orientation`, :func:`vqf_orientation` — x-io Fusion and VQF as peers with the
  same loss semantics (:mod:`.peers`);
* :func:`riann_orientation` — RIANN, a recurrent network for inclination (no magnetometer), fed
  the received samples with the actual time since the last one (:mod:`.neural_peers`);
* :func:`offline_vqf_orientation`, :func:`forward_backward_orientation` — the smoother's
  offline peers: VQF's acausal variant on a gap-filled recording, and any causal estimator
  averaged with its run on the time-reversed recording (:mod:`.offline_peers`);
* :mod:`.fixed_lag` (fixed-lag RTS smoothing on the filter's stored states) and :mod:`.bridging`
  (a Kalman step turned by a measured rotation): the live receiver's filter, :mod:`wsnlib.stream`;
* :func:`triad`, :func:`tilt_quaternion` — single-frame solvers (no memory, nothing to lose).

The loss vocabulary
-------------------
Every filter that runs over time takes the same keywords for what happens around a gap (a
run of lost samples); a filter refuses, with a ``ValueError`` naming it, a value it does not
support:

``gap``
    What the filter's *state* does inside a gap: ``"hold"`` (it stays where it was),
    ``"constant_rate"`` (it keeps turning by the last received angular rate, optionally
    decaying with ``gap_time_constant`` s; dead reckoning, gyroscope only) or ``"ar"`` (by an
    autoregressive prediction of the rate fitted on the rates before the gap, :mod:`.gaps`;
    its span and window ``gap_rate_prediction_span_s`` and ``gap_rate_prediction_window_s``
    are :class:`KalmanSettings` fields for the Kalman filter and smoother, keywords for the
    others).  Defaults: ``"hold"`` for Madgwick's family and the peers, ``"ar"`` for the
    Kalman filter and the smoother.
``replay``
    ``True``: when the first sample after a gap arrives, re-run the gap from the state at its
    start with rates that meet the first received one (paper 001's gyroscope interpolation,
    applied to the state; with ``gap="ar"`` the prediction corrected towards the first received
    rate), then update.  Causal: it changes the state from the gap's end on, never what was
    output on the lost samples.  Madgwick's family, the peers and the Kalman filter (default on
    there).
``output_on_lost``
    What is *output* on a lost sample: ``"estimate"`` (the filter's state: held or predicted,
    per ``gap``) or ``"hold"`` (the previous output, what a receiver that shows only measured
    updates displays).  The state is not affected.  Not the smoother's (it outputs its
    smoothed estimate everywhere).
``blend``
    Paper 001's hybrid: ``None`` (none), ``"output"`` (SLERP towards the single frame as an
    output stage) or ``"feedback"`` (the SLERP's result also replaces the filter's state),
    with μ of eq. (3) from ``rho``, ``tau``, ``schedule``, ``hold_window``, and the *gated*
    hybrid with ``single_frame_gate``.  Madgwick's family and the peers.

A keyword given where the call does not use it (``rho`` without ``blend``, a
``gap_time_constant`` with ``gap="hold"``) is a ``ValueError``, never silently ignored.
:data:`.loss_handling.PAPER_OPTIONS` spells paper 001's five options in this vocabulary.

The arithmetic is numba-compiled: :mod:`._scalar_kernels` holds Madgwick's update, TRIAD,
SLERP and the quaternion helpers as scalar functions that follow the equations line by line,
:mod:`._kernels` the loop over time of Madgwick's filter (one recording) and the drivers that
run batch elements in parallel, :mod:`._kalman_kernels` the Kalman filter's.  :mod:`._batch`
holds the argument checks (the vocabulary's among them) the public functions share.
"""

# Every kernel caches its machine code in the folder of the sources this process imported
# (numba alone would only notice a change of the kernel's own file; see _numba_cache).
from wsnlib.orientation import _numba_cache

with _numba_cache.caching_into_this_version():
    from wsnlib.orientation import bridging, fixed_lag  # noqa: F401  (wsnlib.stream's receiver)
    from wsnlib.orientation.hybrid_blend import SingleFrameGate, single_frame_trusted
    from wsnlib.orientation.kalman import (
        KalmanReference,
        KalmanSettings,
        KalmanState,
        kalman_initial_state,
        kalman_orientation,
        kalman_step,
    )
    from wsnlib.orientation.loss_handling import estimate_orientation
    from wsnlib.orientation.lost_run import effective_lost_run, slerp_weight
    from wsnlib.orientation.madgwick import madgwick, madgwick_step
    from wsnlib.orientation.neural_peers import riann_orientation
    from wsnlib.orientation.offline_peers import forward_backward_orientation, offline_vqf_orientation
    from wsnlib.orientation.peers import fusion_orientation, vqf_orientation
    from wsnlib.orientation.smoothing import smooth_orientation
    from wsnlib.orientation.triad import tilt_quaternion, triad
_numba_cache.drop_other_versions()

__all__ = [
    "KalmanReference",
    "KalmanSettings",
    "KalmanState",
    "SingleFrameGate",
    "effective_lost_run",
    "estimate_orientation",
    "forward_backward_orientation",
    "fusion_orientation",
    "kalman_initial_state",
    "kalman_orientation",
    "kalman_step",
    "madgwick",
    "madgwick_step",
    "offline_vqf_orientation",
    "riann_orientation",
    "single_frame_trusted",
    "slerp_weight",
    "smooth_orientation",
    "tilt_quaternion",
    "triad",
    "vqf_orientation",
]
