"""Gap-aware error-state Kalman filter: reference step, loss behaviour, gates, validation."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from _recordings import FS, error_deg, swinging_recording, turning_recording, vertical_swing_recording

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.loss import LossProfile
from wsnlib.metrics import broad_errors_deg
from wsnlib.orientation import madgwick
from wsnlib.orientation.gaps import AR_RIDGE, ar_end_weights, ar_fit, ar_predict
from wsnlib.orientation.kalman import (
    KALMAN_GAP_TIME_CONSTANT_S,
    MAG_LONG_REJECTION_S,
    KalmanReference,
    KalmanSettings,
    kalman_initial_state,
    kalman_orientation,
    kalman_step,
    long_mag_rejections,
)
from wsnlib.orientation.kalman_settings import gap_prediction_order
from wsnlib.sim.arm import arm_kinematics, movement_set
from wsnlib.sim.imu import ideal_imu

# ------------------------------------------------------------------------------------------
# The compiled step against the matrix form (wsnlib.orientation.kalman.KalmanReference)
# ------------------------------------------------------------------------------------------


def _reference_case(n, seed=3):
    """A turning recording with noise and Gilbert–Elliott gaps (long enough for the AR window)."""
    gyr, acc, mag, _ = turning_recording(n=n, seed=seed)
    rng = np.random.default_rng(seed)
    acc = acc + rng.normal(0, 0.3, acc.shape)  # innovations large enough to trigger the robust gate
    gyr = gyr + 0.01
    received = LossProfile.gilbert_elliott(0.15, 3.0).mask(n, FS, rng)
    received[0] = False  # a gap before the first sample (the filter starts at the first received one)
    return gyr, acc, mag, received


# The hard-iron correction is off: the reference leaves it out (clean data never trigger it anyway).
NO_HARD_IRON = KalmanSettings(mag_hard_iron_min_bias=math.inf)


@pytest.mark.parametrize("options", [
    {},                                                   # "ar" with replay: the AR fit and its end weights
    {"replay": False},
    {"gap": "constant_rate", "gap_time_constant": 0.3},
    {"gap": "constant_rate", "replay": False},
    {"gap": "hold"},
])
def test_compiled_step_equals_the_matrix_form_over_2000_samples(options):
    gyr, acc, mag, received = _reference_case(2000)
    settings = dataclasses.replace(NO_HARD_IRON, gap_rate_prediction_span_s=0.16, gap_rate_prediction_window_s=1.0,
                                   acc_disturbance_factor=16.0)
    got = kalman_orientation(gyr, acc, mag, fs=FS, received=received, settings=settings, full_output=True, **options)
    want, want_P = KalmanReference.run(gyr, acc, mag, received, fs=FS, settings=settings, **options)
    scale = np.abs(want).max()
    np.testing.assert_allclose(Q.canonical(got.quat), Q.canonical(want), rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(got.covariance[-1], want_P, rtol=1e-9, atol=1e-9 * np.abs(want_P).max())


def test_the_matrix_form_refuses_a_disturbed_field_instead_of_passing_by_accident():
    gyr, acc, mag, received = _reference_case(600)
    mag = mag.copy()
    mag[450:] *= 1.5  # after the reference formed (mag_new_first_time_s of received samples)
    with pytest.raises(ValueError, match="disturbed"):
        KalmanReference.run(gyr, acc, mag, received, fs=FS, settings=NO_HARD_IRON)


def test_step_by_step_equals_the_batch_call_sample_by_sample():
    gyr, acc, mag, received = _reference_case(900, seed=5)
    batch = kalman_orientation(gyr, acc, mag, fs=FS, received=received, full_output=True)
    state = kalman_initial_state(fs=FS)
    first = int(np.argmax(received))  # before it the batch call shows its start (it knows the future)
    for t in range(len(gyr)):
        kalman_step(state, gyr[t], acc[t], mag[t], received=bool(received[t]))
        assert state.started == (t >= first)
        if t < first:
            continue
        np.testing.assert_array_equal(state.quat, batch.quat[t])
        np.testing.assert_array_equal(state.gyro_bias, batch.gyro_bias[t])
        np.testing.assert_array_equal(state.covariance, batch.covariance[t])
    saved = state.copy()  # a copy is independent of the state it was taken from
    kalman_step(state, gyr[0], acc[0], mag[0])
    assert not np.array_equal(saved.quat, state.quat) and saved.prediction["covariance"].shape == (9, 9)
    with pytest.raises(ValueError, match="mag must be given"):
        kalman_step(state, gyr[0], acc[0])
    with pytest.raises(ValueError, match="KalmanState"):
        kalman_step("state", gyr[0], acc[0], mag[0])


@pytest.mark.parametrize("options", [{}, {"gap": "constant_rate"}], ids=["ar-replay", "constant_rate-replay"])
def test_causal_a_prefix_gives_the_same_outputs_at_every_gap_end(options):
    """Strict causality: cut the recording just after each gap's end (where the replay and the
    AR fit act); the run on the prefix equals the full run there, bit for bit."""
    gyr, acc, mag, received = _reference_case(1500, seed=5)
    settings = KalmanSettings(gap_rate_prediction_span_s=0.16, gap_rate_prediction_window_s=1.0)
    full = kalman_orientation(gyr, acc, mag, fs=FS, received=received, settings=settings, **options)
    ends = np.flatnonzero(received[1:] & ~received[:-1]) + 1
    assert len(ends) >= 5
    for end in ends:
        prefix = kalman_orientation(gyr[: end + 1], acc[: end + 1], mag[: end + 1], fs=FS,
                                    received=received[: end + 1], settings=settings, **options)
        np.testing.assert_array_equal(prefix, full[: end + 1])


def test_gap_replay_recovers_a_rate_that_changed_in_the_gap():
    """The rate ramps up during a gap: the replayed state at the gap's end is closer to the truth
    than the extrapolated one, and the lost samples' output is the extrapolation either way."""
    n = 150
    t = np.arange(n) / FS
    rate = np.where(t < 1.0, 0.5, 0.5 + 4.0 * (t - 1.0))  # rad/s about a fixed body axis
    axis = np.array([0.3, 0.4, 0.866])
    axis /= np.linalg.norm(axis)
    fine = np.linspace(0.0, t[-1], 20 * (n - 1) + 1)
    fine_rate = np.where(fine < 1.0, 0.5, 0.5 + 4.0 * (fine - 1.0))
    angle = np.concatenate([[0.0], np.cumsum(np.diff(fine) * 0.5 * (fine_rate[1:] + fine_rate[:-1]))])[::20]
    q_true = Q.from_rotation_vector(angle[:, None] * axis)
    gyr = rate[:, None] * axis
    acc = Q.rotate_inverse(q_true, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(q_true, frames.magnetic_field_enu())
    received = np.ones(n, bool)
    received[60:80] = False  # 0.4 s in which the rate goes from 1.3 to 2.9 rad/s
    on = kalman_orientation(gyr, acc, mag, fs=FS, received=received, q0=q_true[0])
    off = kalman_orientation(gyr, acc, mag, fs=FS, received=received, q0=q_true[0], replay=False)
    np.testing.assert_array_equal(on[:80], off[:80])
    err_on, err_off = error_deg(on, q_true), error_deg(off, q_true)
    assert err_off[80] > 5.0
    assert err_on[80] < 0.2 * err_off[80]


def test_hard_iron_offset_is_estimated_and_removed():
    """A magnet fixed to the sensor after 8 s (constant body-frame offset, 40 % of the field; the
    field's reference forms in the first 5 s): with the online hard-iron estimate the heading
    stays close, without it the field is wrong."""
    gyr, acc, mag, q_true = turning_recording(n=1500)
    offset = 0.4 * np.linalg.norm(mag[0]) * np.array([0.6, -0.64, 0.48])
    disturbed = mag.copy()
    disturbed[400:] += offset
    on = kalman_orientation(gyr, acc, disturbed, fs=FS)
    off = kalman_orientation(gyr, acc, disturbed, fs=FS, settings=KalmanSettings(mag_hard_iron_min_bias=math.inf))
    late = slice(750, None)
    assert np.sqrt(np.mean(error_deg(on, q_true)[late] ** 2)) < 3.0
    assert np.sqrt(np.mean(error_deg(off, q_true)[late] ** 2)) > 10.0


# ------------------------------------------------------------------------------------------
# The gap's linear prediction of the rate
# ------------------------------------------------------------------------------------------


def test_gap_rate_fit_matches_numpy_least_squares_and_predicts_an_oscillation():
    t = np.arange(80) / FS
    rates = np.stack([2.0 * np.exp(-0.3 * t) * np.sin(2 * np.pi * 1.5 * t), 0.5 * np.cos(2 * np.pi * 0.7 * t),
                      0.1 + 0.0 * t], axis=1)
    order, window, end = 4, 50, 60
    coef = np.zeros((3, order))
    largest = ar_fit(rates, end, window, order, coef, np.empty((3, order, order + 1)), np.empty((3, order + 1)))
    for a in range(3):  # reference: ridge least squares with numpy
        x = rates[end - window:end, a]
        X = np.stack([x[i:window - order + i] for i in range(order)], axis=1)
        A = X.T @ X
        A += AR_RIDGE * max(1.0, np.trace(A) / order) * np.eye(order)
        np.testing.assert_allclose(coef[a], np.linalg.solve(A, X.T @ x[order:]), rtol=1e-9, atol=1e-12)
    assert largest == pytest.approx(np.linalg.norm(rates[end - window:end], axis=1).max())
    # 10 steps ahead, fed back on its own predictions: close to the oscillation
    buf = rates[:end].copy()
    buf = np.concatenate([buf, np.zeros((10, 3))])
    for k in range(end, end + 10):
        ar_predict(buf, k, order, coef, largest, buf[k])
    assert np.abs(buf[end:, :2] - rates[end:end + 10, :2]).max() < 0.05


def test_gap_rate_fit_at_the_default_order_matches_numpy_least_squares():
    """Order 48 on 300 samples (the defaults at 50 Hz) of a noisy swing: the generalized Schur
    solution equals the normal equations solved directly."""
    rng = np.random.default_rng(4)
    t = np.arange(400) / FS
    rates = np.stack([2.0 * np.sin(2 * np.pi * 0.9 * t), np.cos(2 * np.pi * 0.4 * t) * np.exp(-0.2 * t),
                      0.3 * np.sin(2 * np.pi * 2.1 * t + 1.0)], axis=1) + rng.normal(0.0, 0.05, (400, 3))
    order, window, end = 48, 300, 380
    coef = np.zeros((3, order))
    ar_fit(rates, end, window, order, coef, np.empty((3, order, order + 1)), np.empty((3, order + 1)))
    for a in range(3):
        x = rates[end - window:end, a]
        X = np.stack([x[i:window - order + i] for i in range(order)], axis=1)
        A = X.T @ X
        A += AR_RIDGE * max(1.0, np.trace(A) / order) * np.eye(order)
        want = np.linalg.solve(A, X.T @ x[order:])
        np.testing.assert_allclose(coef[a], want, rtol=1e-8, atol=1e-10 * np.abs(want).max())


def test_gap_rate_end_weights_are_the_gaussian_conditional_expectation():
    order, n = 3, 12
    coef = np.array([[0.2, -0.5, 1.1], [0.0, 0.0, 1.0], [0.1, 0.3, 0.4]])
    h, weights = np.empty(n), np.empty(n)
    for axis in range(3):
        ar_end_weights(coef, axis, order, n, h, weights)
        # reference: the prediction errors e_1..e_n are M ε with M the lower-triangular Toeplitz
        # matrix of the impulse response; E[e_k | e_n] = Cov(e_k, e_n)/Var(e_n) e_n
        impulse = np.zeros(n)
        impulse[0] = 1.0
        for j in range(1, n):
            impulse[j] = sum(coef[axis, i] * impulse[j - order + i] for i in range(order) if j - order + i >= 0)
        M = np.array([[impulse[k - i] if k >= i else 0.0 for i in range(n)] for k in range(n)])
        cov = M @ M.T
        np.testing.assert_allclose(weights, cov[:, -1] / cov[-1, -1], rtol=1e-12)
        assert weights[-1] == pytest.approx(1.0)
    # a random walk (order 1, coefficient 1) gives the linear ramp k/n
    ar_end_weights(np.ones((3, 1)), 0, 1, n, h, weights)
    np.testing.assert_allclose(weights, np.arange(1, n + 1) / n, rtol=1e-12)
    # an explosive fit (impulse response 2^j) falls back to the ramp instead of overflowing
    ramp = np.empty(400)
    ar_end_weights(np.full((3, 1), 2.0), 0, 1, 400, np.empty(400), ramp)
    np.testing.assert_allclose(ramp, np.arange(1, 401) / 400, rtol=1e-12)


def test_linear_prediction_follows_a_swing_through_a_gap_and_replay_lands_on_it():
    gyr, acc, mag, truth = swinging_recording()
    received = np.ones(len(gyr), bool)
    received[300:318] = False  # 0.36 s, half a period of the 1.5 Hz swing
    base = KalmanSettings(acc_rate_gate=math.inf)
    out = {name: kalman_orientation(gyr, acc, mag, fs=FS, received=received, q0=truth[0], settings=base, gap=gap,
                                    replay=r)
           for name, gap, r in (("decay", "constant_rate", False), ("decay+replay", "constant_rate", True),
                                ("predicted", "ar", False), ("predicted+replay", "ar", True))}
    lost = slice(300, 318)
    err = {name: error_deg(q, truth) for name, q in out.items()}
    # on lost samples the output is the prediction: far closer to the swing than the decaying rate
    assert err["predicted"][lost].mean() < 0.2 * err["decay"][lost].mean()
    # at the gap's end (first received sample) the replay with the prediction lands close
    assert err["predicted+replay"][318] < 0.2 * err["decay+replay"][318]
    assert err["predicted+replay"][318] < 1.0


def test_recent_linear_acceleration_lowers_the_accelerometer_weight():
    """Sideways linear acceleration that keeps the norm within the gate (a swing in the
    horizontal plane) tilts the measured direction; with the adaptive noise it moves the
    estimate less."""
    gyr, acc, mag, truth = turning_recording()
    n = len(gyr)
    t = np.arange(n) / FS
    lin = np.zeros((n, 3))
    # 4 m/s² horizontal circle (norm of the specific force ≈ √(g² + 16) − g ≈ 0.8 m/s² off)
    lin[200:400, 0], lin[200:400, 1] = 4.0 * np.cos(2 * np.pi * t[200:400]), 4.0 * np.sin(2 * np.pi * t[200:400])
    lin[200:400, 2] = 1.5 * np.sin(2 * np.pi * 2 * t[200:400])  # and some vertical, so the norm varies
    bad = Q.rotate_inverse(truth, frames.gravity_specific_force_enu() + lin)
    plain = KalmanSettings(velocity_noise_density=1e6)  # the accelerometer's update alone
    off = kalman_orientation(gyr, bad, mag, fs=FS, settings=plain, full_output=True)
    on = kalman_orientation(gyr, bad, mag, fs=FS, settings=dataclasses.replace(plain, acc_disturbance_factor=16.0),
                            full_output=True)
    assert off.acc_used[200:400].mean() > 0.3  # many samples pass the norm gate
    rms_off = np.sqrt(np.mean(error_deg(off.quat, truth)[200:400] ** 2))
    rms_on = np.sqrt(np.mean(error_deg(on.quat, truth)[200:400] ** 2))
    assert rms_on < 0.7 * rms_off
    # without linear acceleration the factor changes (almost) nothing
    still = kalman_orientation(gyr, acc, mag, fs=FS, settings=dataclasses.replace(plain, acc_disturbance_factor=16.0))
    assert error_deg(still, truth).max() < 0.5


# ------------------------------------------------------------------------------------------
# Behaviour
# ------------------------------------------------------------------------------------------


def test_no_loss_close_to_lossless_madgwick_on_simulated_arm():
    truth = arm_kinematics(movement_set(fs=FS)["extension fast"])
    imu = ideal_imu(truth)
    q_k = kalman_orientation(imu.gyr, imu.acc, imu.mag, fs=FS)
    q_m = madgwick(imu.gyr, imu.acc, imu.mag, fs=FS, beta=0.041)
    err_k = error_deg(q_k, truth.quat)
    err_m = error_deg(q_m, truth.quat)
    assert np.sqrt(np.mean(err_k**2)) < np.sqrt(np.mean(err_m**2)) + 2.0
    assert err_k.max() < 5.0


def test_prediction_continues_through_a_gap_instead_of_freezing():
    gyr, acc, mag, truth = turning_recording()
    received = np.ones(len(gyr), bool)
    received[300:318] = False  # 3 packets of 6 samples, 0.36 s, after the field's reference formed (5 s)
    constant = kalman_orientation(gyr, acc, mag, fs=FS, received=received, gap="constant_rate",
                                  gap_time_constant=math.inf)
    decaying = kalman_orientation(gyr, acc, mag, fs=FS, received=received, gap="constant_rate")  # τ = 0.2 s
    predicted = kalman_orientation(gyr, acc, mag, fs=FS, received=received,  # a window of 1 s before the gap
                                   settings=KalmanSettings(gap_rate_prediction_span_s=0.16,
                                                           gap_rate_prediction_window_s=1.0))
    held = madgwick(gyr, acc, mag, fs=FS, beta=0.041, received=received)
    kalman_held = kalman_orientation(gyr, acc, mag, fs=FS, received=received, gap="hold")
    # exact gyroscope: constant-rate extrapolation is far better than holding, the decaying
    # rate in between; the linear prediction follows the sines of the rate better still
    err_held = error_deg(held, truth)[300:318].mean()
    assert error_deg(constant, truth)[300:318].mean() < 0.5 * err_held
    assert error_deg(constant, truth)[300:318].mean() < error_deg(decaying, truth)[300:318].mean() < err_held
    assert error_deg(predicted, truth)[300:318].mean() < 0.5 * error_deg(constant, truth)[300:318].mean()
    assert not np.allclose(decaying[301], decaying[300])  # the estimate moves on lost samples
    # gap="hold": the state stays where it was, as Madgwick's receiver does
    np.testing.assert_array_equal(kalman_held[300:318], np.broadcast_to(kalman_held[299], (18, 4)))
    assert error_deg(kalman_held, truth)[300:318].mean() > error_deg(decaying, truth)[300:318].mean()
    # ... unlike output_on_lost="hold" (the same output in the gap), whose state turned: without
    # the replay, the held state starts the next sample from where the gap began
    shown_held = kalman_orientation(gyr, acc, mag, fs=FS, received=received, output_on_lost="hold", replay=False,
                                    gap="constant_rate", gap_time_constant=math.inf)
    state_held = kalman_orientation(gyr, acc, mag, fs=FS, received=received, gap="hold", replay=False)
    np.testing.assert_array_equal(shown_held[300:318], np.broadcast_to(shown_held[299], (18, 4)))
    assert error_deg(state_held, truth)[318] > 3.0 * error_deg(shown_held, truth)[318]


def test_covariance_grows_over_a_gap_and_shrinks_after():
    gyr, acc, mag, _ = turning_recording()
    received = np.ones(len(gyr), bool)
    received[300:330] = False
    default = kalman_orientation(gyr, acc, mag, fs=FS, received=received, full_output=True).covariance[:, 0, 0]
    assert np.all(np.diff(default[300:330]) > 0) and default[330] < default[329]
    # with the larger rate-error growth of an earlier default (0.5 × ‖ω‖) the gain is > 1/2
    out = kalman_orientation(gyr, acc, mag, fs=FS, received=received, full_output=True,
                             settings=KalmanSettings(gap_rate_relative_noise=0.5))
    tilt_var = out.covariance[:, 0, 0]
    assert np.all(np.diff(tilt_var[300:330]) > 0)  # grows at every lost sample
    assert tilt_var[329] > 100 * tilt_var[299]
    # growth is (σ_gap · elapsed)²: faster than linear in the gap length
    assert tilt_var[329] - tilt_var[299] > 3 * (tilt_var[309] - tilt_var[299]) * 2
    assert tilt_var[330] < 0.5 * tilt_var[329]  # the first sample after the gap gets a large gain (> 1/2)
    assert not out.acc_used[300:330].any() and out.acc_used[330]


def test_accelerometer_gated_under_large_acceleration():
    gyr, acc, mag, truth = turning_recording()
    bad = acc.copy()
    # 2 g of linear acceleration sideways for 1 s: the direction is off by ~60°
    # (an impossible push for a body that stays put: here the gate alone is tested, with the
    # leaky-velocity pseudo-measurement made negligible)
    push = np.array([2 * frames.STANDARD_GRAVITY, 0.0, 0.0])
    bad[300:350] = Q.rotate_inverse(truth[300:350], frames.gravity_specific_force_enu() + push)
    gate_only = KalmanSettings(velocity_noise_density=1e6)
    out = kalman_orientation(gyr, bad, mag, fs=FS, full_output=True, settings=gate_only)
    assert not out.acc_used[300:350].any()
    assert error_deg(out.quat, truth)[300:360].max() < 1.0
    # the norm gate is what excluded them: without it they are used (with inflated noise)
    ungated = kalman_orientation(gyr, bad, mag, fs=FS, full_output=True, settings=KalmanSettings(
        acc_norm_gate=math.inf, velocity_noise_density=1e6))
    assert ungated.acc_used[300:350].all()
    assert not np.array_equal(ungated.quat[300:360], out.quat[300:360])


def test_push_and_return_barely_moves_the_leaky_velocity_tilt():
    # ±2 g for 0.1 s each (a jerk of the wrist that ends at rest): the gate rejects every
    # sample, and the leaky velocity (peak 1 m/s, back to 0) tilts the estimate by < 1°.
    gyr, acc, mag, truth = turning_recording()
    push = np.zeros((10, 3))
    push[:5, 0], push[5:, 0] = 2 * frames.STANDARD_GRAVITY, -2 * frames.STANDARD_GRAVITY
    bad = acc.copy()
    bad[300:310] = Q.rotate_inverse(truth[300:310], frames.gravity_specific_force_enu() + push)
    out = kalman_orientation(gyr, bad, mag, fs=FS, full_output=True)
    assert not out.acc_used[300:310].any()
    error = error_deg(out.quat, truth)
    assert 0.05 < error[300:400].max() < 1.0  # the push is seen (not ignored), and small


def test_magnetic_disturbance_rejected_and_never_tilts():
    gyr, acc, mag, truth = turning_recording()
    disturbed = mag.copy()
    disturbed[300:400] += Q.rotate_inverse(truth[300:400], [40.0, 0.0, 0.0])  # a magnet: norm and dip change
    out = kalman_orientation(gyr, acc, disturbed, fs=FS, full_output=True)
    assert not out.mag_used[300:400].all()
    assert error_deg(out.quat, truth)[300:400].max() < 2.0
    # heading-only: without its gate the magnet turns the heading but does not tilt
    ungated = kalman_orientation(gyr, acc, disturbed, fs=FS, settings=KalmanSettings(mag_norm_gate=math.inf,
                                                                                      mag_dip_gate=math.inf))
    clean = kalman_orientation(gyr, acc, mag, fs=FS)
    err = Q.multiply(ungated, Q.conjugate(clean))  # earth-frame difference
    tilt = np.degrees(2 * np.arctan2(np.hypot(err[..., 1], err[..., 2]), np.hypot(err[..., 0], err[..., 3])))
    heading = np.degrees(2 * np.arctan2(np.abs(err[..., 3]), np.abs(err[..., 0])))
    assert heading[300:400].max() > 5.0
    assert tilt[300:400].max() < 0.2 * heading[300:400].max()


def test_batch_equals_loop_and_broadcasts():
    gyr, acc, mag, _ = turning_recording(n=200)
    rng = np.random.default_rng(5)
    masks = rng.random((3, 200)) > 0.2
    masks[:, 0] = True
    batch = kalman_orientation(gyr, acc, mag, fs=FS, received=masks)
    assert batch.shape == (3, 200, 4)
    for i in range(3):
        np.testing.assert_array_equal(batch[i], kalman_orientation(gyr, acc, mag, fs=FS, received=masks[i]))
    np.testing.assert_allclose(np.linalg.norm(batch, axis=-1), 1.0, atol=1e-12)


def test_lost_samples_may_hold_nan_and_imu_form_runs():
    gyr, acc, mag, _ = turning_recording(n=100)
    received = np.ones(100, bool)
    received[40:50] = False
    gyr, acc, mag = gyr.copy(), acc.copy(), mag.copy()
    gyr[40:50] = acc[40:50] = mag[40:50] = np.nan
    assert np.all(np.isfinite(kalman_orientation(gyr, acc, mag, fs=FS, received=received)))
    assert np.all(np.isfinite(kalman_orientation(gyr, acc, None, fs=FS, received=received)))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"fs": 0.0}, "fs"),
        ({"fs": 1e-300}, "fs"),
        ({"received": np.ones(50)}, "received"),
        ({"q0": [0, 0, 0, 0]}, "q0"),
        ({"settings": {"acc_noise_density": 1}}, "settings"),
    ],
)
def test_rejects_bad_arguments(kwargs, match):
    gyr, acc, mag, _ = turning_recording(n=50)
    args = {"fs": FS} | kwargs
    with pytest.raises(ValueError, match=match):
        kalman_orientation(gyr, acc, mag, **args)


