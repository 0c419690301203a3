"""Exercise checkers of paper 001, orientation under packet loss (notebooks 01–05 and 10)."""

from __future__ import annotations

import numpy as np

from wsnlib.exercises.checking import _Case, _checker, _random_unit_quaternion


@_checker("madgwick_step", n_cases=200, atol=1e-9, rotation=True,
          hint="ENU in and out; Madgwick's report works in NWU (x north, y west); "
               "with beta = 0 only the gyroscope term q + ½ q ⊗ [0, ω] Δt remains")
def check_madgwick_step(rng: np.random.Generator, case: int) -> _Case:
    """Check one update of Madgwick's filter against :func:`wsnlib.orientation.madgwick_step`.

    Parameters
    ----------
    student_function : callable
        ``student_function(q, gyr, acc, mag, dt, beta) -> q_next`` for single samples: ``q``
        the current ENU unit quaternion ``[w, x, y, z]`` (body → earth), ``gyr`` (rad/s),
        ``acc`` (m/s²) and ``mag`` (µT) body-frame 3-vectors (only their directions matter),
        ``dt`` (s), ``beta`` (rad/s); returns the updated unit quaternion, shape (4,).
    atol : float
        Tolerance per component (after choosing the sign of the result nearer the library's).
    """
    from wsnlib.orientation import madgwick_step

    q = _random_unit_quaternion(rng)
    gyr = rng.normal(scale=2.0, size=3)
    acc = rng.normal(scale=9.81, size=3)
    mag = rng.normal(scale=45.0, size=3)
    dt = float(rng.uniform(0.005, 0.05))
    beta = 0.0 if case % 10 == 0 else float(rng.uniform(0.0, 0.5))
    expected = madgwick_step(q, gyr, acc, mag, dt, beta)
    inputs = f"q={q}, gyr={gyr}, acc={acc}, mag={mag}, dt={dt:.4f}, beta={beta:.4f}"
    return _Case(inputs, expected, (q.copy(), gyr.copy(), acc.copy(), mag.copy(), dt, beta))


@_checker("slerp_weight", n_cases=500, atol=1e-12, hint="μ = 1 with nothing lost, and μ = 1/2 at λ = ρτ")
def check_slerp_weight(rng: np.random.Generator, case: int) -> _Case:
    """Check μ(λ) of eq. (3) of paper 001 against :func:`wsnlib.orientation.slerp_weight`.

    Parameters
    ----------
    student_function : callable
        ``student_function(lost_run, rho, tau) -> mu`` for scalars: ``lost_run`` λ ≥ 0 (samples
        lost in a row), ``rho`` > 0, ``tau`` > 0; returns μ in (0, 1].
    atol : float
    """
    from wsnlib.orientation import slerp_weight

    lost_run = 0 if case == 0 else int(rng.integers(0, 200))
    rho = float(rng.uniform(0.05, 10.0))
    tau = float(rng.uniform(0.5, 24.0))
    expected = np.asarray(slerp_weight(lost_run, rho, tau), dtype=float)
    inputs = f"lost_run={lost_run}, rho={rho:.4f}, tau={tau:.4f}"
    return _Case(inputs, expected, (lost_run, rho, tau))


@_checker("slerp", n_cases=500, atol=1e-9, rotation=True,
          hint="flip one quaternion when their dot product is negative (shorter arc), "
               "and handle q_a = q_b without dividing by sin 0")
def check_slerp(rng: np.random.Generator, case: int) -> _Case:
    """Check SLERP (eq. (2) of paper 001) against :func:`wsnlib.quaternion.slerp`.

    Parameters
    ----------
    student_function : callable
        ``student_function(q_a, q_b, mu) -> q`` for single unit quaternions ``[w, x, y, z]``
        and a scalar ``mu`` in [0, 1]: μ = 0 gives ``q_a``, μ = 1 gives ``q_b``, along the
        shorter arc.
    atol : float
        Tolerance per component, after choosing the sign nearer the library's (q and −q are
        the same rotation).
    """
    from wsnlib.quaternion import slerp

    q_a = _random_unit_quaternion(rng)
    q_b = _random_unit_quaternion(rng) * (-1.0 if case % 3 == 0 else 1.0)  # some on the far arc
    if case % 17 == 1:
        q_b = q_a.copy()  # coincident: no 0/0
    mu = float(rng.choice([0.0, 1.0])) if case % 11 == 2 else float(rng.uniform())
    expected = slerp(q_a, q_b, mu)
    inputs = f"q_a={q_a}, q_b={q_b}, mu={mu:.4f}"
    return _Case(inputs, expected, (q_a.copy(), q_b.copy(), mu))


@_checker("knee_point", n_cases=300, atol=0.5,
          hint="scale each cost to [0, 1] over the Pareto points only, and never pick a dominated point")
