"""A first-generation Kinect skeletal tracker as a measuring instrument: true joint
trajectories in, what the tracker reports out (:func:`simulate_kinect`), and target positions
derived from the reported joints (:func:`kinect_target_positions`).

The error model (bias, correlated anisotropic jitter, glitches, occlusion rule, shoulder
frame, time base, order of the random draws) and its sources are documented in
:mod:`wsnlib.sim.optical`; its parameters are :class:`wsnlib.sim.kinect_model.KinectModel`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from wsnlib._validation import as_float_array, check_nonzero_norm, check_positive
from wsnlib.sim.kinect_model import RELATIVE_TO, KinectErrors, KinectModel


def _check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def n_kinect_frames(n_samples: int, fs, frame_rate_hz: float = 30.0) -> int:
    """Number of Kinect frames ``t_k = k / frame_rate_hz`` inside ``[0, (n_samples − 1) / fs]``."""
    if isinstance(n_samples, bool) or not isinstance(n_samples, int | np.integer) or n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer, got {n_samples!r}")
    fs = check_positive(fs, "fs")
    frame_rate = check_positive(frame_rate_hz, "frame_rate_hz")
    if math.isclose(fs, frame_rate, rel_tol=1e-12):
        return int(n_samples)
    return int(math.floor((n_samples - 1) * frame_rate / fs + 1e-9)) + 1


def kinect_frame_times(n_samples: int, fs, frame_rate_hz: float = 30.0) -> np.ndarray:
    """Times (s) of the Kinect frames that cover an input of ``n_samples`` samples at ``fs`` Hz."""
    return np.arange(n_kinect_frames(n_samples, fs, frame_rate_hz)) / float(frame_rate_hz)


def _resample_positions(positions: np.ndarray, fs: float, frame_rate: float, n_frames: int) -> np.ndarray:
    """Linear interpolation along axis −3 from rate ``fs`` to the Kinect frame grid."""
    if n_frames == positions.shape[-3] and math.isclose(fs, frame_rate, rel_tol=1e-12):
        return positions.copy()
    n_samples = positions.shape[-3]
    u = np.arange(n_frames) * (fs / frame_rate)
    lower = np.clip(np.floor(u + 1e-9).astype(int), 0, n_samples - 1)
    upper = np.minimum(lower + 1, n_samples - 1)
    frac = np.clip(u - lower, 0.0, 1.0)[:, None, None]
    return positions[..., lower, :, :] * (1.0 - frac) + positions[..., upper, :, :] * frac


def _resample_mask(mask: np.ndarray, fs: float, frame_rate: float, n_frames: int) -> np.ndarray:
    """Nearest input sample along axis −2 (ties to the later sample)."""
    if n_frames == mask.shape[-2] and math.isclose(fs, frame_rate, rel_tol=1e-12):
        return mask.copy()
    index = np.floor(np.arange(n_frames) * (fs / frame_rate) + 0.5 + 1e-9).astype(int)
    return mask[..., np.minimum(index, mask.shape[-2] - 1), :]


def _camera_vector(value, name: str, batch_shape: tuple[int, ...]) -> np.ndarray:
    arr = as_float_array(value, name, last_dim=3)
    try:
        fits = np.broadcast_shapes(arr.shape[:-1], batch_shape) == batch_shape
    except ValueError:
        fits = False
    if not fits:
        raise ValueError(
            f"{name} has shape {arr.shape}; it must be (3,) or broadcast to the batch shape {batch_shape} + (3,)"
        )
    return arr


def _lateral_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to the unit vectors ``axis`` (..., 3) and to each other."""
    reference = np.broadcast_to(np.array([0.0, 0.0, 1.0]), axis.shape).copy()
    near_z = np.abs(axis[..., 2]) > 0.9
    reference[near_z] = np.array([1.0, 0.0, 0.0])
    first = np.cross(axis, reference)
    first /= np.linalg.norm(first, axis=-1, keepdims=True)
    second = np.cross(axis, first)
    return first, second


