"""The exhaustive search of paper 002's Tables 2 and 3 (wsnlib.optimize)."""

import math

import numpy as np
import pandas as pd
import pytest

from wsnlib.metrics import position_error
from wsnlib.optimize import (
    SearchData,
    SearchGrid,
    Setting,
    average_over_users,
    best_global,
    best_per_movement,
    coupled_selection_regret,
    evaluate_chain,
    evaluate_setting,
    format_subset,
    paper_tables,
    parse_subset,
    proximal_from_selection,
    search,
    select_settings,
    selection_regret,
    union_of_subsets,
)
from wsnlib.posture import ArmChain, recursive_chain
from wsnlib.radio import (
    KNNFingerprint,
    ProbabilisticKNN,
    anchor_subsets,
    knn_from_terms,
    knn_grid_from_terms,
    pknn_from_loglik,
    pknn_grid_from_loglik,
)

CHAIN = ArmChain(segment_lengths_m=(0.30, 0.25), device_offsets_m=(0.15, 0.125))
SMALL = SearchGrid(knn_neighbors=(1, 2, 3), powers=(1, 2), pknn_neighbors=(1, 2))

# Table 1, target 1 (m): P1 down, P2 up, P3 forward, P4 right, P5 forward-left
TABLE1_T1 = np.array([[0, 0, -15], [0, 0, 15], [0, 15, 0], [15, 0, 0], [-11, 11, 0]]) / 100.0


def _directions_to_positions(directions, offset):
    unit = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    return offset * unit, np.arcsin(np.clip(unit[..., 2], -1, 1))


def make_user(rng, *, n_anchors=7, n_train=40, samples=(12, 15, 10, 14), noise_db=2.0, informative=None,
              segment=0, proximal=None, radio_map=None, online_noise=None, repeat_after=None):
    """A small synthetic user: Table 1 radio map, movements between fingerprint positions.

    Movement j goes from fingerprint position j to j + 1 (mod 5; j mod ``repeat_after`` if
    given, so that movements repeat) along a straight line in direction space; its online
    RSS interpolates the two fingerprints.  ``online_noise`` (a callable rng -> (n, A))
    replaces the RSS noise when given.
    """
    positions = TABLE1_T1 * (CHAIN.device_offsets_m[segment] / 0.15)
    n_fp = positions.shape[0]
    if radio_map is None:
        radio_map = rng.normal(-65.0, 10.0, size=(n_fp, n_anchors))
    train_rss = np.repeat(radio_map, n_train, axis=0) + rng.normal(0.0, noise_db, (n_fp * n_train, n_anchors))
    train_pos = np.repeat(positions, n_train, axis=0)
    rows_rss, rows_dir, rows_mov = [], [], []
    for j, n in enumerate(samples):
        jj = j if repeat_after is None else j % repeat_after
        a, b = jj % n_fp, (jj + 1) % n_fp
        t = np.linspace(0.0, 1.0, n)[:, None]
        direction = (1 - t) * positions[a] + t * positions[b] + np.array([1e-3, 2e-3, 0.0])
        rows_dir.append(direction)
        rows_rss.append((1 - t) * radio_map[a] + t * radio_map[b])
        rows_mov.append(np.full(n, j + 1))
    directions = np.concatenate(rows_dir)
    offset = CHAIN.device_offsets_m[segment]
    rel, pitch = _directions_to_positions(directions, offset)
    n_rows = rel.shape[0]
    prox = np.zeros((n_rows, 3)) if proximal is None else np.broadcast_to(proximal, (n_rows, 3))
    online = np.concatenate(rows_rss)
    online = online + (online_noise(rng) if online_noise else rng.normal(0.0, noise_db, online.shape))
    return SearchData(online_rss=np.round(online), movement=np.concatenate(rows_mov), true_positions=prox + rel,
                      pitch=pitch, chain=CHAIN, segment=segment, proximal=proximal,
                      training_rss=np.round(train_rss), training_positions=train_pos)


@pytest.fixture
def users(rng):
    return [make_user(rng) for _ in range(3)]


# --- the batch grid functions of wsnlib.radio ------------------------------------------


def test_knn_grid_equals_knn_from_terms(rng):
    X = rng.normal(-60, 8, (150, 5))
    y = np.repeat(rng.normal(size=(5, 3)), 30, axis=0)
    online = rng.normal(-60, 8, (20, 5))
    masks = anchor_subsets(5)
    for metric in ("euclidean", "manhattan"):
        est = KNNFingerprint(metric=metric).fit(X, y)
        terms = est.anchor_terms(online)
        grid = knn_grid_from_terms(terms, masks, est.positions_, (1, 3, 5), (1, 2.5, 6), metric)
        assert grid.shape == (31, 3, 3, 20, 3)
        for i, k in enumerate((1, 3, 5)):
            for j, p in enumerate((1, 2.5, 6)):
                np.testing.assert_allclose(grid[:, i, j], knn_from_terms(terms, masks, est.positions_, k, p, metric),
                                           rtol=0, atol=1e-12)
        # k = 1: every power gives exactly the nearest position
        assert np.array_equal(grid[:, 0, 0], grid[:, 0, 2])
        first = knn_grid_from_terms(terms, masks, est.positions_, (1, 3, 5), (1, 2.5, 6), metric,
                                    coordinates_first=True)
        assert np.array_equal(np.moveaxis(first, 0, -1), grid)
        one = knn_grid_from_terms(terms, masks[7], est.positions_, (1, 3, 5), (1, 2.5, 6), metric)
        assert np.array_equal(one, grid[7])
        one_first = knn_grid_from_terms(terms, masks[7], est.positions_, (1, 3, 5), (1, 2.5, 6), metric,
                                        coordinates_first=True)
        assert np.array_equal(one_first, first[:, 7])


