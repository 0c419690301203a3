"""PABR loader: parsing (on a small hand-written copy of the format and on the shared subset),
invalid-RSSI dropping, vector building, errors.

The shared subset is read from ``$WSNLIB_PABR_DIR`` or ``../shared/data/pabr`` next to the
checkout; the tests needing it skip without it.
"""

import hashlib
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pooch
import pytest

from wsnlib import paths
from wsnlib.io import download, pabr
from wsnlib.radio import KNNFingerprint

SOURCE_DIR = Path(os.environ.get(pabr.PABR_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "pabr")
HAVE_SHARED = (SOURCE_DIR / "cnf" / "tetam.dev").is_file() and (SOURCE_DIR / "hst" / "set_1").is_dir()
needs_shared = pytest.mark.skipif(not HAVE_SHARED, reason=f"PABR subset not found in {SOURCE_DIR}")

DEV = (
    'Dongles:{"aa0000000001": [[1.00, 2.00, 1.22], 1, "sensor10"], '
    '"aa0000000002": [[3.50, 4.25, 2.30], 2, "sensor11"], "aa0000000003": [[0.0, 9.0, 2.3], 3, "sensor12"]}\n'
    'Beacons:{"bb0000000000": [[], 4, "beacon1"] }\n'
)
MACS = {"sensor10": "aa0000000001", "sensor11": "aa0000000002", "sensor12": "aa0000000003"}


@pytest.fixture(autouse=True)
def no_network(monkeypatch):
    """pooch's HTTP downloader fails loudly here: tests inject their downloader or pass download=False."""

    def refuse(self, url, output_file, pooch_instance, check_only=False):
        raise AssertionError(f"a test tried to download {url}")

    monkeypatch.setattr(pooch.HTTPDownloader, "__call__", refuse)


def _hst(sensor, rssi, t0=100.0):
    return "".join(f"{t0 + 0.5 * i:.9f},{MACS[sensor]},bb0000000000,{r}\n" for i, r in enumerate(rssi))


def _trk_line(t, sensor, rssi, xyz):
    rot = ",".join(["0.0"] * 9)
    return f"{t},{MACS[sensor]},bb0000000000,{rssi},{xyz[0]},{xyz[1]},{xyz[2]},{rot}\n"


@pytest.fixture
def tiny(tmp_path):
    """A three-receiver copy of the dataset's layout with known contents."""
    root = tmp_path / "pabr"
    (root / "cnf").mkdir(parents=True)
    (root / "cnf" / "tetam.dev").write_text(DEV)
    hst = root / "hst" / "set_1"
    hst.mkdir(parents=True)
    # point (0.16, 2.19, 1.85): 4 packets at sensor10 (one invalid: +4), 3 at sensor11
    (hst / "sensor10_0.16_2.19_1.85.mbd").write_text(_hst("sensor10", [-70, -72, 4, -74]))
    (hst / "sensor11_0.16_2.19_1.85.mbd").write_text(_hst("sensor11", [-80, -81, -82]))
    # point (10.36, 0.28, 1.85): sensor10 one packet below -100 (invalid), no trailing newline
    (hst / "sensor10_10.36_0.28_1.85.mbd").write_text(_hst("sensor10", [-60, -101, -62]).rstrip("\n"))
    (hst / "sensor12_10.36_0.28_1.85.mbd").write_text(_hst("sensor12", [-50, -52]))
    trk = root / "trk"
    trk.mkdir()
    lines = [
        _trk_line(10.0, "sensor10", -70, (1.0, 2.0, 1.8)),
        _trk_line(10.4, "sensor11", -80, (1.2, 2.0, 1.8)),
        _trk_line(11.2, "sensor10", -72, (1.4, 2.0, 1.8)),
        _trk_line(11.5, "sensor12", 62, (1.6, 2.0, 1.8)),  # invalid
        _trk_line(12.1, "sensor12", -90, (1.8, 2.0, 1.8)),
    ]
    (trk / "walk_all_sensors.mbd").write_text("".join(lines))
    (trk / "other_all_sensors.mbd").write_text(_trk_line(1.0, "sensor11", -55, (0.0, 0.0, 1.0)))
    (trk / "README.md").write_text("not a track")
    return root


# ------------------------------------------------------------------ folder resolution and errors


def test_folder_resolution(tmp_path, monkeypatch):
    monkeypatch.delenv(pabr.PABR_DIR_ENV_VAR, raising=False)
    assert pabr.pabr_dir() == paths.ROOT / "data" / "raw" / "pabr"
    monkeypatch.setenv(pabr.PABR_DIR_ENV_VAR, str(tmp_path / "env"))
    assert pabr.pabr_dir() == tmp_path / "env"
    assert pabr.pabr_dir(tmp_path / "arg") == tmp_path / "arg"


def test_missing_folder_and_files_name_what_is_missing(tmp_path, tiny):
    with pytest.raises(FileNotFoundError, match="WSNLIB_PABR_DIR") as info:
        pabr.load_pabr_receivers(tmp_path / "nowhere", download=False)
    assert "nowhere" in str(info.value)
    (tiny / "cnf" / "tetam.dev").unlink()
    with pytest.raises(FileNotFoundError, match=r"tetam\.dev.*WSNLIB_PABR_DIR"):
        pabr.load_pabr_fingerprints("set_1", tiny, download=False)


def test_missing_set_and_bad_arguments(tiny):
    with pytest.raises(FileNotFoundError, match="hst/set_2"):
        pabr.load_pabr_fingerprints("set_2", tiny, download=False)
    with pytest.raises(ValueError, match="set_name"):
        pabr.load_pabr_fingerprints("set_3", tiny)
    with pytest.raises(ValueError, match="unknown PABR track"):
        pabr.load_pabr_tracks("nope", tiny)
    with pytest.raises(ValueError, match="common_span_packets"):
        pabr.load_pabr_fingerprints("set_1", tiny, common_span_packets=0)


def test_bad_file_name_and_mac_mismatch(tiny):
    bad = tiny / "hst" / "set_1" / "sensor10_oops.mbd"
    bad.write_text(_hst("sensor10", [-70]))
    with pytest.raises(ValueError, match="sensor10_oops"):
        pabr.load_pabr_fingerprints("set_1", tiny)
    bad.unlink()
    (tiny / "hst" / "set_1" / "sensor12_1.0_1.0_1.0.mbd").write_text(_hst("sensor11", [-70]))
    with pytest.raises(ValueError, match="sensor12.*aa0000000002"):
        pabr.load_pabr_fingerprints("set_1", tiny)


# ------------------------------------------------------------------ parsing (hand-written copy)


def test_receivers(tiny):
    rec = pabr.load_pabr_receivers(tiny)
    assert list(rec["receiver"]) == ["sensor10", "sensor11", "sensor12"]
    assert list(rec["mac"]) == list(MACS.values())
    np.testing.assert_allclose(rec[["x", "y", "z"]].to_numpy()[1], [3.5, 4.25, 2.3])
    assert rec.attrs["beacon"] == {"mac": "bb0000000000", "alias": "beacon1"}


def test_fingerprints_parsed_and_invalid_dropped(tiny):
    fp = pabr.load_pabr_fingerprints("set_1", tiny)
    assert list(fp.columns) == ["point", "x", "y", "z", "receiver", "timestamp", "rssi"]
    assert fp.attrs["n_packets_read"] == 12
    assert fp.attrs["n_dropped_invalid_rssi"] == 2
    assert len(fp) == 10 and fp.attrs["n_points"] == 2
    assert fp["rssi"].between(-100, 0).all()
    p0 = fp[fp["point"] == 0]
    np.testing.assert_allclose(p0[["x", "y", "z"]].drop_duplicates().to_numpy(), [[0.16, 2.19, 1.85]])
    assert p0.groupby("receiver", observed=False).size().to_dict() == {"sensor10": 3, "sensor11": 3, "sensor12": 0}
    p1 = fp[fp["point"] == 1]
    np.testing.assert_allclose(p1[["x", "y", "z"]].iloc[0], [10.36, 0.28, 1.85])
    assert sorted(p1["rssi"]) == [-62.0, -60.0, -52.0, -50.0]
    assert list(fp["receiver"].cat.categories) == ["sensor10", "sensor11", "sensor12"]
    np.testing.assert_allclose(p0[p0["receiver"] == "sensor10"]["timestamp"], [100.0, 100.5, 101.5])


def test_tracks_parsed_and_invalid_dropped(tiny):
    assert pabr.pabr_track_names(tiny) == ["other", "walk"]
    tr = pabr.load_pabr_tracks(data_dir=tiny)
    assert list(tr.columns) == ["track", "timestamp", "receiver", "rssi", "x", "y", "z"]
    assert tr.attrs["n_packets_read"] == 6 and tr.attrs["n_dropped_invalid_rssi"] == 1
    walk = tr[tr["track"] == "walk"]
    assert list(walk["receiver"]) == ["sensor10", "sensor11", "sensor10", "sensor12"]
    np.testing.assert_allclose(walk["x"], [1.0, 1.2, 1.4, 1.8])
    one = pabr.load_pabr_tracks("walk", tiny)
    assert len(one) == 4 and list(one["track"].cat.categories) == ["walk"]


# ------------------------------------------------------------------ vectors


def test_vectors_by_packet_blocks(tiny):
    fp = pabr.load_pabr_fingerprints("set_1", tiny)
    vec = pabr.pabr_vectors(fp, window_packets=2)
    # point 0: sensor10 (-70, -72, -74) -> one block of 2; sensor11 (-80, -81, -82) -> one block
    # point 1: sensor10 (-60, -62) -> one block; sensor12 (-50, -52) -> one block
    assert vec.anchors == ("sensor10", "sensor11", "sensor12")
    np.testing.assert_allclose(vec.rss, [[-71.0, -80.5, np.nan], [-61.0, np.nan, -51.0]])
    np.testing.assert_array_equal(vec.n_readings, [[2, 2, 0], [2, 0, 2]])
    np.testing.assert_allclose(vec.position, [[0.16, 2.19, 1.85], [10.36, 0.28, 1.85]])
    np.testing.assert_array_equal(vec.label, [0, 1])
    np.testing.assert_array_equal(vec.window, [0, 0])
    assert len(vec) == 2
    ones = pabr.pabr_vectors(fp, window_packets=1, fill=-100.0)
    np.testing.assert_allclose(ones.rss[:3, 0], [-70.0, -72.0, -74.0])
    np.testing.assert_allclose(ones.rss[:3, 2], -100.0)
    assert not np.isnan(ones.rss).any()
    complete = pabr.pabr_vectors(fp, window_packets=1, min_receivers=2)
    assert len(complete) == 5  # 3 at point 0, 2 at point 1


def test_vectors_by_time_windows_on_a_track(tiny):
    tr = pabr.load_pabr_tracks("walk", tiny)
    vec = pabr.pabr_vectors(tr, window_s=1.0)
    # packets at 10.0 (s10), 10.4 (s11) | 11.2 (s10) | 12.1 (s12); the invalid one at 11.5 is gone
    np.testing.assert_allclose(vec.rss, [[-70.0, -80.0, np.nan], [-72.0, np.nan, np.nan], [np.nan, np.nan, -90.0]])
    np.testing.assert_allclose(vec.position[:, 0], [1.1, 1.4, 1.8])
    np.testing.assert_allclose(vec.time_s, [10.4, 11.2, 12.1])  # the window's last packet: when it is available
    np.testing.assert_array_equal(vec.window, [0, 1, 2])
    assert list(vec.label) == ["walk"] * 3
    wide = pabr.pabr_vectors(tr, window_s=5.0, fill=-100.0)
    np.testing.assert_allclose(wide.rss, [[-71.0, -80.0, -90.0]])
    np.testing.assert_array_equal(wide.n_readings, [[2, 1, 1]])


def test_vectors_errors(tiny):
    fp = pabr.load_pabr_fingerprints("set_1", tiny)
    with pytest.raises(ValueError, match="exactly one"):
        pabr.pabr_vectors(fp)
    with pytest.raises(ValueError, match="exactly one"):
        pabr.pabr_vectors(fp, window_s=1.0, window_packets=3)
    with pytest.raises(ValueError, match="window_s"):
        pabr.pabr_vectors(fp, window_s=0.0)
    with pytest.raises(ValueError, match="window_packets"):
        pabr.pabr_vectors(fp, window_packets=0)
    with pytest.raises(ValueError, match="min_receivers"):
        pabr.pabr_vectors(fp, window_packets=1, min_receivers=0)
    with pytest.raises(ValueError, match="lacks the column"):
        pabr.pabr_vectors(fp.drop(columns="rssi"), window_packets=1)
    empty = pabr.pabr_vectors(fp, window_packets=10)
    assert empty.rss.shape == (0, 3) and empty.position.shape == (0, 3)


# ------------------------------------------------------------------ the shared subset


@pytest.fixture(scope="module")
def shared():
    if not HAVE_SHARED:
        pytest.skip(f"PABR subset not found in {SOURCE_DIR}")
    return {name: pabr.load_pabr_fingerprints(name, SOURCE_DIR) for name in ("set_1", "set_2")}


@needs_shared
def test_shared_receivers_and_counts(shared):
    rec = pabr.load_pabr_receivers(SOURCE_DIR)
    assert len(rec) == 12 and rec["receiver"].iloc[0] == "sensor10"
    np.testing.assert_allclose(
        rec.loc[rec["receiver"] == "sensor32", ["x", "y", "z"]].to_numpy()[0], [18.12, 11.93, 2.3]
    )
    for name, n_points in (("set_1", 81), ("set_2", 45)):
        fp = shared[name]
        assert fp["point"].nunique() == n_points == fp.attrs["n_points"]
        # SUBSET.md: every receiver's file of a point is cut at the instant the first of them reached
        # its 600th packet: per point, the longest file has exactly 600 lines, every file at least one
        lines = pd.Series({f.name: len(f.read_bytes().splitlines()) for f in (SOURCE_DIR / "hst" / name).glob("*.mbd")})
        per_point = lines.groupby(lines.index.str.split("_", n=1).str[1])
        assert len(lines) == n_points * 12 and per_point.size().eq(12).all()
        assert per_point.max().eq(pabr.SUBSET_SPAN_PACKETS).all() and lines.min() >= 1
        assert fp.attrs["n_packets_read"] == lines.sum()
        # ... so cutting it again to the 600-packet common span changes nothing
        recut = pabr.load_pabr_fingerprints(name, SOURCE_DIR, common_span_packets=pabr.SUBSET_SPAN_PACKETS)
        pd.testing.assert_frame_equal(recut, fp)
        assert fp.attrs["n_dropped_invalid_rssi"] > 0
        assert len(fp) == fp.attrs["n_packets_read"] - fp.attrs["n_dropped_invalid_rssi"]
        assert fp["rssi"].between(-100, 0).all()
        assert fp["z"].between(1.5, 2.5).all()  # beacon height (m)


@needs_shared
def test_shared_tracks():
    names = pabr.pabr_track_names(SOURCE_DIR)
    assert len(names) == 9 and "straight_01" in names
    tr = pabr.load_pabr_tracks("straight_04", SOURCE_DIR)
    assert len(tr) + tr.attrs["n_dropped_invalid_rssi"] == tr.attrs["n_packets_read"] > 500
    assert tr["x"].between(0, 21).all() and tr["y"].between(0, 18).all()
    vec = pabr.pabr_vectors(tr, window_s=2.0)
    assert vec.rss.shape[1] == 12 and np.all(np.diff(vec.time_s) > 0)


@needs_shared
def test_shared_knn_sanity(shared):
    train = pabr.pabr_vectors(shared["set_1"], window_packets=10)
    test = pabr.pabr_vectors(shared["set_2"], window_packets=10, fill=-100.0, min_receivers=12)
    assert train.rss.shape[1] == 12 and not np.isnan(test.rss).any()
    est = KNNFingerprint(n_neighbors=3).fit(train.rss, train.position)
    err = np.linalg.norm(est.predict(test.rss) - test.position, axis=1)
    assert np.median(err) < 4.0  # 20 m x 18 m area; a year between the two sets
    assert isinstance(shared["set_1"], pd.DataFrame)


# ------------------------------------------------------------------ strict parsing: file and line named


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("101.5,aa0000000001,bb0000000000,abc", r"line 2: rssi is 'abc', not a number"),
        ("101.5,aa0000000001,bb0000000000,nan", r"line 2: rssi is nan \(not a finite number"),
        ("101.5,aa0000000001,bb0000000000,-inf", r"line 2: rssi is -inf \(not a finite number"),
        ("oops,aa0000000001,bb0000000000,-70", r"line 2: timestamp is 'oops', not a number"),
        ("101.5,aa0000000001,bb0000000000", r"line 2: 3 comma-separated fields, expected 4"),
        ("101.5,aa0000000001,bb0000000000,-70,5", r"line 2: 5 comma-separated fields, expected 4"),
        ("101.5,aa0000000001,bb0000000000,", r"line 2: rssi is '', not a number"),
    ],
)
def test_fingerprint_parse_errors_name_file_and_line(tiny, line, message):
    path = tiny / "hst" / "set_1" / "sensor11_0.16_2.19_1.85.mbd"
    lines = path.read_text().splitlines()
    lines[1] = line
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=re.escape(str(path)) + ", " + message):
        pabr.load_pabr_fingerprints("set_1", tiny, download=False)


