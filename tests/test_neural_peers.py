"""Tests for wsnlib.orientation.neural_peers (RIANN under packet loss).

References: static data at known tilts and a spin about the vertical at a known tilt (pin the
frame and the inclination; RIANN's heading is arbitrary), the simulated arm's ground truth, and
the ``riann`` package's own one-step API fed the received samples with their Δt.
"""

import importlib.resources

import numpy as np
import pytest
from riann.riann import RIANN

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.loss import gilbert_elliott, packets_to_samples
from wsnlib.metrics.orientation import broad_errors_deg, broad_rmse_deg
from wsnlib.orientation import riann_orientation
from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu

FS = 50.0
G_ENU = frames.gravity_specific_force_enu()
TILTS = [[0.5, 0.0, 0.0], [0.0, -0.6, 0.0], [0.4, -0.3, 1.2], [2.0, 0.3, 0.0]]  # rotation vectors (rad)


def inclination_deg(q_est, q_ref):
    return broad_errors_deg(q_est, q_ref)["inclination"]


@pytest.fixture(scope="module")
def arm():
    """Both nodes of the simulated arm extension, 10 s (500 samples), 2 Monte Carlo runs."""
    truth = arm_kinematics(arm_extension(fs=FS, duration_s=10.0))
    imu = simulate_imu(truth, rng=np.random.default_rng(7), n_runs=2)
    return truth.quat, imu.gyr, imu.acc  # (2, T, 4), (2, 2, T, 3) each


@pytest.fixture(scope="module")
def masks():
    """Bursty masks (2, 2, 500), about 20 % lost, with a gap at the start of one row and at the end of another."""
    packets = gilbert_elliott(84, 0.2, 3.0, rng=np.random.default_rng(3), shape=(2, 2))
    packets[0, 0, :2] = False
    packets[1, 1, -2:] = False
    return packets_to_samples(packets, 6, 500)


def riann_steps(gyr, acc, dt):
    """The riann package's one-step API on ``(N, 3)`` signals, sample k integrated over ``dt[k]`` s."""
    net = RIANN(str(importlib.resources.files("riann") / "riann.onnx"))
    return np.array([net.predict_step(a, g, fs=1.0 / d) for a, g, d in zip(acc, gyr, dt, strict=True)], dtype=float)


# --------------------------------------------------------------------------------------------
# Frame and inclination
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("rotvec", TILTS)
def test_static_tilt_gives_its_inclination(rotvec):
    """A still sensor at a known orientation: after 1 s the inclination is the true one; the
    conjugate (earth → body) would be off by about the tilt."""
    q_true = Q.from_rotation_vector(rotvec)
    acc = np.tile(Q.rotate_inverse(q_true, G_ENU), (200, 1))
    q = riann_orientation(np.zeros((200, 3)), acc, fs=FS)
    err = inclination_deg(q[50:], q_true)
    assert err.max() < 2.0
    assert inclination_deg(Q.conjugate(q[-1]), q_true) > 5.0


@pytest.mark.parametrize("tilt_deg", [0.0, 30.0])
def test_spin_about_the_vertical_keeps_the_inclination(tilt_deg):
    """Turning at 2 rad/s about earth z with the body tilted: the inclination stays the tilt (0 or 30°)."""
    omega, n_t = 2.0, 500
    q0 = Q.from_axis_angle([1.0, 0.0, 0.0], np.radians(tilt_deg))
    t = np.arange(n_t) / FS
    q_true = Q.multiply(Q.from_axis_angle([0.0, 0.0, 1.0], omega * t), q0)  # q_z(ωt) ⊗ q0, body → earth
    gyr = np.tile(Q.rotate_inverse(q0, [0.0, 0.0, omega]), (n_t, 1))  # constant in the body frame
    acc = np.tile(Q.rotate_inverse(q0, G_ENU), (n_t, 1))
    q = riann_orientation(gyr, acc, fs=FS)
    assert inclination_deg(q[50:], q_true[50:]).max() < 3.0


def test_inclination_on_the_simulated_arm(arm):
    """Lossless, RIANN's inclination RMSE against the simulated truth is a few degrees."""
    truth, gyr, acc = arm
    q = riann_orientation(gyr, acc, fs=FS)
    rmse = broad_rmse_deg(q, truth, np.ones(truth.shape[-2], dtype=bool))["inclination"]
    assert rmse.shape == (2, 2)
    assert np.all(rmse < 3.0)


# --------------------------------------------------------------------------------------------
# Loss semantics
# --------------------------------------------------------------------------------------------

