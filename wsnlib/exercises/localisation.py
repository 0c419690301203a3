"""Exercise checkers of paper 002, RSS fingerprinting and arm posture (notebooks 06–09)."""

from __future__ import annotations

import numpy as np

from wsnlib.exercises.checking import _Case, _checker


@_checker("shepard_knn", n_cases=300, atol=1e-9,
          hint="distances over all anchors (Euclidean: sqrt of the summed squares), keep "
               "the k smallest, weights 1/(d**power + wsnlib.radio.SHEPARD_EPS) divided by their sum")
def check_shepard_knn(rng: np.random.Generator, case: int) -> _Case:
    """Check the Shepard-weighted kNN estimate (eqs. (1)–(2) of paper 002) against
    :class:`wsnlib.radio.estimators.KNNFingerprint`.

    The ``k`` fingerprints nearest the online vector (distance in dB over all anchors, ties
    to the lower index) are averaged with weights ``1 / (d^p_s + ε)``, ε =
    :data:`wsnlib.radio.grid.SHEPARD_EPS`, normalised to sum to 1.

    Parameters
    ----------
    student_function : callable
        ``student_function(radio_map, positions, rss, n_neighbors, power, metric) -> position``:
        ``radio_map`` shape (L, A) mean RSS (dBm) per fingerprint and anchor, ``positions``
        shape (L, 3) the fingerprints' positions (m), ``rss`` shape (A,) one complete online
        vector (dBm), ``n_neighbors`` k (1 ≤ k ≤ L), ``power`` p_s > 0, ``metric``
        ``"euclidean"`` or ``"manhattan"``; returns the estimated position, shape (3,).
    atol : float
        Tolerance per coordinate (m).
    """
    from wsnlib.radio.estimators import KNNFingerprint

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


@_checker("gated_pitch", n_cases=200, atol=1e-12,
          hint="| |a| − g | <= xi keeps a sample (inclusive); rejected samples hold the last "
               "kept pitch, and those before the first kept sample take its pitch")
def check_gated_pitch(rng: np.random.Generator, case: int) -> _Case:
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
    atol : float
        Tolerance (rad).
    """
    from wsnlib.posture import pitch_from_acc

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


@_checker("mean_position_error", n_cases=300, atol=1e-12,
          hint="the distance per sample is the norm over the 3 coordinates (axis=-1); "
               "then average over the samples (not the RMS)")
def check_mean_position_error(rng: np.random.Generator, case: int) -> _Case:
    """Check the PE of a movement (eq. (11) of paper 002, averaged over its samples) against
    :func:`wsnlib.metrics.position_error`.

    Parameters
    ----------
    student_function : callable
        ``student_function(estimated, true) -> pe``: ``estimated`` and ``true`` shape (T, 3)
        positions (m) sample by sample; returns the mean Euclidean distance (m), a scalar.
    atol : float
        Tolerance (m).
    """
    from wsnlib.metrics import position_error

    n_samples = int(rng.integers(1, 60))
    true = rng.uniform(-0.6, 0.6, size=(n_samples, 3))
    estimated = true + rng.normal(scale=float(rng.uniform(0.0, 0.3)), size=(n_samples, 3))
    if case % 7 == 0:
        estimated[: n_samples // 2] = true[: n_samples // 2]  # some exact estimates
    expected = np.asarray(position_error(estimated, true).mean())
    inputs = f"estimated={np.array2string(estimated, precision=3)}, true={np.array2string(true, precision=3)}"
    return _Case(inputs, expected, (estimated.copy(), true.copy()))


@_checker("precision_at_accuracy", n_cases=300, atol=1e-12,
          hint="count the errors lower than OR EQUAL TO the accuracy, and divide by all "
               "the errors (a fraction, not a percentage)")
def check_precision_at_accuracy(rng: np.random.Generator, case: int) -> _Case:
    """Check the precision at a given accuracy (Section 4.2 of paper 002) against
    :func:`wsnlib.metrics.precision_at_accuracy`.

    The precision at accuracy ``a`` is the fraction of the errors that are ``<= a``.

    Parameters
    ----------
    student_function : callable
        ``student_function(errors, accuracy) -> precision``: ``errors`` shape (N,) position
        errors (cm), ``accuracy`` a scalar (cm); returns a fraction in [0, 1].
    atol : float
    """
    from wsnlib.metrics import precision_at_accuracy

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
