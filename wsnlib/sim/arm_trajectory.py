"""Joint-angle trajectories of the two-segment arm (paper 001): the motion generators.

An :class:`ArmTrajectory` holds the four joint angles of :mod:`wsnlib.sim.arm` (heading,
pitch, axial rotation, elbow flexion; definitions in that module's docstring) with their
first and second time derivatives, in closed form (minimum-jerk and linear profiles) or from
a quintic spline (:func:`from_joint_angles`).  :func:`wsnlib.sim.arm.arm_kinematics` turns
one into the ground truth of both IMU nodes.

Sources
-------
* Paper 001 (De Vito et al.), Section II and IV: the "90° arm extension" with humerus and
  forearm moving jointly aligned (Figs. 1, 6–8) and the linearly growing humerus pitch
  (Fig. 2).
* Minimum-jerk profile: T. Flash and N. Hogan, "The coordination of arm movements: an
  experimentally confirmed mathematical model", J. Neurosci. 5(7):1688–1703, 1985:
  ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import make_interp_spline

from wsnlib._validation import as_float_array, check_nonnegative, check_positive

#: Joint-angle names, in the order of the last axis of :attr:`ArmTrajectory.angles`.
ANGLE_NAMES: tuple[str, str, str, str] = ("heading", "pitch", "axial", "elbow_flexion")


@dataclass(frozen=True)
class ArmTrajectory:
    """Joint angles of the arm over time, with their first and second time derivatives.

    Build one with :func:`arm_extension`, :func:`pitch_ramp` or :func:`from_joint_angles`
    rather than by hand (the constructor checks shapes, not that ``rates`` really is the
    derivative of ``angles``).

    Attributes
    ----------
    fs : float
        Sampling rate (Hz).
    t : numpy.ndarray, shape (T,)
        Sample times (s), ``t[k] = t[0] + k / fs``.
    angles : numpy.ndarray, shape (T, 4)
        Joint angles (rad) in the order of :data:`ANGLE_NAMES`: heading, pitch, axial,
        elbow flexion (defined in the docstring of :mod:`wsnlib.sim.arm`).
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

    @property
    def heading(self) -> np.ndarray:
        """Heading ψ (rad), shape (T,)."""
        return self.angles[:, 0]

    @property
    def pitch(self) -> np.ndarray:
        """Humerus pitch θ (rad), shape (T,)."""
        return self.angles[:, 1]

    @property
    def axial(self) -> np.ndarray:
        """Humeral axial rotation (rad), shape (T,)."""
        return self.angles[:, 2]

    @property
    def elbow_flexion(self) -> np.ndarray:
        """Elbow flexion β (rad), shape (T,)."""
        return self.angles[:, 3]


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


def _constant(value: float, n: int) -> np.ndarray:
    return np.full(n, float(value))


