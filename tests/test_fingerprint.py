"""Fingerprinting (paper 002, Sec. 3.1): radio map, kNN with Shepard weights, p-kNN and its PMFs."""

import numpy as np
import pytest
from scipy.special import ndtr
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.neighbors import KNeighborsRegressor

from wsnlib.radio import (
    SHEPARD_EPS,
    KNNFingerprint,
    ProbabilisticKNN,
    anchor_subsets,
    knn_from_terms,
    pknn_from_loglik,
)

# A hand-made radio map: 3 positions, 2 anchors, one vector each.
MAP_X = np.array([[-50.0, -70.0], [-60.0, -60.0], [-70.0, -50.0]])
MAP_Y = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 2.0, 0.0]])


def _training(rng, n_positions=6, n_anchors=7, per_position=40, spread=2.0):
    """Gaussian RSS around well separated means, rounded to 1 dBm (like real RSSI)."""
    means = rng.uniform(-90.0, -40.0, size=(n_positions, n_anchors))
    positions = rng.uniform(0.0, 2.0, size=(n_positions, 3))
    X = np.concatenate([np.round(m + rng.normal(0.0, spread, size=(per_position, n_anchors))) for m in means])
    y = np.repeat(positions, per_position, axis=0)
    return X, y, means, positions


# ------------------------------------------------------------------ radio map


def test_radio_map_groups_positions_in_order_of_appearance():
    X = np.array([[-40.0, -80.0], [-60.0, -60.0], [-42.0, -82.0], [-62.0, -58.0], [-90.0, -30.0]])
    y = np.array([[5.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0], [1.0, 0, 0], [-3.0, 0, 0]])
    est = KNNFingerprint(n_neighbors=1).fit(X, y)
    np.testing.assert_array_equal(est.positions_, [[5.0, 0, 0], [1.0, 0, 0], [-3.0, 0, 0]])
    np.testing.assert_allclose(est.radio_map_, [[-41.0, -81.0], [-61.0, -59.0], [-90.0, -30.0]])
    np.testing.assert_array_equal(est.n_readings_, [[2, 2], [2, 2], [1, 1]])
    assert est.n_features_in_ == 2


def test_missing_readings_are_left_out_and_silent_anchor_gets_the_floor():
    nan = np.nan
    X = np.array([[-40.0, nan, nan], [-50.0, -70.0, nan], [nan, -60.0, -55.0], [nan, nan, -65.0]])
    y = np.array([[0.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]])
    est = KNNFingerprint(n_neighbors=1, floor_rss=-95.0).fit(X, y)
    np.testing.assert_allclose(est.radio_map_, [[-45.0, -70.0, -95.0], [-95.0, -60.0, -60.0]])
    np.testing.assert_array_equal(est.n_readings_, [[2, 1, 0], [0, 1, 2]])

    pk = ProbabilisticKNN(n_neighbors=1, floor_rss=-95.0, floor_probability=1e-9).fit(X, y)
    grid = pk.grid_
    np.testing.assert_allclose(pk.radio_map_, est.radio_map_)
    # position 0, anchor 0: readings -40 and -50 only (NaNs excluded)
    np.testing.assert_allclose(pk.pmf_[0, 0, grid == -40], 0.5, atol=1e-6)
    np.testing.assert_allclose(pk.pmf_[0, 0, grid == -50], 0.5, atol=1e-6)
    # anchor 2 never heard at position 0, anchor 0 never at position 1: point mass at the floor
    np.testing.assert_allclose(pk.pmf_[0, 2, grid == -95], 1.0, atol=1e-6)
    np.testing.assert_allclose(pk.pmf_[1, 0, grid == -95], 1.0, atol=1e-6)
    assert grid[0] <= -95 - pk.grid_margin_db and grid[-1] >= -40 + pk.grid_margin_db


# ------------------------------------------------------------------ kNN, eqs. (1)-(2)


