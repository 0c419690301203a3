"""Offline smoother: RTS pass and Hermite gaps."""

from __future__ import annotations

import numpy as np
from _recordings import error_deg, turning_recording

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.orientation.kalman import kalman_orientation
from wsnlib.orientation.smoothing import SMOOTHER_SETTINGS, smooth_orientation

FS = 50.0


def test_smoother_equals_filter_at_the_end():
    gyr, acc, mag, _ = turning_recording(noise=0.02)
    received = np.ones(len(gyr), bool)
    received[100:130] = False
    received[300:320] = False
    filt = kalman_orientation(gyr, acc, mag, fs=FS, received=received, settings=SMOOTHER_SETTINGS)
    smooth = smooth_orientation(gyr, acc, mag, fs=FS, received=received)
    np.testing.assert_allclose(Q.canonical(smooth[-1]), Q.canonical(filt[-1]), atol=1e-12)
    assert not np.allclose(smooth[:-50], filt[:-50])  # ... and differs where later samples help


def test_trailing_gap_is_the_filters_extrapolation():
    gyr, acc, mag, _ = turning_recording(noise=0.02)
    received = np.ones(len(gyr), bool)
    received[-40:] = False
    filt = kalman_orientation(gyr, acc, mag, fs=FS, received=received, settings=SMOOTHER_SETTINGS)
    smooth = smooth_orientation(gyr, acc, mag, fs=FS, received=received)
    np.testing.assert_allclose(Q.canonical(smooth[-41]), Q.canonical(filt[-41]), atol=1e-12)
    # nothing after the last received sample: the smoother extrapolates as the filter does
    rel_s = Q.multiply(Q.conjugate(smooth[-41]), smooth[-40:])
    rel_f = Q.multiply(Q.conjugate(filt[-41]), filt[-40:])
    np.testing.assert_allclose(Q.canonical(rel_s), Q.canonical(rel_f), atol=1e-9)


def test_smoother_reduces_error_across_gaps():
    gyr, acc, mag, truth = turning_recording(noise=0.02)
    rng = np.random.default_rng(1)
    received = np.ones(len(gyr), bool)
    for start in rng.choice(np.arange(50, 550, 60), size=6, replace=False):
        received[start : start + 24] = False  # the paper's burst: 4 packets of 6 samples
    filt = kalman_orientation(gyr, acc, mag, fs=FS, received=received)
    smooth = smooth_orientation(gyr, acc, mag, fs=FS, received=received)
    rts_only = smooth_orientation(gyr, acc, mag, fs=FS, received=received, interpolate_gaps=False)
    lost = ~received
    rms = {name: np.sqrt(np.mean(error_deg(q, truth)[lost] ** 2)) for name, q in
           (("filter", filt), ("smoother", smooth), ("rts", rts_only))}
    assert rms["smoother"] < 0.5 * rms["filter"]
    assert rms["smoother"] <= rms["rts"]


def test_hermite_gap_matches_both_ends_and_is_exact_for_constant_rate():
    n = 200
    gyr = np.tile([0.3, -0.5, 0.8], (n, 1))
    quat = np.empty((n, 4))
    quat[0] = [1.0, 0.0, 0.0, 0.0]
    for k in range(1, n):
        quat[k] = Q.normalize(Q.multiply(quat[k - 1], Q.from_rotation_vector(gyr[k] / FS)))
    acc = Q.rotate_inverse(quat, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(quat, np.broadcast_to(frames.magnetic_field_enu(), (n, 3)))
    received = np.ones(n, bool)
    received[80:120] = False
    smooth = smooth_orientation(gyr, acc, mag, fs=FS, received=received)
    assert error_deg(smooth, quat)[80:120].max() < 0.5


def test_batch_shape_and_unit_norm():
    gyr, acc, mag, _ = turning_recording(n=150, noise=0.02)
    masks = np.random.default_rng(0).random((2, 150)) > 0.3
    masks[:, 0] = True
    out = smooth_orientation(gyr, acc, mag, fs=FS, received=masks)
    assert out.shape == (2, 150, 4)
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(out[1], smooth_orientation(gyr, acc, mag, fs=FS, received=masks[1]))
