"""Angles and error figures for orientation estimates under packet loss (paper 001, Sections II, IV).

* Segment pitch: elevation of the segment axis (the node's body x axis, pointing distally)
  above the horizontal plane, ``asin(z_E · (q ⊗ x_B ⊗ q*))``.
* Elbow angle: the paper defines it as the difference between forearm and humerus pitch
  (Section II, Fig. 1), ideally 0° during an arm extension with aligned segments.  The 3-D
  angle between the two segment axes is offered too; the two agree for motion in a vertical
  plane.
* BROAD errors (:func:`broad_errors_deg`, :func:`broad_rmse_deg`): total, heading and
  inclination error of the earth-frame error quaternion, as defined by the BROAD benchmark
  (Laidig et al., Data 6(7):72, 2021) and its example code.
* Smoothness: RMS angular jerk of an orientation sequence (third time derivative of the
  rotation angle, from finite differences of the body angular velocity), in °/s³.  The
  paper calls single-frame estimates "jerky" without a number; this is ours.  Over a record
  with losses it is dominated by the single step an estimator makes when data return, so it
  is split into the step at each gap's end (:func:`gap_end_steps_deg`) and the continuous
  jitter without those steps (:func:`angle_jitter_rms_deg`).
* Under loss: :func:`quantile_error` (a quantile instead of a maximum that shrinks as loss
  rises) and :func:`error_by_phase` (lost samples, the seconds after a gap, the rest).

Every function returns degrees or seconds, as its name says, and broadcasts over leading
batch dimensions ``(..., T)``.
"""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_bool_mask, as_float_array, check_nonnegative, check_nonzero_norm, check_positive

#: Body-frame axis along the segment (pointing distally), shared with :mod:`wsnlib.sim.arm`.
SEGMENT_AXIS = np.array([1.0, 0.0, 0.0])


def segment_pitch_deg(quat, axis=SEGMENT_AXIS) -> np.ndarray:
    """Elevation (°) of the body-frame ``axis`` above the horizontal plane, ``(..., T, 4) → (..., T)``."""
    quat = as_float_array(quat, "quat", last_dim=4)
    direction = quat_ops.rotate(quat, np.asarray(axis, dtype=float))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    return np.degrees(np.arcsin(np.clip(direction[..., 2], -1.0, 1.0)))


def elbow_angle_deg(quat_humerus, quat_forearm, method: str = "pitch_difference") -> np.ndarray:
    """Elbow joint angle (°) from the orientations of the humerus and forearm nodes.

    Parameters
    ----------
    quat_humerus, quat_forearm : array_like, shape (..., T, 4)
    method : {"pitch_difference", "axis_angle"}
        ``"pitch_difference"`` is the paper's definition, forearm pitch minus humerus pitch
        (signed).  ``"axis_angle"`` is the unsigned 3-D angle between the two segment axes.
    """
    if method == "pitch_difference":
        return segment_pitch_deg(quat_forearm) - segment_pitch_deg(quat_humerus)
    if method == "axis_angle":
        a = quat_ops.rotate(as_float_array(quat_humerus, "quat_humerus", last_dim=4), SEGMENT_AXIS)
        b = quat_ops.rotate(as_float_array(quat_forearm, "quat_forearm", last_dim=4), SEGMENT_AXIS)
        cross = np.linalg.norm(np.cross(a, b), axis=-1)
        return np.degrees(np.arctan2(cross, np.sum(a * b, axis=-1)))
    raise ValueError(f"method must be 'pitch_difference' or 'axis_angle', got {method!r}")


def orientation_error_deg(quat_est, quat_true) -> np.ndarray:
    """Total orientation error (°): rotation angle between estimate and truth, ``(..., T)``."""
    quat_est = as_float_array(quat_est, "quat_est", last_dim=4)
    quat_true = as_float_array(quat_true, "quat_true", last_dim=4)
    return np.degrees(quat_ops.angle_between(quat_est, quat_true))