def test_track_parse_errors_name_file_and_line(tiny):
    path = tiny / "trk" / "walk_all_sensors.mbd"
    lines = path.read_text().splitlines()
    lines[2] = lines[2].replace(",1.4,", ",NaN,", 1)  # the x coordinate of the third packet
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=re.escape(str(path)) + r", line 3: x is NaN"):
        pabr.load_pabr_tracks("walk", tiny)
    lines[2] = lines[2].replace(MACS["sensor10"], "cc0000000009")
    lines[2] = lines[2].replace(",NaN,", ",1.4,")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=re.escape(str(path)) + r", line 3: packet of unknown receiver MAC"):
        pabr.load_pabr_tracks("walk", tiny)


def test_mac_mismatch_names_file_and_line(tiny):
    path = tiny / "hst" / "set_1" / "sensor10_0.16_2.19_1.85.mbd"
    lines = path.read_text().splitlines()
    lines[3] = lines[3].replace(MACS["sensor10"], MACS["sensor11"])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=re.escape(str(path)) + r", line 4: file of sensor10 holds a packet"):
        pabr.load_pabr_fingerprints("set_1", tiny, download=False)


def test_receiver_without_any_file_is_an_error(tiny):
    (tiny / "hst" / "set_1" / "sensor12_10.36_0.28_1.85.mbd").unlink()
    with pytest.raises(ValueError, match=r"no file of receiver\(s\) \['sensor12'\]"):
        pabr.load_pabr_fingerprints("set_1", tiny, download=False)


