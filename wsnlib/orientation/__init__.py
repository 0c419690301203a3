"""Orientation estimators: Madgwick's filter and a gap-aware Kalman filter (data fusion), TRIAD,
Davenport, SVD and QUEST (single frame), and an offline smoother.

All take body-frame signals ``(..., T, 3)`` and return ENU quaternions ``(..., T, 4)``
(see :mod:`wsnlib` for the conventions).  :mod:`.loss_handling` adds paper 001's hybrid
SLERP (eqs. (3)–(4)) and the loss-handling alternatives of its Sec. V behind one dispatcher,
:func:`estimate_orientation`, that runs one settings object per method (:mod:`.method_settings`);
:mod:`.lost_run` holds eq. (3) and the λ schedules, :mod:`.hybrid_blend` eq. (4) as an output
stage on any filter and the gate of the gated hybrid.
:mod:`.peers` wraps two peer filters, x-io Fusion and VQF, with the same loss semantics.
:mod:`.kalman` is the gap-aware error-state Kalman filter (``estimate_orientation(...,
method="kalman")``), :mod:`.smoothing` its offline RTS smoother with Hermite curves across
gaps, :mod:`.single_frame` Wahba solvers beside TRIAD.

The arithmetic is numba-compiled: :mod:`._scalar_kernels` holds Madgwick's update, TRIAD,
SLERP and the quaternion helpers as scalar functions that follow the equations line by line,
:mod:`._kernels` the loop over time of every loss option (one recording) and the drivers that
run batch elements in parallel, :mod:`._kalman_kernels` the Kalman filter's.  :mod:`._batch` holds the
argument checks the public functions share.
"""

from wsnlib.orientation.hybrid_blend import SingleFrameGate, blend_with_single_frame, single_frame_trusted
from wsnlib.orientation.kalman import KalmanSettings, kalman_orientation
from wsnlib.orientation.loss_handling import estimate_orientation
from wsnlib.orientation.lost_run import effective_lost_run, slerp_weight
from wsnlib.orientation.madgwick import madgwick, madgwick_step
from wsnlib.orientation.method_settings import (
    AdaptiveBetaSettings,
    DtExtensionSettings,
    GyroInterpolationSettings,
    HoldLastSettings,
    HybridSettings,
    KalmanMethodSettings,
)
from wsnlib.orientation.peers import fusion_ahrs, vqf_orientation
from wsnlib.orientation.single_frame import davenport, quest, svd_single_frame
from wsnlib.orientation.smoothing import smooth_orientation
from wsnlib.orientation.triad import tilt_quaternion, triad

__all__ = [
    "AdaptiveBetaSettings",
    "DtExtensionSettings",
    "GyroInterpolationSettings",
    "HoldLastSettings",
    "HybridSettings",
    "KalmanMethodSettings",
    "KalmanSettings",
    "SingleFrameGate",
    "blend_with_single_frame",
    "davenport",
    "effective_lost_run",
    "estimate_orientation",
    "fusion_ahrs",
    "kalman_orientation",
    "madgwick",
    "madgwick_step",
    "quest",
    "single_frame_trusted",
    "slerp_weight",
    "smooth_orientation",
    "svd_single_frame",
    "tilt_quaternion",
    "triad",
    "vqf_orientation",
]

# Before any kernel runs: drop numba's cached machine code if a source of this package changed
# (numba alone would only notice a change in the kernel's own file; see _numba_cache).
from wsnlib.orientation import _numba_cache, _scalar_kernels  # noqa: E402

_numba_cache.drop_stale_cache(_numba_cache.cache_dir(_scalar_kernels.squared_norm3), _numba_cache.sources_digest())
