"""Angles, error figures and accuracy measures of both papers, one module per concern.

* :mod:`wsnlib.metrics.orientation` — segment pitch, elbow angle and the orientation errors of
  the BROAD benchmark: total, heading, inclination (paper 001, Sections II, IV).
* :mod:`wsnlib.metrics.smoothness` — RMS jerk, the step at each gap's end and the jitter
  without those steps (ours: the paper calls single-frame estimates "jerky" without a number).
* :mod:`wsnlib.metrics.loss` — figures of merit under loss: maximum, time above a threshold,
  recovery time, quantile, error by phase, :func:`loss_figures_of_merit`, burst response (per gap
  against the run without loss, or one burst per run against the error just before it).
* :mod:`wsnlib.metrics.position` — position error and precision at an accuracy (paper 002).

Every public name is re-exported here, so ``from wsnlib import metrics; metrics.x`` and
``from wsnlib.metrics import x`` work as before the split.  Every function returns degrees,
seconds or the unit of its inputs, as its name says, and broadcasts over leading batch
dimensions ``(..., T)``.
"""

from wsnlib.metrics.loss import (
    GAP_STEP_MAX,
    GAP_STEP_MEAN,
    JERK,
    JITTER,
    MAX_ERROR,
    MEAN_ERROR,
    P95_ERROR,
    PHASES,
    RECOVERY,
    TIME_ABOVE,
    burst_response,
    error_by_phase,
    loss_figures_of_merit,
    max_abs_error,
    quantile_error,
    recovery_time_s,
    single_burst_response,
    summary_table,
    time_above_s,
)
from wsnlib.metrics.orientation import (
    SEGMENT_AXIS,
    broad_errors_deg,
    broad_rmse_deg,
    elbow_angle_deg,
    rmse_of_errors_deg,
    segment_pitch_deg,
)
from wsnlib.metrics.position import position_error, precision_at_accuracy
from wsnlib.metrics.smoothness import (
    angle_jerk_rms_deg,
    angular_jerk_rms_deg,
    gap_end_mask,
    gap_end_steps_deg,
    quat_gap_end_steps_deg,
)

__all__ = ["GAP_STEP_MAX", "GAP_STEP_MEAN", "JERK", "JITTER", "MAX_ERROR", "MEAN_ERROR",
           "P95_ERROR", "PHASES", "RECOVERY", "SEGMENT_AXIS", "TIME_ABOVE", "angle_jerk_rms_deg",
           "angular_jerk_rms_deg", "broad_errors_deg", "broad_rmse_deg", "burst_response", "elbow_angle_deg",
           "error_by_phase", "gap_end_mask", "gap_end_steps_deg", "loss_figures_of_merit", "max_abs_error",
           "position_error", "precision_at_accuracy", "quantile_error", "quat_gap_end_steps_deg", "recovery_time_s",
           "rmse_of_errors_deg", "segment_pitch_deg", "single_burst_response", "summary_table", "time_above_s"]
