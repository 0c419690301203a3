"""The one RSS vector type and the one windowing function (issue 13): the simulated/CSV path
(wsnlib.io.rss.rss_vectors) and the PABR path (wsnlib.io.pabr.pabr_vectors) give the same type
with the same meaning, and a missing reading stays missing in both."""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from wsnlib.io import pabr as pabr_io
from wsnlib.io import rss as rss_io
from wsnlib.io.vectors import READING_COLUMNS, RssVectors, window_readings
from wsnlib.radio import KNNFingerprint

ANCHORS = ("A1", "A2", "A3")

# One point at (0.19, 0.7, 1.85) held 3 s: A1 reads every 0.5 s, A2 only in the first second,
# A3 never.  Then another point at (1.0, 0.0, 0.0) for 1 s, heard by A1 and A3.
READINGS = [  # (time_s, point, anchor, rss_dbm, x)
    *[(0.5 * i, "P1", "A1", -60 - (i % 2), 0.19) for i in range(6)],
    (0.0, "P1", "A2", -80, 0.19),
    (0.5, "P1", "A2", -82, 0.19),
    (3.0, "P2", "A1", -50, 1.0),
    (3.0, "P2", "A3", -70, 1.0),
    (3.5, "P2", "A1", -52, 1.0),
]


def simulated_table() -> pd.DataFrame:
    """READINGS as the long RSS table of the simulator / CSV format (one stream U1/s/T1)."""
    rows = sorted(READINGS, key=lambda r: (r[0], ANCHORS.index(r[2])))
    return pd.DataFrame({
        "time_s": [r[0] for r in rows], "user": "U1", "session": "s", "target": "T1",
        "anchor": [r[2] for r in rows], "rss_dbm": np.array([r[3] for r in rows], dtype=np.int64),
        "label": [r[1] for r in rows], "x_m": [r[4] for r in rows],
        "y_m": [0.7 if r[1] == "P1" else 0.0 for r in rows], "z_m": [1.85 if r[1] == "P1" else 0.0 for r in rows],
    })


def pabr_table() -> pd.DataFrame:
    """READINGS as a load_pabr_fingerprints table (points numbered 0, 1)."""
    return pd.DataFrame({
        "point": [0 if r[1] == "P1" else 1 for r in READINGS],
        "x": [r[4] for r in READINGS],
        "y": [0.7 if r[1] == "P1" else 0.0 for r in READINGS],
        "z": [1.85 if r[1] == "P1" else 0.0 for r in READINGS],
        "receiver": pd.Categorical([r[2] for r in READINGS], categories=list(ANCHORS)),
        "timestamp": [r[0] for r in READINGS],
        "rssi": [float(r[3]) for r in READINGS],
    })


def both(**window):
    return (rss_io.rss_vectors(simulated_table(), anchors=ANCHORS, **window),
            pabr_io.pabr_vectors(pabr_table(), **window))


def test_both_paths_give_the_one_type():
    simulated, pabr = both(window_s=1.0)
    assert type(simulated) is RssVectors and type(pabr) is RssVectors
    assert simulated.anchors == pabr.anchors == ANCHORS
    names = [f.name for f in dataclasses.fields(RssVectors)]
    assert names == ["rss", "n_readings", "time_s", "first_time_s", "position", "label", "target", "session", "user",
                     "window", "n_packets", "anchors"]


@pytest.mark.parametrize("window", [{"window_s": 1.0}, {"window": "point"}])
def test_both_paths_cut_the_same_windows(window):
    simulated, pabr = both(**window)
    np.testing.assert_array_equal(simulated.rss, pabr.rss)
    np.testing.assert_array_equal(simulated.n_readings, pabr.n_readings)
    np.testing.assert_array_equal(simulated.position, pabr.position)
    np.testing.assert_array_equal(simulated.time_s, pabr.time_s)
    np.testing.assert_array_equal(simulated.first_time_s, pabr.first_time_s)
    np.testing.assert_array_equal(simulated.window, pabr.window)
    assert list(pabr.label) == [0] * (len(pabr) - 1) + [1]  # the point's label (old name: groups)
    assert list(simulated.label) == ["P1"] * (len(simulated) - 1) + ["P2"]


def test_windows_by_time_and_per_point():
    simulated, _ = both(window_s=1.0)
    # P1: [0, 1) A1 -60, -61 and A2 -80, -82; [1, 2) A1 only; [2, 3) A1 only; P2: one window
    np.testing.assert_array_equal(simulated.rss, [[-60.5, -81.0, np.nan], [-60.5, np.nan, np.nan],
                                                  [-60.5, np.nan, np.nan], [-51.0, np.nan, -70.0]])
    np.testing.assert_array_equal(simulated.n_readings, [[2, 2, 0], [2, 0, 0], [2, 0, 0], [2, 0, 1]])
    np.testing.assert_array_equal(simulated.window, [0, 1, 2, 0])
    np.testing.assert_array_equal(simulated.time_s, [0.5, 1.5, 2.5, 3.5])  # the window's last reading
    np.testing.assert_array_equal(simulated.first_time_s, [0.0, 1.0, 2.0, 3.0])  # and its first
    point, _ = both(window="point")
    np.testing.assert_array_equal(point.rss, [[-60.5, -81.0, np.nan], [-51.0, np.nan, -70.0]])