def test_gap_feeds_the_time_since_the_last_received_sample(arm, masks):
    """Each received sample reaches RIANN with Δt = its distance to the previous received one
    / fs: the same as the package's one-step API fed the received samples with those Δt, not
    the same as with the nominal 1/fs."""
    _, gyr, acc = arm
    mask = masks[0, 1]
    index = np.flatnonzero(mask)
    assert np.diff(index).max() > 5  # there are gaps
    q = riann_orientation(gyr[0, 1], acc[0, 1], fs=FS, received=mask)
    actual = np.concatenate(([1.0], np.diff(index))) / FS
    expected = riann_steps(gyr[0, 1, index], acc[0, 1, index], actual)
    nominal = riann_steps(gyr[0, 1, index], acc[0, 1, index], np.full(index.size, 1.0 / FS))
    assert np.degrees(Q.angle_between(q[index], expected)).max() < 0.05
    assert np.degrees(Q.angle_between(q[index], nominal)).max() > 1.0


def test_lost_samples_hold_the_output(arm, masks):
    """Lost samples repeat the last received output; those before the first received one the
    output at it; the received ones are unchanged by what lost samples hold (NaN here)."""
    _, gyr, acc = arm
    mask = masks[0, 0]
    assert not mask[0]
    gyr_lost = np.where(mask[:, None], gyr[0, 0], np.nan)
    q = riann_orientation(gyr_lost, acc[0, 0], fs=FS, received=mask)
    first = np.argmax(mask)
    np.testing.assert_array_equal(q[:first], np.tile(q[first], (first, 1)))
    for t in np.flatnonzero(~mask)[np.flatnonzero(~mask) > first]:
        np.testing.assert_array_equal(q[t], q[t - 1])
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)


def test_the_session_runs_on_one_thread_with_the_packages_bits(arm):
    """Our session runs on one thread (a second one only spins beside the batch-1 network) and gives
    the same bits as the riann package's own session (onnxruntime's default threads) on a recording."""
    from wsnlib.orientation.neural_peers import _riann_session

    ours = _riann_session()
    options = ours.get_session_options()
    assert options.intra_op_num_threads == options.inter_op_num_threads == 1
    package = RIANN(str(importlib.resources.files("riann") / "riann.onnx")).session
    assert package.get_session_options().intra_op_num_threads != 1  # (the default: every core)
    _, gyr, acc = arm
    features = np.concatenate((acc[0, 0], gyr[0, 0], np.full((acc.shape[-2], 1), 1.0 / FS)), axis=-1)
    h0 = np.zeros(tuple(package.get_inputs()[1].shape), np.float32)  # the model's zero hidden state
    feeds = {"input": features[None].astype(np.float32), "h0": h0}
    for got, expected in zip(ours.run(None, feeds), package.run(None, feeds), strict=True):
        np.testing.assert_array_equal(got, expected)


def test_batch_matches_elements(arm, masks):
    """(2, 2, T) signals with a (2, 2, T) mask: each element as if run alone."""
    _, gyr, acc = arm
    q = riann_orientation(gyr, acc, fs=FS, received=masks)
    assert q.shape == (2, 2, 500, 4)
    for idx in np.ndindex(2, 2):
        np.testing.assert_array_equal(q[idx], riann_orientation(gyr[idx], acc[idx], fs=FS, received=masks[idx]))


def test_loss_raises_the_error(arm, masks):
    """Under ~20 % bursty loss the inclination RMSE grows (the gaps are held)."""
    truth, gyr, acc = arm
    movement = np.ones(truth.shape[-2], dtype=bool)
    lossless = broad_rmse_deg(riann_orientation(gyr, acc, fs=FS), truth, movement)["inclination"]
    lossy = broad_rmse_deg(riann_orientation(gyr, acc, fs=FS, received=masks), truth, movement)["inclination"]
    assert lossy.mean() > lossless.mean()


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------

def test_no_received_sample_is_an_error(arm):
    _, gyr, acc = arm
    mask = np.ones((2, 2, 500), dtype=bool)
    mask[1, 0] = False
    with pytest.raises(ValueError, match=r"no received sample for batch element \(1, 0\)"):
        riann_orientation(gyr, acc, fs=FS, received=mask)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"acc": np.zeros((10, 2))}, "acc"),
    ({"acc": np.tile(G_ENU, (11, 1))}, "T|time|samples"),
    ({"fs": 0.0}, "fs"),
    ({"received": np.ones(10)}, "received"),
])
def test_bad_inputs_are_named(kwargs, match):
    args = {"gyr": np.zeros((10, 3)), "acc": np.tile(G_ENU, (10, 1)), "fs": FS} | kwargs
    with pytest.raises(ValueError, match=match):
        riann_orientation(**args)
