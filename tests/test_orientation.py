"""Tests for wsnlib.orientation: Madgwick's filter and TRIAD.

References: ``ahrs.filters.Madgwick`` (same report, NWU earth frame), a direct restatement
of the report's matrices for one step, and ``scipy.spatial.transform.Rotation``.
"""

import numpy as np
import pytest
from ahrs.filters import Madgwick
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.orientation import _scalar_kernels, madgwick, madgwick_step, tilt_quaternion, triad
from wsnlib.orientation.madgwick import Q_ENU_FROM_NWU

G_ENU = frames.gravity_specific_force_enu()
M_ENU = frames.magnetic_field_enu()
FS = 50.0


def nwu_from_enu(q):
    return Q.multiply(Q.conjugate(Q_ENU_FROM_NWU), q)


def enu_from_nwu(q):
    return Q.multiply(Q_ENU_FROM_NWU, q)


def recording(rng, n=300, fs=FS, noise=True, rate=1.0):
    """Smooth random motion: true ENU quaternions and the body-frame gyr, acc, mag.

    The true orientation is integrated exactly from a smooth body rate, so ``gyr`` is
    consistent with it; ``noise`` adds white noise to all three sensors.
    """
    t = np.arange(n) / fs
    freq = rng.uniform(0.1, 0.8, size=(3, 1))
    phase = rng.uniform(0, 2 * np.pi, size=(3, 1))
    omega = (rate * np.sin(2 * np.pi * freq * t + phase)).T + 0.05  # never exactly zero
    q = np.empty((n, 4))
    q[0] = Q.from_scipy(Rotation.random(rng=rng))
    for k in range(1, n):
        q[k] = Q.multiply(q[k - 1], Q.from_rotation_vector(omega[k] / fs))
    acc = Q.rotate_inverse(q, G_ENU)
    mag = Q.rotate_inverse(q, M_ENU)
    gyr = omega
    if noise:
        gyr = gyr + rng.normal(0, 0.02, gyr.shape)
        acc = acc + rng.normal(0, 0.3, acc.shape)
        mag = mag + rng.normal(0, 1.5, mag.shape)
    return q, gyr, acc, mag


def angle_deg(q_a, q_b):
    return np.degrees(Q.angle_between(q_a, q_b))


def tilt_deg(q_a, q_b):
    """Angle between the earth-up directions seen by the two orientations (heading-free)."""
    up_a, up_b = Q.rotate_inverse(q_a, [0, 0, 1.0]), Q.rotate_inverse(q_b, [0, 0, 1.0])
    return np.degrees(np.arccos(np.clip(np.sum(up_a * up_b, axis=-1), -1, 1)))


# ================================================================ frames