def arm_extension(
    fs: float = 50.0,
    duration_s: float = 6.0,
    start_s: float = 1.0,
    rise_s: float = 2.0,
    pitch_start_deg: float = -90.0,
    pitch_end_deg: float = 0.0,
    heading_deg: float = 0.0,
    axial_deg: float = 0.0,
) -> ArmTrajectory:
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
        Heading ψ of the arm (degrees, see :mod:`wsnlib.sim.arm`), constant.
    axial_deg : float
        Humeral axial rotation (degrees), constant.

    Returns
    -------
    ArmTrajectory
    """
    fs, t = _time_axis(fs, duration_s)
    check_nonnegative(start_s, "start_s")
    check_positive(rise_s, "rise_s")
    s, ds, dds = minimum_jerk(t, start_s, rise_s)
    span = np.radians(float(pitch_end_deg) - float(pitch_start_deg))
    n = t.size
    angles = np.stack(
        [
            _constant(np.radians(heading_deg), n),
            np.radians(float(pitch_start_deg)) + span * s,
            _constant(np.radians(axial_deg), n),
            np.zeros(n),
        ],
        axis=-1,
    )
    rates = np.stack([np.zeros(n), span * ds, np.zeros(n), np.zeros(n)], axis=-1)
    accelerations = np.stack([np.zeros(n), span * dds, np.zeros(n), np.zeros(n)], axis=-1)
    metadata = {
        "generator": "wsnlib.sim.arm.arm_extension",
        "fs": fs,
        "duration_s": float(duration_s),
        "start_s": float(start_s),
        "rise_s": float(rise_s),
        "pitch_start_deg": float(pitch_start_deg),
        "pitch_end_deg": float(pitch_end_deg),
        "heading_deg": float(heading_deg),
        "axial_deg": float(axial_deg),
    }
    return ArmTrajectory(fs, t, angles, rates, accelerations, metadata)


def pitch_ramp(
    fs: float = 50.0,
    duration_s: float = 60.0,
    pitch_start_deg: float = -60.0,
    pitch_end_deg: float = 60.0,
    heading_deg: float = 0.0,
    axial_deg: float = 0.0,
) -> ArmTrajectory:
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
    angles = np.stack(
        [
            _constant(np.radians(heading_deg), n),
            np.radians(float(pitch_start_deg)) + rate * t,
            _constant(np.radians(axial_deg), n),
            np.zeros(n),
        ],
        axis=-1,
    )
    rates = np.zeros((n, 4))
    rates[:, 1] = rate
    metadata = {
        "generator": "wsnlib.sim.arm.pitch_ramp",
        "fs": fs,
        "duration_s": float(duration_s),
        "pitch_start_deg": float(pitch_start_deg),
        "pitch_end_deg": float(pitch_end_deg),
        "heading_deg": float(heading_deg),
        "axial_deg": float(axial_deg),
    }
    return ArmTrajectory(fs, t, angles, rates, np.zeros((n, 4)), metadata)


def from_joint_angles(t, heading=0.0, pitch=0.0, axial=0.0, elbow_flexion=0.0) -> ArmTrajectory:
    """Trajectory from sampled joint angles; derivatives from a quintic interpolating spline.

    Parameters
    ----------
    t : array_like, shape (T,)
        Uniformly spaced sample times (s), strictly increasing, T ≥ 6; ``fs = 1 / Δt``.
    heading, pitch, axial, elbow_flexion : float or array_like, shape (T,)
        Joint angles (rad, see :mod:`wsnlib.sim.arm`); scalars are held constant.

    Returns
    -------
    ArmTrajectory
        Rates and accelerations are the first and second derivatives of a quintic (k = 5)
        interpolating B-spline through each sampled angle (not-a-knot ends).  They are
        accurate for angles that are smooth at the sampling rate; for an analytic motion,
        build :class:`ArmTrajectory` with closed-form derivatives instead.
    """
    t = as_float_array(t, "t")
    if t.ndim != 1 or t.size < 6:
        raise ValueError(f"t must be a 1-D array of at least 6 sample times, got shape {t.shape}")
    dt = np.diff(t)
    if np.any(dt <= 0.0):
        raise ValueError("t must be strictly increasing")
    step = (t[-1] - t[0]) / (t.size - 1)
    if np.max(np.abs(dt - step)) > 1e-6 * step:
        raise ValueError("t must be uniformly sampled (steps differ by more than 1e-6 relative)")
    columns = []
    for name, value in (
        ("heading", heading),
        ("pitch", pitch),
        ("axial", axial),
        ("elbow_flexion", elbow_flexion),
    ):
        arr = as_float_array(value, name, min_ndim=0)
        if arr.ndim == 0:
            arr = np.full(t.size, float(arr))
        if arr.shape != t.shape:
            raise ValueError(f"{name} must be a scalar or have shape {t.shape}, got {arr.shape}")
        columns.append(arr)
    angles = np.stack(columns, axis=-1)
    spline = make_interp_spline(t, angles, k=5, axis=0)
    rates = spline.derivative(1)(t)
    accelerations = spline.derivative(2)(t)
    metadata = {"generator": "wsnlib.sim.arm.from_joint_angles"}
    return ArmTrajectory(1.0 / step, t, angles, rates, accelerations, metadata)


def reach_and_flex(
    fs: float = 50.0,
    duration_s: float = 6.0,
    start_s: float = 1.0,
    rise_s: float = 2.5,
    pitch_end_deg: float = -20.0,
    heading_end_deg: float = 30.0,
    elbow_end_deg: float = 90.0,
) -> ArmTrajectory:
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
    check_positive(rise_s, "rise_s")
    s, ds, dds = minimum_jerk(t, start_s, rise_s)
    start = np.radians([0.0, -90.0, 0.0, 0.0])
    span = np.radians([float(heading_end_deg), float(pitch_end_deg) + 90.0, 0.0, float(elbow_end_deg)])
    angles = start + s[:, None] * span
    rates = ds[:, None] * span
    accelerations = dds[:, None] * span
    metadata = {
        "generator": "wsnlib.sim.arm.reach_and_flex",
        "fs": fs,
        "duration_s": float(duration_s),
        "start_s": float(start_s),
        "rise_s": float(rise_s),
        "pitch_end_deg": float(pitch_end_deg),
        "heading_end_deg": float(heading_end_deg),
        "elbow_end_deg": float(elbow_end_deg),
    }
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
