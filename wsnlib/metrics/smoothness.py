"""Smoothness of orientation and angle sequences: jerk, steps at gap ends, jitter (ours).

Smoothness: RMS angular jerk of an orientation sequence (third time derivative of the
rotation angle, from finite differences of the body angular velocity), in °/s³.  The paper
calls single-frame estimates "jerky" without a number; this is ours.  Over a record with
losses it is dominated by the single step an estimator makes when data return, so it is split
into the step at each gap's end (:func:`gap_end_steps_deg`) and the continuous jitter without
those steps (:func:`angle_jitter_rms_deg`).

Every function broadcasts over leading batch dimensions ``(..., T)``.
"""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_bool_mask, as_float_array, check_positive


def angular_jerk_rms_deg(quat, fs) -> np.ndarray:
    """RMS angular jerk (°/s³) of an orientation sequence ``(..., T, 4) → (...)``.

    Body angular velocity from consecutive quaternions, ``ω_t = rotvec(q_t* ⊗ q_{t+1})·fs``,
    then jerk as the second finite difference of ω times ``fs²``.  Needs ``T >= 4``.
    A smooth estimate scores low; a noisy single-frame estimate scores high.
    """
    quat = as_float_array(quat, "quat", last_dim=4, min_ndim=2)
    fs = check_positive(fs, "fs")
    if quat.shape[-2] < 4:
        raise ValueError(f"quat needs at least 4 samples along time, got {quat.shape[-2]}")
    jerk = _angular_jerk(quat, fs)
    return np.degrees(np.sqrt(np.mean(np.sum(jerk**2, axis=-1), axis=-1)))


