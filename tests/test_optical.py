"""Tests of the Kinect skeletal-tracker model (wsnlib.sim.optical)."""

import math

import numpy as np
import pytest

from wsnlib.sim.optical import (
    PAPER_CAMERA_DISTANCE_M,
    KinectModel,
    hand_derived_reference,
    kinect_errors,
    kinect_frame_times,
    kinect_target_positions,
    n_kinect_frames,
    simulate_kinect,
)

UPPER_ARM = 0.326
FOREARM = 0.256

#: Kinect 3 m in front of the user (+y), looking back along −y.
CAMERA = np.array([0.0, PAPER_CAMERA_DISTANCE_M, 0.0])
AXIS = np.array([0.0, -1.0, 0.0])


def hanging_arm(n_frames: int, batch=()) -> np.ndarray:
    """Shoulder, elbow, wrist of an arm hanging down (segments across the camera axis)."""
    joints = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -UPPER_ARM], [0.0, 0.0, -UPPER_ARM - FOREARM]])
    return np.broadcast_to(joints, tuple(batch) + (n_frames, 3, 3)).copy()


def pointing_arm(n_frames: int) -> np.ndarray:
    """Arm straight forward, pointing at the camera (segments along the camera axis)."""
    joints = np.array([[0.0, 0.0, 0.0], [0.0, UPPER_ARM, 0.0], [0.0, UPPER_ARM + FOREARM, 0.0]])
    return np.broadcast_to(joints, (n_frames, 3, 3)).copy()


def only(**kwargs) -> KinectModel:
    """The noise-free model with some parameters switched back on."""
    base = {f: getattr(KinectModel.noise_free(), f) for f in KinectModel.__dataclass_fields__}
    base.update(kwargs)
    return KinectModel(**base)


def simulate(truth, model, seed=7, **kwargs):
    kwargs.setdefault("relative_to", "true_shoulder")
    return simulate_kinect(
        truth, rng=np.random.default_rng(seed), camera_position=CAMERA, camera_axis=AXIS, model=model, **kwargs
    )


# ---------------------------------------------------------------------------------------------
# Model parameters
# ---------------------------------------------------------------------------------------------


def test_default_noise_at_three_metres():
    model = KinectModel()
    assert model.depth_noise_std_m(3.0) == pytest.approx(0.0012 + 0.0019 * 2.6**2)  # 14.0 mm
    assert model.lateral_noise_std_m(3.0) == pytest.approx(0.8 * 3.0 / 585.0)  # 4.1 mm
    assert model.jitter_lag1_correlation == pytest.approx(math.exp(-1.0 / 3.0))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"frame_rate_hz": 0.0},
        {"focal_length_px": -1.0},
        {"bias_std_m": -0.01},
        {"glitch_rate_hz": float("nan")},
        {"glitch_mean_duration_s": 0.0},
        {"glitch_min_m": 0.2, "glitch_max_m": 0.1},
        {"depth_noise_offset_m": float("inf")},
    ],
)
def test_model_rejects_bad_parameters(kwargs):
    with pytest.raises(ValueError):
        KinectModel(**kwargs)


# ---------------------------------------------------------------------------------------------
# Determinism, shapes, noise-free behaviour
# ---------------------------------------------------------------------------------------------


def test_same_seed_same_output_and_batches_differ():
    truth = hanging_arm(90, batch=(4,))
    a = simulate(truth, KinectModel(), seed=3, relative_to="tracked_shoulder")
    b = simulate(truth, KinectModel(), seed=3, relative_to="tracked_shoulder")
    c = simulate(truth, KinectModel(), seed=4, relative_to="tracked_shoulder")
    assert a.shape == truth.shape
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert not np.allclose(a[0], a[1])


def test_switching_one_component_off_keeps_the_others():
    truth = hanging_arm(120)
    full = kinect_errors(truth, rng=np.random.default_rng(5), camera_position=CAMERA, camera_axis=AXIS)
    no_bias = kinect_errors(
        truth, rng=np.random.default_rng(5), camera_position=CAMERA, camera_axis=AXIS, model=KinectModel(bias_std_m=0)
    )
    np.testing.assert_array_equal(full.jitter, no_bias.jitter)
    np.testing.assert_array_equal(full.glitch, no_bias.glitch)
    assert np.all(no_bias.bias == 0.0)