def test_missing_receiver_is_missing_not_minus_100_in_both_paths():
    """Bug (b) of issue 13, in both paths: a window without a reading of an anchor is NaN, so
    the training map's cell is the mean of the readings received, not dragged to -100 dBm."""
    for vectors in both(window_s=1.0):
        assert np.isnan(vectors.rss[1:3, 1]).all() and (vectors.n_readings[1:3, 1] == 0).all()
        model = KNNFingerprint(n_neighbors=1).fit(vectors.rss, vectors.position)
        assert model.positions_.shape == (2, 3)  # one fingerprint per point (bug (a))
        np.testing.assert_array_equal(model.positions_[0], [0.19, 0.7, 1.85])  # exact
        np.testing.assert_array_equal(model.radio_map_[0, :2], [-60.5, -81.0])  # not (-81 - 200) / 3
        np.testing.assert_array_equal(model.n_readings_[0], [3, 1, 0])  # vectors with a value


@pytest.mark.parametrize("fill", ["last", "floor", -100.0])
def test_fill_means_the_same_in_both_paths(fill):
    simulated = rss_io.rss_vectors(simulated_table(), anchors=ANCHORS, window_s=1.0, fill=fill, floor_dbm=-99.0)
    pabr = pabr_io.pabr_vectors(pabr_table(), window_s=1.0, fill=fill, floor_dbm=-99.0)
    np.testing.assert_array_equal(simulated.rss[:3], pabr.rss[:3])  # point P1
    assert not np.isnan(pabr.rss).any() and not np.isnan(simulated.rss).any()
    np.testing.assert_array_equal(pabr.n_readings[1], [2, 0, 0])  # counts what was received
    level = -100.0 if fill == -100.0 else -99.0
    if fill == "last":  # A2 carried forward within the stream (user, session, target); A3 never heard
        np.testing.assert_array_equal(pabr.rss[1], [-60.5, -81.0, level])
        # the simulated session goes on from P1 to P2, each PABR point is its own recording
        assert simulated.rss[3, 1] == -81.0 and pabr.rss[3, 1] == level
    else:
        np.testing.assert_array_equal(pabr.rss[1], [-60.5, level, level])
        np.testing.assert_array_equal(simulated.rss, pabr.rss)


def test_a_label_that_returns_is_another_point():
    table = simulated_table()
    later = table[table["label"] == "P1"].assign(time_s=lambda t: t["time_s"] + 10.0)
    vectors = rss_io.rss_vectors(pd.concat([table, later], ignore_index=True), anchors=ANCHORS, window="point")
    assert list(vectors.label) == ["P1", "P2", "P1"]
    np.testing.assert_array_equal(vectors.rss[0], vectors.rss[2])


def test_packet_windows_keep_or_drop_the_short_last_block():
    # simulated: packets are transmissions (A1 and A2 at 0.0 and 0.5 are 2 packets, not 4)
    simulated = rss_io.rss_vectors(simulated_table(), 4, anchors=ANCHORS)
    np.testing.assert_array_equal(simulated.n_packets, [4, 2, 2])  # P1: 6 packets -> 4 + 2; P2: 2
    np.testing.assert_array_equal(simulated.rss[0], [-60.5, -81.0, np.nan])
    # PABR: each receiver's own blocks of 4 readings; incomplete blocks are dropped
    pabr = pabr_io.pabr_vectors(pabr_table(), window_packets=4)
    np.testing.assert_array_equal(pabr.rss, [[-60.5, np.nan, np.nan]])


def test_map_key_and_select():
    vectors = both(window_s=1.0)[1]
    with pytest.raises(dataclasses.FrozenInstanceError):
        vectors.position = np.zeros((len(vectors), 3))
    np.testing.assert_array_equal(vectors.map_key, ["PABR/beacon"] * len(vectors))
    assert len(vectors.select(label=1)) == 1


def test_window_readings_errors():
    readings = simulated_table()[list(READING_COLUMNS)]
    with pytest.raises(ValueError, match="exactly one"):
        window_readings(readings, ANCHORS)
    with pytest.raises(ValueError, match="exactly one"):
        window_readings(readings, ANCHORS, window_s=1.0, window="point")
    with pytest.raises(ValueError, match="window_s"):
        window_readings(readings, ANCHORS, window_s=-1.0)
    with pytest.raises(ValueError, match="window must be 'point'"):
        window_readings(readings, ANCHORS, window="hour")
    with pytest.raises(ValueError, match="fill"):
        window_readings(readings, ANCHORS, window_s=1.0, fill="mean")
    with pytest.raises(ValueError, match="floor_dbm"):
        window_readings(readings, ANCHORS, window_s=1.0, fill="last")
    with pytest.raises(ValueError, match="fill must be a finite"):
        window_readings(readings, ANCHORS, window_s=1.0, fill=float("nan"))
    with pytest.raises(ValueError, match="min_anchors"):
        window_readings(readings, ANCHORS, window_s=1.0, min_anchors=0)
    with pytest.raises(ValueError, match="lacks the column"):
        window_readings(readings.drop(columns="label"), ANCHORS, window_s=1.0)
    with pytest.raises(ValueError, match=r"anchor\(s\) \['A3'\] not in anchors"):
        window_readings(readings, ANCHORS[:2], window_s=1.0)
    with pytest.raises(ValueError, match="'time_s' must hold finite"):
        window_readings(readings.assign(time_s=np.nan), ANCHORS, window_s=1.0)
    empty = window_readings(readings.iloc[:0], ANCHORS, window_s=1.0)
    assert len(empty) == 0 and empty.rss.shape == (0, 3) and empty.position.shape == (0, 3)