def test_rejects_nan_in_received_sample_and_bad_settings():
    gyr, acc, mag, _ = turning_recording(n=50)
    acc = acc.copy()
    acc[10] = np.nan
    with pytest.raises(ValueError, match="acc"):
        kalman_orientation(gyr, acc, mag, fs=FS)
    with pytest.raises(ValueError, match="acc_noise_density"):
        KalmanSettings(acc_noise_density=-1.0)
    with pytest.raises(ValueError, match="gyro_noise"):
        KalmanSettings(gyro_noise=math.inf)
    with pytest.raises(ValueError, match="replay"):
        kalman_orientation(gyr, acc, mag, fs=FS, replay=1.0)
    with pytest.raises(ValueError, match="mag_hard_iron_tau_s"):
        KalmanSettings(mag_hard_iron_tau_s=0.0)
    np.testing.assert_array_equal(kalman_orientation(gyr[:9], acc[:9], mag[:9], fs=FS, replay=np.bool_(False)),
                                  kalman_orientation(gyr[:9], acc[:9], mag[:9], fs=FS, replay=False))
    with pytest.raises(ValueError, match="gap_rate_prediction_span_s"):
        KalmanSettings(gap_rate_prediction_span_s=0)
    for gone in ("gap_replay", "gap_rate_prediction", "gap_rate_decay_s"):  # now kalman_orientation's keywords
        with pytest.raises(TypeError, match=gone):
            KalmanSettings(**{gone: True})
    with pytest.raises(ValueError, match="acc_disturbance_factor"):
        KalmanSettings(acc_disturbance_factor=-1.0)
    assert KalmanSettings(acc_disturbance_factor=0).acc_disturbance_factor == 0.0
    # The predictor's order is the span in samples at the run's rate, within [1, 64].
    span = KalmanSettings(gap_rate_prediction_span_s=0.5)
    assert [gap_prediction_order(span, 1.0 / fs) for fs in (1.0, 40.0, 100.0, 2000 / 7)] == [1, 20, 50, 64]