def _angular_jerk(quat: np.ndarray, fs: float) -> np.ndarray:
    """Angular jerk vectors (rad/s³), ``(..., T, 4) → (..., T − 3, 3)``."""
    delta = quat_ops.canonical(quat_ops.multiply(quat_ops.conjugate(quat[..., :-1, :]), quat[..., 1:, :]))
    sin_half = np.linalg.norm(delta[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sin_half, delta[..., :1])
    axis = np.divide(delta[..., 1:], sin_half, out=np.zeros_like(delta[..., 1:]), where=sin_half > 0)
    omega = axis * angle * fs
    return np.diff(omega, n=2, axis=-2) * fs**2


def angle_jerk_rms_deg(angle_deg, fs) -> np.ndarray:
    """RMS jerk (°/s³) of a scalar angle trace in degrees, ``(..., T) → (...)``; third difference."""
    angle_deg = as_float_array(angle_deg, "angle_deg")
    fs = check_positive(fs, "fs")
    if angle_deg.shape[-1] < 4:
        raise ValueError(f"angle_deg needs at least 4 samples, got {angle_deg.shape[-1]}")
    jerk = np.diff(angle_deg, n=3, axis=-1) * fs**3
    return np.sqrt(np.mean(jerk**2, axis=-1))


# --- Smoothness split: the step at a gap's end vs continuous jitter (issue 12) -------------
# The RMS third difference over a whole record (``angle_jerk_rms_deg``) is dominated by the one
# step an estimator makes when data return after a gap: a single jump of s degrees enters three
# third-difference windows with weights 1, 3, 3 (…), i.e. adds about ``s·fs³·√(19/N)`` to the RMS
# of N windows, whatever the estimate does elsewhere.  The two figures below separate that step
# from the jitter of the rest of the record.


def gap_end_mask(received) -> np.ndarray:
    """True at the first received sample after each run of lost samples, ``(..., T)``.

    A gap at the very start of the record counts (the estimator outputs something during it,
    e.g. its initial state); a gap still open at the record's end has no end and does not.
    """
    received = np.asarray(received)
    if received.dtype != np.bool_ or received.ndim < 1:
        raise ValueError(f"received must be a boolean mask with a time axis, got dtype {received.dtype}, "
                         f"shape {received.shape}")
    ends = np.zeros(received.shape, dtype=bool)
    ends[..., 1:] = received[..., 1:] & ~received[..., :-1]
    return ends


def gap_end_steps_deg(angle_deg, received) -> dict[str, np.ndarray]:
    """Step of an angle trace at the end of each gap: ``|x_e − x_{e−1}|`` (°).

    ``e`` is the first received sample after a gap (:func:`gap_end_mask`), ``e − 1`` the last
    output during the gap: the jump a user sees when data return.

    Parameters
    ----------
    angle_deg : array_like, shape (..., T)
        An angle, or an angle's error, in degrees (the step of the error equals the step of the
        estimate minus the truth's own change over one sample).
    received : array_like of bool, shape (..., T)
        Loss mask; broadcast to ``angle_deg``.

    Returns
    -------
    dict
        ``"step_deg"`` (..., T): the step at gap ends, 0 elsewhere (``step_deg[gap_end]`` lists
        the steps gap by gap); ``"gap_end"`` (..., T) bool; ``"max_deg"``, ``"mean_deg"`` (...):
        largest and mean step over the gaps, 0 for a record without a closed gap (see
        ``"n_gaps"``); ``"n_gaps"`` (...) int.
    """
    angle = as_float_array(angle_deg, "angle_deg")
    if angle.shape[-1] < 2:
        raise ValueError(f"angle_deg needs at least 2 samples, got {angle.shape[-1]}")
    ends = gap_end_mask(as_bool_mask(received, "received", angle.shape))
    step = np.zeros(angle.shape)
    step[..., 1:] = np.abs(np.diff(angle, axis=-1))
    step = np.where(ends, step, 0.0)
    n_gaps = np.count_nonzero(ends, axis=-1)
    return {"step_deg": step, "gap_end": ends, "max_deg": step.max(axis=-1),
            "mean_deg": step.sum(axis=-1) / np.maximum(n_gaps, 1), "n_gaps": n_gaps}


def quat_gap_end_steps_deg(quat, received) -> dict[str, np.ndarray]:
    """:func:`gap_end_steps_deg` for orientations: rotation angle between ``q_{e−1}`` and ``q_e`` (°).

    ``quat`` (..., T, 4), ``received`` (..., T); same keys as :func:`gap_end_steps_deg`.
    """
    quat = as_float_array(quat, "quat", last_dim=4, min_ndim=2)
    if quat.shape[-2] < 2:
        raise ValueError(f"quat needs at least 2 samples along time, got {quat.shape[-2]}")
    ends = gap_end_mask(as_bool_mask(received, "received", quat.shape[:-1]))
    step = np.zeros(quat.shape[:-1])
    step[..., 1:] = np.degrees(quat_ops.angle_between(quat[..., 1:, :], quat[..., :-1, :]))
    step = np.where(ends, step, 0.0)
    n_gaps = np.count_nonzero(ends, axis=-1)
    return {"step_deg": step, "gap_end": ends, "max_deg": step.max(axis=-1),
            "mean_deg": step.sum(axis=-1) / np.maximum(n_gaps, 1), "n_gaps": n_gaps}


def _windows_without_gap_ends(ends: np.ndarray, n_windows: int, width: int) -> np.ndarray:
    """Windows of samples ``i … i + width`` that do not hold a gap-end step, ``(..., n_windows)``.

    The step lives between samples ``e − 1`` and ``e``, so it is inside window ``i`` when
    ``i + 1 <= e <= i + width``.
    """
    touched = np.zeros(ends.shape[:-1] + (n_windows,), dtype=bool)
    for shift in range(1, width + 1):
        touched |= ends[..., shift:shift + n_windows]
    return ~touched


def angle_jitter_rms_deg(angle_deg, fs, received) -> np.ndarray:
    """Continuous jitter (°/s³): RMS third difference of an angle trace, gap-end steps excluded.

    :func:`angle_jerk_rms_deg` without the third-difference windows that contain a gap-end
    step (the three windows ``x[i..i+3]`` with ``i ∈ [e − 3, e − 1]`` for each gap end ``e``),
    so it measures how jittery the output is between those steps — during gaps, during the
    return to the data and with data.  With ``received`` all True it equals
    :func:`angle_jerk_rms_deg`.

    Parameters
    ----------
    angle_deg : array_like, shape (..., T)
        Angle or angle error (°), ``T >= 4``.
    fs : float
        Sampling rate (Hz).
    received : array_like of bool, shape (..., T)

    Returns
    -------
    numpy.ndarray, shape (...)

    Raises
    ------
    ValueError
        If some record has no window left (gaps end on every few samples).
    """
    angle = as_float_array(angle_deg, "angle_deg")
    fs = check_positive(fs, "fs")
    if angle.shape[-1] < 4:
        raise ValueError(f"angle_deg needs at least 4 samples, got {angle.shape[-1]}")
    ends = gap_end_mask(as_bool_mask(received, "received", angle.shape))
    jerk = np.diff(angle, n=3, axis=-1) * fs**3
    keep = _windows_without_gap_ends(ends, jerk.shape[-1], 3)
    return _masked_rms(jerk**2, keep)


def angular_jitter_rms_deg(quat, fs, received) -> np.ndarray:
    """:func:`angular_jerk_rms_deg` without the windows that hold a gap-end step (°/s³).

    The jerk window ``j`` spans quaternions ``j … j + 3`` (angular velocity from consecutive
    pairs, then its second difference); windows with ``j ∈ [e − 3, e − 1]`` for a gap end ``e``
    are left out.  ``quat`` (..., T, 4) with ``T >= 4``; ``received`` (..., T).
    """
    quat = as_float_array(quat, "quat", last_dim=4, min_ndim=2)
    fs = check_positive(fs, "fs")
    if quat.shape[-2] < 4:
        raise ValueError(f"quat needs at least 4 samples along time, got {quat.shape[-2]}")
    ends = gap_end_mask(as_bool_mask(received, "received", quat.shape[:-1]))
    jerk = _angular_jerk(quat, fs)
    keep = _windows_without_gap_ends(ends, jerk.shape[-2], 3)
    return np.degrees(_masked_rms(np.sum(jerk**2, axis=-1), keep))


def _masked_rms(squares: np.ndarray, keep: np.ndarray) -> np.ndarray:
    count = np.count_nonzero(keep, axis=-1)
    if np.any(count == 0):
        bad = tuple(int(i) for i in np.argwhere(count == 0)[0])
        raise ValueError(f"no jerk window is free of a gap-end step{f' (batch index {bad})' if bad else ''}; "
                         "the jitter is undefined")
    return np.sqrt(np.sum(np.where(keep, squares, 0.0), axis=-1) / count)
