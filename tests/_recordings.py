"""Exact signals of a smoothly turning sensor, shared by the Kalman filter and smoother tests."""

import numpy as np

from wsnlib import frames
from wsnlib import quaternion as Q

FS = 50.0


def _exact_signals(gyr):
    """``acc, mag, quat`` of a sensor turning at ``gyr`` from 0.3 rad about x, the truth
    integrated as the filter does."""
    quat = np.empty((len(gyr), 4))
    quat[0] = Q.from_axis_angle([1.0, 0.0, 0.0], 0.3)
    for k in range(1, len(gyr)):  # q_k = q_{k-1} ⊗ Exp(ω_k Δt)
        quat[k] = Q.normalize(Q.multiply(quat[k - 1], Q.from_rotation_vector(gyr[k] / FS)))
    acc = Q.rotate_inverse(quat, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(quat, np.broadcast_to(frames.magnetic_field_enu(), (len(gyr), 3)))
    return acc, mag, quat


def vertical_swing_recording(n):
    """``gyr, acc, mag, quat``: a swing of up to 4 rad/s about the vertical, slower about the other
    axes (angular accelerations up to ~18 rad/s²), exact signals."""
    t = np.arange(n) / FS
    gyr = np.stack([1.0 * np.sin(2 * np.pi * 0.5 * t), 0.5 * np.sin(2 * np.pi * 0.3 * t + 1.0),
                    4.0 * np.sin(2 * np.pi * 0.7 * t + 2.0)], axis=-1)
    return (gyr, *_exact_signals(gyr))


def swinging_recording(n=600, freq=1.5, amp=6.0):
    """``gyr, acc, mag, quat`` of a fast swing about a fixed body axis (rate ``amp`` rad/s at
    ``freq`` Hz), exact signals."""
    axis = np.array([0.2, 0.9, 0.39])
    gyr = amp * np.sin(2 * np.pi * freq * (np.arange(n) / FS))[:, None] * (axis / np.linalg.norm(axis))
    return (gyr, *_exact_signals(gyr))


def turning_recording(n=600, seed=0, noise=0.0):
    """``gyr, acc, mag, quat`` (rates ≤ ~1.5 rad/s), truth integrated as the filter does;
    ``noise`` > 0 adds white noise (and a 0.02 rad/s gyro bias)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    freqs, phases, amps = rng.uniform(0.1, 0.5, 3), rng.uniform(0, 2 * np.pi, 3), rng.uniform(0.5, 1.2, 3)
    gyr = amps * np.sin(2 * np.pi * freqs * t[:, None] + phases)
    acc, mag, quat = _exact_signals(gyr)
    if noise:
        gyr = gyr + rng.normal(0, noise, gyr.shape) + 0.02
        acc = acc + rng.normal(0, 10 * noise, acc.shape)
        mag = mag + rng.normal(0, 30 * noise, mag.shape)
    return gyr, acc, mag, quat


def error_deg(q_est, q_true):
    return np.degrees(Q.angle_between(q_est, q_true))