def test_pknn_grid_equals_pknn_from_loglik(rng):
    X = np.round(rng.normal(-60, 4, (150, 4)))
    y = np.repeat(rng.normal(size=(5, 3)), 30, axis=0)
    est = ProbabilisticKNN().fit(X, y)
    loglik = est.anchor_log_likelihoods(np.round(rng.normal(-60, 4, (20, 4))))
    grid = pknn_grid_from_loglik(loglik, anchor_subsets(4), est.positions_, (1, 2, 4))
    for i, k in enumerate((1, 2, 4)):
        np.testing.assert_allclose(grid[:, i], pknn_from_loglik(loglik, anchor_subsets(4), est.positions_, k),
                                   rtol=0, atol=1e-12)
    first = pknn_grid_from_loglik(loglik, anchor_subsets(4), est.positions_, (1, 2, 4), coordinates_first=True)
    assert np.array_equal(np.moveaxis(first, 0, -1), grid)
    mask = anchor_subsets(4)[3]
    assert np.array_equal(pknn_grid_from_loglik(loglik, mask, est.positions_, (1, 2, 4)), grid[3])
    assert np.array_equal(pknn_grid_from_loglik(loglik, mask, est.positions_, (1, 2, 4), coordinates_first=True),
                          first[:, 3])


def test_grid_functions_reject_bad_grids(rng):
    terms = rng.random((3, 5, 4))
    pos = rng.random((5, 3))
    with pytest.raises(ValueError, match="at least one"):
        knn_grid_from_terms(terms, anchor_subsets(4), pos, (), (1,))
    with pytest.raises(ValueError, match="at least one"):
        knn_grid_from_terms(terms, anchor_subsets(4), pos, (1,), ())
    with pytest.raises(ValueError, match="larger than"):
        pknn_grid_from_loglik(-terms, anchor_subsets(4), pos, (1, 6))


# --- the search --------------------------------------------------------------------------------


def test_results_layout_and_sizes(users):
    res = search(users, grid=SMALL)
    n_sub = 127
    n_det = n_sub * 2 * (1 + 2 * 2)
    n_prob = n_sub * 2
    assert len(res) == (n_det + n_prob) * 4 * 3
    assert set(res.columns) >= {"approach", "config", "subset", "anchors", "n_anchors", "metric", "k", "p_s",
                                "user", "movement", "pe_cm", "n_samples", "estimate"}
    assert res["pe_cm"].notna().all() and (res["pe_cm"] >= 0).all()
    det = res[res["approach"] == "deterministic"]
    assert det["config"].nunique() == n_det
    assert SMALL.n_settings(7, "deterministic") == n_det and SMALL.n_settings(7, "probabilistic") == n_prob
    # configs ordered by subset size first
    sizes = det.drop_duplicates("config").sort_values("config")["n_anchors"].to_numpy()
    assert np.all(np.diff(sizes) >= 0)
    assert det["p_s"].dtype == "Int64"


def test_k1_ignores_power(users):
    res = search(users, approaches="deterministic", grid=SearchGrid(knn_neighbors=(1, 2), powers=(1, 3, 6)))
    k1 = res[res["k"] == 1]
    assert k1["p_s"].isna().all()
    # one k = 1 row per (subset, metric, user, movement)
    assert not k1.duplicated(["subset", "metric", "user", "movement"]).any()
    assert len(k1) == 127 * 2 * 3 * 4
    # the estimator agrees that the power changes nothing at k = 1
    u = users[0]
    preds = [KNNFingerprint(n_neighbors=1, power=p).fit(u.training_rss, u.training_positions).predict(u.online_rss)
             for p in (1, 3, 6)]
    assert np.array_equal(preds[0], preds[1]) and np.array_equal(preds[0], preds[2])


def _direct_pe(data, setting, proximal):
    """Reference: a fitted estimator per setting + wsnlib.posture, one movement at a time."""
    mask = setting.mask(data.n_anchors)
    if setting.approach == "deterministic":
        est = KNNFingerprint(n_neighbors=setting.k, metric=setting.metric,
                             power=1 if setting.p_s is None else setting.p_s, anchors=mask)
    else:
        est = ProbabilisticKNN(n_neighbors=setting.k, anchors=mask)
    radio = est.fit(data.training_rss, data.training_positions).predict(data.online_rss)
    chain = ArmChain((data.segment_length_m,), (data.device_offset_m,))
    out = {}
    for m in np.unique(data.movement):
        rows = data.movement == m
        devices = recursive_chain(radio[rows][:, None, :], data.pitch[rows][:, None], chain,
                                  origin=proximal[rows])["devices"][:, 0]
        out[int(m)] = 100 * position_error(devices, data.true_positions[rows]).mean()
    return out


