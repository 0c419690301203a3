"""Aligning an optical reference (motion-capture markers) to an IMU: a time lag and two rotations.

A reference brought from another lab gives orientations ``q_ref(t')`` of a marker cluster, stamped
on the reference's own clock ``t'`` and expressed in the lab's own world frame.  Before any
orientation error against the IMU means anything, three unknowns must be found.  Every quaternion
here follows the project convention, ``[w, x, y, z]`` mapping a child frame's vectors into its
parent frame (``v_parent = q ⊗ v_child ⊗ q*``); the frames are the IMU body S, the marker cluster
M, the reference's world (the lab) L and the earth frame ENU E:

=====================  =========================  ==========================================
quaternion             maps vectors               what it is
=====================  =========================  ==========================================
``q_ref(t')``          M → L                      the reference as recorded (given)
``sensor_to_marker``   S → M                      how the IMU sits in the cluster (constant)
``reference_to_enu``   L → E                      the lab's axes in ENU (constant)
=====================  =========================  ==========================================

and the reference orientation of the IMU, comparable with any filter's output (S → ENU), is::

    q_ES(t) = reference_to_enu ⊗ q_ref(t − τ) ⊗ sensor_to_marker                          (1)

with ``τ`` the lag: the reference sample stamped ``t'`` shows the motion the IMU saw at ``t' + τ``.

Step 1 — the lag τ, from the angular-rate magnitudes
    The reference's body rates come from finite differences of its quaternions, one per pair of
    neighbouring valid rows (NaN rows and gaps in the time stamps are never bridged)::

        ω_M(t'_{k+½}) = rotvec(q_k* ⊗ q_{k+1}) / (t'_{k+1} − t'_k)                         (2)

    A rate's magnitude is the same in every frame, ``‖ω_S‖ = ‖ω_M‖``, so the lag needs neither
    rotation.  On a uniform grid with the IMU's median step Δ, both rates are smoothed by the
    same moving average (``rate_smoothing_s``), and ``τ = argmax_τ corr(‖ω_gyro(t)‖, ‖ω_M(t − τ)‖)``
    over ``τ = kΔ``, ``|τ| ≤ max_lag_s`` (Pearson correlation over the samples where the
    reference exists), refined below a sample by the parabola through the peak ``c₀`` and its two
    neighbours: ``τ = (k + δ)Δ``, ``δ = ½ (c₋ − c₊) / (c₋ − 2c₀ + c₊)``.

Step 2 — the sensor-to-marker rotation, from the rate vectors
    After the lag, the gyro sees the marker rates turned into the sensor frame (``R_SM`` is the
    rotation matrix of ``sensor_to_marker*``) plus its bias ``b``::

        ω_gyro(t) = R_SM · ω_M(t − τ) + b                                                    (3)

    Both sides pass the same masked moving average (so smoothing biases neither), and ``R_SM``
    and ``b`` are the weighted Kabsch solution (weighted means removed, then Wahba's problem by
    :meth:`scipy.spatial.transform.Rotation.align_vectors`), iteratively reweighted with Tukey's
    biweight ``w = (1 − (r/c)²)²`` for ``r < c``, 0 beyond, ``c = 3 · median(r)`` (for Gaussian
    3-D residuals ≈ 4.6 σ, near Tukey's 4.685 σ): a marker swap (a stretch of wrong quaternions)
    gives residuals far beyond ``c`` and is dropped, with weight 0 — the *outliers*.

Step 3 — the lab-to-ENU rotation, from gravity and the magnetic field
    The IMU's own specific force and magnetic field, turned into the lab frame by the reference
    and the rotation of step 2, ``f_L(t) = q_ref(t − τ) ⊗ sensor_to_marker ⊗ acc(t) ⊗ (…)*``
    (and ``m_L`` from ``mag``), are at low acceleration::

        f_L ≈ R_LE · g ẑ,    m_L − (m_L · f̂_L) f̂_L ∥ R_LE · ŷ                              (4)

    (gravity's specific force points up, the field's horizontal part points north).  The
    rotation ``R_EL`` (``reference_to_enu``) is the robust Wahba solution of the pairs
    ``(ẑ, f̂_L(t))`` over the samples with ``‖acc‖`` within 10 % of its median and
    ``(ŷ, n̂_L(t))`` (the unit horizontal field) over those that also have ``‖mag‖`` within 10 % of
    its median, reweighted as in step 2.

    It is fitted on the SENSORS, never on an orientation estimator's output: fitting it on a
    filter's estimate would absorb that filter's own errors (a heading offset, a tilt from
    unmodelled acceleration) into the reference, which would then agree with the filter better
    than the truth does — the filter would look better than it is, and any comparison between
    filters would be biased towards the one the alignment was fitted on.

The reference's quaternion convention is checked on the way: steps 1–2 also run on the array
read as the inverse rotation (``q*``, world → marker), and the reading whose rates agree better
with the gyro (smaller median residual of (3) relative to the median rate) is used, with a warning
when it is the inverse (:attr:`Alignment.reference_read_as_inverse`).  The inverse's rate
magnitudes equal the plain reading's, but (2) then gives the rate in the lab frame, which no
constant rotation maps onto the gyro.  A scalar-last array ``[x, y, z, w]`` read as
``[w, x, y, z]`` is caught by the same test, and the rates cannot tell it from an inverse one: the
reordering is a linear isometry of ℝ⁴ with determinant −1, and every such map is
``q ↦ a ⊗ q* ⊗ b`` with constant unit ``a``, ``b`` — the inverse rotation between two constant
rotations, which ``reference_to_enu`` and ``sensor_to_marker`` absorb.  So the warning names both
causes; the aligned reference (1) is right either way, while the two rotations then refer to the
reading used (fix the array and run again to have them in the lab's and the cluster's own axes).
For the same reason a scalar-last array of the inverse rotation passes unnoticed, with the same
aligned reference.

:func:`estimate_alignment` finds the three unknowns; :func:`align_reference` applies (1) to a
reference series on the IMU's time stamps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from wsnlib import quaternion as quat_ops
from wsnlib._user_warnings import warn_user
from wsnlib._validation import as_float_array, check_positive
from wsnlib.plausibility import check_imu_plausible

#: Residuals beyond this multiple of their median get weight 0 (outliers) in the robust fits.
CUTOFF_PER_MEDIAN = 3.0

#: Samples whose ‖acc‖ (‖mag‖) is within this fraction of its median count as low-acceleration
#: (undisturbed) for step 3.
NORM_TOLERANCE = 0.1

#: Neighbouring reference rows further apart than this multiple of the median step are a gap.
_GAP_PER_MEDIAN_STEP = 1.5

#: Fewest samples a fit may rest on.
_MIN_SAMPLES = 50

#: Reference rates (eq. 2) above this multiple of the gyro's largest rate are no motion the IMU
#: saw (the jump of a marker swap): they are dropped.
_RATE_LIMIT_PER_GYRO_MAX = 1.5

_IRLS_MAX_ITERATIONS = 50
_IRLS_ROTATION_CHANGE = 1e-7  # rad: the fit has converged


@dataclass(frozen=True)
class Alignment:
    """The lag and rotations that map an optical reference onto an IMU, with diagnostics.

    Attributes
    ----------
    lag_s : float
        τ (s): the reference sample stamped ``t'`` shows the IMU's motion at ``t' + τ``.
    sensor_to_marker : numpy.ndarray, shape (4,)
        ``[w, x, y, z]`` mapping IMU body-frame vectors into the marker cluster's frame (S → M).
    reference_to_enu : numpy.ndarray, shape (4,)
        ``[w, x, y, z]`` mapping the reference's world-frame (lab) vectors into ENU (L → E).
    gyro_bias : numpy.ndarray, shape (3,)
        ``b`` of eq. (3) (rad/s, IMU body frame): the gyro's constant offset seen by the fit.
    reference_read_as_inverse : bool
        The reference array's rates agreed with the gyro only when it was read as the inverse
        rotation, world → marker: it is world → marker, or scalar-last ``[x, y, z, w]`` (module
        docstring; the rates cannot tell which).  :func:`align_reference` reads it so too.
    lag_correlation : float
        Peak correlation of the rate magnitudes (1 = identical shapes).
    rate_residual_rms : float
        RMS (rad/s) of ``‖ω_gyro − R_SM ω_M − b‖`` over the samples kept (weight > 0).
    rate_residual_median, rate_residual_p95 : float
        Median and 95th percentile (rad/s) of that residual over every sample used, outliers
        included.
    rate_outlier_fraction : float
        Fraction of the rate samples given weight 0 (residual > 3 × median).
    gravity_residual_median_deg, gravity_residual_p95_deg : float
        Median and 95th percentile (°) of the angle between ``R_EL f̂_L`` and up, over the
        low-acceleration samples, outliers included.
    north_residual_median_deg : float
        Median (°) of the angle between the rotated horizontal field and north.
    world_outlier_fraction : float
        Fraction of the gravity and north pairs given weight 0 in step 3.
    """

    lag_s: float
    sensor_to_marker: np.ndarray = field(repr=False)
    reference_to_enu: np.ndarray = field(repr=False)
    gyro_bias: np.ndarray = field(repr=False)
    reference_read_as_inverse: bool
    lag_correlation: float
    rate_residual_rms: float
    rate_residual_median: float
    rate_residual_p95: float
    rate_outlier_fraction: float
    gravity_residual_median_deg: float
    gravity_residual_p95_deg: float
    north_residual_median_deg: float
    world_outlier_fraction: float


@dataclass(frozen=True)
class _RateFit:
    """Steps 1–2 for one reading of the reference."""

    lag_s: float
    correlation: float
    marker_to_sensor: Rotation
    bias: np.ndarray
    residual: np.ndarray
    weights: np.ndarray
    relative_residual: float


def estimate_alignment(gyr, acc, mag, time_s, quat_ref, ref_time_s, *, max_lag_s: float = 1.0,
                       rate_smoothing_s: float = 0.05) -> Alignment:
    """Find the lag, the sensor-to-marker and the lab-to-ENU rotations (module docstring, steps 1–3).

    Parameters
    ----------
    gyr, acc, mag : array_like, shape (T, 3)
        The IMU: angular rate (rad/s), specific force (m/s², +g up at rest), magnetic field (µT),
        body frame S; finite.
    time_s : array_like, shape (T,)
        IMU sample times (s), strictly increasing and evenly spaced up to jitter (steps 1–2 run on a
        uniform grid with their median step); ``np.arange(T) / fs`` for a rate ``fs``.
    quat_ref : array_like, shape (T_ref, 4)
        The reference, marker cluster → lab world frame, ``[w, x, y, z]`` (an inverse or
        scalar-last array is detected, with a warning); rows holding NaN are missing samples.
    ref_time_s : array_like, shape (T_ref,)
        Reference sample times (s) on the reference's clock, strictly increasing.
    max_lag_s : float
        The lag is searched in ``[−max_lag_s, max_lag_s]`` (s).
    rate_smoothing_s : float
        Width (s) of the moving average both rate signals pass before steps 1–2 (it tames the
        noise that differentiating the reference amplifies).

    Returns
    -------
    Alignment

    Raises
    ------
    ValueError
        A wrong shape, NaN/inf in the IMU, times not strictly increasing, a non-positive
        ``max_lag_s``/``rate_smoothing_s``, an implausible IMU (e.g. acc and mag swapped), too
        little overlap between reference and IMU, or a best lag on the edge of the search range.
    """
    gyr, acc, mag, time_s = _check_imu(gyr, acc, mag, time_s)
    raw, ref_time_s = _check_reference(quat_ref, ref_time_s)
    max_lag_s = check_positive(max_lag_s, "max_lag_s")
    rate_smoothing_s = check_positive(rate_smoothing_s, "rate_smoothing_s")
    check_imu_plausible(gyr, acc, mag, where="estimate_alignment")

    step = float(np.median(np.diff(time_s)))
    grid = time_s[0] + step * np.arange(int(np.floor((time_s[-1] - time_s[0]) / step)) + 1)
    gyr_grid = np.stack([np.interp(grid, time_s, gyr[:, axis]) for axis in range(3)], axis=1)
    width = 2 * int(round(rate_smoothing_s / (2.0 * step))) + 1
    max_shift = int(np.ceil(max_lag_s / step))

    gyr_max = float(np.max(np.linalg.norm(gyr_grid, axis=1)))
    fits, errors = {}, {}
    for inverse in (False, True):
        try:
            fits[inverse] = _fit_rates(gyr_grid, grid, _read_reference(raw, inverse), ref_time_s, max_shift, width,
                                       gyr_max)
        except ValueError as exc:
            errors[inverse] = exc
    if not fits:
        raise errors[False]
    inverse = min(fits, key=lambda key: fits[key].relative_residual)
    fit = fits[inverse]
    if inverse:
        plain = f"{fits[False].relative_residual:.2f}" if False in fits else "no fit"
        warn_user(f"quat_ref's rates agree with the gyro only when it is read as the inverse rotation (relative "
                  f"residual {fit.relative_residual:.2f}, against {plain} as given): it is world → marker, or "
                  f"scalar-last [x, y, z, w], which the rates cannot tell apart.  It was read as the inverse: the "
                  f"aligned reference (align_reference) is right either way, but sensor_to_marker and "
                  f"reference_to_enu refer to that reading; fix quat_ref's convention and run again to have them "
                  f"in the cluster's and the lab's own axes")

    sensor_to_marker = fit.marker_to_sensor.inv()
    world = _fit_world(acc, mag, time_s, _read_reference(raw, inverse), ref_time_s, fit.lag_s,
                       quat_ops.from_scipy(sensor_to_marker))
    kept = fit.weights > 0.0
    return Alignment(
        lag_s=fit.lag_s,
        sensor_to_marker=quat_ops.canonical(quat_ops.from_scipy(sensor_to_marker)),
        reference_to_enu=quat_ops.canonical(quat_ops.from_scipy(world["rotation"])),
        gyro_bias=fit.bias,
        reference_read_as_inverse=inverse,
        lag_correlation=fit.correlation,
        rate_residual_rms=float(np.sqrt(np.mean(fit.residual[kept] ** 2))),
        rate_residual_median=float(np.median(fit.residual)),
        rate_residual_p95=float(np.percentile(fit.residual, 95)),
        rate_outlier_fraction=float(np.mean(~kept)),
        gravity_residual_median_deg=float(np.median(world["gravity_deg"])),
        gravity_residual_p95_deg=float(np.percentile(world["gravity_deg"], 95)),
        north_residual_median_deg=float(np.median(world["north_deg"])),
        world_outlier_fraction=world["outlier_fraction"],
    )


def align_reference(quat_ref, ref_time_s, time_s, alignment: Alignment) -> np.ndarray:
    """The reference as the IMU's orientation in ENU on the IMU's time stamps, eq. (1).

    Parameters
    ----------
    quat_ref : array_like, shape (T_ref, 4)
        The reference as recorded, in the layout given to :func:`estimate_alignment` (read as the
        inverse if it found so); NaN rows are missing samples.
    ref_time_s : array_like, shape (T_ref,)
        Reference sample times (s), reference clock, strictly increasing.
    time_s : array_like, shape (T,)
        IMU sample times (s), strictly increasing.
    alignment : Alignment
        From :func:`estimate_alignment`.

    Returns
    -------
    numpy.ndarray, shape (T, 4)
        ``reference_to_enu ⊗ q_ref(t − τ) ⊗ sensor_to_marker``, ``[w, x, y, z]`` IMU body → ENU,
        with ``q_ref(t − τ)`` by SLERP between the two reference rows around ``t − τ``; NaN where
        either of them is missing, where they are further apart than 1.5 median steps (a gap),
        or where ``t − τ`` lies outside the reference's span.
    """
    if not isinstance(alignment, Alignment):
        raise ValueError(f"alignment must be an Alignment (from estimate_alignment), got {type(alignment).__name__}")
    raw, ref_time_s = _check_reference(quat_ref, ref_time_s)
    time_s = _check_times(time_s, "time_s")
    quat = _read_reference(raw, alignment.reference_read_as_inverse)
    q_lm = _reference_at(quat, ref_time_s, time_s - alignment.lag_s)
    ok = ~np.isnan(q_lm[:, 0])
    out = np.full((time_s.size, 4), np.nan)
    q_es = quat_ops.multiply(quat_ops.multiply(alignment.reference_to_enu, q_lm[ok]), alignment.sensor_to_marker)
    out[ok] = q_es / np.linalg.norm(q_es, axis=-1, keepdims=True)
    return out


# --- inputs ------------------------------------------------------------------------------------

def _check_times(value, name: str, n: int | None = None) -> np.ndarray:
    times = as_float_array(value, name)
    if times.ndim != 1 or times.size < 2:
        raise ValueError(f"{name} must be 1-D with at least 2 time stamps (s), got shape {times.shape}")
    if n is not None and times.size != n:
        raise ValueError(f"{name} must have one time stamp per sample ({n}), got {times.size}")
    if np.any(np.diff(times) <= 0.0):
        raise ValueError(f"{name} must be strictly increasing (s)")
    return times


def _check_imu(gyr, acc, mag, time_s):
    arrays = [as_float_array(value, name, last_dim=3) for value, name in ((gyr, "gyr"), (acc, "acc"), (mag, "mag"))]
    for arr, name in zip(arrays, ("gyr", "acc", "mag"), strict=True):
        if arr.ndim != 2:
            raise ValueError(f"{name} must have shape (T, 3), got {arr.shape}")
        if arr.shape != arrays[0].shape:
            raise ValueError(f"gyr, acc and mag must have the same shape (T, 3), got {arrays[0].shape} and "
                             f"{arr.shape} ({name})")
    return (*arrays, _check_times(time_s, "time_s", arrays[0].shape[0]))


def _check_reference(quat_ref, ref_time_s):
    raw = quat_ops.as_quat_with_gaps(quat_ref, "quat_ref")
    if raw.ndim != 2:
        raise ValueError(f"quat_ref must have shape (T_ref, 4), got {raw.shape}")
    if np.isnan(raw[:, 0]).all():
        raise ValueError("quat_ref has no sample (every row is NaN)")
    return raw, _check_times(ref_time_s, "ref_time_s", raw.shape[0])


def _read_reference(raw: np.ndarray, inverse: bool) -> np.ndarray:
    """Unit ``[w, x, y, z]`` marker → world quaternions (conjugated if ``inverse``); NaN rows kept."""
    quat = np.full_like(raw, np.nan)
    ok = ~np.isnan(raw[:, 0])
    quat[ok] = quat_ops.normalize(raw[ok])
    return quat_ops.conjugate(quat) if inverse else quat


# --- step 1 and 2: rates -----------------------------------------------------------------------

def _fit_rates(gyr_grid, grid, quat, ref_time_s, max_shift: int, width: int, gyr_max: float) -> _RateFit:
    mid_s, rates, valid = _body_rates(quat, ref_time_s)
    valid &= np.linalg.norm(rates, axis=1) <= _RATE_LIMIT_PER_GYRO_MAX * gyr_max
    step = grid[1] - grid[0]

    # Step 1: the reference's rates on the grid extended by the search range on both sides.
    extended = grid[0] + step * np.arange(-max_shift, grid.size + max_shift)
    ref_ext, ok_ext = _rates_at(mid_s, rates, valid, extended)
    ref_ext, ok_ext = _masked_moving_average(ref_ext, ok_ext, width)
    gyr_smooth, _ = _masked_moving_average(gyr_grid, np.ones(grid.size, bool), width)
    shift, correlation = _best_shift(np.linalg.norm(gyr_smooth, axis=1), np.linalg.norm(ref_ext, axis=1), ok_ext,
                                     max_shift)
    lag_s = float(shift * step)

    # Step 2: rates paired at the refined lag, both smoothed over the same samples.
    ref_at, ok = _rates_at(mid_s, rates, valid, grid - lag_s)
    ref_at, ok_ref = _masked_moving_average(ref_at, ok, width)
    gyr_at, _ = _masked_moving_average(gyr_grid, ok, width)
    if np.count_nonzero(ok_ref) < _MIN_SAMPLES:
        raise ValueError(f"only {np.count_nonzero(ok_ref)} IMU samples have reference rates at lag {lag_s:.3f} s "
                         f"(at least {_MIN_SAMPLES} needed)")
    rotation, bias, residual, weights = _robust_rotation(gyr_at[ok_ref], ref_at[ok_ref], with_offset=True)
    relative = float(np.median(residual) / max(np.median(np.linalg.norm(gyr_at[ok_ref], axis=1)), 1e-12))
    return _RateFit(lag_s, correlation, rotation, bias, residual, weights, relative)


def _body_rates(quat: np.ndarray, times: np.ndarray):
    """Eq. (2): body rates (rad/s) at the midpoints of neighbouring rows, and where they exist."""
    valid = ~np.isnan(quat[:-1, 0]) & ~np.isnan(quat[1:, 0]) & ~_gaps(times)
    rates = np.zeros((times.size - 1, 3))
    if np.any(valid):
        delta = quat_ops.multiply(quat_ops.conjugate(quat[:-1][valid]), quat[1:][valid])
        rates[valid] = quat_ops.to_scipy(delta).as_rotvec() / np.diff(times)[valid, None]
    return 0.5 * (times[:-1] + times[1:]), rates, valid


def _gaps(times: np.ndarray) -> np.ndarray:
    """Boolean per interval: the time stamps jump by more than 1.5 median steps."""
    steps = np.diff(times)
    return steps > _GAP_PER_MEDIAN_STEP * np.median(steps)


def _rates_at(mid_s, rates, valid, query):
    """Rates linearly interpolated at ``query``, and where both neighbours exist (never across a gap)."""
    filled = np.where(valid[:, None], rates, 0.0)
    out = np.stack([np.interp(query, mid_s, filled[:, axis]) for axis in range(3)], axis=1)
    ok = np.interp(query, mid_s, valid.astype(float), left=0.0, right=0.0) == 1.0
    return out, ok


def _masked_moving_average(x, mask, width: int):
    """Mean of ``x`` over the samples of ``mask`` in a centred window; kept where more than half is in ``mask``."""
    kernel = np.ones(width)
    count = np.convolve(mask.astype(float), kernel, mode="same")
    sums = np.stack([np.convolve(np.where(mask, x[:, axis], 0.0), kernel, mode="same") for axis in range(3)], axis=1)
    ok = 2.0 * count > width
    return sums / np.maximum(count, 1.0)[:, None], ok


def _best_shift(gyr_norm, ref_norm_ext, ref_ok_ext, max_shift: int) -> tuple[float, float]:
    """Step 1: the shift (in grid steps, sub-sample) maximising the correlation, and that correlation."""
    shifts = np.arange(-max_shift, max_shift + 1)
    correlation = _masked_correlation(gyr_norm, ref_norm_ext, ref_ok_ext)[::-1]  # index i ↔ shift max_shift − i
    if np.all(np.isnan(correlation)):
        raise ValueError(f"the reference's rates and the IMU overlap in fewer than {_MIN_SAMPLES} samples at every "
                         f"lag within ±max_lag_s (rates exist between two present rows, without a gap, at most "
                         f"{_RATE_LIMIT_PER_GYRO_MAX:g} × the gyro's largest); check ref_time_s against time_s")
    best = int(np.nanargmax(correlation))
    if best in (0, shifts.size - 1):
        raise ValueError(f"the best lag, {shifts[best]:+d} IMU samples, lies on the edge of the search range "
                         f"±max_lag_s; widen max_lag_s")
    left, peak, right = correlation[best - 1: best + 2]
    curvature = left - 2.0 * peak + right
    offset = 0.0
    if np.isfinite(left) and np.isfinite(right) and curvature < 0.0:
        offset = float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))
    return float(shifts[best] + offset), float(peak)


def _masked_correlation(x, y_ext, y_ok_ext) -> np.ndarray:
    """Pearson correlation of ``x`` (length n) with every window ``y_ext[i:i + n]``, over the samples where
    ``y_ok_ext`` holds; NaN where fewer than the minimum samples count.  The six sums come from
    :func:`scipy.signal.correlate` (by FFT), not a loop over the windows."""
    mask = y_ok_ext.astype(float)
    y = np.where(y_ok_ext, y_ext, 0.0)

    from scipy import signal  # here, not at the top: scipy.signal takes 0.5 s to import, in every kernel

    def window_sums(a, b):
        return signal.correlate(a, b, mode="valid")

    ones = np.ones(x.size)
    count = np.rint(window_sums(mask, ones))
    sum_x, sum_y = window_sums(mask, x), window_sums(y, ones)
    sum_xx, sum_yy, sum_xy = window_sums(mask, x * x), window_sums(y * y, ones), window_sums(y, x)
    enough = count >= _MIN_SAMPLES
    count = np.maximum(count, 1.0)
    covariance = sum_xy - sum_x * sum_y / count
    variance = (sum_xx - sum_x**2 / count) * (sum_yy - sum_y**2 / count)
    ok = enough & (variance > 0.0)
    return np.divide(covariance, np.sqrt(np.where(ok, variance, 1.0)), out=np.full(count.size, np.nan), where=ok)


def _robust_rotation(target, source, *, with_offset: bool):
    """Rotation ``R`` (and offset ``b``) with ``target ≈ R·source + b``, Tukey-reweighted (module docstring).

    Returns the rotation, the offset (zeros without ``with_offset``), each pair's residual norm and
    its final weight (0 for an outlier).
    """
    weights, previous = np.ones(len(target)), None
    for _ in range(_IRLS_MAX_ITERATIONS):
        if with_offset:
            target_mean = weights @ target / weights.sum()
            source_mean = weights @ source / weights.sum()
            rotation, _ = Rotation.align_vectors(target - target_mean, source - source_mean, weights=weights)
            offset = target_mean - rotation.apply(source_mean)
        else:
            rotation, _ = Rotation.align_vectors(target, source, weights=weights)
            offset = np.zeros(3)
        residual = np.linalg.norm(target - rotation.apply(source) - offset, axis=1)
        cutoff = CUTOFF_PER_MEDIAN * np.median(residual)
        if cutoff == 0.0:  # an exact fit
            break
        weights = np.where(residual < cutoff, (1.0 - (residual / cutoff) ** 2) ** 2, 0.0)
        if previous is not None and (previous.inv() * rotation).magnitude() < _IRLS_ROTATION_CHANGE:
            break
        previous = rotation
    return rotation, offset, residual, weights


# --- step 3: the world ---------------------------------------------------------------------------

def _reference_at(quat, ref_time_s, query) -> np.ndarray:
    """``q_ref`` at ``query`` (s, reference clock) by SLERP between the neighbouring rows; NaN where either
    is missing, they straddle a gap, or ``query`` is outside the reference's span."""
    index = np.clip(np.searchsorted(ref_time_s, query, side="right") - 1, 0, ref_time_s.size - 2)
    present = ~np.isnan(quat[:, 0])
    ok = ((query >= ref_time_s[0]) & (query <= ref_time_s[-1]) & present[index] & present[index + 1]
          & ~_gaps(ref_time_s)[index])
    out = np.full((query.size, 4), np.nan)
    left = index[ok]
    mu = (query[ok] - ref_time_s[left]) / (ref_time_s[left + 1] - ref_time_s[left])
    out[ok] = quat_ops.slerp(quat[left], quat[left + 1], np.clip(mu, 0.0, 1.0))
    return out


