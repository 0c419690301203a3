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
generators in closed form (minimum-jerk and linear profiles), or from a quintic spline fitted
to sampled angles in :func:`from_joint_angles`.

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

The geometry (:class:`wsnlib.arm_model.ArmGeometry`) and the kinematics this module computes
(:class:`wsnlib.arm_model.ArmKinematics`, layout ``(node, T, C)``; former name ``ArmTruth``)
live in :mod:`wsnlib.arm_model`, shared with paper 002's simulators and the posture chain;
the joint-angle trajectories and their generators (:class:`ArmTrajectory`,
:func:`arm_extension`, …) live in :mod:`wsnlib.sim.arm_trajectory`; this module computes
:func:`arm_kinematics` and re-exports both under their old names.
"""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion as Q

# The arm's geometry and kinematics live in wsnlib.arm_model (shared with paper 002's
# simulators and the posture chain); re-exported here under their former names.
from wsnlib.arm_model import (  # noqa: F401
    DEFAULT_BODY_HEIGHT_M,
    FOREARM_FRACTION,
    JOINT_NAMES,
    NODE_NAMES,
    Q_REFERENCE,
    UPPER_ARM_FRACTION,
    ArmGeometry,
    ArmKinematics,
)

# The joint-angle trajectories live in wsnlib.sim.arm_trajectory; re-exported (old path).
from wsnlib.sim.arm_trajectory import (  # noqa: F401
    ANGLE_NAMES,
    ArmTrajectory,
    arm_extension,
    from_joint_angles,
    minimum_jerk,
    movement_set,
    pitch_ramp,
    reach_and_flex,
)

#: Former name of :class:`wsnlib.arm_model.ArmKinematics` (the ground truth of both nodes).
ArmTruth = ArmKinematics

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
    if not isinstance(trajectory, ArmTrajectory):
        raise ValueError(f"trajectory must be an ArmTrajectory, got {type(trajectory).__name__}")
    geometry = ArmGeometry.paper001() if geometry is None else geometry
    if not isinstance(geometry, ArmGeometry):
        raise ValueError(f"geometry must be an ArmGeometry, got {type(geometry).__name__}")
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

    return ArmKinematics(
        fs=trajectory.fs,
        time_s=trajectory.t.copy(),
        nodes=NODE_NAMES,
        quat=quat,
        gyr=np.stack([humerus[1], forearm[1]]),
        ang_acc=np.stack([humerus[2], forearm[2]]),
        pos=np.stack([p_h, p_e + p_fr]),
        vel=np.stack([v_h, v_e + v_fr]),
        acc_lin=np.stack([a_h, a_e + a_fr]),
        joint_pos=np.stack([np.zeros((n, 3)), p_e, p_w]),
        geometry=geometry,
        trajectory=trajectory,
    )