def test_receiver_unheard_in_the_tracks_is_a_warning(tiny):
    with pytest.warns(UserWarning, match=r"\['sensor10', 'sensor12'\].*heard no valid packet"):
        other = pabr.load_pabr_tracks("other", tiny)
    assert len(other) == 1


def test_common_span_cut(tiny):
    hst = tiny / "hst" / "set_1"
    # point (0.16, 2.19, 1.85): sensor10 every 0.5 s from 100.0 s, sensor11 every 0.5 s from 100.2 s
    (hst / "sensor10_0.16_2.19_1.85.mbd").write_text(_hst("sensor10", [-70, -71, -72, -73, -74]))
    (hst / "sensor11_0.16_2.19_1.85.mbd").write_text(_hst("sensor11", [-80, -81, -82, -83], t0=100.2))
    full = pabr.load_pabr_fingerprints("set_1", tiny, download=False)
    cut = pabr.load_pabr_fingerprints("set_1", tiny, common_span_packets=2, download=False)
    p0 = cut[cut["point"] == 0]
    # sensor10 reaches its 2nd packet at 100.5 s, first of the two: the cut is at 100.5 s (inclusive)
    assert p0.groupby("receiver", observed=True)["rssi"].apply(list).to_dict() == {
        "sensor10": [-70.0, -71.0], "sensor11": [-80.0]
    }
    # point (10.36, 0.28, 1.85): sensor10 (100.0, 100.5 invalid, 101.0), sensor12 (100.0, 100.5): cut at 100.5 s
    p1 = cut[cut["point"] == 1]
    assert sorted(p1["rssi"]) == [-60.0, -52.0, -50.0]
    assert cut.attrs["n_packets_read"] == 7 and full.attrs["n_packets_read"] == 14
    again = pabr.load_pabr_fingerprints("set_1", tiny, common_span_packets=100, download=False)
    pd.testing.assert_frame_equal(again, full)


