"""The PABR checks of notebook 06 (wsnlib.studies.pabr_fingerprinting) on small hand-made tables."""

import numpy as np
import pandas as pd
import pytest

from wsnlib import metrics
from wsnlib.io.pabr import pabr_vectors
from wsnlib.radio import KNNFingerprint, ProbabilisticKNN
from wsnlib.studies import pabr_fingerprinting as study

RECEIVERS = ["r1", "r2"]


def fingerprints(readings):
    """A load_pabr_fingerprints-like table from ``{point: (position, {receiver: [rssi, ...]})}``, 1 packet/s."""
    rows = [(point, *position, receiver, 100.0 + i, float(value))
            for point, (position, per_receiver) in readings.items()
            for receiver, values in per_receiver.items() for i, value in enumerate(values)]
    table = pd.DataFrame(rows, columns=["point", "x", "y", "z", "receiver", "timestamp", "rssi"])
    table["receiver"] = pd.Categorical(table["receiver"], categories=RECEIVERS)
    return table


def track(packets):
    """A load_pabr_tracks-like table from ``[(time, receiver, rssi, x), ...]`` (y = z = 0)."""
    table = pd.DataFrame([("walk", t, r, float(v), x, 0.0, 0.0) for t, r, v, x in packets],
                         columns=["track", "timestamp", "receiver", "rssi", "x", "y", "z"])
    table["receiver"] = pd.Categorical(table["receiver"], categories=RECEIVERS)
    table["track"] = pd.Categorical(table["track"])
    return table


# Two points 1 m apart, each receiver loud near "its" point.
MAP = fingerprints({0: ((0.0, 0.0, 0.0), {"r1": [-50] * 4, "r2": [-80] * 4}),
                    1: ((1.0, 0.0, 0.0), {"r1": [-80] * 4, "r2": [-50] * 4})})


def test_score_models_scores_every_vector_with_every_model():
    radio_map = pabr_vectors(MAP, window="point")
    models = {"NN": KNNFingerprint(1).fit(radio_map.rss, radio_map.position),
              "p-NN": ProbabilisticKNN(1).fit(radio_map.rss, radio_map.position)}
    online = pabr_vectors(MAP, window_packets=2, fill="last")
    scores = study.score_models(models, online, test="same")
    assert list(scores.columns) == ["test", "estimator", "unit", "error_m"]
    assert len(scores) == 2 * len(online) and list(scores["estimator"].unique()) == ["NN", "p-NN"]
    np.testing.assert_array_equal(scores["unit"].unique(), ["0", "1"])
    np.testing.assert_array_equal(scores["error_m"], 0.0)


def test_online_gap_treatments():
    # r2 (loud near point 1) misses windows 1 and 2; the beacon is at x = 0.2 m, then at point 1.
    packets = [(0.1, "r1", -65, 0.2), (0.2, "r2", -50, 0.2),   # complete: (-65, -50), nearer point 1
               (1.1, "r1", -70, 0.2),                          # r1 alone is nearer point 1 (-80 vs -50)
               (2.1, "r1", -65, 0.2),                          # r1 alone is halfway: a tie, to point 0
               (3.1, "r1", -80, 1.0), (3.2, "r2", -50, 1.0)]   # complete, at point 1
    radio_map = pabr_vectors(MAP, window="point")
    models = {"NN": KNNFingerprint(1).fit(radio_map.rss, radio_map.position)}
    errors = study.online_gap_errors(models, track(packets), [1.0])
    assert list(errors["treatment"].unique()) == list(study.ONLINE_TREATMENTS)
    incomplete = errors.groupby("treatment", sort=False)["incomplete"].apply(list)
    assert incomplete.tolist() == [[False, True, True, False]] * 3
    error = errors.groupby("treatment", sort=False)["error_m"].apply(list)
    # not heard: (-70, -100) and (-65, -100) are nearer point 0; the last reading (-50) puts both at
    # point 1; left out, -70 alone is nearer point 1 and -65 alone ties (lower index: point 0).
    np.testing.assert_allclose(error["not heard"], [0.8, 0.2, 0.2, 0.0])
    np.testing.assert_allclose(error["last reading"], [0.8, 0.8, 0.8, 0.0])
    np.testing.assert_allclose(error["left out"], [0.8, 0.8, 0.2, 0.0])


def test_pmf_source_decides_what_a_single_packet_matches():
    # At point 0 the receiver alternates -60/-70 (2-packet means: -65); at point 1 it reads -65.
    table = fingerprints({0: ((0.0, 0.0, 0.0), {"r1": [-60, -70] * 20, "r2": [-90] * 40}),
                          1: ((1.0, 0.0, 0.0), {"r1": [-65] * 40, "r2": [-90] * 40})})
    errors = study.pmf_source_errors({"p-NN": ProbabilisticKNN(1, pmf="histogram")}, {"same": (table, table)},
                                     pmf_packets=(1, 2), windows=(1, 2))
    assert set(errors.columns) == {"test", "pmf_packets", "window", "estimator", "unit", "error_m"}
    mean = errors.groupby(["pmf_packets", "window"])["error_m"].mean()
    assert mean[(1, 1)] == 0.0        # single-packet PMFs tell -60/-70 from -65
    assert mean[(2, 1)] > 0.2         # PMFs of 2-packet means put point 0 at -65 only
    assert mean[(2, 2)] > 0.2         # ... where point 1 is too: a tie, to the lower index
    vectors = pabr_vectors(table, window_packets=1, fill="last")
    model = ProbabilisticKNN(1).fit(*(lambda v: (v.rss, v.position))(pabr_vectors(table, window_packets=2)))
    np.testing.assert_allclose(errors.query("pmf_packets == 2 and window == 1")["error_m"],
                               metrics.position_error(model.predict(vectors.rss), vectors.position))


def test_compare_on_units():
    rng = np.random.default_rng(0)
    units = [str(u) for u in range(10)]
    base = rng.uniform(1.0, 2.0, size=10)
    errors = pd.DataFrame({"unit": units * 3, "estimator": ["a"] * 10 + ["b"] * 10 + ["c"] * 10,
                           "error_m": np.concatenate([base, base + 0.5, base + 1e-9])})
    worse = study.compare_on_units(errors, "b", "a", rng=rng, n_boot=500)
    assert worse.verdict == "higher" and worse.difference == pytest.approx(0.5) and worse.n_units == 10
    assert study.compare_on_units(errors, "a", "b", rng=rng, n_boot=500).verdict == "lower"
    assert study.compare_on_units(errors, "a", "c", rng=rng, n_boot=500).verdict == "tie"   # within 1 mm
    assert study.compare_on_units(errors, "a", "c", rng=rng, n_boot=500, resolution_m=0.0).verdict == "lower"
    with pytest.raises(ValueError, match="no rows"):
        study.compare_on_units(errors, "a", "d", rng=rng)
