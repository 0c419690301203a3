import json

import numpy as np
import pandas as pd
import pytest

from wsnlib import testbed as T
from wsnlib.io import rss as RSS
from wsnlib.io.sidecar import sidecar_path
from wsnlib.sim import arm_motion as M
from wsnlib.sim import body as B
from wsnlib.sim import radio as R


@pytest.fixture(scope="module")
def table():
    rng = np.random.default_rng(21)
    user = B.make_users(1, rng=rng)[0]
    motion = M.concatenate([M.hold("P1", 2.0), M.movement("raise_P1_P3", 2.0), M.hold("P3", 2.0)])
    a = R.simulate_rss(motion, user, rng=rng, session="training")
    b = R.simulate_rss(M.hold("P4", 1.0), user.moved(rng), rng=rng, session="online_static")
    return R.concat_rss([a, b])


def _write(df, path, **kwargs):
    return RSS.write_rss(df, path, {"seed": 21, "note": "test"}, **kwargs)


# --------------------------------------------------------------------------------------------
# Round trip
# --------------------------------------------------------------------------------------------


def test_round_trip_and_byte_identical_rewrite(table, tmp_path):
    first = _write(table, tmp_path / "a.csv")
    df, sidecar = RSS.read_rss(first)
    assert list(df.columns) == list(RSS.COLUMNS)
    assert df["rss_dbm"].dtype == np.int64
    assert df["time_s"].dtype == np.float64
    np.testing.assert_array_equal(df["rss_dbm"], table["rss_dbm"])
    for column in ("time_s", "x_m", "y_m", "z_m"):
        np.testing.assert_allclose(df[column], table[column], atol=5e-7)
    for column in RSS.TEXT_COLUMNS:
        assert df[column].tolist() == table[column].tolist()
    assert sidecar["packet_rate_hz"] == 30.0
    assert sidecar["anchors"] == list(T.ANCHOR_NAMES) and sidecar["targets"] == list(T.TARGET_NAMES)
    assert sidecar["metadata"] == {"seed": 21, "note": "test"}
    assert set(sidecar["anchor_positions_m"][table["user"].iloc[0]]) == {"training", "online_static"}
    second = RSS.write_rss(df, tmp_path / "b.csv", sidecar["metadata"])
    assert first.read_bytes() == second.read_bytes()
    assert sidecar_path(first).read_bytes() == sidecar_path(second).read_bytes()
    again = _write(table, tmp_path / "c.csv")
    assert again.read_bytes() == first.read_bytes()


def test_csv_text_format(table, tmp_path):
    path = _write(table, tmp_path / "a.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(RSS.COLUMNS)
    fields = lines[1].split(",")
    assert "." not in fields[5] and int(fields[5]) < 0  # rss_dbm is an integer
    assert all(len(fields[i].split(".")[1]) == 6 for i in (0, 7, 8, 9))
    assert "-0.000000" not in path.read_text()


def test_writer_sorts_rows_and_needs_a_packet_rate(table, tmp_path):
    shuffled = table.sample(frac=1.0, random_state=0)
    shuffled.attrs = table.attrs
    a = _write(shuffled, tmp_path / "a.csv")
    b = _write(table, tmp_path / "b.csv")
    assert a.read_bytes() == b.read_bytes()
    bare = pd.DataFrame(table)
    bare.attrs = {}
    with pytest.raises(ValueError, match="packet_rate_hz"):
        _write(bare, tmp_path / "c.csv")
    _write(bare, tmp_path / "d.csv", packet_rate_hz=30.0)
    assert RSS.read_rss(tmp_path / "d.csv")[1]["anchor_positions_m"] == {}


# --------------------------------------------------------------------------------------------
# Bad files
# --------------------------------------------------------------------------------------------


def _hand_made(path):
    """Drop the row count and SHA-256 from the sidecar, as in a hand-converted file, so that
    the reader's checks of the CSV's content (not its integrity check) are what a test sees."""
    side = sidecar_path(path)
    meta = json.loads(side.read_text())
    side.write_text(json.dumps({k: v for k, v in meta.items() if k not in ("csv_rows", "csv_sha256")}))
    return path


def _corrupt(path, row, column, value):
    _hand_made(path)
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    fields = lines[row].split(",")
    fields[header.index(column)] = value
    lines[row] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("column", "value", "message"),
    [
        ("rss_dbm", "-60.5", "integers"),
        ("rss_dbm", "abc", "integers"),
        ("rss_dbm", "-300", "outside"),
        ("x_m", "nan", "non-finite"),
        ("time_s", "", "non-numeric"),
        ("anchor", "A9", "not in the sidecar"),
        ("target", "T3", "not in the sidecar"),
        ("label", "", "empty"),
        ("y_m", "0.999999", "same packet"),
    ],
)
def test_bad_values_name_the_file_and_column(table, tmp_path, column, value, message):
    path = _write(table, tmp_path / "bad.csv")
    _corrupt(path, 2, column, value)
    with pytest.raises(ValueError, match=message) as err:
        RSS.read_rss(path)
    assert str(path) in str(err.value)
    assert column in str(err.value)