# ------------------------------------------------------------------------------------------
# The loss vocabulary's keywords (gap, replay, output_on_lost, gap_time_constant)
# ------------------------------------------------------------------------------------------


def test_gap_time_constant_defaults_to_the_kalman_constant_and_decays_the_rate():
    gyr, acc, mag, _ = turning_recording(n=200)
    rng = np.random.default_rng(6)
    masks = rng.random((2, 200)) > 0.2
    default = kalman_orientation(gyr, acc, mag, fs=FS, received=masks, gap="constant_rate")
    assert KALMAN_GAP_TIME_CONSTANT_S == 0.2
    np.testing.assert_array_equal(default, kalman_orientation(gyr, acc, mag, fs=FS, received=masks,
                                                              gap="constant_rate", gap_time_constant=0.2))
    slower = kalman_orientation(gyr, acc, mag, fs=FS, received=masks, gap="constant_rate", gap_time_constant=0.3)
    assert np.abs(slower - default).max() > 1e-6
    # without a window of rates before the gaps, "ar" is the decaying rate, with the same time constant
    np.testing.assert_array_equal(kalman_orientation(gyr, acc, mag, fs=FS, received=masks), default)
    settings = KalmanSettings(acc_noise_density=0.1 / math.sqrt(FS))
    imu = kalman_orientation(gyr, acc, None, fs=FS, received=masks, settings=settings,
                             gap="constant_rate", gap_time_constant=0.3)
    assert imu.shape == (2, 200, 4) and np.all(np.isfinite(imu))