def test_frame_change_maps_north_to_enu_y():
    np.testing.assert_allclose(Q.rotate(Q_ENU_FROM_NWU, [1.0, 0, 0]), [0, 1.0, 0], atol=1e-15)
    np.testing.assert_allclose(Q.rotate(Q_ENU_FROM_NWU, [0, 1.0, 0]), [-1.0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(Q.rotate(Q_ENU_FROM_NWU, [0, 0, 1.0]), [0, 0, 1.0], atol=1e-15)


# ================================================================ TRIAD


def test_triad_recovers_true_orientation_and_matches_align_vectors(rng):
    q_true = Q.from_scipy(Rotation.random(200, rng=rng))
    acc, mag = Q.rotate_inverse(q_true, G_ENU), Q.rotate_inverse(q_true, M_ENU)
    q = triad(acc, mag)
    np.testing.assert_allclose(np.abs(np.sum(q * q_true, axis=-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    for i in range(0, 200, 20):
        ref, _ = Rotation.align_vectors([G_ENU, M_ENU], [acc[i], mag[i]])
        assert angle_deg(q[i], Q.from_scipy(ref)) < 1e-9


def test_triad_with_noise_equals_align_vectors_with_gravity_primary(rng):
    # TRIAD matches the primary vector exactly and the secondary as well as it can, which
    # is what align_vectors does with an infinite weight on the first pair.
    q_true = Q.from_scipy(Rotation.random(50, rng=rng))
    acc = Q.rotate_inverse(q_true, G_ENU) + rng.normal(0, 0.5, (50, 3))
    mag = Q.rotate_inverse(q_true, M_ENU) + rng.normal(0, 5.0, (50, 3))
    q = triad(acc, mag)
    up = Q.rotate(q, acc / np.linalg.norm(acc, axis=-1, keepdims=True))
    np.testing.assert_allclose(up, np.broadcast_to([0, 0, 1.0], up.shape), atol=1e-12)
    for i in range(50):
        ref, _ = Rotation.align_vectors(
            [G_ENU / 9.80665, M_ENU / 46.0],
            [acc[i] / np.linalg.norm(acc[i]), mag[i] / np.linalg.norm(mag[i])],
            weights=[np.inf, 1.0],
        )
        assert angle_deg(q[i], Q.from_scipy(ref)) < 1e-7


def test_triad_shapes_and_broadcasting(rng):
    q_true, _, acc, mag = recording(rng, n=12, noise=False)
    out = triad(np.stack([acc, acc]), mag)
    assert out.shape == (2, 12, 4)
    np.testing.assert_allclose(out[1], triad(acc, mag), atol=1e-15)
    assert triad(acc[0], mag[0]).shape == (4,)
    assert np.all(out[..., 0] >= 0.0)


@pytest.mark.parametrize(
    "acc, mag, name",
    [
        ([0.0, 0.0, 0.0], [0.0, 20.0, -30.0], "acc"),
        ([0.0, 0.0, 9.8], [0.0, 0.0, 0.0], "mag"),
        ([np.nan, 0.0, 9.8], [0.0, 20.0, -30.0], "acc"),
        ([0.0, 0.0, 9.8], [0.0, np.inf, -30.0], "mag"),
        ([0.0, 9.8], [0.0, 20.0, -30.0], "acc"),
        ([0.0, 0.0, 9.8], [0.0, 0.0, -30.0], "parallel"),
        (np.ones((2, 3)), np.ones((3, 3)) + [0, 0, 1], "broadcast"),
    ],
)
def test_triad_errors(acc, mag, name):
    with pytest.raises(ValueError, match=name):
        triad(acc, mag)


def test_tilt_quaternion_zero_heading(rng):
    q_true = Q.from_scipy(Rotation.random(100, rng=rng))
    acc = 9.81 * Q.rotate_inverse(q_true, [0, 0, 1.0])
    q = tilt_quaternion(acc)
    up = Q.rotate(q, acc / 9.81)
    np.testing.assert_allclose(up, np.broadcast_to([0, 0, 1.0], up.shape), atol=1e-12)
    # Smallest rotation: its axis is horizontal, so no twist about the vertical.
    np.testing.assert_allclose(q[:, 3], 0.0, atol=1e-15)
    np.testing.assert_allclose(tilt_quaternion([0, 0, 9.81]), [1.0, 0, 0, 0])
    np.testing.assert_allclose(tilt_quaternion([0, 0, -9.81]), [0.0, 1.0, 0, 0])
    flip = tilt_quaternion([1e-9, 0, -9.81])
    np.testing.assert_allclose(Q.rotate(flip, [1e-9 / 9.81, 0, -1.0]), [0, 0, 1.0], atol=1e-9)
    with pytest.raises(ValueError, match="acc"):
        tilt_quaternion([0.0, 0.0, 0.0])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_triad_inverts_the_sensor_model(seed):
    q_true = Q.from_scipy(Rotation.random(rng=np.random.default_rng(seed)))
    q = triad(Q.rotate_inverse(q_true, G_ENU), Q.rotate_inverse(q_true, M_ENU))
    assert angle_deg(q, q_true) < 1e-6


# ================================================================ Madgwick: references


def ahrs_reference(gyr, acc, mag, q0, beta, fs=FS):
    """ahrs' per-sample updates from q0 (NWU), converted back to ENU."""
    filt = Madgwick(frequency=fs, gain=beta)
    q = nwu_from_enu(q0)
    out = []
    for t in range(len(gyr)):
        if mag is None:
            q = filt.updateIMU(q, gyr[t], acc[t])
        else:
            q = filt.updateMARG(q, gyr[t], acc[t], mag[t])
        out.append(q)
    return enu_from_nwu(np.array(out))


@pytest.mark.parametrize("form", ["MARG", "IMU"])
def test_madgwick_matches_ahrs(rng, form):
    _, gyr, acc, mag = recording(rng, n=300)
    mag = mag if form == "MARG" else None
    q0 = Q.from_scipy(Rotation.random(rng=rng))
    ours = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0)
    ref = ahrs_reference(gyr, acc, mag, q0, beta=0.1)
    np.testing.assert_allclose(ours, ref, atol=1e-9, rtol=0)


def report_step_nwu(q, gyr, acc, mag, dt, beta):
    """Eqs. (11), (25)-(34), (42)-(46) of the report, written as matrices, one sample."""
    qw, qx, qy, qz = q
    a = acc / np.linalg.norm(acc)
    f = [2 * (qx * qz - qw * qy) - a[0], 2 * (qw * qx + qy * qz) - a[1],
         2 * (0.5 - qx**2 - qy**2) - a[2]]  # fmt: skip
    jac = [[-2 * qy, 2 * qz, -2 * qw, 2 * qx], [2 * qx, 2 * qw, 2 * qz, 2 * qy],
           [0, -4 * qx, -4 * qy, 0]]  # fmt: skip
    if mag is not None:
        m = mag / np.linalg.norm(mag)
        h = Q.multiply(Q.multiply(q, np.r_[0.0, m]), Q.conjugate(q))  # eq. (45)
        bx, bz = np.hypot(h[1], h[2]), h[3]  # eq. (46): b_x itself, not 2 b_x
        f += [
            2 * bx * (0.5 - qy**2 - qz**2) + 2 * bz * (qx * qz - qw * qy) - m[0],
            2 * bx * (qx * qy - qw * qz) + 2 * bz * (qw * qx + qy * qz) - m[1],
            2 * bx * (qw * qy + qx * qz) + 2 * bz * (0.5 - qx**2 - qy**2) - m[2],
        ]
        jac += [
            [-2 * bz * qy, 2 * bz * qz, -4 * bx * qy - 2 * bz * qw, -4 * bx * qz + 2 * bz * qx],
            [-2 * bx * qz + 2 * bz * qx, 2 * bx * qy + 2 * bz * qw, 2 * bx * qx + 2 * bz * qz,
             -2 * bx * qw + 2 * bz * qy],
            [2 * bx * qy, 2 * bx * qz - 4 * bz * qx, 2 * bx * qw - 4 * bz * qy, 2 * bx * qx],
        ]  # fmt: skip
    grad = np.array(jac).T @ np.array(f)
    q_dot = 0.5 * Q.multiply(q, np.r_[0.0, gyr]) - beta * grad / np.linalg.norm(grad)
    q_new = q + q_dot * dt
    return q_new / np.linalg.norm(q_new)


@pytest.mark.parametrize("form", ["MARG", "IMU"])
def test_madgwick_step_matches_report_restatement(rng, form):
    _, gyr, acc, mag = recording(rng, n=20)
    q = Q.from_scipy(Rotation.random(20, rng=rng))
    mag = mag if form == "MARG" else None
    ours = madgwick_step(q, gyr, acc, mag, 0.02, 0.3)
    for i in range(20):
        ref = report_step_nwu(
            nwu_from_enu(q[i]), gyr[i], acc[i], None if mag is None else mag[i], 0.02, 0.3
        )
        np.testing.assert_allclose(ours[i], enu_from_nwu(ref), atol=1e-13)


def _gradient(q_nwu, acc, mag):
    """The compiled gradient, sample by sample, component axis first (4, N)."""
    return np.array([_scalar_kernels.madgwick_gradient(tuple(q), tuple(a), tuple(m), True)
                     for q, a, m in zip(q_nwu.T, acc.T, mag.T, strict=True)]).T


def test_gradient_vanishes_at_the_true_orientation(rng):
    # With consistent acc and mag the report's b = [0, √(h_x²+h_y²), 0, h_z] reproduces the
    # measured field, so f = 0 and ∇f = 0.  The C-port variant (b_x, b_z halved) fails.
    q_true = Q.from_scipy(Rotation.random(50, rng=rng))
    acc = Q.rotate_inverse(q_true, G_ENU / 9.80665)
    mag = Q.rotate_inverse(q_true, M_ENU / 46.0)
    grad = np.array(_gradient(nwu_from_enu(q_true).T, acc.T, mag.T))
    np.testing.assert_allclose(grad, 0.0, atol=1e-14)
    # ...and it does not vanish elsewhere.
    q_off = Q.multiply(q_true, Q.from_axis_angle([0, 0, 1.0], 0.2))
    grad_off = np.array(_gradient(nwu_from_enu(q_off).T, acc.T, mag.T))
    assert np.all(np.linalg.norm(grad_off, axis=0) > 1e-3)


# ================================================================ Madgwick: behaviour


@pytest.mark.parametrize("form", ["MARG", "IMU"])
def test_stationary_converges_from_wrong_start(rng, form):
    q_true = Q.from_scipy(Rotation.random(rng=rng))
    n, fs, beta = 600, 100.0, 0.5
    acc = np.tile(Q.rotate_inverse(q_true, G_ENU), (n, 1))
    mag = np.tile(Q.rotate_inverse(q_true, M_ENU), (n, 1)) if form == "MARG" else None
    gyr = np.zeros((n, 3))
    q0 = Q.multiply(q_true, Q.from_axis_angle([1.0, -2.0, 0.5], np.radians(60)))
    out = madgwick(gyr, acc, mag, fs=fs, beta=beta, q0=q0)
    bound = np.degrees(2 * beta / fs) + 0.1  # normalised-gradient chatter, see module notes
    if form == "MARG":
        assert angle_deg(out[0], q_true) > 50
        assert np.all(angle_deg(out[-50:], q_true) < bound)
    else:
        assert np.all(tilt_deg(out[-50:], q_true) < bound)


def test_constant_rate_tracks_truth(rng):
    n, fs = 1000, 100.0
    omega = np.array([0.4, -0.3, 0.8])
    q_true = np.empty((n, 4))
    q_true[0] = Q.from_scipy(Rotation.random(rng=rng))
    for k in range(1, n):
        q_true[k] = Q.multiply(q_true[k - 1], Q.from_rotation_vector(omega / fs))
    acc, mag = Q.rotate_inverse(q_true, G_ENU), Q.rotate_inverse(q_true, M_ENU)
    gyr = np.tile(omega, (n, 1))
    out = madgwick(gyr, acc, mag, fs=fs, beta=0.1)
    assert angle_deg(out[0], q_true[0]) < 1e-9  # TRIAD start
    # The normalised gradient keeps the estimate chattering at a few β/fs around the truth.
    err = angle_deg(out, q_true)
    assert np.max(err) < 1.0
    assert np.mean(err[500:]) < 0.6


def test_noisy_recording_stays_close(rng):
    q_true, gyr, acc, mag = recording(rng, n=500)
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1)
    assert np.sqrt(np.mean(angle_deg(out, q_true) ** 2)) < 5.0


# ================================================================ Madgwick: packet loss


@pytest.fixture
def rec(rng):
    return recording(rng, n=120)


@pytest.mark.parametrize("with_q0", [False, True])
@pytest.mark.parametrize("form", ["MARG", "IMU"])
def test_all_received_equals_no_mask(rec, with_q0, form):
    _, gyr, acc, mag = rec
    mag = mag if form == "MARG" else None
    q0 = [0.5, 0.5, 0.5, 0.5] if with_q0 else None
    full = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0)
    masked = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0, received=np.ones(120, bool))
    np.testing.assert_array_equal(masked, full)


def test_lost_samples_hold_the_previous_output(rec, rng):
    _, gyr, acc, mag = rec
    received = rng.random(120) > 0.3
    received[0] = True
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=received)
    lost = np.flatnonzero(~received)
    np.testing.assert_array_equal(out[lost], out[lost - 1])
    # The filter just skips lost samples: same as running on the received ones only.
    kept = madgwick(gyr[received], acc[received], mag[received], fs=FS, beta=0.1)
    np.testing.assert_array_equal(out[received], kept)