@pytest.mark.parametrize("relative_to", ["tracked_shoulder", "session_shoulder", "true_shoulder"])
def test_noise_free_model_reports_the_truth(relative_to):
    truth = hanging_arm(60) + np.linspace(0.0, 0.1, 60)[:, None, None]
    out = simulate(truth, KinectModel.noise_free(), relative_to=relative_to)
    np.testing.assert_allclose(out, truth, atol=1e-15)


def test_resampling_to_thirty_frames_per_second():
    fs = 100.0
    n = 101  # 1 s
    t = np.arange(n) / fs
    truth = hanging_arm(n)
    truth[..., 0] += 0.2 * t[:, None]  # linear drift: interpolation is exact
    out = simulate(truth, KinectModel.noise_free(), fs=fs)
    times = kinect_frame_times(n, fs)
    assert n_kinect_frames(n, fs) == 31 == out.shape[0]
    np.testing.assert_allclose(times, np.arange(31) / 30.0)
    np.testing.assert_allclose(out[:, :, 0], np.broadcast_to(0.2 * times[:, None], (31, 3)), atol=1e-12)
    assert n_kinect_frames(45, 30.0) == 45


# ---------------------------------------------------------------------------------------------
# Jitter: anisotropy and temporal correlation
# ---------------------------------------------------------------------------------------------


def test_depth_error_exceeds_lateral_by_the_model_ratio():
    model = only(depth_noise_const_m=0.0012, depth_noise_quad_m_per_m2=0.0019, lateral_noise_px=0.8,
                 jitter_correlation_s=0.1)
    truth = hanging_arm(3000, batch=(8,))
    error = simulate(truth, model) - truth
    wrist_depth = PAPER_CAMERA_DISTANCE_M
    depth_std = np.std(error[..., 2, 1])  # camera axis is y
    lateral_std = np.sqrt(0.5 * (np.var(error[..., 2, 0]) + np.var(error[..., 2, 2])))
    assert depth_std == pytest.approx(model.depth_noise_std_m(wrist_depth), rel=0.05)
    assert lateral_std == pytest.approx(model.lateral_noise_std_m(wrist_depth), rel=0.05)
    expected_ratio = model.depth_noise_std_m(wrist_depth) / model.lateral_noise_std_m(wrist_depth)
    assert expected_ratio == pytest.approx(3.42, abs=0.01)
    assert depth_std / lateral_std == pytest.approx(expected_ratio, rel=0.07)


@pytest.mark.parametrize("correlation_s", [0.0, 0.1, 0.3])
def test_jitter_lag1_autocorrelation_matches_the_model(correlation_s):
    model = only(depth_noise_const_m=0.01, jitter_correlation_s=correlation_s)
    truth = hanging_arm(4000, batch=(6,))
    error = (simulate(truth, model) - truth)[..., 1]  # depth component, (6, T, 3)
    lag1 = np.sum(error[:, 1:] * error[:, :-1]) / np.sum(error**2)
    assert lag1 == pytest.approx(model.jitter_lag1_correlation, abs=0.02)


# ---------------------------------------------------------------------------------------------
# Glitches: rate, magnitude, duration, occlusion rule
# ---------------------------------------------------------------------------------------------


def _bursts(error):
    """Starts of constant nonzero error runs, per joint: a new burst changes the error vector."""
    magnitude = np.linalg.norm(error, axis=-1)
    on = magnitude > 0
    changed = np.any(error[1:] != error[:-1], axis=-1)
    start = on.copy()
    start[1:] &= changed
    return start, on, magnitude


