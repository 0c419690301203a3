"""A catalogue of bad inputs and faults (issue 14): each must raise a ValueError naming the
argument, the file or the sidecar — or, for file writes, leave the old file or none.

The batch runner's faults (stuck cell, dead kernel, signals, stale outputs, bad command
lines) are in ``test_reproduce.py``; the pitch low-pass at high orders in ``test_posture.py``.
"""

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from wsnlib import _files, plotting  # noqa: E402
from wsnlib import quaternion as Q  # noqa: E402
from wsnlib.io import accel  # noqa: E402
from wsnlib.io import rss as RSS  # noqa: E402
from wsnlib.io.recording import Recording, read_recording, write_recording  # noqa: E402
from wsnlib.io.sidecar import sidecar_path  # noqa: E402
from wsnlib.radio import KNNFingerprint, ProbabilisticKNN  # noqa: E402
from wsnlib.radio import _checks as radio_checks  # noqa: E402

# --------------------------------------------------------------------------------------------
# Quaternion helpers: wrong shapes, zero quaternions and NaN name the argument
# --------------------------------------------------------------------------------------------

IDENTITY = [1.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: Q.rotate([1.0, 0.0, 0.0], [1.0, 0.0, 0.0]), "q"),
        (lambda: Q.rotate(IDENTITY, [1.0, 0.0, 0.0, 0.0]), "v"),
        (lambda: Q.rotate(np.ones((2, 4)), np.ones((3, 3))), "v"),
        (lambda: Q.angle_between([0.0, 0.0, 0.0, 0.0], IDENTITY), "q_a"),
        (lambda: Q.angle_between(IDENTITY, np.zeros((3, 4))), "q_b"),
        (lambda: Q.angle_between(IDENTITY, [1.0, 0.0]), "q_b"),
        (lambda: Q.from_axis_angle([0.0, 0.0, 1.0], np.nan), "angle"),
        (lambda: Q.from_axis_angle([np.nan, 0.0, 1.0], 0.5), "axis"),
        (lambda: Q.from_axis_angle(np.ones((2, 3)), np.ones(5)), "angle"),
        (lambda: Q.slerp(np.ones((2, 4)), np.ones((3, 4)), 0.5), "q_a"),
        (lambda: Q.slerp(IDENTITY, [1.0, 0.0, 0.0], 0.5), "q_b"),
        (lambda: Q.slerp(np.tile(IDENTITY, (2, 1)), np.tile(IDENTITY, (2, 1)), np.full(3, 0.5)), "mu"),
        (lambda: Q.conjugate([1.0, 0.0, 0.0]), "q"),
        (lambda: Q.conjugate(1.0), "q"),
        (lambda: Q.multiply(IDENTITY, [1.0, 0.0]), "q"),
        (lambda: Q.multiply(np.ones((2, 4)), np.ones((3, 4))), "p"),
    ],
)
def test_quaternion_errors_name_the_argument(call, name):
    with pytest.raises(ValueError, match=rf"(?<![\w\[]){name}(?![\w(])"):
        call()


def test_quaternion_checks_leave_valid_results_alone(rng):
    q = Q.normalize(rng.normal(size=(5, 4)))
    v = rng.normal(size=(5, 3))
    np.testing.assert_allclose(np.linalg.norm(Q.rotate(q, v), axis=-1), np.linalg.norm(v, axis=-1))
    assert Q.angle_between(q, q) == pytest.approx(np.zeros(5), abs=1e-7)
    assert Q.angle_between(q[0], -q[0]) == pytest.approx(0.0, abs=1e-7)


# --------------------------------------------------------------------------------------------
# Fingerprint estimators: nonsense training data is refused; predict works in chunks
# --------------------------------------------------------------------------------------------


def _training(rng, n_positions=6, n_anchors=5, per_position=20):
    means = rng.uniform(-90.0, -40.0, size=(n_positions, n_anchors))
    positions = rng.uniform(0.0, 3.0, size=(n_positions, 3))
    X = np.repeat(means, per_position, axis=0) + rng.normal(scale=2.0, size=(n_positions * per_position, n_anchors))
    y = np.repeat(positions, per_position, axis=0)
    return X, y


