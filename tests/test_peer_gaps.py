"""Gap prediction and replay of the peer filters (:mod:`wsnlib.orientation.peers`, "Gap prediction")
and the whole-gap rates of :func:`wsnlib.orientation.gaps.gap_rates` they use.

Truth: rotations about one fixed axis by a known angle ``θ(t)`` (scipy ``Rotation``), the
gyroscope the exact mean rate of each sample's interval, accelerometer and magnetometer the
ENU gravity and field seen in the body frame; so an exactly predicted rate gives exactly the
true orientation on lost samples.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.orientation import fusion_orientation, gaps, vqf_orientation

FS = 50.0
WRAPPERS = [fusion_orientation, vqf_orientation]
AXIS = np.array([1.0, 0.4, 0.2]) / np.linalg.norm([1.0, 0.4, 0.2])
GAP_START, GAP = 500, 20  # a 20-sample gap after 10 s (the AR window, 6 s, is full)


def rotation_about_axis(theta, gyro_noise=0.0):
    """Truth ``(T, 4)`` and ``gyr, acc, mag`` for the angle ``theta`` (T,) rad about :data:`AXIS`."""
    q_true = Q.from_scipy(Rotation.from_rotvec(theta[:, None] * AXIS))
    rate = np.diff(theta, prepend=theta[0]) * FS  # sample k's rate turns q_{k−1} into q_k
    gyr = rate[:, None] * AXIS + np.random.default_rng(5).normal(0.0, gyro_noise, (theta.size, 3))
    acc = Q.rotate_inverse(q_true, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(q_true, frames.magnetic_field_enu())
    return q_true, gyr, acc, mag


def swing(n_t=800, gyro_noise=0.01):
    """A damped swing: 1.2 rad · exp(−t/20 s) · sin(2π 0.8 Hz t)."""
    t = np.arange(n_t) / FS
    return rotation_about_axis(1.2 * np.exp(-t / 20.0) * np.sin(2 * np.pi * 0.8 * t), gyro_noise)


def one_gap(n_t=800):
    received = np.ones(n_t, dtype=bool)
    received[GAP_START:GAP_START + GAP] = False
    return received


def error_deg(quat, q_true):
    return np.degrees(Q.angle_between(quat, q_true))


LOST = slice(GAP_START, GAP_START + GAP)
AFTER = slice(GAP_START + GAP, GAP_START + GAP + 10)


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_a_constant_rate_is_followed_through_gaps(wrapper):
    t = np.arange(800) / FS
    q_true, gyr, acc, mag = rotation_about_axis(1.0 * t)  # 1 rad/s: 23° in the gap
    received = one_gap()
    received[-10:] = False  # and a gap at the end of the recording
    err = {gap: error_deg(wrapper(gyr, acc, mag, fs=FS, received=received, gap=gap), q_true)
           for gap in ("hold", "constant_rate", "ar")}
    for gap in ("constant_rate", "ar"):
        assert err[gap][LOST].max() < 2.0, gap
        assert err[gap][-10:].max() < 2.0, gap
    assert err["hold"][LOST].mean() > 8.0
    assert err["hold"][-1] > 8.0


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_the_linear_prediction_follows_a_swing_better_than_the_held_rate(wrapper):
    q_true, gyr, acc, mag = swing()
    err = {gap: error_deg(wrapper(gyr, acc, mag, fs=FS, received=one_gap(), gap=gap), q_true)[LOST].mean()
           for gap in ("constant_rate", "ar")}
    assert err["ar"] < 0.3 * err["constant_rate"]
    assert err["ar"] < 3.0


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("gap", ["hold", "constant_rate", "ar"])
def test_replay_is_causal_and_lands_closer_after_the_gap(wrapper, gap):
    q_true, gyr, acc, mag = swing()
    off, on = (wrapper(gyr, acc, mag, fs=FS, received=one_gap(), gap=gap, replay=replay) for replay in (False, True))
    np.testing.assert_array_equal(on[:GAP_START + GAP], off[:GAP_START + GAP])  # lost samples unchanged
    err_off, err_on = error_deg(off, q_true)[AFTER].mean(), error_deg(on, q_true)[AFTER].mean()
    if gap == "ar":  # the prediction is already close here: the replay must not spoil it
        assert err_on < max(1.5 * err_off, 2.0)
    else:  # the linear ramp between the rates around the gap
        assert err_on < 0.6 * err_off


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("gap", ["hold", "constant_rate", "ar"])
def test_replay_without_gaps_changes_nothing(wrapper, gap):
    q_true, gyr, acc, mag = swing(400)
    off, on = (wrapper(gyr, acc, mag, fs=FS, gap=gap, replay=replay) for replay in (False, True))
    np.testing.assert_array_equal(on, off)


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_replay_starts_from_the_state_at_the_gaps_start(wrapper):
    """With ``"ar"`` the filter turned through the gap already; the replay of a constant rate
    (exact rates) must restart from the gap's start, not add the turn a second time."""
    t = np.arange(800) / FS
    q_true, gyr, acc, mag = rotation_about_axis(1.0 * t)
    quat = wrapper(gyr, acc, mag, fs=FS, received=one_gap(), gap="ar", replay=True)
    assert error_deg(quat, q_true)[AFTER].max() < 2.0