def _parents(parents, n_joints: int) -> tuple[int, ...]:
    if parents is None:
        return tuple(range(-1, n_joints - 1))
    try:
        values = tuple(int(p) for p in parents)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"parents must be a sequence of {n_joints} integers, got {parents!r}") from exc
    if len(values) != n_joints:
        raise ValueError(f"parents has {len(values)} entries for {n_joints} joints")
    for joint, parent in enumerate(values):
        if parent < -1 or parent >= n_joints or parent == joint:
            raise ValueError(f"parents[{joint}] = {parent} is not −1 (root) or another joint's index")
    return values


def _occlusion_score(truth: np.ndarray, axis: np.ndarray, parents: tuple[int, ...], occluded) -> np.ndarray:
    """Score in [0, 1]: cos² of the most end-on incident segment, or 1 where ``occluded``."""
    score = np.zeros(truth.shape[:-1])
    camera_axis = axis[..., None, :]  # broadcast over frames
    for joint, parent in enumerate(parents):
        if parent < 0:
            continue
        segment = truth[..., joint, :] - truth[..., parent, :]
        length = np.linalg.norm(segment, axis=-1)
        cosine = np.divide(
            np.sum(segment * camera_axis, axis=-1), length, out=np.zeros_like(length), where=length > 0
        )
        aligned = cosine**2
        score[..., joint] = np.maximum(score[..., joint], aligned)
        score[..., parent] = np.maximum(score[..., parent], aligned)
    if occluded is not None:
        score = np.where(occluded, 1.0, score)
    return score


def _ar1_unit(rng: np.random.Generator, shape: tuple[int, ...], phi: float) -> np.ndarray:
    """Stationary unit-variance AR(1) noise along axis −3 (frames)."""
    white = rng.standard_normal(shape)
    if phi == 0.0 or shape[-3] == 1:
        return white
    gain = math.sqrt(1.0 - phi**2)
    initial = (1.0 - gain) * white[..., :1, :, :]  # makes the first output equal white[0] ~ N(0, 1)
    out, _ = signal.lfilter([gain], [1.0, -phi], white, axis=-3, zi=initial)
    return out


def _glitches(rng, score, model: KinectModel):
    """Burst errors (..., K, J, 3), active mask and start mask (..., K, J)."""
    shape = score.shape
    n_frames = shape[-2]
    dt = 1.0 / model.frame_rate_hz
    uniform = rng.random(shape)
    mean_frames = max(1.0, model.glitch_mean_duration_s * model.frame_rate_hz)
    durations = rng.geometric(1.0 / mean_frames, size=shape)
    magnitudes = rng.uniform(model.glitch_min_m, model.glitch_max_m, size=shape)
    directions = rng.standard_normal(shape + (3,))
    norms = np.linalg.norm(directions, axis=-1, keepdims=True)
    directions = directions / np.where(norms > 0, norms, 1.0)

    rate = model.glitch_rate_hz + (model.glitch_rate_occluded_hz - model.glitch_rate_hz) * score
    start_probability = -np.expm1(-rate * dt)
    candidate = uniform < start_probability
    offsets = magnitudes[..., None] * directions

    glitch = np.zeros(shape + (3,))
    active = np.zeros(shape, dtype=bool)
    started = np.zeros(shape, dtype=bool)
    if not np.any(candidate):
        return glitch, active, started
    per_frame = shape[:-2] + shape[-1:]
    remaining = np.zeros(per_frame, dtype=np.int64)
    offset = np.zeros(per_frame + (3,))
    for k in range(n_frames):
        start = (remaining == 0) & candidate[..., k, :]
        remaining = np.where(start, durations[..., k, :], remaining)
        offset = np.where(start[..., None], offsets[..., k, :, :], offset)
        on = remaining > 0
        active[..., k, :] = on
        started[..., k, :] = start
        glitch[..., k, :, :] = np.where(on[..., None], offset, 0.0)
        remaining = np.maximum(remaining - 1, 0)
    return glitch, active, started