@pytest.mark.parametrize("metric", ["euclidean", "manhattan"])
def test_k1_returns_the_nearest_fingerprint_position(metric):
    est = KNNFingerprint(n_neighbors=1, metric=metric, power=3).fit(MAP_X, MAP_Y)
    online = np.array([[-52.0, -69.0], [-61.0, -58.0], [-75.0, -45.0], [-60.0, -60.0]])
    np.testing.assert_array_equal(est.predict(online), MAP_Y[[0, 1, 2, 1]])


@pytest.mark.parametrize("power", [1, 2, 5])
def test_equal_distances_give_the_midpoint(power):
    est = KNNFingerprint(n_neighbors=2, power=power).fit(MAP_X[:2], MAP_Y[:2])
    np.testing.assert_allclose(est.predict([[-55.0, -65.0]]), [[0.5, 0.0, 0.0]])


@pytest.mark.parametrize("metric", ["euclidean", "manhattan"])
@pytest.mark.parametrize("power", [1, 2, 3])
def test_shepard_weights_formula(metric, power):
    online = np.array([[-58.0, -63.0]])
    diff = online - MAP_X
    d = np.sqrt((diff**2).sum(1)) if metric == "euclidean" else np.abs(diff).sum(1)
    w = 1.0 / (d**power + 0.0001)
    expected = (w[:, None] * MAP_Y).sum(0) / w.sum()
    est = KNNFingerprint(n_neighbors=3, metric=metric, power=power).fit(MAP_X, MAP_Y)
    np.testing.assert_allclose(est.predict(online)[0], expected, rtol=1e-12)
    dist, idx = est.kneighbors(online)
    np.testing.assert_array_equal(idx[0], np.argsort(d))
    np.testing.assert_allclose(dist[0], np.sort(d))
    assert SHEPARD_EPS == 1e-4


def test_online_vector_equal_to_a_fingerprint_is_not_a_division_by_zero():
    est = KNNFingerprint(n_neighbors=3).fit(MAP_X, MAP_Y)
    out = est.predict(MAP_X[[1]])
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out[0], MAP_Y[1], atol=1e-4)  # weight 1e4 against ~1/14


@pytest.mark.parametrize("metric", ["euclidean", "manhattan"])
@pytest.mark.parametrize("k", [1, 3, 5])
@pytest.mark.parametrize("power", [1, 2, 3])
def test_matches_sklearn_kneighbors_regressor(rng, metric, k, power):
    X, y, _, _ = _training(rng, n_positions=12, per_position=5)
    est = KNNFingerprint(n_neighbors=k, metric=metric, power=power).fit(X, y)
    online = rng.uniform(-90.0, -40.0, size=(50, 7))
    ref = KNeighborsRegressor(
        n_neighbors=k, weights=lambda d: 1.0 / (d**power + 1e-4), metric=metric, algorithm="brute"
    ).fit(est.radio_map_, est.positions_)
    np.testing.assert_allclose(est.predict(online), ref.predict(online), rtol=1e-10, atol=1e-12)


def test_batch_prediction_equals_one_vector_at_a_time(rng):
    X, y, _, _ = _training(rng)
    online = rng.uniform(-90.0, -40.0, size=(20, 7))
    for est in (KNNFingerprint(n_neighbors=3).fit(X, y), ProbabilisticKNN(n_neighbors=3).fit(X, y)):
        batch = est.predict(online)
        assert batch.shape == (20, 3)
        single = np.array([est.predict(row[None, :])[0] for row in online])
        np.testing.assert_allclose(batch, single, rtol=1e-12)


def test_overflowing_power_falls_back_to_the_nearest_position():
    est = KNNFingerprint(n_neighbors=3, power=400).fit(MAP_X, MAP_Y)  # 22 dB ** 400 overflows
    np.testing.assert_allclose(est.predict([[-90.0, -40.0]]), MAP_Y[[2]])


# ------------------------------------------------------------------ anchor subsets


