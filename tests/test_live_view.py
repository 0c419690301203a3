"""The live view's session (wsnlib.live_view): a replay over UDP loopback into the receiver."""

import time
import types

import numpy as np
from _recordings import FS, turning_recording

from wsnlib import live_view
from wsnlib.orientation import kalman_orientation
from wsnlib.stream import udp
from wsnlib.studies.loss_tolerance import StudyRecording
from wsnlib.studies.streaming import NONE


def _unit(n=1500):
    gyr, acc, mag, quat = turning_recording(n, seed=3, noise=0.01)
    return StudyRecording(source="turning", node="imu", fs=FS, gyr=gyr, acc=acc, mag=mag, quat_ref=quat,
                          movement=np.ones(n, bool))


class _SlowBatches(udp.Batches):
    """A receiving thread that gets the core late: each read waits 0.2 s first (a busy machine)."""

    def read(self, sock, timeout_s):
        time.sleep(0.2)
        return super().read(sock, timeout_s)


def test_a_replay_as_fast_as_possible_is_the_batch_filter_however_late_the_receiver_runs(monkeypatch):
    """Sent as fast as possible (the notebook batch's figure), the session outputs, up to the last delivered
    packet, exactly the batch filter on the delivered samples — also when the receiving thread runs late
    (reads 0.2 s apart, 64 datagrams at a time, so the last is read long after the sender's linger) and its
    clock runs 1,000 times too fast (which would declare every waiting packet lost if it were used)."""
    monkeypatch.setattr(live_view, "Batches", lambda size: _SlowBatches(64))
    start = time.monotonic()
    racing = types.SimpleNamespace(monotonic=lambda: start + 1000.0 * (time.monotonic() - start), sleep=time.sleep)
    monkeypatch.setattr(live_view, "time", racing)  # the session's clock only (not the process's)
    unit = _unit()
    session = live_view.Session(unit, loss_rate=0.1, latency_s=0.0, scheme=NONE, seed=4, speed=None).start()
    assert session.done.wait(timeout=60)
    assert len(session.datagrams) > 3 * 64 and not session.delivered.all()  # several slow reads, some loss
    spp = session.stream.samples_per_packet
    last = int(np.flatnonzero(session.delivered)[-1] + 1) * spp - 1
    received = np.repeat(session.delivered, spp)[: session.n]
    values = session.stream.values
    batch = kalman_orientation(values[:, 0:3], values[:, 3:6], values[:, 6:9], fs=FS, received=received)
    assert session.output[: last + 1].all() and not session.output[last + 1:].any()
    np.testing.assert_array_equal(session.received[: last + 1], received[: last + 1])
    assert np.abs(session.quat[: last + 1] - batch[: last + 1]).max() < 1e-9
