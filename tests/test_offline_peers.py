"""Tests for wsnlib.orientation.offline_peers: offline VQF on a gap-filled recording and the
forward–backward average of a causal estimator.

References: exact signals of sensors with a known orientation (tests/_recordings.py: the truth
integrated from the gyroscope, accelerometer and magnetometer the truth's gravity and field in
the body frame), and that truth held over a gap (what a filter without a fill would show).
"""

import numpy as np
import pytest
from _recordings import FS, _exact_signals, error_deg, swinging_recording, turning_recording

from wsnlib.orientation import forward_backward_orientation, offline_vqf_orientation, vqf_orientation

N = 1000
#: A 1-second gap in the middle of the recording.
GAP = slice(475, 525)
#: VQF's start-up (its initial convergence) is not scored.
SETTLED = 250


@pytest.fixture(scope="module")
def turning():
    return turning_recording(n=N)


def _gap_mask(n=N):
    received = np.ones(n, bool)
    received[GAP] = False
    return received


def test_lossless_offline_vqf_follows_the_truth(turning):
    gyr, acc, mag, quat = turning
    error = error_deg(offline_vqf_orientation(gyr, acc, mag, fs=FS), quat)
    assert error[SETTLED:].max() < 2.0


def test_offline_vqf_is_batched_like_one_call_per_element(turning):
    gyr, acc, mag, _ = turning
    received = np.stack([_gap_mask(), np.ones(N, bool)])
    batched = offline_vqf_orientation(gyr, acc, mag, fs=FS, received=received)
    assert batched.shape == (2, N, 4)
    for k in range(2):
        one = offline_vqf_orientation(gyr, acc, mag, fs=FS, received=received[k])
        np.testing.assert_allclose(batched[k], one, atol=1e-12)


@pytest.mark.parametrize("rate_profile", ["constant", "linear"])
def test_offline_vqf_fills_a_gap_in_a_turn(rate_profile):
    """A 1-s gap in a turn whose rate is constant or changes linearly: the linear fill of the
    gyroscope is exact there (a held rate is not, for the linear one), so the error on the lost
    samples stays small, while the truth held from the gap's start is tens of degrees off."""
    axis = np.array([0.3, -0.5, 0.9])
    scale = np.ones(N) if rate_profile == "constant" else np.linspace(0.2, 2.0, N)
    gyr = scale[:, None] * axis
    acc, mag, quat = _exact_signals(gyr)
    received = _gap_mask()
    gyr[~received] = acc[~received] = mag[~received] = np.nan  # lost samples are never read
    error = error_deg(offline_vqf_orientation(gyr, acc, mag, fs=FS, received=received), quat)
    held = error_deg(quat[GAP.start - 1], quat[GAP])
    assert error[GAP].max() < 2.0
    assert held.mean() > 20.0


def test_offline_vqf_holds_its_output_outside_the_received_span(turning):
    """Outside the span of received samples nothing is made up: the output there is the one at
    the span's end, and inside it is offline VQF of the span alone."""
    gyr, acc, mag, _ = turning
    received = np.zeros(N, bool)
    received[300:700] = True
    out = offline_vqf_orientation(gyr, acc, mag, fs=FS, received=received)
    span = offline_vqf_orientation(gyr[300:700], acc[300:700], mag[300:700], fs=FS)
    np.testing.assert_allclose(out[300:700], span, atol=1e-12)
    np.testing.assert_allclose(out[:300], np.broadcast_to(span[0], (300, 4)), atol=1e-12)
    np.testing.assert_allclose(out[700:], np.broadcast_to(span[-1], (300, 4)), atol=1e-12)


def test_forward_backward_of_a_lossless_recording_follows_the_truth(turning):
    """Both runs, the backward one alone too: a gyroscope not negated (or not reversed) on the
    time-reversed recording turns the backward run the wrong way, far from the truth."""
    gyr, acc, mag, quat = turning
    runs = []

    def recording_vqf(*args, **kwargs):
        out = vqf_orientation(*args, **kwargs)
        runs.append(out)
        return out

    averaged = forward_backward_orientation(recording_vqf, gyr, acc, mag, fs=FS)
    backward = runs[1][::-1]
    assert error_deg(backward, quat)[:-SETTLED].max() < 4.0
    assert error_deg(averaged, quat)[SETTLED:-SETTLED].max() < 3.0
    # the premise: the same backward run with the gyroscope's sign kept is far off
    wrong = vqf_orientation(gyr[::-1], acc[::-1], mag[::-1], fs=FS)[::-1]
    assert error_deg(wrong, quat)[:-SETTLED].mean() > 30.0