@pytest.mark.parametrize("cls", [KNNFingerprint, ProbabilisticKNN])
def test_anchor_subset_equals_fitting_on_the_columns(rng, cls):
    X, y, _, _ = _training(rng)
    online = rng.uniform(-90.0, -40.0, size=(15, 7))
    cols = [1, 4, 5]
    sub = cls(n_neighbors=3, anchors=cols).fit(X, y)
    mask = np.zeros(7, dtype=bool)
    mask[cols] = True
    by_mask = cls(n_neighbors=3, anchors=mask).fit(X, y)
    reduced = cls(n_neighbors=3).fit(X[:, cols], y)
    np.testing.assert_allclose(sub.predict(online), reduced.predict(online[:, cols]), rtol=1e-12)
    np.testing.assert_array_equal(sub.predict(online), by_mask.predict(online))
    assert sub.radio_map_.shape == (6, 7)  # the learned map keeps every anchor


def test_knn_subset_batch_equals_per_subset_fits(rng):
    X, y, _, _ = _training(rng, n_positions=8)
    online = rng.uniform(-90.0, -40.0, size=(10, 7))
    subsets = anchor_subsets(7)
    assert subsets.shape == (127, 7) and not np.any(subsets.sum(1) == 0)
    for metric, k, power in [("euclidean", 3, 1), ("manhattan", 2, 2), ("euclidean", 1, 1)]:
        full = KNNFingerprint(n_neighbors=k, metric=metric, power=power).fit(X, y)
        batch = knn_from_terms(full.anchor_terms(online), subsets, full.positions_, k, power, metric)
        assert batch.shape == (127, 10, 3)
        for s, mask in enumerate(subsets):
            one = KNNFingerprint(n_neighbors=k, metric=metric, power=power, anchors=mask).fit(X, y)
            np.testing.assert_allclose(batch[s], one.predict(online), rtol=1e-10, atol=1e-12)
    single = knn_from_terms(full.anchor_terms(online), subsets[5], full.positions_, 1, 1, "euclidean")
    np.testing.assert_allclose(single, batch[5])


@pytest.mark.parametrize("pmf", ["histogram", "parzen"])
def test_pknn_subset_batch_equals_per_subset_fits(rng, pmf):
    X, y, _, _ = _training(rng, n_positions=8)
    online = np.round(rng.uniform(-90.0, -40.0, size=(10, 7)))
    subsets = anchor_subsets(7)
    full = ProbabilisticKNN(n_neighbors=3, pmf=pmf).fit(X, y)
    batch = pknn_from_loglik(full.anchor_log_likelihoods(online), subsets, full.positions_, 3)
    assert batch.shape == (127, 10, 3)
    for s, mask in enumerate(subsets):
        one = ProbabilisticKNN(n_neighbors=3, pmf=pmf, anchors=mask).fit(X, y)
        np.testing.assert_allclose(batch[s], one.predict(online), rtol=1e-9, atol=1e-12)


def test_anchor_subsets_sizes():
    assert anchor_subsets(12).shape == (4095, 12)
    pairs = anchor_subsets(4, sizes=[2])
    assert pairs.shape == (6, 4) and np.all(pairs.sum(1) == 2)


# ------------------------------------------------------------------ p-kNN, eqs. (3)-(4)


@pytest.mark.parametrize("pmf", ["histogram", "parzen", "gmm"])
def test_vector_drawn_from_a_position_pmf_is_classified_there(rng, pmf):
    X, y, _, positions = _training(rng, n_positions=6, per_position=60)
    est = ProbabilisticKNN(n_neighbors=1, pmf=pmf, random_state=0).fit(X, y)
    for target in range(6):
        draws = np.array([[rng.choice(est.grid_, p=est.pmf_[target, a]) for a in range(7)] for _ in range(5)])
        np.testing.assert_array_equal(est.predict(draws), np.repeat(positions[[target]], 5, axis=0))


