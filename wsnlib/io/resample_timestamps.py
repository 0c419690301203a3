"""Resampling of recordings given by their time stamps (irregular, repeated, with gaps) to any rate.

:func:`resample_signal_timestamped`, :func:`resample_quaternion_timestamped` and
:func:`resample_mask_timestamped` (the section "Resampling from time stamps").  Regular signals whose
rate ratio is a ratio of small integers (BROAD's 2000/7 Hz to 50 Hz): :mod:`wsnlib.io.resample`, whose
anti-alias filter the downsampling here shares.

Resampling from time stamps
---------------------------
For other labs' recordings, which come with a time stamp per sample rather than a rate.
Stamps ``time_s`` are in seconds, shape ``(T,)``, one per sample and shared by every batch
element, from any origin (e.g. Unix time); the output has the same origin.  Before anything
else:

* Equal stamps: samples sharing a stamp become one, their mean (quaternions: the normalised
  mean, each turned to the hemisphere of the first valid one, NaN rows left out; masks: the
  first).  Stamps must not decrease: sort the samples first.
* Repeated values (sample-and-hold): a sensor read faster than it measures repeats its last
  value under later stamps; interpolating through those copies draws a stair.  With
  ``drop_repeated_values=True`` (the default; signals and quaternions) a sample whose values
  equal the previous sample's exactly, in every channel of every batch element, is dropped:
  the first of each run is kept, with the stamp of when it was measured.  A value held longer
  than the max gap is then a gap (a stuck sensor, or a reference holding its last pose).  A
  noisy sensor almost never repeats all its axes exactly; synthetic signals that stay exactly
  constant need ``drop_repeated_values=False``.  Masks are never thinned.
* Gaps: consecutive samples kept are joined when at most ``max_gap_s`` apart (default
  :data:`MAX_GAP_INTERVALS` = 2.5 times their median interval: at regular stamps one missing
  sample is bridged, two are not).  An output time in a longer interval, or outside the first
  to last sample, is not invented: it is invalid (``valid`` False with NaN values for
  signals, False for masks, NaN for quaternions).  A sample missing from a signal is a
  missing row; NaN in a signal is an error.
* If the sensor did sample regularly and only the stamps jitter (logging delays), fit a line
  to the stamps first: interpolating the true samples at jittered times adds error.

The grid (:func:`resample_signal_timestamped`): output sample ``k`` at
``t_k = t_0 + k / fs_out`` (s), where ``t_0`` is the first stamp, for ``k = 0 … T_out − 1`` with
``T_out = ⌊(t_last − t_0)·fs_out⌋ + 1`` and ``t_last`` the last stamp (to a tolerance of 1e-9
of the median interval, so that 10 s at 50 Hz gives 501 samples): every ``t_k`` lies in
``[t_0, t_last]``.  ``fs_out`` may be above or below the input rate ``fs_in``, taken as
1 / (median interval between the samples kept).  The quaternion and mask functions take any
output times (e.g. that grid, so that everything lines up sample by sample).

* IMU signals (:func:`resample_signal_timestamped`): a cubic spline
  (:class:`scipy.interpolate.CubicSpline`, not-a-knot ends) through the samples kept, one per
  stretch between gaps (never across a gap).  Upsampling (``fs_out ≥ fs_in``): the spline at
  ``t_k``, no filter.  Downsampling: the spline on the fine regular grid
  ``t_0 + j / (m·fs_out)``, ``m = max(2, ⌈2·fs_in / fs_out⌉)`` (at least twice the input rate,
  so the spline's images above the input's Nyquist frequency do not fold into the band),
  filtered by the FIR of :func:`~wsnlib.io.resample.resample_signal` for ``up, down = 1, m``
  (Kaiser β = 5, ``20·m + 1`` taps, cutoff ``fs_out / 2``, unit DC gain, centred: no delay),
  every ``m``-th sample kept.  Its response, the same for every ``m``: gain within 0.21 % up to
  ``0.4·fs_out``, −6.0 dB at ``fs_out / 2``, at least 55 dB attenuation from ``0.6·fs_out``.
  Each stretch is extended beyond its ends by point reflection; the first and last
  ``10 / fs_out`` s of output of each stretch (0.2 s at 50 Hz) depend on that extension.  The
  filter acts on the spline, whose own error comes on top: for stamps jittered by ±30 % of the
  interval, a sinusoid of frequency ``f`` is reproduced to about 1e-5 of its amplitude at
  ``f = fs_in / 45``, 5e-3 at ``fs_in / 9``, 3 % at ``fs_in / 6``; content near ``fs_in / 2``
  is not resolved from such stamps, and leaks into the band (a 40 Hz tone sampled at ~90 Hz
  with ±30 % jitter comes out at 50 Hz only 3 dB down; with regular stamps, 58 dB).
* Orientations (:func:`resample_quaternion_timestamped`): SLERP between the two samples kept
  around each time (shorter arc), not filtered, as
  :func:`~wsnlib.io.resample.resample_quaternion`; on a stamp the sample itself.  NaN where a
  needed neighbour is NaN, where the neighbours are more than ``max_gap_s`` apart, or outside
  ``[t_0, t_last]``.
* Masks (:func:`resample_mask_timestamped`): the nearest sample (ties go to the later one);
  invalid (False, and ``valid`` False) where the neighbours are more than ``max_gap_s`` apart
  or outside ``[t_0, t_last]``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import interpolate

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_float_array, check_flag, check_positive, real_array
from wsnlib.io.resample import _antialias_filter

#: Default ``max_gap_s``: this many times the median interval between the samples kept.
MAX_GAP_INTERVALS = 2.5

#: Times closer than this fraction of the median sample interval count as equal (plus float
#: rounding of the stamps themselves); it decides whether an output time falls on a sample.
_TIME_RTOL = 1e-9


@dataclasses.dataclass(frozen=True)
class Resampled:
    """Samples on a grid of times, with the mask of the times that input samples back.

    Attributes
    ----------
    time_s : numpy.ndarray, shape (T_out,)
        Output times (s), same origin as the input stamps.
    values : numpy.ndarray
        A signal: shape ``(..., T_out, C)`` in the input's units, NaN where ``valid`` is
        False.  A mask: shape ``(..., T_out)``, False where ``valid`` is False.
    valid : numpy.ndarray of bool, shape (T_out,)
        True where an output time lies between input samples at most ``max_gap_s`` apart;
        False in a longer gap or outside the recording.  Pass it on as the ``received`` mask
        (the filters ignore the values of samples not received).
    """

    time_s: np.ndarray
    values: np.ndarray
    valid: np.ndarray


def resample_signal_timestamped(x, time_s, fs_out, *, max_gap_s=None, drop_repeated_values: bool = True) -> Resampled:
    """An IMU signal with time stamps, resampled onto a regular grid at any ``fs_out`` (see the
    module docstring, "Resampling from time stamps").

    Parameters
    ----------
    x : array_like, shape (..., T, 3) (or (..., T, C))
        Finite samples, time on axis -2 (e.g. ``gyr`` rad/s, ``acc`` m/s², ``mag`` µT).  A
        missing sample is a missing row (and stamp), not a NaN.
    time_s : array_like, shape (T,)
        Time stamp of each sample (s), shared by every batch element; any origin, irregular,
        equal stamps allowed, never decreasing.
    fs_out : float
        Output rate (Hz), above or below the input's.
    max_gap_s : float, optional
        Longest interval (s) between consecutive samples kept that is interpolated across;
        output times in a longer one are not valid.  Default :data:`MAX_GAP_INTERVALS` times
        the median interval.
    drop_repeated_values : bool
        Drop a sample whose values equal the previous sample's exactly (sample-and-hold
        copies); False keeps them (synthetic signals that are exactly constant).

    Returns
    -------
    Resampled
        ``time_s`` = ``t_0 + k / fs_out`` for ``k = 0 … T_out − 1`` with ``t_0`` the first stamp
        and ``T_out = ⌊(t_last − t_0)·fs_out⌋ + 1``; ``values`` shape ``(..., T_out, C)``, NaN
        where ``valid`` (shape ``(T_out,)``) is False.
    """
    x = as_float_array(x, "x", min_ndim=2)
    stamps = _check_time_stamps(time_s, x.shape[-2], "x", "axis -2")
    fs_out = check_positive(fs_out, "fs_out")
    repeated = check_flag(drop_repeated_values, "drop_repeated_values")
    starts = _equal_stamp_groups(stamps)
    t, x = stamps[starts], _group_means(x, starts)
    if repeated:
        keep = np.concatenate([[True], ~_same_as_previous(x)])
        t, x = t[keep], x[..., keep, :]
    _check_enough(t.size, "x needs at least 2 samples with distinct stamps and values (equal stamps are merged, "
                          "repeated values dropped: drop_repeated_values=False keeps them)")
    interval = float(np.median(np.diff(t)))
    max_gap = _max_gap(max_gap_s, interval)
    origin = stamps[0]
    tol = _time_tolerance(stamps, interval)
    n_out = int(math.floor((stamps[-1] - origin + tol) * fs_out)) + 1
    t_rel = t - origin
    values = np.full(x.shape[:-2] + (n_out, x.shape[-1]), np.nan)
    valid = np.zeros(n_out, dtype=bool)
    # fine-grid factor m; 0 (no filter) unless fs_out is below the input rate (beyond rounding)
    downsampling = fs_out * interval < 1.0 - _TIME_RTOL
    factor = max(2, math.ceil(2.0 / (interval * fs_out))) if downsampling else 0
    for first, last in _segments(t_rel, max_gap):
        a, b = t_rel[first], t_rel[last]
        k0 = max(math.ceil((a - tol) * fs_out), 0)
        k1 = min(math.floor((b + tol) * fs_out), n_out - 1)
        if k1 < k0:
            continue
        spline = interpolate.CubicSpline(t_rel[first:last + 1], x[..., first:last + 1, :], axis=-2)
        if factor:
            values[..., k0:k1 + 1, :] = _lowpass_decimate(spline, a, b, k0, k1, fs_out, factor, tol)
        else:
            values[..., k0:k1 + 1, :] = spline(np.clip(np.arange(k0, k1 + 1) / fs_out, a, b))
        valid[k0:k1 + 1] = True
    return Resampled(time_s=origin + np.arange(n_out) / fs_out, values=values, valid=valid)


def _lowpass_decimate(spline, a: float, b: float, k0: int, k1: int, fs_out: float, factor: int,
                      tol: float) -> np.ndarray:
    """Outputs ``k0 … k1`` of one segment ``[a, b]``: the spline on the fine grid ``j / (m·fs_out)``,
    extended by point reflection, filtered by the anti-alias FIR and kept every ``m``-th sample."""
    fs_fine = factor * fs_out
    half_len = 10 * factor  # the filter's half length, _antialias_filter(1, m)
    j0 = min(math.ceil((a - tol) * fs_fine), k0 * factor)
    j1 = max(math.floor((b + tol) * fs_fine), k1 * factor)
    fine = spline(np.clip(np.arange(j0, j1 + 1) / fs_fine, a, b))
    # start the extended array on a multiple of m, at least half_len before j0: resample_poly's
    # output n is then fine sample start + n·m, and its own zero padding never reaches a kept output
    start = (j0 - half_len) // factor * factor
    pad = [(0, 0)] * fine.ndim
    pad[-2] = (j0 - start, half_len)
    extended = np.pad(fine, pad, mode="reflect", reflect_type="odd")
    from scipy import signal  # here, not at the top: scipy.signal takes 0.5 s to import, in every kernel

    y = signal.resample_poly(extended, 1, factor, axis=-2, window=_antialias_filter(1, factor))
    first = k0 - start // factor
    return y[..., first:first + k1 - k0 + 1, :]


def resample_quaternion_timestamped(quat, time_s, time_out_s, *, max_gap_s=None,
                                    drop_repeated_values: bool = True) -> np.ndarray:
    """Orientations with time stamps, by SLERP at any output times (e.g. the grid of
    :func:`resample_signal_timestamped`).

    Parameters
    ----------
    quat : array_like, shape (..., T, 4)
        Quaternions ``[w, x, y, z]`` (normalised here); a row holding NaN marks a missing
        sample (e.g. an optical reference whose markers were lost).
    time_s : array_like, shape (T,)
        Time stamp of each row (s), as in :func:`resample_signal_timestamped`.
    time_out_s : array_like, shape (T_out,)
        Output times (s), same origin as ``time_s``; any finite values, in any order.
    max_gap_s : float, optional
        Longest interval (s) between consecutive rows kept that is interpolated across.
        Default :data:`MAX_GAP_INTERVALS` times the median interval.
    drop_repeated_values : bool
        Drop a row equal to the previous row (a reference that holds its last pose).

    Returns
    -------
    numpy.ndarray, shape (..., T_out, 4)
        ``SLERP(q_i, q_{i+1}, μ)``, ``t_i ≤ t < t_{i+1}``, ``μ = (t − t_i) / (t_{i+1} − t_i)``,
        along the shorter arc; ``q_i`` itself (normalised) when ``t`` is on a stamp, whatever
        its neighbours.  NaN where a needed neighbour is NaN, where ``t_{i+1} − t_i >
        max_gap_s``, and outside ``[t_0, t_last]``.
    """
    quat = quat_ops.as_quat_with_gaps(quat, "quat")
    if quat.ndim < 2:
        raise ValueError(f"quat must have shape (..., T, 4), got shape {quat.shape}")
    stamps = _check_time_stamps(time_s, quat.shape[-2], "quat", "axis -2")
    times = _check_output_times(time_out_s)
    repeated = check_flag(drop_repeated_values, "drop_repeated_values")
    ok = ~np.isnan(quat[..., 0])
    unit = np.where(ok[..., None], quat, quat_ops.identity())
    unit = unit / np.linalg.norm(unit, axis=-1, keepdims=True)
    starts = _equal_stamp_groups(stamps)
    t, unit, ok = stamps[starts], *_quaternion_group_means(unit, ok, starts)
    if repeated:
        keep = np.concatenate([[True], ~_same_as_previous(np.where(ok[..., None], unit, np.nan))])
        t, unit, ok = t[keep], unit[..., keep, :], ok[..., keep]
    _check_enough(t.size, "quat needs at least 2 rows with distinct stamps and values (equal stamps are merged, "
                          "repeated rows dropped: drop_repeated_values=False keeps them)")
    interval = float(np.median(np.diff(t)))
    near = _neighbours(t, times, _max_gap(max_gap_s, interval), _time_tolerance(stamps, interval))
    left, right = near.left, near.right
    valid = near.inside & ((near.bridged & ok[..., left] & ok[..., right])
                           | (near.on_left & ok[..., left]) | (near.on_right & ok[..., right]))
    out = quat_ops.slerp(unit[..., left, :], unit[..., right, :], near.mu)
    out = np.where(near.on_right[:, None], unit[..., right, :], out)
    out = np.where(near.on_left[:, None], unit[..., left, :], out)
    return np.where(valid[..., None], out, np.nan)


def resample_mask_timestamped(mask, time_s, time_out_s, *, max_gap_s=None) -> Resampled:
    """A boolean mask with time stamps at any output times: the value of the nearest sample.

    Parameters
    ----------
    mask : array_like of bool, shape (..., T)
        E.g. ``movement`` or ``received``; time on the last axis.
    time_s : array_like, shape (T,)
        Time stamp of each sample (s), as in :func:`resample_signal_timestamped`; of samples
        sharing a stamp the first counts (a mask is not averaged, nor thinned for repeats).
    time_out_s : array_like, shape (T_out,)
        Output times (s), same origin; any finite values, in any order.
    max_gap_s : float, optional
        As in :func:`resample_quaternion_timestamped`.

    Returns
    -------
    Resampled
        ``time_s`` a copy of ``time_out_s``; ``values`` shape ``(..., T_out)``, the nearest
        sample's value (a time halfway between two samples takes the later one, as
        :func:`~wsnlib.io.resample.resample_mask`), False where ``valid`` is False: outside
        ``[t_0, t_last]`` or between samples more than ``max_gap_s`` apart (on a stamp is valid).
    """
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.ndim < 1:
        raise ValueError(f"mask must be a boolean array of shape (..., T), got {mask.dtype} {mask.shape}")
    stamps = _check_time_stamps(time_s, mask.shape[-1], "mask", "its last axis")
    times = _check_output_times(time_out_s)
    starts = _equal_stamp_groups(stamps)
    t, mask = stamps[starts], mask[..., starts]
    _check_enough(t.size, "mask needs at least 2 samples with distinct time stamps")
    interval = float(np.median(np.diff(t)))
    near = _neighbours(t, times, _max_gap(max_gap_s, interval), _time_tolerance(stamps, interval))
    valid = near.inside & (near.bridged | near.on_left | near.on_right)
    later = (times - t[near.left]) >= (t[near.right] - times)
    nearest = np.where(later, near.right, near.left)
    return Resampled(time_s=times.copy(), values=mask[..., nearest] & valid, valid=valid)


@dataclasses.dataclass(frozen=True)
class _Neighbours:
    """For each output time: the samples ``left``/``right`` around it and where it falls."""

    left: np.ndarray      # index of t_i ≤ t (clipped to the span's first interval)
    right: np.ndarray     # left + 1
    mu: np.ndarray        # (t − t_i) / (t_{i+1} − t_i), clipped to [0, 1]
    inside: np.ndarray    # t in [t_0, t_last]
    bridged: np.ndarray   # the interval t_i … t_{i+1} is at most max_gap_s long
    on_left: np.ndarray   # t is on t_i (within the tolerance)
    on_right: np.ndarray  # t is on t_{i+1}


def _neighbours(t: np.ndarray, times: np.ndarray, max_gap: float, tol: float) -> _Neighbours:
    right = np.clip(np.searchsorted(t, times, side="right"), 1, t.size - 1)
    left = right - 1
    step = t[right] - t[left]
    return _Neighbours(left=left, right=right, mu=np.clip((times - t[left]) / step, 0.0, 1.0),
                       inside=(times >= t[0] - tol) & (times <= t[-1] + tol), bridged=step <= max_gap,
                       on_left=np.abs(times - t[left]) <= tol, on_right=np.abs(times - t[right]) <= tol)


def _check_time_stamps(time_s, n_samples: int, owner: str, where: str) -> np.ndarray:
    """``time_s`` as a finite, non-decreasing float array with one stamp per sample of ``owner``."""
    stamps = real_array(time_s, "time_s")
    if stamps.ndim != 1:
        raise ValueError(f"time_s must be 1-D (one stamp per sample, shared by every batch element), "
                         f"got shape {stamps.shape}")
    if stamps.size != n_samples:
        raise ValueError(f"time_s has {stamps.size} stamps but {owner} has {n_samples} samples along {where}")
    if not np.all(np.isfinite(stamps)):
        raise ValueError(f"time_s contains NaN or inf (first at index {int(np.flatnonzero(~np.isfinite(stamps))[0])})")
    back = np.flatnonzero(np.diff(stamps) < 0.0)
    if back.size:
        i = int(back[0])
        raise ValueError(f"time_s must not decrease (equal stamps are merged), got time_s[{i}] = {stamps[i]!r} "
                         f"> time_s[{i + 1}] = {stamps[i + 1]!r}; sort the samples by time first")
    _check_enough(stamps.size, f"{owner} needs at least 2 samples along {where}")
    return stamps


def _check_output_times(time_out_s) -> np.ndarray:
    times = real_array(time_out_s, "time_out_s")
    if times.ndim != 1:
        raise ValueError(f"time_out_s must be 1-D, got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        bad = int(np.flatnonzero(~np.isfinite(times))[0])
        raise ValueError(f"time_out_s contains NaN or inf (first at index {bad})")
    return times


def _check_enough(n_samples: int, what: str) -> None:
    if n_samples < 2:
        raise ValueError(f"{what}, got {n_samples}")


def _max_gap(max_gap_s, interval: float) -> float:
    if max_gap_s is None:
        return MAX_GAP_INTERVALS * interval
    return check_positive(max_gap_s, "max_gap_s")


def _time_tolerance(stamps: np.ndarray, interval: float) -> float:
    """Times closer than this are equal: 1e-9 of the median interval plus the stamps' rounding."""
    return _TIME_RTOL * interval + 4.0 * float(np.spacing(np.max(np.abs(stamps))))