@pytest.mark.parametrize("segment", [0, 1])
def test_search_equals_direct_evaluation(rng, segment):
    if segment == 0:
        data = make_user(rng)
        proximal = np.zeros((data.movement.size, 3))
    else:  # forearm: the proximal joint is an (estimated) elbow that moves
        n = sum((12, 15, 10, 14))
        proximal = rng.normal(0, 0.05, (n, 3)) + np.array([0.0, 0.0, -0.3])
        data = make_user(rng, segment=1, proximal=proximal)
    res = search(data, grid=SMALL)
    settings = [Setting("deterministic", (1, 3, 6), 1, "manhattan"),
                Setting("deterministic", (2, 4), 3, "euclidean", 2),
                Setting("deterministic", (1, 2, 3, 4, 5, 6, 7), 2, "manhattan", 1),
                Setting("probabilistic", (5,), 1), Setting("probabilistic", (2, 5, 7), 2)]
    for setting in settings:
        rows = res[(res["approach"] == setting.approach) & (res["subset"] == setting.subset)
                   & (res["k"] == setting.k)]
        if setting.approach == "deterministic":
            rows = rows[rows["metric"] == setting.metric]
            rows = rows[rows["p_s"].isna()] if setting.p_s is None else rows[rows["p_s"] == setting.p_s]
        got = dict(zip(rows["movement"], rows["pe_cm"], strict=True))
        want = _direct_pe(data, setting, proximal)
        assert got.keys() == want.keys()
        np.testing.assert_allclose([got[m] for m in want], list(want.values()), rtol=0, atol=1e-9)
        # evaluate_setting is the per-sample view of the same numbers
        per_sample = evaluate_setting(data, setting)["pe_m"]
        for m, value in want.items():
            assert per_sample[data.movement == m].mean() * 100 == pytest.approx(value, abs=1e-9)


def test_radio_estimate_scores_the_radio_position(rng):
    data = make_user(rng)
    res = search(data, approaches="deterministic", estimate="radio", grid=SMALL)
    setting = Setting("deterministic", (2, 4, 6), 2, "euclidean", 2)
    radio = KNNFingerprint(n_neighbors=2, power=2, anchors=[1, 3, 5]).fit(
        data.training_rss, data.training_positions).predict(data.online_rss)
    row = res[(res["subset"] == setting.subset) & (res["k"] == 2) & (res["metric"] == "euclidean")
              & (res["p_s"] == 2) & (res["movement"] == 2)]
    want = 100 * position_error(radio, data.true_positions)[data.movement == 2].mean()
    assert row["pe_cm"].item() == pytest.approx(want, abs=1e-9)
    assert (res["estimate"] == "radio").all()