def test_bad_structure(table, tmp_path):
    path = _hand_made(_write(table, tmp_path / "x.csv"))
    text = path.read_text().splitlines()
    # Missing column.
    path.write_text("\n".join(",".join(line.split(",")[:-1]) for line in text) + "\n")
    with pytest.raises(ValueError, match=r"missing column.*z_m"):
        RSS.read_rss(path)
    # Columns out of order.
    swapped = [",".join([f[1], f[0], *f[2:]]) for f in (line.split(",") for line in text)]
    path.write_text("\n".join(swapped) + "\n")
    with pytest.raises(ValueError, match="order"):
        RSS.read_rss(path)
    # Duplicated row, rows out of order.
    path.write_text("\n".join([text[0], text[1], text[1], *text[2:]]) + "\n")
    with pytest.raises(ValueError, match="duplicate"):
        RSS.read_rss(path)
    path.write_text("\n".join([text[0], text[20], *text[1:20], *text[21:]]) + "\n")
    with pytest.raises(ValueError, match="out of order"):
        RSS.read_rss(path)
    # Empty table.
    path.write_text(text[0] + "\n")
    with pytest.raises(ValueError, match="no data rows"):
        RSS.read_rss(path)


def test_bad_sidecar(table, tmp_path):
    path = _write(table, tmp_path / "s.csv")
    side = sidecar_path(path)
    meta = json.loads(side.read_text())
    side.write_text(json.dumps({**meta, "format_version": 2}))
    with pytest.raises(ValueError, match="format_version"):
        RSS.read_rss(path)
    side.write_text(json.dumps({k: v for k, v in meta.items() if k != "anchors"}))
    with pytest.raises(ValueError, match="anchors"):
        RSS.read_rss(path)
    side.write_text(json.dumps({**meta, "packet_rate_hz": -1}))
    with pytest.raises(ValueError, match="packet_rate_hz"):
        RSS.read_rss(path)
    side.unlink()
    with pytest.raises(ValueError, match="sidecar"):
        RSS.read_rss(path)
    with pytest.raises(ValueError, match="no such file"):
        RSS.read_rss(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="sidecar"):
        RSS.write_rss(table, tmp_path / "x.json")


def test_writer_validates_the_table(table, tmp_path):
    bad = table.astype({"rss_dbm": float})
    bad.loc[3, "rss_dbm"] = -60.5
    with pytest.raises(ValueError, match="rss_dbm"):
        _write(bad, tmp_path / "a.csv")
    with pytest.raises(ValueError, match="missing column"):
        _write(table.drop(columns="label"), tmp_path / "a.csv")
    with pytest.raises(ValueError, match="JSON"):
        RSS.write_rss(table, tmp_path / "b.csv", {"x": object()})


# --------------------------------------------------------------------------------------------
# Fingerprint vectors
# --------------------------------------------------------------------------------------------