def test_output_on_lost_hold_holds_the_output_and_changes_nothing_else():
    gyr, acc, mag, _ = turning_recording(n=200)
    received = np.ones(200, bool)
    received[[0, 1]] = False  # leading gap (q0 None: the output there is the initial estimate)
    received[50:70] = False
    received[199] = False  # a gap at the end
    predicted = kalman_orientation(gyr, acc, mag, fs=FS, received=received, full_output=True)
    held = kalman_orientation(gyr, acc, mag, fs=FS, received=received, output_on_lost="hold", full_output=True)
    np.testing.assert_array_equal(held.quat[received], predicted.quat[received])
    np.testing.assert_array_equal(held.quat[50:70], np.broadcast_to(predicted.quat[49], (20, 4)))
    np.testing.assert_array_equal(held.quat[199], predicted.quat[198])
    np.testing.assert_array_equal(held.quat[:2], predicted.quat[:2])
    np.testing.assert_array_equal(held.covariance, predicted.covariance)  # the state still predicts
    np.testing.assert_array_equal(held.gyro_bias, predicted.gyro_bias)
    assert not np.allclose(predicted.quat[60], predicted.quat[49])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"gap": "freeze"}, "gap.*'hold'.*'constant_rate'.*'ar'"),
        ({"gap": None}, "gap"),
        ({"gap": "hold", "gap_time_constant": 1.0}, "gap_time_constant.*gap='hold'"),
        ({"gap_time_constant": 0.0}, "gap_time_constant"),
        ({"gap": "constant_rate", "gap_time_constant": -1.0}, "gap_time_constant"),
        ({"replay": "yes"}, "replay"),
        ({"output_on_lost": "previous"}, "output_on_lost.*'estimate'.*'hold'"),
        ({"settings": {"acc_noise_density": 1}}, "settings"),
    ],
)
def test_kalman_orientation_rejects_bad_loss_options(kwargs, match):
    gyr, acc, mag, _ = turning_recording(n=50)
    with pytest.raises(ValueError, match=match):
        kalman_orientation(gyr, acc, mag, fs=FS, **kwargs)


