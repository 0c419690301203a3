"""The optical references of paper 002 (Tables 2–3): a first-generation Kinect skeletal tracker
as a measuring instrument, and the paper's own hand-derived reference positions.

Paper 002 (Section 4.1) ran the Kinect SDK's *Skeletal Viewer* with the Kinect about 3 m in
front of the user, saved the arm joints of every frame (~30 fps) and derived the two target
positions from them; its Table 3 reports the resulting position error (PE) of "Kinect".  This
module turns true joint trajectories into what such a tracker reports, so that the comparison
can be simulated (:func:`simulate_kinect`, with the error components of :func:`kinect_errors`
and the parameters of :class:`KinectModel`; target positions derived from the reported joints
by :func:`kinect_target_positions`).  Every number below is a published Kinect figure or a
stated assumption; none was fitted to paper 002's tables.

Error model
-----------
For joint ``j`` at output frame ``k`` the tracker reports ``p + b + e + g`` (then referenced to
the shoulder, see below):

* **b — skeleton-model bias**: one draw per joint and session (per batch element),
  ``N(0, bias_std_m²)`` on each axis, constant over time.  It stands for the offset between the
  tracker's joint centre (a mode of per-pixel body-part votes pushed into the body, Shotton et
  al. 2011) and the anatomical joint centre.
* **e — jitter**: anisotropic and temporally correlated.  In the camera frame (depth axis =
  the optical axis ``camera_axis``; two lateral axes perpendicular to it) each component is a
  stationary unit-variance AR(1) process with lag-1 correlation
  ``φ = exp(−1 / (frame_rate_hz · jitter_correlation_s))``, scaled frame by frame by the
  depth-dependent standard deviations of Nguyen et al. (2012)::

      σ_depth(Z)   = depth_noise_const_m + depth_noise_quad_m_per_m2 · (Z − depth_noise_offset_m)²
      σ_lateral(Z) = lateral_noise_px · Z / focal_length_px

  where ``Z = (p − camera_position) · camera_axis`` is the joint's depth (m).  At Z = 3 m:
  σ_depth = 14.0 mm, σ_lateral = 4.1 mm, a ratio of 3.4.
* **g — glitches**: rare bursts of a large error (tracking loss, a joint snapping to another body
  part, self-occlusion).  Each joint has a hazard rate that grows with an *occlusion score*
  ``s ∈ [0, 1]``::

      rate = glitch_rate_hz + (glitch_rate_occluded_hz − glitch_rate_hz) · s

  A burst starts in a frame with probability ``1 − exp(−rate / frame_rate_hz)`` (only while no
  burst of that joint is under way), lasts a geometric number of frames with mean
  ``glitch_mean_duration_s · frame_rate_hz`` (at least one), and adds a constant offset of
  magnitude ``U[glitch_min_m, glitch_max_m]`` in a uniformly random direction.

Occlusion rule
~~~~~~~~~~~~~~
The score of a joint is the largest of

* ``cos²(angle between a body segment touching the joint and the camera axis)`` over the
  segments ending at the joint (joint–parent) and starting at it (joint–children): a segment
  seen end-on (arm pointing at or away from the camera) is foreshortened to a blob in the depth
  image and hides the joints behind it, so both of its end joints are at risk; a segment in the
  image plane scores 0;
* 1 in frames flagged by the caller's ``occluded`` mask (e.g. the arm crossing in front of or
  behind the torso, which needs a body model this module does not have).

Shoulder frame
~~~~~~~~~~~~~~
Paper 002 expresses positions relative to the shoulder, which the user keeps still; the Kinect
reports camera coordinates, so the Kinect joints must be referenced to a shoulder estimate.
Section 4.1 does not say which; ``relative_to`` chooses:

* ``"tracked_shoulder"`` (default): the tracked shoulder of the same frame is the origin.  The
  reported shoulder is exact and every other joint carries ``err_joint − err_shoulder``: the
  shoulder's jitter, bias and glitches *add* (for independent errors the variance doubles), and
  only error common to the whole skeleton would cancel (there is none in this model).
* ``"session_shoulder"``: the session mean of the tracked shoulder is the origin (the shoulder
  is still); its jitter averages out, its bias remains.
* ``"true_shoulder"``: errors are kept absolute, as if the camera were registered to the true
  shoulder; the shoulder itself then carries its own error.

Time base
~~~~~~~~~
The tracker delivers frames at ``frame_rate_hz``.  Input sampled at ``fs`` is linearly
interpolated to the frame times ``t_k = k / frame_rate_hz`` inside the input span
(:func:`kinect_frame_times`); with ``fs == frame_rate_hz`` frames are the input samples.
A caller-supplied ``occluded`` mask takes the nearest input sample.

Random draws
~~~~~~~~~~~~
Every draw comes from ``rng`` in a fixed order (bias, jitter, glitch timing, durations,
magnitudes, directions) and its amount depends only on the array shapes, never on parameter
values: with the same seed, switching one error component off leaves the others' realisation
unchanged (common random numbers for ablations).

Sources (verified = read for this module; otherwise as stated)
--------------------------------------------------------------
* Frame rate 30 fps — K. Khoshelham, S. Oude Elberink, "Accuracy and resolution of Kinect
  depth data for indoor mapping applications", *Sensors* 12(2):1437–1454, 2012, Section 1
  ("a frame rate of up to 30 fps"); paper 002, Section 4.1 ("around 30 fps").  Verified.
* Depth noise rising with distance — Khoshelham & Oude Elberink 2012, abstract: the random
  depth error "ranges from a few millimeters up to about 4 cm at the maximum range of the
  sensor".  Verified.  Their model has it grow with the square of the distance; with their
  5 m maximum range (from memory, not re-read) that gives 4 cm · (3/5)² ≈ 1.4 cm at 3 m, which
  agrees with the Nguyen formula used here.
* σ_depth(Z) = 1.2 mm + 1.9 mm/m² · (Z − 0.4 m)² and σ_lateral = 0.8 px · Z / f (the lateral
  term for surfaces facing the camera) — C. V. Nguyen, S. Izadi, D. Lovell, "Modeling Kinect
  sensor noise for improved 3D reconstruction and tracking", 3DIMPVT 2012, pp. 524–530.  The
  coefficients were verified as reproduced, with attribution to this paper, in several public
  implementations (e.g. ETH Zurich's elevation_mapping ``KinectSensorProcessor``); the paper's
  own text was not read.  These are *per-pixel* depth-map noise figures.
* focal_length_px = 585 — assumed: the Kinect v1 IR-camera focal length commonly paired with
  the Nguyen lateral formula in public code.
* Skeleton smoothing in Kinect SDK 1.x is a Holt double-exponential filter — Microsoft, "Joint
  Filtering", Kinect for Windows SDK 1.5–1.8 documentation.  Verified; used only as the reason
  for a correlated jitter.
* Error peaks "even higher than 10÷15 cm associated with similar arm movements" — paper 002,
  Section 5, citing its refs. [12] (Chang et al., PervasiveHealth 2012) and [27] (Š. Obdržálek
  et al., "Accuracy and robustness of Kinect pose estimation in the context of coaching of
  elderly population", IEEE EMBC 2012, pp. 1188–1193).  Verified in paper 002 only; the two
  studies' own figures could not be read here.  Poorer resolution along the Kinect z axis:
  paper 002, Section 2, citing [12].

Assumed, with the reasoning:

* Skeleton jitter has the per-pixel scale and anisotropy of Nguyen et al.  A tracked joint is a
  mode of many pixels' votes (J. Shotton et al., "Real-time human pose recognition in parts from
  single depth images", CVPR 2011), which averages pixel noise, while the per-frame part
  classification adds jitter of its own; no skeleton-level jitter figure was verified.
* ``jitter_correlation_s = 0.1`` s (3 frames, φ = 0.72 at 30 fps): the SDK's smoothing filter
  and the tracker's skeleton fitting make consecutive frames' errors alike over a few frames.
* ``bias_std_m = 0.02`` m per axis (3.5 cm RMS in 3-D): "a few centimetres" between Kinect
  joint centres and marker-based joint centres is the order of magnitude reported in Kinect
  vs. motion-capture comparisons (Obdržálek et al. 2012; Q. Wang et al., "Evaluation of pose
  tracking accuracy in the first and second generations of Microsoft Kinect", ICHI 2015), but
  their tables could not be read here; B. Bonnechère et al. (*Gait & Posture* 39:593–598, 2014,
  SDK 1.5) and R. A. Clark et al. (*Gait & Posture* 36(3), 2012) report joint angles and
  landmark excursions rather than joint-centre offsets.  Not verified.
* ``glitch_min_m, glitch_max_m = 0.10, 0.15``: the 10–15 cm peaks quoted by paper 002.
* ``glitch_rate_hz = 0.02`` (one burst per joint every 50 s in clear view),
  ``glitch_rate_occluded_hz = 0.5`` (one every 2 s while seen end-on or occluded),
  ``glitch_mean_duration_s = 0.3`` (9 frames): paper 002 calls the peaks occasional and tied to
  arm movements of 2–4 s; a movement that passes through an end-on posture for about a second
  then meets about one burst on some joint.  Not verified.

Hand-derived reference (:func:`hand_derived_reference`)
-------------------------------------------------------
Paper 002, Sec. 4.2: there was no optoelectronic system; "true target positions have been
manually derived": each movement starts and ends at two fingerprint positions of known
coordinates, the trajectory is taken to be the arc between them, and "the users are asked to
try to perform these movements at constant speed and, therefore, physical positions of
intermediate points along the trajectories can be computed by sampling at constant rate the
arcs' points".  "Some errors are certainly introduced …, these errors tend to be limited to a
few centimeters."  The Kinect was scored against the same reference ("following the same
experimental approach").  Our simulated users move on exactly those arcs at constant speed,
so the two error sources the paper's procedure leaves are modelled:

* posture: the user's arm is off the drawn arc — a small rotation of the whole arm about the
  shoulder, one per (session, movement), rotation vector ~ N(0, σ_rot² I) (an error growing
  with the distance from the shoulder, shared by both targets);
* timing: the manual segmentation of the movement and the constant-speed assumption put the
  reference ahead of or behind the arm — one time offset per (session, movement),
  ~ N(0, σ_t²), the reference reading the trajectory at ``t + δ`` (held at the movement's ends).

σ_rot = 3° and σ_t = 0.1 s are *assumed* ("a few centimeters": at the forearm target, about
0.45 m from the shoulder, 3° is 2.4 cm per perpendicular axis; 0.1 s at the 0.2–0.4 m/s of a
2–4 s movement is 2–4 cm along the arc).  The paper gives no number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from wsnlib import fixed_order
from wsnlib._validation import (
    as_bool_mask,
    as_float_array,
    check_choice,
    check_count,
    check_fields,
    check_nonnegative,
    check_nonzero_norm,
    check_positive,
    check_rng,
    check_type,
)
from wsnlib.sim.body import perpendicular_unit
from wsnlib.sim.radio import ar1_filter

#: Distance between the Kinect and the user in paper 002, Section 4.1 (m).
PAPER_CAMERA_DISTANCE_M = 3.0

#: Accepted values of ``relative_to`` in :func:`simulate_kinect`.
RELATIVE_TO = ("tracked_shoulder", "session_shoulder", "true_shoulder")


@dataclass(frozen=True)
class KinectModel:
    """Error parameters of a first-generation Kinect skeletal tracker (module docstring).

    Parameters
    ----------
    frame_rate_hz : float
        Skeleton frame rate (Hz).  30 (Khoshelham & Oude Elberink 2012; paper 002).
    depth_noise_const_m, depth_noise_quad_m_per_m2, depth_noise_offset_m : float
        ``σ_depth(Z) = const + quad · (Z − offset)²`` (m): 0.0012 m, 0.0019 m/m², 0.4 m
        (Nguyen et al. 2012).
    lateral_noise_px : float
        Lateral noise (pixels); ``σ_lateral(Z) = lateral_noise_px · Z / focal_length_px`` (m).
        0.8 px (Nguyen et al. 2012).
    focal_length_px : float
        Depth-camera focal length (pixels).  585 (assumed).
    jitter_correlation_s : float
        Correlation time of the AR(1) jitter (s); 0 gives white jitter.  0.1 s (assumed).
    bias_std_m : float
        Standard deviation of the per-joint, per-session offset on each axis (m).  0.02
        (assumed).
    glitch_rate_hz : float
        Burst hazard of a joint in clear view (1/s).  0.02 (assumed).
    glitch_rate_occluded_hz : float
        Burst hazard at occlusion score 1 (1/s).  0.5 (assumed).
    glitch_mean_duration_s : float
        Mean burst duration (s); bursts last at least one frame.  0.3 (assumed).
    glitch_min_m, glitch_max_m : float
        Range of the burst error magnitude (m), uniform.  0.10–0.15 (paper 002, Section 5).
    """

    frame_rate_hz: float = 30.0
    depth_noise_const_m: float = 0.0012
    depth_noise_quad_m_per_m2: float = 0.0019
    depth_noise_offset_m: float = 0.4
    lateral_noise_px: float = 0.8
    focal_length_px: float = 585.0
    jitter_correlation_s: float = 0.1
    bias_std_m: float = 0.02
    glitch_rate_hz: float = 0.02
    glitch_rate_occluded_hz: float = 0.5
    glitch_mean_duration_s: float = 0.3
    glitch_min_m: float = 0.10
    glitch_max_m: float = 0.15

    def __post_init__(self):
        positive = ("frame_rate_hz", "focal_length_px", "glitch_mean_duration_s")
        check_fields(self, positive=positive, nonnegative=[item.name for item in fields(self) if item.name not in
                                                            (*positive, "depth_noise_offset_m")])
        offset = float(self.depth_noise_offset_m)
        if not math.isfinite(offset):
            raise ValueError(f"depth_noise_offset_m must be finite, got {self.depth_noise_offset_m!r}")
        object.__setattr__(self, "depth_noise_offset_m", offset)
        if self.glitch_min_m > self.glitch_max_m:
            raise ValueError(f"glitch_min_m = {self.glitch_min_m} exceeds glitch_max_m = {self.glitch_max_m}")

    @classmethod
    def noise_free(cls, frame_rate_hz: float = 30.0) -> KinectModel:
        """A model with every error component switched off (reports the truth at its frames)."""
        return cls(frame_rate_hz=frame_rate_hz, depth_noise_const_m=0.0, depth_noise_quad_m_per_m2=0.0,
                   lateral_noise_px=0.0, bias_std_m=0.0, glitch_rate_hz=0.0, glitch_rate_occluded_hz=0.0)

    @property
    def jitter_lag1_correlation(self) -> float:
        """Lag-1 (one frame) autocorrelation φ of the jitter."""
        if self.jitter_correlation_s == 0.0:
            return 0.0
        return math.exp(-1.0 / (self.frame_rate_hz * self.jitter_correlation_s))

    def depth_noise_std_m(self, depth_m) -> np.ndarray:
        """Jitter standard deviation along the camera axis at depth ``depth_m`` (m)."""
        depth = np.asarray(depth_m, dtype=float)
        return self.depth_noise_const_m + self.depth_noise_quad_m_per_m2 * (depth - self.depth_noise_offset_m) ** 2

    def lateral_noise_std_m(self, depth_m) -> np.ndarray:
        """Jitter standard deviation across the camera axis (each lateral axis) at ``depth_m`` (m)."""
        return self.lateral_noise_px * np.asarray(depth_m, dtype=float) / self.focal_length_px


@dataclass(frozen=True)
class KinectErrors:
    """The error components of one simulated Kinect session, before shoulder referencing.

    ``...`` are the batch dimensions of the input, ``K`` the number of Kinect frames, ``J`` the
    number of joints.  Reported positions are ``truth + bias + jitter + glitch``.

    Attributes
    ----------
    times : ndarray, shape (K,)
        Frame times (s), ``k / frame_rate_hz``.
    truth : ndarray, shape (..., K, J, 3)
        True joint positions at the frame times (m).
    bias : ndarray, shape (..., 1, J, 3)
        Per-joint session offsets (m).
    jitter : ndarray, shape (..., K, J, 3)
        Correlated anisotropic jitter (m).
    glitch : ndarray, shape (..., K, J, 3)
        Burst errors (m); zero outside bursts.
    glitch_active : ndarray of bool, shape (..., K, J)
        Frames inside a burst.
    glitch_start : ndarray of bool, shape (..., K, J)
        First frame of each burst.
    occlusion_score : ndarray, shape (..., K, J)
        The score ``s ∈ [0, 1]`` that set the burst hazard.
    """

    times: np.ndarray
    truth: np.ndarray
    bias: np.ndarray
    jitter: np.ndarray
    glitch: np.ndarray
    glitch_active: np.ndarray
    glitch_start: np.ndarray
    occlusion_score: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """Absolute error ``bias + jitter + glitch``, shape (..., K, J, 3) (m)."""
        return self.bias + self.jitter + self.glitch


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------


def n_kinect_frames(n_samples: int, fs, frame_rate_hz: float = 30.0) -> int:
    """Number of Kinect frames ``t_k = k / frame_rate_hz`` inside ``[0, (n_samples − 1) / fs]``."""
    check_count(n_samples, "n_samples")
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
        raise ValueError(f"{name} has shape {arr.shape}; it must be (3,) or broadcast to the batch shape "
                         f"{batch_shape} + (3,)")
    return arr


def _occlusion_score(truth: np.ndarray, axis: np.ndarray, occluded) -> np.ndarray:
    """Score in [0, 1]: cos² of the most end-on incident segment of the joint chain, or 1 where ``occluded``."""
    score = np.zeros(truth.shape[:-1])
    camera_axis = axis[..., None, :]  # broadcast over frames
    for joint in range(1, truth.shape[-2]):
        parent = joint - 1
        segment = truth[..., joint, :] - truth[..., parent, :]
        length = np.linalg.norm(segment, axis=-1)
        cosine = np.divide(np.sum(segment * camera_axis, axis=-1), length, out=np.zeros_like(length), where=length > 0)
        aligned = cosine**2
        score[..., joint] = np.maximum(score[..., joint], aligned)
        score[..., parent] = np.maximum(score[..., parent], aligned)
    if occluded is not None:
        score = np.where(occluded, 1.0, score)
    return score


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


def kinect_errors(true_positions, *, rng: np.random.Generator, fs: float = 30.0, camera_position, camera_axis,
                  model: KinectModel | None = None, occluded=None) -> KinectErrors:
    """Draw the error components of a Kinect session (module docstring).

    Parameters
    ----------
    true_positions : array_like, shape (..., T, J, 3)
        True positions (m) of a chain of joints, root first (shoulder → elbow → wrist), in any
        right-handed frame (the paper's shoulder frame), sampled at ``fs``.  Leading dimensions
        are batches (sessions, Monte Carlo runs).
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

    Returns
    -------
    KinectErrors
    """
    model = check_type(KinectModel() if model is None else model, KinectModel, "model")
    rng = check_rng(rng)
    fs = check_positive(fs, "fs")
    positions = as_float_array(true_positions, "true_positions", last_dim=3, min_ndim=3)
    n_samples, n_joints = positions.shape[-3], positions.shape[-2]
    if n_samples < 1 or n_joints < 1:
        raise ValueError(f"true_positions needs at least one sample and one joint, got shape {positions.shape}")
    batch_shape = positions.shape[:-3]
    position = _camera_vector(camera_position, "camera_position", batch_shape)
    axis = _camera_vector(camera_axis, "camera_axis", batch_shape)
    axis = axis / check_nonzero_norm(axis, "camera_axis", "the camera's viewing direction")[..., None]
    mask = None if occluded is None else as_bool_mask(occluded, "occluded", positions.shape[:-1])

    frame_rate = model.frame_rate_hz
    n_frames = n_kinect_frames(n_samples, fs, frame_rate)
    truth = _resample_positions(positions, fs, frame_rate, n_frames)
    if mask is not None:
        mask = _resample_mask(mask, fs, frame_rate, n_frames)

    axis_b = axis[..., None, None, :]  # broadcast over frames and joints
    depth = np.sum((truth - position[..., None, None, :]) * axis_b, axis=-1)
    if np.any(depth <= 0.0):
        bad = np.argwhere(depth <= 0.0)[0]
        raise ValueError(f"a joint is not in front of the camera (depth {depth[tuple(bad)]:.3f} m at index "
                         f"{tuple(int(i) for i in bad)}); check camera_position and camera_axis")
    shape = truth.shape

    bias = model.bias_std_m * rng.standard_normal(shape[:-3] + (1,) + shape[-2:])

    unit = ar1_filter(rng.standard_normal(shape), model.jitter_lag1_correlation, axis=-3)  # AR(1) over frames
    lateral_1 = perpendicular_unit(axis)  # two unit vectors perpendicular to the axis and to each other
    lateral_2 = np.cross(axis, lateral_1)
    sigma_depth = model.depth_noise_std_m(depth)[..., None]
    sigma_lateral = model.lateral_noise_std_m(depth)[..., None]
    jitter = (unit[..., 0:1] * sigma_depth * axis_b
              + unit[..., 1:2] * sigma_lateral * lateral_1[..., None, None, :]
              + unit[..., 2:3] * sigma_lateral * lateral_2[..., None, None, :])

    score = _occlusion_score(truth, axis, mask)
    glitch, active, started = _glitches(rng, score, model)

    return KinectErrors(times=np.arange(n_frames) / frame_rate, truth=truth, bias=bias, jitter=jitter, glitch=glitch,
                        glitch_active=active, glitch_start=started, occlusion_score=score)


def simulate_kinect(true_positions, *, rng: np.random.Generator, fs: float = 30.0, camera_position, camera_axis,
                    model: KinectModel | None = None, occluded=None,
                    relative_to: str = "tracked_shoulder") -> np.ndarray:
    """Joint positions as a first-generation Kinect skeletal tracker reports them.

    Parameters
    ----------
    true_positions, rng, fs, camera_position, camera_axis, model, occluded
        As in :func:`kinect_errors`; the shoulder is the first joint (as in
        :data:`wsnlib.arm_model.JOINT_NAMES`).
    relative_to : {"tracked_shoulder", "session_shoulder", "true_shoulder"}
        Which shoulder estimate is the origin of the reported coordinates (module docstring).

    Returns
    -------
    ndarray, shape (..., K, J, 3)
        Reported joint positions (m) in the frame of ``true_positions``, at the Kinect frame
        times :func:`kinect_frame_times` (``K = T`` when ``fs`` equals the frame rate).
    """
    check_choice(relative_to, "relative_to", RELATIVE_TO)
    errors = kinect_errors(true_positions, rng=rng, fs=fs, camera_position=camera_position, camera_axis=camera_axis,
                           model=model, occluded=occluded)
    error = errors.total
    shoulder = error[..., :1, :]
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
        elbow) and forearm (elbow → wrist) of :data:`wsnlib.arm_model.JOINT_NAMES`.
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


# --------------------------------------------------------------------------------------------
# Paper 002's hand-derived reference
# --------------------------------------------------------------------------------------------

#: Default standard deviation (°, per axis) of the posture rotation of the hand-derived reference.
REFERENCE_ROTATION_STD_DEG = 3.0

#: Default standard deviation (s) of the timing offset of the hand-derived reference.
REFERENCE_TIMING_STD_S = 0.1


def hand_derived_reference(true_positions, movement, time_s, *, rng: np.random.Generator,
                           rotation_std_deg: float = REFERENCE_ROTATION_STD_DEG,
                           timing_std_s: float = REFERENCE_TIMING_STD_S) -> np.ndarray:
    """Reference positions as paper 002 derived them by hand, from the true ones (module docstring,
    "Hand-derived reference").

    Parameters
    ----------
    true_positions : array_like, shape (n, 3) or (n, J, 3)
        True positions (m) in the shoulder frame (origin at the shoulder), rows in time order
        within each movement; ``J`` targets share each row's posture and timing errors.
    movement : array_like of int, shape (n,)
        Movement label of each row (the errors are drawn once per label; label 0 or any other
        is treated alike).
    time_s : array_like, shape (n,)
        Time of each row (s), non-decreasing within a movement; the timing offset interpolates
        the movement's own rows in time.
    rng : numpy.random.Generator
        Draws, per movement in sorted label order, the rotation vector (3) then the time offset.
        The number of draws does not depend on the standard deviations, so zero ones reproduce
        the truth with the same generator state afterwards.
    rotation_std_deg, timing_std_s : float
        Standard deviations (≥ 0) of the two error components.

    Returns
    -------
    numpy.ndarray, shape of ``true_positions``
        The reference (m).  With both standard deviations 0 it equals ``true_positions``.
    """
    rng = check_rng(rng)
    positions = as_float_array(true_positions, "true_positions", last_dim=3)
    if positions.ndim not in (2, 3):
        raise ValueError(f"true_positions must have shape (n, 3) or (n, J, 3), got {positions.shape}")
    n = positions.shape[0]
    labels = np.asarray(movement)
    if labels.shape != (n,) or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"movement must be integer labels of shape ({n},), got dtype {labels.dtype}, "
                         f"shape {labels.shape}")
    times = as_float_array(time_s, "time_s")
    if times.shape != (n,):
        raise ValueError(f"time_s must have shape ({n},), got {times.shape}")
    sigma_rot = math.radians(check_nonnegative(rotation_std_deg, "rotation_std_deg"))
    sigma_t = check_nonnegative(timing_std_s, "timing_std_s")
    flat = positions.reshape(n, -1, 3)
    reference = flat.copy()
    for label in np.unique(labels):
        rows = np.flatnonzero(labels == label)
        rotvec = sigma_rot * rng.standard_normal(3)
        shift = sigma_t * rng.standard_normal()
        t = times[rows]
        if np.any(np.diff(t) < 0):
            raise ValueError(f"time_s must be non-decreasing within movement {label}")
        shifted = flat[rows]
        if shift != 0.0 and rows.size > 1:
            query = np.clip(t + shift, t[0], t[-1])
            shifted = np.stack([np.stack([np.interp(query, t, flat[rows, j, d]) for d in range(3)], axis=-1)
                                for j in range(flat.shape[1])], axis=1)
        angle = float(fixed_order.norm(rotvec))
        if angle > 0.0:
            axis = rotvec / angle
            # Rodrigues' rotation of every point about the shoulder (the origin).
            cross = np.cross(axis, shifted)
            dot = np.sum(shifted * axis, axis=-1, keepdims=True)
            shifted = shifted * math.cos(angle) + cross * math.sin(angle) + axis * dot * (1.0 - math.cos(angle))
        reference[rows] = shifted
    return reference.reshape(positions.shape)