def _fit_world(acc, mag, time_s, quat, ref_time_s, lag_s: float, sensor_to_marker) -> dict:
    """Step 3: ``reference_to_enu`` from eq. (4), with its residuals (°) and outlier fraction."""
    q_lm = _reference_at(quat, ref_time_s, time_s - lag_s)
    present = ~np.isnan(q_lm[:, 0])
    acc_norm, mag_norm = np.linalg.norm(acc, axis=1), np.linalg.norm(mag, axis=1)
    calm = present & (np.abs(acc_norm - np.median(acc_norm)) <= NORM_TOLERANCE * np.median(acc_norm))
    steady = calm & (np.abs(mag_norm - np.median(mag_norm)) <= NORM_TOLERANCE * np.median(mag_norm))
    if np.count_nonzero(calm) < _MIN_SAMPLES or np.count_nonzero(steady) < _MIN_SAMPLES:
        raise ValueError(f"too few samples with the reference present and low acceleration ({np.count_nonzero(calm)})"
                         f" or an undisturbed field ({np.count_nonzero(steady)}); at least {_MIN_SAMPLES} needed")
    q_ls = quat_ops.multiply(q_lm, sensor_to_marker)
    up = quat_ops.rotate(q_ls[calm], acc[calm])
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    field_l = quat_ops.rotate(q_ls[steady], mag[steady])
    up_steady = up[steady[calm]]
    north = field_l - np.sum(field_l * up_steady, axis=1, keepdims=True) * up_steady
    north /= np.maximum(np.linalg.norm(north, axis=1, keepdims=True), 1e-12)
    target = np.concatenate([np.tile([0.0, 0.0, 1.0], (len(up), 1)), np.tile([0.0, 1.0, 0.0], (len(north), 1))])
    rotation, _, _, weights = _robust_rotation(target, np.concatenate([up, north]), with_offset=False)
    return {"rotation": rotation,
            "gravity_deg": _angle_deg(rotation.apply(up), [0.0, 0.0, 1.0]),
            "north_deg": _angle_deg(rotation.apply(north), [0.0, 1.0, 0.0]),
            "outlier_fraction": float(np.mean(weights == 0.0))}


def _angle_deg(vectors, direction) -> np.ndarray:
    """Angle (°) between each unit vector and a unit direction (atan2: accurate near 0)."""
    cross = np.linalg.norm(np.cross(vectors, direction), axis=1)
    return np.degrees(np.arctan2(cross, vectors @ np.asarray(direction)))