# --- BROAD's error metrics ------------------------------------------------------------------
# Laidig, Caruso, Cereatti, Seel, "BROAD—A Benchmark for Robust Inertial Orientation
# Estimation", Data 6(7):72, 2021, doi:10.3390/data6070072, and its example code
# (github.com/dlaidig/broad, example_code/broad_utils.py: calculateErrorQuatEarth,
# calculateTotalError, calculateHeadingError, calculateInclinationError, calculateRMSE).

#: Keys of :func:`broad_errors_deg` and :func:`broad_rmse_deg`.
BROAD_ERROR_KEYS = ("total", "heading", "inclination")


def broad_errors_deg(quat_est, quat_ref) -> dict[str, np.ndarray]:
    """BROAD's total, heading and inclination errors (°) per sample, ``(..., T, 4) → (..., T)``.

    As in BROAD's ``broad_utils.py``: both inputs are normalised, the error quaternion is
    expressed in the earth frame, ``q_e = q_est ⊗ q_ref*`` (``calculateErrorQuatEarth``), and
    with ``q_e = [w, x, y, z]`` (z is the vertical of ENU)

    * total = ``2·acos(|w|)``, the rotation angle of ``q_e``;
    * heading = ``2·atan(|z / w|)``, the angle of the rotation about the vertical axis in
      ``q_e`` (its twist about earth z);
    * inclination = ``2·acos(√(w² + z²))``, the remaining rotation about a horizontal axis
      (the tilt error).

    They are evaluated in the equivalent ``atan2`` forms, ``2·atan2(‖(x, y, z)‖, |w|)``,
    ``2·atan2(|z|, |w|)`` and ``2·atan2(‖(x, y)‖, ‖(w, z)‖)``, which stay accurate near 0 where
    ``acos`` loses digits; they agree with BROAD's formulas except at ``w = z = 0`` (an error of
    exactly 180° about a horizontal axis), where BROAD's heading is 0/0 and ours is 0.

    Parameters
    ----------
    quat_est : array_like, shape (..., T, 4)
        Estimated orientation ``[w, x, y, z]``, body → ENU; must be finite (an estimate that
        is NaN is an error to report, not a sample to skip).
    quat_ref : array_like, shape (..., T, 4)
        Reference orientation; rows holding NaN (BROAD: optical markers lost) are expected.
        Broadcasts against ``quat_est``.

    Returns
    -------
    dict[str, numpy.ndarray]
        ``"total"``, ``"heading"``, ``"inclination"``: degrees in ``[0, 180]``, shape
        ``(..., T)``; NaN exactly where the reference is NaN.
    """
    est = as_float_array(quat_est, "quat_est", last_dim=4)
    est = est / check_nonzero_norm(est, "quat_est", "a zero quaternion is not a rotation")[..., None]
    ref = quat_ops.as_quat_with_gaps(quat_ref, "quat_ref")
    ref = ref / np.linalg.norm(ref, axis=-1, keepdims=True)
    try:
        np.broadcast_shapes(est.shape, ref.shape)
    except ValueError as exc:
        raise ValueError(f"quat_est {est.shape} and quat_ref {ref.shape} do not broadcast") from exc
    w, x, y, z = np.moveaxis(quat_ops.multiply(est, quat_ops.conjugate(ref)), -1, 0)
    abs_w, abs_z = np.abs(w), np.abs(z)
    errors = {
        "total": 2.0 * np.arctan2(np.sqrt(x * x + y * y + z * z), abs_w),
        "heading": 2.0 * np.arctan2(abs_z, abs_w),
        "inclination": 2.0 * np.arctan2(np.hypot(x, y), np.hypot(w, z)),
    }
    return {key: np.degrees(value) for key, value in errors.items()}