# ------------------------------------------------------------------ issue 13: positions and missing readings


def test_vectors_of_a_point_share_its_exact_position(tiny):
    """Bug (a): the float mean of a point's positions made one point several fingerprints."""
    hst = tiny / "hst" / "set_1"
    for f in hst.glob("*.mbd"):
        f.unlink()
    # point (0.19, 0.7, 1.85): sensor10 hears 7 packets in the first second, 3 in the next; sensor11 1 and 1
    times10 = [100.0 + 0.1 * i for i in range(7)] + [101.0, 101.3, 101.6]
    (hst / "sensor10_0.19_0.7_1.85.mbd").write_text(
        "".join(f"{t:.9f},{MACS['sensor10']},bb0000000000,-70\n" for t in times10)
    )
    (hst / "sensor11_0.19_0.7_1.85.mbd").write_text(_hst("sensor11", [-80, -81], t0=100.05))
    (hst / "sensor12_0.19_0.7_1.85.mbd").write_text(_hst("sensor12", [-90], t0=100.05))
    fp = pabr.load_pabr_fingerprints("set_1", tiny, download=False)
    vec = pabr.pabr_vectors(fp, window_s=1.0)
    assert len(vec) == 2
    np.testing.assert_array_equal(vec.position, [[0.19, 0.7, 1.85]] * 2)  # exact, not 0.18999999999999997
    est = KNNFingerprint(n_neighbors=1).fit(vec.rss, vec.position)
    assert est.positions_.shape == (1, 3)  # one fingerprint per point
    # tracks keep the mean ground truth of the window's packets
    tr = pabr.load_pabr_tracks("walk", tiny)
    np.testing.assert_allclose(pabr.pabr_vectors(tr, window_s=1.0).position[0], [1.1, 2.0, 1.8])