# ------------------------------------------------------------------------------------------
# Any rate, any start (issue 24)
# ------------------------------------------------------------------------------------------


def _still(n, q_true=(1.0, 0.0, 0.0, 0.0)):
    q = np.broadcast_to(np.asarray(q_true, dtype=float), (n, 4))
    return (np.zeros((n, 3)), Q.rotate_inverse(q, frames.gravity_specific_force_enu()),
            Q.rotate_inverse(q, frames.magnetic_field_enu()), q)


def test_one_settings_object_corrects_as_fast_in_seconds_at_any_rate():
    """Noise densities, not per-sample noise: a 20° tilt error of the start decays in the same time
    (s) at 25, 50 and 200 Hz (with per-sample noise, much faster at 200 than at 25 Hz)."""
    start = Q.from_rotation_vector(np.radians([14.0, 14.0, 0.0]))
    settle = {}
    for fs in (25.0, 50.0, 200.0):
        gyr, acc, _, q_true = _still(int(20 * fs))
        error = error_deg(kalman_orientation(gyr, acc, None, fs=fs, q0=start), q_true)
        settle[fs] = np.argmax(error < 0.5 * error[0]) / fs  # time (s) to halve the error
    assert settle[25.0] > 0.1
    assert max(settle.values()) < 1.3 * min(settle.values()), settle