def test_all_lost_with_q0_returns_q0(rec):
    _, gyr, acc, mag = rec
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2])
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0, received=np.zeros(120, bool))
    np.testing.assert_allclose(out, np.broadcast_to(q0, out.shape), atol=1e-15, rtol=0)


def test_all_lost_without_q0_raises(rec):
    _, gyr, acc, mag = rec
    received = np.ones((3, 120), bool)
    received[1] = False
    with pytest.raises(ValueError, match="received.*\\(1,\\).*q0"):
        madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=received)


@pytest.mark.parametrize("with_q0", [False, True])
def test_first_sample_lost(rec, with_q0):
    _, gyr, acc, mag = rec
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2]) if with_q0 else None
    received = np.ones(120, bool)
    received[:3] = False
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0, received=received)
    tail = madgwick(gyr[3:], acc[3:], mag[3:], fs=FS, beta=0.1, q0=q0)
    np.testing.assert_allclose(out[3:], tail, atol=1e-15, rtol=0)
    start = q0 if with_q0 else triad(acc[3], mag[3])  # the initial estimate
    np.testing.assert_allclose(out[:3], np.broadcast_to(start, (3, 4)), atol=1e-15, rtol=0)


def test_last_sample_lost(rec):
    _, gyr, acc, mag = rec
    received = np.ones(120, bool)
    received[-1] = False
    acc = acc.copy()
    acc[-1] = np.nan
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=received)
    np.testing.assert_array_equal(out[-1], out[-2])
    np.testing.assert_array_equal(out[:-1], madgwick(gyr[:-1], acc[:-1], mag[:-1], fs=FS, beta=0.1))