@pytest.mark.parametrize("cls", [KNNFingerprint, ProbabilisticKNN])
@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda X: np.full_like(X, np.nan), r"\bX\b has no reading"),
        (lambda X: 10.0 ** (X / 10.0), r"\bX\b holds only readings >= 0.*mW"),  # linear power in mW
        (lambda X: np.where(np.arange(X.size).reshape(X.shape) == 7, -1e9, X),
         r"\bX\b .*-1e\+09 dBm at index \(1, 2\)"),
        (lambda X: X + 200.0, r"\bX\b .*outside the plausible range \[-130, 20\] dBm"),
    ],
)
def test_fit_refuses_training_data_without_usable_dbm_values(rng, cls, edit, match):
    X, y = _training(rng)
    with pytest.raises(ValueError, match=match):
        cls().fit(edit(X), y)


@pytest.mark.parametrize("cls", [KNNFingerprint, ProbabilisticKNN])
@pytest.mark.parametrize("floor", [-1e9, 25.0, np.nan, "low"])
def test_fit_refuses_an_implausible_floor_rss(rng, cls, floor):
    X, y = _training(rng)
    with pytest.raises(ValueError, match="floor_rss"):
        cls(floor_rss=floor).fit(X, y)


def test_a_glitch_no_longer_asks_for_a_giant_grid(rng):
    X, y = _training(rng)
    X[3, 1] = -1e9
    with pytest.raises(ValueError, match=r"\bX\b"):
        ProbabilisticKNN().fit(X, y)
    X[3, 1] = np.nan  # a missing reading is fine
    assert ProbabilisticKNN().fit(X, y).grid_.size < 200


@pytest.mark.parametrize(
    "make",
    [
        lambda: KNNFingerprint(n_neighbors=3, power=2),
        lambda: KNNFingerprint(n_neighbors=2, metric="manhattan", anchors=[0, 2, 3]),
        lambda: ProbabilisticKNN(n_neighbors=3),
        lambda: ProbabilisticKNN(n_neighbors=2, pmf="parzen", anchors=[1, 4]),
    ],
)
def test_predict_in_chunks_equals_predict_at_once(rng, monkeypatch, make):
    X, y = _training(rng)
    online = rng.uniform(-95.0, -35.0, size=(53, X.shape[1]))
    est = make().fit(X, y)
    whole = est.predict(online), est.kneighbors(online)
    proba = est.predict_log_proba(online) if isinstance(est, ProbabilisticKNN) else None

    # Ask for chunks of at most 7 vectors and record the vectors each chunk holds.
    n_fp, n_anchors = est.radio_map_.shape
    monkeypatch.setattr(radio_checks, "_CHUNK_ELEMENTS", 7 * n_fp * n_anchors)
    sizes = []
    inner = type(est)._neighbors_chunk

    def spy(self, chunk, k):
        sizes.append(chunk.shape[0])
        return inner(self, chunk, k)

    monkeypatch.setattr(type(est), "_neighbors_chunk", spy)
    chunked = est.predict(online), est.kneighbors(online)
    assert max(sizes) == 7 and sum(sizes) == 2 * len(online)  # predict + kneighbors
    np.testing.assert_array_equal(chunked[0], whole[0])
    np.testing.assert_array_equal(chunked[1][0], whole[1][0])
    np.testing.assert_array_equal(chunked[1][1], whole[1][1])
    if proba is not None:
        np.testing.assert_array_equal(est.predict_log_proba(online), proba)
    assert est.predict(online[:0]).shape == (0, 3)


def test_the_chunk_bound_keeps_a_100k_query_small():
    """The largest intermediate (vectors x fingerprints x anchors) of a 100,000-vector query
    over PABR's 81 positions x 12 receivers stays at _CHUNK_ELEMENTS values (32 MB)."""
    est = KNNFingerprint()
    est.radio_map_ = np.zeros((81, 12))
    chunks = est._query_chunks(100_000)
    largest = max(c.stop - c.start for c in chunks)
    assert largest * 81 * 12 <= radio_checks._CHUNK_ELEMENTS
    assert largest * 81 * 12 * 8 <= 40e6  # bytes per (n, L, A) float array
    assert chunks[0].start == 0 and chunks[-1].stop == 100_000
    assert all(a.stop == b.start for a, b in zip(chunks, chunks[1:], strict=False))


# --------------------------------------------------------------------------------------------
# Atomic writes
# --------------------------------------------------------------------------------------------