def test_gap_rates_hold_a_decaying_rate_and_replay_the_linear_ramp():
    history = np.tile([0.5, -1.0, 2.0], (10, 1))
    history[-1] = [1.0, 0.0, -2.0]  # the last received rate
    measured = np.array([3.0, 4.0, 2.0])
    predicted, replayed = gaps.gap_rates(history, 4, measured, gaps.CONSTANT_RATE, 0.5, 2, 300)
    np.testing.assert_allclose(predicted, [[0.5**k * v for v in (1.0, 0.0, -2.0)] for k in range(1, 5)])
    frac = np.arange(1, 5)[:, None] / 5.0
    np.testing.assert_allclose(replayed, history[-1] + frac * (measured - history[-1]))


def test_gap_rates_predict_an_oscillation_with_the_ar_fit():
    t = np.arange(400) / FS
    rates = np.stack([np.sin(2 * np.pi * 0.8 * t), 0.5 * np.cos(2 * np.pi * 0.5 * t), 0.3 + 0.0 * t], axis=1)
    predicted, replayed = gaps.gap_rates(rates[:350], 20, rates[370], gaps.AR, 1.0, 10, 300)
    assert np.abs(predicted - rates[350:370]).max() < 0.05  # a held rate would be off by ~1 rad/s
    assert np.abs(replayed - rates[350:370]).max() < 0.05


def test_the_compiled_dead_reckoning_is_the_quaternion_formula_bit_for_bit():
    """``peers._predict_gap`` (compiled) gives the bits of ``q_last ⊗ Exp(ω Δt Σ_{j≤k} f^j)`` written with
    :func:`wsnlib.quaternion.from_rotation_vector` and :func:`~wsnlib.quaternion.multiply` in numpy."""
    from wsnlib.orientation.peers import _predict_gap

    rng = np.random.default_rng(11)
    for case in range(200):
        q_last = Q.normalize(rng.normal(size=4))
        omega = rng.normal(size=3) * 10 ** rng.uniform(-4, 1.5) * (case % 7 != 0)  # some exactly still
        n_lost, dt = int(rng.integers(1, 60)), 1.0 / rng.choice([40.0, 50.0, 1500.0])
        factor = 1.0 if case % 3 == 0 else float(np.exp(-dt / rng.uniform(0.05, 2.0)))
        k = np.arange(1, n_lost + 1)
        weight = k.astype(float) if factor == 1.0 else factor * (1.0 - factor**k) / (1.0 - factor)
        expected = Q.multiply(q_last, Q.from_rotation_vector(omega * dt * weight[:, None]))
        assert _predict_gap(q_last, omega, n_lost, dt, factor).tobytes() == expected.tobytes(), case
