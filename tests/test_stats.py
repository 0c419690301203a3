"""Bootstrap intervals, paired differences and rankings with ties (wsnlib.stats)."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats as scipy_stats

from wsnlib import stats

N_REPEATS = 200


def _coverage_bounds(level: float, n: int = N_REPEATS) -> tuple[float, float]:
    """Acceptance band for an observed coverage: a 99.9 % binomial interval around ``level``,
    widened downward by 3 points for the bootstrap's known small-sample undercoverage."""
    low, high = scipy_stats.binom.interval(0.999, n, level)
    return low / n - 0.03, high / n


@pytest.mark.parametrize("method", ["bca", "percentile"])
def test_interval_covers_the_true_mean_at_about_the_nominal_rate(method):
    # Skewed (exponential) data, true mean 2, 40 units per data set, 200 data sets.
    rng = np.random.default_rng(7)
    level, hits = 0.9, 0
    for _ in range(N_REPEATS):
        sample = rng.exponential(2.0, size=40)
        ci = stats.bootstrap_ci(sample, rng=rng, level=level, n_boot=1000, method=method)
        hits += bool(ci.contains(2.0))
    low, high = _coverage_bounds(level)
    assert low <= hits / N_REPEATS <= high


def test_interval_fails_to_cover_a_wrong_mean():
    # The coverage test above could pass with huge intervals; these must exclude a far value.
    rng = np.random.default_rng(8)
    misses = sum(not stats.bootstrap_ci(rng.normal(0.0, 1.0, 40), rng=rng, n_boot=500).contains(1.0)
                 for _ in range(50))
    assert misses >= 48


def test_interval_shape_estimate_and_determinism():
    values = np.random.default_rng(1).normal(size=(30, 2, 3))
    a = stats.bootstrap_ci(values, rng=np.random.default_rng(5), n_boot=500)
    b = stats.bootstrap_ci(values, rng=np.random.default_rng(5), n_boot=500)
    assert a.low.shape == a.high.shape == a.estimate.shape == (2, 3)
    np.testing.assert_array_equal(a.low, b.low)
    np.testing.assert_allclose(a.estimate, values.mean(axis=0))
    assert np.all(a.low < a.estimate) and np.all(a.estimate < a.high)
    assert (a.n_units, a.n_boot, a.method, a.statistic) == (30, 500, "bca", "mean")
    med = stats.bootstrap_ci(values, rng=np.random.default_rng(5), n_boot=500, statistic="median")
    np.testing.assert_allclose(med.estimate, np.median(values, axis=0))
    assert np.all(med.low <= med.estimate) and np.all(med.estimate <= med.high)


def test_percentile_interval_matches_scipy():
    values = np.random.default_rng(2).gamma(2.0, size=60)
    ours = stats.bootstrap_ci(values, rng=np.random.default_rng(3), n_boot=4000, method="percentile")
    theirs = scipy_stats.bootstrap((values,), np.mean, n_resamples=4000, method="percentile",
                                   random_state=np.random.default_rng(4)).confidence_interval
    # Different resamples: agreement within Monte Carlo error of the quantiles.
    assert ours.low == pytest.approx(theirs.low, abs=0.05)
    assert ours.high == pytest.approx(theirs.high, abs=0.05)
    bca = stats.bootstrap_ci(values, rng=np.random.default_rng(3), n_boot=4000)
    theirs_bca = scipy_stats.bootstrap((values,), np.mean, n_resamples=4000, method="BCa",
                                       random_state=np.random.default_rng(4)).confidence_interval
    assert bca.low == pytest.approx(theirs_bca.low, abs=0.05)
    assert bca.high == pytest.approx(theirs_bca.high, abs=0.05)


def test_constant_sample_gives_a_point_interval():
    ci = stats.bootstrap_ci(np.full(10, 3.0), rng=np.random.default_rng(0), n_boot=200)
    assert ci.low == ci.high == ci.estimate == 3.0