def test_the_field_reference_is_not_set_by_a_disturbed_first_second():
    """The first second's field is 60 % stronger and tilted (a magnet near the start position); then
    the earth's field.  The reference forms from the consistent field that follows, and the heading
    is within 8° from 10 s on (set from the first sample for good, the gates rejected the true field for a minute)."""
    gyr, acc, mag, q_true = turning_recording(n=1500, seed=3)
    disturbed = mag.copy()
    disturbed[:50] = 1.6 * Q.rotate_inverse(q_true[:50], Q.rotate(Q.from_rotation_vector([0.0, 0.0, 0.7]),
                                                                  frames.magnetic_field_enu()))
    out = kalman_orientation(gyr, acc, disturbed, fs=FS, full_output=True)
    heading = broad_errors_deg(out.quat, q_true)["heading"]
    assert np.max(heading[500:]) < 8.0  # (the old filter: 40°, the true field rejected for a minute)
    assert out.mag_used[500:].all()


def test_a_magnetometer_rejected_for_longer_than_10_s_is_counted_and_warned_once():
    gyr, acc, mag, q_true = turning_recording(n=2000, seed=4)
    disturbed = mag.copy()
    # A field of its own for 16 s that turns the field (heading 36°, dip 18°): one that only changed
    # the field's strength, with its dip, is followed within seconds (mag_norm_tau_s) and used.
    offset_enu = 0.5 * np.linalg.norm(mag[0]) * np.array([0.8, 0.0, 0.6])
    disturbed[500:1300] += Q.rotate_inverse(q_true[500:1300], offset_enu)
    with pytest.warns(UserWarning, match="1 time\\(s\\) for longer than 10 s") as caught:
        out = kalman_orientation(np.stack([gyr, gyr]), np.stack([acc, acc]), np.stack([disturbed, mag]), fs=FS,
                                 settings=NO_HARD_IRON, full_output=True)
    assert len([w for w in caught if "magnetometer" in str(w.message)]) == 1
    np.testing.assert_array_equal(out.long_mag_rejections, [1, 0])