def _toy():
    """Two packets of T1 (A1 misses the second), a third with a new label; one T2 packet."""
    rows = [
        (0.0, "T1", "A1", -50, "P1", 0.0),
        (0.0, "T1", "A2", -60, "P1", 0.0),
        (0.1, "T1", "A2", -62, "P1", 0.1),
        (0.2, "T1", "A1", -54, "P2", 0.2),
        (0.05, "T2", "A3", -70, "P1", 0.5),
    ]
    df = pd.DataFrame(
        {
            "time_s": [r[0] for r in rows],
            "user": "U1",
            "session": "s",
            "target": [r[1] for r in rows],
            "anchor": [r[2] for r in rows],
            "rss_dbm": np.array([r[3] for r in rows], dtype=np.int64),
            "label": [r[4] for r in rows],
            "x_m": [r[5] for r in rows],
            "y_m": 0.0,
            "z_m": 0.0,
        }
    )
    return df


def test_vectors_one_per_packet_with_nan_for_missing_readings():
    v = RSS.rss_vectors(_toy(), anchors=("A1", "A2", "A3"))
    assert len(v) == 4
    np.testing.assert_array_equal(v.target, ["T1", "T1", "T1", "T2"])
    np.testing.assert_array_equal(v.rss[0], [-50, -60, np.nan])
    np.testing.assert_array_equal(v.rss[1], [np.nan, -62, np.nan])
    np.testing.assert_array_equal(v.label, ["P1", "P1", "P2", "P1"])
    np.testing.assert_array_equal(v.time_s, [0.0, 0.1, 0.2, 0.05])
    np.testing.assert_array_equal(v.n_readings[1], [0, 1, 0])
    assert v.select(target="T2").rss.shape == (1, 3)


def test_vectors_windows_average_and_respect_label_changes():
    v = RSS.rss_vectors(_toy(), 2, anchors=("A1", "A2", "A3"), target="T1")
    assert len(v) == 2  # packets 1–2 (P1) together, packet 3 (P2) alone
    np.testing.assert_array_equal(v.rss[0], [-50, -61, np.nan])
    np.testing.assert_array_equal(v.n_packets, [2, 1])
    np.testing.assert_allclose(v.position[0], [0.05, 0.0, 0.0])
    assert v.time_s[0] == 0.1  # available with the window's last packet


def test_vectors_fill_last_and_floor():
    last = RSS.rss_vectors(_toy(), anchors=("A1", "A2", "A3"), fill="last", floor_dbm=-99.0)
    np.testing.assert_array_equal(last.rss[:3], [[-50, -60, -99], [-50, -62, -99], [-54, -62, -99]])
    np.testing.assert_array_equal(last.rss[3], [-99, -99, -70])  # another target: no carry-over
    floor = RSS.rss_vectors(_toy(), anchors=("A1", "A2", "A3"), fill="floor")
    np.testing.assert_array_equal(floor.rss[1], [RSS.DEFAULT_FLOOR_DBM, -62, RSS.DEFAULT_FLOOR_DBM])
    assert not np.isnan(last.rss).any() and not np.isnan(floor.rss).any()
    with pytest.raises(ValueError, match="fill"):
        RSS.rss_vectors(_toy(), fill="mean")
    with pytest.raises(ValueError, match="window_packets"):
        RSS.rss_vectors(_toy(), 0)


def test_vectors_of_a_simulated_session(table):
    v = RSS.rss_vectors(table)
    packets = table.groupby(["session", "target"])["time_s"].nunique().sum()
    assert len(v) == packets
    assert v.rss.shape == (packets, 7)
    assert np.isnan(v.rss).any()  # some anchors miss some packets
    assert np.nanmax(v.rss) < 0
    assert list(dict.fromkeys(v.session)) == ["training", "online_static"]
    w = RSS.rss_vectors(table, 10, fill="last")
    assert len(w) < len(v) / 5 and not np.isnan(w.rss).any()
    np.testing.assert_array_equal(np.unique(w.label), np.unique(table["label"]))
