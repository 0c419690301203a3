"""Motions of paper 002's straight arm: pieces of constant-speed rotation about fixed axes.

:meth:`ArmMotion.kinematics` evaluates a motion for a user (or any two-segment
:class:`wsnlib.arm_model.ArmGeometry`) into the package's one kinematics type,
:class:`wsnlib.arm_model.ArmKinematics` (layout ``(node, T, C)``), which the radio, the
SunSPOT accelerometer, the Kinect model, the IMU simulator and the posture chain consume.
Shoulder frame (x right, y forward, z up; :mod:`wsnlib.sim.body`), metres, seconds, radians.

Postures (paper 002, Table 1)
-----------------------------
The arm is straight in every posture, so both targets lie on one ray from the shoulder, at
``d1`` (T1) and ``d2`` (T2) along the arm direction ``u``:

====  =============================  =========================================
P1    arm down                       u = (0, 0, −1)
P2    arm up                         u = (0, 0, +1)
P3    forward, horizontal            u = (0, +1, 0)
P4    sideways (right), horizontal   u = (+1, 0, 0)
P5    across the body, horizontal    u = (−sin 56.7°, cos 56.7°, 0)
====  =============================  =========================================

Table 1's P5 entries, T1 (−11, 11, 0) cm and T2 (−34, 21, 0) cm, are not collinear with the
shoulder (45° and 58° across the body; T2 is 40 cm from the shoulder, not 42.5 cm), so no
straight arm passes through both.  We take the straight arm that fits both points in least
squares, ``u ∝ d1·T1 + d2·T2`` (56.7° across the body), which misses the table by 3.2 cm
(T1) and 2.7 cm (T2).  :data:`TABLE1_POSITIONS_CM` keeps the table verbatim.

Segment (node) frames follow :mod:`wsnlib.arm_model`: body x along the segment (distal), body
z "dorsal" (up when the arm points forward palm down), body y = z × x.  A posture's
orientation is ``R_z(ψ) ⊗ q_ref ⊗ R_y(−θ)`` with heading ψ and pitch θ of ``u`` (ψ = 0 for
the vertical postures), i.e. each posture is P3 turned rigidly about the vertical (P4, P5) or
the lateral axis (P1, P2).  Moving the arm along the paper's movements reproduces exactly
these orientations at the end points (tested).

Movements (paper 002, Sec. 4.1 and Fig. 5)
------------------------------------------
Four transitional movements, each at constant angular speed (the paper's users were asked to
move "at constant speed", 2–4 s per movement), each a rotation of the straight arm about one
fixed axis through the shoulder:

* ``lower_P2_P3_P1``: from P2 down through P3 to P1 (180° about −x);
* ``horizontal_P4_P3_P5``: from P4 through P3 to P5 (146.7° about +z);
* ``raise_P1_P3``: from P1 up to P3 (90° about −x);
* ``horizontal_P3_P4``: from P3 to P4 (90° about −z).

:func:`arc` builds any constant-speed great-circle arc between two directions (SLERP of the
directions), optionally through a via-point (two great-circle pieces at the same angular
speed; the angular velocity jumps at the via-point unless both pieces share the axis, as in
the paper's movements).  Angular acceleration is zero inside every piece; the steps of the
angular velocity at the start and end of a constant-speed movement are idealised away (a
real arm needs some 100 ms to get up to speed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib import fixed_order
from wsnlib import quaternion as Q
from wsnlib._validation import as_float_array, check_nonnegative, check_positive
from wsnlib.arm_model import Q_REFERENCE, ArmGeometry, ArmKinematics
from wsnlib.io.sidecar import check_name
from wsnlib.sim.body import User
from wsnlib.testbed import MOVEMENTS, TRANSITION_LABEL, posture_direction


def _unit(v, name: str) -> np.ndarray:
    v = as_float_array(v, name)
    if v.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {v.shape}")
    norm = float(fixed_order.norm(v))
    if norm == 0.0:
        raise ValueError(f"{name} must not be the zero vector")
    return v / norm


def direction_orientation(direction) -> np.ndarray:
    """Segment orientation (4,) for an arm pointing along ``direction``, axial rotation 0.

    ``R_z(ψ) ⊗ q_ref ⊗ R_y(−θ)`` (the convention of :mod:`wsnlib.sim.arm`) with heading
    ``ψ = atan2(−u_x, u_y)`` (0 for a vertical arm) and pitch ``θ = asin(u_z)``; the segment's
    body x axis is rotated onto ``direction``.
    """
    u = _unit(direction, "direction")
    pitch = float(np.arcsin(np.clip(u[2], -1.0, 1.0)))
    horizontal = np.hypot(u[0], u[1])
    heading = 0.0 if horizontal < 1e-12 else float(np.arctan2(-u[0], u[1]))
    q_heading = Q.from_axis_angle([0.0, 0.0, 1.0], heading)
    q_pitch = Q.from_axis_angle([0.0, 1.0, 0.0], -pitch)
    return Q.multiply(Q.multiply(q_heading, Q_REFERENCE), q_pitch)


def posture_orientation(posture: str) -> np.ndarray:
    """Orientation (4,) of both segments in ``posture`` (:func:`direction_orientation`)."""
    return direction_orientation(posture_direction(posture))


@dataclass(frozen=True, eq=False)
class ArmMotion:
    """Motion of the straight right arm: consecutive pieces, each a rotation at constant
    angular speed about a fixed axis through the shoulder (speed 0 = holding still).

    Build with :func:`hold`, :func:`arc`, :func:`movement`, :func:`transition` and
    :func:`concatenate`; evaluate with :meth:`kinematics` or :meth:`sample`.

    Attributes (one entry per piece)
    --------------------------------
    start_s : numpy.ndarray (P,)
        Piece start times (s), from 0; piece ``i`` lasts ``duration_s[i]``.
    duration_s : numpy.ndarray (P,)
    quat_start : numpy.ndarray (P, 4)
        Segment orientation at the start of the piece (both segments: the arm is straight).
    axis : numpy.ndarray (P, 3)
        Unit rotation axis (shoulder frame).
    speed : numpy.ndarray (P,)
        Angular speed (rad/s), ≥ 0.
    labels : tuple of str (P,)
        Label of each piece (posture name, movement label or :data:`TRANSITION_LABEL`).
    """

    start_s: np.ndarray
    duration_s: np.ndarray
    quat_start: np.ndarray
    axis: np.ndarray
    speed: np.ndarray
    labels: tuple[str, ...]

    def __post_init__(self):
        n = len(self.labels)
        if n == 0:
            raise ValueError("an ArmMotion needs at least one piece")
        for name, shape in (("start_s", (n,)), ("duration_s", (n,)), ("quat_start", (n, 4)), ("axis", (n, 3)),
                            ("speed", (n,))):
            arr = as_float_array(getattr(self, name), name)
            if arr.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if np.any(self.duration_s <= 0.0) or np.any(self.speed < 0.0):
            raise ValueError("durations must be > 0 and speeds >= 0")
        for label in self.labels:
            check_name(label, "labels")
        object.__setattr__(self, "labels", tuple(self.labels))

    @property
    def total_duration_s(self) -> float:
        """End time (s) of the last piece."""
        return float(self.start_s[-1] + self.duration_s[-1])

    @property
    def quat_end(self) -> np.ndarray:
        """Orientation (4,) at the end of the motion."""
        angle = self.speed[-1] * self.duration_s[-1]
        return Q.multiply(Q.from_axis_angle(self.axis[-1], angle), self.quat_start[-1])

    def _piece_at(self, t: np.ndarray) -> np.ndarray:
        idx = np.searchsorted(self.start_s, t, side="right") - 1
        return np.clip(idx, 0, len(self.labels) - 1)

    def kinematics(self, time_s, user, *, fs: float | None = None) -> ArmKinematics:
        """Exact state of both segments and devices at times ``time_s`` (s).

        Times before 0 or after the end hold the first/last orientation (at rest).

        Parameters
        ----------
        time_s : array_like, shape (T,)
            Times (s).
        user : User or wsnlib.arm_model.ArmGeometry
            Whose arm: a :class:`User` (its :attr:`User.geometry`, with the target
            distances from the shoulder taken as stored) or a two-segment geometry (its
            devices must be on the segment axes: the arm is straight).
        fs : float, optional
            Sampling rate (Hz) to record in the result, for uniformly spaced times.

        Returns
        -------
        wsnlib.arm_model.ArmKinematics
            Layout ``(node, T, C)``: both segments share one orientation (the arm is
            straight); devices at ``d_s · u`` with ``d_s`` their distance from the shoulder
            and ``u`` the arm direction; velocity ``ω × r`` and acceleration ``ω × (ω × r)``
            (angular acceleration zero inside constant-speed pieces; the steps between
            pieces are impulses, not represented); joints at 0, ``L1 · u``, ``(L1 + L2) · u``.
            ``label`` holds the label of the piece being executed.
        """
        t = as_float_array(time_s, "time_s")
        if t.ndim != 1:
            raise ValueError(f"time_s must be 1-D, got shape {t.shape}")
        if isinstance(user, User):
            geometry = user.geometry
            distances = np.asarray(user.target_distances_m)
        elif isinstance(user, ArmGeometry):
            geometry = user
            if geometry.n_segments != 2 or np.any(np.asarray(geometry.device_normal_offsets_m) != 0.0):
                raise ValueError("user must be a User or a two-segment ArmGeometry with devices on the axes")
            first, second = geometry.device_offsets_m
            distances = np.array([first, geometry.segment_lengths_m[0] + second])
        else:
            raise ValueError(f"user must be a User or an ArmGeometry, got {type(user).__name__}")
        idx = self._piece_at(t)
        local = np.clip(t - self.start_s[idx], 0.0, self.duration_s[idx])
        moving = (t >= self.start_s[idx]) & (t < self.start_s[idx] + self.duration_s[idx])
        axis = self.axis[idx]
        speed = self.speed[idx]
        quat = Q.multiply(Q.from_axis_angle(axis, speed * local), self.quat_start[idx])
        quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
        direction = Q.rotate(quat, np.array([1.0, 0.0, 0.0]))
        omega = np.where(moving[:, None], speed[:, None] * axis, 0.0)
        r = direction[None, :, :] * distances[:, None, None]  # (2, T, 3)
        w = np.broadcast_to(omega[None, :, :], r.shape)
        velocity = np.cross(w, r)
        acceleration = np.cross(w, velocity)  # α = 0 within pieces
        quat2 = np.repeat(quat[None, :, :], 2, axis=0)
        upper, fore = geometry.segment_lengths_m
        joints = np.stack([np.zeros_like(direction), upper * direction, (upper + fore) * direction])
        return ArmKinematics(time_s=t.copy(), quat=quat2, gyr=Q.rotate_inverse(quat2, w), ang_acc=np.zeros_like(r),
                             pos=r, vel=velocity, acc_lin=acceleration, joint_pos=joints, geometry=geometry, fs=fs,
                             label=np.array(self.labels, dtype=object)[idx], trajectory=self)

    def sample(self, user, fs: float = 30.0) -> ArmKinematics:
        """:meth:`kinematics` at ``k / fs`` for ``k = 0 … round(total · fs)`` (both ends included)."""
        fs = check_positive(fs, "fs")
        n = int(round(self.total_duration_s * fs)) + 1
        return self.kinematics(np.arange(n) / fs, user, fs=fs)


def _single_piece(duration_s, quat_start, axis, speed, label) -> ArmMotion:
    return ArmMotion(start_s=np.zeros(1), duration_s=np.array([check_positive(duration_s, "duration_s")]),
                     quat_start=np.asarray(quat_start, dtype=float)[None], axis=np.asarray(axis, dtype=float)[None],
                     speed=np.array([speed]), labels=(label,))


def hold(posture, duration_s: float, *, label: str | None = None) -> ArmMotion:
    """Hold the arm still for ``duration_s`` seconds.

    Parameters
    ----------
    posture : str, array_like (3,) or array_like (4,)
        A posture name, an arm direction or an orientation quaternion (e.g. the end of a
        previous motion, :attr:`ArmMotion.quat_end`), as in :func:`transition`.
    duration_s : float
    label : str, optional
        Default: the posture name, or ``"hold"`` for a direction or a quaternion.
    """
    if label is None:
        label = posture if isinstance(posture, str) else "hold"
    return _single_piece(duration_s, _as_orientation(posture), [0.0, 0.0, 1.0], 0.0, label)


def arc(direction_start, direction_end, duration_s: float, *, via=None, label: str = "arc") -> ArmMotion:
    """Constant-angular-speed great-circle arc of the straight arm (SLERP of directions).

    Parameters
    ----------
    direction_start, direction_end : array_like (3,) or posture name
        Arm directions (normalised here).
    duration_s : float
        Duration of the whole arc (s).
    via : array_like (3,) or posture name, optional
        Pass through this direction: two great-circle pieces with the same angular speed,
        times split in proportion to their angles.  Needed when start and end are (nearly)
        opposite, where the great circle is not defined.
    label : str
        Label of every piece.

    Returns
    -------
    ArmMotion
        With angular speed ``(total angle) / duration_s``.
    """

    def _dir(v, name):
        return posture_direction(v) if isinstance(v, str) else _unit(v, name)

    points = [_dir(direction_start, "direction_start")]
    if via is not None:
        points.append(_dir(via, "via"))
    points.append(_dir(direction_end, "direction_end"))
    duration = check_positive(duration_s, "duration_s")
    angles, axes = [], []
    for a, b in zip(points[:-1], points[1:], strict=True):
        angle = float(np.arccos(np.clip(fixed_order.dot(a, b), -1.0, 1.0)))
        cross = np.cross(a, b)
        if angle > np.pi - 1e-3:
            raise ValueError("start and end of an arc piece are opposite: give a via direction")
        if angle < 1e-9:
            raise ValueError("an arc piece has zero length (equal directions); use hold()")
        angles.append(angle)
        axes.append(cross / fixed_order.norm(cross))
    speed = sum(angles) / duration
    q = direction_orientation(points[0])
    starts, quats = [], []
    t = 0.0
    for angle, axis in zip(angles, axes, strict=True):
        starts.append(t)
        quats.append(q)
        q = Q.multiply(Q.from_axis_angle(axis, angle), q)
        t += angle / speed
    return ArmMotion(start_s=np.array(starts), duration_s=np.array(angles) / speed, quat_start=np.array(quats),
                     axis=np.array(axes), speed=np.full(len(angles), speed), labels=(label,) * len(angles))


def movement(name: str, duration_s: float, *, label: str | None = None) -> ArmMotion:
    """One of the paper's transitional movements (:data:`MOVEMENTS`) at constant speed.

    Parameters
    ----------
    name : str
        Key of :data:`MOVEMENTS`, e.g. ``"lower_P2_P3_P1"``.
    duration_s : float
        Duration (s); the paper's users took 2–4 s.
    label : str, optional
        Default ``name``.
    """
    try:
        postures = MOVEMENTS[name]
    except KeyError:
        raise ValueError(f"movement must be one of {list(MOVEMENTS)}, got {name!r}") from None
    via = postures[1] if len(postures) == 3 else None
    return arc(postures[0], postures[-1], duration_s, via=via, label=name if label is None else label)


def transition(posture_from, posture_to, duration_s: float, *, label: str = TRANSITION_LABEL) -> ArmMotion:
    """Move between postures at constant angular speed, arriving in ``posture_to``'s orientation.

    ``posture_from`` / ``posture_to``: a posture name (its :func:`posture_orientation`), an
    arm direction (3,) (:func:`direction_orientation`) or an orientation quaternion (4,).
    One rotation about the fixed axis of ``q_to ⊗ q_from*`` (SLERP of the orientations,
    shorter way round), so the arm arrives in ``q_to`` exactly, axial twist included; equal
    orientations give a hold.  Used for the unlabelled moves between the recorded postures and
    movements of a session.
    """
    q0 = Q.normalize(_as_orientation(posture_from))
    q1 = Q.normalize(_as_orientation(posture_to))
    rel = Q.canonical(Q.multiply(q1, Q.conjugate(q0)))
    vec_norm = float(fixed_order.norm(rel[1:]))
    angle = 2.0 * float(np.arctan2(vec_norm, rel[0]))
    duration = check_positive(duration_s, "duration_s")
    if angle < 1e-9:
        return _single_piece(duration, q0, [0.0, 0.0, 1.0], 0.0, label)
    return _single_piece(duration, q0, rel[1:] / vec_norm, angle / duration, label)


def _as_orientation(value) -> np.ndarray:
    if isinstance(value, str):
        return posture_orientation(value)
    arr = as_float_array(value, "orientation")
    if arr.shape == (4,):
        return Q.normalize(arr)
    if arr.shape == (3,):
        return direction_orientation(arr)
    raise ValueError(f"expected a posture name, a direction (3,) or a quaternion (4,), got shape {arr.shape}")


def concatenate(motions) -> ArmMotion:
    """Motions one after the other; each must start in the orientation where the previous ended."""
    motions = list(motions)
    if not motions:
        raise ValueError("concatenate needs at least one motion")
    starts, durations, quats, axes, speeds, labels = [], [], [], [], [], []
    offset = 0.0
    for i, m in enumerate(motions):
        if not isinstance(m, ArmMotion):
            raise ValueError(f"motions[{i}] must be an ArmMotion, got {type(m).__name__}")
        if i > 0:
            gap = float(Q.angle_between(motions[i - 1].quat_end, m.quat_start[0]))
            if gap > 1e-6:
                raise ValueError(f"motions[{i}] starts {np.degrees(gap):.3g}° away from where motions[{i - 1}] ends")
        starts.append(m.start_s + offset)
        durations.append(m.duration_s)
        quats.append(m.quat_start)
        axes.append(m.axis)
        speeds.append(m.speed)
        labels.extend(m.labels)
        offset += m.total_duration_s
    return ArmMotion(start_s=np.concatenate(starts), duration_s=np.concatenate(durations),
                     quat_start=np.concatenate(quats), axis=np.concatenate(axes), speed=np.concatenate(speeds),
                     labels=tuple(labels))


def jittered_direction(posture: str, sigma_deg: float, rng: np.random.Generator) -> np.ndarray:
    """``posture``'s direction turned by a small random rotation (rotation vector ~ N(0, σ²) per axis).

    Models a user replicating a posture within a few degrees (paper 002, footnote 8: "slight
    variations of the kept arm postures are unavoidable").
    """
    sigma = np.radians(check_nonnegative(sigma_deg, "sigma_deg"))
    rot = Q.from_rotation_vector(rng.normal(0.0, sigma, 3))
    return Q.rotate(rot, posture_direction(posture))
