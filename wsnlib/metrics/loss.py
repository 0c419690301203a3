"""Error figures of merit under packet loss: maxima, time above a threshold, recovery, by phase.

* :func:`max_abs_error`, :func:`time_above_s`, :func:`recovery_time_s`: how large and how
  long an error is after a loss begins.
* Under loss: :func:`quantile_error` (a quantile instead of a maximum that shrinks as loss
  rises) and :func:`error_by_phase` (lost samples, the seconds after a gap, the rest).
* :func:`loss_figures_of_merit` (the columns used across notebooks), :func:`summary_table`
  (Monte Carlo median and range), :func:`burst_response` (burst by burst, against the same
  run without loss) and :func:`single_burst_response` (one burst per run, against the error just
  before it: paper 001's protocol).

Every function returns degrees or seconds, as its name says, and broadcasts over leading
batch dimensions ``(..., T)``.
"""

from __future__ import annotations

import functools

import numpy as np

from wsnlib._validation import as_bool_mask, as_float_array, check_nonnegative, check_positive
from wsnlib.metrics.smoothness import angle_jerk_rms_deg, gap_end_mask, gap_end_steps_deg


def max_abs_error(error, start: int = 0, where=None) -> np.ndarray:
    """Largest ``|error|`` over time (last axis) from sample ``start`` on, ``(..., T) → (...)``.

    Parameters
    ----------
    error : array_like, shape (..., T)
    start : int
        First sample considered.
    where : array_like of bool, shape (..., T), optional
        Only samples where this is True count (e.g. the ``received`` mask, to judge what an
        estimator produces when it has data).  A sequence with no counted sample gives 0.
    """
    error = as_float_array(error, "error")
    _check_start(start, error.shape[-1])
    magnitude = np.abs(error)
    if where is not None:
        magnitude = np.where(as_bool_mask(where, "where", magnitude.shape), magnitude, 0.0)
    return np.max(magnitude[..., start:], axis=-1)


def time_above_s(error, threshold, fs, start: int = 0) -> np.ndarray:
    """Total time (s) during which ``|error| > threshold`` from sample ``start`` on.

    Parameters
    ----------
    error : array_like, shape (..., T)
        Error trace, e.g. elbow angle error in degrees.
    threshold : float
        Same unit as ``error``.
    fs : float
        Sampling rate (Hz).
    start : int
        First sample counted (e.g. the sample at which a loss begins).
    """
    error = as_float_array(error, "error")
    threshold = check_nonnegative(threshold, "threshold")
    fs = check_positive(fs, "fs")
    _check_start(start, error.shape[-1])
    return np.count_nonzero(np.abs(error[..., start:]) > threshold, axis=-1) / fs


def recovery_time_s(error, threshold, fs, start: int) -> np.ndarray:
    """Time (s) from sample ``start`` until ``|error|`` falls below ``threshold`` for good.

    It is the time of the last sample above the threshold, plus one sample period, minus
    the time of ``start``; 0 when the error never exceeds the threshold from ``start`` on.
    If the error is still above the threshold at the last sample, the result is ``inf``
    (it did not recover within the record) — an explicit value, never NaN.

    Parameters
    ----------
    error : array_like, shape (..., T)
    threshold : float
    fs : float
        Sampling rate (Hz).
    start : int
        Reference sample, e.g. the first received sample after a burst of losses.
    """
    error = as_float_array(error, "error")
    threshold = check_nonnegative(threshold, "threshold")
    fs = check_positive(fs, "fs")
    n = error.shape[-1]
    _check_start(start, n)
    above = np.abs(error[..., start:]) > threshold
    any_above = above.any(axis=-1)
    # Index of the last sample above the threshold (counted from ``start``).
    last = (n - start - 1) - np.argmax(above[..., ::-1], axis=-1)
    seconds = np.where(any_above, (last + 1) / fs, 0.0)
    return np.where(above[..., -1], np.inf, seconds)