def kinect_errors(
    true_positions,
    *,
    rng: np.random.Generator,
    fs: float = 30.0,
    camera_position,
    camera_axis,
    model: KinectModel | None = None,
    occluded=None,
    parents=None,
) -> KinectErrors:
    """Draw the error components of a Kinect session (see the docstring of :mod:`wsnlib.sim.optical`).

    Parameters
    ----------
    true_positions : array_like, shape (..., T, J, 3)
        True joint positions (m), in any right-handed frame (the paper's shoulder frame), sampled
        at ``fs``.  Leading dimensions are batches (sessions, Monte Carlo runs).
    rng : numpy.random.Generator
    fs : float
        Sampling rate of ``true_positions`` (Hz).  Resampled to ``model.frame_rate_hz``.
    camera_position : array_like, shape (3,) or (..., 3)
        Kinect position in the same frame (m), e.g. 3 m in front of the user.
    camera_axis : array_like, shape (3,) or (..., 3)
        Direction the Kinect looks (its optical/depth axis, from the camera towards the user);
        normalised here.  Every joint must lie in front of the camera (positive depth).
    model : KinectModel, optional
        Error parameters; default :class:`KinectModel()`.
    occluded : array_like of bool, shape (..., T, J), optional
        Input samples in which the caller knows a joint is hidden (score 1).
    parents : sequence of int, optional
        Parent joint of each joint (−1 for the root), for the segment-alignment rule.  Default:
        a chain ``(−1, 0, 1, …)``, i.e. shoulder → elbow → wrist.

    Returns
    -------
    KinectErrors
    """
    model = KinectModel() if model is None else model
    if not isinstance(model, KinectModel):
        raise ValueError(f"model must be a KinectModel, got {type(model).__name__}")
    rng = _check_rng(rng)
    fs = check_positive(fs, "fs")
    positions = as_float_array(true_positions, "true_positions", last_dim=3, min_ndim=3)
    n_samples, n_joints = positions.shape[-3], positions.shape[-2]
    if n_samples < 1 or n_joints < 1:
        raise ValueError(f"true_positions needs at least one sample and one joint, got shape {positions.shape}")
    batch_shape = positions.shape[:-3]
    position = _camera_vector(camera_position, "camera_position", batch_shape)
    axis = _camera_vector(camera_axis, "camera_axis", batch_shape)
    axis = axis / check_nonzero_norm(axis, "camera_axis", "the camera's viewing direction")[..., None]
    chain = _parents(parents, n_joints)
    mask = None
    if occluded is not None:
        arr = np.asarray(occluded)
        if arr.dtype != np.bool_:
            raise ValueError(f"occluded must be a boolean mask, got dtype {arr.dtype}")
        try:
            mask = np.broadcast_to(arr, positions.shape[:-1])
        except ValueError as exc:
            raise ValueError(f"occluded has shape {arr.shape}, which does not fit {positions.shape[:-1]}") from exc

    frame_rate = model.frame_rate_hz
    n_frames = n_kinect_frames(n_samples, fs, frame_rate)
    truth = _resample_positions(positions, fs, frame_rate, n_frames)
    if mask is not None:
        mask = _resample_mask(mask, fs, frame_rate, n_frames)

    axis_b = axis[..., None, None, :]  # broadcast over frames and joints
    depth = np.sum((truth - position[..., None, None, :]) * axis_b, axis=-1)
    if np.any(depth <= 0.0):
        bad = np.argwhere(depth <= 0.0)[0]
        raise ValueError(
            f"a joint is not in front of the camera (depth {depth[tuple(bad)]:.3f} m at index "
            f"{tuple(int(i) for i in bad)}); check camera_position and camera_axis"
        )
    shape = truth.shape

    bias = model.bias_std_m * rng.standard_normal(shape[:-3] + (1,) + shape[-2:])

    unit = _ar1_unit(rng, shape, model.jitter_lag1_correlation)
    lateral_1, lateral_2 = _lateral_basis(axis)
    sigma_depth = model.depth_noise_std_m(depth)[..., None]
    sigma_lateral = model.lateral_noise_std_m(depth)[..., None]
    jitter = (
        unit[..., 0:1] * sigma_depth * axis_b
        + unit[..., 1:2] * sigma_lateral * lateral_1[..., None, None, :]
        + unit[..., 2:3] * sigma_lateral * lateral_2[..., None, None, :]
    )

    score = _occlusion_score(truth, axis, chain, mask)
    glitch, active, started = _glitches(rng, score, model)

    return KinectErrors(
        times=np.arange(n_frames) / frame_rate,
        truth=truth,
        bias=bias,
        jitter=jitter,
        glitch=glitch,
        glitch_active=active,
        glitch_start=started,
        occlusion_score=score,
    )