def test_training_map_leaves_missing_readings_out(tiny):
    """Bug (b): a window without a packet of a receiver is missing, not a -100 dBm reading."""
    hst = tiny / "hst" / "set_1"
    # point 0: sensor11 hears only in the first of three 1-s windows
    (hst / "sensor10_0.16_2.19_1.85.mbd").write_text(_hst("sensor10", [-70, -70, -72, -72, -74, -74]))
    (hst / "sensor11_0.16_2.19_1.85.mbd").write_text(_hst("sensor11", [-80, -82]))
    fp = pabr.load_pabr_fingerprints("set_1", tiny, download=False)
    train = pabr.pabr_vectors(fp, window_s=1.0)
    assert np.isnan(train.rss[1:3, 1]).all()  # windows 1 and 2 of point 0: sensor11 missing
    est = KNNFingerprint(n_neighbors=1).fit(train.rss, train.position)
    point0 = np.flatnonzero(np.all(est.positions_ == [0.16, 2.19, 1.85], axis=1))[0]
    np.testing.assert_allclose(est.radio_map_[point0, :2], [-72.0, -81.0])  # not (-81 - 200) / 3
    np.testing.assert_array_equal(est.n_readings_[point0, :2], [3, 1])
    # window="point": one vector per point, each receiver's mean over all its packets
    per_point = pabr.pabr_vectors(fp, window="point")
    np.testing.assert_allclose(per_point.rss, [[-72.0, -81.0, np.nan], [-61.0, np.nan, -51.0]])
    np.testing.assert_array_equal(per_point.n_readings, [[6, 2, 0], [2, 0, 2]])
    np.testing.assert_array_equal(per_point.window, [0, 0])
    np.testing.assert_array_equal(per_point.position, [[0.16, 2.19, 1.85], [10.36, 0.28, 1.85]])
    with pytest.raises(ValueError, match="exactly one"):
        pabr.pabr_vectors(fp, window="point", window_s=1.0)
    with pytest.raises(ValueError, match="window must be 'point'"):
        pabr.pabr_vectors(fp, window="track")
    with pytest.raises(ValueError, match="window must be 'point'"):
        pabr.pabr_vectors(pabr.load_pabr_tracks("walk", tiny), window="point")


