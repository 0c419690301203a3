"""Two-segment arm kinematics: joint-angle trajectories and exact ground truth for two IMU nodes.

The arm is the chain shoulder → humerus → elbow → forearm → wrist, with the shoulder fixed at
the origin of the earth frame (ENU: x east, y north, z up).  Each segment carries one IMU node
(node order ``("humerus", "forearm")``, see :data:`NODE_NAMES`).

Segment (node body) frames
--------------------------
Each node's body frame is aligned with its segment:

* body **x** runs along the segment, pointing distally (shoulder → elbow for the humerus,
  elbow → wrist for the forearm);
* body **z** is the segment's dorsal "up" side: in the *reference posture* — arm straight,
  pointing horizontally forward (north), palm down — body z points up (earth +z) on both
  segments;
* body **y** completes the right-handed frame (``y = z × x``); in the reference posture it
  points west, i.e. to the subject's left when facing north.

So in the reference posture both nodes have the quaternion ``q_ref`` = 90° about earth z
(body x → north, body y → west, body z → up).

Joint angles (all rad)
----------------------
* ``heading`` ψ: rotation of the whole arm about earth z (right-hand rule about "up", i.e.
  counter-clockwise seen from above).  ψ = 0 points the humerus north, ψ = +π/2 west.  It is
  the ENU yaw of the humerus direction, not a compass bearing (bearing = −ψ).
* ``pitch`` θ: elevation of the humerus x axis above the horizontal plane, applied about the
  humerus body −y axis.  The humerus pitch as computed by metrics,
  ``asin(x_E · ẑ)`` with ``x_E = q ⊗ x̂ ⊗ q*``, equals θ exactly for θ ∈ [−π/2, π/2]
  (−π/2: arm hanging down; 0: horizontal forward; +π/2: straight up).
* ``axial``: humeral axial (internal/external) rotation about the humerus' own x axis; it
  does not change the humerus pitch, but turns the plane in which the elbow flexes.
* ``elbow_flexion`` β: rotation of the forearm relative to the humerus about the humerus body
  −y axis (flexion raises the hand when the arm points forward palm down).  The elbow angle,
  the angle between the two body x axes, is ``|β|`` (0 when the segments are aligned).

Orientation of the nodes, as products of elementary rotations ``R_a(α)`` about axis ``a``::

    q_humerus = R_z(ψ) ⊗ q_ref ⊗ R_y(−θ) ⊗ R_x(axial)
    q_forearm = q_humerus ⊗ R_y(−β)

Derivatives are analytic.  For a product ``q = A ⊗ B`` with body rates ``ω_A``, ``ω_B`` and
body-frame angular accelerations ``ω̇_A``, ``ω̇_B``, eq. (1) of paper 001
(``q̇ = ½ q ⊗ [0, ω]``) gives::

    ω  = R_Bᵀ ω_A + ω_B
    ω̇  = R_Bᵀ ω̇_A − ω_B × (R_Bᵀ ω_A) + ω̇_B

and the acceleration of a point fixed at ``r`` in a body frame rotating about a fixed point is
``R (ω̇ × r + ω × (ω × r))``.  Joint-angle rates and accelerations come from the trajectory
generators in closed form (minimum-jerk and linear profiles).

Sources
-------
* Paper 001 (De Vito et al.), Section II and IV: the "90° arm extension" with humerus and
  forearm moving jointly aligned (Figs. 1, 6–8) and the linearly growing humerus pitch
  (Fig. 2).
* Minimum-jerk profile: T. Flash and N. Hogan, "The coordination of arm movements: an
  experimentally confirmed mathematical model", J. Neurosci. 5(7):1688–1703, 1985:
  ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵``.
* Segment lengths as fractions of body height H (upper arm 0.186 H, forearm 0.146 H): D. A.
  Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley 2009, Fig. 4.1,
  after R. Drillis and R. Contini (1966).  The fractions are as widely reproduced from that
  figure; the book itself was not re-read for this module.  The node mounting points are
  assumptions (see :meth:`wsnlib.arm_model.ArmGeometry.paper001`).

An :class:`ArmTrajectory` holds the four joint angles with their first and second time
derivatives; the generators (:func:`arm_extension`, :func:`pitch_ramp`,
:func:`reach_and_flex`, :func:`movement_set`) build them and :func:`arm_kinematics` turns one
into the ground truth of both nodes.  The geometry (:class:`wsnlib.arm_model.ArmGeometry`) and
the kinematics (:class:`wsnlib.arm_model.ArmKinematics`, layout ``(node, T, C)``) live in
:mod:`wsnlib.arm_model`, shared with paper 002's simulators and the posture chain.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wsnlib import quaternion as Q
from wsnlib._validation import as_float_array, check_nonnegative, check_positive, check_type
from wsnlib.arm_model import NODE_NAMES, Q_REFERENCE, ArmGeometry, ArmKinematics

# --------------------------------------------------------------------------------------------
# Joint-angle trajectories
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ArmTrajectory:
    """Joint angles of the arm over time, with their first and second time derivatives.

    Build one with :func:`arm_extension`, :func:`pitch_ramp` or :func:`reach_and_flex`
    rather than by hand (the constructor checks shapes, not that ``rates`` really is the
    derivative of ``angles``).

    Attributes
    ----------
    fs : float
        Sampling rate (Hz).
    t : numpy.ndarray, shape (T,)
        Sample times (s), ``t[k] = t[0] + k / fs``.
    angles : numpy.ndarray, shape (T, 4)
        Joint angles (rad) in the order heading, pitch, axial, elbow flexion (defined in the
        module docstring).
    rates : numpy.ndarray, shape (T, 4)
        Their time derivatives (rad/s).
    accelerations : numpy.ndarray, shape (T, 4)
        Their second time derivatives (rad/s²).
    metadata : dict
        Provenance (generator name and parameters), JSON-serialisable; copied into the
        recording sidecar by :func:`wsnlib.sim.imu.simulate_recording`.
    """

    fs: float
    t: np.ndarray
    angles: np.ndarray
    rates: np.ndarray
    accelerations: np.ndarray
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        fs = check_positive(self.fs, "fs")
        t = as_float_array(self.t, "t")
        if t.ndim != 1 or t.size < 2:
            raise ValueError(f"t must be a 1-D array of at least 2 samples, got shape {t.shape}")
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "t", t)
        for name in ("angles", "rates", "accelerations"):
            arr = as_float_array(getattr(self, name), name, last_dim=4)
            if arr.shape != (t.size, 4):
                raise ValueError(f"{name} must have shape ({t.size}, 4), got {arr.shape}")
            object.__setattr__(self, name, arr)
        if not isinstance(self.metadata, dict):
            raise ValueError(f"metadata must be a dict, got {type(self.metadata).__name__}")

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.t.size


def _time_axis(fs: float, duration_s: float) -> tuple[float, np.ndarray]:
    fs = check_positive(fs, "fs")
    duration = check_positive(duration_s, "duration_s")
    n = int(round(duration * fs))
    if n < 2:
        raise ValueError(f"duration_s * fs must give at least 2 samples, got {duration * fs:g}")
    return fs, np.arange(n) / fs


def minimum_jerk(t, start_s: float, rise_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk transition 0 → 1 (Flash & Hogan 1985) and its derivatives.

    ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` with ``τ = (t − start_s) / rise_s`` clipped to [0, 1]:
    0 before ``start_s``, 1 after ``start_s + rise_s``, with zero velocity and acceleration at
    both ends.

    Parameters
    ----------
    t : array_like, shape (T,)
        Times (s).
    start_s : float
        Start of the transition (s).
    rise_s : float
        Duration of the transition (s), > 0.

    Returns
    -------
    s, ds, dds : numpy.ndarray, shape (T,)
        Profile (1), its first (1/s) and second (1/s²) time derivative.
    """
    t = as_float_array(t, "t", min_ndim=0)
    rise = check_positive(rise_s, "rise_s")
    start = float(start_s)
    tau = np.clip((t - start) / rise, 0.0, 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / rise
    dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / rise**2
    return s, ds, dds


def _pitch_angles(heading_deg: float, pitch: np.ndarray, axial_deg: float) -> np.ndarray:
    """Joint angles (T, 4): constant heading and axial rotation (degrees), ``pitch`` (rad), elbow 0."""
    n = pitch.size
    return np.stack([np.full(n, float(np.radians(heading_deg))), pitch, np.full(n, float(np.radians(axial_deg))),
                     np.zeros(n)], axis=-1)


def arm_extension(fs: float = 50.0, duration_s: float = 6.0, start_s: float = 1.0, rise_s: float = 2.0,
                  pitch_start_deg: float = -90.0, pitch_end_deg: float = 0.0, heading_deg: float = 0.0,
                  axial_deg: float = 0.0) -> ArmTrajectory:
    """The paper's "90° arm extension": the straight arm rises from rest, then rests again.

    Humerus and forearm move jointly aligned (elbow flexion 0 throughout).  The humerus
    pitch is ``pitch_start_deg`` until ``start_s``, follows a minimum-jerk profile to
    ``pitch_end_deg`` over ``rise_s`` seconds, then stays there until ``duration_s``.

    Parameters
    ----------
    fs : float
        Sampling rate (Hz); the paper's IMU samples at 50 Hz.
    duration_s : float
        Length of the trajectory (s); ``round(duration_s · fs)`` samples from t = 0.
    start_s, rise_s : float
        Start (s) and duration (s) of the raise.  With the defaults (1 s, 2 s at 50 Hz) the
        paper's loss "right after 80 samples" (1.6 s) falls in the middle of the movement.
    pitch_start_deg, pitch_end_deg : float
        Humerus (and forearm) pitch before and after the raise (degrees); the default −90° →
        0° is the arm hanging down, raised forward to horizontal.
    heading_deg : float
        Heading ψ of the arm (degrees, module docstring), constant.
    axial_deg : float
        Humeral axial rotation (degrees), constant.

    Returns
    -------
    ArmTrajectory
    """
    fs, t = _time_axis(fs, duration_s)
    check_nonnegative(start_s, "start_s")
    s, ds, dds = minimum_jerk(t, start_s, rise_s)
    span = np.radians(float(pitch_end_deg) - float(pitch_start_deg))
    n = t.size
    angles = _pitch_angles(heading_deg, np.radians(float(pitch_start_deg)) + span * s, axial_deg)
    rates = np.stack([np.zeros(n), span * ds, np.zeros(n), np.zeros(n)], axis=-1)
    accelerations = np.stack([np.zeros(n), span * dds, np.zeros(n), np.zeros(n)], axis=-1)
    metadata = {"generator": "wsnlib.sim.arm.arm_extension", "fs": fs, "duration_s": float(duration_s),
                "start_s": float(start_s), "rise_s": float(rise_s), "pitch_start_deg": float(pitch_start_deg),
                "pitch_end_deg": float(pitch_end_deg), "heading_deg": float(heading_deg),
                "axial_deg": float(axial_deg)}
    return ArmTrajectory(fs, t, angles, rates, accelerations, metadata)


def pitch_ramp(fs: float = 50.0, duration_s: float = 60.0, pitch_start_deg: float = -60.0, pitch_end_deg: float = 60.0,
               heading_deg: float = 0.0, axial_deg: float = 0.0) -> ArmTrajectory:
    """Humerus pitch growing linearly with time, forearm aligned (paper 001, Fig. 2).

    The pitch goes from ``pitch_start_deg`` at t = 0 to ``pitch_end_deg`` at the last sample,
    at the constant rate ``(pitch_end − pitch_start) / ((T − 1) / fs)``; angular acceleration
    is zero throughout.

    Parameters
    ----------
    fs : float
        Sampling rate (Hz).
    duration_s : float
        Length (s); ``round(duration_s · fs)`` samples.
    pitch_start_deg, pitch_end_deg : float
        Pitch at the first and last sample (degrees), within [−90, 90].
    heading_deg, axial_deg : float
        Constant heading and humeral axial rotation (degrees).

    Returns
    -------
    ArmTrajectory
    """
    fs, t = _time_axis(fs, duration_s)
    for name, value in (("pitch_start_deg", pitch_start_deg), ("pitch_end_deg", pitch_end_deg)):
        if not -90.0 <= float(value) <= 90.0:
            raise ValueError(f"{name} must lie in [-90, 90] degrees, got {value!r}")
    n = t.size
    rate = np.radians(float(pitch_end_deg) - float(pitch_start_deg)) / t[-1]
    angles = _pitch_angles(heading_deg, np.radians(float(pitch_start_deg)) + rate * t, axial_deg)
    rates = np.zeros((n, 4))
    rates[:, 1] = rate
    metadata = {"generator": "wsnlib.sim.arm.pitch_ramp", "fs": fs, "duration_s": float(duration_s),
                "pitch_start_deg": float(pitch_start_deg), "pitch_end_deg": float(pitch_end_deg),
                "heading_deg": float(heading_deg), "axial_deg": float(axial_deg)}
    return ArmTrajectory(fs, t, angles, rates, np.zeros((n, 4)), metadata)


def reach_and_flex(fs: float = 50.0, duration_s: float = 6.0, start_s: float = 1.0, rise_s: float = 2.5,
                   pitch_end_deg: float = -20.0, heading_end_deg: float = 30.0,
                   elbow_end_deg: float = 90.0) -> ArmTrajectory:
    """A three-joint movement: the arm rises and swings sideways while the elbow flexes.

    From hanging (pitch −90°, heading 0°, elbow straight) to ``pitch_end_deg``,
    ``heading_end_deg`` and ``elbow_end_deg`` of flexion, all joints following one
    minimum-jerk profile over ``rise_s`` seconds — roughly bringing a hand towards the mouth.
    Unlike the arm extension, the elbow angle is not 0, and the heading changes.

    Parameters
    ----------
    fs, duration_s, start_s, rise_s : float
        As in :func:`arm_extension`.
    pitch_end_deg, heading_end_deg, elbow_end_deg : float
        Final humerus pitch, heading and elbow flexion (degrees).

    Returns
    -------
    ArmTrajectory
        Closed-form angles, rates and accelerations.
    """
    fs, t = _time_axis(fs, duration_s)
    check_nonnegative(start_s, "start_s")
    s, ds, dds = minimum_jerk(t, start_s, rise_s)
    start = np.radians([0.0, -90.0, 0.0, 0.0])
    span = np.radians([float(heading_end_deg), float(pitch_end_deg) + 90.0, 0.0, float(elbow_end_deg)])
    angles = start + s[:, None] * span
    rates = ds[:, None] * span
    accelerations = dds[:, None] * span
    metadata = {"generator": "wsnlib.sim.arm.reach_and_flex", "fs": fs, "duration_s": float(duration_s),
                "start_s": float(start_s), "rise_s": float(rise_s), "pitch_end_deg": float(pitch_end_deg),
                "heading_end_deg": float(heading_end_deg), "elbow_end_deg": float(elbow_end_deg)}
    return ArmTrajectory(fs, t, angles, rates, accelerations, metadata)


def movement_set(fs: float = 50.0, duration_s: float = 8.0, start_s: float = 1.0) -> dict[str, ArmTrajectory]:
    """Movements of equal length at different speeds, for Monte Carlo studies.

    Three 90° arm extensions (raise in 1.5 s, 3 s and 5 s: fast, medium and slow; peak
    angular rates ≈ 112, 56 and 34 °/s) and one :func:`reach_and_flex` (2.5 s).  Every
    movement starts at ``start_s`` and all have ``round(duration_s · fs)`` samples, so their
    IMU signals stack into one batch.

    Returns
    -------
    dict[str, ArmTrajectory]
        Name → trajectory, in a fixed order.
    """
    return {
        "extension fast": arm_extension(fs, duration_s, start_s, rise_s=1.5),
        "extension medium": arm_extension(fs, duration_s, start_s, rise_s=3.0),
        "extension slow": arm_extension(fs, duration_s, start_s, rise_s=5.0),
        "reach and flex": reach_and_flex(fs, duration_s, start_s, rise_s=2.5),
    }


_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


# --------------------------------------------------------------------------------------------
# Kinematics
# --------------------------------------------------------------------------------------------


def _axis_factor(axis: np.ndarray, angle, rate, accel):
    """(quaternion, body rate, body angular acceleration) of a rotation about a fixed axis."""
    q = Q.from_axis_angle(axis, angle)
    return q, rate[..., None] * axis, accel[..., None] * axis


def _compose(a, b):
    """Chain rule for ``q = A ⊗ B``: body rate and angular acceleration of the product."""
    q_a, w_a, dw_a = a
    q_b, w_b, dw_b = b
    w_a_in_b = Q.rotate_inverse(q_b, w_a)
    w = w_a_in_b + w_b
    dw = Q.rotate_inverse(q_b, dw_a) - np.cross(w_b, w_a_in_b) + dw_b
    return Q.multiply(q_a, q_b), w, dw


def _point_motion(q, w, dw, r):
    """Earth-frame position, velocity, acceleration of body point ``r`` about a fixed origin."""
    w_x_r = np.cross(w, r)
    pos = Q.rotate(q, np.broadcast_to(r, w.shape))
    vel = Q.rotate(q, w_x_r)
    acc = Q.rotate(q, np.cross(dw, r) + np.cross(w, w_x_r))
    return pos, vel, acc


def arm_kinematics(trajectory: ArmTrajectory, geometry: ArmGeometry | None = None) -> ArmKinematics:
    """Ground-truth orientations, rates and mounting-point motion of both nodes.

    Parameters
    ----------
    trajectory : ArmTrajectory
        Joint angles with their derivatives.
    geometry : wsnlib.arm_model.ArmGeometry, optional
        Segment lengths and node mounting points (two segments); default
        ``ArmGeometry.paper001()``, paper 001's arm.

    Returns
    -------
    wsnlib.arm_model.ArmKinematics
        Quaternions ``(2, T, 4)``, body angular rate and acceleration ``(2, T, 3)``,
        mounting-point position/velocity/linear acceleration ``(2, T, 3)`` (earth frame),
        joint centres ``(3, T, 3)``.  All derivatives are analytic (module docstring).
    """
    check_type(trajectory, ArmTrajectory, "trajectory")
    geometry = check_type(ArmGeometry.paper001() if geometry is None else geometry, ArmGeometry, "geometry")
    ang, rate, acc = trajectory.angles, trajectory.rates, trajectory.accelerations
    n = trajectory.n_samples

    heading = _axis_factor(_Z, ang[:, 0], rate[:, 0], acc[:, 0])
    reference = (np.broadcast_to(Q_REFERENCE, (n, 4)), np.zeros((n, 3)), np.zeros((n, 3)))
    # Pitch raises body x: rotation about body -y (R_y(-θ) maps x to (cos θ, 0, sin θ)).
    pitch = _axis_factor(_Y, -ang[:, 1], -rate[:, 1], -acc[:, 1])
    axial = _axis_factor(_X, ang[:, 2], rate[:, 2], acc[:, 2])
    elbow = _axis_factor(_Y, -ang[:, 3], -rate[:, 3], -acc[:, 3])

    humerus = _compose(_compose(_compose(heading, reference), pitch), axial)
    forearm = _compose(humerus, elbow)

    if geometry.n_segments != 2:
        raise ValueError(f"geometry must have 2 segments (upper arm, forearm), got {geometry.n_segments}")
    r_humerus, r_forearm = geometry.device_points_m
    r_elbow = np.array([geometry.segment_lengths_m[0], 0.0, 0.0])
    r_wrist = np.array([geometry.segment_lengths_m[1], 0.0, 0.0])

    p_h, v_h, a_h = _point_motion(*humerus, r_humerus)
    p_e, v_e, a_e = _point_motion(*humerus, r_elbow)
    p_fr, v_fr, a_fr = _point_motion(*forearm, r_forearm)  # relative to the elbow
    p_w = p_e + Q.rotate(forearm[0], np.broadcast_to(r_wrist, (n, 3)))

    quat = np.stack([humerus[0], forearm[0]])
    # Continuous sign in time (q and -q are the same rotation): flip where the dot product
    # with the previous sample is negative, cumulatively.
    dots = np.sum(quat[:, 1:] * quat[:, :-1], axis=-1)
    flips = np.concatenate([np.zeros((2, 1), dtype=int), np.cumsum(dots < 0.0, axis=-1)], axis=-1)
    quat = np.where((flips % 2 == 1)[..., None], -quat, quat)
    quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)

    return ArmKinematics(fs=trajectory.fs, time_s=trajectory.t.copy(), nodes=NODE_NAMES, quat=quat,
                         gyr=np.stack([humerus[1], forearm[1]]), ang_acc=np.stack([humerus[2], forearm[2]]),
                         pos=np.stack([p_h, p_e + p_fr]), vel=np.stack([v_h, v_e + v_fr]),
                         acc_lin=np.stack([a_h, a_e + a_fr]), joint_pos=np.stack([np.zeros((n, 3)), p_e, p_w]),
                         geometry=geometry, trajectory=trajectory)