def check_knee_point(rng: np.random.Generator, case: int) -> _Case:
    """Check the knee of a two-cost Pareto front against :func:`wsnlib.tuning.knee_point`.

    The knee is the Pareto point (no other point at least as good on both costs and better on
    one) nearest the ideal corner once each cost is min–max scaled over the front; ties go to
    the lowest index.

    Parameters
    ----------
    student_function : callable
        ``student_function(cost_a, cost_b) -> index`` for two 1-D arrays of equal length
        (lower is better); returns the integer index of the knee.
    atol : float
        Indices must be equal; kept for the common signature (any value below 1 means equal).
    """
    from wsnlib.tuning import knee_point

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


def _reference_gyro_interpolation(gyr: np.ndarray, received: np.ndarray) -> np.ndarray:
    """Lost samples filled linearly between the received samples around each gap; edge gaps held."""
    index = np.arange(received.size)
    return np.stack([np.interp(index, index[received], gyr[received, axis]) for axis in range(3)], axis=-1)


@_checker("gyro_interpolation", n_cases=200, atol=1e-12,
          hint="never read gyr on a lost sample; the weight of the sample after the gap "
               "is (t − t_before)/(t_after − t_before)")
def check_gyro_interpolation(rng: np.random.Generator, case: int) -> _Case:
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
    atol : float
    """
    from wsnlib import loss

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


@_checker("triad", n_cases=300, atol=1e-9, rotation=True,
          hint="build the same orthonormal triad (a, a×m/|a×m|, a × that) in the body and "
               "from the ENU references (up, and wsnlib.frames.magnetic_field_enu()), then R = M_ref M_bodyᵀ")
def check_triad(rng: np.random.Generator, case: int) -> _Case:
    """Check TRIAD (Shuster & Oh 1981) against :func:`wsnlib.orientation.triad`.

    Parameters
    ----------
    student_function : callable
        ``student_function(acc, mag) -> q`` for one body-frame specific force (m/s², points up
        at rest) and one magnetic field reading (µT), shape (3,) each; returns the ENU unit
        quaternion ``[w, x, y, z]`` (body → earth) that maps ``acc`` exactly onto earth up and
        puts ``mag`` in the plane of up and the local field (north = +y).
    atol : float
        Tolerance per component, after choosing the sign nearer the library's.
    """
    from wsnlib.orientation import triad

    acc = rng.normal(scale=9.81, size=3)
    mag = rng.normal(scale=45.0, size=3)
    return _Case(f"acc={acc}, mag={mag}", triad(acc, mag), (acc.copy(), mag.copy()))


def _reference_gain_after_gap(prior_variance, gap_rate_std, n_lost, fs, measurement_variance):
    """Scalar Kalman gain of the first measurement after ``n_lost`` lost samples (notebook 10)."""
    variance = prior_variance + (gap_rate_std * n_lost / fs) ** 2
    return variance / (variance + measurement_variance)


@_checker("gain_after_gap", n_cases=300, atol=1e-12,
          hint="the added variance is the square of the angle the rate error turns over the gap, "
               "(σ_gap · λ/fs)², not σ_gap² · λ/fs")
def check_gain_after_gap(rng: np.random.Generator, case: int) -> _Case:
    """Check the Kalman gain of the first measurement after a gap (notebook 10).

    The gap-aware filter (:mod:`wsnlib.orientation.kalman`, "Gap") predicts through ``λ`` lost
    samples with the last angular rate, whose error (std ``σ_gap``, rad/s) adds ``(σ_gap λ Δt)²``
    to an attitude variance ``P`` (rad²); the first measurement after the gap (noise variance
    ``r``, rad²) then gets the gain ``K = P_λ / (P_λ + r)``, ``P_λ = P + (σ_gap λ Δt)²`` — the
    part of the measurement that is believed, which ``1 − μ(λ)`` of the paper's eq. (3) sets by hand.
    (The gyroscope's own white noise over the gap is left out here.)

    Parameters
    ----------
    student_function : callable
        ``student_function(prior_variance, gap_rate_std, n_lost, fs, measurement_variance) -> K``,
        scalars (rad², rad/s, samples, Hz, rad²); returns the gain in [0, 1).
    atol : float
    """
    arguments = (float(rng.uniform(1e-6, 1e-2)), float(rng.uniform(0.05, 2.0)),
                 int(rng.integers(0, 100)) if case % 4 else 0, float(rng.choice([50.0, 100.0, 285.7])),
                 float(rng.uniform(1e-4, 1e-1)))
    inputs = "prior_variance={:.3g}, gap_rate_std={:.3g}, n_lost={}, fs={:g}, measurement_variance={:.3g}".format(
        *arguments)
    return _Case(inputs, _reference_gain_after_gap(*arguments), arguments)
