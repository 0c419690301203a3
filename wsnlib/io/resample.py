"""Resampling of regular signals whose rate ratio is a ratio of small integers: BROAD's 2000/7 ≈ 285.714 Hz
to the 50 Hz of the WSN nodes.

:func:`resample_signal`, :func:`resample_quaternion`, :func:`resample_mask` and :func:`resample_broad`
(the sections "Time grid" and "What each signal gets").  Recordings given by their time stamps
(irregular, repeated, with gaps), to any rate: :mod:`wsnlib.io.resample_timestamps`.

Time grid
---------
The rate ratio must be a ratio of small integers, ``fs_out / fs_in = up / down`` (found with
:meth:`fractions.Fraction.limit_denominator`, denominator ≤ 1000, and accepted only if it
matches to 1e-9 relative).  BROAD stores ``sampling_rate`` = 2000/7 Hz to full double
precision, so 50 Hz is exactly ``7/40``: every 40 input samples give 7 output samples.

Input sample ``i`` is at ``i / fs_in``, output sample ``k`` at ``t_k = k / fs_out``, for every
``t_k`` inside the input span ``[0, (T - 1) / fs_in]``: ``T_out = (T - 1)·up // down + 1``
samples (9317 for a BROAD trial of 53,240 samples).  All three functions below produce this
same grid, so their outputs line up sample by sample.

What each signal gets
---------------------
* IMU signals (:func:`resample_signal`): anti-alias low-pass FIR and polyphase resampling,
  :func:`scipy.signal.resample_poly`, with scipy's standard filter (Kaiser window β = 5,
  ``20·max(up, down) + 1`` taps at the rate ``fs_in·up``, cutoff at the output Nyquist
  frequency ``fs_out / 2``), whose polyphase branches are rescaled to unit DC gain so that a
  constant stays exactly constant.  For 285.714 → 50 Hz: gain within 0.2 % up to 20 Hz,
  −6 dB at 25 Hz, at least 55 dB attenuation from 30 Hz on.  The filter is linear-phase and
  centred (no delay): output ``k`` estimates the band-limited signal at ``t_k``.  Edges: the
  signal is extended beyond both ends by point reflection through the end value
  (``padtype="antireflect"``), which continues constants and linear trends; the first and
  last ``10·down / up`` input samples' worth of output (0.2 s at BROAD's rates) depend on that
  extension.
* Orientations (:func:`resample_quaternion`): SLERP between the two input samples around
  ``t_k`` (shorter arc), not filtered — the reference is sampled, not smoothed.  If either
  neighbour is NaN (optical markers lost) the output is NaN: gaps are never bridged, and a gap
  widens by at most one output sample on each side.
* Masks (:func:`resample_mask`): the nearest input sample (ties go to the later one).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from fractions import Fraction

import numpy as np

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_float_array, check_positive
from wsnlib.io.broad import BroadTrial

#: Largest ``down`` (or ``up``) accepted in the rate ratio.
MAX_DENOMINATOR = 1000

#: Relative tolerance between the requested ``fs_out / fs_in`` and the ratio ``up / down``.
_RATIO_RTOL = 1e-9

#: Kaiser window parameter of the anti-alias filter (scipy's default for resample_poly).
_KAISER_BETA = 5.0


def resample_factors(fs_in, fs_out) -> tuple[int, int]:
    """The integers ``(up, down)`` with ``fs_out / fs_in = up / down``, coprime.

    Raises ``ValueError`` if a rate is not positive and finite, if ``fs_out > fs_in``
    (upsampling: :func:`~wsnlib.io.resample_timestamps.resample_signal_timestamped`), or if the
    ratio is no ratio of integers ≤ :data:`MAX_DENOMINATOR` (within 1e-9 relative; other rates:
    :func:`~wsnlib.io.resample_timestamps.resample_signal_timestamped`).
    """
    fs_in = check_positive(fs_in, "fs_in")
    fs_out = check_positive(fs_out, "fs_out")
    if fs_out > fs_in:
        raise ValueError(f"fs_out = {fs_out:g} Hz exceeds fs_in = {fs_in:g} Hz; only downsampling is supported "
                         f"here: to upsample, use wsnlib.io.resample_timestamps.resample_signal_timestamped("
                         f"x, time_s, fs_out)")
    ratio = fs_out / fs_in
    fraction = Fraction(ratio).limit_denominator(MAX_DENOMINATOR)
    if not math.isclose(float(fraction), ratio, rel_tol=_RATIO_RTOL):
        raise ValueError(f"fs_out / fs_in = {fs_out!r} / {fs_in!r} = {ratio!r} is not a ratio of integers up to "
                         f"{MAX_DENOMINATOR} (nearest {fraction}): resample from the time stamps instead, with "
                         f"wsnlib.io.resample_timestamps.resample_signal_timestamped(x, time_s, fs_out) (any "
                         f"rates, irregular stamps); only if fs_in was rounded from such a ratio, give it exactly "
                         f"(BROAD: 2000/7 Hz, not 285.714)")
    return fraction.numerator, fraction.denominator


def n_resampled(n_samples: int, fs_in, fs_out) -> int:
    """Number of output samples ``(T - 1)·up // down + 1`` (the output times inside the input span)."""
    up, down = resample_factors(fs_in, fs_out)
    _check_length(n_samples)
    return (int(n_samples) - 1) * up // down + 1