def test_perfect_heading_and_pitch_give_zero_pe(rng):
    """Every fingerprint position on one vertical half-plane: any weighted mean keeps its heading."""
    heading = math.radians(30)
    elevations = np.radians([-60, -20, 10, 40, 75])
    unit = np.stack([np.cos(elevations) * math.cos(heading), np.cos(elevations) * math.sin(heading),
                     np.sin(elevations)], axis=-1)
    fp = 0.15 * unit
    train_rss = np.round(rng.normal(-65, 6, (5 * 30, 7)))
    n = 40
    pitch = np.radians(rng.uniform(-80, 80, n))
    truth = 0.15 * np.stack([np.cos(pitch) * math.cos(heading), np.cos(pitch) * math.sin(heading),
                             np.sin(pitch)], axis=-1)
    data = SearchData(online_rss=np.round(rng.normal(-65, 6, (n, 7))), movement=np.repeat([1, 2], n // 2),
                      true_positions=truth, pitch=pitch, chain=CHAIN, training_rss=train_rss,
                      training_positions=np.repeat(fp, 30, axis=0))
    res = search(data, grid=SearchGrid(powers=(1, 6)))
    assert res["pe_cm"].max() < 1e-9


def test_planted_best_subset_is_found(rng):
    """Only anchors 2 and 5 (1-based) carry position information; the others mislead.

    Four fingerprint positions on a 2 × 2 pattern: anchor 2 tells the column, anchor 5 the
    row, so neither alone suffices; the other anchors have random per-position means in
    training and uniform random online readings.
    """
    positions = np.array([[0.15, 0.0, 0.0], [0.0, 0.15, 0.0], [-0.1, 0.1, 0.05], [0.1, 0.1, -0.05]])
    col, row = np.array([0, 1, 0, 1]), np.array([0, 0, 1, 1])
    n_fp, n_anchors = 4, 7
    informative = np.zeros((n_fp, n_anchors), dtype=bool)
    informative[:, [1, 4]] = True
    users = []
    for _ in range(3):
        means = rng.uniform(-90, -50, (n_fp, n_anchors))
        means[:, 1] = np.where(col == 0, -50.0, -75.0)
        means[:, 4] = np.where(row == 0, -55.0, -80.0)
        train = np.repeat(means, 60, axis=0) + rng.normal(0, 1.0, (n_fp * 60, n_anchors))
        truth_fp = np.repeat(np.arange(n_fp), 15)
        online = np.where(informative[truth_fp], means[truth_fp] + rng.normal(0, 1.0, (truth_fp.size, n_anchors)),
                          rng.uniform(-90, -50, (truth_fp.size, n_anchors)))
        true = positions[truth_fp]
        pitch = np.arcsin(true[:, 2] / np.linalg.norm(true, axis=-1))
        users.append(SearchData(online_rss=np.round(online), movement=truth_fp + 1, true_positions=true, pitch=pitch,
                                chain=CHAIN, training_rss=np.round(train),
                                training_positions=np.repeat(positions, 60, axis=0)))
    grid = SearchGrid(knn_neighbors=(1, 2, 3, 4), powers=(1, 2, 3), pknn_neighbors=(1, 2, 3, 4))
    res = search(users, grid=grid)
    best = select_settings(res, per_movement=False).set_index("approach")
    assert best.loc["deterministic", "subset"] == "{2, 5}"
    assert best.loc["probabilistic", "subset"] == "{2, 5}"
    assert best.loc["deterministic", "pe_cm"] < 1e-9 and best.loc["probabilistic", "pe_cm"] < 1e-9
    # ties at PE 0 (k = 1 with either distance, supersets that also classify right) go to the
    # fewest anchors and the first distance
    assert best.loc["deterministic", "metric"] == "euclidean" and best.loc["deterministic", "k"] == 1
    per_mov = select_settings(res, per_movement=True)
    assert (per_mov["subset"] == "{2, 5}").all()


def test_selection_is_the_argmin_of_the_users_average(users):
    res = search(users, grid=SMALL)
    avg = res.groupby(["approach", "config", "movement"], as_index=False)["pe_cm"].mean()
    table2 = best_per_movement(res)
    for (approach, movement), part in avg.groupby(["approach", "movement"]):
        best = part.sort_values(["pe_cm", "config"]).iloc[0]
        cfg = res[(res["approach"] == approach) & (res["config"] == best["config"])].iloc[0]
        assert table2.loc[movement, (approach, "PE [cm]")] == pytest.approx(best["pe_cm"], abs=1e-9)
        assert table2.loc[movement, (approach, "anchors subset")] == cfg["subset"]
        assert table2.loc[movement, (approach, "N")] == len(cfg["anchors"])
    averaged = average_over_users(res)
    merged = averaged.merge(avg, on=["approach", "config", "movement"], suffixes=("", "_ref"))
    assert len(merged) == len(avg) == len(averaged) and (averaged["n_users"] == 3).all()
    np.testing.assert_allclose(merged["pe_cm"], merged["pe_cm_ref"], rtol=0, atol=1e-12)
    pd.testing.assert_frame_equal(best_global(averaged), best_global(res))  # averaged input works too
    glob = avg.groupby(["approach", "config"], as_index=False)["pe_cm"].mean()
    table3 = best_global(res)
    for approach, part in glob.groupby("approach"):
        best = part.sort_values(["pe_cm", "config"]).iloc[0]
        cfg = res[(res["approach"] == approach) & (res["config"] == best["config"])].iloc[0]
        assert table3.loc["all", (approach, "PE [cm]")] == pytest.approx(best["pe_cm"], abs=1e-9)
        assert table3.loc["all", (approach, "anchors subset")] == cfg["subset"]
    # paper layout: k = 1 shows "—", distances capitalised; p-kNN has no distance column
    assert list(table3["probabilistic"].columns) == ["PE [cm]", "N", "anchors subset", "k"]
    assert list(table3["deterministic"].columns) == ["PE [cm]", "N", "anchors subset", "distance", "k", "p_s"]
    det = best_per_movement(res)["deterministic"]
    assert set(det["distance"]) <= {"Euclidean", "Manhattan"}
    assert all((p == "—") == (k == 1) for p, k in zip(det["p_s"], det["k"], strict=True))


def test_selection_on_averaged_results_and_ties():
    rows = []
    for config, subset, pe in [(0, (1,), 5.0), (1, (2,), 3.0), (2, (1, 2), 3.0), (3, (1, 3), 2.0 + 1e-12)]:
        for movement in (1, 2):
            rows.append({"approach": "probabilistic", "config": config, "subset": format_subset(subset),
                         "anchors": subset, "n_anchors": len(subset), "metric": None, "k": 1,
                         "p_s": pd.NA, "movement": movement,
                         "pe_cm": pe if movement == 1 else (5.0 if config == 0 else 3.0)})
    res = pd.DataFrame(rows)
    res["p_s"] = res["p_s"].astype("Int64")
    t2 = best_per_movement(res)
    assert t2.loc[1, ("probabilistic", "anchors subset")] == "{1, 3}"
    assert t2.loc[2, ("probabilistic", "anchors subset")] == "{2}"  # three-way tie at 3.0: the lowest config
    assert select_settings(res, per_movement=True).loc[1, "config"] == 1


def test_union_of_subsets():
    table3 = pd.DataFrame({("deterministic", "anchors subset"): ["{3, 5, 6, 7}", "{2, 3, 6}"],
                           ("probabilistic", "anchors subset"): ["{6, 7}", "{2, 3, 4, 7}"]})
    assert union_of_subsets(table3) == (2, 3, 5, 6, 7)                    # the paper's example, Sec. 5
    assert union_of_subsets(table3, approach="probabilistic") == (2, 3, 4, 6, 7)
    assert union_of_subsets("{1, 5}", (2, 5), np.array([0, 0, 1], dtype=bool)) == (1, 2, 3, 5)
    assert union_of_subsets(["{1}", "{4}"]) == (1, 4)
    assert format_subset(union_of_subsets(table3)) == "{2, 3, 5, 6, 7}"
    assert parse_subset("{1, 5, 6}") == (1, 5, 6)
    with pytest.raises(ValueError):
        union_of_subsets()
    with pytest.raises(ValueError):
        parse_subset("{0, 1}")


def test_paper_tables_couple_target2_to_target1(rng):
    users1, users2 = [], []
    for _ in range(2):
        u1 = make_user(rng)
        users1.append(u1)
        users2.append(make_user(rng, segment=1, proximal=np.zeros(3)))  # proximal replaced by the elbow
    tables = paper_tables(users1, users2, grid=SMALL)
    assert tables.table2.index.names == ["target", "movement"]
    assert list(tables.table3.index) == ["Target 1", "Target 2"]
    assert tables.table2.shape[0] == 8
    # target 2 of Table 3 = searching target 2 with the elbow of target 1's global setting
    for approach in ("deterministic", "probabilistic"):
        sel1 = tables.selection3[(tables.selection3["target"] == 1) & (tables.selection3["approach"] == approach)]
        setting = Setting.from_row(sel1.iloc[0])
        fitted = [u.fitted() for u in users2]
        elbows = [evaluate_setting(u1, setting)["joints"] for u1 in users1]
        res = search([u.with_proximal(e) for u, e in zip(fitted, elbows, strict=True)], approaches=approach, grid=SMALL)
        want = best_global(res)
        assert tables.table3.loc["Target 2", (approach, "PE [cm]")] == pytest.approx(
            want.loc["all", (approach, "PE [cm]")], abs=1e-9)
        # the elbow lies at the upper-arm length from the shoulder
        np.testing.assert_allclose(np.linalg.norm(elbows[0], axis=-1), CHAIN.segment_lengths_m[0])
    # Table 2's target 2, movement 3: elbow from target 1's best setting for movement 3
    sel = tables.selection2[(tables.selection2["target"] == 1) & (tables.selection2["approach"] == "deterministic")]
    elbow = proximal_from_selection(users1[0], sel)
    rows = users1[0].movement == 3
    setting3 = Setting.from_row(sel.set_index("movement").loc[3].to_dict() | {"approach": "deterministic"})
    np.testing.assert_allclose(elbow[rows], evaluate_setting(users1[0], setting3)["joints"][rows])
    assert set(tables.deployable.columns) == {"Table 2", "Table 3"}
    # the tables' last rows (mean PE over both targets): choosing per movement is never worse
    mean2, mean3 = (sel.groupby("approach")["pe_cm"].mean() for sel in (tables.selection2, tables.selection3))
    assert mean2["deterministic"] <= mean3["deterministic"] + 1e-9


def test_evaluate_chain_equals_the_hand_wired_chain(rng):
    """Target 2 from the elbow of target 1 (eq. (10)), as wired by hand before evaluate_chain."""
    user1 = make_user(rng)
    user2 = make_user(rng, segment=1, proximal=np.zeros(3))
    setting1 = Setting("deterministic", (1, 2, 3), 3, "euclidean", 2)
    setting2 = Setting("probabilistic", (1, 4, 5), 2)
    chain = evaluate_chain(user1, user2, setting1, setting2)
    first = evaluate_setting(user1, setting1)
    second = evaluate_setting(user2.with_proximal(first["joints"]), setting2)
    for key, hand in (("T1", first), ("T2", second)):
        assert set(chain[key]) == {*hand, "radio_pe_m"}
        for name, values in hand.items():
            np.testing.assert_array_equal(chain[key][name], values)
    for key, data, setting in (("T1", user1, setting1), ("T2", user2, setting2)):
        radio = evaluate_setting(data, setting, estimate="radio")
        np.testing.assert_array_equal(chain[key]["radio_pe_m"], radio["pe_m"])
    # The elbow target 2 starts from lies at the upper-arm length from the shoulder.
    np.testing.assert_allclose(np.linalg.norm(chain["T1"]["joints"], axis=-1), CHAIN.segment_lengths_m[0])
    # Target 2 rides on target 1's estimate: another target-1 setting moves target 2's hybrid
    # error but not its radio estimate; selection2 defaults to selection1.
    other = evaluate_chain(user1, user2, Setting("deterministic", (6, 7), 1, "manhattan"), setting2)
    assert np.abs(other["T2"]["pe_m"] - chain["T2"]["pe_m"]).max() > 1e-3
    np.testing.assert_array_equal(other["T2"]["radio"], chain["T2"]["radio"])
    same = evaluate_chain(user1, user2, setting1)
    np.testing.assert_array_equal(same["T2"]["pe_m"],
                                  evaluate_setting(user2.with_proximal(first["joints"]), setting1)["pe_m"])
    with pytest.raises(ValueError, match="same online rows"):
        evaluate_chain(user1, make_user(rng, segment=1, samples=(3, 3, 3, 3)), setting1)
    with pytest.raises(ValueError, match="target2 must be a SearchData"):
        evaluate_chain(user1, None, setting1)


def _fake_results(pe):
    """A search()-like table from PEs (C, M, U), probabilistic settings with one anchor each."""
    n_config, n_mov, n_user = pe.shape
    c, m, u = np.meshgrid(np.arange(n_config), np.arange(n_mov), np.arange(n_user), indexing="ij")
    res = pd.DataFrame({"approach": "probabilistic", "config": c.ravel(), "movement": m.ravel() + 1,
                        "user": u.ravel() + 1, "pe_cm": pe.ravel(), "metric": None, "k": 1, "n_anchors": 1})
    res["anchors"] = [(int(i) + 1,) for i in res["config"]]
    res["subset"] = [format_subset(a) for a in res["anchors"]]
    res["p_s"] = pd.array([pd.NA] * len(res), dtype="Int64")
    return res


def test_determinism(rng):
    u = make_user(rng)
    a = search([u, u], grid=SMALL)
    b = search([u, u], grid=SMALL)
    pd.testing.assert_frame_equal(a, b)


def test_chunking_does_not_change_results(users):
    a = search(users, grid=SMALL)
    b = search(users, grid=SMALL, chunk_elements=1)
    pd.testing.assert_frame_equal(a, b, check_exact=True)  # same bits: subset sums in a fixed order


def test_fitted_estimators_are_used_as_given(rng):
    u = make_user(rng)
    knn = KNNFingerprint(metric="manhattan", n_neighbors=2).fit(u.training_rss, u.training_positions)
    pknn = ProbabilisticKNN(pmf="parzen").fit(u.training_rss, u.training_positions)
    bare = SearchData(u.online_rss, u.movement, u.true_positions, u.pitch, CHAIN, knn=knn, pknn=pknn)
    assert bare.fitted().knn is knn
    res_given = search(bare, grid=SMALL)
    res_fit = search(u, grid=SMALL)
    det = res_given["approach"] == "deterministic"
    np.testing.assert_allclose(res_given.loc[det, "pe_cm"], res_fit.loc[det, "pe_cm"])
    assert not np.allclose(res_given.loc[~det, "pe_cm"], res_fit.loc[~det, "pe_cm"])  # parzen ≠ histogram
    template = SearchData(u.online_rss, u.movement, u.true_positions, u.pitch, CHAIN,
                          training_rss=u.training_rss, training_positions=u.training_positions,
                          pknn=ProbabilisticKNN(pmf="parzen"))
    res_template = search(template, approaches="probabilistic", grid=SMALL)
    np.testing.assert_allclose(res_template["pe_cm"], res_given.loc[~det, "pe_cm"])


def test_undefined_heading_is_held_within_a_movement():
    """k = 1 onto P1 (straight below the shoulder): the heading is held, and reset per movement."""
    positions = np.array([[0.0, 0.0, -0.15], [0.15, 0.0, 0.0], [0.0, 0.15, 0.0]])
    radio_map = np.array([[-50.0, -80.0], [-80.0, -50.0], [-65.0, -65.0]])
    online = np.array([[-80, -50], [-50, -80], [-50, -80], [-65, -65], [-50, -80]], dtype=float)
    movement = np.array([1, 1, 1, 2, 2])
    pitch = np.full(5, -0.3)
    data = SearchData(online, movement, np.zeros((5, 3)), pitch, CHAIN,
                      training_rss=radio_map, training_positions=positions)
    out = evaluate_setting(data, Setting("deterministic", (1, 2), 1, "euclidean"))
    heading = np.arctan2(out["devices"][:, 1], out["devices"][:, 0])
    np.testing.assert_allclose(heading, [0, 0, 0, math.pi / 2, math.pi / 2], atol=1e-12)
    out2 = evaluate_setting(data.with_proximal(np.zeros(3)), Setting("deterministic", (1, 2), 1, "euclidean"))
    np.testing.assert_allclose(out["devices"], out2["devices"])
    # movement 2 row 0 is P3 (defined), row 1 holds it; a movement starting on P1 would get ψ = 0
    data_b = SearchData(online[[1, 0, 3, 4]], np.array([1, 1, 2, 2]), np.zeros((4, 3)), pitch[:4], CHAIN,
                        training_rss=radio_map, training_positions=positions)
    out_b = evaluate_setting(data_b, Setting("deterministic", (1, 2), 1, "euclidean"))
    heading_b = np.arctan2(out_b["devices"][:, 1], out_b["devices"][:, 0])
    np.testing.assert_allclose(heading_b, [0, 0, math.pi / 2, math.pi / 2], atol=1e-12)
    res = search(data_b, approaches="deterministic", grid=SearchGrid(knn_neighbors=(1,), metrics=("euclidean",)))
    row = res[(res["subset"] == "{1, 2}") & (res["movement"] == 2)]
    assert row["pe_cm"].item() == pytest.approx(100 * out_b["pe_m"][2:].mean(), abs=1e-9)


def test_progress_bar(users, capsys):
    search(users[:1], grid=SMALL, progress=True)
    assert "subset chunks" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"approaches": "bayesian"}, "approach"),
        ({"approaches": ()}, "at least one"),
        ({"estimate": "kalman"}, "estimate"),
        ({"grid": "paper"}, "SearchGrid"),
    ],
)
def test_search_argument_errors(users, kwargs, match):
    with pytest.raises(ValueError, match=match):
        search(users, **kwargs)