def quantile_error(error, q: float = 0.95, where=None) -> np.ndarray:
    """Quantile ``q`` of ``|error|`` over time (last axis), counting only samples in ``where``.

    A replacement for :func:`max_abs_error` over received samples: the maximum of fewer samples
    is smaller, so a maximum over the received samples shrinks as loss rises even when nothing
    improves, while a quantile estimates the same number at every loss rate (for losses that
    do not pick the worst samples).

    Parameters
    ----------
    error : array_like, shape (..., T)
    q : float
        Quantile in [0, 1] (0.95 = the 95th percentile; 1 = the maximum).
    where : array_like of bool, shape (..., T), optional
        Samples that count (e.g. ``received``); default all.

    Returns
    -------
    numpy.ndarray, shape (...)
        Linear-interpolation quantile (numpy's default), in the unit of ``error``.

    Raises
    ------
    ValueError
        If some record has no counted sample.
    """
    error = as_float_array(error, "error")
    if isinstance(q, bool) or not np.isscalar(q) or not 0.0 <= float(q) <= 1.0:
        raise ValueError(f"q must be a number in [0, 1], got {q!r}")
    magnitude = np.abs(error)
    if where is not None:
        where = as_bool_mask(where, "where", error.shape)
        count = np.count_nonzero(where, axis=-1)
        if np.any(count == 0):
            bad = tuple(int(i) for i in np.argwhere(count == 0)[0])
            raise ValueError(f"no sample counts (where is all False){f' at batch index {bad}' if bad else ''}")
        magnitude = np.where(where, magnitude, np.nan)
        return np.nanquantile(magnitude, float(q), axis=-1)
    return np.quantile(magnitude, float(q), axis=-1)


#: Phases of :func:`error_by_phase`, in order.
PHASES = ("lost", "after_gap", "steady")