def test_atomic_path_keeps_the_old_file_when_the_writer_fails(tmp_path):
    target = tmp_path / "table.csv"
    target.write_text("old\n")
    with pytest.raises(RuntimeError, match="disk full"):
        with _files.atomic_path(target) as tmp:
            tmp.write_text("half of a new")
            raise RuntimeError("disk full")
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["table.csv"]  # no temporary file left
    _files.atomic_write_text(target, "new\n")
    assert target.read_text() == "new\n"
    assert [p.name for p in tmp_path.iterdir()] == ["table.csv"]
    assert _files.write_csv(pd.DataFrame({"a": [1]}), tmp_path / "x.csv", index=False).read_text() == "a\n1\n"


def test_savefig_checks_every_format_before_writing_anything(output_dir):
    fig, ax = plt.subplots()
    ax.plot([0, 1])
    with pytest.raises(ValueError, match="formats"):
        plotting.savefig(fig, "checked", formats=("png", "jpg"))
    with pytest.raises(ValueError, match="formats"):
        plotting.savefig(fig, "checked", formats=())
    assert not list((output_dir / "figures").glob("*")) if (output_dir / "figures").exists() else True
    written = plotting.savefig(fig, "checked", formats="png")
    assert [p.name for p in written] == ["checked.png"]
    assert sorted(p.name for p in (output_dir / "figures").iterdir()) == ["checked.png"]
    plt.close(fig)


# --------------------------------------------------------------------------------------------
# Recording formats: truncated copies and foreign units are refused
# --------------------------------------------------------------------------------------------


def _cut_at_a_line_end(path, keep_rows):
    lines = path.read_bytes().split(b"\n")
    path.write_bytes(b"\n".join(lines[: 1 + keep_rows]) + b"\n")


def _set_units(path, units):
    side = sidecar_path(path)
    meta = json.loads(side.read_text())
    meta["units"] = units
    side.write_text(json.dumps(meta))


def _recording(rng, n=40):
    shape = (2, n)
    return Recording(fs=50.0, time_s=np.arange(n) / 50.0, nodes=("humerus", "forearm"),
                     gyr=rng.normal(size=shape + (3,)), acc=rng.normal(size=shape + (3,)),
                     mag=rng.normal(size=shape + (3,)))


@pytest.fixture(scope="module")
def rss_table():
    from wsnlib.sim import arm_motion as M
    from wsnlib.sim import body as B
    from wsnlib.sim import radio as R

    rng = np.random.default_rng(3)
    user = B.make_users(1, rng=rng)[0]
    return R.simulate_rss(M.hold("P1", 2.0), user, rng=rng, session="training")


def _acc_table(n=20):
    time_s = np.repeat(np.arange(n) / 30.0, 2)
    return pd.DataFrame({
        "time_s": time_s, "user": "U1", "session": "online_dynamic", "target": ["T1", "T2"] * n,
        "label": "P1", "acc_x_m_s2": 0.1, "acc_y_m_s2": 0.2, "acc_z_m_s2": 9.8,
    })


def _writers(rng, rss_table, tmp_path):
    return {
        "recording": (write_recording(_recording(rng), tmp_path / "rec.csv"), read_recording),
        "rss": (RSS.write_rss(rss_table, tmp_path / "rss.csv", packet_rate_hz=30.0), RSS.read_rss),
        "acc": (accel.write_acc(_acc_table(), tmp_path / "acc.csv", rate_hz=30.0), accel.read_acc),
    }


