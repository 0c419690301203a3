"""Realistic disturbances for the IMU simulator and their calibration against BROAD.

* :mod:`wsnlib.sim.disturbance.model` — the model: acceleration-rich motion (a translation
  of the body) and magnetic disturbance (hard iron, soft iron, passing dipoles), drawn by
  :func:`draw_disturbance` from the Generator passed in and applied by
  :func:`apply_disturbance` (the hook of :func:`wsnlib.sim.imu.simulate_imu`).
* :mod:`wsnlib.sim.disturbance.calibration` — the table of TRIAD's errors recorded on BROAD
  and the grid fit that chose :data:`UNDISTURBED_BROAD` and :data:`DISTURBED_BROAD`.

Every public name is re-exported here, so ``from wsnlib.sim.disturbance import x`` works as
before the split.
"""

from wsnlib.sim.disturbance.calibration import (
    BROAD_CALIBRATED,
    BROAD_CALIBRATION_TRIALS,
    BROAD_GROUPS,
    BROAD_LINEAR_ACC_RMS,
    BROAD_TRIAD_ERROR_DEG,
    CALIBRATION_BASE,
    CALIBRATION_GRIDS,
    CALIBRATION_KINDS,
    CALIBRATION_TOLERANCE,
    DISTURBED_BROAD,
    DISTURBED_DIPOLE_MOMENT_AM2,
    ERROR_KINDS,
    SOFT_IRON_STD,
    UNDISTURBED_BROAD,
    broad_group,
    broad_triad_errors,
    broad_triad_statistics,
    calibrate_disturbance,
    error_statistics,
    error_table,
    simulated_triad_errors,
    triad_calibration_table,
)
from wsnlib.sim.disturbance.model import (
    DIPOLE_CONSTANT_UT_M3_PER_AM2,
    DIPOLE_MIN_DISTANCE_M,
    Disturbance,
    DisturbanceSignals,
    apply_disturbance,
    dipole_field_ut,
    draw_disturbance,
    translation_motion,
)

__all__ = [
    "BROAD_CALIBRATED", "BROAD_CALIBRATION_TRIALS", "BROAD_GROUPS", "BROAD_LINEAR_ACC_RMS", "BROAD_TRIAD_ERROR_DEG",
    "CALIBRATION_BASE", "CALIBRATION_GRIDS", "CALIBRATION_KINDS", "CALIBRATION_TOLERANCE",
    "DIPOLE_CONSTANT_UT_M3_PER_AM2", "DIPOLE_MIN_DISTANCE_M", "DISTURBED_BROAD", "DISTURBED_DIPOLE_MOMENT_AM2",
    "Disturbance", "DisturbanceSignals", "ERROR_KINDS", "SOFT_IRON_STD", "UNDISTURBED_BROAD", "apply_disturbance",
    "broad_group", "broad_triad_errors", "broad_triad_statistics", "calibrate_disturbance", "dipole_field_ut",
    "draw_disturbance", "error_statistics", "error_table", "simulated_triad_errors", "translation_motion",
    "triad_calibration_table",
]
