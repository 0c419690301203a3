"""Tests for the gated hybrid (:class:`wsnlib.orientation.SingleFrameGate`) and the peers' gap
prediction (``gap="constant_rate"`` of :func:`fusion_orientation` and :func:`vqf_orientation`).

References: a plain-Python restatement of the four checks (:func:`reference_trusted`),
the ungated hybrid and the plain data fusion (what the gate must reduce to when it is open /
closed), and a sample-by-sample quaternion product for the gap prediction.
"""

import math

import numpy as np
import pytest

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.loss import gilbert_elliott, packets_to_samples
from wsnlib.orientation import (
    SingleFrameGate,
    estimate_orientation,
    fusion_orientation,
    kalman_orientation,
    madgwick,
    single_frame_trusted,
    vqf_orientation,
)
from wsnlib.orientation.hybrid_blend import blend_with_single_frame
from wsnlib.orientation.peers import _predict_gap

FS = 50.0
G_ENU = frames.gravity_specific_force_enu()
M_ENU = frames.magnetic_field_enu()
N = 400
BLENDS = ["output", "feedback"]
WRAPPERS = [fusion_orientation, vqf_orientation]


def rotation(rate=0.5, n=N, axis=(1.0, 2.0, -0.5)):
    """Noise-free data of a rotation about a fixed body axis at ``rate`` rad/s: q, gyr, acc, mag."""
    t = np.arange(n) / FS
    axis = np.asarray(axis) / np.linalg.norm(axis)
    q = Q.multiply(Q.normalize([0.9, 0.1, -0.3, 0.2]), Q.from_rotation_vector(rate * t[:, None] * axis))
    gyr = np.broadcast_to(rate * axis, (n, 3)).copy()
    return q, gyr, Q.rotate_inverse(q, G_ENU), Q.rotate_inverse(q, M_ENU)