@pytest.mark.parametrize("kind", ["recording", "rss", "acc"])
def test_a_copy_cut_at_a_line_end_is_refused(rng, rss_table, tmp_path, kind):
    path, read = _writers(rng, rss_table, tmp_path)[kind]
    meta = json.loads(sidecar_path(path).read_text())
    assert meta["csv_rows"] == len(path.read_text().splitlines()) - 1
    read(path)  # the intact file reads
    _cut_at_a_line_end(path, keep_rows=meta["csv_rows"] // 3)
    with pytest.raises(ValueError, match=rf"has {meta['csv_rows'] // 3} data rows but its sidecar .* says "
                                         rf"{meta['csv_rows']}") as info:
        read(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("kind", ["recording", "rss", "acc"])
def test_an_edited_copy_is_refused_by_its_checksum(rng, rss_table, tmp_path, kind):
    path, read = _writers(rng, rss_table, tmp_path)[kind]
    text = path.read_text()
    last_digit = max(i for i, c in enumerate(text) if c in "12345678")
    path.write_text(text[:last_digit] + str(int(text[last_digit]) + 1) + text[last_digit + 1:])
    with pytest.raises(ValueError, match="SHA-256") as info:
        read(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("kind", "units", "key"),
    [
        ("rss", {"time": "s", "rss": "mW", "position": "m"}, "rss"),
        ("rss", {"time": "s", "rss": "dBm", "position": "cm"}, "position"),
        ("rss", None, "units"),
        ("acc", {"time": "s", "acc": "g"}, "acc"),
        ("acc", {"time": "ms", "acc": "m/s^2 (specific force)"}, "time"),
        ("recording", {"time": "s", "gyr": "deg/s", "acc": "m/s^2", "mag": "uT"}, "gyr"),
    ],
)
def test_readers_refuse_undocumented_units(rng, rss_table, tmp_path, kind, units, key):
    path, read = _writers(rng, rss_table, tmp_path)[kind]
    _set_units(path, units)
    with pytest.raises(ValueError, match="units") as info:
        read(path)
    assert sidecar_path(path).name in str(info.value)
    assert repr(key) in str(info.value) or key == "units"


# --------------------------------------------------------------------------------------------
# Issue 23: dataset folders, registries and RSS targets that a user gets wrong
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("loader", ["broad", "pabr"])
def test_dataset_folder_variable_naming_a_file_is_refused(tmp_path, monkeypatch, loader):
    from wsnlib.io import broad, pabr

    module, folder_of = {"broad": (broad, broad.broad_dir), "pabr": (pabr, pabr.pabr_dir)}[loader]
    a_file = tmp_path / "not_a_folder.mat"
    a_file.write_bytes(b"x")
    variable = module.BROAD_DIR_ENV_VAR if loader == "broad" else module.PABR_DIR_ENV_VAR
    monkeypatch.setenv(variable, str(a_file))
    with pytest.raises(NotADirectoryError, match=rf"\${variable}.*not_a_folder\.mat is a file"):
        folder_of()
    with pytest.raises(NotADirectoryError, match=r"data_dir .*is a file"):
        folder_of(a_file)


def test_malformed_registry_row_names_the_line(tmp_path, monkeypatch):
    from importlib import resources

    from wsnlib.io import download

    (tmp_path / "registry").mkdir()
    monkeypatch.setattr(resources, "files", lambda package: tmp_path)
    (tmp_path / "registry" / "toy.tsv").write_text("# toy\nfile\tsha256\na.mat\tabc\nb.mat\n")
    with pytest.raises(ValueError, match=r"toy\.tsv, line 4: 1 tab-separated fields, expected 2"):
        download.read_registry("toy", ["file", "sha256"])
    with pytest.raises(ValueError, match=r"toy\.tsv: expected the header"):
        download.read_registry("toy", ["file", "sha256", "bytes"])


def test_rss_vectors_of_a_target_without_packets_is_refused():
    table = pd.DataFrame({"time_s": [0.0, 0.1], "user": "u1", "session": "s1", "target": "T1", "anchor": "A1",
                          "rss_dbm": [-60, -61], "label": "p0", "x_m": 0.0, "y_m": 0.0, "z_m": 0.0})
    assert len(RSS.rss_vectors(table, target="T1", anchors=("A1",))) > 0
    with pytest.raises(ValueError, match=r"target 't1' has no packets.*\['T1'\]"):
        RSS.rss_vectors(table, target="t1", anchors=("A1",))



# --------------------------------------------------------------------------------------------
# Issue 23: recordings implausible as a whole, and complex input, through the public filters
# --------------------------------------------------------------------------------------------


def _still_recording(n=200):
    """A sensor turning slowly at 50 Hz in the documented units (rad/s, m/s², µT), with sensor noise."""
    t = np.arange(n) / 50.0
    noise = np.random.default_rng(23).normal(size=(3, n, 3))
    gyr = np.stack([0.3 * np.sin(t), 0.2 * np.cos(t), np.full_like(t, 0.1)], axis=-1) + 0.01 * noise[0]
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + 0.05 * noise[1]
    return gyr, acc, np.tile([0.0, 25.0, -38.0], (n, 1)) + 0.3 * noise[2]


def _filters():
    from wsnlib.orientation import estimate_orientation, kalman_orientation, madgwick, smooth_orientation

    return {"madgwick": lambda g, a, m: madgwick(g, a, m, fs=50.0, beta=0.1),
            "estimate_orientation": lambda g, a, m: estimate_orientation(g, a, m, fs=50.0, beta=0.1),
            "kalman_orientation": lambda g, a, m: kalman_orientation(g, a, m, fs=50.0),
            "smooth_orientation": lambda g, a, m: smooth_orientation(g, a, m, fs=50.0)}


@pytest.mark.parametrize("name", ["madgwick", "estimate_orientation", "kalman_orientation", "smooth_orientation"])
def test_filters_refuse_a_recording_in_the_wrong_units(name):
    run = _filters()[name]
    gyr, acc, mag = _still_recording()
    run(gyr, acc, mag)  # the documented units pass
    with pytest.raises(ValueError, match="gyr looks like deg/s"):
        run(np.degrees(gyr) * 100, acc, mag)
    with pytest.raises(ValueError, match="acc and mag look swapped"):
        run(gyr, mag, acc)
    with pytest.raises(ValueError, match="acc must be real"):
        run(gyr, acc.astype(complex) + 1j, mag)


@pytest.mark.parametrize("blend", ["output", "feedback"])
def test_hybrid_refuses_acc_parallel_to_mag_where_it_needs_triad(blend):
    from wsnlib.orientation import estimate_orientation, madgwick
    from wsnlib.orientation.hybrid_blend import blend_with_single_frame

    gyr, acc, mag = _still_recording(60)
    received = np.ones(60, dtype=bool)
    received[20:26] = False
    mag = mag.copy()
    mag[26] = 40.0 * acc[26] / np.linalg.norm(acc[26])  # the first sample after the gap: no heading
    with pytest.raises(ValueError, match="acc and mag are parallel .* the hybrid's single frame after a gap"):
        estimate_orientation(gyr, acc, mag, fs=50.0, beta=0.1, received=received, blend=blend)
    quat_d = madgwick(gyr, acc, mag, fs=50.0, beta=0.1, received=received)
    with pytest.raises(ValueError, match="acc and mag are parallel"):
        blend_with_single_frame(quat_d, acc, mag, received=received)
    received[26] = False  # not received: never read
    estimate_orientation(gyr, acc, mag, fs=50.0, beta=0.1, received=received, blend=blend)


@pytest.mark.parametrize("name", ["kalman_orientation", "smooth_orientation"])
def test_kalman_filters_refuse_acc_that_does_not_match_their_gravity(name):
    from wsnlib.orientation import KalmanSettings, kalman_orientation, smooth_orientation

    run = {"kalman_orientation": kalman_orientation, "smooth_orientation": smooth_orientation}[name]
    gyr, acc, mag = _still_recording()
    with pytest.raises(ValueError, match=r"median norm is 1 m/s² where gravity of 9.807 m/s² is expected: .*in g\?"):
        run(gyr, acc / 9.81, mag, fs=50.0)
    with pytest.raises(ValueError, match="gravity of 1 m/s² is expected: .*gravity given to the filter right"):
        run(gyr, acc, mag, fs=50.0, settings=KalmanSettings(gravity=1.0))
    run(gyr, acc / 9.81, mag, fs=50.0, settings=KalmanSettings(gravity=1.0))  # consistent units are fine


@pytest.mark.parametrize("name", ["kalman_orientation", "smooth_orientation"])
def test_kalman_filters_refuse_settings_that_are_not_kalman_settings(name):
    from wsnlib.orientation import kalman_orientation, smooth_orientation

    run = {"kalman_orientation": kalman_orientation, "smooth_orientation": smooth_orientation}[name]
    gyr, acc, mag = _still_recording()
    with pytest.raises(ValueError, match="settings must be a KalmanSettings, got dict"):
        run(gyr, acc, mag, fs=50.0, settings={"gravity": 9.81})


def test_kalman_settings_that_underflow_name_the_field():
    from wsnlib.orientation import KalmanSettings, kalman_orientation

    gyr, acc, mag = _still_recording()
    with pytest.raises(ValueError, match=r"KalmanSettings bias_noise=1e-300 at fs = 50.0 Hz"):
        kalman_orientation(gyr, acc, mag, fs=50.0, settings=KalmanSettings(bias_noise=1e-300))


@pytest.mark.filterwarnings("ignore:the magnetometer was rejected")  # a turning gyro, a fixed field: not the point
@pytest.mark.parametrize("name", ["madgwick", "kalman_orientation"])
def test_a_broadcast_batch_is_not_materialised(name):
    """Issue 23: np.broadcast_to inputs were copied in full before the memory check (an OOM kill)."""
    import tracemalloc

    from wsnlib.orientation import kalman_orientation, madgwick

    def run(batch):
        gyr, acc, mag = (np.broadcast_to(x, (batch,) + x.shape) for x in _still_recording(3000))
        if name == "madgwick":
            return madgwick(gyr, acc, mag, fs=50.0, beta=0.1)
        return kalman_orientation(gyr, acc, mag, fs=50.0)

    run(2)  # warm: compiled code loaded
    tracemalloc.start()
    out = run(100)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    per_sample = {"madgwick": 4 * 8, "kalman_orientation": 8 * 13 + 2}[name]  # what the memory check counts
    assert out.shape == (100, 3000, 4)
    assert peak < 1.25 * per_sample * out.shape[0] * out.shape[1]  # copies of the signals would add 9 × 8 B


@pytest.mark.parametrize("name", ["madgwick", "estimate_orientation", "kalman_orientation", "smooth_orientation"])
def test_one_implausible_sample_is_treated_as_lost(name):
    """Issue 23: one gyro sample of 1e6 rad/s corrupted 10 s of output; acc·1e200 was called parallel to mag."""
    run = _filters()[name]
    gyr, acc, mag = _still_recording(400)
    clean = run(gyr, acc, mag)
    for signal, value in (("gyr", 1e6), ("acc", 1e200)):
        bad = {"gyr": gyr.copy(), "acc": acc.copy()}
        bad[signal][100] *= value
        with pytest.warns(UserWarning, match=r"1 received sample\(s\) with an implausible reading") as caught:
            out = run(bad["gyr"], bad["acc"], mag)
        assert [w.filename for w in caught] == [__file__]  # the user's call, at any depth of the library
        assert np.all(np.isfinite(out))
        # a lost sample costs a little; the corrupted sample used to leave tens of degrees for seconds
        assert Q.angle_between(out[150:], clean[150:]).max() < np.radians(5.0)


def test_kalman_full_output_counts_what_it_treated_as_lost_and_warns_of_an_unused_magnetometer():
    from wsnlib.orientation import kalman_orientation

    gyr, acc, mag = _still_recording(400)
    gyr = gyr.copy()
    gyr[[50, 60]] = 1e6
    with pytest.warns(UserWarning, match="2 received sample"):
        out = kalman_orientation(gyr, acc, mag, fs=50.0, full_output=True)
    assert out.treated_as_lost.sum() == 2 and out.treated_as_lost[50] and out.treated_as_lost[60]
    frozen = np.broadcast_to(mag[0], mag.shape).copy()
    frozen[:, 0] += np.repeat(np.arange(4), 100) * 1e-3  # updates once in 100 samples
    with pytest.warns(UserWarning, match="mag is frozen: 99% of the received samples") as caught:
        kalman_orientation(_still_recording(400)[0], acc, frozen, fs=50.0)
    assert {w.filename for w in caught} == {__file__}
    gyr, acc, mag = _still_recording(4000)  # 80 s: longer than 3 × mag_new_time_s
    magnet = mag + np.where(np.arange(4000)[:, None] >= 500, [0.0, 300.0, 0.0], 0.0)  # a magnet from 10 s on
    with pytest.warns(UserWarning, match=r"magnetometer was rejected on \d+% of the received samples") as caught:
        kalman_orientation(gyr, acc, magnet, fs=50.0)
    assert {w.filename for w in caught} == {__file__}


def test_a_saturated_magnetometer_is_named():
    from wsnlib.plausibility import magnetometer_problem

    gyr, acc, mag = _still_recording(400)
    clipped = mag.copy()
    clipped[100:300, 1] = 800.0  # a magnet near the sensor: the y axis at its full scale
    assert "mag looks saturated: 50% of the received samples sit at ±800 µT on axis y" in magnetometer_problem(
        clipped, np.ones(400, dtype=bool))
    assert magnetometer_problem(mag, np.ones(400, dtype=bool)) is None


def test_a_write_that_fails_for_lack_of_space_names_the_file(tmp_path, monkeypatch):
    """Issue 23: a full disk failed with "OSError: [Errno 27] File too large", naming no file."""
    import errno
    import os

    def full_disk(src, dst):
        raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))

    monkeypatch.setattr(_files.os, "replace", full_disk)
    target = tmp_path / "a01_table.csv"
    with pytest.raises(OSError, match=rf"writing {target}: File too large") as info:
        _files.atomic_write_text(target, "a\n1\n")
    assert info.value.errno == errno.EFBIG and not list(tmp_path.iterdir())  # no file, no temporary left