@pytest.mark.parametrize("signal", ["gyr", "acc", "mag"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_lost_sample_is_fine_received_raises(rec, signal, bad):
    _, gyr, acc, mag = rec
    data = {"gyr": gyr.copy(), "acc": acc.copy(), "mag": mag.copy()}
    data[signal][50] = [0.0, bad, 1.0]
    received = np.ones(120, bool)
    received[50] = False
    out = madgwick(**data, fs=FS, beta=0.1, received=received)
    assert np.all(np.isfinite(out))
    with pytest.raises(ValueError, match=signal):
        madgwick(**data, fs=FS, beta=0.1)


def test_zero_vectors_in_lost_samples_are_fine(rec):
    _, gyr, acc, mag = rec
    acc, mag = acc.copy(), mag.copy()
    acc[10] = 0.0
    mag[11] = 0.0
    received = np.ones(120, bool)
    received[10:12] = False
    assert np.all(np.isfinite(madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=received)))


@pytest.mark.parametrize("form", ["MARG", "IMU"])
def test_one_recording_with_a_batch_of_masks(rec, rng, form):
    _, gyr, acc, mag = rec
    mag = mag if form == "MARG" else None
    masks = rng.random((6, 120)) > 0.4
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=masks)
    assert out.shape == (6, 120, 4)
    for i in range(6):
        one = madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=masks[i])
        np.testing.assert_allclose(out[i], one, atol=1e-14, rtol=0)