def test_grid_errors():
    with pytest.raises(ValueError, match="empty grid"):
        SearchGrid(knn_neighbors=())
    with pytest.raises(ValueError, match="empty grid"):
        SearchGrid(metrics=())
    with pytest.raises(ValueError, match="empty grid"):
        SearchGrid(powers=())
    with pytest.raises(ValueError, match="metrics"):
        SearchGrid(metrics=("cosine",))
    with pytest.raises(ValueError, match="positive"):
        SearchGrid(powers=(0,))
    with pytest.raises(ValueError, match="no anchor"):
        SearchGrid(subsets=np.array([[True, False], [False, False]]))
    grid = SearchGrid(subsets=np.array([[True, True, False], [False, True, False]]))
    assert grid.subset_masks(3)[0].tolist() == [False, True, False]  # reordered: fewest anchors first
    with pytest.raises(ValueError, match="anchors"):
        grid.subset_masks(4)


def test_k_larger_than_fingerprints_raises(users):
    with pytest.raises(ValueError, match="only 5 fingerprint positions"):
        search(users, grid=SearchGrid(knn_neighbors=(1, 6)))


def test_search_data_shape_errors(rng):
    u = make_user(rng)
    n = u.movement.size
    base = dict(online_rss=u.online_rss, movement=u.movement, true_positions=u.true_positions, pitch=u.pitch,
                chain=CHAIN, training_rss=u.training_rss, training_positions=u.training_positions)
    bad = [
        ({"movement": u.movement[:-1]}, "movement"),
        ({"movement": u.movement + 0.5}, "integer"),
        ({"true_positions": u.true_positions[:, :2]}, "true_positions"),
        ({"true_positions": u.true_positions[:-1]}, "true_positions"),
        ({"pitch": u.pitch[:-1]}, "pitch"),
        ({"pitch": u.pitch + 4.0}, "pi/2"),
        ({"proximal": np.zeros((n + 1, 3))}, "proximal"),
        ({"online_rss": u.online_rss[:, 0]}, "online_rss"),
        ({"training_rss": u.training_rss[:, :3]}, "training_rss"),
        ({"training_positions": None}, "both"),
        ({"segment": 2}, "segment"),
        ({"chain": (0.3, 0.15)}, "ArmChain"),
        ({"knn": ProbabilisticKNN()}, "KNNFingerprint"),
    ]
    for change, match in bad:
        with pytest.raises(ValueError, match=match):
            SearchData(**(base | change))
    no_training = SearchData(**(base | {"training_rss": None, "training_positions": None}))
    with pytest.raises(ValueError, match="training"):
        search(no_training, grid=SMALL)
    with pytest.raises(ValueError, match="same number of anchors"):
        search([u, make_user(rng, n_anchors=5)], grid=SMALL)
    with pytest.raises(ValueError, match="no user"):
        search([], grid=SMALL)
    with pytest.raises(ValueError, match="NaN"):
        search(SearchData(**(base | {"online_rss": np.where(u.online_rss > -60, np.nan, u.online_rss)})))