def broad_rmse_deg(quat_est, quat_ref, movement) -> dict[str, np.ndarray]:
    """BROAD's RMSE (°) of the total, heading and inclination errors over the movement phase.

    What BROAD's ``calculateRMSE`` does: the errors of :func:`broad_errors_deg` on the samples
    where ``movement`` is True, RMS with NaN excluded (their ``rmse`` uses ``np.nanmean``), so
    samples whose reference is NaN simply do not count — they are not interpolated.  No heading
    offset is removed: BROAD evaluates every algorithm, 6D or 9D, in the ENU frame of the
    reference (its example only turns the Madgwick/Mahony output from their north-west-up earth
    frame into ENU by a fixed 90° rotation about the vertical), so an estimator without
    magnetometer shows its heading drift.

    Parameters
    ----------
    quat_est, quat_ref : array_like, shape (..., T, 4)
        As in :func:`broad_errors_deg`.
    movement : array_like of bool, shape (T,) or (..., T)
        Samples that count; broadcast against the errors.

    Returns
    -------
    dict[str, numpy.ndarray]
        ``"total"``, ``"heading"``, ``"inclination"``: RMSE in degrees, shape ``(...)``.

    Raises
    ------
    ValueError
        If, for some batch element, no sample is both in ``movement`` and has a reference
        (never a silent NaN); on a non-boolean ``movement`` or the input errors of
        :func:`broad_errors_deg`.
    """
    errors = broad_errors_deg(quat_est, quat_ref)
    shape = errors["total"].shape
    movement = np.asarray(movement)
    if movement.dtype != np.bool_:
        raise ValueError(f"movement must be a boolean mask, got dtype {movement.dtype}")
    try:
        movement = np.broadcast_to(movement, shape)
    except ValueError as exc:
        raise ValueError(f"movement has shape {movement.shape}, which does not fit the errors' {shape}") from exc
    valid = movement & ~np.isnan(errors["total"])
    count = np.count_nonzero(valid, axis=-1)
    if np.any(count == 0):
        bad = tuple(int(i) for i in np.argwhere(count == 0)[0])
        where = f" (batch index {bad})" if bad else ""
        raise ValueError(
            f"no sample is both in the movement phase and has a reference (non-NaN quat_ref){where}; "
            f"the RMSE is undefined"
        )
    return {key: np.sqrt(np.sum(np.where(valid, value, 0.0) ** 2, axis=-1) / count) for key, value in errors.items()}


def max_abs_error(error, start: int = 0, where=None) -> np.ndarray:
    """Largest ``|error|`` over time (last axis) from sample ``start`` on, ``(..., T) → (...)``.

    Parameters
    ----------
    error : array_like, shape (..., T)
    start : int
        First sample considered.
    where : array_like of bool, shape (..., T), optional
        Only samples where this is True count (e.g. the ``received`` mask, to judge what an
        estimator produces when it has data).  A sequence with no counted sample gives 0.
    """
    error = as_float_array(error, "error")
    _check_start(start, error.shape[-1])
    magnitude = np.abs(error)
    if where is not None:
        where = np.asarray(where)
        if where.dtype != np.bool_:
            raise ValueError(f"where must be a boolean mask, got dtype {where.dtype}")
        magnitude = np.where(where, magnitude, 0.0)
    return np.max(magnitude[..., start:], axis=-1)


def time_above_s(error, threshold, fs, start: int = 0) -> np.ndarray:
    """Total time (s) during which ``|error| > threshold`` from sample ``start`` on.

    Parameters
    ----------
    error : array_like, shape (..., T)
        Error trace, e.g. elbow angle error in degrees.
    threshold : float
        Same unit as ``error``.
    fs : float
        Sampling rate (Hz).
    start : int
        First sample counted (e.g. the sample at which a loss begins).
    """
    error = as_float_array(error, "error")
    threshold = check_nonnegative(threshold, "threshold")
    fs = check_positive(fs, "fs")
    _check_start(start, error.shape[-1])
    return np.count_nonzero(np.abs(error[..., start:]) > threshold, axis=-1) / fs