def test_k1_is_the_map_position_and_k_weights_are_posteriors(rng):
    X, y, _, _ = _training(rng, spread=6.0)
    online = np.round(rng.uniform(-90.0, -40.0, size=(30, 7)))
    est = ProbabilisticKNN(n_neighbors=1).fit(X, y)
    post = np.exp(est.predict_log_proba(online))
    np.testing.assert_allclose(post.sum(1), 1.0)
    np.testing.assert_array_equal(est.predict(online), est.positions_[np.argmax(post, axis=1)])

    est3 = ProbabilisticKNN(n_neighbors=3).fit(X, y)
    logpost, idx = est3.kneighbors(online)
    top = np.argsort(-post, axis=1, kind="stable")[:, :3]
    np.testing.assert_array_equal(idx, top)
    p_top = np.take_along_axis(post, top, axis=1)
    np.testing.assert_allclose(np.exp(logpost), p_top, rtol=1e-9)
    expected = (p_top[:, :, None] * est3.positions_[top]).sum(1) / p_top.sum(1, keepdims=True)
    np.testing.assert_allclose(est3.predict(online), expected, rtol=1e-9)


def test_log_posteriors_agree_bit_for_bit_with_the_neighbour_ranking(rng):
    """predict_log_proba sums a subset's anchors in the same fixed order as kneighbors (no BLAS)."""
    X, y, _, _ = _training(rng, spread=6.0)
    online = np.round(rng.uniform(-90.0, -40.0, size=(30, 7)))
    est = ProbabilisticKNN(n_neighbors=3, anchors=(0, 1, 2, 4, 5, 6)).fit(X, y)
    logpost, idx = est.kneighbors(online)
    np.testing.assert_array_equal(np.take_along_axis(est.predict_log_proba(online), idx, axis=1), logpost)


def test_histogram_pmf_is_the_normalised_histogram():
    X = np.array([[-60.0], [-60.0], [-61.0], [-63.4], [-59.6]])  # rounded: -60, -60, -61, -63, -60
    y = np.zeros((5, 3))
    est = ProbabilisticKNN(n_neighbors=1, floor_probability=1e-12).fit(X, y)
    pmf = dict(zip(est.grid_.tolist(), est.pmf_[0, 0], strict=True))
    assert pmf[-60] == pytest.approx(0.6) and pmf[-61] == pytest.approx(0.2) and pmf[-63] == pytest.approx(0.2)
    assert pmf[-62] == pytest.approx(0.0, abs=1e-11)


def test_log_space_is_stable_with_12_anchors_and_extreme_values(rng):
    X, y, _, _ = _training(rng, n_anchors=12, per_position=30, spread=0.5)
    # a floor so small that a product of 12 PMF values underflows to 0 for every position
    est = ProbabilisticKNN(n_neighbors=3, floor_probability=1e-300).fit(X, y)
    online = np.array([[-1000.0] * 12, [1000.0] * 12, [0.0] * 6 + [-200.0] * 6, [-1e9] * 12])
    naive = np.prod(np.take_along_axis(est.pmf_, np.zeros((6, 12, 1), dtype=int), axis=2)[..., 0], axis=1)
    assert np.all(naive == 0.0)  # the linear-space likelihood would give 0/0
    out = est.predict(online)
    post = np.exp(est.predict_log_proba(online))
    assert np.all(np.isfinite(out)) and np.all(np.isfinite(post))
    np.testing.assert_allclose(post.sum(1), 1.0)
    ll = est.anchor_log_likelihoods(online)
    assert ll.shape == (4, 6, 12) and np.all(np.isfinite(ll))


def test_floor_probability_keeps_a_position_with_one_unseen_reading(rng):
    X, y, means, positions = _training(rng, spread=1.0)
    est = ProbabilisticKNN(n_neighbors=1, floor_probability=1e-4).fit(X, y)
    assert np.all(est.pmf_ > 0) and np.all(np.isfinite(est.log_pmf_))
    np.testing.assert_allclose(est.pmf_.sum(-1), 1.0)
    assert est.pmf_.min() == pytest.approx(1e-4, rel=0.05)  # ε, less the renormalisation
    online = np.round(means[[2]])
    online[0, 3] = -20.0  # never seen anywhere: costs log(eps) at every position alike
    np.testing.assert_array_equal(est.predict(online), positions[[2]])