def simulate_kinect(
    true_positions,
    *,
    rng: np.random.Generator,
    fs: float = 30.0,
    camera_position,
    camera_axis,
    model: KinectModel | None = None,
    occluded=None,
    parents=None,
    relative_to: str = "tracked_shoulder",
    shoulder_index: int = 0,
) -> np.ndarray:
    """Joint positions as a first-generation Kinect skeletal tracker reports them.

    Parameters
    ----------
    true_positions, rng, fs, camera_position, camera_axis, model, occluded, parents
        As in :func:`kinect_errors`.
    relative_to : {"tracked_shoulder", "session_shoulder", "true_shoulder"}
        Which shoulder estimate is the origin of the reported coordinates (see :mod:`wsnlib.sim.optical`).
    shoulder_index : int
        Index of the shoulder on the joint axis (0 for :data:`wsnlib.sim.arm.JOINT_NAMES`).

    Returns
    -------
    ndarray, shape (..., K, J, 3)
        Reported joint positions (m) in the frame of ``true_positions``, at the Kinect frame
        times :func:`kinect_frame_times` (``K = T`` when ``fs`` equals the frame rate).
    """
    if relative_to not in RELATIVE_TO:
        raise ValueError(f"relative_to must be one of {RELATIVE_TO}, got {relative_to!r}")
    positions = as_float_array(true_positions, "true_positions", last_dim=3, min_ndim=3)
    n_joints = positions.shape[-2]
    if isinstance(shoulder_index, bool) or not isinstance(shoulder_index, int | np.integer):
        raise ValueError(f"shoulder_index must be an integer, got {shoulder_index!r}")
    if not -n_joints <= shoulder_index < n_joints:
        raise ValueError(f"shoulder_index = {shoulder_index} is out of range for {n_joints} joints")
    errors = kinect_errors(
        positions,
        rng=rng,
        fs=fs,
        camera_position=camera_position,
        camera_axis=camera_axis,
        model=model,
        occluded=occluded,
        parents=parents,
    )
    error = errors.total
    shoulder_index = int(shoulder_index) % n_joints
    shoulder = error[..., shoulder_index : shoulder_index + 1, :]
    if relative_to == "tracked_shoulder":
        error = error - shoulder
    elif relative_to == "session_shoulder":
        error = error - np.mean(shoulder, axis=-3, keepdims=True)
    return errors.truth + error


def kinect_target_positions(joint_positions, *, segments=((0, 1), (1, 2)), fractions=(0.5, 0.5)) -> np.ndarray:
    """Points on body segments, interpolated between (tracked) joints.

    Paper 002 saved the Kinect arm joints and derived the target nodes from them; a target on a
    segment is ``p_start + fraction · (p_end − p_start)``.

    Parameters
    ----------
    joint_positions : array_like, shape (..., T, J, 3)
        Joint positions (m), e.g. the output of :func:`simulate_kinect`.
    segments : sequence of (int, int)
        ``(start joint, end joint)`` of each target's segment.  Default: upper arm (shoulder →
        elbow) and forearm (elbow → wrist) of :data:`wsnlib.sim.arm.JOINT_NAMES`.
    fractions : sequence of float
        Position of each target along its segment, 0 at the start joint, 1 at the end joint.
        Default 0.5 (mid upper arm, mid forearm).

    Returns
    -------
    ndarray, shape (..., T, n_targets, 3)
    """
    positions = as_float_array(joint_positions, "joint_positions", last_dim=3, min_ndim=3)
    n_joints = positions.shape[-2]
    try:
        pairs = [(int(a), int(b)) for a, b in segments]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"segments must be a sequence of (start, end) joint indices, got {segments!r}") from exc
    weights = as_float_array(fractions, "fractions")
    if weights.ndim != 1 or weights.shape[0] != len(pairs) or len(pairs) == 0:
        raise ValueError(f"need one fraction per segment: {len(pairs)} segments, fractions shape {weights.shape}")
    for start, end in pairs:
        if not (0 <= start < n_joints and 0 <= end < n_joints) or start == end:
            raise ValueError(f"segment ({start}, {end}) does not join two of the {n_joints} joints")
    starts = positions[..., [a for a, _ in pairs], :]
    ends = positions[..., [b for _, b in pairs], :]
    return starts + weights[:, None] * (ends - starts)