def test_paired_difference_is_sharper_than_separate_intervals():
    rng = np.random.default_rng(11)
    unit = rng.normal(10.0, 5.0, size=25)          # large unit-to-unit spread, shared
    a, b = unit + 0.5 + rng.normal(0, 0.2, 25), unit + rng.normal(0, 0.2, 25)
    diff = stats.paired_difference_ci(a, b, rng=rng, n_boot=1000)
    assert diff.low > 0.0                          # a is worse than b, clearly, when paired
    ca, cb = (stats.bootstrap_ci(x, rng=rng, n_boot=1000) for x in (a, b))
    assert ca.low < cb.high                        # ... though their own intervals overlap
    with pytest.raises(ValueError, match="same shape"):
        stats.paired_difference_ci(a, b[:-1], rng=rng)


def test_rank_with_ties_detects_a_planted_tie():
    rng = np.random.default_rng(21)
    unit = rng.normal(0.0, 1.0, size=30)
    samples = pd.DataFrame({
        "best": unit + 5.0 + rng.normal(0, 0.3, 30),
        "tied": unit + 5.05 + rng.normal(0, 0.3, 30),   # within noise of "best"
        "worse": unit + 8.0 + rng.normal(0, 0.3, 30),   # far behind
    })
    for paired in (True, False):
        table = stats.rank_with_ties(samples, rng=np.random.default_rng(1), n_boot=1000, paired=paired)
        assert set(table.index[:2]) == {"best", "tied"}
        assert table.loc["best", "tie_group"] == table.loc["tied", "tie_group"] == 1
        assert table.loc["worse", "tie_group"] == 2
        assert table.loc["best", "tied"] and not table.loc["worse", "tied"]
        assert list(table["rank"]) == [1, 2, 3]
        sentence = stats.describe_ranking(table, what="RMSE", unit="°")
        assert "tie" in sentence and "worse" not in sentence
    # Separated: no tie, and the sentence says so.
    clear = stats.rank_with_ties(samples[["best", "worse"]], rng=np.random.default_rng(1), n_boot=1000)
    assert list(clear["tie_group"]) == [1, 2]
    assert "separated" in stats.describe_ranking(clear)
    higher = stats.rank_with_ties(samples, rng=np.random.default_rng(1), n_boot=1000, lower_is_better=False)
    assert higher.index[0] == "worse"


def test_rank_intervals_groups_by_overlap_with_the_leader():
    table = pd.DataFrame({"estimate": [1.0, 2.0, 2.5, 4.0], "ci_low": [0.5, 1.4, 1.6, 3.5],
                          "ci_high": [1.5, 2.6, 3.4, 4.5]}, index=["a", "b", "c", "d"])
    ranked = stats.rank_intervals(table)
    # b overlaps a; c does not overlap a (leader) → new group led by c; d does not overlap c.
    assert ranked["tie_group"].to_dict() == {"a": 1, "b": 1, "c": 2, "d": 3}


@pytest.mark.parametrize("kwargs, match", [
    ({"values": [1.0]}, "at least 2 units"),
    ({"values": [1.0, np.nan]}, "NaN"),
    ({"values": [1.0, 2.0], "level": 1.0}, "level"),
    ({"values": [1.0, 2.0], "n_boot": 10}, "n_boot"),
    ({"values": [1.0, 2.0], "method": "bootstrap-t"}, "method"),
    ({"values": [1.0, 2.0], "statistic": "mode"}, "statistic"),
    ({"values": [1.0, 2.0], "rng": 3}, "rng"),
])
def test_bad_input_is_rejected(kwargs, match):
    args = {"rng": np.random.default_rng(0), **kwargs}
    with pytest.raises(ValueError, match=match):
        stats.bootstrap_ci(**args)


def test_bad_rankings_are_rejected():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="at least 2 methods"):
        stats.rank_with_ties({"a": [1.0, 2.0]}, rng=rng)
    with pytest.raises(ValueError, match="same number of units"):
        stats.rank_with_ties({"a": [1.0, 2.0], "b": [1.0, 2.0, 3.0]}, rng=rng)
    with pytest.raises(ValueError, match="1-D"):
        stats.rank_with_ties({"a": [[1.0, 2.0]], "b": [[1.0, 2.0]]}, rng=rng)
    with pytest.raises(ValueError, match="ci_low <= estimate"):
        stats.rank_intervals(pd.DataFrame({"estimate": [1.0], "ci_low": [2.0], "ci_high": [3.0]}))
    with pytest.raises(ValueError, match="rank_with_ties"):
        stats.describe_ranking(pd.DataFrame({"estimate": [1.0]}))


