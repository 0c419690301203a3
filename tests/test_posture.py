import math

import numpy as np
import pytest

from wsnlib import frames, posture
from wsnlib.posture import PAPER_ARM_CHAIN, ArmChain, forward_chain, pitch_from_acc, recursive_chain

G = frames.STANDARD_GRAVITY


def _static_acc(pitch, roll=0.0, gravity=G):
    """Accelerometer at rest, device x along the segment at elevation ``pitch``, rolled by ``roll``."""
    pitch, roll = np.broadcast_arrays(np.asarray(pitch, float), np.asarray(roll, float))
    return gravity * np.stack(
        [np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)], axis=-1
    )


# --- pitch from the accelerometer, eqs. (5)–(7) ------------------------------------------------

PITCH_GRID_DEG = [-90.0, -89.0, -60.0, -30.0, -1.0, 0.0, 1.0, 45.0, 75.0, 89.9, 90.0]


@pytest.mark.parametrize("method", ["gating", "lowpass", "none"])
@pytest.mark.parametrize("roll_deg", [0.0, 40.0, -120.0, 180.0])
def test_pitch_is_exact_on_static_noise_free_readings(method, roll_deg):
    pitch = np.radians(PITCH_GRID_DEG)
    # each pitch held for 20 samples: (n_pitch, T=20, 3)
    acc = np.repeat(_static_acc(pitch, np.radians(roll_deg))[:, None, :], 20, axis=1)
    got = pitch_from_acc(acc, method=method, fs=30.0)
    assert got.shape == (len(pitch), 20)
    assert got == pytest.approx(np.repeat(pitch[:, None], 20, axis=1), abs=1e-7)
    assert np.all(np.abs(got) <= math.pi / 2)


def test_pitch_sign_follows_the_segment_and_its_device_axis():
    up = _static_acc(np.radians(30.0))[None, :]
    assert pitch_from_acc(up)[0] == pytest.approx(np.radians(30.0))   # segment above horizontal: θ > 0
    # the same pose read by a device mounted with its -y axis along the segment
    mounted = np.array([[0.0, -G * np.sin(np.radians(30.0)), G * np.cos(np.radians(30.0))]])
    assert pitch_from_acc(mounted, segment_axis=(0.0, -2.0, 0.0))[0] == pytest.approx(np.radians(30.0))
    # arm hanging down / straight up are the ±90° limits
    assert pitch_from_acc([[-G, 0.0, 0.0], [G, 0.0, 0.0]]) == pytest.approx([-math.pi / 2, math.pi / 2])