def test_selection_and_setting_errors():
    with pytest.raises(ValueError, match="DataFrame"):
        best_global([1, 2])
    with pytest.raises(ValueError, match="lacks"):
        best_per_movement(pd.DataFrame({"pe_cm": [1.0]}))
    with pytest.raises(ValueError, match="metric"):
        Setting("deterministic", (1,), 2, None, 1)
    with pytest.raises(ValueError, match="p_s"):
        Setting("deterministic", (1,), 2, "euclidean")
    with pytest.raises(ValueError, match="approach"):
        Setting("bayes", (1,), 1)
    assert Setting("deterministic", (1,), 1, "euclidean", 3).p_s is None


# --- selection regret with swapped folds, and target 2 without the leak ----------------------


def test_regret_is_nonnegative_per_fold_on_a_planted_example():
    """Settings equal up to noise: choosing on one half cannot beat the other half's own best."""
    rng = np.random.default_rng(17)
    pe = 10.0 + rng.normal(0.0, 2.0, (300, 8, 5))
    pe[:, 4:] += 1.5                     # the second repetition is harder: an unswapped gap misleads
    res = _fake_results(pe)
    units = selection_regret(res, by_unit=True)
    per_fold = units.groupby(["split", "selection", "fold"])["regret_cm"].mean()
    assert (per_fold >= -1e-12).all()
    assert len(per_fold) == 2 * 2 + 5 * 2            # two swapped repetition folds, five held-out users
    summary = selection_regret(res).loc["probabilistic"]
    assert list(summary.columns) == ["in_sample_cm", "out_of_sample_cm", "oracle_cm", "regret_cm", "regret_se_cm",
                                     "optimism_cm", "optimism_se_cm", "n_folds", "n_units"]
    assert (summary["regret_cm"] > 0.5).all()       # pure noise: choosing is all luck
    assert (summary["regret_se_cm"] > 0).all() and (summary["n_units"] == 5).all()
    rep = summary.loc["repetition"]
    # Swapped folds: mean in-sample = mean oracle, so optimism = regret (>= 0) ...
    np.testing.assert_allclose(rep["optimism_cm"], rep["regret_cm"], atol=1e-9)
    # ... while one unswapped fold is off by the halves' difficulty.
    unswapped = units[(units["split"] == "repetition") & (units["fold"] == "select on movements {1, 2, 3, 4}")]
    assert (unswapped.groupby("selection")["optimism_cm"].mean() > rep["optimism_cm"] + 1.0).all()
    # Hand check of one fold: global rule, select on movements 5-8, score on 1-4.
    mean = pe.mean(axis=2)
    pick, oracle = np.argmin(mean[:, 4:].mean(axis=1)), np.argmin(mean[:, :4].mean(axis=1))
    fold = units[(units["split"] == "repetition") & (units["selection"] == "global")
                 & (units["fold"] == "select on movements {5, 6, 7, 8}")]
    np.testing.assert_allclose(fold["out_of_sample_cm"], pe[pick, :4].mean(axis=0))
    np.testing.assert_allclose(fold["regret_cm"], pe[pick, :4].mean(axis=0) - pe[oracle, :4].mean(axis=0))
    np.testing.assert_allclose(fold["in_sample_cm"], pe[pick, 4:].mean(axis=0))


