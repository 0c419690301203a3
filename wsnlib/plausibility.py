"""Is a recording plausible as a whole?  Unit and channel mistakes that a sensor person makes.

An orientation filter fed a gyro in deg/s, an accelerometer in g or the accelerometer and the
magnetometer swapped does not fail: it returns an orientation that is wrong by 15° to 180°,
silently.  :func:`check_imu_plausible` looks at the whole recording (the medians of the vector
norms over the received samples, so a few outliers or a fast movement cannot trip it) and raises
``ValueError`` naming the likely cause; :func:`imu_unit_problems` returns every cause found as
text instead (the recording health check, :mod:`wsnlib.io.health`, reports them).  The bounds are
wide on purpose: they refuse only what no human-motion recording in the documented units can look
like.

* gyroscope (rad/s): the median ‖ω‖ of human motion is below ~3 rad/s (BROAD's fastest trials:
  ~2.5); above :data:`GYRO_MEDIAN_MAX_RAD_S` = 20 rad/s (1,150 °/s, all the time) the gyro is in
  deg/s (a 1 rad/s motion reads 57).
* accelerometer and magnetometer swapped: the median ‖acc‖ of a body sensor stays near g
  (9.81 m/s²), the median ‖mag‖ near the earth's field (25–65 µT); ‖acc‖ in the field's range
  together with ‖mag‖ near g is a swap.
* accelerometer scale (only where a filter uses the magnitude of gravity, ``gravity=``): a median
  ‖acc‖ off ``gravity`` by more than a factor 2 is an accelerometer in g (median ≈ 1) or a
  ``gravity`` setting that does not match the data.  Filters that normalise the accelerometer
  (Madgwick's) pass no ``gravity``: for them any consistent unit is fine.

One sample can be implausible too: :func:`implausible_samples` finds the received samples whose
norm no body-worn sensor can read (:data:`SAMPLE_NORM_MAX`); the filters treat them as lost, with
one warning per call (one gyro sample of 1e6 rad/s used to corrupt 10 s of output).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Above this median ‖gyr‖ (rad/s) a recording's gyro is taken to be in deg/s.
GYRO_MEDIAN_MAX_RAD_S = 20.0
#: Median ‖acc‖ range (m/s²) read as "this is the magnetometer" (the earth's field is 25–65 µT).
SWAPPED_ACC_RANGE = (15.0, 100.0)
#: Median ‖mag‖ range (µT) read as "this is the accelerometer" (g ≈ 9.81 m/s²).
SWAPPED_MAG_RANGE = (4.0, 15.0)
#: Largest factor between the median ‖acc‖ and ``gravity`` (either way).
ACC_SCALE_FACTOR_MAX = 2.0


#: A received sample whose norm is beyond these is no measurement (a bit error, one packet in other
#: units): the filters treat it as lost.  Far above any body-worn sensor's range: gyroscopes saturate at
#: ≤ 4,000 °/s (70 rad/s), accelerometers at ≤ 16 g (a high-g one at 200 g), magnetometers at ≤ 5 mT.
SAMPLE_NORM_MAX = {"gyr": 100.0, "acc": 2000.0, "mag": 1e4}

#: At most this many samples (spread evenly in time) enter a median: cheap on a long or large batch
#: (a units check needs no more; the median of every sample cost ~10 % of a Kalman filter run).
MEDIAN_SAMPLES = 1 << 12


def _squared_norms(vectors: np.ndarray) -> np.ndarray:
    """``(x² + y²) + z²`` of each vector of ``vectors`` (..., 3) (inf where it overflows)."""
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    with np.errstate(over="ignore", invalid="ignore"):
        return x * x + y * y + z * z


@njit(cache=True)
def _finite_squared_norms(vectors, keep, step):
    """``(x² + y²) + z²`` of ``vectors[b, t]`` ``(B, T, 3)`` for every ``b`` and every ``t = 0, step,
    2 step, …`` with ``keep[t // step]``, where finite (one pass; the order of the result is not
    meaningful)."""
    n_t = vectors.shape[1]
    out = np.empty(vectors.shape[0] * ((n_t + step - 1) // step))
    n = 0
    for b in range(vectors.shape[0]):
        for k in range(keep.shape[0]):
            if keep[k]:
                x, y, z = vectors[b, k * step, 0], vectors[b, k * step, 1], vectors[b, k * step, 2]
                square = x * x + y * y + z * z
                if math.isfinite(square):
                    out[n] = square
                    n += 1
    return out[:n]


@njit(cache=True)
def _any_beyond(vectors, limit):
    """Whether some ``(x² + y²) + z²`` of ``vectors`` ``(B, T, 3)`` exceeds ``limit`` (inf does; NaN does not)."""
    for b in range(vectors.shape[0]):
        for t in range(vectors.shape[1]):
            x, y, z = vectors[b, t, 0], vectors[b, t, 1], vectors[b, t, 2]
            if x * x + y * y + z * z > limit:
                return True
    return False


def _median_norm(vectors: np.ndarray, received: np.ndarray | None) -> float:
    """Median ‖v‖ over the samples of ``vectors`` (..., T, 3) received in some batch element (NaN if none)."""
    n_t = vectors.shape[-2]
    step = max(1, vectors.size // 3 // MEDIAN_SAMPLES)
    keep = np.ones((n_t + step - 1) // step, dtype=bool)
    if received is not None:
        rx = np.asarray(received)[..., ::step]
        keep = rx.reshape(-1, rx.shape[-1]).any(axis=0) if rx.ndim > 1 else rx
    rows = vectors[None] if vectors.ndim == 2 else vectors.reshape((-1,) + vectors.shape[-2:])
    # Lost samples may hold anything, and a single huge sample (a norm beyond 1e308 is inf) is no unit mistake.
    squares = _finite_squared_norms(rows, keep, step)
    if not squares.size:
        return float("nan")
    # The median of the norms from that of the squares (√ is monotonic): the middle one, or the
    # mean of the two middle ones.
    middle = squares.size // 2
    squares = np.partition(squares, middle)
    high = np.sqrt(squares[middle])
    if squares.size % 2:
        return float(high)
    return float((np.sqrt(squares[:middle].max()) + high) / 2.0)


def imu_unit_problems(gyr: np.ndarray | None, acc: np.ndarray, mag: np.ndarray | None = None,
                      received: np.ndarray | None = None, *, gravity: float | None = None) -> list[str]:
    """What makes a recording implausible as a whole, in words: one sentence per problem found,
    naming the likely cause, in the order gyro units, acc and mag swapped, acc scale; ``[]`` when
    it is plausible.

    The arguments and the bounds are those of :func:`check_imu_plausible`, which raises on the
    first of these; a health check (:mod:`wsnlib.io.health`) lists them all.
    """
    problems = []
    gyr_median = float("nan") if gyr is None else _median_norm(gyr, received)
    if gyr_median > GYRO_MEDIAN_MAX_RAD_S:
        problems.append(f"gyr looks like deg/s, not rad/s: its median norm is {gyr_median:.3g} "
                        f"(human motion: below ~3 rad/s); convert it with np.radians")
    acc_median = _median_norm(acc, received)
    if mag is not None:
        mag_median = _median_norm(mag, received)
        if (SWAPPED_ACC_RANGE[0] <= acc_median <= SWAPPED_ACC_RANGE[1]
                and SWAPPED_MAG_RANGE[0] <= mag_median <= SWAPPED_MAG_RANGE[1]):
            problems.append(f"acc and mag look swapped: median norm of acc {acc_median:.3g} (a magnetic "
                            f"field in µT?), of mag {mag_median:.3g} (gravity in m/s²?)")
    if gravity is not None and np.isfinite(acc_median):
        ratio = acc_median / gravity
        if not 1.0 / ACC_SCALE_FACTOR_MAX <= ratio <= ACC_SCALE_FACTOR_MAX:
            if 0.5 <= acc_median <= 2.0:
                hint = "the accelerometer in g? multiply it by 9.80665"
            elif 7.0 <= acc_median <= 13.0:
                hint = "the accelerometer reads m/s²: is the gravity given to the filter right?"
            else:
                hint = "acc in other units than m/s²?"
            # (said for a filter's own setting and for the health check's standard gravity alike)
            problems.append(f"acc's median norm is {acc_median:.3g} m/s² where gravity of {gravity:.4g} m/s² is "
                            f"expected: {hint} (or give the filters the gravity the data reads at rest)")
    return problems


def check_imu_plausible(gyr: np.ndarray | None, acc: np.ndarray, mag: np.ndarray | None = None,
                        received: np.ndarray | None = None, *, gravity: float | None = None,
                        where: str = "") -> None:
    """Raise ``ValueError`` naming the likely cause if a recording is implausible as a whole.

    Parameters
    ----------
    gyr, acc : numpy.ndarray, shape (..., T, 3)
        Angular rate (rad/s; None: not checked) and specific force (m/s²), body frame.
    mag : numpy.ndarray, shape (..., T, 3), optional
        Magnetic field (µT), body frame; None for an IMU without magnetometer.
    received : numpy.ndarray of bool, shape (..., T), optional
        Only samples received in some batch element count (lost ones may hold anything).
    gravity : float, optional
        The magnitude of gravity (m/s²) the caller's filter expects the accelerometer to read at
        rest; None skips the scale check.
    where : str
        Prefix of the message (the calling function's name).

    The checks and their bounds are in the module docstring; the message is the first of
    :func:`imu_unit_problems`.  Nothing is checked when no sample is received.
    """
    problems = imu_unit_problems(gyr, acc, mag, received, gravity=gravity)
    if problems:
        prefix = f"{where}: " if where else ""
        raise ValueError(prefix + problems[0])


def implausible_samples(signals: dict) -> np.ndarray | None:
    """Bool ``(..., T)`` (the broadcast of the signals' leading shapes): a sample of ``gyr``, ``acc`` or
    ``mag`` (``signals[name]``, ``(..., T, 3)``) whose norm exceeds :data:`SAMPLE_NORM_MAX` or overflows;
    None when there is none (the usual case: nothing is allocated beyond the norms)."""
    found = None
    for name, arr in signals.items():
        limit = SAMPLE_NORM_MAX[name] ** 2
        if not _any_beyond(arr[None] if arr.ndim == 2 else arr.reshape((-1,) + arr.shape[-2:]), limit):
            continue  # the usual case: nothing allocated
        beyond = _squared_norms(arr) > limit  # an overflowing norm is inf: beyond the limit
        if beyond.any():
            found = beyond if found is None else found | beyond
    return found


#: Above this fraction of received samples a magnetometer is reported frozen (a reading repeated
#: exactly from the previous received sample; a coarsely quantised sensor held still repeats often,
#: so only nearly all of them) or saturated (an axis at its largest |value|).
MAG_STUCK_FRACTION = 0.95
MAG_SATURATED_FRACTION = 0.05
#: A clipped axis reads at least this (µT): twice the strongest geomagnetic field (~65 µT), so that
#: a quantised axis that barely moves is not taken for one.
MAG_SATURATION_MIN_UT = 130.0


@njit(cache=True)
def _magnetometer_counts(m, rx):
    """Over the samples ``t`` of ``m`` (T, 3) with ``rx[t]``: how many there are, how many repeat the
    previous such sample exactly, each axis' largest |value| (NaN if one is NaN) and how many sit at it."""
    n = repeats = last = 0
    peak = np.zeros(3)
    at_peak = np.zeros(3, dtype=np.int64)
    for t in range(m.shape[0]):
        if not rx[t]:
            continue
        if n > 0 and m[t, 0] == m[last, 0] and m[t, 1] == m[last, 1] and m[t, 2] == m[last, 2]:
            repeats += 1
        for a in range(3):
            value = abs(m[t, a])
            if math.isnan(value):
                peak[a] = math.nan
            elif value > peak[a]:  # (False once the peak is NaN)
                peak[a] = value
        last = t
        n += 1
    for t in range(m.shape[0]):
        if rx[t]:
            for a in range(3):
                if abs(m[t, a]) == peak[a]:
                    at_peak[a] += 1
    return n, repeats, peak, at_peak


def magnetometer_problem(mag: np.ndarray, received: np.ndarray) -> str | None:
    """What is wrong with a magnetometer over a whole recording, in words, or None.

    ``mag`` ``(..., T, 3)`` (µT), ``received`` ``(..., T)`` bool.  *Frozen*: more than
    :data:`MAG_STUCK_FRACTION` of the received samples repeat the previous received one exactly
    (a sensor that stopped updating; real readings carry noise).  *Saturated*: on some axis more
    than :data:`MAG_SATURATED_FRACTION` of the received samples sit exactly at that axis' largest
    magnitude, beyond :data:`MAG_SATURATION_MIN_UT` (a clipped range; a magnet near the sensor).
    Checked per batch element of ``mag``'s own leading shape, on the samples received in some
    batch element; the first problem found.
    """
    rx = np.asarray(received)
    rx = rx.reshape(-1, mag.shape[-2]).any(axis=0) if rx.ndim > 1 else rx  # received in some batch element
    for m in mag.reshape((-1,) + mag.shape[-2:]):
        n, repeats, peak, at_peak = _magnetometer_counts(m, rx)
        if n < 10:
            continue
        frozen = repeats / (n - 1)
        if frozen > MAG_STUCK_FRACTION:
            return f"mag is frozen: {frozen:.0%} of the received samples repeat the previous one exactly"
        at_peak = at_peak / n
        if np.any((at_peak > MAG_SATURATED_FRACTION) & (peak > MAG_SATURATION_MIN_UT)):
            axis = int(np.argmax(at_peak))
            return (f"mag looks saturated: {at_peak[axis]:.0%} of the received samples sit at ±{peak[axis]:.4g} µT on "
                    f"axis {'xyz'[axis]}")
    return None