@needs_shared
def test_shared_map_has_one_fingerprint_per_point(shared):
    train = pabr.pabr_vectors(shared["set_1"], window_packets=10)
    assert np.isnan(train.rss).any()  # missing stays missing in a training map
    est = KNNFingerprint(n_neighbors=3).fit(train.rss, train.position)
    assert est.positions_.shape == (81, 3)
    per_point = pabr.pabr_vectors(shared["set_1"], window="point")
    assert len(per_point) == 81 and not np.isnan(per_point.rss).any()


# ------------------------------------------------------------------ download (injected downloader, no network)


class CopyDownloader:
    """Stands in for pooch's downloader: copies ``<source>/<path in the URL after the commit>``."""

    def __init__(self, source: Path, corrupt: bool = False):
        self.source, self.corrupt, self.urls = source, corrupt, []

    def __call__(self, url, output_file, pooch_instance):
        self.urls.append(url)
        relative = url.split(f"/{pabr.PABR_COMMIT}/", 1)[1]
        data = (self.source / relative).read_bytes()
        Path(output_file).write_bytes(data + b"x" if self.corrupt else data)


@pytest.fixture
def tiny_registry(tiny, monkeypatch):
    """The registry pointed at the tiny copy's files (their SHA-256), as if it were the dataset."""
    (tiny / "LICENSE.md").write_text("CC0\n")
    registry = {
        f.relative_to(tiny).as_posix(): download.RegistryEntry(sha256=hashlib.sha256(f.read_bytes()).hexdigest())
        for f in tiny.rglob("*")
        if f.is_file() and f.name != "README.md"
    }
    monkeypatch.setattr(pabr, "PABR_REGISTRY", registry)
    return registry


def test_download_of_a_missing_folder(tmp_path, tiny, tiny_registry, monkeypatch):
    folder = tmp_path / "fresh" / "pabr"
    monkeypatch.setenv(pabr.PABR_DIR_ENV_VAR, str(folder))
    fake = CopyDownloader(tiny)
    fp = pabr.load_pabr_fingerprints("set_1", downloader=fake)
    pd.testing.assert_frame_equal(fp, pabr.load_pabr_fingerprints("set_1", tiny, download=False))
    base = f"https://raw.githubusercontent.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset/{pabr.PABR_COMMIT}/"
    expected = ["cnf/tetam.dev", "LICENSE.md"] + sorted(n for n in tiny_registry if n.startswith("hst/set_1/"))
    assert fake.urls == [base + name for name in expected]
    tracks = pabr.load_pabr_tracks(downloader=fake)
    assert list(tracks["track"].cat.categories) == ["other", "walk"]
    assert sorted(p.name for p in (folder / "trk").iterdir()) == ["other_all_sensors.mbd", "walk_all_sensors.mbd"]
    n_urls = len(fake.urls)
    pabr.load_pabr_fingerprints("set_1", downloader=fake)  # present now: nothing downloaded again
    pabr.load_pabr_tracks(downloader=fake)
    assert len(fake.urls) == n_urls