def test_parzen_pmf_and_silverman_bandwidth():
    values = np.array([-60.0, -62.0, -61.0, -65.0, -61.0, -60.0, -63.0, -61.0])
    y = np.zeros((values.size, 3))
    est = ProbabilisticKNN(n_neighbors=1, pmf="parzen", floor_probability=1e-15).fit(values[:, None], y)
    sigma = values.std(ddof=1)
    q25, q75 = np.quantile(values, [0.25, 0.75], method="inverted_cdf")
    expected_h = 0.9 * min(sigma, (q75 - q25) / 1.34) * values.size**-0.2
    assert est.bandwidth_[0, 0] == pytest.approx(max(expected_h, 0.5))
    h = est.bandwidth_[0, 0]
    grid = est.grid_.astype(float)
    ref = np.mean([ndtr((grid + 0.5 - v) / h) - ndtr((grid - 0.5 - v) / h) for v in values], axis=0)
    np.testing.assert_allclose(est.pmf_[0, 0], ref / ref.sum(), atol=1e-12)
    # zero variance (the paper's concern) gets the minimum bandwidth, not a spike
    flat = ProbabilisticKNN(pmf="parzen", n_neighbors=1, min_bandwidth_db=1.5)
    flat.fit(np.full((20, 1), -70.0), np.zeros((20, 3)))
    assert flat.bandwidth_[0, 0] == 1.5
    assert flat.pmf_[0, 0, flat.grid_ == -69] > 0.1
    fixed = ProbabilisticKNN(pmf="parzen", n_neighbors=1, bandwidth_db=3.0).fit(values[:, None], y)
    assert fixed.bandwidth_[0, 0] == 3.0


def test_gmm_pmf_is_normalised_bimodal_and_seeded(rng):
    values = np.concatenate([rng.normal(-80.0, 1.0, 100), rng.normal(-60.0, 1.0, 100)]).round()
    y = np.zeros((200, 3))
    a = ProbabilisticKNN(pmf="gmm", n_neighbors=1, n_components=2, random_state=7).fit(values[:, None], y)
    b = ProbabilisticKNN(pmf="gmm", n_neighbors=1, n_components=2, random_state=7).fit(values[:, None], y)
    np.testing.assert_array_equal(a.pmf_, b.pmf_)
    np.testing.assert_allclose(a.pmf_.sum(-1), 1.0)
    pmf = a.pmf_[0, 0]
    near = lambda c: pmf[np.abs(a.grid_ - c) <= 3].sum()  # noqa: E731
    assert near(-80) > 0.4 and near(-60) > 0.4 and pmf[a.grid_ == -70][0] < 1e-3


@pytest.mark.parametrize("pmf", ["histogram", "parzen", "gmm"])
def test_pmfs_are_normalised_and_predictions_sensible(rng, pmf):
    X, y, means, positions = _training(rng, n_positions=5, per_position=50, spread=3.0)
    est = ProbabilisticKNN(n_neighbors=3, pmf=pmf, random_state=1).fit(X, y)
    assert est.pmf_.shape == (5, 7, est.grid_.size)
    np.testing.assert_allclose(est.pmf_.sum(-1), 1.0)
    assert np.all(est.pmf_ > 0)
    out = est.predict(np.round(means))
    assert np.max(np.linalg.norm(out - positions, axis=1)) < 0.05


# ------------------------------------------------------------------ conventions and errors


def test_sklearn_conventions():
    est = ProbabilisticKNN(n_neighbors=2, pmf="parzen", bandwidth_db=1.0)
    assert est.get_params()["bandwidth_db"] == 1.0
    assert not hasattr(est, "pmf_")
    copy = clone(est)
    assert copy.get_params() == est.get_params()
    assert est.fit(MAP_X, MAP_Y) is est
    assert KNNFingerprint().set_params(n_neighbors=1).n_neighbors == 1


