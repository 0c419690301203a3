"""Old home of paper 002's posture study; the code now lives in :mod:`wsnlib.studies.posture`.

Every name is re-exported here (the same objects), so ``wsnlib.posture_study.study_inputs`` and
the other old import paths keep working.  New code imports from :mod:`wsnlib.studies.posture`.
"""

from wsnlib.studies.posture import (
    RADIO_ASSUMPTIONS,
    RadioSensitivity,
    StudyInputs,
    evaluate_chain,
    kinect_errors,
    perturbed_channel,
    pitch_errors_deg,
    radio_sensitivity,
    selected_errors,
    sensitivity_grid,
    study_inputs,
    true_joints_straight_arm,
    with_reference_error,
)

__all__ = [
    "RADIO_ASSUMPTIONS",
    "RadioSensitivity",
    "StudyInputs",
    "evaluate_chain",
    "kinect_errors",
    "perturbed_channel",
    "pitch_errors_deg",
    "radio_sensitivity",
    "selected_errors",
    "sensitivity_grid",
    "study_inputs",
    "true_joints_straight_arm",
    "with_reference_error",
]
