"""Packets that carry their own redundancy (issue 27): the summaries, the bridge step, and the receiver
bridging bursts with them — causal outputs of lost samples unchanged, the state after the burst and
(with latency) the lost samples themselves close to the lossless filter."""

import numpy as np
import pytest
from _recordings import FS, _exact_signals, error_deg, swinging_recording, turning_recording

from wsnlib import quaternion as Q
from wsnlib.orientation import KalmanSettings, bridging, kalman_initial_state
from wsnlib.stream import Receiver, ReceiverOutput, encode_stream, node_stream
from wsnlib.stream.simulation import packets_sent_twice, receiver_output

SPP = 6


def _jerky(n=2400, seed=0):
    """``gyr, acc, mag, quat`` of band-limited random rates (≈ 3 rad/s, changes within 0.2 s): motion a
    predictor through a gap cannot foresee; exact signals."""
    rng = np.random.default_rng(seed)
    kernel = np.hanning(15)
    gyr = np.stack([np.convolve(rng.normal(0, 1, n + 14), kernel, "valid") for _ in range(3)], axis=1)
    gyr *= 3.0 / np.sqrt(np.mean(np.sum(gyr**2, axis=1)))
    return (gyr, *_exact_signals(gyr))


def test_summaries_are_the_rotations_of_the_covered_packets():
    gyr, acc, mag, _ = swinging_recording(300)
    for layout, covered in (("consecutive", lambda p, j: (p - 1 - j, p - 1 - j)),
                            ("doubling", lambda p, j: (p - 2**j, p - 1))):
        stream = node_stream(gyr, acc, mag, fs=FS, redundancy=4, bits=16, layout=layout)
        assert list(stream.summary_k[:10]) == ([0, 1, 2, 3, 4, 4, 4, 4, 4, 4] if layout == "consecutive"
                                               else [0, 1, 2, 2, 3, 3, 3, 3, 4, 4])
        for p in (9, 30, 47):
            for j in range(4):
                first, last = covered(p, j)
                q = np.array([1.0, 0.0, 0.0, 0.0])
                for w in stream.gyr[first * SPP:(last + 1) * SPP]:  # Π Exp(ω Δt) of the dequantised rates
                    q = Q.normalize(Q.multiply(q, Q.from_rotation_vector(w / FS)))
                got = Q.from_rotation_vector(stream.summaries[p, j])
                assert np.degrees(Q.angle_between(got, q)) <= np.degrees(stream.rotation_scale[p])


def test_bridge_step_turns_by_the_measured_rotation_and_grows_the_covariance_as_stated():
    settings = KalmanSettings(initial_bias_sigma=1e-9)  # (the bias prior's share of the growth is left out)
    state = kalman_initial_state(fs=FS, settings=settings, q0=Q.from_axis_angle([0.0, 1.0, 0.0], 0.4))
    rotation, k, sigma = np.array([0.3, -0.8, 0.5]), 12, 0.01
    bridge_c = state.constants.copy()
    q0, p0 = state.quat.copy(), state.covariance.copy()
    for run in range(1, k + 1):
        bridging.bridge_step(state.record[0], state.gap[0], state.history, state.work[0], state.constants[0],
                             bridge_c[0], tuple(rotation * FS / k), sigma, run, np.empty((0, 4)))
    expected = Q.multiply(q0, Q.from_rotation_vector(rotation))
    assert np.abs(state.quat - expected).max() < 1e-12 or np.abs(state.quat + expected).max() < 1e-12
    c = state.constants[0]
    grown = np.diag(state.covariance)[:3] - np.diag(p0)[:3]  # gyro noise and the summary's rate error
    np.testing.assert_allclose(grown, k * c["gyro_var"] + (sigma * k / FS) ** 2, rtol=1e-3)


def _bursts(n_packets, lengths, start=20, spacing=60):
    packets = np.ones(n_packets, bool)
    for i, length in enumerate(lengths):
        packets[start + i * spacing: start + i * spacing + length] = False
    return packets


def _outputs(stream, packets, latency=0, bridge=True):
    rx = Receiver(FS, latency=latency, bridge=bridge)
    out = ReceiverOutput.concatenate([rx.receive(encode_stream(stream, packets=np.flatnonzero(packets))),
                                      rx.flush()])
    assert np.array_equal(out.sample, np.arange(stream.n_samples))
    return out


