"""PABR loader: parsing (on a small hand-written copy of the format and on the shared subset),
invalid-RSSI dropping, vector building, errors.

The shared subset is read from ``$WSNLIB_PABR_DIR`` or ``../shared/data/pabr`` next to the
checkout; the tests needing it skip without it.
"""

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wsnlib import pabr, paths
from wsnlib.fingerprint import KNNFingerprint

SOURCE_DIR = Path(os.environ.get(pabr.PABR_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "pabr")
HAVE_SHARED = (SOURCE_DIR / "cnf" / "tetam.dev").is_file() and (SOURCE_DIR / "hst" / "set_1").is_dir()
needs_shared = pytest.mark.skipif(not HAVE_SHARED, reason=f"PABR subset not found in {SOURCE_DIR}")

DEV = (
    'Dongles:{"aa0000000001": [[1.00, 2.00, 1.22], 1, "sensor10"], '
    '"aa0000000002": [[3.50, 4.25, 2.30], 2, "sensor11"], "aa0000000003": [[0.0, 9.0, 2.3], 3, "sensor12"]}\n'
    'Beacons:{"bb0000000000": [[], 4, "beacon1"] }\n'
)
MACS = {"sensor10": "aa0000000001", "sensor11": "aa0000000002", "sensor12": "aa0000000003"}


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
        pabr.load_pabr_receivers(tmp_path / "nowhere")
    assert "nowhere" in str(info.value)
    (tiny / "cnf" / "tetam.dev").unlink()
    with pytest.raises(FileNotFoundError, match=r"tetam\.dev.*WSNLIB_PABR_DIR"):
        pabr.load_pabr_fingerprints("set_1", tiny)


def test_missing_set_and_bad_arguments(tiny):
    with pytest.raises(FileNotFoundError, match="hst/set_2"):
        pabr.load_pabr_fingerprints("set_2", tiny)
    with pytest.raises(ValueError, match="set_name"):
        pabr.load_pabr_fingerprints("set_3", tiny)
    with pytest.raises(ValueError, match="unknown PABR track"):
        pabr.load_pabr_tracks("nope", tiny)


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
    assert vec.receivers == ("sensor10", "sensor11", "sensor12")
    np.testing.assert_allclose(vec.rss, [[-71.0, -80.5, np.nan], [-61.0, np.nan, -51.0]])
    np.testing.assert_array_equal(vec.counts, [[2, 2, 0], [2, 0, 2]])
    np.testing.assert_allclose(vec.positions, [[0.16, 2.19, 1.85], [10.36, 0.28, 1.85]])
    np.testing.assert_array_equal(vec.groups, [0, 1])
    np.testing.assert_array_equal(vec.windows, [0, 0])
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
    np.testing.assert_allclose(vec.positions[:, 0], [1.1, 1.4, 1.8])
    np.testing.assert_allclose(vec.times, [10.2, 11.2, 12.1])
    np.testing.assert_array_equal(vec.windows, [0, 1, 2])
    assert list(vec.groups) == ["walk"] * 3
    wide = pabr.pabr_vectors(tr, window_s=5.0, fill=-100.0)
    np.testing.assert_allclose(wide.rss, [[-71.0, -80.0, -90.0]])
    np.testing.assert_array_equal(wide.counts, [[2, 1, 1]])


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
    assert empty.rss.shape == (0, 3) and empty.positions.shape == (0, 3)


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
        assert fp.attrs["n_packets_read"] == n_points * 12 * 600  # truncated to 600 packets per file
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
    assert vec.rss.shape[1] == 12 and np.all(np.diff(vec.times) > 0)


@needs_shared
def test_shared_knn_sanity(shared):
    train = pabr.pabr_vectors(shared["set_1"], window_packets=10)
    test = pabr.pabr_vectors(shared["set_2"], window_packets=10, fill=-100.0, min_receivers=12)
    assert train.rss.shape[1] == 12 and not np.isnan(test.rss).any()
    est = KNNFingerprint(n_neighbors=3).fit(train.rss, train.positions)
    err = np.linalg.norm(est.predict(test.rss) - test.positions, axis=1)
    assert np.median(err) < 4.0  # 20 m x 18 m area; a year between the two sets
    assert isinstance(shared["set_1"], pd.DataFrame)