def error_by_phase(error_deg, received, fs, *, after_s: float = 2.0, statistic: str = "rms") -> dict[str, np.ndarray]:
    """Mean or RMS of an error trace split by phase: lost samples, just after a gap, the rest.

    Phases (disjoint; together every sample):

    * ``"lost"``: samples not received (the estimator runs without data);
    * ``"after_gap"``: received samples within ``after_s`` seconds of a gap's end, i.e. from
      the first received sample ``e`` after a gap to ``e + round(after_s·fs) − 1`` (the return
      to the data);
    * ``"steady"``: the other received samples.

    Samples whose error is NaN (e.g. no reference) are skipped in every phase.

    Parameters
    ----------
    error_deg : array_like, shape (..., T)
        Error trace (°); NaN allowed (missing reference), inf not.
    received : array_like of bool, shape (..., T)
    fs : float
        Sampling rate (Hz).
    after_s : float
        Length of the after-gap phase (s), >= 0.
    statistic : {"rms", "mean"}
        RMS of the error, or mean of ``|error|``.

    Returns
    -------
    dict
        For each phase in :data:`PHASES` its value (°, shape (...)) and ``"n_<phase>"`` its
        number of samples (int, shape (...)).  A phase without a sample has value NaN and count
        0 — explicitly, so pool over records with the counts, e.g.
        ``sqrt(Σ n·v² / Σ n)`` for RMS.
    """
    error = np.asarray(error_deg, dtype=float)
    if error.ndim < 1:
        raise ValueError("error_deg must have a time axis")
    if np.any(np.isinf(error)):
        raise ValueError("error_deg contains inf")
    if statistic not in ("rms", "mean"):
        raise ValueError(f"statistic must be 'rms' or 'mean', got {statistic!r}")
    fs = check_positive(fs, "fs")
    window = int(round(check_nonnegative(after_s, "after_s") * fs))
    received = as_bool_mask(received, "received", error.shape)
    ends = gap_end_mask(received)
    # Samples since the latest gap end (large before the first one).
    n = error.shape[-1]
    index = np.arange(n)
    last_end = np.maximum.accumulate(np.where(ends, index, -n - window - 1), axis=-1)
    after = received & (index - last_end < window)
    phases = {"lost": ~received, "after_gap": after, "steady": received & ~after}
    valid = ~np.isnan(error)
    value = np.abs(error) if statistic == "mean" else error**2
    out: dict[str, np.ndarray] = {}
    for name, mask in phases.items():
        mask = mask & valid
        count = np.count_nonzero(mask, axis=-1)
        total = np.sum(np.where(mask, value, 0.0), axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        out[name] = np.sqrt(mean) if statistic == "rms" else mean
        out[f"n_{name}"] = count
    return out


def _check_start(start: int, n_samples: int) -> None:
    if not isinstance(start, int | np.integer) or not 0 <= start < n_samples:
        raise ValueError(f"start must be an integer sample index in [0, {n_samples}), got {start!r}")


#: Column names of :func:`loss_figures_of_merit`, with units.
MAX_ERROR = "max error after loss (°)"
MEAN_ERROR = "mean |error| (°)"
TIME_ABOVE = "time above threshold (s)"
RECOVERY = "recovery time (s)"
JERK = "RMS jerk (°/s³)"
GAP_STEP_MAX = "max step at gap end (°)"
GAP_STEP_MEAN = "mean step at gap end (°)"
JITTER = "RMS jitter, gap ends excluded (°/s³)"
P95_ERROR = "95th percentile |error|, received (°)"


def loss_figures_of_merit(error_deg, *, fs, received, threshold_deg=5.0, start: int = 0,
                          recovery_start: int | None = None, extended: bool = False) -> dict[str, np.ndarray]:
    """The figures of merit used across notebooks for an angle error trace under loss.

    Parameters
    ----------
    error_deg : array_like, shape (..., T)
        Error of an angle (e.g. elbow angle minus its true value), degrees.
    fs : float
        Sampling rate (Hz).
    received : array_like of bool, shape (..., T)
        Loss mask of the node(s) behind the estimate; the maximum error counts only received
        samples (what the estimator produces when it has data).
    threshold_deg : float
        Threshold for the time-above and recovery figures.
    start : int
        First sample considered (e.g. where the loss begins).
    recovery_start : int, optional
        Sample from which recovery is timed (e.g. the first received sample after a burst).
        Left out when None (it means nothing for scattered losses).
    extended : bool
        Also return the split of the jerk into the step at gap ends and the continuous jitter,
        and a quantile in place of the maximum (see below).

    Returns
    -------
    dict[str, numpy.ndarray]
        :data:`MAX_ERROR` (°, received samples from ``start``), :data:`MEAN_ERROR` (°, mean
        ``|error|`` over all samples from ``start``), :data:`TIME_ABOVE` (s, all samples
        from ``start``: during a gap the user still sees an estimate),
        :data:`RECOVERY` (s, only with ``recovery_start``; ``inf`` if never) and :data:`JERK`
        (°/s³, RMS third derivative of the error trace over the whole record), each of shape
        ``(...)``.  With ``extended``: :data:`GAP_STEP_MAX` and :data:`GAP_STEP_MEAN` (°, the
        step of the error at the gap ends of the whole record, :func:`gap_end_steps_deg`; 0
        without a closed gap), :data:`JITTER` (°/s³, :func:`angle_jerk_rms_deg` given ``received``) and
        :data:`P95_ERROR` (°, 95th percentile of ``|error|`` over received samples from
        ``start``, :func:`quantile_error`).
    """
    error_deg = as_float_array(error_deg, "error_deg")
    received = as_bool_mask(received, "received", error_deg.shape)
    result = {MAX_ERROR: max_abs_error(error_deg, start=start, where=received),
              MEAN_ERROR: np.mean(np.abs(error_deg[..., start:]), axis=-1),
              TIME_ABOVE: time_above_s(error_deg, threshold_deg, fs, start=start)}
    if recovery_start is not None:
        result[RECOVERY] = recovery_time_s(error_deg, threshold_deg, fs, start=recovery_start)
    result[JERK] = angle_jerk_rms_deg(error_deg, fs)
    if extended:
        steps = gap_end_steps_deg(error_deg, received)
        result[GAP_STEP_MAX] = steps["max_deg"]
        result[GAP_STEP_MEAN] = steps["mean_deg"]
        result[JITTER] = angle_jerk_rms_deg(error_deg, fs, received)
        result[P95_ERROR] = quantile_error(error_deg[..., start:], 0.95, where=received[..., start:])
    return result


def summary_table(results: dict[str, dict[str, np.ndarray]], quantiles=(0.1, 0.9)):
    """Median and quantile range of Monte Carlo figures of merit, one row per estimator.

    Parameters
    ----------
    results : dict[str, dict[str, array_like]]
        Estimator name → figure name → values over realisations (any shape, flattened).
    quantiles : (float, float)
        Lower and upper quantile of the range columns.

    Returns
    -------
    pandas.DataFrame
        Columns ``(figure, "median")``, ``(figure, "q10")``, ``(figure, "q90")`` (named after
        the quantiles), index = estimator names, in the order given.
    """
    import pandas as pd

    statistics = {"median": np.median, **{f"q{round(100 * q)}": functools.partial(np.quantile, q=q) for q in quantiles}}
    rows = {name: {(figure, statistic): float(function(np.ravel(np.asarray(values, dtype=float))))
                   for figure, values in figures.items() for statistic, function in statistics.items()}
            for name, figures in results.items()}
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.columns = pd.MultiIndex.from_tuples(table.columns, names=["figure", "statistic"])
    return table


def burst_response(error_lossy_deg, error_lossless_deg, burst_ends, fs, *, window_s: float = 2.0,
                   threshold_deg: float = 1.0, min_valid_fraction: float = 0.5) -> dict[str, np.ndarray]:
    """How much a loss burst adds to the error, burst by burst, against the same run without loss.

    For each burst, the *increase* ``e_lossy − e_lossless`` is examined over the ``window_s``
    seconds that follow the burst's end (the first received sample after it):

    * ``mean_increase_deg``: mean increase over the window;
    * ``peak_increase_deg``: largest increase in the window;
    * ``recovery_s``: time until the increase falls below ``threshold_deg`` for the rest of
      the window (0 if it never exceeds it; ``inf`` if it is still above at the window's last
      valid sample).

    Error traces may hold NaN where the reference is missing (e.g. optical markers lost); those
    samples are skipped.  A burst whose window has fewer than ``min_valid_fraction`` valid
    samples, or whose window runs past the record's end, is dropped and counted in ``dropped``,
    so every returned value is a number.

    Parameters
    ----------
    error_lossy_deg, error_lossless_deg : array_like, shape (..., T)
        Error magnitudes (°) with and without loss; broadcast together.
    burst_ends : array_like of int, shape (B,)
        Index of the first received sample after each burst.
    fs : float
        Sampling rate (Hz).
    window_s, threshold_deg, min_valid_fraction : float

    Returns
    -------
    dict
        ``mean_increase_deg``, ``peak_increase_deg``, ``recovery_s``: arrays ``(..., B_kept)``;
        ``kept``: indices of the kept bursts; ``dropped``: how many were dropped.
    """
    lossy = np.asarray(error_lossy_deg, dtype=float)
    lossless = np.asarray(error_lossless_deg, dtype=float)
    increase = lossy - lossless
    fs = check_positive(fs, "fs")
    window = int(round(check_positive(window_s, "window_s") * fs))
    threshold_deg = check_nonnegative(threshold_deg, "threshold_deg")
    ends = np.asarray(burst_ends)
    if ends.ndim != 1 or not np.issubdtype(ends.dtype, np.integer):
        raise ValueError("burst_ends must be a 1-D array of sample indices")
    n = increase.shape[-1]
    in_range = (ends >= 0) & (ends + window <= n)
    segments = np.stack([increase[..., e:e + window] for e in ends[in_range]], axis=-2) if in_range.any() \
        else np.empty(increase.shape[:-1] + (0, window))
    valid = np.isfinite(segments)
    enough = valid.mean(axis=-1) >= min_valid_fraction                       # (..., B)
    keep = np.all(enough, axis=tuple(range(enough.ndim - 1))) if enough.ndim > 1 else enough
    kept = np.flatnonzero(in_range)[keep]
    segments, valid = segments[..., keep, :], valid[..., keep, :]
    filled = np.where(valid, segments, 0.0)
    count = valid.sum(axis=-1)
    mean_increase = filled.sum(axis=-1) / np.maximum(count, 1)
    peak_increase = np.where(valid, segments, -np.inf).max(axis=-1, initial=-np.inf)
    above = valid & (segments > threshold_deg)
    last = (window - 1) - np.argmax(above[..., ::-1], axis=-1)
    recovery = np.where(above.any(axis=-1), (last + 1) / fs, 0.0)
    last_valid = (window - 1) - np.argmax(valid[..., ::-1], axis=-1)
    still_above = np.take_along_axis(above, last_valid[..., None], axis=-1)[..., 0]
    recovery = np.where(still_above, np.inf, recovery)
    return {"mean_increase_deg": mean_increase, "peak_increase_deg": peak_increase, "recovery_s": recovery,
            "kept": kept, "dropped": int(ends.size - kept.size)}


def single_burst_response(error_deg, received, fs, *, before_s: float = 0.5, window_s: float = 4.0,
                          threshold_deg: float = 2.0, level_deg: float = 10.0,
                          min_valid_fraction: float = 0.5) -> dict[str, np.ndarray]:
    """How one burst of loss changes the error, against the error just before it (one burst per run).

    Paper 001's protocol: a run loses a single burst (Section IV: four packets after 80 samples),
    so nothing before it carries an earlier burst's error.  Each run (a row of ``error_deg``)
    holds exactly one run of lost samples, from its first lost sample ``s`` to its first received
    sample after it ``e``:

    * ``before_deg``: mean error over the ``before_s`` seconds before ``s`` — where the method was;
    * ``peak_increase_deg``: largest error from ``s`` to the end of the window, minus ``before_deg``;
    * ``mean_increase_deg``: mean error over the ``window_s`` seconds from ``e``, minus ``before_deg``;
    * ``recovery_s``: time from ``e`` until the error stays within ``threshold_deg`` of
      ``before_deg`` for the rest of the window (0 if it never leaves it after ``e``; ``inf`` if it
      is still out at the window's last valid sample).  A method with a low error before the
      burst must come back closer, in degrees, than one with a high error: hence also
    * ``level_recovery_s``: the same against an absolute level, the time until the error stays at
      or below ``level_deg`` (``inf`` also when it was above that level before the burst and stays so).

    Samples where the error is NaN (no reference) are skipped; a run whose before- or
    after-window holds fewer than ``min_valid_fraction`` valid samples gets NaN everywhere.

    Parameters
    ----------
    error_deg : array_like, shape (..., T)
        Error magnitude (°) of each run.
    received : array_like of bool, shape (..., T)
        Each run's mask (broadcast with ``error_deg``), with exactly one run of lost samples that
        ends before the record does, and at least one sample before it.
    fs : float
        Sampling rate (Hz).
    before_s, window_s : float
        The window before the burst and the one after it (s), > 0.
    threshold_deg, level_deg : float
        Relative and absolute recovery thresholds (°), >= 0.
    min_valid_fraction : float

    Returns
    -------
    dict of numpy.ndarray, shape (...)
        ``before_deg``, ``peak_increase_deg``, ``mean_increase_deg``, ``recovery_s``,
        ``level_recovery_s``; and ``start``, ``end`` (int, the indices ``s`` and ``e``).
    """
    error = np.asarray(error_deg, dtype=float)
    mask = np.asarray(received)
    if mask.dtype != np.bool_:
        raise ValueError(f"received must be a boolean mask, got dtype {mask.dtype}")
    if error.ndim == 0 or not np.all(np.isfinite(error) | np.isnan(error)):
        raise ValueError("error_deg must be an array (..., T) of finite errors or NaN")
    error, mask = np.broadcast_arrays(error, mask)
    fs = check_positive(fs, "fs")
    before = int(round(check_positive(before_s, "before_s") * fs))
    window = int(round(check_positive(window_s, "window_s") * fs))
    threshold_deg = check_nonnegative(threshold_deg, "threshold_deg")
    level_deg = check_nonnegative(level_deg, "level_deg")
    shape = error.shape[:-1]
    n = error.shape[-1]
    flat_error, flat_mask = error.reshape(-1, n), mask.reshape(-1, n)
    out = {key: np.full(flat_error.shape[0], np.nan) for key in
           ("before_deg", "peak_increase_deg", "mean_increase_deg", "recovery_s", "level_recovery_s")}
    starts, ends = np.zeros(flat_error.shape[0], dtype=int), np.zeros(flat_error.shape[0], dtype=int)
    for k, (e, m) in enumerate(zip(flat_error, flat_mask, strict=True)):
        lost = np.flatnonzero(~m)
        if lost.size == 0 or lost[-1] - lost[0] + 1 != lost.size:
            raise ValueError(f"received must hold exactly one run of lost samples per run; run {k} has "
                             f"{'none' if lost.size == 0 else 'several'}")
        start, end = int(lost[0]), int(lost[-1]) + 1
        if start == 0 or end >= n:
            raise ValueError(f"run {k}: the burst must leave a sample before it and one after it")
        starts[k], ends[k] = start, end
        ahead, after = e[max(start - before, 0):start], e[end:min(end + window, n)]
        if (np.isfinite(ahead).sum() < min_valid_fraction * before
                or np.isfinite(after).sum() < min_valid_fraction * window):
            continue
        base = float(np.nanmean(ahead))
        out["before_deg"][k] = base
        out["peak_increase_deg"][k] = float(np.nanmax(e[start:min(end + window, n)])) - base
        out["mean_increase_deg"][k] = float(np.nanmean(after)) - base
        out["recovery_s"][k] = _time_until_within(after, base + threshold_deg, fs)
        out["level_recovery_s"][k] = _time_until_within(after, level_deg, fs)
    result = {key: value.reshape(shape) for key, value in out.items()}
    result.update(start=starts.reshape(shape), end=ends.reshape(shape))
    return result


def _time_until_within(after: np.ndarray, limit: float, fs: float) -> float:
    """Time (s) from the first sample of ``after`` until its valid samples stay ``<= limit``: 0 if they
    always do, ``inf`` if the last valid one does not."""
    valid = np.flatnonzero(np.isfinite(after))
    above = valid[after[valid] > limit]
    if above.size == 0:
        return 0.0
    if above[-1] == valid[-1]:
        return float("inf")
    return (int(above[-1]) + 1) / fs
