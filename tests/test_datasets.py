import json

import numpy as np
import pytest

from wsnlib import quaternion as Q
from wsnlib.io.recording import BASE_COLUMNS, QUAT_COLUMNS, UNITS, Recording, read_recording, write_recording
from wsnlib.io.sidecar import sidecar_path


def _recording(rng, n_samples=40, with_quat=True, nodes=("humerus", "forearm")):
    shape = (len(nodes), n_samples)
    quat = Q.normalize(rng.normal(size=shape + (4,))) if with_quat else None
    return Recording(
        fs=50.0,
        time_s=np.arange(n_samples) / 50.0,
        nodes=nodes,
        gyr=rng.normal(scale=2.0, size=shape + (3,)),
        acc=rng.normal(scale=9.8, size=shape + (3,)),
        mag=rng.normal(scale=40.0, size=shape + (3,)),
        quat_true=quat,
        metadata={"generator": "test", "seed": np.int64(12345), "params": {"beta": 0.1}},
    )


def _assert_close(a: Recording, b: Recording):
    assert a.nodes == b.nodes
    assert a.fs == b.fs
    np.testing.assert_allclose(b.time_s, a.time_s, rtol=1e-9, atol=1e-12)
    for name in ("gyr", "acc", "mag"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-8, atol=1e-12)
    if a.quat_true is None:
        assert b.quat_true is None
    else:
        np.testing.assert_allclose(b.quat_true, a.quat_true, rtol=0, atol=1e-8)


def test_round_trip(tmp_path, rng):
    rec = _recording(rng)
    path = write_recording(rec, tmp_path / "sub" / "rec.csv")
    back = read_recording(path)
    _assert_close(rec, back)
    assert back.metadata == {"generator": "test", "seed": 12345, "params": {"beta": 0.1}}
    header = path.read_text().splitlines()[0].split(",")
    assert header == [*BASE_COLUMNS, *QUAT_COLUMNS]
    assert len(path.read_text().splitlines()) == 1 + 2 * 40
    side = json.loads((tmp_path / "sub" / "rec.json").read_text())
    assert side["fs_hz"] == 50.0 and side["nodes"] == ["humerus", "forearm"]
    assert side["units"] == UNITS and side["has_quaternions"] is True


def test_rewrite_is_byte_identical(tmp_path, rng):
    rec = _recording(rng)
    write_recording(rec, tmp_path / "a.csv")
    write_recording(rec, tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()
    # Reading and writing again reproduces the same bytes (a fixed point).
    write_recording(read_recording(tmp_path / "a.csv"), tmp_path / "c.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "c.csv").read_bytes()


def test_file_without_quaternions(tmp_path, rng):
    rec = _recording(rng, with_quat=False, nodes=("wrist",))
    path = write_recording(rec, tmp_path / "real.csv")
    assert "quat_w" not in path.read_text().splitlines()[0]
    back = read_recording(path)
    assert back.quat_true is None
    _assert_close(rec, back)


def test_read_without_sidecar_infers_fs_and_nodes(tmp_path, rng):
    rec = _recording(rng)
    path = write_recording(rec, tmp_path / "rec.csv")
    (tmp_path / "rec.json").unlink()
    with pytest.warns(UserWarning, match="no sidecar rec.json.*cut short"):
        back = read_recording(path)
    assert back.nodes == rec.nodes
    assert back.fs == pytest.approx(50.0)
    assert back.metadata == {}


def _hand_made(path):
    """Drop the row count and SHA-256 from the sidecar, as in a hand-converted file, so that
    the reader's checks of the CSV's content (not its integrity check) are what a test sees."""
    side = sidecar_path(path)
    meta = json.loads(side.read_text())
    side.write_text(json.dumps({k: v for k, v in meta.items() if k not in ("csv_rows", "csv_sha256")}))


def _rewrite(path, edit):
    if sidecar_path(path).exists():
        _hand_made(path)
    lines = path.read_text().splitlines()
    lines = edit(lines)
    path.write_text("\n".join(lines) + "\n")


def _written(tmp_path, rng, **kwargs):
    return write_recording(_recording(rng, **kwargs), tmp_path / "rec.csv")


def _drop_column(lines, name):
    idx = lines[0].split(",").index(name)
    return [",".join(c for i, c in enumerate(line.split(",")) if i != idx) for line in lines]


def _set_cell(lines, row, column, value):
    idx = lines[0].split(",").index(column)
    cells = lines[row].split(",")
    cells[idx] = value
    lines[row] = ",".join(cells)
    return lines


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda lines: _drop_column(lines, "acc_y_m_s2"), r"missing column.*acc_y_m_s2"),
        (lambda lines: _drop_column(lines, "quat_z"), r"all four or none.*quat_z"),
        (lambda lines: _set_cell(lines, 5, "mag_x_uT", "nan"), r"column 'mag_x_uT'.*non-finite"),
        (lambda lines: _set_cell(lines, 7, "gyr_z_rad_s", "inf"), r"column 'gyr_z_rad_s'"),
        (lambda lines: _set_cell(lines, 3, "acc_x_m_s2", "abc"), r"column 'acc_x_m_s2'.*'abc'"),
        (lambda lines: _set_cell(lines, 4, "time_s", "0.0612"), r"column 'time_s'.*different time"),
        (lambda lines: lines[:-1], r"column 'node'.*different sample counts"),
        (lambda lines: _set_cell(lines, 2, "node", "elbow"), r"column 'node'.*elbow"),
        (lambda lines: [lines[0] + ",temp_C"] + [x + ",25" for x in lines[1:]], "unknown column"),
        (lambda lines: _set_cell(lines, 1, "quat_w", "0.9"), "unit quaternion"),
    ],
)
def test_read_errors_name_file_and_column(tmp_path, rng, edit, match):
    path = _written(tmp_path, rng)
    _rewrite(path, edit)
    with pytest.raises(ValueError, match=match) as info:
        read_recording(path)
    assert "rec.csv" in str(info.value) or "rec.json" in str(info.value)