def test_download_of_one_missing_track(tmp_path, tiny, tiny_registry):
    folder = tmp_path / "partial"
    shutil.copytree(tiny / "cnf", folder / "cnf")
    (folder / "trk").mkdir()
    shutil.copy(tiny / "trk" / "other_all_sensors.mbd", folder / "trk")
    fake = CopyDownloader(tiny)
    walk = pabr.load_pabr_tracks("walk", folder, downloader=fake)
    assert len(walk) == 4 and [u.rsplit("/", 2)[-2:] for u in fake.urls] == [["trk", "walk_all_sensors.mbd"]]


def test_download_failing_the_hash_check_keeps_nothing(tmp_path, tiny, tiny_registry):
    folder = tmp_path / "fresh"
    with pytest.raises(ValueError, match=r"tetam\.dev.*failed the hash check"):
        pabr.load_pabr_receivers(folder, downloader=CopyDownloader(tiny, corrupt=True))
    assert not folder.exists()  # nor the folders made for the download
    with pytest.raises(ValueError, match="unknown PABR file"):
        pabr.pabr_file("hst/set_3/x.mbd", folder)


def test_without_download_a_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"cnf/tetam\.dev.*WSNLIB_PABR_DIR"):
        pabr.pabr_file("cnf/tetam.dev", tmp_path, download=False)
    with pytest.raises(AssertionError, match="tried to download"):  # the default goes to pooch's HTTP downloader
        pabr.pabr_file("cnf/tetam.dev", tmp_path)


def test_registry_lists_the_full_dataset():
    names = list(pabr.PABR_REGISTRY)
    assert set(names[:2]) == {"LICENSE.md", "cnf/tetam.dev"}
    assert sum(n.startswith("hst/set_1/") for n in names) == 81 * 12
    assert sum(n.startswith("hst/set_2/") for n in names) == 45 * 12
    assert sum(n.startswith("trk/") and n.endswith("_all_sensors.mbd") for n in names) == 9
    assert len(names) == 2 + 81 * 12 + 45 * 12 + 9
    assert all(re.fullmatch(r"[0-9a-f]{64}", e.sha256) and e.size_bytes > 0 for e in pabr.PABR_REGISTRY.values())


@needs_shared
def test_registry_matches_the_shared_full_files(tmp_path):
    """The shared copy's device file, licence and tracks are the full files: the registry verifies them."""
    full = ["LICENSE.md", "cnf/tetam.dev"] + [f"trk/{p.name}" for p in (SOURCE_DIR / "trk").glob("*_all_sensors.mbd")]
    assert len(full) == 11
    for name in full:
        data = (SOURCE_DIR / name).read_bytes()
        entry = pabr.PABR_REGISTRY[name]
        assert hashlib.sha256(data).hexdigest() == entry.sha256 and len(data) == entry.size_bytes, name
    fake = CopyDownloader(SOURCE_DIR)
    downloaded = pabr.load_pabr_tracks("straight_04", tmp_path, downloader=fake)  # verified by the real registry
    pd.testing.assert_frame_equal(downloaded, pabr.load_pabr_tracks("straight_04", SOURCE_DIR))


# ------------------------------------------------------------------ files a copy or a conversion got wrong (issue 23)


def test_empty_file_is_named(tiny):
    (tiny / "hst" / "set_1" / "sensor12_0.16_2.19_1.85.mbd").write_bytes(b"")
    with pytest.raises(ValueError, match=r"sensor12_0\.16_2\.19_1\.85\.mbd: the file is empty"):
        pabr.load_pabr_fingerprints("set_1", tiny)
    (tiny / "trk" / "walk_all_sensors.mbd").write_bytes(b"")
    with pytest.raises(ValueError, match=r"walk_all_sensors\.mbd: the file is empty"):
        pabr.load_pabr_tracks("walk", tiny)


def test_timestamps_in_milliseconds_are_refused(tiny):
    path = tiny / "hst" / "set_1" / "sensor11_0.16_2.19_1.85.mbd"
    path.write_text(_hst("sensor11", [-80, -81], t0=1569304545701.0))
    with pytest.raises(ValueError, match=r"sensor11_0\.16_2\.19_1\.85\.mbd, line 1: timestamp .*milliseconds"):
        pabr.load_pabr_fingerprints("set_1", tiny)
    (tiny / "trk" / "walk_all_sensors.mbd").write_text(_trk_line(1581249601408.7, "sensor10", -70, (1, 2, 1.8)))
    with pytest.raises(ValueError, match=r"walk_all_sensors\.mbd, line 1: timestamp .*milliseconds"):
        pabr.load_pabr_tracks("walk", tiny)