def _burst_ranges(packets):
    edges = np.diff(np.concatenate([[0], (~packets).astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _predicted(stream, packets, end):
    """The output for the lost packets just before packet ``end`` by a receiver that never gets ``end``
    (or anything later): its clock declares them lost."""
    rx = Receiver(FS, reorder=1)
    sent = np.flatnonzero(packets[:end])
    outs = [rx.receive([d], (p + 1) * SPP / FS) for p, d in zip(sent, encode_stream(stream, packets=sent),
                                                                 strict=True)]
    out = ReceiverOutput.concatenate(outs + [rx.expire((end + 1) * SPP / FS + 1e-6)])
    burst = out.sample >= sent[-1] * SPP + SPP
    assert out.sample[burst][-1] == end * SPP - 1
    return out.quat[burst]


def _after_gaps(packets, n_samples, seconds=1.0):
    mask = np.repeat(packets, SPP)[:n_samples]
    ends = np.flatnonzero(mask[1:] & ~mask[:-1]) + 1
    after = np.zeros(n_samples, bool)
    for e in ends:
        after[e: e + int(seconds * FS)] = True
    return after & mask


def test_bridging_keeps_the_causal_output_of_lost_samples_and_restores_the_state_after_the_burst():
    gyr, acc, mag, truth = _jerky()
    stream = node_stream(gyr, acc, mag, fs=FS, redundancy=4, bits=12, layout="doubling")
    packets = _bursts(stream.n_packets, [1, 2, 3, 5, 8, 4, 6])
    lossless = _outputs(stream, np.ones(stream.n_packets, bool)).quat
    bridged, plain = _outputs(stream, packets).quat, _outputs(stream, packets, bridge=False).quat
    for start, stop in _burst_ranges(packets):  # lost samples: the prediction before the packet after them came
        np.testing.assert_array_equal(bridged[start * SPP: stop * SPP], _predicted(stream, packets, stop))
    after = _after_gaps(packets, stream.n_samples)
    gap_error = error_deg(plain[after], lossless[after]).mean()
    assert gap_error > 2.0  # the swing makes the prediction through the gaps go wrong
    assert error_deg(bridged[after], lossless[after]).mean() < 0.1 * gap_error


def test_with_latency_the_lost_samples_themselves_are_filled():
    gyr, acc, mag, truth = _jerky(seed=1)
    stream = node_stream(gyr, acc, mag, fs=FS, redundancy=4, bits=12, layout="doubling")
    packets = _bursts(stream.n_packets, [2, 3, 4, 4, 3, 2])
    lost = ~np.repeat(packets, SPP)[:stream.n_samples]
    latency = 4 * SPP + 6  # longer than every burst
    plain = _outputs(stream, packets, latency, bridge=False).quat
    bridged = _outputs(stream, packets, latency).quat
    assert error_deg(bridged[lost], truth[lost]).mean() < 0.4 * error_deg(plain[lost], truth[lost]).mean()


@pytest.mark.parametrize("layout,k,covers_five", [("doubling", 4, True), ("consecutive", 4, False),
                                                  ("consecutive", 5, True)])
def test_a_burst_of_five_packets_is_bridged_by_four_doubling_entries(layout, k, covers_five):
    gyr, acc, mag, _ = _jerky(seed=2)
    stream = node_stream(gyr, acc, mag, fs=FS, redundancy=k, bits=12, layout=layout)
    packets = _bursts(stream.n_packets, [5] * 6)
    lossless = _outputs(stream, np.ones(stream.n_packets, bool)).quat
    after = _after_gaps(packets, stream.n_samples)
    plain = error_deg(_outputs(stream, packets, bridge=False).quat[after], lossless[after]).mean()
    bridged = error_deg(_outputs(stream, packets).quat[after], lossless[after]).mean()
    assert (bridged < 0.1 * plain) == covers_five  # consecutive 4 leaves the burst's first packet to prediction
    assert bridged < plain


def test_the_simulation_is_the_receiver():
    gyr, acc, mag, _ = turning_recording(900, seed=3, noise=0.01)
    stream = node_stream(gyr, acc, mag, fs=FS, redundancy=3, bits=10)
    packets = np.random.default_rng(2).random(stream.n_packets) > 0.25
    packets[:2] = [False, True]
    last = np.flatnonzero(packets)[-1] * SPP + SPP - 1
    simulated = receiver_output(stream, packets, latencies=[0, 10, 50])
    for i, latency in enumerate([0, 10, 50]):
        out = _outputs_from(stream, packets, latency)
        keep = out.sample <= last
        assert np.abs(out.quat[keep] - simulated[i, out.sample[keep]]).max() <= 1e-12
    np.testing.assert_array_equal(simulated[:, :SPP], np.repeat(simulated[:, SPP:SPP + 1], SPP, axis=1))


def _outputs_from(stream, packets, latency):
    rx = Receiver(FS, latency=latency)
    return ReceiverOutput.concatenate([rx.receive(encode_stream(stream, packets=np.flatnonzero(packets))),
                                      rx.flush()])


def test_sending_twice_loses_a_packet_only_when_both_slots_are_lost():
    slots = np.array([1, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1], bool)
    np.testing.assert_array_equal(packets_sent_twice(slots), [1, 0, 1, 1, 1, 1, 1, 0, 0, 1])
    with pytest.raises(ValueError, match="no packet"):
        receiver_output(node_stream(*swinging_recording(60)[:3], fs=FS), np.zeros(10, bool))