@pytest.mark.parametrize("cls", [KNNFingerprint, ProbabilisticKNN])
def test_bad_input_raises(cls):
    with pytest.raises(NotFittedError):
        cls().predict(MAP_X)
    est = cls(n_neighbors=2).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="NaN.*fill"):
        est.predict([[-50.0, np.nan]])
    with pytest.raises(ValueError, match="length 3"):
        est.predict([[-50.0, -60.0, -70.0]])
    with pytest.raises(ValueError, match="reshape"):
        est.predict([-50.0, -60.0])
    with pytest.raises(ValueError, match="n_neighbors=4"):
        cls(n_neighbors=4).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="n_neighbors"):
        cls(n_neighbors=0).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="empty subset"):
        cls(anchors=[]).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="empty subset"):
        cls(anchors=np.array([False, False])).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="anchors"):
        cls(anchors=[0, 2]).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="duplicate"):
        cls(anchors=[1, 1]).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="y must have shape"):
        cls(n_neighbors=1).fit(MAP_X, MAP_Y[:2])
    with pytest.raises(ValueError, match="inf"):
        cls(n_neighbors=1).fit(np.array([[np.inf, -50.0]]), MAP_Y[:1])


def test_bad_parameters_raise():
    with pytest.raises(ValueError, match="metric"):
        KNNFingerprint(metric="cosine").fit(MAP_X, MAP_Y)
    for power in (0, -1, np.nan):
        with pytest.raises(ValueError, match="power"):
            KNNFingerprint(power=power).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="pmf"):
        ProbabilisticKNN(pmf="kde").fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="floor_probability"):
        ProbabilisticKNN(floor_probability=0.0).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="bandwidth_db"):
        ProbabilisticKNN(pmf="parzen", bandwidth_db=-1.0).fit(MAP_X, MAP_Y)
    with pytest.raises(ValueError, match="n_components"):
        ProbabilisticKNN(pmf="gmm", n_components=0).fit(MAP_X, MAP_Y)


def test_batch_function_errors(rng):
    terms = rng.uniform(size=(4, 3, 2))
    with pytest.raises(ValueError, match="empty subset"):
        knn_from_terms(terms, np.array([[True, False], [False, False]]), MAP_Y, 1, 1)
    with pytest.raises(ValueError, match="boolean"):
        knn_from_terms(terms, np.array([1, 0]), MAP_Y, 1, 1)
    with pytest.raises(ValueError, match="n_neighbors=5"):
        knn_from_terms(terms, np.array([True, True]), MAP_Y, 5, 1)
    with pytest.raises(ValueError, match="positions"):
        pknn_from_loglik(-terms, np.array([True, True]), MAP_Y[:2], 1)
    with pytest.raises(ValueError, match="inf"):
        pknn_from_loglik(np.full((4, 3, 2), -np.inf), np.array([True, True]), MAP_Y, 1)


def test_fit_predict_by_group_uses_each_groups_own_map():
    from wsnlib.radio import KNNFingerprint, fit_predict_by_group

    X_train = np.array([[-50.0, -60.0], [-70.0, -40.0], [-50.0, -60.0], [-70.0, -40.0]])
    y_train = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0], [6.0, 0, 0]])
    groups_train = np.array(["a", "a", "b", "b"])
    X = np.array([[-51.0, -59.0], [-51.0, -59.0]])
    pred = fit_predict_by_group(KNNFingerprint(n_neighbors=1), X_train, y_train, groups_train, X, np.array(["a", "b"]))
    np.testing.assert_allclose(pred[:, 0], [0.0, 5.0])
    with pytest.raises(ValueError, match="groups"):
        fit_predict_by_group(KNNFingerprint(n_neighbors=1), X_train, y_train, groups_train, X, np.array(["a", "c"]))



# ------------------------------------------------------------------ missing online readings


@pytest.mark.parametrize("cls, options", [(KNNFingerprint, {"metric": "euclidean", "power": 2}),
                                          (KNNFingerprint, {"metric": "manhattan", "power": 1}),
                                          (ProbabilisticKNN, {"pmf": "histogram"}),
                                          (ProbabilisticKNN, {"pmf": "parzen"})])