def test_positions_in_centimetres_are_refused(tiny):
    (tiny / "hst" / "set_1" / "sensor12_1036_28_185.mbd").write_text(_hst("sensor12", [-50]))
    with pytest.raises(ValueError, match=r"sensor12_1036_28_185\.mbd, line 1: reference point position .* not cm"):
        pabr.load_pabr_fingerprints("set_1", tiny)
    lines = _trk_line(10.0, "sensor10", -70, (100.0, 200.0, 180.0)) + _trk_line(10.4, "sensor11", -80, (120, 200, 180))
    (tiny / "trk" / "walk_all_sensors.mbd").write_text(lines)
    with pytest.raises(ValueError, match=r"walk_all_sensors\.mbd, line 1: ground-truth position .* not cm"):
        pabr.load_pabr_tracks("walk", tiny)


def test_a_packet_stored_twice_counts_once(tiny):
    walk = tiny / "trk" / "walk_all_sensors.mbd"
    first = walk.read_text().splitlines(keepends=True)[0]
    walk.write_text(walk.read_text() + first)
    with pytest.warns(UserWarning, match="dropped 1 of 6 packets that repeat an earlier line"):
        tr = pabr.load_pabr_tracks("walk", tiny)
    assert len(tr) == 4 and tr.attrs["n_dropped_repeated"] == 1 and tr.attrs["n_packets_read"] == 6
    path = tiny / "hst" / "set_1" / "sensor11_0.16_2.19_1.85.mbd"
    path.write_text(path.read_text() + path.read_text().splitlines(keepends=True)[-1])
    with pytest.warns(UserWarning, match="dropped 1 of 13 packets"):
        fp = pabr.load_pabr_fingerprints("set_1", tiny)
    assert (fp["receiver"] == "sensor11").sum() == 3 and fp.attrs["n_dropped_repeated"] == 1


def test_a_shuffled_track_is_returned_in_time_order(tiny):
    walk = tiny / "trk" / "walk_all_sensors.mbd"
    lines = walk.read_text().splitlines(keepends=True)
    walk.write_text("".join(lines[::-1]))
    tr = pabr.load_pabr_tracks("walk", tiny)
    np.testing.assert_array_equal(tr["timestamp"], [10.0, 10.4, 11.2, 12.1])
    assert list(tr["receiver"]) == ["sensor10", "sensor11", "sensor10", "sensor12"]


# ------------------------------------------------------------------ same-day split and moving vectors


def test_time_split_cuts_each_point_at_the_middle_of_its_span(tiny):
    fp = pabr.load_pabr_fingerprints("set_1", tiny)
    early, late = pabr.pabr_time_split(fp)
    assert len(early) + len(late) == len(fp)
    # point 0 spans 100.0-101.5 s (cut at 100.75), point 1 100.0-101.0 s (cut at 100.5)
    assert sorted(early.loc[early["point"] == 0, "timestamp"]) == [100.0, 100.0, 100.5, 100.5]
    assert sorted(late.loc[late["point"] == 1, "timestamp"]) == [100.5, 101.0]
    assert early.attrs["set_name"] == "set_1"
    tr = pabr.load_pabr_tracks("walk", tiny)
    first, second = pabr.pabr_time_split(tr, fraction=0.25)      # 10.0-12.1 s: cut at 10.525
    np.testing.assert_allclose(first["timestamp"], [10.0, 10.4])
    with pytest.raises(ValueError, match="fraction"):
        pabr.pabr_time_split(fp, fraction=1.0)
    with pytest.raises(ValueError, match="lacks the column"):
        pabr.pabr_time_split(fp.drop(columns="timestamp"))


def test_vector_motion_of_packet_blocks_and_time_windows(tiny):
    tr = pabr.load_pabr_tracks("walk", tiny)
    blocks = pabr.pabr_vectors(tr, window_packets=1)
    # block 0: the first packet of each receiver, 10.0 (x = 1.0) to 12.1 s (x = 1.8); block 1: s10 at 11.2 alone
    motion = pabr.pabr_vector_motion(tr, blocks)
    np.testing.assert_allclose(motion["span_s"], [2.1, 0.0])
    np.testing.assert_allclose(motion["moved_m"], [0.8, 0.0], atol=1e-12)
    windows = pabr.pabr_vectors(tr, window_s=1.0)
    np.testing.assert_allclose(pabr.pabr_vector_motion(tr, windows)["span_s"], [0.4, 0.0, 0.0])
    with pytest.warns(UserWarning, match="heard no valid packet"):
        other = pabr.load_pabr_tracks("other", tiny)
    with pytest.raises(ValueError, match="not in tracks"):
        pabr.pabr_vector_motion(other, blocks)