def _equal_stamp_groups(stamps: np.ndarray) -> np.ndarray:
    """Index of the first sample of each run of equal stamps."""
    return np.flatnonzero(np.concatenate([[True], np.diff(stamps) > 0.0]))


def _group_means(x: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Mean over each run of equal stamps along axis -2 (the samples themselves if none repeats)."""
    if starts.size == x.shape[-2]:
        return x
    counts = np.diff(np.append(starts, x.shape[-2]))
    return np.add.reduceat(x, starts, axis=-2) / counts[:, None]


def _quaternion_group_means(unit: np.ndarray, ok: np.ndarray, starts: np.ndarray):
    """Per run of equal stamps: the normalised mean of its valid unit quaternions, each turned
    to the hemisphere of the run's first valid one; NaN-marked (``ok`` False) if none is valid."""
    n = unit.shape[-2]
    if starts.size == n:
        return unit, ok
    group = np.cumsum(np.isin(np.arange(n), starts)) - 1
    first_valid = np.minimum.reduceat(np.where(ok, np.arange(n), n), starts, axis=-1)
    any_valid = first_valid < n
    reference = np.take_along_axis(unit, np.minimum(first_valid, n - 1)[..., None], axis=-2)[..., group, :]
    sign = np.where(np.sum(unit * reference, axis=-1) < 0.0, -1.0, 1.0)
    summed = np.add.reduceat(np.where(ok[..., None], sign[..., None] * unit, 0.0), starts, axis=-2)
    summed = np.where(any_valid[..., None], summed, quat_ops.identity())
    return summed / np.linalg.norm(summed, axis=-1, keepdims=True), any_valid


def _same_as_previous(x: np.ndarray) -> np.ndarray:
    """``(T - 1,)``: sample ``i + 1`` equals sample ``i`` in every channel of every batch element
    (NaN never equals anything)."""
    rows = np.moveaxis(x, -2, 0).reshape(x.shape[-2], -1)
    return np.all(rows[1:] == rows[:-1], axis=1)


def _segments(t: np.ndarray, max_gap: float) -> list[tuple[int, int]]:
    """``(first, last)`` sample indices of each run of ≥ 2 samples joined by intervals ≤ ``max_gap``."""
    joined = np.diff(t) <= max_gap
    edges = np.diff(np.concatenate([[0], joined.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True))