def test_glitch_rate_magnitude_and_duration_in_clear_view():
    model = only(glitch_rate_hz=0.5, glitch_rate_occluded_hz=0.5, glitch_mean_duration_s=0.3)
    n = 30 * 2000
    truth = hanging_arm(n)
    errors = kinect_errors(truth, rng=np.random.default_rng(11), camera_position=CAMERA, camera_axis=AXIS,
                           model=model)
    start, on, magnitude = _bursts(errors.glitch)
    np.testing.assert_array_equal(start, errors.glitch_start)
    np.testing.assert_array_equal(on, errors.glitch_active)
    # hazard per second of burst-free time
    free_time_s = np.sum(~on) / model.frame_rate_hz
    n_starts = np.sum(start)
    assert n_starts / free_time_s == pytest.approx(model.glitch_rate_hz, rel=0.1)  # ~850 bursts: 3.4 % s.d.
    assert np.all((magnitude[on] >= 0.10 - 1e-12) & (magnitude[on] <= 0.15 + 1e-12))
    assert magnitude[on].min() < 0.102 and magnitude[on].max() > 0.148
    assert np.sum(on) / n_starts / model.frame_rate_hz == pytest.approx(0.3, rel=0.1)


def test_glitches_are_likelier_when_the_arm_points_at_the_camera():
    model = only(glitch_rate_hz=0.02, glitch_rate_occluded_hz=0.5)
    n = 30 * 600
    clear = kinect_errors(hanging_arm(n), rng=np.random.default_rng(1), camera_position=CAMERA, camera_axis=AXIS,
                          model=model)
    aligned = kinect_errors(pointing_arm(n), rng=np.random.default_rng(1), camera_position=CAMERA,
                            camera_axis=AXIS, model=model)
    np.testing.assert_allclose(clear.occlusion_score, 0.0, atol=1e-12)
    np.testing.assert_allclose(aligned.occlusion_score, 1.0)
    free_clear = np.sum(~clear.glitch_active) / 30.0
    free_aligned = np.sum(~aligned.glitch_active) / 30.0
    rate_clear = np.sum(clear.glitch_start) / free_clear
    rate_aligned = np.sum(aligned.glitch_start) / free_aligned
    assert rate_aligned == pytest.approx(0.5, rel=0.1)
    assert rate_clear < 0.05
    assert rate_aligned > 10 * rate_clear


