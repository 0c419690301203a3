"""Angles and orientation errors (paper 001, Sections II, IV; the BROAD benchmark).

* Segment pitch: elevation of the segment axis (the node's body x axis, pointing distally)
  above the horizontal plane, ``asin(z_E · (q ⊗ x_B ⊗ q*))``.
* Elbow angle: the paper defines it as the difference between forearm and humerus pitch
  (Section II, Fig. 1), ideally 0° during an arm extension with aligned segments.  The 3-D
  angle between the two segment axes is offered too; the two agree for motion in a vertical
  plane.
* BROAD errors (:func:`broad_errors_deg`, :func:`broad_rmse_deg`): total, heading and
  inclination error of the earth-frame error quaternion, as defined by the BROAD benchmark
  (Laidig et al., Data 6(7):72, 2021) and its example code.

Every function returns degrees and broadcasts over leading batch dimensions ``(..., T)``.
"""

from __future__ import annotations

import math

import numpy as np

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_bool_mask, as_float_array
from wsnlib.metrics._kernels import error_angle_arguments

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


# --- BROAD's error metrics ------------------------------------------------------------------
# Laidig, Caruso, Cereatti, Seel, "BROAD—A Benchmark for Robust Inertial Orientation
# Estimation", Data 6(7):72, 2021, doi:10.3390/data6070072, and its example code
# (github.com/dlaidig/broad, example_code/broad_utils.py: calculateErrorQuatEarth,
# calculateTotalError, calculateHeadingError, calculateInclinationError, calculateRMSE).

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
    est = quat_ops.normalize(quat_est, "quat_est")
    ref = quat_ops.as_quat_with_gaps(quat_ref, "quat_ref", unit=True)
    try:
        shape = np.broadcast_shapes(est.shape, ref.shape)
    except ValueError as exc:
        raise ValueError(f"quat_est {est.shape} and quat_ref {ref.shape} do not broadcast") from exc
    # Rows (M, T, 4): the estimates, and one reference for all of them (a single recording's, (T, 4) or
    # (1, …, T, 4)) unless it has a batch of its own.
    n_t, n_rows = (shape[-2], math.prod(shape[:-2])) if len(shape) > 1 else (1, 1)
    est_rows = np.ascontiguousarray(np.broadcast_to(est, shape)).reshape(n_rows, n_t, 4)
    one_recording = ref.ndim > 1 and ref.shape[-2] == n_t and ref.size == 4 * n_t
    ref_rows = ref.reshape(1, n_t, 4) if one_recording else (
        np.ascontiguousarray(np.broadcast_to(ref, shape)).reshape(n_rows, n_t, 4))
    # ‖(x, y, z)‖, |w|, |z|, hypot(x, y), hypot(w, z) of q_est ⊗ q_ref*, each (..., T)
    args = np.empty((5,) + shape[:-1])
    error_angle_arguments(est_rows, ref_rows, args.reshape(5, n_rows, n_t))
    errors = {
        "total": 2.0 * np.arctan2(args[0], args[1]),
        "heading": 2.0 * np.arctan2(args[2], args[1]),
        "inclination": 2.0 * np.arctan2(args[3], args[4]),
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
    return rmse_of_errors_deg(broad_errors_deg(quat_est, quat_ref), movement)


def rmse_of_errors_deg(errors, movement) -> dict[str, np.ndarray]:
    """:func:`broad_rmse_deg` from errors already computed by :func:`broad_errors_deg` (same keys, same
    rules: RMS over ``movement`` with NaN excluded; ``ValueError`` for a batch element with no such
    sample), for a caller that also needs the errors per sample."""
    movement = as_bool_mask(movement, "movement", errors["total"].shape)
    valid = movement & ~np.isnan(errors["total"])
    count = np.count_nonzero(valid, axis=-1)
    if np.any(count == 0):
        bad = tuple(int(i) for i in np.argwhere(count == 0)[0])
        where = f" (batch index {bad})" if bad else ""
        raise ValueError(f"no sample is both in the movement phase and has a reference (non-NaN quat_ref){where}; "
                         f"the RMSE is undefined")
    return {key: np.sqrt(np.sum(np.where(valid, value, 0.0) ** 2, axis=-1) / count) for key, value in errors.items()}
