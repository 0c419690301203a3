"""Smoothness of orientation and angle sequences: jerk, steps at gap ends, jitter (ours).

Smoothness: RMS angular jerk of an orientation sequence (third time derivative of the
rotation angle, from finite differences of the body angular velocity), in °/s³.  The paper
calls single-frame estimates "jerky" without a number; this is ours.  Over a record with
losses it is dominated by the single step an estimator makes when data return, so it is split
into the step at each gap's end (:func:`gap_end_steps_deg`) and the continuous jitter without
those steps (:func:`angle_jerk_rms_deg` given the ``received`` mask).

Every function broadcasts over leading batch dimensions ``(..., T)``.
"""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_bool_mask, as_float_array, check_positive
from wsnlib.metrics._kernels import rotation_steps, squared_jerk


def angular_jerk_rms_deg(quat, fs, received=None) -> np.ndarray:
    """RMS angular jerk (°/s³) of an orientation sequence ``(..., T, 4) → (...)``; with ``received``, its jitter.

    Body angular velocity from consecutive quaternions, ``ω_t = rotvec(q_t* ⊗ q_{t+1})·fs``,
    then jerk as the second finite difference of ω times ``fs²``.  Needs ``T >= 4``.
    A smooth estimate scores low; a noisy single-frame estimate scores high.

    With ``received`` (..., T), the continuous jitter: the jerk window ``j`` spans quaternions
    ``j … j + 3`` (angular velocity from consecutive pairs, then its second difference), and the
    windows with ``j ∈ [e − 3, e − 1]`` for a gap end ``e`` (they hold the gap-end step) are left
    out, as in :func:`angle_jerk_rms_deg`.
    """
    quat = as_float_array(quat, "quat", last_dim=4, min_ndim=2)
    fs = check_positive(fs, "fs")
    if quat.shape[-2] < 4:
        raise ValueError(f"quat needs at least 4 samples along time, got {quat.shape[-2]}")
    return np.degrees(_rms_without_gap_ends(_squared_angular_jerk(quat, fs), received, quat.shape[:-1]))


def _squared_angular_jerk(quat: np.ndarray, fs: float) -> np.ndarray:
    """Squared norms of the angular jerk vectors (rad²/s⁶), ``(..., T, 4) → (..., T − 3)``: the rate
    ``ω_t = rotvec(q_t* ⊗ q_{t+1})·fs`` (the step's angle ``2·atan2(sin, cos)`` of its half angle),
    its second difference times ``fs²``."""
    batch, n_t = quat.shape[:-2], quat.shape[-2]
    rows = np.ascontiguousarray(quat.reshape(-1, n_t, 4))  # (one memory layout: the kernel is compiled once)
    vector = np.empty((rows.shape[0], n_t - 1, 3))
    sin_half, cos_half = np.empty((rows.shape[0], n_t - 1)), np.empty((rows.shape[0], n_t - 1))
    rotation_steps(rows, vector, sin_half, cos_half)
    angle = 2.0 * np.arctan2(sin_half, cos_half)
    out = np.empty((rows.shape[0], n_t - 3))
    squared_jerk(vector, sin_half, angle, fs, fs**2, out)
    return out.reshape(batch + (n_t - 3,))


def angle_jerk_rms_deg(angle_deg, fs, received=None) -> np.ndarray:
    """RMS jerk (°/s³) of a scalar angle trace in degrees, ``(..., T) → (...)``; third difference.

    With ``received`` (..., T), the continuous jitter: the third-difference windows that contain
    a gap-end step (the three windows ``x[i..i+3]`` with ``i ∈ [e − 3, e − 1]`` for each gap end
    ``e``) are left out, so it measures how jittery the output is between those steps — during
    gaps, during the return to the data and with data.  With ``received`` all True it equals the
    jerk.

    Parameters
    ----------
    angle_deg : array_like, shape (..., T)
        Angle or angle error (°), ``T >= 4``.
    fs : float
        Sampling rate (Hz).
    received : array_like of bool, shape (..., T), optional

    Returns
    -------
    numpy.ndarray, shape (...)

    Raises
    ------
    ValueError
        If, with ``received``, some record has no window left (gaps end on every few samples).
    """
    angle_deg = as_float_array(angle_deg, "angle_deg")
    fs = check_positive(fs, "fs")
    if angle_deg.shape[-1] < 4:
        raise ValueError(f"angle_deg needs at least 4 samples, got {angle_deg.shape[-1]}")
    jerk = np.diff(angle_deg, n=3, axis=-1) * fs**3
    return _rms_without_gap_ends(jerk**2, received, angle_deg.shape)