def recovery_time_s(error, threshold, fs, start: int) -> np.ndarray:
    """Time (s) from sample ``start`` until ``|error|`` falls below ``threshold`` for good.

    It is the time of the last sample above the threshold, plus one sample period, minus
    the time of ``start``; 0 when the error never exceeds the threshold from ``start`` on.
    If the error is still above the threshold at the last sample, the result is ``inf``
    (it did not recover within the record) — an explicit value, never NaN.

    Parameters
    ----------
    error : array_like, shape (..., T)
    threshold : float
    fs : float
        Sampling rate (Hz).
    start : int
        Reference sample, e.g. the first received sample after a burst of losses.
    """
    error = as_float_array(error, "error")
    threshold = check_nonnegative(threshold, "threshold")
    fs = check_positive(fs, "fs")
    n = error.shape[-1]
    _check_start(start, n)
    above = np.abs(error[..., start:]) > threshold
    any_above = above.any(axis=-1)
    # Index of the last sample above the threshold (counted from ``start``).
    last = (n - start - 1) - np.argmax(above[..., ::-1], axis=-1)
    seconds = np.where(any_above, (last + 1) / fs, 0.0)
    return np.where(above[..., -1], np.inf, seconds)


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


def quantile_error(error, q: float = 0.95, where=None) -> np.ndarray:
    """Quantile ``q`` of ``|error|`` over time (last axis), counting only samples in ``where``.

    A replacement for :func:`max_abs_error` over received samples: the maximum of fewer samples
    is smaller, so a maximum over the received samples shrinks as loss rises even when nothing
    improves, while a quantile estimates the same number at every loss rate (for losses that
    do not pick the worst samples).

    Parameters
    ----------
    error : array_like, shape (..., T)
    q : float
        Quantile in [0, 1] (0.95 = the 95th percentile; 1 = the maximum).
    where : array_like of bool, shape (..., T), optional
        Samples that count (e.g. ``received``); default all.

    Returns
    -------
    numpy.ndarray, shape (...)
        Linear-interpolation quantile (numpy's default), in the unit of ``error``.

    Raises
    ------
    ValueError
        If some record has no counted sample.
    """
    error = as_float_array(error, "error")
    if isinstance(q, bool) or not np.isscalar(q) or not 0.0 <= float(q) <= 1.0:
        raise ValueError(f"q must be a number in [0, 1], got {q!r}")
    magnitude = np.abs(error)
    if where is not None:
        where = as_bool_mask(where, "where", error.shape)
        count = np.count_nonzero(where, axis=-1)
        if np.any(count == 0):
            bad = tuple(int(i) for i in np.argwhere(count == 0)[0])
            raise ValueError(f"no sample counts (where is all False){f' at batch index {bad}' if bad else ''}")
        magnitude = np.where(where, magnitude, np.nan)
        return np.nanquantile(magnitude, float(q), axis=-1)
    return np.quantile(magnitude, float(q), axis=-1)


#: Phases of :func:`error_by_phase`, in order.
PHASES = ("lost", "after_gap", "steady")