def test_read_rejects_ragged_node_order(tmp_path, rng):
    path = _written(tmp_path, rng)

    def swap(lines):
        lines[1], lines[2] = lines[2], lines[1]
        return lines

    _rewrite(path, swap)
    with pytest.raises(ValueError, match="cycle through"):
        read_recording(path)


def test_read_rejects_time_not_increasing_and_wrong_fs(tmp_path, rng):
    path = _written(tmp_path, rng)
    _rewrite(path, lambda lines: _set_cell(_set_cell(lines, 5, "time_s", "0"), 6, "time_s", "0"))
    with pytest.raises(ValueError, match="strictly increasing"):
        read_recording(path)
    path = _written(tmp_path, rng)
    side = tmp_path / "rec.json"
    meta = json.loads(side.read_text())
    meta["fs_hz"] = 100.0
    side.write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="fs_hz"):
        read_recording(path)


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("units", {"time": "s", "gyr": "deg/s", "acc": "m/s^2", "mag": "uT"}, "gyr"),
        ("format_version", 3, "format_version"),
        ("fs_hz", -5, "fs_hz"),
        ("has_quaternions", False, "has_quaternions"),
    ],
)
def test_read_rejects_bad_sidecar(tmp_path, rng, key, value, match):
    path = _written(tmp_path, rng)
    side = tmp_path / "rec.json"
    meta = json.loads(side.read_text())
    meta[key] = value
    side.write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=match):
        read_recording(path)