def test_occluded_mask_and_partial_alignment_set_the_score():
    n = 10
    truth = hanging_arm(n)
    # forearm 60° off the camera axis: cos² = 0.25 for elbow and wrist
    truth[:, 2] = truth[:, 1] + FOREARM * np.array([0.0, math.cos(math.radians(60)), -math.sin(math.radians(60))])
    occluded = np.zeros((n, 3), dtype=bool)
    occluded[5:, 0] = True
    errors = kinect_errors(truth, rng=np.random.default_rng(0), camera_position=CAMERA, camera_axis=AXIS,
                           occluded=occluded)
    np.testing.assert_allclose(errors.occlusion_score[:, 1:], 0.25, atol=1e-12)
    np.testing.assert_allclose(errors.occlusion_score[:5, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(errors.occlusion_score[5:, 0], 1.0)


# ---------------------------------------------------------------------------------------------
# Shoulder referencing and bias
# ---------------------------------------------------------------------------------------------


def test_tracked_shoulder_reference_makes_shoulder_exact_and_adds_its_error():
    truth = hanging_arm(200)
    rng_kwargs = {"rng": np.random.default_rng(9), "camera_position": CAMERA, "camera_axis": AXIS}
    errors = kinect_errors(truth, **rng_kwargs)
    out = simulate_kinect(truth, **{**rng_kwargs, "rng": np.random.default_rng(9)})
    np.testing.assert_allclose(out[:, 0], truth[:, 0], atol=1e-15)
    expected = truth + errors.total - errors.total[:, :1]
    np.testing.assert_allclose(out, expected, atol=1e-15)
    session = simulate_kinect(truth, **{**rng_kwargs, "rng": np.random.default_rng(9)}, relative_to="session_shoulder")
    np.testing.assert_allclose(np.mean(session[:, 0] - truth[:, 0], axis=0), 0.0, atol=1e-15)


def test_bias_is_constant_per_session_with_the_model_spread():
    model = only(bias_std_m=0.02)
    truth = hanging_arm(5, batch=(4000,))
    error = simulate(truth, model) - truth
    np.testing.assert_allclose(error, np.broadcast_to(error[:, :1], error.shape))
    assert np.std(error[:, 0]) == pytest.approx(0.02, rel=0.03)


# ---------------------------------------------------------------------------------------------
# Targets
# ---------------------------------------------------------------------------------------------


def test_target_interpolation_is_exact_on_noise_free_input():
    truth = hanging_arm(30)
    tracked = simulate(truth, KinectModel.noise_free(), relative_to="tracked_shoulder")
    targets = kinect_target_positions(tracked)
    expected = np.array([[0.0, 0.0, -UPPER_ARM / 2], [0.0, 0.0, -UPPER_ARM - FOREARM / 2]])
    np.testing.assert_allclose(targets, np.broadcast_to(expected, (30, 2, 3)), atol=1e-15)
    custom = kinect_target_positions(truth, segments=[(0, 1), (1, 2), (0, 2)], fractions=[0.6, 0.8, 1.0])
    np.testing.assert_allclose(custom[0, 0], [0.0, 0.0, -0.6 * UPPER_ARM])
    np.testing.assert_allclose(custom[0, 1], [0.0, 0.0, -UPPER_ARM - 0.8 * FOREARM])
    np.testing.assert_allclose(custom[0, 2], truth[0, 2])


# ---------------------------------------------------------------------------------------------
# Bad inputs
# ---------------------------------------------------------------------------------------------


def _call(**overrides):
    kwargs = {
        "rng": np.random.default_rng(0),
        "camera_position": CAMERA,
        "camera_axis": AXIS,
    }
    truth = overrides.pop("truth", hanging_arm(10))
    kwargs.update(overrides)
    return simulate_kinect(truth, **kwargs)


@pytest.mark.parametrize(
    "overrides, match",
    [
        ({"truth": np.full((10, 3, 3), np.nan)}, "NaN"),
        ({"truth": np.zeros((10, 3, 2))}, r"\(\.\.\., 3\)"),
        ({"truth": np.zeros((10, 3))}, "dimension"),
        ({"truth": np.zeros((0, 3, 3))}, "at least one sample"),
        ({"fs": 0.0}, "fs"),
        ({"fs": -30.0}, "fs"),
        ({"rng": 1}, "Generator"),
        ({"camera_axis": [0.0, 0.0, 0.0]}, "zero-norm"),
        ({"camera_axis": [0.0, 1.0, 0.0]}, "in front of the camera"),
        ({"camera_position": [0.0, 3.0]}, "camera_position"),
        ({"camera_position": np.zeros((2, 3))}, "batch shape"),
        ({"occluded": np.zeros((10, 3))}, "boolean"),
        ({"occluded": np.zeros((4, 3), dtype=bool)}, "does not fit"),
        ({"relative_to": "camera"}, "relative_to"),
        ({"model": {"bias_std_m": 0.0}}, "KinectModel"),
    ],
)
def test_bad_inputs_raise_value_error(overrides, match):
    with pytest.raises(ValueError, match=match):
        _call(**overrides)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"segments": [(0, 3)]}, "segment"),
        ({"segments": [(1, 1)]}, "segment"),
        ({"fractions": [0.5]}, "fraction"),
        ({"fractions": [0.5, float("nan")]}, "NaN"),
        ({"segments": "ab"}, "segments"),
    ],
)
def test_target_positions_reject_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        kinect_target_positions(hanging_arm(3), **kwargs)


def test_frame_count_rejects_bad_input():
    with pytest.raises(ValueError, match="n_samples"):
        n_kinect_frames(0, 30.0)
    with pytest.raises(ValueError, match="fs"):
        kinect_frame_times(10, 0.0)


# --- paper 002's hand-derived reference --------------------------------------------------------


