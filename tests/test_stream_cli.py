"""``python -m wsnlib.stream send / receive`` over UDP loopback (issue 27): what the receiver writes is
the batch filter on what the sender dumped; Ctrl-C ends the receiver cleanly."""

import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from _recordings import FS, turning_recording

from wsnlib.io.recording import Recording, write_recording
from wsnlib.orientation import kalman_orientation
from wsnlib.stream.__main__ import loss_spec


def _recording(tmp_path, n=900):
    nodes = [turning_recording(n, seed=s, noise=0.01) for s in (1, 2)]
    rec = Recording(fs=FS, time_s=np.arange(n) / FS, nodes=("upper", "fore"),
                    gyr=np.stack([x[0] for x in nodes]), acc=np.stack([x[1] for x in nodes]),
                    mag=np.stack([x[2] for x in nodes]), quat_true=np.stack([x[3] for x in nodes]))
    path = tmp_path / "rec.csv"
    write_recording(rec, path)
    return path


def _start_receiver(out, *options):
    proc = subprocess.Popen([sys.executable, "-m", "wsnlib.stream", "receive", "--port", "0", "--out", str(out),
                             *options], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.startswith("listening on 127.0.0.1:"), line + proc.stderr.read()
    return proc, int(line.strip().rsplit(":", 1)[1])


def _send(recording, port, dump, *options):
    result = subprocess.run([sys.executable, "-m", "wsnlib.stream", "send", str(recording), "--port", str(port),
                             "--loss", "ge:0.15:3", "--seed", "4", "--dump", str(dump), *options],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_send_and_receive_over_udp_equal_the_batch_filter(tmp_path):
    recording = _recording(tmp_path)
    out, dump = tmp_path / "out.csv", tmp_path / "sent.npz"
    receiver, port = _start_receiver(out, "--idle-exit", "2")
    try:
        assert "sent" in _send(recording, port, dump, "--speed", "max", "--node", "7")
        stdout, stderr = receiver.communicate(timeout=120)
    finally:
        receiver.kill()
    assert receiver.returncode == 0, stderr
    assert "idle: wrote" in stdout and "received" in stdout and "rejected datagrams: short 0" in stdout
    sent = np.load(dump)
    assert sent["gyr"].shape == (2, 900, 3) and float(sent["fs"]) == FS
    rows = pd.read_csv(out)
    assert list(rows.columns) == ["node", "sample", "received", "w", "x", "y", "z"]
    for i, node in enumerate(sent["node"]):
        mine = rows[rows["node"] == node]
        mask = sent["received"][i]
        first, last = np.flatnonzero(mask)[[0, -1]]
        batch = kalman_orientation(sent["gyr"][i][first:], sent["acc"][i][first:], sent["mag"][i][first:], fs=FS,
                                   received=mask[first:])
        upto = mine[mine["sample"] <= last]  # after the last packet the receiver predicts until it is idle
        np.testing.assert_array_equal(upto["sample"], np.arange(first, last + 1))
        np.testing.assert_array_equal(upto["received"], mask[first:last + 1])
        assert np.abs(upto[["w", "x", "y", "z"]].to_numpy() - batch[: last + 1 - first]).max() < 1e-8  # %.9g
        assert not mine[mine["sample"] > last]["received"].any()


def test_ctrl_c_ends_the_receiver_cleanly(tmp_path):
    recording = _recording(tmp_path, n=300)
    out = tmp_path / "out.csv"
    receiver, port = _start_receiver(out, "--latency", "10")
    try:
        _send(recording, port, tmp_path / "sent.npz", "--speed", "max", "--redundancy", "2")
        time.sleep(1.0)
        receiver.send_signal(signal.SIGINT)
        stdout, stderr = receiver.communicate(timeout=60)
    finally:
        receiver.kill()
    assert receiver.returncode == 0 and "Traceback" not in stderr, stderr
    assert "stopped: wrote" in stdout and "lost" in stdout
    rows = pd.read_csv(out)
    assert len(rows) >= 2 * 250 and rows.groupby("node")["sample"].apply(lambda s: s.is_monotonic_increasing).all()


def test_loss_spec():
    assert loss_spec("none") is None
    assert loss_spec("ge:0.1") == (0.1, 3.0) and loss_spec("ge:0.2:5") == (0.2, 5.0)
    for bad in ("ge", "ge:1.5", "ge:0.1:0.5", "burst:1:2", "ge:x"):
        with pytest.raises(Exception, match="not a loss"):
            loss_spec(bad)


def test_the_command_line_refuses_bad_arguments_with_a_message(tmp_path, capsys):
    from wsnlib.stream.__main__ import main

    recording = str(_recording(tmp_path, n=60))
    (tmp_path / "my_trial.mat").write_bytes(b"")  # a .mat file is read as a BROAD trial, by its name
    refusals = {
        ("send", str(tmp_path / "nothere.mat"), "--port", "5005"): "nothere.mat: no such file",
        ("send", str(tmp_path / "my_trial.mat"), "--port", "5005"): "my_trial.mat: unknown BROAD trial 'my_trial'",
        ("send", recording, "--port", "0"): "argument --port: '0': needs a whole number 1-65535",
        ("send", recording, "--port", "5005", "--samples-per-packet", "0"): "'0': needs a whole number 1-32",
        ("send", recording, "--port", "5005", "--fs", "-3"): "argument --fs: '-3': needs a number > 0",
        ("receive", "--port", "70000", "--out", str(tmp_path / "x.csv")): "'70000': needs a whole number 0-65535",
        ("send", recording, "--port", "5005", "--node", "65535"): "the recording's 2 nodes need ids up to 65535",
        ("send", recording, "--port", "5005", "--speed", "0"): "argument --speed: '0': needs a number > 0, or 'max'",
        ("receive", "--port", "0", "--out", "x.csv", "--latency", "-1"): "'-1': needs a whole number >= 0",
        ("receive", "--port", "0", "--out", "x.csv", "--reorder", "0"): "'0': needs a whole number >= 1",
        ("receive", "--port", "0", "--out", "x.csv", "--idle-exit", "-2"): "'-2': needs a number > 0",
    }
    for args, said in refusals.items():
        with pytest.raises(SystemExit) as stopped:
            main(list(args))
        code = stopped.value.code
        assert code not in (0, None), args
        assert said in capsys.readouterr().err + (code if isinstance(code, str) else ""), args
