"""The checkers' shared machinery: the report of a passed check, argument checks, comparison.

A checker draws random cases from the ``rng`` passed in (:class:`_Case`: inputs, the
library's answer, a description of the inputs for the message) and compares the student's
function with the library on each; the first disagreement raises ``AssertionError`` saying
what was expected and what came back.  :func:`_checker` makes a checker of the function that
draws one case.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib import fixed_order
from wsnlib._validation import check_count, check_positive, check_rng


@dataclass(frozen=True)
class ExerciseReport:
    """Outcome of a passed check.

    Attributes
    ----------
    exercise : str
        What was checked, e.g. ``"slerp_weight"``.
    n_cases : int
        Number of random inputs compared.
    max_abs_difference : float
        Largest absolute difference from the library over all cases (units of the output).
    """

    exercise: str
    n_cases: int
    max_abs_difference: float

    def __str__(self) -> str:
        return (f"{self.exercise}: passed on {self.n_cases} random cases "
                f"(largest difference from wsnlib {self.max_abs_difference:.2e})")


# ------------------------------------------------------------------------------------------
# Shared helpers
# ------------------------------------------------------------------------------------------


def _as_output(value, shape: tuple[int, ...], exercise: str, inputs: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise AssertionError(f"{exercise}: your function returned {value!r} for {inputs}, "
                             f"which is not an array of numbers ({error})") from None
    if arr.shape != shape:
        raise AssertionError(f"{exercise}: your function returned shape {arr.shape} for {inputs}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise AssertionError(f"{exercise}: your function returned non-finite values {arr} for {inputs}")
    return arr


def _compare(got: np.ndarray, expected: np.ndarray, atol: float, exercise: str, inputs: str, hint: str = "") -> float:
    difference = float(np.max(np.abs(got - expected))) if got.size else 0.0
    if not difference <= atol:
        message = (f"{exercise}: for {inputs}\n  expected {np.array2string(expected, precision=6)}\n"
                   f"  got      {np.array2string(got, precision=6)}\n  (largest difference {difference:.3g} > "
                   f"tolerance {atol:g})")
        raise AssertionError(message + (f"\n  Hint: {hint}" if hint else ""))
    return difference


def _random_unit_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= fixed_order.norm(q)
    return q if q[0] >= 0 else -q


def _same_rotation(got: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """``got`` with its sign flipped where that brings it nearer ``expected`` (q and −q are one rotation)."""
    sign = np.where(np.sum(got * expected, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    return got * sign


@dataclass(frozen=True)
class _Case:
    """One random case: how the error message shows it, the library's answer, the student's arguments."""

    inputs: str
    expected: object
    arguments: tuple


#: The end of every checker's docstring: the parameters and outcome all checkers share.
_SHARED_DOC = """rng : numpy.random.Generator
        Draws the random cases.
    n_cases : int
        Number of random cases compared.

    Returns
    -------
    ExerciseReport

    Raises
    ------
    AssertionError
        On the first case where the student's function disagrees with the library.
    """


def _checker(exercise: str, *, n_cases: int, atol: float, hint: str, rotation: bool = False):
    """Turn ``draw(rng, case) -> _Case`` into the checker ``check(student_function, *, rng, n_cases, atol)``.

    The checker checks its arguments, calls ``student_function(*case.arguments)`` on
    ``draw(rng, 0)`` … ``draw(rng, n_cases - 1)`` and compares each output with the library's
    (``hint`` ends the message of a disagreement).  ``rotation``: the outputs are quaternions,
    compared after choosing the sign nearer the library's (q and −q are the same rotation).
    ``n_cases`` and ``atol`` are the checker's defaults.  The checker takes ``draw``'s name, and
    its docstring (what is checked, ``student_function``, ``atol``) followed by :data:`_SHARED_DOC`.
    """
    def decorate(draw):
        def check(student_function, *, rng: np.random.Generator, n_cases: int = n_cases,
                  atol: float = atol) -> ExerciseReport:
            if not callable(student_function):
                raise ValueError(f"student_function must be callable, got {type(student_function).__name__}")
            check_rng(rng)
            check_count(n_cases, "n_cases")
            check_positive(atol, "atol")
            worst = 0.0
            for index in range(n_cases):
                case = draw(rng, index)
                expected = np.asarray(case.expected, dtype=float)
                got = _as_output(student_function(*case.arguments), expected.shape, exercise, case.inputs)
                if rotation:
                    got = _same_rotation(got, expected)
                worst = max(worst, _compare(got, expected, atol, exercise, case.inputs, hint=hint))
            return ExerciseReport(exercise, n_cases, worst)

        check.__name__ = check.__qualname__ = draw.__name__
        check.__module__ = draw.__module__
        check.__doc__ = draw.__doc__ + _SHARED_DOC
        return check

    return decorate