def error_by_phase(error_deg, received, fs, *, after_s: float = 2.0, statistic: str = "rms") -> dict[str, np.ndarray]:
    """Mean or RMS of an error trace split by phase: lost samples, just after a gap, the rest.

    Phases (disjoint; together every sample):

    * ``"lost"``: samples not received (the estimator runs without data);
    * ``"after_gap"``: received samples within ``after_s`` seconds of a gap's end, i.e. from
      the first received sample ``e`` after a gap to ``e + round(after_s·fs) − 1`` (the return
      to the data);
    * ``"steady"``: the other received samples.

    Samples whose error is NaN (e.g. no reference) are skipped in every phase.

    Parameters
    ----------
    error_deg : array_like, shape (..., T)
        Error trace (°); NaN allowed (missing reference), inf not.
    received : array_like of bool, shape (..., T)
    fs : float
        Sampling rate (Hz).
    after_s : float
        Length of the after-gap phase (s), >= 0.
    statistic : {"rms", "mean"}
        RMS of the error, or mean of ``|error|``.

    Returns
    -------
    dict
        For each phase in :data:`PHASES` its value (°, shape (...)) and ``"n_<phase>"`` its
        number of samples (int, shape (...)).  A phase without a sample has value NaN and count
        0 — explicitly, so pool over records with the counts, e.g.
        ``sqrt(Σ n·v² / Σ n)`` for RMS.
    """
    error = np.asarray(error_deg, dtype=float)
    if error.ndim < 1:
        raise ValueError("error_deg must have a time axis")
    if np.any(np.isinf(error)):
        raise ValueError("error_deg contains inf")
    if statistic not in ("rms", "mean"):
        raise ValueError(f"statistic must be 'rms' or 'mean', got {statistic!r}")
    fs = check_positive(fs, "fs")
    window = int(round(check_nonnegative(after_s, "after_s") * fs))
    received = as_bool_mask(received, "received", error.shape)
    ends = gap_end_mask(received)
    # Samples since the latest gap end (large before the first one).
    n = error.shape[-1]
    index = np.arange(n)
    last_end = np.maximum.accumulate(np.where(ends, index, -n - window - 1), axis=-1)
    after = received & (index - last_end < window)
    phases = {"lost": ~received, "after_gap": after, "steady": received & ~after}
    valid = ~np.isnan(error)
    value = np.abs(error) if statistic == "mean" else error**2
    out: dict[str, np.ndarray] = {}
    for name, mask in phases.items():
        mask = mask & valid
        count = np.count_nonzero(mask, axis=-1)
        total = np.sum(np.where(mask, value, 0.0), axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        out[name] = np.sqrt(mean) if statistic == "rms" else mean
        out[f"n_{name}"] = count
    return out


def _check_start(start: int, n_samples: int) -> None:
    if not isinstance(start, int | np.integer) or not 0 <= start < n_samples:
        raise ValueError(f"start must be an integer sample index in [0, {n_samples}), got {start!r}")


#: Column names of :func:`loss_figures_of_merit`, with units.
MAX_ERROR = "max error after loss (°)"
MEAN_ERROR = "mean |error| (°)"
TIME_ABOVE = "time above threshold (s)"
RECOVERY = "recovery time (s)"
JERK = "RMS jerk (°/s³)"
GAP_STEP_MAX = "max step at gap end (°)"
GAP_STEP_MEAN = "mean step at gap end (°)"
JITTER = "RMS jitter, gap ends excluded (°/s³)"
P95_ERROR = "95th percentile |error|, received (°)"


def loss_figures_of_merit(error_deg, *, fs, received, threshold_deg=5.0, start: int = 0,
                          recovery_start: int | None = None, extended: bool = False) -> dict[str, np.ndarray]:
    """The figures of merit used across notebooks for an angle error trace under loss.

    Parameters
    ----------
    error_deg : array_like, shape (..., T)
        Error of an angle (e.g. elbow angle minus its true value), degrees.
    fs : float
        Sampling rate (Hz).
    received : array_like of bool, shape (..., T)
        Loss mask of the node(s) behind the estimate; the maximum error counts only received
        samples (what the estimator produces when it has data).
    threshold_deg : float
        Threshold for the time-above and recovery figures.
    start : int
        First sample considered (e.g. where the loss begins).
    recovery_start : int, optional
        Sample from which recovery is timed (e.g. the first received sample after a burst).
        Left out when None (it means nothing for scattered losses).
    extended : bool
        Also return the split of the jerk into the step at gap ends and the continuous jitter,
        and a quantile in place of the maximum (see below).

    Returns
    -------
    dict[str, numpy.ndarray]
        :data:`MAX_ERROR` (°, received samples from ``start``), :data:`MEAN_ERROR` (°, mean
        ``|error|`` over all samples from ``start``), :data:`TIME_ABOVE` (s, all samples
        from ``start``: during a gap the user still sees an estimate),
        :data:`RECOVERY` (s, only with ``recovery_start``; ``inf`` if never) and :data:`JERK`
        (°/s³, RMS third derivative of the error trace over the whole record), each of shape
        ``(...)``.  With ``extended``: :data:`GAP_STEP_MAX` and :data:`GAP_STEP_MEAN` (°, the
        step of the error at the gap ends of the whole record, :func:`gap_end_steps_deg`; 0
        without a closed gap), :data:`JITTER` (°/s³, :func:`angle_jitter_rms_deg`) and
        :data:`P95_ERROR` (°, 95th percentile of ``|error|`` over received samples from
        ``start``, :func:`quantile_error`).
    """
    error_deg = as_float_array(error_deg, "error_deg")
    received = np.asarray(received)
    if received.dtype != np.bool_:
        raise ValueError(f"received must be a boolean mask, got dtype {received.dtype}")
    result = {
        MAX_ERROR: max_abs_error(error_deg, start=start, where=np.broadcast_to(received, error_deg.shape)),
        MEAN_ERROR: np.mean(np.abs(error_deg[..., start:]), axis=-1),
        TIME_ABOVE: time_above_s(error_deg, threshold_deg, fs, start=start),
    }
    if recovery_start is not None:
        result[RECOVERY] = recovery_time_s(error_deg, threshold_deg, fs, start=recovery_start)
    result[JERK] = angle_jerk_rms_deg(error_deg, fs)
    if extended:
        full_received = np.broadcast_to(received, error_deg.shape)
        steps = gap_end_steps_deg(error_deg, full_received)
        result[GAP_STEP_MAX] = steps["max_deg"]
        result[GAP_STEP_MEAN] = steps["mean_deg"]
        result[JITTER] = angle_jitter_rms_deg(error_deg, fs, full_received)
        result[P95_ERROR] = quantile_error(error_deg[..., start:], 0.95, where=full_received[..., start:])
    return result


def summary_table(results: dict[str, dict[str, np.ndarray]], quantiles=(0.1, 0.9)):
    """Median and quantile range of Monte Carlo figures of merit, one row per estimator.

    Parameters
    ----------
    results : dict[str, dict[str, array_like]]
        Estimator name → figure name → values over realisations (any shape, flattened).
    quantiles : (float, float)
        Lower and upper quantile of the range columns.

    Returns
    -------
    pandas.DataFrame
        Columns ``(figure, "median")``, ``(figure, "q10")``, ``(figure, "q90")`` (named after
        the quantiles), index = estimator names, in the order given.
    """
    import pandas as pd

    low, high = quantiles
    rows = {}
    for name, figures in results.items():
        row = {}
        for figure, values in figures.items():
            values = np.ravel(np.asarray(values, dtype=float))
            row[(figure, "median")] = float(np.median(values))
            row[(figure, f"q{round(100 * low)}")] = float(np.quantile(values, low))
            row[(figure, f"q{round(100 * high)}")] = float(np.quantile(values, high))
        rows[name] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.columns = pd.MultiIndex.from_tuples(table.columns, names=["figure", "statistic"])
    return table


def burst_response(error_lossy_deg, error_lossless_deg, burst_ends, fs, *, window_s: float = 2.0,
                   threshold_deg: float = 1.0, min_valid_fraction: float = 0.5) -> dict[str, np.ndarray]:
    """How much a loss burst adds to the error, burst by burst, against the same run without loss.

    For each burst, the *increase* ``e_lossy − e_lossless`` is examined over the ``window_s``
    seconds that follow the burst's end (the first received sample after it):

    * ``mean_increase_deg``: mean increase over the window;
    * ``peak_increase_deg``: largest increase in the window;
    * ``recovery_s``: time until the increase falls below ``threshold_deg`` for the rest of
      the window (0 if it never exceeds it; ``inf`` if it is still above at the window's last
      valid sample).

    Error traces may hold NaN where the reference is missing (e.g. optical markers lost); those
    samples are skipped.  A burst whose window has fewer than ``min_valid_fraction`` valid
    samples, or whose window runs past the record's end, is dropped and counted in ``dropped``,
    so every returned value is a number.

    Parameters
    ----------
    error_lossy_deg, error_lossless_deg : array_like, shape (..., T)
        Error magnitudes (°) with and without loss; broadcast together.
    burst_ends : array_like of int, shape (B,)
        Index of the first received sample after each burst.
    fs : float
        Sampling rate (Hz).
    window_s, threshold_deg, min_valid_fraction : float

    Returns
    -------
    dict
        ``mean_increase_deg``, ``peak_increase_deg``, ``recovery_s``: arrays ``(..., B_kept)``;
        ``kept``: indices of the kept bursts; ``dropped``: how many were dropped.
    """
    lossy = np.asarray(error_lossy_deg, dtype=float)
    lossless = np.asarray(error_lossless_deg, dtype=float)
    increase = lossy - lossless
    fs = check_positive(fs, "fs")
    window = int(round(check_positive(window_s, "window_s") * fs))
    threshold_deg = check_nonnegative(threshold_deg, "threshold_deg")
    ends = np.asarray(burst_ends)
    if ends.ndim != 1 or not np.issubdtype(ends.dtype, np.integer):
        raise ValueError("burst_ends must be a 1-D array of sample indices")
    n = increase.shape[-1]
    in_range = (ends >= 0) & (ends + window <= n)
    segments = np.stack([increase[..., e:e + window] for e in ends[in_range]], axis=-2) if in_range.any() \
        else np.empty(increase.shape[:-1] + (0, window))
    valid = np.isfinite(segments)
    enough = valid.mean(axis=-1) >= min_valid_fraction                       # (..., B)
    keep = np.all(enough, axis=tuple(range(enough.ndim - 1))) if enough.ndim > 1 else enough
    kept = np.flatnonzero(in_range)[keep]
    segments, valid = segments[..., keep, :], valid[..., keep, :]
    filled = np.where(valid, segments, 0.0)
    count = valid.sum(axis=-1)
    mean_increase = filled.sum(axis=-1) / np.maximum(count, 1)
    peak_increase = np.where(valid, segments, -np.inf).max(axis=-1, initial=-np.inf)
    above = valid & (segments > threshold_deg)
    last = (window - 1) - np.argmax(above[..., ::-1], axis=-1)
    recovery = np.where(above.any(axis=-1), (last + 1) / fs, 0.0)
    last_valid = (window - 1) - np.argmax(valid[..., ::-1], axis=-1)
    still_above = np.take_along_axis(above, last_valid[..., None], axis=-1)[..., 0]
    recovery = np.where(still_above, np.inf, recovery)
    return {"mean_increase_deg": mean_increase, "peak_increase_deg": peak_increase, "recovery_s": recovery,
            "kept": kept, "dropped": int(ends.size - kept.size)}


# --- Localisation accuracy (paper 002, Section 4.2) ------------------------------------------


def position_error(est, true) -> np.ndarray:
    """Euclidean distance between estimated and true positions, eq. (11) of paper 002.

    ``d_E(ŝ_t, s_t)``, ``(..., 3) → (...)``, in the unit of the inputs; the paper's PE is its
    mean over the samples of a movement, ``position_error(est, true).mean(axis=-1)``.
    ``est`` and ``true`` broadcast together.
    """
    est = as_float_array(est, "est", last_dim=3)
    true = as_float_array(true, "true", last_dim=3)
    try:
        np.broadcast_shapes(est.shape, true.shape)
    except ValueError as exc:
        raise ValueError(f"est {est.shape} and true {true.shape} do not broadcast") from exc
    return np.linalg.norm(est - true, axis=-1)


def precision_at_accuracy(errors, accuracies) -> np.ndarray:
    """Precision as a function of accuracy (paper 002, Section 4.2): the errors' empirical CDF.

    Precision at accuracy ``a`` is the fraction of ``errors`` that are ``<= a`` ("a precision
    of 60 % with an accuracy of 10 cm means that 60 % of the estimation errors … are lower than
    or equal to 10 cm").

    Parameters
    ----------
    errors : array_like, any shape
        Position errors (e.g. :func:`position_error`), all pooled; finite, at least one.
    accuracies : array_like, any shape
        Accuracy values, same unit as ``errors``.

    Returns
    -------
    numpy.ndarray, shape of ``accuracies``
        Fractions in ``[0, 1]``, non-decreasing in the accuracy.
    """
    errors = np.sort(as_float_array(errors, "errors", min_ndim=0).ravel())
    if errors.size == 0:
        raise ValueError("errors must hold at least one value")
    accuracies = np.asarray(accuracies, dtype=float)
    if np.any(np.isnan(accuracies)):
        raise ValueError("accuracies contains NaN")
    return np.searchsorted(errors, accuracies, side="right") / errors.size