def test_regret_is_small_when_one_setting_is_truly_best():
    rng = np.random.default_rng(18)
    pe = 10.0 + rng.normal(0.0, 0.5, (300, 8, 5))
    pe[42] -= 3.0
    summary = selection_regret(_fake_results(pe))
    assert (summary["regret_cm"].abs() < 1e-9).all()  # every fold picks 42, the test data's best too
    assert (summary["out_of_sample_cm"] < 7.8).all()


def test_regret_bad_input():
    res = _fake_results(np.ones((3, 8, 2)))
    with pytest.raises(ValueError, match="splits"):
        selection_regret(res, splits=("bootstrap",))
    with pytest.raises(ValueError, match="overlap"):
        selection_regret(res, first=(1, 2), second=(2, 3))
    with pytest.raises(ValueError, match="no movement"):
        selection_regret(res, first=(1,), second=(9,))
    with pytest.raises(ValueError, match="at least 2 users"):
        selection_regret(_fake_results(np.ones((3, 8, 1))), splits="leave-one-user-out")


def test_coupled_regret_takes_target2_elbow_from_the_selection_half(rng):
    """Target 1's choice depends on the half; target 2's held-out figures must use that choice."""
    users1, users2 = [], []
    for _ in range(2):
        maps = rng.normal(-65.0, 10.0, size=(5, 7))
        users1.append(make_user(rng, samples=(10,) * 8, noise_db=6.0, repeat_after=4, radio_map=maps))
        users2.append(make_user(rng, samples=(10,) * 8, noise_db=6.0, repeat_after=4, segment=1,
                                proximal=np.zeros(3)))
    tables = paper_tables(users1, users2, grid=SMALL, approaches="deterministic")
    res1 = tables.target1
    units = coupled_selection_regret(users1, users2, grid=SMALL, approaches="deterministic", splits="repetition",
                                     results1=res1, by_unit=True)
    # Target 1's global choice on movements 1-4 differs from the choice on all data (the leak's source).
    first_half = select_settings(res1[res1["movement"] <= 4], per_movement=False).iloc[0]
    on_all = tables.selection3[tables.selection3["target"] == 1].iloc[0]
    assert first_half["config"] != on_all["config"]
    # Rebuild the fold by hand: elbow from target 1's first-half choice, search target 2, select on 1-4.
    setting = Setting.from_row(first_half)
    elbows = [evaluate_setting(u, setting)["joints"] for u in users1]
    res2 = search([u.with_proximal(e) for u, e in zip(users2, elbows, strict=True)], grid=SMALL,
                  approaches="deterministic")
    pick = select_settings(res2[res2["movement"] <= 4], per_movement=False).iloc[0]
    second = res2[(res2["movement"] >= 5) & (res2["config"] == pick["config"])]
    want = second.groupby("user")["pe_cm"].mean().to_numpy()
    got = units[(units["target"] == 2) & (units["selection"] == "global")
                & (units["fold"] == "select on movements {1, 2, 3, 4}")].sort_values("unit")
    np.testing.assert_allclose(got["out_of_sample_cm"], want, atol=1e-9)
    # The leaky version (elbow from the all-data choice) gives other numbers.
    leaky = tables.target2_global
    leaky_pick = select_settings(leaky[leaky["movement"] <= 4], per_movement=False).iloc[0]
    leaky_out = leaky[(leaky["movement"] >= 5) & (leaky["config"] == leaky_pick["config"])]
    assert not np.allclose(leaky_out.groupby("user")["pe_cm"].mean().to_numpy(), want)
    # Regret >= 0 per fold for both targets; summary has both targets.
    per_fold = units.groupby(["target", "selection", "fold"])["regret_cm"].mean()
    assert (per_fold >= -1e-9).all()
    summary = coupled_selection_regret(users1, users2, grid=SMALL, approaches="deterministic",
                                       splits="repetition", results1=res1)
    assert summary.index.names == ["target", "approach", "split", "selection"]
    assert set(summary.index.get_level_values("target")) == {1, 2}
    # Without results1 the target-1 search is done here, with the same outcome.
    pd.testing.assert_frame_equal(summary, coupled_selection_regret(
        users1, users2, grid=SMALL, approaches="deterministic", splits="repetition"))
    mov_units = units[(units["target"] == 2) & (units["selection"] == "per_movement")]
    assert len(mov_units) == 2 * 2