def test_gating_rejects_high_magnitude_samples_and_holds_the_last_good_pitch():
    pitch = np.radians([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    acc = _static_acc(pitch)
    acc[2] = 1.5 * _static_acc(np.radians(80.0))           # |a| = 1.5 g: rejected
    acc[3] = _static_acc(np.radians(80.0)) + [3.0, 0, 0]   # dynamic acceleration along x: rejected
    got = pitch_from_acc(acc, xi=0.5)
    assert got == pytest.approx(np.radians([10.0, 20.0, 20.0, 20.0, 50.0, 60.0]))
    assert posture.gravity_gate(acc, xi=0.5).tolist() == [True, True, False, False, True, True]
    # a magnitude just inside the gate counts
    acc[2] = (G + 0.49) / G * _static_acc(np.radians(80.0))
    assert pitch_from_acc(acc, xi=0.5)[2] == pytest.approx(np.radians(80.0))


def test_gating_before_the_first_accepted_sample_takes_its_pitch():
    acc = _static_acc(np.radians([5.0, 5.0, 25.0, 35.0]))
    acc[:2] *= 2.0
    assert pitch_from_acc(acc)[:, None] == pytest.approx(np.radians([[25.0], [25.0], [25.0], [35.0]]))


def test_gating_with_no_accepted_sample_raises_naming_xi():
    acc = np.stack([_static_acc(np.radians([0.0, 10.0, 20.0])), 2.0 * _static_acc(np.radians([0.0, 10.0, 20.0]))])
    assert pitch_from_acc(acc[:1]).shape == (1, 3)
    with pytest.raises(ValueError, match=r"xi.*batch index \(1,\)|batch index \(1,\).*xi"):
        pitch_from_acc(acc)
    # a larger gate lets them through; xi = 0 keeps only exact-g samples
    assert pitch_from_acc(acc, xi=1.01 * G).shape == (2, 3)
    assert pitch_from_acc(acc[0], xi=0.0) == pytest.approx(np.radians([0.0, 10.0, 20.0]))


def test_lowpass_removes_a_high_frequency_disturbance():
    fs, n = 100.0, 400
    t = np.arange(n) / fs
    true_pitch = np.radians(30.0)
    acc = np.repeat(_static_acc(true_pitch)[None, :], n, axis=0)
    acc[:, 0] += 3.0 * np.sin(2 * np.pi * 12.0 * t)      # 12 Hz vibration along the segment
    acc[:, 2] += 2.0 * np.sin(2 * np.pi * 9.0 * t + 1.0)
    raw = pitch_from_acc(acc, method="none")
    smooth = pitch_from_acc(acc, method="lowpass", fs=fs, cutoff_hz=1.0, order=2)
    settled = slice(100, None)
    assert np.max(np.abs(raw[settled] - true_pitch)) > np.radians(10.0)
    assert np.max(np.abs(smooth[settled] - true_pitch)) < np.radians(0.5)
    # causal: changing the future leaves the past unchanged
    later = acc.copy()
    later[200:] += 5.0
    assert np.array_equal(pitch_from_acc(later, method="lowpass", fs=fs)[:200],
                          pitch_from_acc(acc, method="lowpass", fs=fs)[:200])


@pytest.mark.parametrize(("order", "cutoff_hz"), [(2, 1.0), (8, 0.05), (10, 0.2), (6, 0.02)])
def test_lowpass_matches_the_butterworth_response_at_high_orders(order, cutoff_hz):
    """Reference: a Butterworth low-pass passes a sinusoid at its cut-off with gain 1/sqrt(2)
    (scipy's bilinear design is exact there) and a constant with gain 1.  Along the segment
    axis x, with z constant, the settled pitch peaks at atan((g sin θ0 + A/sqrt(2)) / (g cos θ0)).
    The (b, a) polynomial form was unstable for order 8 at 0.05 Hz (pitch 0..84° for ±17°)."""
    fs, periods = 30.0, 25
    t = np.arange(int(periods * fs / cutoff_hz)) / fs
    base, amplitude = np.radians(10.0), 1.5  # rad, m/s²
    acc = np.zeros(t.shape + (3,))
    acc[:, 0] = G * np.sin(base) + amplitude * np.sin(2 * np.pi * cutoff_hz * t)
    acc[:, 2] = G * np.cos(base)
    pitch = pitch_from_acc(acc, method="lowpass", fs=fs, cutoff_hz=cutoff_hz, order=order)
    settled = pitch[-int(3 * fs / cutoff_hz):]  # the last three periods
    peak = math.atan((G * math.sin(base) + amplitude / math.sqrt(2.0)) / (G * math.cos(base)))
    trough = math.atan((G * math.sin(base) - amplitude / math.sqrt(2.0)) / (G * math.cos(base)))
    assert np.degrees(settled.max()) == pytest.approx(np.degrees(peak), abs=0.02)
    assert np.degrees(settled.min()) == pytest.approx(np.degrees(trough), abs=0.02)
    # A pose held still is returned unchanged from the first sample (steady-state start).
    still = pitch_from_acc(np.repeat(_static_acc(np.radians(17.0))[None], 3000, axis=0),
                           method="lowpass", fs=fs, cutoff_hz=cutoff_hz, order=order)
    np.testing.assert_allclose(still, np.radians(17.0), atol=1e-9)


def test_pitch_is_vectorised_over_batches(rng):
    pitch = rng.uniform(-1.5, 1.5, size=(3, 4, 50))
    acc = _static_acc(pitch, rng.uniform(-3, 3, size=pitch.shape)) + 0.05 * rng.standard_normal(pitch.shape + (3,))
    acc[..., 10:15, :] *= 1.3
    for method in ("gating", "lowpass", "none"):
        batch = pitch_from_acc(acc, method=method, fs=30.0)
        single = np.stack([[pitch_from_acc(acc[i, j], method=method, fs=30.0) for j in range(4)] for i in range(3)])
        assert np.array_equal(batch, single)


@pytest.mark.parametrize(
    ("acc", "kwargs", "match"),
    [
        ([[0.0, np.nan, G]], {}, "acc contains NaN"),
        ([[0.0, 0.0, G], [0.0, 0.0, 0.0]], {}, "acc has a zero-norm vector"),
        ([[0.0, G]], {}, r"acc must have shape \(\.\.\., 3\)"),
        ([0.0, 0.0, G], {}, "acc must have at least 2"),
        ([[0.0, 0.0, G]], {"method": "kalman"}, "method"),
        ([[0.0, 0.0, G]], {"xi": -0.1}, "xi"),
        ([[0.0, 0.0, G]], {"xi": float("nan")}, "xi"),
        ([[0.0, 0.0, G]], {"method": "lowpass"}, "fs"),
        ([[0.0, 0.0, G]], {"method": "lowpass", "fs": 0.0}, "fs"),
        ([[0.0, 0.0, G]], {"method": "lowpass", "fs": -30.0}, "fs"),
        ([[0.0, 0.0, G]], {"fs": 0.0}, "fs"),
        ([[0.0, 0.0, G]], {"method": "lowpass", "fs": 30.0, "cutoff_hz": 15.0}, "cutoff_hz"),
        ([[0.0, 0.0, G]], {"method": "lowpass", "fs": 30.0, "cutoff_hz": 0.0}, "cutoff_hz"),
        ([[0.0, 0.0, G]], {"method": "lowpass", "fs": 30.0, "order": 0}, "order"),
        ([[0.0, 0.0, G]], {"segment_axis": (0.0, 0.0, 0.0)}, "segment_axis"),
        ([[0.0, 0.0, G]], {"segment_axis": (1.0, 0.0)}, "segment_axis"),
        ([[0.0, 0.0, G]], {"gravity": 0.0}, "gravity"),
    ],
)
def test_pitch_rejects_bad_inputs(acc, kwargs, match):
    with pytest.raises(ValueError, match=match):
        pitch_from_acc(acc, **kwargs)


# --- the recursive chain, eqs. (8)–(10) ----------------------------------------------------------

# Table 1 of paper 002 (cm → m): target 1 (upper arm), target 2 (forearm) per posture.
TABLE1 = {
    "P1": ([0.0, 0.0, -0.15], [0.0, 0.0, -0.425]),
    "P2": ([0.0, 0.0, 0.15], [0.0, 0.0, 0.425]),
    "P3": ([0.0, 0.15, 0.0], [0.0, 0.425, 0.0]),
    "P4": ([0.15, 0.0, 0.0], [0.425, 0.0, 0.0]),
    "P5": ([-0.11, 0.11, 0.0], [-0.34, 0.21, 0.0]),
}
# (heading, pitch) in degrees of (upper arm, forearm) in each posture
TABLE1_ANGLES = {
    "P1": ((0.0, -90.0), (0.0, -90.0)),
    "P2": ((0.0, 90.0), (0.0, 90.0)),
    "P3": ((90.0, 0.0), (90.0, 0.0)),
    "P4": ((0.0, 0.0), (0.0, 0.0)),
    "P5": ((135.0, 0.0), (180.0, 0.0)),   # bent elbow: upper arm forward-left, forearm to the left
}


@pytest.mark.parametrize("name", list(TABLE1))
def test_table1_postures_are_recovered(name):
    radio = np.array(TABLE1[name])[None]                                   # (T=1, S=2, 3)
    heading, pitch = np.radians(np.array(TABLE1_ANGLES[name])).T
    truth = forward_chain(heading[None], pitch[None], PAPER_ARM_CHAIN)
    # exact inputs: radio estimates on the true segment line
    exact = recursive_chain(truth["devices"], pitch[None], PAPER_ARM_CHAIN)
    assert exact["devices"] == pytest.approx(truth["devices"], abs=1e-12)
    assert exact["joints"] == pytest.approx(truth["joints"], abs=1e-12)
    # the paper's (rounded) table values as radio estimates
    table = recursive_chain(radio, pitch[None], PAPER_ARM_CHAIN)
    tolerance = 1e-12 if name != "P5" else 0.01
    assert table["devices"] == pytest.approx(radio, abs=tolerance)
    assert table["devices"] == pytest.approx(truth["devices"], abs=tolerance)
    # straight arm: elbow at 0.30 m and wrist at 0.55 m from the shoulder
    if name != "P5":
        unit = radio[0, 0] / 0.15
        assert table["joints"][0] == pytest.approx(np.stack([0.30 * unit, 0.55 * unit]), abs=1e-12)


def test_bent_elbow_postures_are_exact(rng):
    # hand-checked: upper arm hanging down, forearm pointing forward
    radio = np.array([[[0.0, 0.0, -0.15], [0.0, 0.125, -0.30]]])
    out = recursive_chain(radio, np.radians([[-90.0, 0.0]]), PAPER_ARM_CHAIN)
    assert out["joints"][0] == pytest.approx(np.array([[0.0, 0.0, -0.30], [0.0, 0.25, -0.30]]), abs=1e-12)
    assert out["devices"][0] == pytest.approx(radio[0], abs=1e-12)
    # a grid of bent postures with radio estimates on the true segment line
    heading = rng.uniform(0.0, 2 * np.pi, size=(200, 2))
    pitch = rng.uniform(-np.pi / 2, np.pi / 2, size=(200, 2))
    truth = forward_chain(heading, pitch, PAPER_ARM_CHAIN)
    out = recursive_chain(truth["devices"], pitch, PAPER_ARM_CHAIN)
    assert out["devices"] == pytest.approx(truth["devices"], abs=1e-12)
    assert out["joints"] == pytest.approx(truth["joints"], abs=1e-12)
    assert out["heading"] == pytest.approx(heading, abs=1e-9)
    assert not out["heading_held"].any()
    # a radio estimate anywhere on the ray from the joint (beyond or short of the device) is as good
    elbow = truth["joints"][:, 0]
    far = truth["devices"].copy()
    far[:, 0] = 3.0 * truth["devices"][:, 0]
    far[:, 1] = elbow + 0.2 * (truth["devices"][:, 1] - elbow)
    out = recursive_chain(far, pitch, PAPER_ARM_CHAIN)
    assert out["devices"] == pytest.approx(truth["devices"], abs=1e-12)


def test_radio_distance_and_height_errors_are_corrected():
    chain = PAPER_ARM_CHAIN
    heading = np.radians([[30.0, 100.0]])
    pitch = np.radians([[20.0, -35.0]])
    truth = forward_chain(heading, pitch, chain)
    elbow = truth["joints"][0, 0]
    # radio estimates at the right azimuth, but at the wrong distance and height
    radio = np.array([[
        [0.4 * np.cos(heading[0, 0]), 0.4 * np.sin(heading[0, 0]), -0.25],
        elbow + [0.05 * np.cos(heading[0, 1]), 0.05 * np.sin(heading[0, 1]), 0.30],
    ]])
    out = recursive_chain(radio, pitch, chain)
    assert np.linalg.norm(out["devices"][0, 0]) == pytest.approx(chain.device_offsets_m[0])
    assert np.linalg.norm(out["devices"][0, 1] - out["joints"][0, 0]) == pytest.approx(chain.device_offsets_m[1])
    assert np.linalg.norm(out["joints"][0, 1] - out["joints"][0, 0]) == pytest.approx(chain.segment_lengths_m[1])
    assert out["devices"] == pytest.approx(truth["devices"], abs=1e-12)
    assert out["joints"] == pytest.approx(truth["joints"], abs=1e-12)
    # and the correction brings the radio estimate closer to the truth
    assert np.all(np.linalg.norm(out["devices"] - truth["devices"], axis=-1)
                  < np.linalg.norm(radio - truth["devices"], axis=-1))


def test_end_to_end_from_accelerometer_pitch():
    heading = np.radians([[135.0, 180.0], [60.0, 60.0]])
    pitch = np.radians([[-10.0, 25.0], [45.0, 45.0]])
    truth = forward_chain(heading, pitch, PAPER_ARM_CHAIN)
    acc = np.moveaxis(_static_acc(pitch, roll=0.3), 1, 0)               # (S, T, 3), one series per device
    estimated_pitch = pitch_from_acc(acc).T                              # (T, S)
    # radio estimates 30 % too far from each proximal joint, along the true azimuth
    proximal = np.concatenate([np.zeros((2, 1, 3)), truth["joints"][:, :1]], axis=1)
    radio = proximal + 1.3 * (truth["devices"] - proximal)
    out = recursive_chain(radio, estimated_pitch, PAPER_ARM_CHAIN)
    assert out["joints"] == pytest.approx(truth["joints"], abs=1e-9)


def test_chain_is_vectorised_over_batches_and_time(rng):
    radio = rng.normal(scale=0.3, size=(3, 7, 2, 3))
    pitch = rng.uniform(-np.pi / 2, np.pi / 2, size=(3, 7, 2))
    batch = recursive_chain(radio, pitch, PAPER_ARM_CHAIN)
    for key in ("devices", "joints", "heading"):
        single = np.stack([
            np.concatenate([recursive_chain(radio[r, t][None], pitch[r, t][None], PAPER_ARM_CHAIN)[key]
                            for t in range(7)])
            for r in range(3)
        ])
        assert np.array_equal(batch[key], single), key
    # pitch broadcast over the batch
    shared = recursive_chain(radio, pitch[0], PAPER_ARM_CHAIN)
    assert shared["devices"][2] == pytest.approx(recursive_chain(radio[2], pitch[0], PAPER_ARM_CHAIN)["devices"])
    # a moved origin translates everything
    moved = recursive_chain(radio + [1.0, 2.0, 3.0], pitch, PAPER_ARM_CHAIN, origin=(1.0, 2.0, 3.0))
    assert moved["joints"] == pytest.approx(batch["joints"] + [1.0, 2.0, 3.0], abs=1e-12)


def test_undefined_heading_holds_the_previous_one_or_zero():
    chain = ArmChain(segment_lengths_m=(0.3,), device_offsets_m=(0.15,))
    radio = np.array([
        [0.0, 0.0, 0.2],       # straight above the shoulder: undefined, nothing earlier → 0
        [0.0, 0.1, 0.0],       # forward: 90°
        [0.0, 0.0, -0.1],      # straight below: hold 90°
        [1e-12, 0.0, -0.1],    # within the tolerance: hold 90°
        [-0.2, 0.0, 0.05],     # left: 180°
    ])[:, None, :]
    pitch = np.full((5, 1), np.radians(30.0))
    out = recursive_chain(radio, pitch, chain)
    assert out["heading"][:, 0] == pytest.approx(np.radians([0.0, 90.0, 90.0, 90.0, 180.0]))
    assert out["heading_held"][:, 0].tolist() == [True, False, True, True, False]
    c, s = 0.15 * np.cos(np.radians(30.0)), 0.15 * np.sin(np.radians(30.0))
    assert out["devices"][:, 0] == pytest.approx(
        np.array([[c, 0, s], [0, c, s], [0, c, s], [0, c, s], [-c, 0, s]]), abs=1e-12)
    # held per batch element, independently
    both = recursive_chain(np.stack([radio, radio[::-1]]), pitch, chain)
    assert both["heading"][1, :, 0] == pytest.approx(np.radians([180.0, 180.0, 180.0, 90.0, 90.0]))
    # at ±90° pitch the heading moves nothing
    vertical = recursive_chain(radio, np.full((5, 1), -np.pi / 2), chain)
    assert vertical["joints"][:, 0] == pytest.approx(np.tile([0.0, 0.0, -0.3], (5, 1)), abs=1e-12)
    # a zero tolerance only catches exact verticals
    exact = recursive_chain(radio, pitch, chain, heading_tol_m=0.0)
    assert exact["heading_held"][:, 0].tolist() == [True, False, True, False, False]


def test_three_segment_chain(rng):
    chain = ArmChain(segment_lengths_m=(0.30, 0.25, 0.08), device_offsets_m=(0.15, 0.125, 0.04))
    heading = rng.uniform(0.0, 2 * np.pi, size=(2, 10, 3))
    pitch = rng.uniform(-1.4, 1.4, size=(2, 10, 3))
    truth = forward_chain(heading, pitch, chain)
    out = recursive_chain(truth["devices"], pitch, chain)
    assert out["devices"].shape == (2, 10, 3, 3)
    assert out["joints"] == pytest.approx(truth["joints"], abs=1e-12)
    hand = np.linalg.norm(out["joints"][..., 2, :] - out["joints"][..., 1, :], axis=-1)
    assert hand == pytest.approx(np.full((2, 10), 0.08))
    # hand-checked: arm straight forward, hand bent down
    radio = np.array([[[0.0, 0.1, 0.0], [0.0, 0.4, 0.0], [0.0, 0.55, -0.2]]])
    out = recursive_chain(radio, np.radians([[0.0, 0.0, -90.0]]), chain)
    assert out["joints"][0] == pytest.approx(np.array([[0, 0.30, 0], [0, 0.55, 0], [0, 0.55, -0.08]]), abs=1e-12)
    assert out["devices"][0, 2] == pytest.approx([0.0, 0.55, -0.04], abs=1e-12)


def test_arm_chain_validation():
    chain = ArmChain([0.3, 0.25], np.array([0.15, 0.125]))
    assert chain.segment_lengths_m == (0.3, 0.25) and chain.n_segments == 2
    assert hash(chain) == hash(ArmChain((0.3, 0.25), (0.15, 0.125)))
    with pytest.raises(ValueError, match="segment_lengths_m"):
        ArmChain((0.3, 0.0), (0.15, 0.0))
    with pytest.raises(ValueError, match="device_offsets_m"):
        ArmChain((0.3, 0.25), (0.15,))
    with pytest.raises(ValueError, match="device_offsets_m"):
        ArmChain((0.3,), (-0.1,))
    with pytest.raises(ValueError, match=r"device_offsets_m\[1\].*exceeds"):
        ArmChain((0.3, 0.25), (0.15, 0.3))
    with pytest.raises(ValueError, match="at least one"):
        ArmChain((), ())


@pytest.mark.parametrize(
    ("radio", "pitch", "kwargs", "match"),
    [
        (np.zeros((4, 2, 3)), np.zeros((4, 3)), {}, "do not fit"),
        (np.zeros((4, 3, 3)), np.zeros((4, 3)), {}, "chain has 2"),
        (np.zeros((4, 2, 2)), np.zeros((4, 2)), {}, r"radio_positions must have shape \(\.\.\., 3\)"),
        (np.zeros((2, 3)), np.zeros((1, 2)), {}, "radio_positions must have at least 3"),
        (np.full((4, 2, 3), np.nan), np.zeros((4, 2)), {}, "radio_positions contains NaN"),
        (np.zeros((4, 2, 3)), np.full((4, 2), 2.0), {}, r"pitch must lie in \[-pi/2, pi/2\]"),
        (np.zeros((4, 2, 3)), np.zeros((4, 2)), {"heading_tol_m": -1.0}, "heading_tol_m"),
        (np.zeros((4, 2, 3)), np.zeros((4, 2)), {"origin": (0.0, 0.0)}, "origin"),
        (np.zeros((4, 2, 3)), np.zeros((4, 2)), {"chain": (0.3, 0.25)}, "chain must be an ArmChain"),
    ],
)
def test_chain_rejects_bad_inputs(radio, pitch, kwargs, match):
    chain = kwargs.pop("chain", PAPER_ARM_CHAIN)
    with pytest.raises(ValueError, match=match):
        recursive_chain(radio, pitch, chain, **kwargs)