# --- Smoothness split: the step at a gap's end vs continuous jitter (issue 12) -------------
# The RMS third difference over a whole record (``angle_jerk_rms_deg``) is dominated by the one
# step an estimator makes when data return after a gap: a single jump of s degrees enters three
# third-difference windows with weights 1, 3, 3 (…), i.e. adds about ``s·fs³·√(19/N)`` to the RMS
# of N windows, whatever the estimate does elsewhere.  The step (``gap_end_steps_deg``) and the
# jitter (the jerk functions given ``received``: ``_rms_without_gap_ends``) separate the two.


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


def _rms_without_gap_ends(squares: np.ndarray, received, shape: tuple) -> np.ndarray:
    """RMS over the jerk windows ``i … i + 3`` (last axis of ``squares``), those holding a gap-end
    step of ``received`` (shape ``shape``) left out: the step between samples ``e − 1`` and ``e`` is
    inside window ``i`` when ``i + 1 <= e <= i + 3``.  Every window without ``received``."""
    if received is None:
        return np.sqrt(np.mean(squares, axis=-1))
    ends = gap_end_mask(as_bool_mask(received, "received", shape))
    n_windows = squares.shape[-1]
    keep = ~np.any([ends[..., shift:shift + n_windows] for shift in (1, 2, 3)], axis=0)
    count = np.count_nonzero(keep, axis=-1)
    if np.any(count == 0):
        bad = tuple(int(i) for i in np.argwhere(count == 0)[0])
        raise ValueError(f"no jerk window is free of a gap-end step{f' (batch index {bad})' if bad else ''}; "
                         "the jitter is undefined")
    return np.sqrt(np.sum(np.where(keep, squares, 0.0), axis=-1) / count)


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
    return _steps_at(ends, step)


def quat_gap_end_steps_deg(quat, received) -> dict[str, np.ndarray]:
    """:func:`gap_end_steps_deg` for orientations: rotation angle between ``q_{e−1}`` and ``q_e`` (°).

    ``quat`` (..., T, 4), ``received`` (..., T); same keys as :func:`gap_end_steps_deg`.
    """
    quat = as_float_array(quat, "quat", last_dim=4, min_ndim=2)
    if quat.shape[-2] < 2:
        raise ValueError(f"quat needs at least 2 samples along time, got {quat.shape[-2]}")
    ends = gap_end_mask(as_bool_mask(received, "received", quat.shape[:-1]))
    step = np.zeros(quat.shape[:-1])
    at = np.nonzero(np.broadcast_to(ends, step.shape))  # only the gap ends count (_steps_at)
    before = (*at[:-1], at[-1] - 1)  # a gap end is never the first sample
    quat = np.broadcast_to(quat, step.shape + (4,))
    step[at] = np.degrees(quat_ops.angle_between(quat[at], quat[before]))
    return _steps_at(ends, step)


def _steps_at(ends: np.ndarray, step: np.ndarray) -> dict[str, np.ndarray]:
    """The dictionary of :func:`gap_end_steps_deg` from the gap ends and every sample's step."""
    step = np.where(ends, step, 0.0)
    n_gaps = np.count_nonzero(ends, axis=-1)
    return {"step_deg": step, "gap_end": ends, "max_deg": step.max(axis=-1),
            "mean_deg": step.sum(axis=-1) / np.maximum(n_gaps, 1), "n_gaps": n_gaps}