def test_batched_recordings_equal_one_at_a_time(rng):
    recs = [recording(rng, n=80) for _ in range(6)]
    gyr, acc, mag = (np.stack([r[k] for r in recs]).reshape(2, 3, 80, 3) for k in (1, 2, 3))
    masks = (rng.random((2, 3, 80)) > 0.2) | (np.arange(80) == 5)
    q0 = Q.from_scipy(Rotation.random(3, rng=rng))  # (3, 4) broadcasts against (2, 3)
    for kwargs in ({}, {"received": masks}, {"received": masks, "q0": q0}):
        out = madgwick(gyr, acc, mag, fs=FS, beta=0.2, **kwargs)
        assert out.shape == (2, 3, 80, 4)
        for i in range(2):
            for j in range(3):
                one = {k: v[i, j] if k == "received" else v[j] for k, v in kwargs.items()}
                ref = madgwick(gyr[i, j], acc[i, j], mag[i, j], fs=FS, beta=0.2, **one)
                np.testing.assert_allclose(out[i, j], ref, atol=1e-14, rtol=0)


def test_madgwick_is_a_loop_of_madgwick_step(rec):
    _, gyr, acc, mag = rec
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2])
    out = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0)
    q = q0
    for t in range(120):
        q = madgwick_step(q, gyr[t], acc[t], mag[t], 1 / FS, 0.1)
        np.testing.assert_allclose(q, out[t], atol=1e-12)