def resampled_times(n_samples: int, fs_in, fs_out) -> np.ndarray:
    """Output sample times ``k / fs_out`` (s), shape ``(T_out,)``, for ``n_samples`` input samples."""
    return np.arange(n_resampled(n_samples, fs_in, fs_out)) / float(fs_out)


def _check_length(n_samples) -> None:
    if not isinstance(n_samples, int | np.integer) or n_samples < 2:
        raise ValueError(f"need at least 2 input samples along time, got {n_samples!r}")


@functools.lru_cache(maxsize=16)
def _antialias_filter(up: int, down: int) -> np.ndarray:
    """scipy's resample_poly filter, with every polyphase branch scaled to DC gain 1/up."""
    from scipy import signal  # here, not at the top: scipy.signal takes 0.5 s to import, in every kernel

    half_len = 10 * max(up, down)
    taps = signal.firwin(2 * half_len + 1, 1.0 / max(up, down), window=("kaiser", _KAISER_BETA))
    for phase in range(up):
        taps[phase::up] /= up * taps[phase::up].sum()
    taps.setflags(write=False)
    return taps


def resample_signal(x, fs_in, fs_out, axis: int = -2) -> np.ndarray:
    """Low-pass filter and downsample a signal from ``fs_in`` to ``fs_out`` (see the module docstring).

    Parameters
    ----------
    x : array_like, shape (..., T, 3) (or any shape with time on ``axis``)
        Finite samples (e.g. ``gyr`` rad/s, ``acc`` m/s², ``mag`` µT); NaN is rejected.
    fs_in, fs_out : float
        Rates (Hz), ``fs_out <= fs_in``, ``fs_out / fs_in`` a ratio of small integers.
    axis : int
        Time axis; default the second to last.

    Returns
    -------
    numpy.ndarray
        Same shape except ``T_out = (T - 1)·up // down + 1`` on ``axis``; sample ``k`` is at
        ``k / fs_out``.  Same units as ``x``.
    """
    x = as_float_array(x, "x")
    axis = _normalize_axis(axis, x.ndim)
    up, down = resample_factors(fs_in, fs_out)
    _check_length(x.shape[axis])
    n_out = (x.shape[axis] - 1) * up // down + 1
    if up == down:
        return x.copy()
    from scipy import signal  # here, not at the top: scipy.signal takes 0.5 s to import, in every kernel

    y = signal.resample_poly(x, up, down, axis=axis, window=_antialias_filter(up, down), padtype="antireflect")
    return np.take(y, np.arange(n_out), axis=axis)


def _normalize_axis(axis, ndim: int) -> int:
    if not isinstance(axis, int | np.integer) or not -ndim <= axis < ndim:
        raise ValueError(f"axis {axis!r} is out of range for an array with {ndim} dimension(s)")
    return int(axis) % ndim