@pytest.fixture(scope="module")
def masks():
    packets = gilbert_elliott(N // 6 + 1, 0.25, 3.0, rng=np.random.default_rng(11), shape=(3,))
    packets[:, 0] = True
    return packets_to_samples(packets, 6, N)


def reference_trusted(gyr, acc, mag, received, gate: SingleFrameGate, fs=FS):
    """The documented checks, one sample at a time, in plain Python."""
    k = 1.0 - math.exp(-1.0 / (fs * gate.reference_tau_s))
    ref_norm = ref_dip = None
    out = np.zeros(len(received), dtype=bool)
    for t in np.flatnonzero(received):
        a, m, g = acc[t], mag[t], gyr[t]
        acc_ok = abs(np.linalg.norm(a) / 9.80665 - 1.0) <= gate.acc_norm_tolerance
        rate_ok = np.linalg.norm(g) <= gate.rate_limit
        m_norm = np.linalg.norm(m)
        dip = math.asin(float(np.clip(-(a @ m) / (np.linalg.norm(a) * m_norm), -1.0, 1.0)))
        if ref_norm is None:
            ref_norm, ref_dip = m_norm, dip
        mag_ok = abs(m_norm - ref_norm) <= gate.mag_norm_tolerance * ref_norm and abs(dip - ref_dip) <= (
            gate.mag_dip_tolerance)
        out[t] = acc_ok and rate_ok and mag_ok
        ref_norm += k * (m_norm - ref_norm)
        if acc_ok:
            ref_dip += k * (dip - ref_dip)
    return out


def disturbed():
    """Rotation data with an accelerating stretch, a fast stretch and a disturbed field."""
    _, gyr, acc, mag = rotation()
    acc, mag, gyr = acc.copy(), mag.copy(), gyr.copy()
    acc[50:80] *= 1.3  # 0.3 g along the measured direction
    gyr[120:140] *= 8.0  # 4 rad/s
    mag[200:260] = mag[200:260] * 1.4  # norm 40 % up
    mag[300:340] += 25.0 * np.array([0.0, 0.0, 1.0])  # dip moved
    return gyr, acc, mag


# ================================================================ the checks


def test_trusted_matches_reference_and_closes_where_disturbed(masks):
    gyr, acc, mag = disturbed()
    gate = SingleFrameGate()
    got = single_frame_trusted(gyr, acc, mag, masks, fs=FS)
    assert got.shape == masks.shape
    for row in range(masks.shape[0]):
        np.testing.assert_array_equal(got[row], reference_trusted(gyr, acc, mag, masks[row], gate))
    full = single_frame_trusted(gyr, acc, mag, fs=FS)
    assert full[:50].all() and full[80:120].all() and full[140:200].all()
    assert not full[50:80].any(), "acceleration of 0.3 g must close the gate"
    assert not full[120:140].any(), "4 rad/s must close the gate"
    assert not full[200:260].any(), "a field 40 % stronger must close the gate"
    assert not full[300:340].all(), "a field tilted out of its dip must close the gate"
    assert not got[~masks].any(), "lost samples are never trusted"


def test_each_tolerance_can_be_switched_off():
    gyr, acc, mag = disturbed()
    off = SingleFrameGate(acc_norm_tolerance=np.inf, rate_limit=np.inf, mag_norm_tolerance=np.inf,
                          mag_dip_tolerance=np.inf)
    assert single_frame_trusted(gyr, acc, mag, fs=FS, single_frame_gate=off).all()
    only_rate = SingleFrameGate(acc_norm_tolerance=np.inf, mag_norm_tolerance=np.inf, mag_dip_tolerance=np.inf)
    got = single_frame_trusted(gyr, acc, mag, fs=FS, single_frame_gate=only_rate)
    np.testing.assert_array_equal(~got, np.isin(np.arange(N), np.arange(120, 140)))


def test_reference_follows_a_lasting_change_of_the_field():
    """A field that stays changed becomes the reference after a few τ_ref."""
    _, gyr, acc, mag = rotation(n=3000)
    mag = mag.copy()
    mag[500:] *= 1.3
    got = single_frame_trusted(gyr, acc, mag, fs=FS, single_frame_gate=SingleFrameGate(reference_tau_s=5.0))
    assert not got[500:520].any() and got[-500:].all()


# ================================================================ the gated hybrid reduces to known filters


@pytest.mark.parametrize("blend", BLENDS)
def test_closed_gate_gives_the_data_fusion(masks, blend):
    """Accelerating everywhere: the gated hybrid is Madgwick's filter with the same mask."""
    _, gyr, acc, mag = rotation()
    acc = acc * 1.5  # Madgwick and TRIAD use the direction only; the gate sees 1.5 g
    kwargs = dict(fs=FS, beta=0.1, received=masks)
    gated = estimate_orientation(gyr, acc, mag, blend=blend, rho=1.0, tau=0.5,
                                 single_frame_gate=SingleFrameGate(), **kwargs)
    plain = estimate_orientation(gyr, acc, mag, **kwargs)
    np.testing.assert_array_equal(gated, plain)
    ungated = estimate_orientation(gyr, acc, mag, blend=blend, rho=1.0, tau=0.5, **kwargs)
    assert np.abs(ungated - plain).max() > 1e-6, "the test needs samples where the plain hybrid blends"


@pytest.mark.parametrize("blend", BLENDS)
def test_open_gate_equals_the_ungated_hybrid(masks, blend):
    """Clean, slow motion: every sample trusted, so the gated hybrid is the hybrid."""
    _, gyr, acc, mag = rotation()
    assert single_frame_trusted(gyr, acc, mag, masks, fs=FS).sum() == masks.sum()
    kwargs = dict(fs=FS, beta=0.02, received=masks, blend=blend, rho=1.0, tau=2.0)
    np.testing.assert_array_equal(estimate_orientation(gyr, acc, mag, single_frame_gate=True, **kwargs),
                                  estimate_orientation(gyr, acc, mag, **kwargs))


def test_output_blend_skips_exactly_the_untrusted_samples(masks):
    gyr, acc, mag = disturbed()
    kwargs = dict(fs=FS, beta=0.05, received=masks, blend="output", rho=1.0, tau=200.0)
    gated = estimate_orientation(gyr, acc, mag, single_frame_gate=True, **kwargs)
    ungated = estimate_orientation(gyr, acc, mag, **kwargs)
    q_d = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.05, received=masks)
    trusted = single_frame_trusted(gyr, acc, mag, masks, fs=FS)
    untrusted_rx = masks & ~trusted
    assert untrusted_rx.sum() > 20
    np.testing.assert_array_equal(gated[untrusted_rx], q_d[untrusted_rx])
    np.testing.assert_array_equal(gated[trusted], ungated[trusted])