def test_madgwick_step_per_element_dt_and_beta(rng):
    _, gyr, acc, mag = recording(rng, n=5)
    q = Q.from_scipy(Rotation.random(5, rng=rng))
    dt = np.array([0.02, 0.04, 0.06, 0.1, 0.01])
    beta = np.array([0.0, 0.1, 0.5, 1.0, 0.05])
    out = madgwick_step(q, gyr, acc, mag, dt, beta)
    for i in range(5):
        np.testing.assert_allclose(
            out[i], madgwick_step(q[i], gyr[i], acc[i], mag[i], dt[i], beta[i]), atol=1e-15
        )
    # One sample, many states.
    assert madgwick_step(q, gyr[0], acc[0], None, 0.02, 0.1).shape == (5, 4)


# ================================================================ errors


def _good(rec):
    _, gyr, acc, mag = rec
    return {"gyr": gyr, "acc": acc, "mag": mag, "fs": FS, "beta": 0.1}


@pytest.mark.parametrize(
    "change, name",
    [
        ({"gyr": np.zeros((120, 4))}, "gyr"),
        ({"acc": np.zeros(3)}, "acc"),
        ({"mag": np.zeros((119, 3)) + 1}, "mag"),
        ({"acc": np.ones((119, 3))}, "acc"),
        ({"received": np.ones(119, bool)}, "received"),
        ({"received": np.ones(120)}, "received"),
        ({"received": np.ones(120, int)}, "received"),
        ({"received": np.ones((4, 120), bool), "gyr": np.zeros((3, 120, 3))}, "received"),
        ({"fs": 0.0}, "fs"),
        ({"fs": -50.0}, "fs"),
        ({"fs": np.nan}, "fs"),
        ({"beta": -0.1}, "beta"),
        ({"beta": np.nan}, "beta"),
        ({"q0": [0.0, 0.0, 0.0, 0.0]}, "q0"),
        ({"q0": [1.0, 0.0, 0.0]}, "q0"),
        ({"q0": [1.0, np.nan, 0.0, 0.0]}, "q0"),
        ({"gyr": "abc"}, "gyr"),
    ],
)
def test_madgwick_bad_input(rec, change, name):
    kwargs = _good(rec) | change
    with pytest.raises(ValueError, match=name):
        madgwick(**kwargs)


@pytest.mark.parametrize("signal", ["acc", "mag"])
def test_madgwick_zero_vector_in_received_sample(rec, signal):
    kwargs = _good(rec)
    kwargs[signal] = kwargs[signal].copy()
    kwargs[signal][7] = 0.0
    with pytest.raises(ValueError, match=f"{signal} is a zero vector"):
        madgwick(**kwargs)


@pytest.mark.parametrize(
    "change, name",
    [
        ({"q": [0.0, 0.0, 0.0, 0.0]}, "q"),
        ({"gyr": [0.0, np.nan, 0.0]}, "gyr"),
        ({"acc": [0.0, 0.0, 0.0]}, "acc"),
        ({"mag": [0.0, 0.0, 0.0]}, "mag"),
        ({"acc": [0.0, 1.0]}, "acc"),
        ({"dt": 0.0}, "dt"),
        ({"dt": [0.01, -0.01]}, "dt"),
        ({"beta": -1.0}, "beta"),
        ({"beta": np.nan}, "beta"),
        ({"q": np.ones((3, 4)), "gyr": np.ones((2, 3))}, "q"),
    ],
)
def test_madgwick_step_bad_input(change, name):
    kwargs = {"q": [1.0, 0, 0, 0], "gyr": [0.1, 0, 0], "acc": [0, 0, 9.8],
              "mag": [0, 20.0, -30.0], "dt": 0.02, "beta": 0.1} | change  # fmt: skip
    with pytest.raises(ValueError, match=name):
        madgwick_step(**kwargs)