def test_missing_file(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        read_recording(tmp_path / "absent.csv")


def test_recording_validation(rng):
    rec = _recording(rng)
    with pytest.raises(ValueError, match="gyr"):
        Recording(50.0, rec.time_s, rec.nodes, rec.gyr[:, :-1], rec.acc, rec.mag)
    with pytest.raises(ValueError, match="acc"):
        bad = rec.acc.copy()
        bad[0, 3, 1] = np.nan
        Recording(50.0, rec.time_s, rec.nodes, rec.gyr, bad, rec.mag)
    with pytest.raises(ValueError, match="quat_true"):
        Recording(50.0, rec.time_s, rec.nodes, rec.gyr, rec.acc, rec.mag, rec.quat_true[..., :3])
    with pytest.raises(ValueError, match="unique"):
        Recording(50.0, rec.time_s, ("a", "a"), rec.gyr, rec.acc, rec.mag)
    with pytest.raises(ValueError, match="comma"):
        Recording(50.0, rec.time_s, ("a,b", "c"), rec.gyr, rec.acc, rec.mag)
    with pytest.raises(ValueError, match="fs"):
        Recording(0.0, rec.time_s, rec.nodes, rec.gyr, rec.acc, rec.mag)
    with pytest.raises(ValueError, match="time_s"):
        Recording(50.0, rec.time_s[::-1], rec.nodes, rec.gyr, rec.acc, rec.mag)
    assert rec.node_index("forearm") == 1
    with pytest.raises(ValueError, match="elbow"):
        rec.node_index("elbow")


def test_write_rejects_bad_metadata_and_path(tmp_path, rng):
    rec = _recording(rng)
    rec.metadata = {"thing": object()}
    with pytest.raises(ValueError, match="metadata"):
        write_recording(rec, tmp_path / "rec.csv")
    with pytest.raises(ValueError, match="sidecar"):
        write_recording(_recording(rng), tmp_path / "rec.json")


# --- format version 2: missing reference rows and the movement mask ---------------------------------------------

#: What the version-1 writer wrote for :func:`_tiny` (its sidecar recorded this SHA-256): a recording
#: that uses nothing of version 2 must still be written byte for byte so.
V1_CSV = """time_s,node,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2,\
mag_x_uT,mag_y_uT,mag_z_uT,quat_w,quat_x,quat_y,quat_z
0,a,0,0.1,0.2,0,0,9.81,0,20,-40,1,0,0,0
0,b,0.9,1,1.1,0,0,9.81,0,20,-40,1,0,0,0
0.02,a,0.3,0.4,0.5,0,0,9.81,0,20,-40,1,0,0,0
0.02,b,1.2,1.3,1.4,0,0,9.81,0,20,-40,1,0,0,0
0.04,a,0.6,0.7,0.8,0,0,9.81,0,20,-40,1,0,0,0
0.04,b,1.5,1.6,1.7,0,0,9.81,0,20,-40,1,0,0,0
"""
V1_SHA256 = "8d325e7b11701380849f4324b9fc95c04c3ec05acc3560dbeb73d9d81c95294e"


def _tiny(**changes):
    fields = dict(fs=50.0, time_s=np.arange(3) / 50.0, nodes=("a", "b"), gyr=np.arange(18.0).reshape(2, 3, 3) / 10,
                  acc=np.full((2, 3, 3), [0.0, 0.0, 9.81]), mag=np.full((2, 3, 3), [0.0, 20.0, -40.0]),
                  quat_true=np.tile([1.0, 0.0, 0.0, 0.0], (2, 3, 1)), metadata={"k": 1})
    return Recording(**{**fields, **changes})


def test_a_recording_without_version_2_content_is_written_as_version_1_byte_for_byte(tmp_path):
    path = write_recording(_tiny(), tmp_path / "v1.csv")
    assert path.read_text() == V1_CSV
    side = json.loads(sidecar_path(path).read_text())
    assert side["format_version"] == 1 and side["csv_sha256"] == V1_SHA256 and "has_movement" not in side
    back = read_recording(path)
    assert back.movement is None and back.reference_valid.all()


def test_a_hand_made_version_1_file_is_read_as_before(tmp_path):
    path = tmp_path / "old.csv"
    path.write_text(V1_CSV)
    sidecar_path(path).write_text(json.dumps({"format": "wsnlib-recording", "format_version": 1, "fs_hz": 50,
                                              "nodes": ["a", "b"], "units": UNITS, "has_quaternions": True}))
    back = read_recording(path)
    assert back.nodes == ("a", "b") and back.n_samples == 3 and back.movement is None
    np.testing.assert_array_equal(back.gyr[1, 2], [1.5, 1.6, 1.7])
    np.testing.assert_array_equal(back.quat_true, np.tile([1.0, 0.0, 0.0, 0.0], (2, 3, 1)))


def test_version_2_round_trip_with_missing_reference_and_movement(tmp_path, rng):
    rec = _recording(rng, n_samples=30)
    rec.quat_true[0, 5:9] = np.nan    # node 0 loses its markers for 4 samples
    rec.quat_true[1, 20] = np.nan
    movement = np.ones((2, 30), bool)
    movement[:, :4] = False
    movement[1, 25:] = False
    rec = Recording(rec.fs, rec.time_s, rec.nodes, rec.gyr, rec.acc, rec.mag, rec.quat_true, rec.metadata,
                    movement=movement)
    expected_valid = np.ones((2, 30), bool)
    expected_valid[0, 5:9] = False
    expected_valid[1, 20] = False
    np.testing.assert_array_equal(rec.reference_valid, expected_valid)
    path = write_recording(rec, tmp_path / "v2.csv")
    lines = path.read_text().splitlines()
    assert lines[0].split(",")[-5:] == ["quat_w", "quat_x", "quat_y", "quat_z", "movement"]
    assert lines[1 + 2 * 5].split(",")[-5:] == ["", "", "", "", "1"]   # sample 5, node 0: no reference
    assert lines[1].endswith(",0") and lines[1 + 2 * 10].endswith(",1")
    side = json.loads(sidecar_path(path).read_text())
    assert side["format_version"] == 2 and side["has_movement"] is True and side["has_quaternions"] is True
    back = read_recording(sidecar_path(path))   # the sidecar's path reads the CSV beside it
    np.testing.assert_array_equal(back.reference_valid, expected_valid)
    np.testing.assert_array_equal(back.movement, movement)
    assert back.movement.dtype == bool
    np.testing.assert_allclose(back.quat_true[expected_valid], rec.quat_true[expected_valid], atol=1e-8)
    write_recording(back, tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_bytes() == path.read_bytes()


def test_version_2_without_reference_but_with_movement(tmp_path, rng):
    plain = _recording(rng, n_samples=10, with_quat=False, nodes=("wrist",))
    rec = Recording(plain.fs, plain.time_s, plain.nodes, plain.gyr, plain.acc, plain.mag,
                    movement=np.arange(10)[None, :] >= 3)
    path = write_recording(rec, tmp_path / "m.csv")
    assert path.read_text().splitlines()[0].endswith("mag_z_uT,movement")
    back = read_recording(path)
    assert back.quat_true is None and not back.reference_valid.any()
    np.testing.assert_array_equal(back.movement, rec.movement)


def _v2_written(tmp_path):
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (2, 3, 1))
    quat[0, 1] = np.nan
    return write_recording(_tiny(quat_true=quat, movement=np.ones((2, 3), bool)), tmp_path / "rec.csv")


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda lines: _set_cell(lines, 3, "quat_w", "1"), r"data row 3 leaves \['quat_x', 'quat_y', 'quat_z'\] empty"),
        (lambda lines: _set_cell(lines, 2, "quat_y", ""), r"data row 2 leaves \['quat_y'\] empty but not all four"),
        (lambda lines: _set_cell(lines, 4, "movement", "2"), r"column 'movement' must hold 0 or 1.*data row 4"),
        (lambda lines: _set_cell(lines, 1, "quat_x", "abc"), r"column 'quat_x'.*'abc'"),
        (lambda lines: _set_cell(lines, 1, "quat_x", "inf"), r"column 'quat_x'.*'inf'"),
    ],
)
def test_version_2_errors_name_file_column_and_row(tmp_path, edit, match):
    path = _v2_written(tmp_path)
    _rewrite(path, edit)
    with pytest.raises(ValueError, match=match) as info:
        read_recording(path)
    assert "rec.csv" in str(info.value)