def resample_quaternion(quat, fs_in, fs_out) -> np.ndarray:
    """Orientations at the output times by SLERP between the neighbouring input samples.

    Parameters
    ----------
    quat : array_like, shape (..., T, 4)
        Unit quaternions ``[w, x, y, z]``; rows holding NaN mark missing samples (e.g. BROAD's
        reference where the markers were lost).
    fs_in, fs_out : float
        As in :func:`resample_signal`.

    Returns
    -------
    numpy.ndarray, shape (..., T_out, 4)
        ``SLERP(q_i, q_{i+1}, μ)`` with ``i = ⌊t_k·fs_in⌋``, ``μ = t_k·fs_in − i`` (computed in
        exact integer arithmetic), along the shorter arc (:func:`wsnlib.quaternion.slerp`);
        ``q_i`` itself (normalised) when ``t_k`` falls on an input sample, whatever its
        neighbour.  NaN where a needed neighbour is NaN.
    """
    quat = quat_ops.as_quat_with_gaps(quat, "quat")
    if quat.ndim < 2:
        raise ValueError(f"quat must have shape (..., T, 4), got {quat.shape}")
    up, down = resample_factors(fs_in, fs_out)
    n_in = quat.shape[-2]
    _check_length(n_in)
    k = np.arange((n_in - 1) * up // down + 1)
    left = k * down // up
    remainder = k * down % up
    right = np.minimum(left + 1, n_in - 1)
    ok = ~np.isnan(quat[..., 0])
    valid = ok[..., left] & (ok[..., right] | (remainder == 0))
    filled = np.where(ok[..., None], quat, quat_ops.identity())
    filled = filled / np.linalg.norm(filled, axis=-1, keepdims=True)
    q_left = filled[..., left, :]
    out = quat_ops.slerp(q_left, filled[..., right, :], remainder / up)
    out = np.where((remainder == 0)[:, None], q_left, out)
    return np.where(valid[..., None], out, np.nan)


def resample_mask(mask, fs_in, fs_out) -> np.ndarray:
    """Boolean mask ``(..., T)`` at the output times: the value of the nearest input sample.

    Input sample ``round(t_k·fs_in)`` (a time exactly halfway between two input samples takes
    the later one), so ``T_out`` matches :func:`resample_signal`.
    """
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.ndim < 1:
        raise ValueError(f"mask must be a boolean array of shape (..., T), got {mask.dtype} {mask.shape}")
    up, down = resample_factors(fs_in, fs_out)
    _check_length(mask.shape[-1])
    k = np.arange((mask.shape[-1] - 1) * up // down + 1)
    nearest = (2 * k * down + up) // (2 * up)
    return mask[..., nearest].copy()


def resample_broad(trial: BroadTrial, fs_out: float = 50.0) -> BroadTrial:
    """A :class:`~wsnlib.io.broad.BroadTrial` resampled to ``fs_out`` (all signals on one grid).

    ``gyr``, ``acc``, ``mag`` by :func:`resample_signal`, ``quat_ref`` by
    :func:`resample_quaternion` (NaN gaps stay NaN), ``movement`` by :func:`resample_mask`;
    ``time_s`` is ``k / fs_out`` and ``fs`` is ``fs_out``.  ``info`` gets a line saying so.
    """
    if not isinstance(trial, BroadTrial):
        raise ValueError(f"trial must be a BroadTrial (see wsnlib.io.broad.load_broad), got {type(trial).__name__}")
    fs_in = trial.fs
    fs_out = check_positive(fs_out, "fs_out")
    note = (f"[wsnlib] Resampled from {fs_in:.9g} Hz to {fs_out:g} Hz by wsnlib.io.resample "
            f"(IMU: anti-alias FIR + polyphase; opt_quat: SLERP, NaN kept; movement: nearest sample).")
    return dataclasses.replace(trial, fs=fs_out, time_s=resampled_times(trial.n_samples, fs_in, fs_out),
                               gyr=resample_signal(trial.gyr, fs_in, fs_out),
                               acc=resample_signal(trial.acc, fs_in, fs_out),
                               mag=resample_signal(trial.mag, fs_in, fs_out),
                               quat_ref=resample_quaternion(trial.quat_ref, fs_in, fs_out),
                               movement=resample_mask(trial.movement, fs_in, fs_out),
                               info=f"{trial.info}\n\n{note}" if trial.info else note)