def test_forward_backward_beats_the_forward_run_on_a_gap_in_a_swing():
    """A 1-s gap over a swing's turning point: each run alone extrapolates the rate from its
    side of the gap; the average, weighted towards the run that saw a sample more recently, is
    closer to the truth on the lost samples (an unweighted midpoint is not, here)."""
    gyr, acc, mag, quat = swinging_recording(n=N, freq=0.5, amp=2.0)
    received = _gap_mask()
    forward = vqf_orientation(gyr, acc, mag, fs=FS, received=received, gap="constant_rate")
    averaged = forward_backward_orientation(vqf_orientation, gyr, acc, mag, fs=FS, received=received,
                                            gap="constant_rate")
    forward_error = error_deg(forward, quat)[GAP].mean()
    assert forward_error > 10.0
    assert error_deg(averaged, quat)[GAP].mean() < 0.7 * forward_error


def test_forward_backward_weights_each_run_by_its_distance_to_a_received_sample(turning):
    """Two fake runs, the truth forwards and the identity backwards: on received samples the
    midpoint, before the first received sample the backward run, after the last the forward."""
    gyr, acc, mag, quat = turning
    identity = np.zeros_like(quat)
    identity[:, 0] = 1.0
    calls = []

    def fake(g, a, m, *, fs, received):
        calls.append(received)
        return quat if len(calls) == 1 else identity

    received = np.ones(N, bool)
    received[:10] = received[-10:] = False
    out = forward_backward_orientation(fake, gyr, acc, mag, fs=FS, received=received)
    np.testing.assert_array_equal(calls[1], received[::-1])
    np.testing.assert_allclose(error_deg(out[:10], identity[:10]), 0.0, atol=1e-9)
    np.testing.assert_allclose(error_deg(out[-10:], quat[-10:]), 0.0, atol=1e-9)
    half = error_deg(out[10:-10], quat[10:-10])
    np.testing.assert_allclose(half, 0.5 * error_deg(identity[10:-10], quat[10:-10]), atol=1e-9)


def test_forward_backward_refuses_a_6d_estimator(turning):
    gyr, acc, _, _ = turning
    with pytest.raises(ValueError, match="needs mag"):
        forward_backward_orientation(vqf_orientation, gyr, acc, fs=FS)


@pytest.mark.parametrize("function", [offline_vqf_orientation, forward_backward_orientation])
def test_no_received_sample_is_refused(turning, function):
    gyr, acc, mag, _ = turning
    received = np.ones((2, N), bool)
    received[1] = False
    args = (gyr, acc, mag) if function is offline_vqf_orientation else (vqf_orientation, gyr, acc, mag)
    with pytest.raises(ValueError, match="no received sample for batch element"):
        function(*args, fs=FS, received=received)


@pytest.mark.parametrize("function", [offline_vqf_orientation, forward_backward_orientation])
def test_a_mask_of_the_wrong_length_is_refused(turning, function):
    gyr, acc, mag, _ = turning
    args = (gyr, acc, mag) if function is offline_vqf_orientation else (vqf_orientation, gyr, acc, mag)
    with pytest.raises(ValueError, match=r"received must have shape \(\.\.\., 1000\)"):
        function(*args, fs=FS, received=np.ones(N - 1, bool))


def test_offline_vqf_refuses_unknown_params(turning):
    gyr, acc, mag, _ = turning
    with pytest.raises(ValueError, match="unknown key 'tauAccel'"):
        offline_vqf_orientation(gyr, acc, mag, fs=FS, params={"tauAccel": 1.0})


def test_forward_backward_refuses_a_non_callable_estimator(turning):
    gyr, acc, mag, _ = turning
    with pytest.raises(ValueError, match="estimate must be a callable"):
        forward_backward_orientation("vqf", gyr, acc, mag, fs=FS)
