"""Checkers for the notebooks' implementation exercises.

Each notebook hides one algorithm of :mod:`wsnlib` behind an exercise: the student writes the
function, then calls the checker here, which compares it with the library on random inputs
drawn from the ``rng`` passed in.  A checker returns an :class:`ExerciseReport` when the
student's function agrees everywhere and raises ``AssertionError`` with the first input on
which it does not (what was expected, what came back), so that the message says what to fix.
Arguments that are not functions or generators raise ``ValueError``.

Modules, one per paper, and the machinery they share:

* :mod:`wsnlib.exercises.orientation` — paper 001 (notebooks 01–05 and 10).
* :mod:`wsnlib.exercises.localisation` — paper 002 (notebooks 06–09).
* :mod:`wsnlib.exercises.checking` — :class:`ExerciseReport` and the comparison of cases.

Every checker is named ``check_<what the student writes>``, has the signature
``check_x(student_function, *, rng, n_cases=..., atol=...)`` and is re-exported here, so that
notebooks call ``exercises.check_x``.
"""

from wsnlib.exercises.checking import ExerciseReport
from wsnlib.exercises.localisation import (
    check_gated_pitch,
    check_mean_position_error,
    check_precision_at_accuracy,
    check_shepard_knn,
)
from wsnlib.exercises.orientation import (
    check_gain_after_gap,
    check_gyro_interpolation,
    check_knee_point,
    check_madgwick_step,
    check_slerp,
    check_slerp_weight,
    check_triad,
)

__all__ = ["ExerciseReport", "check_gain_after_gap", "check_gated_pitch", "check_gyro_interpolation",
           "check_knee_point", "check_madgwick_step", "check_mean_position_error", "check_precision_at_accuracy",
           "check_shepard_knn", "check_slerp", "check_slerp_weight", "check_triad"]
