"""Fixed-lag smoothing in the live receiver (issue 27): latency 0 is the causal filter, a latency as
long as the stream is the offline smoother, and the error falls towards it as the latency grows."""

import numpy as np
import pytest
from _recordings import FS, error_deg, swinging_recording, turning_recording

from wsnlib.loss import gilbert_elliott, packets_to_samples
from wsnlib.orientation import kalman_orientation, smooth_orientation
from wsnlib.stream import Receiver, ReceiverOutput, encode_stream, node_stream

SPP = 6


def _case(n=900, seed=3, fast=False, rate=0.2):
    gyr, acc, mag, quat = swinging_recording(n) if fast else turning_recording(n, seed=seed, noise=0.01)
    stream = node_stream(gyr, acc, mag, fs=FS)
    packets = gilbert_elliott(stream.n_packets, rate, 3.0, rng=np.random.default_rng(seed))
    packets[0] = packets[-1] = True
    return stream, packets, quat


def _receive(stream, packets, latency, order=None, **options):
    data = encode_stream(stream, packets=np.flatnonzero(packets))
    if order is not None:
        data = [data[i] for i in order]
    rx = Receiver(FS, latency=latency, **options)
    out = ReceiverOutput.concatenate([rx.receive(data), rx.flush()])
    np.testing.assert_array_equal(out.sample, np.arange(stream.n_samples))  # every sample once, in order
    return out


@pytest.mark.parametrize("fast", [False, True])
def test_latency_zero_is_the_filter_and_a_whole_stream_of_latency_the_smoother(fast):
    stream, packets, _ = _case(fast=fast)
    mask = packets_to_samples(packets, SPP, stream.n_samples)
    args = (stream.gyr, stream.acc, stream.mag)
    causal = kalman_orientation(*args, fs=FS, received=mask)
    offline = smooth_orientation(*args, fs=FS, received=mask, interpolate_gaps=False)
    assert np.abs(_receive(stream, packets, 0).quat - causal).max() <= 1e-9
    longest = _receive(stream, packets, stream.n_samples)
    assert np.abs(longest.quat - offline).max() <= 1e-9
    np.testing.assert_array_equal(longest.received, mask)
    assert np.abs(causal - offline).max() > 1e-2  # (the two ends differ: the test can tell them apart)


def test_the_output_approaches_the_smoother_as_the_latency_grows():
    """(Whether that lowers the error is the data's question: notebook 11 draws it on BROAD.)"""
    stream, packets, _ = _case(n=1500, seed=5, rate=0.2)
    mask = packets_to_samples(packets, SPP, stream.n_samples)
    offline = smooth_orientation(stream.gyr, stream.acc, stream.mag, fs=FS, received=mask, interpolate_gaps=False)
    distance = [error_deg(_receive(stream, packets, latency).quat, offline)[:-400].mean()  # (full lag there)
                for latency in (0, 5, 25, 100, 400)]
    assert all(a > b for a, b in zip(distance, distance[1:], strict=False)), distance
    assert distance[-1] < 0.15 * distance[0]  # (slowly: the bias states remember for long)


def test_fixed_lag_output_does_not_depend_on_the_order_inside_the_window():
    stream, packets, _ = _case(n=600, seed=8)
    in_order = _receive(stream, packets, 12, reorder=4)
    rng = np.random.default_rng(1)
    sent = np.flatnonzero(packets)
    keys = sent + rng.uniform(0.0, 4.0, sent.size)
    keys[0] = -1.0
    shuffled = _receive(stream, packets, 12, order=np.argsort(keys, kind="stable"), reorder=4)
    assert np.abs(shuffled.quat - in_order.quat).max() <= 1e-12
