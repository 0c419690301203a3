"""A first-generation Kinect skeletal tracker as a measuring instrument (paper 002, Tables 2–3).

Paper 002 (Section 4.1) ran the Kinect SDK's *Skeletal Viewer* with the Kinect about 3 m in
front of the user, saved the arm joints of every frame (~30 fps) and derived the two target
positions from them; its Table 3 reports the resulting position error (PE) of "Kinect".  This
module turns true joint trajectories into what such a tracker reports, so that the comparison
can be simulated.  Every number below is a published Kinect figure or a stated assumption; none
was fitted to paper 002's tables.

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

The code lives in three modules, re-exported here (this stays the public path):
:mod:`wsnlib.sim.kinect_model` (:class:`KinectModel`, :class:`KinectErrors`),
:mod:`wsnlib.sim.kinect` (:func:`kinect_errors`, :func:`simulate_kinect`,
:func:`kinect_target_positions`, the frame grid) and :mod:`wsnlib.sim.hand_reference`
(:func:`hand_derived_reference`, paper 002's hand-derived reference positions).
"""

from wsnlib.sim.hand_reference import (
    REFERENCE_ROTATION_STD_DEG,
    REFERENCE_TIMING_STD_S,
    hand_derived_reference,
)
from wsnlib.sim.kinect import (
    kinect_errors,
    kinect_frame_times,
    kinect_target_positions,
    n_kinect_frames,
    simulate_kinect,
)
from wsnlib.sim.kinect_model import PAPER_CAMERA_DISTANCE_M, RELATIVE_TO, KinectErrors, KinectModel

__all__ = [
    "hand_derived_reference",
    "kinect_errors",
    "kinect_frame_times",
    "kinect_target_positions",
    "KinectErrors",
    "KinectModel",
    "n_kinect_frames",
    "PAPER_CAMERA_DISTANCE_M",
    "REFERENCE_ROTATION_STD_DEG",
    "REFERENCE_TIMING_STD_S",
    "RELATIVE_TO",
    "simulate_kinect",
]