def _arc_rows(n_movements=40, n_rows=60):
    """Both targets on a straight arm sweeping 90° in each movement, 30 rows per second."""
    angle = np.linspace(0.0, np.pi / 2, n_rows)
    direction = np.stack([np.zeros_like(angle), np.sin(angle), -np.cos(angle)], axis=-1)
    one = np.stack([0.15 * direction, 0.45 * direction], axis=1)                  # (n_rows, 2, 3)
    truth = np.concatenate([one] * n_movements)
    movement = np.repeat(np.arange(1, n_movements + 1), n_rows)
    time_s = np.tile(np.arange(n_rows) / 30.0, n_movements) + np.repeat(np.arange(n_movements) * 10.0, n_rows)
    return truth, movement, time_s


def test_hand_derived_reference_zero_error_and_determinism():
    truth, movement, time_s = _arc_rows(3)
    rng = np.random.default_rng(1)
    exact = hand_derived_reference(truth, movement, time_s, rng=rng, rotation_std_deg=0.0, timing_std_s=0.0)
    np.testing.assert_array_equal(exact, truth)
    a = hand_derived_reference(truth, movement, time_s, rng=np.random.default_rng(2))
    b = hand_derived_reference(truth, movement, time_s, rng=np.random.default_rng(2))
    np.testing.assert_array_equal(a, b)
    assert a.shape == truth.shape and not np.allclose(a, truth)
    # (n, 3) input works too and gives the same rows as the first target of (n, J, 3).
    single = hand_derived_reference(truth[:, 0], movement, time_s, rng=np.random.default_rng(2))
    np.testing.assert_allclose(single, a[:, 0], atol=1e-15)


def test_hand_derived_reference_error_sizes():
    truth, movement, time_s = _arc_rows(400)
    # Posture only: a rotation ~ N(0, σ² I) moves a point at radius r by |ω × p|, RMS √2·σ·r,
    # and keeps its distance from the shoulder.
    rotated = hand_derived_reference(truth, movement, time_s, rng=np.random.default_rng(3),
                                     rotation_std_deg=3.0, timing_std_s=0.0)
    error = np.linalg.norm(rotated - truth, axis=-1)
    rms = np.sqrt(np.mean(error**2, axis=0))
    np.testing.assert_allclose(rms, math.sqrt(2) * math.radians(3.0) * np.array([0.15, 0.45]), rtol=0.1)
    np.testing.assert_allclose(np.linalg.norm(rotated, axis=-1), np.linalg.norm(truth, axis=-1))
    # Timing only: the reference runs along the arc (same radius), ahead or behind.
    shifted = hand_derived_reference(truth, movement, time_s, rng=np.random.default_rng(3),
                                     rotation_std_deg=0.0, timing_std_s=0.1)
    np.testing.assert_allclose(np.linalg.norm(shifted, axis=-1), np.linalg.norm(truth, axis=-1), rtol=2e-3)
    speed = 0.45 * (np.pi / 2) / (59 / 30.0)                                        # m/s of the forearm target
    along = np.sqrt(np.mean(np.linalg.norm(shifted - truth, axis=-1)[:, 1] ** 2))
    assert 0.3 * 0.1 * speed < along < 1.1 * 0.1 * speed                             # ends are held: a bit less
    # Default: "a few centimetres" at the forearm target.
    both = hand_derived_reference(truth, movement, time_s, rng=np.random.default_rng(3))
    assert 0.02 < np.sqrt(np.mean(np.linalg.norm(both - truth, axis=-1)[:, 1] ** 2)) < 0.06


@pytest.mark.parametrize("kwargs, match", [
    ({"movement": np.ones(5)}, "movement"),
    ({"time_s": np.zeros(4)}, "time_s"),
    ({"rotation_std_deg": -1.0}, "rotation_std_deg"),
    ({"rng": 0}, "rng"),
    ({"true_positions": np.zeros((5, 2))}, "true_positions"),
    ({"time_s": np.array([0.0, 1.0, 0.5, 2.0, 3.0])}, "non-decreasing"),
])
def test_hand_derived_reference_rejects_bad_input(kwargs, match):
    args = {"true_positions": np.ones((5, 3)), "movement": np.ones(5, dtype=int), "time_s": np.arange(5.0),
            "rng": np.random.default_rng(0), **kwargs}
    with pytest.raises(ValueError, match=match):
        hand_derived_reference(args.pop("true_positions"), args.pop("movement"), args.pop("time_s"), **args)