@pytest.mark.parametrize("leading", [False, True])
def test_kernel_gate_equals_blend_with_single_frame_gate(masks, leading):
    """The gate inside the filter loop and the output-stage gate agree (Madgwick's output blend)."""
    gyr, acc, mag = disturbed()
    q0 = None if not leading else Q.normalize([0.9, 0.1, -0.3, 0.2])
    kwargs = dict(fs=FS, received=masks, q0=q0)
    inside = estimate_orientation(gyr, acc, mag, beta=0.05, blend="output", rho=1.0, tau=6.0,
                                  single_frame_gate=True, **kwargs)
    stage = blend_with_single_frame(madgwick(gyr, acc, mag, beta=0.05, **kwargs), acc, mag, masks, rho=1.0,
                                    tau=6.0, leading_gap=leading, single_frame_gate=True, gyr=gyr, fs=FS)
    np.testing.assert_allclose(inside, stage, atol=1e-12, rtol=0)


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("blend", BLENDS)
def test_peers_closed_gate_gives_the_plain_peer(masks, wrapper, blend):
    _, gyr, acc, mag = rotation()
    acc = acc * 1.5
    plain = wrapper(gyr, acc, mag, fs=FS, received=masks[:1])
    gated = wrapper(gyr, acc, mag, fs=FS, received=masks[:1], blend=blend, rho=1.0, tau=0.5,
                    single_frame_gate=SingleFrameGate())
    np.testing.assert_allclose(gated, plain, atol=1e-12, rtol=0)


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("blend", BLENDS)
def test_peers_open_gate_equals_the_ungated_hybrid(masks, wrapper, blend):
    _, gyr, acc, mag = rotation()
    kwargs = dict(fs=FS, received=masks[:1], blend=blend, rho=1.0, tau=2.0)
    np.testing.assert_allclose(wrapper(gyr, acc, mag, single_frame_gate=True, **kwargs),
                               wrapper(gyr, acc, mag, **kwargs), atol=1e-12, rtol=0)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"acc_norm_tolerance": 0.0}, "acc_norm_tolerance"),
        ({"rate_limit": -1.0}, "rate_limit"),
        ({"mag_norm_tolerance": np.nan}, "mag_norm_tolerance"),
        ({"mag_dip_tolerance": "x"}, "mag_dip_tolerance"),
        ({"reference_tau_s": 0.0}, "reference_tau_s"),
    ],
)
def test_gate_settings_errors(kwargs, name):
    with pytest.raises(ValueError, match=name):
        SingleFrameGate(**kwargs)


def test_gate_argument_errors():
    _, gyr, acc, mag = rotation(n=20)
    with pytest.raises(ValueError, match="single_frame_gate is not used by estimate_orientation without blend"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, single_frame_gate=True)
    with pytest.raises(TypeError, match="single_frame_gate"):  # the Kalman filter has no hybrid
        kalman_orientation(gyr, acc, mag, fs=FS, single_frame_gate=True)
    with pytest.raises(ValueError, match="single_frame_gate"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, blend="output", single_frame_gate="yes")
    with pytest.raises(ValueError, match="return_weight"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, blend="output", single_frame_gate=True,
                             return_weight=True)
    with pytest.raises(ValueError, match="gyr"):
        blend_with_single_frame(Q.identity((20,)), acc, mag, single_frame_gate=True)
    with pytest.raises(ValueError, match="single_frame_gate"):
        blend_with_single_frame(Q.identity((20,)), acc, mag, gyr=gyr, fs=FS)
    for wrapper in WRAPPERS:
        with pytest.raises(ValueError, match=f"single_frame_gate is not used by {wrapper.__name__} without blend"):
            wrapper(gyr, acc, mag, fs=FS, single_frame_gate=True)
        with pytest.raises(ValueError, match="single_frame_gate"):
            wrapper(gyr, acc, mag, fs=FS, blend="output", single_frame_gate="yes")
    with pytest.raises(ValueError, match="mag"):
        single_frame_trusted(gyr, acc, None, fs=FS)
    with pytest.raises(ValueError, match="fs"):
        single_frame_trusted(gyr, acc, mag, fs=0.0)