def _clustered(rng, n_groups=7, sizes=(3, 2, 2, 1, 2, 3, 4), n_draws=5, truth=10.0):
    labels = np.repeat(np.arange(n_groups), sizes)
    group_effect = rng.normal(0.0, 2.0, n_groups)[labels]
    return labels, truth + group_effect[:, None] + rng.normal(0.0, 1.0, (labels.size, n_draws))


def test_grouped_interval_covers_clustered_truth_better_than_a_trial_bootstrap():
    # Trials of one group share an effect: resampling trials as if independent is too narrow.
    rng = np.random.default_rng(1)
    grouped = naive = 0
    for _ in range(200):
        labels, values = _clustered(rng)
        ci = stats.grouped_bootstrap_ci(values, labels, rng=rng, n_boot=400)
        grouped += bool(ci.low <= 10.0 <= ci.high)
        flat = stats.bootstrap_ci(values.mean(axis=1), rng=rng, n_boot=400, method="percentile")
        naive += bool(flat.low <= 10.0 <= flat.high)
    assert grouped / 200 >= 0.8 and naive / 200 <= 0.75


def test_grouped_interval_estimate_and_draw_spread():
    rng = np.random.default_rng(2)
    values = np.zeros((4, 3, 2))
    values[..., 1] = np.array([1.0, 2.0, 3.0])  # method 1: only the draws differ, identical on every unit
    ci = stats.grouped_bootstrap_ci(values, ["a", "a", "b", "c"], rng=rng, n_boot=500)
    assert ci.estimate.shape == (2,) and ci.estimate[1] == 2.0 and ci.n_units == 3
    assert ci.low[0] == ci.high[0] == 0.0          # no spread at all: the estimate itself
    assert ci.low[1] < 2.0 < ci.high[1]            # spread from the draws alone is resampled


def test_grouped_ratio_of_proportional_methods_is_exact():
    rng = np.random.default_rng(3)
    labels, values = _clustered(rng)
    ci = stats.grouped_ratio_ci(values, 2.0 * values, labels, rng=rng, n_boot=300)
    assert np.isclose(ci.estimate, 0.5) and np.isclose(ci.low, 0.5) and np.isclose(ci.high, 0.5)


@pytest.mark.parametrize(("values", "groups", "match"), [
    (np.ones(4), [0, 0, 1, 1], "n_units, n_draws"),
    (np.ones((4, 2)), [0, 0, 1], "one label per unit"),
    (np.ones((4, 2)), [0, 0, 0, 0], "2 distinct"),
    (np.array([[1.0, np.nan], [1.0, 1.0]]), [0, 1], "NaN"),
])
def test_grouped_interval_refuses_bad_input(values, groups, match):
    with pytest.raises(ValueError, match=match):
        stats.grouped_bootstrap_ci(values, groups, rng=np.random.default_rng(0))


def test_grouped_ranking_ties_what_the_groups_cannot_separate():
    rng = np.random.default_rng(4)
    labels, base = _clustered(rng)
    # "b" is "a" + 3 on every unit and draw (separated whatever the groups); "c" is "a" plus
    # one shared offset per group of ±1 (no consistent difference: a tie).
    offsets = np.where(np.unique(labels) % 2 == 0, 1.0, -1.0)[labels]
    samples = {"a": base, "b": base + 3.0, "c": base + offsets[:, None] - offsets.mean()}
    table = stats.rank_with_ties(samples, rng=rng, groups=labels, n_boot=500)
    assert table.loc["b", "tie_group"] > table.loc["a", "tie_group"]
    assert table.loc["c", "tie_group"] == table.loc["a", "tie_group"]
    assert (table["n_units"] == 7).all()
    assert "over 7 groups" in stats.describe_ranking(table)