def _long_rejections_by_runs(used, received, fs):
    """The definition, one rejection at a time: the rejected received samples between two used ones."""
    count, run = 0, []
    for t in [*np.flatnonzero(received), None]:
        if t is not None and not used[t]:
            run.append(t)
            continue
        count += bool(run) and (run[-1] - run[0] + 1) / fs > MAG_LONG_REJECTION_S
        run = []
    return count


def test_long_mag_rejections_span_lost_samples_and_end_at_a_used_one():
    fs = 10.0  # 10 s = 100 samples
    used, received = np.ones((4, 400), dtype=bool), np.ones((4, 400), dtype=bool)
    used[0, 50:151] = False  # 101 samples: 10.1 s, counted
    used[1, 50:150] = False  # 100 samples: 10 s, not longer
    used[2, 50:120] = used[2, 130:181] = False  # two short ones ...
    received[2, 120:130] = False  # ... joined by lost samples: 50 … 180, counted
    used[3, 10:130] = used[3, 250:400] = False  # a used sample at 130 ends the first; the second runs to the end
    np.testing.assert_array_equal(long_mag_rejections(used, received, fs), [1, 0, 1, 2])
    rng = np.random.default_rng(8)  # random rejections and gaps in runs, against the definition
    used = np.repeat(rng.random((50, 40)) < 0.7, 10, axis=1)
    received = np.repeat(rng.random((50, 80)) < 0.8, 5, axis=1)
    counts = long_mag_rejections(used, received, 2.0)
    assert counts.sum() > 10
    want = [_long_rejections_by_runs(u, r, 2.0) for u, r in zip(used, received, strict=True)]
    np.testing.assert_array_equal(counts, want)


def test_a_field_whose_strength_halves_is_used_again_within_seconds():
    """From 20 s on the field is half as strong (a sensor's gain; its direction holds), and a gyroscope
    glitch at 20 s turns the estimate by 30° about the vertical.  The norm gate's reference follows
    the field (mag_norm_tau_s), so the magnetometer is used again within 5 s and the heading is
    back within 8° by 30 s (what is left: the glitch taken partly as gyroscope bias, slowly
    forgotten).  With the gate's norm following at VQF's 20 s, the new field was rejected until
    it became the new reference (20 s of turning) and the heading kept the glitch (31°)."""
    gyr, acc, mag, q_true = turning_recording(n=2500, seed=5, noise=0.002)
    step = 20 * int(FS)
    mag = mag.copy()
    mag[step:] *= 0.5
    gyr = gyr.copy()
    gyr[step:step + 25, :] += Q.rotate_inverse(q_true[step:step + 25], [0.0, 0.0, math.radians(30.0) * FS / 25])
    out = kalman_orientation(gyr, acc, mag, fs=FS, full_output=True)
    heading = np.abs(broad_errors_deg(out.quat, q_true)["heading"])
    assert np.max(heading[step + 50:step + 100]) > 10.0  # the glitch took effect
    assert out.mag_used[step + 5 * int(FS):].mean() > 0.95
    assert np.max(heading[step + 10 * int(FS):]) < 8.0


def test_a_magnet_on_the_sensor_is_removed_while_the_field_strength_drifts():
    """A magnet fixed to the sensor from 20 s on (40 % of the field) while the whole field, magnet
    included, is scaled by 0.8 + 0.4 cos(2π t / 60 s) (a drifting gain): the reference norm lags
    the scale, but the corrected field's norm is steadier than the raw one's, so the hard-iron
    correction is applied (heading within 8°, field used on 90 % of the samples; deciding by the
    lagging reference norm alone: 17°, 74 %)."""
    gyr, acc, mag, q_true = turning_recording(n=4000, seed=6, noise=0.002)
    magnet = 0.4 * np.linalg.norm(mag[0]) * np.array([0.6, -0.64, 0.48])
    mag = mag.copy()
    mag[20 * int(FS):] += magnet
    mag *= 0.8 + 0.4 * np.cos(2 * np.pi * np.arange(len(mag)) / FS / 60.0)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        out = kalman_orientation(gyr, acc, mag, fs=FS, full_output=True)
    heading = np.abs(broad_errors_deg(out.quat, q_true)["heading"])
    assert np.max(heading) < 8.0
    assert out.mag_used.mean() > 0.9


def test_a_drifting_field_strength_is_used_at_once_after_a_gap():
    """The field's strength grows by 5 %/s from 10 s on (a drifting gain, half of the largest rate the
    norm gate follows: mag_norm_gate / mag_norm_tau_s = 10 %/s) and nothing is received from 18 s to
    20 s.  The gate's follower stood still in the gap, 15 % behind; its tolerance widens with the gap
    by the same rate, so the first field after the gap is used (with the gate of a sample, it was
    rejected for ~1 s, while the heading was the gap's least certain)."""
    gyr, acc, mag, q_true = turning_recording(n=1500, seed=7, noise=0.002)
    t = np.arange(len(mag)) / FS
    mag = mag * np.exp(0.05 * np.clip(t - 10.0, 0.0, None))[:, None]
    received = (t < 18.0) | (t >= 20.0)
    out = kalman_orientation(gyr, acc, mag, fs=FS, received=received, full_output=True)
    after = int(20.0 * FS)
    assert out.mag_used[int(12.0 * FS):int(18.0 * FS)].all()  # the follower kept up with the drift before
    assert out.mag_used[after:after + int(FS)].all()