def test_skipping_a_missing_online_reading_equals_leaving_its_anchor_out(rng, cls, options):
    X, y, means, _ = _training(rng, n_anchors=5)
    X[rng.uniform(size=X.shape) < 0.1] = np.nan                      # missing in training too
    online = np.round(means + rng.normal(0.0, 3.0, size=means.shape))
    missing = rng.uniform(size=online.shape) < 0.3
    missing[:, 0] = False                                            # every vector keeps a reading
    online[missing] = np.nan
    skip = cls(n_neighbors=3, online_missing="skip", **options).fit(X, y)
    out = skip.predict(online)
    for row, vector in enumerate(online):
        heard = np.flatnonzero(~np.isnan(vector))
        alone = cls(n_neighbors=3, anchors=heard, **options).fit(X, y)
        np.testing.assert_allclose(out[row], alone.predict(np.nan_to_num(vector[None], nan=-100.0))[0], atol=1e-12)
    if cls is ProbabilisticKNN:   # the posterior, too, is the one over the heard anchors
        row = int(np.argmax(missing.sum(axis=1)))
        heard = np.flatnonzero(~missing[row])
        alone = cls(n_neighbors=3, anchors=heard, **options).fit(X, y)
        np.testing.assert_allclose(np.exp(skip.predict_log_proba(online[row : row + 1])),
                                   np.exp(alone.predict_log_proba(np.nan_to_num(online[row : row + 1], nan=-100.0))),
                                   atol=1e-12)


@pytest.mark.parametrize("cls", [KNNFingerprint, ProbabilisticKNN])
def test_a_complete_vector_is_the_same_whether_missing_readings_raise_or_are_skipped(rng, cls):
    X, y, means, _ = _training(rng)
    online = np.round(means + rng.normal(0.0, 2.0, size=means.shape))
    np.testing.assert_array_equal(cls(online_missing="skip").fit(X, y).predict(online),
                                  cls().fit(X, y).predict(online))


@pytest.mark.parametrize("cls", [KNNFingerprint, ProbabilisticKNN])
def test_missing_online_readings_raise_by_default_and_a_vector_with_none_is_refused(cls):
    with pytest.raises(ValueError, match="online_missing='skip'"):
        cls(n_neighbors=1).fit(MAP_X, MAP_Y).predict([[-50.0, np.nan]])
    skip = cls(n_neighbors=1, online_missing="skip").fit(MAP_X, MAP_Y)
    np.testing.assert_array_equal(skip.predict([[-50.0, np.nan]]), MAP_Y[:1])
    with pytest.raises(ValueError, match="row 1 has no reading"):
        skip.predict([[-50.0, np.nan], [np.nan, np.nan]])
    with pytest.raises(ValueError, match="row 0 has no reading on any selected anchor"):
        cls(n_neighbors=1, anchors=[1], online_missing="skip").fit(MAP_X, MAP_Y).predict([[-50.0, np.nan]])
    with pytest.raises(ValueError, match="online_missing"):
        cls(online_missing="fill").fit(MAP_X, MAP_Y)


def test_gmm_cells_are_fitted_on_one_thread(rng, monkeypatch):
    """Non-integer readings in cells of more than 256 (where the k-means start would use its threads)."""
    from sklearn.mixture import GaussianMixture
    from threadpoolctl import threadpool_info

    seen = []
    fit = GaussianMixture.fit

    def recording_fit(self, values, *args, **kwargs):
        seen.append({info["user_api"]: info["num_threads"] for info in threadpool_info()})
        return fit(self, values, *args, **kwargs)

    monkeypatch.setattr(GaussianMixture, "fit", recording_fit)
    X = rng.normal(-60.0, 3.0, size=(600, 2))
    y = np.repeat([[0.0, 0, 0], [1.0, 0, 0]], 300, axis=0)
    ProbabilisticKNN(pmf="gmm", n_neighbors=1, random_state=0).fit(X, y)
    assert len(seen) == 4 and all(threads == 1 for counts in seen for threads in counts.values())