@pytest.mark.parametrize("drop_movement, match", [(False, r"'movement' column needs format_version 2"),
                                                   (True, r"data row 3 has no reference.*needs format_version 2")])
def test_version_2_content_under_a_version_1_sidecar_is_refused(tmp_path, drop_movement, match):
    path = _v2_written(tmp_path)
    _rewrite(path, (lambda lines: _drop_column(lines, "movement")) if drop_movement else (lambda lines: lines))
    meta = json.loads(sidecar_path(path).read_text())
    meta["format_version"] = 1
    del meta["has_movement"]
    sidecar_path(path).write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=match):
        read_recording(path)


def test_has_movement_must_match_the_csv(tmp_path):
    path = _v2_written(tmp_path)
    meta = json.loads(sidecar_path(path).read_text())
    meta["has_movement"] = False
    sidecar_path(path).write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="'has_movement' is False but .* has the 'movement' column"):
        read_recording(path)


def test_recording_validation_of_version_2_fields():
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (2, 3, 1))
    quat[1, 2, 3] = np.nan
    with pytest.raises(ValueError, match=r"quat_true at node 1, sample 2 .* four NaN"):
        _tiny(quat_true=quat)
    quat[1, 2] = np.inf
    with pytest.raises(ValueError, match=r"quat_true at node 1, sample 2"):
        _tiny(quat_true=quat)
    with pytest.raises(ValueError, match=r"movement must be a boolean array of shape \(2, 3\)"):
        _tiny(movement=np.ones((2, 3)))
    with pytest.raises(ValueError, match=r"movement must be a boolean array of shape \(2, 3\)"):
        _tiny(movement=np.ones((3,), bool))
    assert not _tiny(quat_true=None).reference_valid.any()
