"""Bootstrap confidence intervals over units (trials, users, realisations) and rankings with ties.

Every table that ranks methods is computed from a handful of units — 17 BROAD trials, five
users, a few hundred Monte Carlo realisations — so a "winner" may be one by chance.  This
module gives

* :func:`bootstrap_ci`: a confidence interval for the mean (or median) over axis 0, the units;
* :func:`paired_difference_ci`: the same for the difference of two methods scored on the
  *same* units (paired: the unit-to-unit spread cancels, so the interval is narrower than
  what two separate intervals suggest);
* :func:`grouped_bootstrap_ci` and :func:`grouped_ratio_ci`: intervals over *groups of units
  and repeated draws* (e.g. near-duplicate trials grouped by their kind of motion, each scored
  under several random loss masks), by a two-stage bootstrap;
* :func:`rank_intervals` and :func:`rank_with_ties`: a ranking table in which methods that
  cannot be told apart share a tie group, and :func:`describe_ranking`, a sentence generated
  from such a table (so that a notebook's claim follows from its numbers).

Method
------
The bootstrap resamples the units with replacement (``n_boot`` resamples, every index drawn
from the ``rng`` passed in).  Two intervals are offered:

* ``"percentile"``: the ``(1 − level)/2`` and ``(1 + level)/2`` quantiles of the resampled
  statistic (Efron & Tibshirani, *An Introduction to the Bootstrap*, 1993, Sec. 13.3);
* ``"bca"`` (default): bias-corrected and accelerated (Efron 1987; Efron & Tibshirani 1993,
  Sec. 14.3), whose quantile levels are shifted by the bias correction
  ``z0 = Φ⁻¹(fraction of resamples below the estimate)`` and the acceleration ``a`` from the
  jackknife, ``a = Σ (θ̄ − θ_(i))³ / (6 [Σ (θ̄ − θ_(i))²]^{3/2})``.  It is second-order
  accurate and copes with skewed statistics (errors are positive and skewed).

Groups and draws
----------------
When units come in groups that are not independent (BROAD's near-duplicate trials of one kind
of motion) and each unit is scored several times (loss draws), :func:`grouped_bootstrap_ci`
resamples in two stages (Davison & Hinkley, *Bootstrap Methods and their Application*, 1997,
Sec. 3.8): the groups with replacement, then, for every unit of every group drawn, its draws
with replacement; the statistic is the mean over the drawn units of the mean over their drawn
draws.  Percentile intervals.  A group drawn twice gets two independent draw-resamples, so its
draws' counts are one multinomial of ``times drawn × n_draws`` — which is how it is computed,
without a loop over resamples.

With very few units (five users) no bootstrap interval reaches its nominal coverage — the
resampled mean's spread is ``(n − 1)/n`` of the sample's and the shape is that of the few
values present — so such intervals are too narrow, not too wide: a tie they report is real,
a separation may not be.

Ties
----
:func:`rank_intervals` sorts by the estimate; the best method leads tie group 1, and every
following method whose interval overlaps the leader's joins it; the first method that does not
overlap leads group 2, and so on.  Overlap of two 95 % intervals is a conservative test (two
intervals can overlap while the difference is significant); with paired units,
:func:`rank_with_ties` (``paired=True``) uses the interval of the paired difference to the
group leader instead, which is the sharper and correct test.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Mapping

import numpy as np
from scipy.special import ndtr, ndtri

from wsnlib._validation import as_float_array, check_count, check_rng

#: Accepted interval methods.
CI_METHODS = ("bca", "percentile")

#: Accepted statistics.
STATISTICS = ("mean", "median")


@dataclasses.dataclass(frozen=True)
class BootstrapInterval:
    """A bootstrap confidence interval of a statistic over units (axis 0).

    Attributes
    ----------
    estimate : numpy.ndarray, shape (...)
        The statistic of the units themselves (mean or median over axis 0).
    low, high : numpy.ndarray, shape (...)
        Interval bounds, same unit as the values.
    level : float
        Confidence level (e.g. 0.95).
    method : {"bca", "percentile"}
    statistic : {"mean", "median"}
    n_units : int
        Number of units resampled.
    n_boot : int
        Number of resamples.
    """

    estimate: np.ndarray
    low: np.ndarray
    high: np.ndarray
    level: float
    method: str
    statistic: str
    n_units: int
    n_boot: int

    def contains(self, value) -> np.ndarray:
        """Whether ``low <= value <= high`` (broadcast), shape (...)."""
        return (self.low <= value) & (value <= self.high)


def _check_options(level, n_boot, method, statistic) -> tuple[float, int]:
    if isinstance(level, bool) or not isinstance(level, numbers.Real) or not 0.0 < float(level) < 1.0:
        raise ValueError(f"level must be a number in (0, 1), got {level!r}")
    check_count(n_boot, "n_boot", 100)
    if method not in CI_METHODS:
        raise ValueError(f"method must be one of {CI_METHODS}, got {method!r}")
    if statistic not in STATISTICS:
        raise ValueError(f"statistic must be one of {STATISTICS}, got {statistic!r}")
    return float(level), int(n_boot)


def _units(values, name: str) -> np.ndarray:
    arr = as_float_array(values, name)
    if arr.shape[0] < 2:
        raise ValueError(f"{name} needs at least 2 units along axis 0 to resample, got shape {arr.shape}")
    return arr


def _resampled(values: np.ndarray, statistic: str, rng: np.random.Generator, n_boot: int) -> np.ndarray:
    """The statistic of ``n_boot`` resamples of the units: ``(n_boot, ...)``."""
    n = values.shape[0]
    index = rng.integers(0, n, size=(n_boot, n))
    flat = values.reshape(n, -1)
    if statistic == "mean":
        counts = np.zeros((n_boot, n))
        np.add.at(counts, (np.repeat(np.arange(n_boot), n), index.ravel()), 1.0)
        out = counts[:, 0, None] * flat[0]  # units added in order (a matrix product's order is the BLAS kernel's)
        for i in range(1, n):
            out += counts[:, i, None] * flat[i]
        out /= n
    else:
        out = np.median(flat[index], axis=1)
    return out.reshape((n_boot,) + values.shape[1:])


def _jackknife(values: np.ndarray, statistic: str) -> np.ndarray:
    """Leave-one-unit-out statistics ``(n, ...)``."""
    n = values.shape[0]
    if statistic == "mean":
        return (values.sum(axis=0, keepdims=True) - values) / (n - 1)
    keep = ~np.eye(n, dtype=bool)
    return np.stack([np.median(values[keep[i]], axis=0) for i in range(n)])


def _interval(values, boot, estimate, level, method, statistic):
    alpha = np.array([(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    n_boot = boot.shape[0]
    if method == "percentile":
        probs = np.broadcast_to(alpha.reshape((2,) + (1,) * estimate.ndim), (2,) + estimate.shape)
    else:
        below = np.mean(boot < estimate, axis=0) + 0.5 * np.mean(boot == estimate, axis=0)
        below = np.clip(below, 0.5 / n_boot, 1.0 - 0.5 / n_boot)
        z0 = ndtri(below)
        jack = _jackknife(values, statistic)
        dev = jack.mean(axis=0) - jack
        num = np.sum(dev**3, axis=0)
        den = 6.0 * np.sum(dev**2, axis=0) ** 1.5
        accel = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
        z_alpha = ndtri(alpha).reshape((2,) + (1,) * estimate.ndim)
        shifted = z0 + z_alpha
        probs = ndtr(z0 + shifted / (1.0 - accel * shifted))
    # Quantile of each element's resamples at its own probability.
    order = np.sort(boot, axis=0)
    position = probs * (n_boot - 1)
    lower = np.clip(np.floor(position).astype(int), 0, n_boot - 1)
    upper = np.minimum(lower + 1, n_boot - 1)
    frac = position - lower
    lo_hi = (np.take_along_axis(order, lower, axis=0) * (1.0 - frac)
             + np.take_along_axis(order, upper, axis=0) * frac)  # fmt: skip
    # A constant sample (zero spread) gives the estimate itself.
    return np.minimum(lo_hi[0], estimate), np.maximum(lo_hi[1], estimate)


def bootstrap_ci(values, *, rng: np.random.Generator, level: float = 0.95, n_boot: int = 2000,
                 method: str = "bca", statistic: str = "mean") -> BootstrapInterval:
    """Bootstrap confidence interval of the mean (or median) over the units on axis 0.

    Parameters
    ----------
    values : array_like, shape (n_units, ...)
        One value per unit (trial, user, Monte Carlo realisation) along axis 0; trailing axes
        are independent quantities (e.g. methods), resampled with the *same* units (paired).
        Finite, at least 2 units.
    rng : numpy.random.Generator
        Draws the resampled unit indices.
    level : float
        Confidence level in (0, 1).
    n_boot : int
        Number of resamples (>= 100; 2000 is plenty for 95 % intervals).
    method : {"bca", "percentile"}
        Interval construction (module docstring).
    statistic : {"mean", "median"}

    Returns
    -------
    BootstrapInterval
        ``estimate``, ``low``, ``high`` of shape ``values.shape[1:]``, same unit as ``values``.
    """
    rng = check_rng(rng)
    level, n_boot = _check_options(level, n_boot, method, statistic)
    values = _units(values, "values")
    estimate = np.mean(values, axis=0) if statistic == "mean" else np.median(values, axis=0)
    boot = _resampled(values, statistic, rng, n_boot)
    low, high = _interval(values, boot, estimate, level, method, statistic)
    return BootstrapInterval(estimate=estimate, low=low, high=high, level=level, method=method,
                             statistic=statistic, n_units=values.shape[0], n_boot=n_boot)


def paired_difference_ci(a, b, *, rng: np.random.Generator, level: float = 0.95, n_boot: int = 2000,
                         method: str = "bca", statistic: str = "mean") -> BootstrapInterval:
    """Bootstrap interval of the mean (or median) of the paired differences ``a − b`` over units.

    Parameters
    ----------
    a, b : array_like, shape (n_units, ...)
        The same units scored by two methods (row ``i`` of both is unit ``i``).
    rng, level, n_boot, method, statistic
        As in :func:`bootstrap_ci`.

    Returns
    -------
    BootstrapInterval
        Of ``a − b``; an interval that excludes 0 separates the two methods at ``level``.
    """
    a = _units(a, "a")
    b = _units(b, "b")
    if a.shape != b.shape:
        raise ValueError(f"a and b must have the same shape (paired units), got {a.shape} and {b.shape}")
    return bootstrap_ci(a - b, rng=rng, level=level, n_boot=n_boot, method=method, statistic=statistic)


#: Columns of :func:`rank_intervals` (and :func:`rank_with_ties`, which adds the paired ones).
RANK_COLUMNS = ("estimate", "ci_low", "ci_high", "rank", "tie_group", "tied")


def rank_intervals(table, *, lower_is_better: bool = True):
    """Ranking with tie groups from estimates and intervals (module docstring, "Ties").

    Parameters
    ----------
    table : pandas.DataFrame
        Index = method names; columns ``estimate``, ``ci_low``, ``ci_high`` (finite,
        ``ci_low <= estimate <= ci_high``).
    lower_is_better : bool
        True for errors, False for scores.

    Returns
    -------
    pandas.DataFrame
        Rows sorted best first, with the input columns and ``rank`` (1 = best estimate),
        ``tie_group`` (1 = tied with the best …) and ``tied`` (the group has other members).
    """
    import pandas as pd

    if not isinstance(table, pd.DataFrame):
        raise ValueError(f"table must be a pandas DataFrame, got {type(table).__name__}")
    missing = {"estimate", "ci_low", "ci_high"} - set(table.columns)
    if missing:
        raise ValueError(f"table lacks the columns {sorted(missing)}")
    if table.empty:
        raise ValueError("table holds no method")
    numbers_ = as_float_array(table[["estimate", "ci_low", "ci_high"]].to_numpy(), "table")
    if np.any(numbers_[:, 1] > numbers_[:, 0]) or np.any(numbers_[:, 0] > numbers_[:, 2]):
        raise ValueError("every row needs ci_low <= estimate <= ci_high")
    sign = 1.0 if lower_is_better else -1.0
    out = table.iloc[np.argsort(sign * numbers_[:, 0], kind="stable")].copy()
    out["rank"] = np.arange(1, len(out) + 1)
    groups, group, leader = [], 0, None
    for _, row in out.iterrows():
        if leader is None or not (row["ci_low"] <= leader["ci_high"] and leader["ci_low"] <= row["ci_high"]):
            group += 1
            leader = row
        groups.append(group)
    out["tie_group"] = groups
    out["tied"] = out.groupby("tie_group")["tie_group"].transform("size").to_numpy() > 1
    out.attrs.update(table.attrs)
    return out


def _as_samples(samples) -> tuple[list[str], list[np.ndarray]]:
    import pandas as pd

    if isinstance(samples, pd.DataFrame):
        names = [str(c) for c in samples.columns]
        arrays = [samples[c].to_numpy(dtype=float) for c in samples.columns]
    elif isinstance(samples, Mapping):
        names = [str(k) for k in samples]
        arrays = [np.asarray(v, dtype=float) for v in samples.values()]
    else:
        raise ValueError(f"samples must be a mapping method → values or a DataFrame (columns = methods), "
                         f"got {type(samples).__name__}")
    if len(names) < 2:
        raise ValueError(f"ranking needs at least 2 methods, got {names}")
    if len(set(names)) != len(names):
        raise ValueError(f"method names must be distinct, got {names}")
    for name, arr in zip(names, arrays, strict=True):
        if arr.ndim != 1:
            raise ValueError(f"values of method {name!r} must be 1-D (one per unit), got shape {arr.shape}")
        _units(arr, f"values of method {name!r}")
    return names, arrays


def rank_with_ties(samples, *, rng: np.random.Generator, level: float = 0.95, n_boot: int = 2000, method: str = "bca",
                   statistic: str = "mean", paired: bool = True, lower_is_better: bool = True, groups=None):
    """Rank methods by their per-unit values with bootstrap intervals; overlapping → tie.

    Parameters
    ----------
    samples : mapping method → array_like (n_units,), or pandas.DataFrame
        Per-unit values of each method (e.g. RMSE per trial), DataFrame columns = methods,
        rows = units.  With ``paired=True`` every method must have the same units in the
        same order.
    rng : numpy.random.Generator
    level, n_boot, method, statistic
        As in :func:`bootstrap_ci`.
    paired : bool
        True: a method ties with its group's leader when the interval of the paired difference
        (method − leader) contains 0 (the sharper test, for methods scored on the same units).
        False: when the two methods' own intervals overlap (:func:`rank_intervals`).
    lower_is_better : bool
    groups : array_like, shape (n_units,), optional
        Each unit's group: every method's sample is then ``(n_units, n_draws)`` and every
        interval is :func:`grouped_bootstrap_ci`'s (groups, then draws; percentile, mean; needs
        ``paired``); ``n_units`` is the number of groups.

    Returns
    -------
    pandas.DataFrame
        Index = method, best first; columns :data:`RANK_COLUMNS` (``estimate`` is the mean or
        median over units, ``ci_low``/``ci_high`` its interval), ``n_units``, and with
        ``paired=True`` also ``diff_to_leader`` with ``diff_low``/``diff_high`` (the paired
        difference to the tie group's leader; 0 for the leader itself).
    """
    import pandas as pd

    rng = check_rng(rng)
    _check_options(level, n_boot, method, statistic)
    if groups is not None:
        return _rank_grouped(samples, groups, rng=rng, level=level, n_boot=n_boot, paired=paired,
                             lower_is_better=lower_is_better)
    names, arrays = _as_samples(samples)
    sizes = {arr.size for arr in arrays}
    if paired and len(sizes) != 1:
        raise ValueError(f"paired=True needs the same number of units for every method, got sizes "
                         f"{dict(zip(names, [a.size for a in arrays], strict=True))}")
    rows = {}
    for name, arr in zip(names, arrays, strict=True):
        ci = bootstrap_ci(arr, rng=rng, level=level, n_boot=n_boot, method=method, statistic=statistic)
        rows[name] = {"estimate": float(ci.estimate), "ci_low": float(ci.low), "ci_high": float(ci.high),
                      "n_units": arr.size}
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "method"
    table.attrs["level"] = float(level)
    if not paired:
        return rank_intervals(table, lower_is_better=lower_is_better)
    sign = 1.0 if lower_is_better else -1.0
    order = [names[i] for i in np.argsort(sign * table.loc[names, "estimate"].to_numpy(), kind="stable")]
    by_name = dict(zip(names, arrays, strict=True))
    out = table.loc[order].copy()
    _tie_with_leaders(out, order, lambda name, leader: paired_difference_ci(
        by_name[name], by_name[leader], rng=rng, level=level, n_boot=n_boot, method=method, statistic=statistic))
    out.attrs.update(table.attrs)
    return out


def _tie_with_leaders(out, order, difference) -> None:
    """Fill ``out``'s rank, tie_group, tied, diff_to_leader, diff_low, diff_high: walking ``order`` (best
    first), a method ties with its group's leader when ``difference(method, leader)``'s interval holds 0."""
    groups, diffs, lows, highs = [], [], [], []
    group, leader = 0, None
    for name in order:
        if leader is not None:
            diff = difference(name, leader)
            d, lo, hi = float(diff.estimate), float(diff.low), float(diff.high)
        if leader is None or not lo <= 0.0 <= hi:
            group += 1
            leader = name
            d = lo = hi = 0.0
        groups.append(group)
        diffs.append(d)
        lows.append(lo)
        highs.append(hi)
    out["rank"] = np.arange(1, len(out) + 1)
    out["tie_group"] = groups
    out["tied"] = out.groupby("tie_group")["tie_group"].transform("size").to_numpy() > 1
    out["diff_to_leader"] = diffs
    out["diff_low"] = lows
    out["diff_high"] = highs


def _rank_grouped(samples, groups, *, rng, level, n_boot, paired, lower_is_better):
    """:func:`rank_with_ties` with ``groups``: samples ``method → (n_units, n_draws)``."""
    import pandas as pd

    if not paired:
        raise ValueError("groups need paired=True (every method scored on the same units and draws)")
    if not isinstance(samples, Mapping):
        raise ValueError(f"with groups, samples must map each method to an (n_units, n_draws) array, got "
                         f"{type(samples).__name__}")
    arrays = {str(name): as_float_array(values, f"samples[{name!r}]") for name, values in samples.items()}
    shapes = {arr.shape for arr in arrays.values()}
    if len(arrays) < 1 or len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(f"with groups, every method needs the same (n_units, n_draws) shape, got {shapes}")
    cis = {name: grouped_bootstrap_ci(arr, groups, rng=rng, level=level, n_boot=n_boot)
           for name, arr in arrays.items()}
    table = pd.DataFrame({name: {"estimate": float(ci.estimate), "ci_low": float(ci.low), "ci_high": float(ci.high),
                                 "n_units": ci.n_units} for name, ci in cis.items()}).T
    table["n_units"] = table["n_units"].astype(int)
    table.index.name = "method"
    sign = 1.0 if lower_is_better else -1.0
    order = list(table.index[np.argsort(sign * table["estimate"].to_numpy(), kind="stable")])
    out = table.loc[order].copy()
    _tie_with_leaders(out, order, lambda name, leader: grouped_bootstrap_ci(
        arrays[name] - arrays[leader], groups, rng=rng, level=level, n_boot=n_boot))
    out.attrs.update(level=float(level), units="groups (resampled with their loss draws)")
    return out


def describe_ranking(ranking, *, what: str = "error", unit: str = "", decimals: int = 1) -> str:
    """One sentence on the best method(s) of a :func:`rank_with_ties` / :func:`rank_intervals` table.

    E.g. ``"hybrid and hold-last tie for the lowest error (3.1 [2.5, 3.8] and 3.3 [2.6, 4.0] °;
    95 % intervals over 17 units)"`` or ``"hybrid has the lowest error …, ahead of …"``.  For a
    notebook's Markdown/print output, so the claim is generated from the numbers.

    Parameters
    ----------
    ranking : pandas.DataFrame
        Output of :func:`rank_with_ties` or :func:`rank_intervals` (best first).
    what : str
        The quantity, e.g. ``"RMSE"``.
    unit : str
        Appended to the numbers, e.g. ``"°"``.
    decimals : int
    """
    if "tie_group" not in getattr(ranking, "columns", ()):
        raise ValueError("ranking must be a table from rank_with_ties() or rank_intervals()")

    def fmt(name):
        row = ranking.loc[name]
        text = f"{row['estimate']:.{decimals}f} [{row['ci_low']:.{decimals}f}, {row['ci_high']:.{decimals}f}]"
        return f"{name} {text}{(' ' + unit) if unit else ''}"

    first = ranking[ranking["tie_group"] == ranking["tie_group"].iloc[0]]
    unit_name = ranking.attrs.get("units", "units")
    units = f" over {int(ranking['n_units'].iloc[0])} {unit_name}" if "n_units" in ranking.columns else ""
    level = ranking.attrs.get("level")
    scope = f"({round(100 * level)} % intervals{units})" if level is not None else f"(intervals{units})"
    if len(first) > 1:
        names = list(first.index)
        listed = ", ".join(names[:-1]) + f" and {names[-1]}"
        return f"{listed} cannot be told apart on {what} — a tie: " + "; ".join(fmt(n) for n in names) + f" {scope}."
    best = first.index[0]
    if len(ranking) == 1:
        return f"{fmt(best)} {scope}."
    runner = ranking.index[1]
    return f"{best} has the best {what}, separated from the runner-up: {fmt(best)} vs {fmt(runner)} {scope}."


def ratio_of_means_ci(a, b, *, rng: np.random.Generator, level: float = 0.95, n_boot: int = 2000) -> BootstrapInterval:
    """Percentile bootstrap interval of ``mean(a) / mean(b)`` over paired units.

    The units (rows of ``a`` and ``b`` together) are resampled; each resample's ratio of means
    gives the percentile interval (Efron & Tibshirani 1993, Sec. 13.3).  E.g. "our RMSE is
    0.4× the peer's", trials as units.

    Parameters
    ----------
    a, b : array_like, shape (n_units,)
        The same units scored by two methods; ``b`` > 0 (a ratio to a mean of 0 is undefined).
    rng, level, n_boot
        As in :func:`bootstrap_ci`.

    Returns
    -------
    BootstrapInterval
        Of the ratio (unitless), ``method="percentile"``.
    """
    rng = check_rng(rng)
    level, n_boot = _check_options(level, n_boot, "percentile", "mean")
    a, b = _units(a, "a"), _units(b, "b")
    if a.ndim != 1 or a.shape != b.shape:
        raise ValueError(f"a and b must be 1-D with the same shape (paired units), got {a.shape} and {b.shape}")
    if np.any(b <= 0):
        raise ValueError("b must be > 0 on every unit (the ratio's denominator)")
    boot = _resampled(np.stack([a, b], axis=1), "mean", rng, n_boot)
    ratios = boot[:, 0] / boot[:, 1]
    return _percentile_interval(ratios, np.asarray(a.mean() / b.mean()), level, a.shape[0], n_boot)


def _percentile_interval(boot: np.ndarray, estimate: np.ndarray, level: float, n_units: int,
                         n_boot: int) -> BootstrapInterval:
    """The percentile interval of the resampled means ``boot`` ``(n_boot, ...)``, widened to hold ``estimate``."""
    low, high = np.quantile(boot, [(1.0 - level) / 2.0, (1.0 + level) / 2.0], axis=0)
    return BootstrapInterval(estimate=estimate, low=np.minimum(low, estimate), high=np.maximum(high, estimate),
                             level=level, method="percentile", statistic="mean", n_units=n_units, n_boot=n_boot)


def _grouped_means(values: np.ndarray, labels: np.ndarray, rng: np.random.Generator, n_boot: int) -> np.ndarray:
    """Two-stage resampled means (module docstring) of ``values`` ``(n_units, n_draws, k)``: ``(n_boot, k)``."""
    n_units, n_draws = values.shape[:2]
    distinct, member = np.unique(labels, return_inverse=True)
    group_counts = rng.multinomial(len(distinct), np.full(len(distinct), 1.0 / len(distinct)), size=n_boot)
    draw_counts = rng.multinomial(group_counts[:, member] * n_draws, np.full(n_draws, 1.0 / n_draws))
    weights = draw_counts.reshape(n_boot, n_units * n_draws).astype(float)
    flat = values.reshape(n_units * n_draws, -1)
    return (weights @ flat) / weights.sum(axis=1, keepdims=True)


def _grouped_values(values, groups, name: str) -> tuple[np.ndarray, np.ndarray]:
    arr = as_float_array(values, name)
    if arr.ndim < 2:
        raise ValueError(f"{name} must have shape (n_units, n_draws, ...), got {arr.shape}")
    labels = np.asarray(groups)
    if labels.shape != arr.shape[:1]:
        raise ValueError(f"groups must hold one label per unit ({arr.shape[0]}), got shape {labels.shape}")
    if len(np.unique(labels)) < 2:
        raise ValueError("groups must hold at least 2 distinct labels to resample groups")
    return arr, labels


def grouped_bootstrap_ci(values, groups, *, rng: np.random.Generator, level: float = 0.95,
                         n_boot: int = 2000) -> BootstrapInterval:
    """Percentile interval of the mean over units and draws, resampling groups, then draws.

    Parameters
    ----------
    values : array_like, shape (n_units, n_draws, ...)
        Each unit's value under each of its draws (e.g. RMSE per trial and loss mask); trailing
        axes are independent quantities (methods), resampled together (paired).  Finite.
    groups : array_like, shape (n_units,)
        Each unit's group (resampled whole); at least 2 distinct labels.
    rng, level, n_boot
        As in :func:`bootstrap_ci`.

    Returns
    -------
    BootstrapInterval
        ``estimate`` the mean over units of the mean over draws, shape ``values.shape[2:]``;
        ``method="percentile"``; ``n_units`` the number of groups.
    """
    rng = check_rng(rng)
    level, n_boot = _check_options(level, n_boot, "percentile", "mean")
    arr, labels = _grouped_values(values, groups, "values")
    tail = arr.shape[2:]
    estimate = arr.mean(axis=(0, 1))
    boot = _grouped_means(arr.reshape(arr.shape[:2] + (-1,)), labels, rng, n_boot)
    return _percentile_interval(boot.reshape((n_boot,) + tail), estimate, level, len(np.unique(labels)), n_boot)


def grouped_ratio_ci(a, b, groups, *, rng: np.random.Generator, level: float = 0.95,
                     n_boot: int = 2000) -> BootstrapInterval:
    """Percentile interval of ``mean(a) / mean(b)`` with :func:`grouped_bootstrap_ci`'s two-stage resampling.

    Parameters
    ----------
    a, b : array_like, shape (n_units, n_draws)
        The same units and draws scored by two methods; ``b`` > 0.
    groups, rng, level, n_boot
        As in :func:`grouped_bootstrap_ci`.
    """
    rng = check_rng(rng)
    level, n_boot = _check_options(level, n_boot, "percentile", "mean")
    a, labels = _grouped_values(a, groups, "a")
    b, _ = _grouped_values(b, groups, "b")
    if a.ndim != 2 or a.shape != b.shape:
        raise ValueError(f"a and b must have the same shape (n_units, n_draws), got {a.shape} and {b.shape}")
    if np.any(b <= 0):
        raise ValueError("b must be > 0 on every unit and draw (the ratio's denominator)")
    boot = _grouped_means(np.stack([a, b], axis=2), labels, rng, n_boot)
    ratios = boot[:, 0] / boot[:, 1]
    return _percentile_interval(ratios, np.asarray(a.mean() / b.mean()), level, len(np.unique(labels)), n_boot)
