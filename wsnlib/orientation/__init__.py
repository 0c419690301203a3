"""Orientation estimators: Madgwick's filter and a gap-aware Kalman filter (data fusion), TRIAD,
Davenport, SVD and QUEST (single frame), and an offline smoother.

All take body-frame signals ``(..., T, 3)`` and return ENU quaternions ``(..., T, 4)``
(see :mod:`wsnlib` for the conventions).  :mod:`.loss_handling` adds paper 001's hybrid
SLERP (eqs. (3)–(4)) and the loss-handling alternatives of its Sec. V.
:mod:`.peers` wraps two peer filters, x-io Fusion and VQF, with the same loss semantics.
:mod:`.kalman` is the gap-aware error-state Kalman filter (``estimate_orientation(...,
method="kalman")``), :mod:`.smoothing` its offline RTS smoother with Hermite curves across
gaps, :mod:`.single_frame` Wahba solvers beside TRIAD.

The arithmetic of Madgwick's update, TRIAD, SLERP and every loss option is in
:mod:`._kernels`: numba-compiled scalar functions that follow the equations line by line,
one loop over time per recording, batch elements in parallel.  :mod:`._batch` holds the
argument checks the public functions share.
"""

from wsnlib.orientation.kalman import KalmanSettings, kalman_orientation
from wsnlib.orientation.loss_handling import (
    blend_with_single_frame,
    effective_lost_run,
    estimate_orientation,
    slerp_weight,
)
from wsnlib.orientation.madgwick import madgwick, madgwick_step
from wsnlib.orientation.peers import fusion_ahrs, vqf_orientation
from wsnlib.orientation.single_frame import davenport, quest, svd_single_frame
from wsnlib.orientation.smoothing import smooth_orientation
from wsnlib.orientation.triad import tilt_quaternion, triad

__all__ = [
    "KalmanSettings",
    "blend_with_single_frame",
    "davenport",
    "effective_lost_run",
    "estimate_orientation",
    "fusion_ahrs",
    "kalman_orientation",
    "madgwick",
    "madgwick_step",
    "quest",
    "slerp_weight",
    "smooth_orientation",
    "svd_single_frame",
    "tilt_quaternion",
    "triad",
    "vqf_orientation",
]