def _rejected_after_one_field(explained: float, noise: float = 0.0, pairs: float = 100.0) -> bool:
    """One received field after a state whose hard-iron sums say a body-fixed offset b explains the share
    ``explained`` of the field's rate residual y, the field's white noise the share ``noise`` and a smooth
    residual the rest, while the two older rules both pick the raw field: the reference norm lags a gain
    that fell (raw norm 32.8 µT, closer to the reference's 33 than the corrected 50.2) and the raw norm is
    the steadier.  The gate's norm follows the corrected field, so only the corrected field is used;
    the sums hold ``pairs`` residuals (none forgotten); returns whether the magnetometer was rejected."""
    state = kalman_initial_state(fs=FS, q0=Q.identity())
    rec = state.record
    earth = np.array([0.0, 20.0, -46.0])                      # µT, ENU; the sensor is level, heading 0
    offset = np.array([0.0, 0.0, 20.0])                       # the magnet, body frame
    A = 4.0 * np.array([1.0, 0.0, 0.0, 1.0, 0.0, 1.0])        # Σ [ω]×ᵀ[ω]× (packed 00 01 02 11 12 22)
    rec["hi_A"], rec["hi_r"], rec["hard_iron"] = A, 4.0 * offset, offset  # r = A b: b solves the sums
    magnet = 4.0 * offset @ offset                            # Σ‖ω × b‖²
    total = magnet / explained                                # Σ‖y‖²
    white = noise * total
    # Σ y_k·y_{k−1}: a smooth residual's products are its energy, differentiated white noise's −1/2 of it
    rec["hi_syy"], rec["hi_syy1"] = total, total - white - 0.5 * white
    rec["hi_w"], rec["hi_w2"] = pairs, pairs
    rec["hi_norm_vars"] = [0.0, 1.0]                          # the raw norm looks the steadier
    rec["mag_ref_norm"], rec["mag_gate_norm"], rec["mag_ref_time"] = 33.0, 50.2, 100.0
    rec["mag_ref_dip"] = math.atan2(46.0, 20.0)
    kalman_step(state, np.zeros(3), np.array([0.0, 0.0, 9.81]), earth + offset)
    return bool(rec["mag_reject_time"][0] > 0.0)


def test_a_magnet_the_data_show_is_removed_whatever_the_reference_norm():
    """The hard-iron correction is used when the offset explains more of the field's rate residual than it
    leaves (``MAG_HARD_IRON_EXPLAINED``), although the reference norm (lagging a drifting gain) and the norms'
    steadiness both point to the raw field; at a quarter explained, those two decide (raw: rejected)."""
    assert not _rejected_after_one_field(explained=0.8)
    assert _rejected_after_one_field(explained=0.25)


def test_a_magnet_is_judged_on_the_residual_beyond_the_fields_white_noise():
    """The differentiated field's white noise is most of ṁ + ω × m on BROAD at 50 Hz (BROAD trial 34, a
    magnet 3 cm from the sensor: the offset explains 0.2–0.3 of it, the rest mostly noise) and no offset
    can explain it: an offset that explains a quarter of the residual, where the rest is white noise but
    a twentieth, is the magnet (corrected field used), while a quarter of a residual whose rest is smooth
    is not (the older rules decide: raw field, rejected)."""
    assert not _rejected_after_one_field(explained=0.25, noise=0.7)
    assert _rejected_after_one_field(explained=0.25, noise=0.0)


def test_a_residual_beyond_the_noise_counts_only_when_significant():
    """Beyond white noise that is 0.7 of the residual, 0.3 is left: with 100 pairs in the sums that is
    16 standard deviations of what noise alone gives (the magnet: corrected field used); with 3 pairs (just
    after the start) it is 2.7, under MAG_HARD_IRON_SIGNIFICANCE = 3, and the older rules decide (rejected)."""
    assert not _rejected_after_one_field(explained=0.25, noise=0.7, pairs=100.0)
    assert _rejected_after_one_field(explained=0.25, noise=0.7, pairs=3.0)


def _lag_estimates(gyr, acc, mag):
    state = kalman_initial_state(fs=FS, q0=Q.identity())
    lags = np.empty(len(gyr))
    for t in range(len(gyr)):
        kalman_step(state, gyr[t], acc[t], mag[t])
        lags[t] = state.record["lag"][0]
    return lags


def test_a_magnetometer_that_lags_the_gyroscope_is_advanced_by_its_estimated_lag():
    """The field read two samples late while the sensor swings at up to 4 rad/s about the vertical.
    The synthetic recording turns by each rate over the interval before its sample (the filter's
    own convention), while the estimate (``mag_lag_tau_s``, from the sensors alone) times the field
    against the rate's sample instant, as a real gyroscope's reading is: a field read on time reads
    as half a sample early (−10 ms), two samples late as 30 ms.  The estimate settles there, and the
    heading error from 20 s on is less than half of the uncompensated filter's (``mag_lag_max_s=0``);
    on the field read on time the half sample costs less than 0.1°."""
    gyr, acc, mag, q_true = vertical_swing_recording(3000)
    late = np.concatenate([mag[:2], mag[:-2]])
    settle = int(20 * FS)
    lags = _lag_estimates(gyr, acc, late)
    assert np.abs(lags[settle:] - 0.030).max() < 0.003, lags[-1]
    assert np.abs(_lag_estimates(gyr, acc, mag)[settle:] + 0.010).max() < 0.003
    off = KalmanSettings(mag_lag_max_s=0.0)
    heading = {name: np.sqrt(np.mean(broad_errors_deg(kalman_orientation(gyr, acc, m, fs=FS, settings=s),
                                                      q_true)["heading"][settle:] ** 2))
               for name, m, s in (("late", late, None), ("late, off", late, off), ("on time", mag, None),
                                  ("on time, off", mag, off))}
    assert heading["late, off"] > 0.2  # the lag shows (noise-free, the filter's gain averages most of it)
    assert heading["late"] < 0.5 * heading["late, off"], heading
    assert heading["on time"] < heading["on time, off"] + 0.1, heading