# ================================================================ the peers' gap prediction


def test_predict_gap_is_the_sample_by_sample_product():
    q_last = Q.normalize([0.3, -0.2, 0.8, 0.1])
    omega = np.array([1.0, -2.0, 0.5])
    for factor in (1.0, 0.9):
        got = _predict_gap(q_last, omega, 7, 1.0 / FS, factor)
        q, w = q_last, omega.copy()
        for k in range(7):
            w = w * factor
            q = Q.multiply(q, Q.from_rotation_vector(w / FS))
            np.testing.assert_allclose(got[k], q, atol=1e-14)


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_constant_rate_gap_follows_a_constant_rotation(wrapper):
    """Constant rate, exact signals: the prediction stays on the truth, holding does not."""
    q_true, gyr, acc, mag = rotation(rate=2.0, n=600)
    mask = np.ones(600, dtype=bool)
    mask[400:430] = False  # 0.6 s gap after the filter has converged
    mask[580:] = False  # a gap at the end
    mask[:5] = False  # a gap before the start is held either way
    held = wrapper(gyr, acc, mag, fs=FS, received=mask)
    pred = wrapper(gyr, acc, mag, fs=FS, received=mask, gap="constant_rate")
    np.testing.assert_array_equal(pred[:400], held[:400])
    np.testing.assert_array_equal(pred[:5], np.broadcast_to(pred[5], (5, 4)))
    err_pred = np.degrees(Q.angle_between(pred, q_true))
    err_held = np.degrees(Q.angle_between(held, q_true))
    before = err_pred[399]
    assert err_pred[400:430].max() < before + 0.5 and err_held[429] > 60.0
    assert err_pred[580:].max() < err_pred[579] + 0.5 and err_held[-1] > 30.0
    # The filter continues from the prediction: no jump back when the gap ends.
    assert err_pred[430:440].max() < before + 0.5


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_gap_time_constant_decays_the_extrapolated_rate(wrapper):
    _, gyr, acc, mag = rotation(rate=2.0, n=300)
    mask = np.ones(300, dtype=bool)
    mask[250:280] = False
    const = wrapper(gyr, acc, mag, fs=FS, received=mask, gap="constant_rate")
    decayed = wrapper(gyr, acc, mag, fs=FS, received=mask, gap="constant_rate", gap_time_constant=0.1)
    turned_const = np.degrees(Q.angle_between(const[279], const[249]))
    turned_decay = np.degrees(Q.angle_between(decayed[279], decayed[249]))
    expected_decay = np.degrees(2.0 * sum(math.exp(-k / (FS * 0.1)) for k in range(1, 31)) / FS)
    assert turned_const == pytest.approx(np.degrees(2.0 * 30 / FS), abs=0.5)
    assert turned_decay == pytest.approx(expected_decay, abs=0.5)


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_gap_prediction_with_the_feedback_hybrid_and_batches(wrapper, masks):
    _, gyr, acc, mag = rotation()
    batch = wrapper(gyr, acc, mag, fs=FS, received=masks, gap="constant_rate", blend="feedback", tau=6.0)
    for row in range(masks.shape[0]):
        one = wrapper(gyr, acc, mag, fs=FS, received=masks[row], gap="constant_rate", blend="feedback", tau=6.0)
        np.testing.assert_array_equal(batch[row], one)
    assert np.all(np.isfinite(batch))


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_gap_argument_errors(wrapper):
    _, gyr, acc, mag = rotation(n=20)
    with pytest.raises(ValueError, match="gap"):
        wrapper(gyr, acc, mag, fs=FS, gap="linear")
    with pytest.raises(ValueError, match="gap_rate_prediction_window_s only apply to gap='ar' in " + wrapper.__name__):
        wrapper(gyr, acc, mag, fs=FS, gap="constant_rate", gap_rate_prediction_window_s=2.0)
    with pytest.raises(ValueError, match="gap_time_constant.*gap='hold'"):
        wrapper(gyr, acc, mag, fs=FS, gap_time_constant=0.2)
    with pytest.raises(ValueError, match="gap_time_constant"):
        wrapper(gyr, acc, mag, fs=FS, gap="constant_rate", gap_time_constant=-1.0)
