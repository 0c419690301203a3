"""Checkers for the notebooks' implementation exercises.

Each notebook hides one algorithm of :mod:`wsnlib` behind an exercise: the student writes the
function, then calls the checker here, which compares it with the library on random inputs
drawn from the ``rng`` passed in.  A checker returns an :class:`ExerciseReport` when the
student's function agrees everywhere and raises ``AssertionError`` with the first input on
which it does not (what was expected, what came back), so that the message says what to fix.
Arguments that are not functions or generators raise ``ValueError``.

Sections, one per paper: paper 001 (notebooks 01–05), then paper 002 (notebooks 06–09).
Every checker is named ``check_<what the student writes>`` and has the signature
``check_x(student_function, *, rng, n_cases=..., atol=...)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def _check_arguments(student_function, rng, n_cases: int, atol: float) -> np.random.Generator:
    if not callable(student_function):
        raise ValueError(f"student_function must be callable, got {type(student_function).__name__}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    if not isinstance(n_cases, int | np.integer) or n_cases < 1:
        raise ValueError(f"n_cases must be a positive integer, got {n_cases!r}")
    if not np.isfinite(atol) or atol <= 0:
        raise ValueError(f"atol must be a positive finite number, got {atol!r}")
    return rng


def _as_output(value, shape: tuple[int, ...], exercise: str, inputs: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise AssertionError(f"{exercise}: your function returned {value!r} for {inputs}, "
                             f"which is not an array of numbers ({error})") from None
    if arr.shape != shape:
        raise AssertionError(f"{exercise}: your function returned shape {arr.shape} for {inputs}, "
                             f"expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise AssertionError(f"{exercise}: your function returned non-finite values {arr} for {inputs}")
    return arr


def _compare(got: np.ndarray, expected: np.ndarray, atol: float, exercise: str, inputs: str,
             hint: str = "") -> float:
    difference = float(np.max(np.abs(got - expected))) if got.size else 0.0
    if not difference <= atol:
        message = (f"{exercise}: for {inputs}\n  expected {np.array2string(expected, precision=6)}\n"
                   f"  got      {np.array2string(got, precision=6)}\n  (largest difference {difference:.3g} > "
                   f"tolerance {atol:g})")
        raise AssertionError(message + (f"\n  Hint: {hint}" if hint else ""))
    return difference


def _random_unit_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
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


def _run_cases(exercise: str, student_function, draw, *, n_cases: int, atol: float, hint: str,
               rotation: bool = False) -> ExerciseReport:
    """Call ``student_function(*case.arguments)`` on ``draw(0)`` … ``draw(n_cases - 1)`` and compare.

    ``rotation``: the outputs are quaternions, compared after choosing the sign nearer the
    library's (q and −q are the same rotation).
    """
    worst = 0.0
    for index in range(n_cases):
        case = draw(index)
        expected = np.asarray(case.expected, dtype=float)
        got = _as_output(student_function(*case.arguments), expected.shape, exercise, case.inputs)
        if rotation:
            got = _same_rotation(got, expected)
        worst = max(worst, _compare(got, expected, atol, exercise, case.inputs, hint=hint))
    return ExerciseReport(exercise, n_cases, worst)


# ------------------------------------------------------------------------------------------
# Paper 001: notebooks 01–05
# ------------------------------------------------------------------------------------------


def check_madgwick_step(student_function, *, rng: np.random.Generator, n_cases: int = 200,
                        atol: float = 1e-9) -> ExerciseReport:
    """Check one update of Madgwick's filter against :func:`wsnlib.orientation.madgwick_step`.

    Parameters
    ----------
    student_function : callable
        ``student_function(q, gyr, acc, mag, dt, beta) -> q_next`` for single samples: ``q``
        the current ENU unit quaternion ``[w, x, y, z]`` (body → earth), ``gyr`` (rad/s),
        ``acc`` (m/s²) and ``mag`` (µT) body-frame 3-vectors (only their directions matter),
        ``dt`` (s), ``beta`` (rad/s); returns the updated unit quaternion, shape (4,).
    rng : numpy.random.Generator
        Draws the states, readings, time steps and gains.
    n_cases : int
    atol : float
        Tolerance per component (after choosing the sign of the result nearer the library's).

    Returns
    -------
    ExerciseReport

    Raises
    ------
    AssertionError
        On the first case where the student's quaternion differs from the library's.
    """
    from wsnlib.orientation import madgwick_step

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        q = _random_unit_quaternion(rng)
        gyr = rng.normal(scale=2.0, size=3)
        acc = rng.normal(scale=9.81, size=3)
        mag = rng.normal(scale=45.0, size=3)
        dt = float(rng.uniform(0.005, 0.05))
        beta = 0.0 if case % 10 == 0 else float(rng.uniform(0.0, 0.5))
        expected = madgwick_step(q, gyr, acc, mag, dt, beta)
        inputs = f"q={q}, gyr={gyr}, acc={acc}, mag={mag}, dt={dt:.4f}, beta={beta:.4f}"
        return _Case(inputs, expected, (q.copy(), gyr.copy(), acc.copy(), mag.copy(), dt, beta))

    return _run_cases("madgwick_step", student_function, draw, n_cases=n_cases, atol=atol, rotation=True,
                      hint="ENU in and out; Madgwick's report works in NWU (x north, y west); "
                           "with beta = 0 only the gyroscope term q + ½ q ⊗ [0, ω] Δt remains")


def check_slerp_weight(student_function, *, rng: np.random.Generator, n_cases: int = 500,
                       atol: float = 1e-12) -> ExerciseReport:
    """Check μ(λ) of eq. (3) of paper 001 against :func:`wsnlib.orientation.slerp_weight`.

    Parameters
    ----------
    student_function : callable
        ``student_function(lost_run, rho, tau) -> mu`` for scalars: ``lost_run`` λ ≥ 0 (samples
        lost in a row), ``rho`` > 0, ``tau`` > 0; returns μ in (0, 1].
    rng : numpy.random.Generator
    n_cases : int
    atol : float

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.orientation import slerp_weight

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        lost_run = 0 if case == 0 else int(rng.integers(0, 200))
        rho = float(rng.uniform(0.05, 10.0))
        tau = float(rng.uniform(0.5, 24.0))
        expected = np.asarray(slerp_weight(lost_run, rho, tau), dtype=float)
        inputs = f"lost_run={lost_run}, rho={rho:.4f}, tau={tau:.4f}"
        return _Case(inputs, expected, (lost_run, rho, tau))

    return _run_cases("slerp_weight", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="μ = 1 with nothing lost, and μ = 1/2 at λ = ρτ")


def check_slerp(student_function, *, rng: np.random.Generator, n_cases: int = 500,
                atol: float = 1e-9) -> ExerciseReport:
    """Check SLERP (eq. (2) of paper 001) against :func:`wsnlib.quaternion.slerp`.

    Parameters
    ----------
    student_function : callable
        ``student_function(q_a, q_b, mu) -> q`` for single unit quaternions ``[w, x, y, z]``
        and a scalar ``mu`` in [0, 1]: μ = 0 gives ``q_a``, μ = 1 gives ``q_b``, along the
        shorter arc.
    rng : numpy.random.Generator
    n_cases : int
    atol : float
        Tolerance per component, after choosing the sign nearer the library's (q and −q are
        the same rotation).

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.quaternion import slerp

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        q_a = _random_unit_quaternion(rng)
        q_b = _random_unit_quaternion(rng) * (-1.0 if case % 3 == 0 else 1.0)  # some on the far arc
        if case % 17 == 1:
            q_b = q_a.copy()  # coincident: no 0/0
        mu = float(rng.choice([0.0, 1.0])) if case % 11 == 2 else float(rng.uniform())
        expected = slerp(q_a, q_b, mu)
        inputs = f"q_a={q_a}, q_b={q_b}, mu={mu:.4f}"
        return _Case(inputs, expected, (q_a.copy(), q_b.copy(), mu))

    return _run_cases("slerp", student_function, draw, n_cases=n_cases, atol=atol, rotation=True,
                      hint="flip one quaternion when their dot product is negative (shorter arc), "
                      "and handle q_a = q_b without dividing by sin 0")


def check_knee_point(student_function, *, rng: np.random.Generator, n_cases: int = 300,
                     atol: float = 0.5) -> ExerciseReport:
    """Check the knee of a two-cost Pareto front against :func:`wsnlib.tuning.knee_point`.

    The knee is the Pareto point (no other point at least as good on both costs and better on
    one) nearest the ideal corner once each cost is min–max scaled over the front; ties go to
    the lowest index.

    Parameters
    ----------
    student_function : callable
        ``student_function(cost_a, cost_b) -> index`` for two 1-D arrays of equal length
        (lower is better); returns the integer index of the knee.
    rng : numpy.random.Generator
    n_cases : int
    atol : float
        Indices must be equal; kept for the common signature (any value below 1 means equal).

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.tuning import knee_point

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        n_points = int(rng.integers(1, 40))
        if case % 4 == 0:  # a trade-off curve with noise, like the tuning grid
            a = np.sort(rng.uniform(0, 10, n_points))
            cost_a, cost_b = a, 10.0 / (1.0 + a) + rng.normal(scale=0.3, size=n_points)
        else:
            cost_a, cost_b = rng.uniform(0, 10, n_points), rng.uniform(0, 5, n_points)
        if case % 9 == 1:  # repeated values: ties on one cost
            cost_a = np.round(cost_a)
        inputs = f"cost_a={np.array2string(cost_a, precision=3)}, cost_b={np.array2string(cost_b, precision=3)}"
        return _Case(inputs, knee_point(cost_a, cost_b), (cost_a.copy(), cost_b.copy()))

    return _run_cases("knee_point", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="scale each cost to [0, 1] over the Pareto points only, and never pick a dominated point")


def _reference_gyro_interpolation(gyr: np.ndarray, received: np.ndarray) -> np.ndarray:
    """Lost samples filled linearly between the received samples around each gap; edge gaps held."""
    index = np.arange(received.size)
    return np.stack([np.interp(index, index[received], gyr[received, axis]) for axis in range(3)], axis=-1)


def check_gyro_interpolation(student_function, *, rng: np.random.Generator, n_cases: int = 200,
                             atol: float = 1e-12) -> ExerciseReport:
    """Check the gyroscope filled linearly across gaps (the ω that ``method="gyro_interpolation"`` replays).

    Inside a gap, ω is interpolated linearly (per axis, in time) between the last received
    sample before the gap and the first received sample after it, as
    :func:`wsnlib.orientation.estimate_orientation` does with ``method="gyro_interpolation"``.
    A gap at the start takes the first received ω, a gap at the end the last received ω
    (the library replays neither; filling them so keeps the exercise defined everywhere).

    Parameters
    ----------
    student_function : callable
        ``student_function(gyr, received) -> gyr_filled``: ``gyr`` shape (T, 3) rad/s (what is
        stored on lost samples is garbage), ``received`` boolean shape (T,) with at least one
        True; returns shape (T, 3), equal to ``gyr`` on received samples.
    rng : numpy.random.Generator
    n_cases : int
    atol : float

    Returns
    -------
    ExerciseReport
    """
    from wsnlib import loss

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        n_samples = int(rng.integers(5, 120))
        packets = loss.gilbert_elliott(n_samples, loss_rate=float(rng.uniform(0.05, 0.5)),
                                       mean_burst=float(rng.uniform(1.0, 6.0)), rng=rng)
        received = np.asarray(packets, dtype=bool)
        if not received.any():
            received[rng.integers(n_samples)] = True
        if case % 5 == 0:
            received[0] = False  # a gap at the start
        if not received.any():
            received[-1] = True
        gyr = rng.normal(scale=2.0, size=(n_samples, 3))
        gyr_seen = np.where(received[:, None], gyr, rng.normal(scale=100.0, size=(n_samples, 3)))
        expected = _reference_gyro_interpolation(gyr, received)
        inputs = f"received={received.astype(int)} (T={n_samples})"
        return _Case(inputs, expected, (gyr_seen.copy(), received.copy()))

    return _run_cases("gyro_interpolation", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="never read gyr on a lost sample; the weight of the sample after the gap "
                           "is (t − t_before)/(t_after − t_before)")


def check_triad(student_function, *, rng: np.random.Generator, n_cases: int = 300,
                atol: float = 1e-9) -> ExerciseReport:
    """Check TRIAD (Shuster & Oh 1981) against :func:`wsnlib.orientation.triad`.

    Parameters
    ----------
    student_function : callable
        ``student_function(acc, mag) -> q`` for one body-frame specific force (m/s², points up
        at rest) and one magnetic field reading (µT), shape (3,) each; returns the ENU unit
        quaternion ``[w, x, y, z]`` (body → earth) that maps ``acc`` exactly onto earth up and
        puts ``mag`` in the plane of up and the local field (north = +y).
    rng : numpy.random.Generator
    n_cases : int
    atol : float
        Tolerance per component, after choosing the sign nearer the library's.

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.orientation import triad

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        acc = rng.normal(scale=9.81, size=3)
        mag = rng.normal(scale=45.0, size=3)
        expected = triad(acc, mag)
        inputs = f"acc={acc}, mag={mag}"
        return _Case(inputs, expected, (acc.copy(), mag.copy()))

    return _run_cases("triad", student_function, draw, n_cases=n_cases, atol=atol, rotation=True,
                      hint="build the same orthonormal triad (a, a×m/|a×m|, a × that) in the body and "
                      "from the ENU references (up, and wsnlib.frames.magnetic_field_enu()), "
                      "then R = M_ref M_bodyᵀ")


# ------------------------------------------------------------------------------------------
# Paper 002: notebooks 06–09
# ------------------------------------------------------------------------------------------


def check_shepard_knn(student_function, *, rng: np.random.Generator, n_cases: int = 300,
                      atol: float = 1e-9) -> ExerciseReport:
    """Check the Shepard-weighted kNN estimate (eqs. (1)–(2) of paper 002) against
    :class:`wsnlib.fingerprint.KNNFingerprint`.

    The ``k`` fingerprints nearest the online vector (distance in dB over all anchors, ties
    to the lower index) are averaged with weights ``1 / (d^p_s + ε)``, ε =
    :data:`wsnlib.fingerprint.SHEPARD_EPS`, normalised to sum to 1.

    Parameters
    ----------
    student_function : callable
        ``student_function(radio_map, positions, rss, n_neighbors, power, metric) -> position``:
        ``radio_map`` shape (L, A) mean RSS (dBm) per fingerprint and anchor, ``positions``
        shape (L, 3) the fingerprints' positions (m), ``rss`` shape (A,) one complete online
        vector (dBm), ``n_neighbors`` k (1 ≤ k ≤ L), ``power`` p_s > 0, ``metric``
        ``"euclidean"`` or ``"manhattan"``; returns the estimated position, shape (3,).
    rng : numpy.random.Generator
        Draws the radio maps, positions, online vectors and settings.
    n_cases : int
    atol : float
        Tolerance per coordinate (m).

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.fingerprint import KNNFingerprint

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        n_fingerprints = int(rng.integers(1, 12))
        n_anchors = int(rng.integers(1, 9))
        radio_map = rng.uniform(-95.0, -40.0, size=(n_fingerprints, n_anchors))
        positions = rng.uniform(-0.5, 0.5, size=(n_fingerprints, 3))
        rss = radio_map[rng.integers(n_fingerprints)] + rng.normal(scale=4.0, size=n_anchors)
        if case % 10 == 3:
            rss = radio_map[rng.integers(n_fingerprints)].copy()  # exactly on a fingerprint: d = 0
        n_neighbors = int(rng.integers(1, n_fingerprints + 1))
        power = float(rng.choice([0.5, 1.0, 2.0, 4.0])) if case % 2 else float(rng.uniform(0.2, 6.0))
        metric = "euclidean" if case % 3 else "manhattan"
        model = KNNFingerprint(n_neighbors, metric=metric, power=power).fit(radio_map, positions)
        expected = model.predict(rss[None, :])[0]
        inputs = (f"n_neighbors={n_neighbors}, power={power:.3f}, metric={metric!r}, "
                  f"radio_map={np.array2string(radio_map, precision=1)}, rss={np.array2string(rss, precision=1)}")
        return _Case(inputs, expected, (radio_map.copy(), positions.copy(), rss.copy(), n_neighbors, power, metric))

    return _run_cases("shepard_knn", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="distances over all anchors (Euclidean: sqrt of the summed squares), keep "
                      "the k smallest, weights 1/(d**power + wsnlib.fingerprint.SHEPARD_EPS) "
                      "divided by their sum")


def check_gated_pitch(student_function, *, rng: np.random.Generator, n_cases: int = 200,
                      atol: float = 1e-12) -> ExerciseReport:
    """Check the accelerometer pitch with a gravity gate (eqs. (6)–(7) of paper 002) against
    :func:`wsnlib.posture.pitch_from_acc` with ``method="gating"``.

    θ = arcsin(a_x / |a|) (the segment along the device's x axis) on every sample whose
    magnitude lies in ``[g − ξ, g + ξ]``; a rejected sample holds the pitch of the last
    accepted one, and rejected samples before the first accepted one take the first accepted
    pitch.

    Parameters
    ----------
    student_function : callable
        ``student_function(acc, xi, gravity) -> pitch``: ``acc`` shape (T, 3) (m/s², device
        frame, at least one sample passes the gate), ``xi`` ξ ≥ 0 (m/s²), ``gravity`` g
        (m/s²); returns the pitch (rad), shape (T,).
    rng : numpy.random.Generator
    n_cases : int
    atol : float
        Tolerance (rad).

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.posture import pitch_from_acc

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        n_samples = int(rng.integers(1, 80))
        gravity = 9.80665 if case % 4 else float(rng.uniform(9.7, 9.9))
        xi = float(rng.choice([0.01, 0.1, 0.5, 2.0])) if case % 5 == 0 else float(rng.uniform(0.05, 1.5))
        pitch = np.cumsum(rng.normal(scale=0.1, size=n_samples)) + rng.uniform(-1.2, 1.2)
        roll = rng.uniform(-np.pi, np.pi)
        direction = np.stack([np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)], axis=-1)
        acc = gravity * direction + rng.normal(scale=float(rng.uniform(0.0, 2.0)), size=(n_samples, 3))
        accepted = np.abs(np.linalg.norm(acc, axis=-1) - gravity) <= xi
        if not accepted.any():  # the exercise promises one sample inside the gate
            keep = int(rng.integers(n_samples)) if case % 3 else n_samples - 1   # sometimes only the last
            acc[keep] = gravity * direction[keep]   # |a| = g up to rounding, well inside the gate
        expected = pitch_from_acc(acc, method="gating", xi=xi, gravity=gravity)
        inputs = f"xi={xi:.3f}, gravity={gravity:.5f}, acc={np.array2string(acc, precision=3)}"
        return _Case(inputs, expected, (acc.copy(), xi, gravity))

    return _run_cases("gated_pitch", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="| |a| − g | <= xi keeps a sample (inclusive); rejected samples hold the last "
                      "kept pitch, and those before the first kept sample take its pitch")


def check_mean_position_error(student_function, *, rng: np.random.Generator, n_cases: int = 300,
                              atol: float = 1e-12) -> ExerciseReport:
    """Check the PE of a movement (eq. (11) of paper 002, averaged over its samples) against
    :func:`wsnlib.metrics.position_error`.

    Parameters
    ----------
    student_function : callable
        ``student_function(estimated, true) -> pe``: ``estimated`` and ``true`` shape (T, 3)
        positions (m) sample by sample; returns the mean Euclidean distance (m), a scalar.
    rng : numpy.random.Generator
    n_cases : int
    atol : float
        Tolerance (m).

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.metrics import position_error

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        n_samples = int(rng.integers(1, 60))
        true = rng.uniform(-0.6, 0.6, size=(n_samples, 3))
        estimated = true + rng.normal(scale=float(rng.uniform(0.0, 0.3)), size=(n_samples, 3))
        if case % 7 == 0:
            estimated[: n_samples // 2] = true[: n_samples // 2]  # some exact estimates
        expected = np.asarray(position_error(estimated, true).mean())
        inputs = f"estimated={np.array2string(estimated, precision=3)}, true={np.array2string(true, precision=3)}"
        return _Case(inputs, expected, (estimated.copy(), true.copy()))

    return _run_cases("mean_position_error", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="the distance per sample is the norm over the 3 coordinates (axis=-1); "
                      "then average over the samples (not the RMS)")


def check_precision_at_accuracy(student_function, *, rng: np.random.Generator, n_cases: int = 300,
                                atol: float = 1e-12) -> ExerciseReport:
    """Check the precision at a given accuracy (Section 4.2 of paper 002) against
    :func:`wsnlib.metrics.precision_at_accuracy`.

    The precision at accuracy ``a`` is the fraction of the errors that are ``<= a``.

    Parameters
    ----------
    student_function : callable
        ``student_function(errors, accuracy) -> precision``: ``errors`` shape (N,) position
        errors (cm), ``accuracy`` a scalar (cm); returns a fraction in [0, 1].
    rng : numpy.random.Generator
    n_cases : int
    atol : float

    Returns
    -------
    ExerciseReport
    """
    from wsnlib.metrics import precision_at_accuracy

    rng = _check_arguments(student_function, rng, n_cases, atol)

    def draw(case: int) -> _Case:
        n_errors = int(rng.integers(1, 200))
        errors = rng.gamma(2.0, float(rng.uniform(1.0, 10.0)), size=n_errors)
        if case % 3 == 0:
            errors = np.round(errors)  # whole centimetres: errors equal to the accuracy
        accuracy = float(rng.choice(errors)) if case % 3 == 0 else float(rng.uniform(0.0, 40.0))
        if case % 11 == 5:
            accuracy = float(rng.choice([0.0, errors.max() + 1.0]))
        expected = np.asarray(precision_at_accuracy(errors, accuracy), dtype=float)
        inputs = f"accuracy={accuracy:g}, errors={np.array2string(errors, precision=2, threshold=20)}"
        return _Case(inputs, expected, (errors.copy(), accuracy))

    return _run_cases("precision_at_accuracy", student_function, draw, n_cases=n_cases, atol=atol,
                      hint="count the errors lower than OR EQUAL TO the accuracy, and divide by all "
                      "the errors (a fraction, not a percentage)")
