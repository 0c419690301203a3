"""Realistic disturbances for the IMU simulator: magnetic disturbance and acceleration-rich motion.

The clean simulator (:mod:`wsnlib.sim.imu`) gives TRIAD a single-frame error of a fraction of a
degree, while on BROAD's real recordings TRIAD is off by 10° (median) to 60–110° (90th
percentile).  Two things the clean simulator leaves out cause that gap, and this module adds
them to :func:`wsnlib.sim.imu.simulate_imu` through its ``disturbance`` argument:

Acceleration-rich motion (m/s²)
    A translation of the whole body (shoulder) — walking, shaking, a tapping hand — adds a
    linear acceleration that the accelerometer cannot tell from gravity, so TRIAD tilts.
    :class:`~wsnlib.sim.arm.ArmTrajectory` has the shoulder fixed at the origin, so the
    translation is not part of the arm kinematics: :func:`translation_motion` draws it as
    band-limited Gaussian noise in the earth frame (common to both nodes, which ride on the
    same body) and the hook adds ``q* ⊗ a_translation ⊗ q`` to the specific force.  The
    orientation, the gyroscope and the ground truth are unchanged (a pure translation does not
    rotate); the displacement moves the node positions used by the dipole field below.  Each
    trial's RMS acceleration is drawn log-normally, because BROAD's trials range from 0.9 m/s²
    (slow rotation) to 19 m/s² (fast translation): one level for all trials cannot reproduce
    both the median and the tail of TRIAD's error.

Magnetic disturbance (µT)
    * **Hard iron near the body**: a constant offset vector in the body frame of each node
      (a magnet or steel part attached to the sensor or the limb — BROAD's "attached magnet"
      trials), random direction, log-normal magnitude.
    * **Soft iron**: ``mag = S · field`` with ``S = I + E``, ``E`` symmetric with
      independent ``N(0, soft_iron_std²)`` entries (residual of an imperfect calibration).
    * **Ferrous objects passing**: a magnetic dipole moving on a straight line past the body
      (BROAD's "stationary magnet" trials turn it around: the sensor passes the magnet), its
      field ``B(r) = µ0/(4π) · (3 (m·r̂) r̂ − m) / |r|³`` evaluated in the earth frame at each
      node's position and rotated into the body frame — a time-local disturbance.

Every random draw comes from the Generator passed to :func:`draw_disturbance`, in a fixed
order and shape whatever the parameter values (zero levels still consume their draws), so a
calibration grid over the levels uses common random numbers and the same seed always gives
the same signals.

Calibration against BROAD lives in :mod:`wsnlib.sim.disturbance.calibration`
(:data:`~wsnlib.sim.disturbance.calibration.UNDISTURBED_BROAD`,
:data:`~wsnlib.sim.disturbance.calibration.DISTURBED_BROAD`).

Sources
-------
* D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD—A Benchmark for Robust Inertial
  Orientation Estimation", Data 6(7):72, 2021 (CC BY 4.0): the trial groups (undisturbed
  rotation/translation; disturbed by tapping, phone vibration, a stationary magnet, a magnet
  attached at 2–5 cm), and the recordings from which the numbers below are measured.
* Dipole field and µ0/(4π) = 10⁻⁷ T·m/A: J. D. Jackson, *Classical Electrodynamics*, 3rd ed.,
  Section 5.6 (field of a localized current distribution far away: a magnetic dipole).
* Hard- and soft-iron model: the standard magnetometer error model (offset vector and a
  symmetric 3×3 matrix in the sensor frame), as in Freescale/NXP application note AN4246,
  "Calibrating an eCompass in the Presence of Hard- and Soft-Iron Interference" (T. Ozyagcilar).
  Recalled, not re-read for this module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from wsnlib import quaternion as Q
from wsnlib._validation import check_nonnegative, check_positive

#: µ0 / (4π) in µT·m³/(A·m²): B (µT) = 0.1 · (3 (m·r̂) r̂ − m) / r³ with m in A·m², r in m.
DIPOLE_CONSTANT_UT_M3_PER_AM2 = 1e-7 * 1e6

#: Closest distance (m) at which the dipole field is evaluated; nearer, the point-dipole model
#: (and the sensor's range) no longer holds.
DIPOLE_MIN_DISTANCE_M = 0.05


@dataclass(frozen=True)
class Disturbance:
    """Levels of the magnetic disturbance and of the acceleration-rich motion.

    All levels default to 0 (no disturbance); :data:`UNDISTURBED_BROAD` and
    :data:`DISTURBED_BROAD` hold the calibrated settings.

    Parameters
    ----------
    translation_acc_rms_m_s2 : float
        Median over trials of the RMS (over time) of the norm of the body's translational
        acceleration (m/s², earth frame).
    translation_acc_log_sd : float
        Standard deviation of the natural log of that RMS across trials (log-normal spread).
    translation_band_hz : tuple of float
        ``(low, high)`` band (Hz) of the translation: flat spectrum inside, nothing outside.
        Default (0.5, 4.0), *assumed*: voluntary body and arm movement lies mostly below
        ~5 Hz (tremor and tapping above it are left out); the low edge keeps the displacement
        bounded (≈ 4 cm RMS for 1.4 m/s² RMS over 8 s).
    hard_iron_ut : float
        Median magnitude (µT) of the constant body-frame offset of each node.
    hard_iron_log_sd : float
        Log-normal spread of that magnitude across runs and nodes.
    soft_iron_std : float
        Standard deviation (dimensionless) of the entries of ``S − I``.
    dipole_moment_am2 : float
        Magnetic moment (A·m²) of the ferrous object passing the body; 0 turns it off.  For
        scale: 1 A·m² gives 100 µT at 0.1 m and 0.8 µT at 0.5 m beside the dipole (twice
        that on its axis).
    dipole_distance_m : tuple of float
        Range (m) of the closest-approach distance to the centre of the two nodes, drawn
        uniformly per trial.
    dipole_speed_m_s : float
        Speed (m/s) of the object along its straight path (walking pace by default, 1 m/s).
    """

    translation_acc_rms_m_s2: float = 0.0
    translation_acc_log_sd: float = 0.0
    translation_band_hz: tuple[float, float] = (0.5, 4.0)
    hard_iron_ut: float = 0.0
    hard_iron_log_sd: float = 0.0
    soft_iron_std: float = 0.0
    dipole_moment_am2: float = 0.0
    dipole_distance_m: tuple[float, float] = (0.1, 0.5)
    dipole_speed_m_s: float = 1.0

    def __post_init__(self):
        for name in ("translation_acc_rms_m_s2", "translation_acc_log_sd", "hard_iron_ut", "hard_iron_log_sd",
                     "soft_iron_std", "dipole_moment_am2"):
            object.__setattr__(self, name, check_nonnegative(getattr(self, name), name))
        object.__setattr__(self, "dipole_speed_m_s", check_positive(self.dipole_speed_m_s, "dipole_speed_m_s"))
        for name in ("translation_band_hz", "dipole_distance_m"):
            value = tuple(float(v) for v in np.ravel(getattr(self, name)))
            if len(value) != 2 or not (0.0 < value[0] < value[1]) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be two finite numbers 0 < low < high, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)
        if self.dipole_distance_m[0] < DIPOLE_MIN_DISTANCE_M:
            raise ValueError(f"dipole_distance_m must start at {DIPOLE_MIN_DISTANCE_M} m or more, "
                             f"got {self.dipole_distance_m!r}")

    @property
    def is_off(self) -> bool:
        """True when every level is zero (the simulator then gives its clean readings)."""
        return (self.translation_acc_rms_m_s2 == 0.0 and self.hard_iron_ut == 0.0
                and self.soft_iron_std == 0.0 and self.dipole_moment_am2 == 0.0)


class DisturbanceSignals(NamedTuple):
    """One draw of the disturbance for a batch of runs; ``B`` = batch shape, ``N`` nodes, ``T`` samples.

    Attributes
    ----------
    translation_acc_enu : numpy.ndarray, shape (*B, 1, T, 3)
        Translational acceleration of the body (m/s², earth frame), shared by the nodes.
    translation_pos_enu : numpy.ndarray, shape (*B, 1, T, 3)
        The corresponding displacement (m, earth frame), zero mean.
    dipole_field_enu : numpy.ndarray, shape (*B, N, T, 3)
        Field of the passing object at each node (µT, earth frame).
    hard_iron_body : numpy.ndarray, shape (*B, N, 1, 3)
        Constant offset (µT, body frame).
    soft_iron : numpy.ndarray, shape (*B, N, 1, 3, 3)
        Matrix ``S`` (body frame) applied to the field before the offset.
    """

    translation_acc_enu: np.ndarray
    translation_pos_enu: np.ndarray
    dipole_field_enu: np.ndarray
    hard_iron_body: np.ndarray
    soft_iron: np.ndarray


def translation_motion(n_samples: int, fs: float, rms_m_s2, band_hz=(0.5, 4.0), *,
                       rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Band-limited random translation: acceleration and displacement, earth frame.

    Parameters
    ----------
    n_samples : int
        T, ≥ 2.
    fs : float
        Sampling rate (Hz).
    rms_m_s2 : float or array_like, shape B
        RMS over time of the acceleration's norm (m/s²), one per run; the output is scaled
        to it exactly.
    band_hz : tuple of float
        Pass band (Hz); at least one frequency bin of the record must fall inside it.
    rng : numpy.random.Generator
        Draws ``(*B, 3, T//2 + 1)`` complex Gaussian coefficients (real and imaginary parts).

    Returns
    -------
    acc, pos : numpy.ndarray, shape (*B, T, 3)
        Acceleration (m/s²) and displacement (m, ``pos'' = acc`` on the record's circle of
        frequencies, zero mean).
    """
    if isinstance(n_samples, bool) or not isinstance(n_samples, int | np.integer) or n_samples < 2:
        raise ValueError(f"n_samples must be an integer >= 2, got {n_samples!r}")
    fs = check_positive(fs, "fs")
    rms = np.asarray(rms_m_s2, dtype=float)
    if not np.all(np.isfinite(rms)) or np.any(rms < 0.0):
        raise ValueError("rms_m_s2 must be finite and non-negative")
    low, high = (float(v) for v in band_hz)
    freq = np.fft.rfftfreq(n_samples, 1.0 / fs)
    inside = (freq >= low) & (freq <= high)
    if not inside.any():
        raise ValueError(f"band_hz {band_hz!r} holds no frequency of a {n_samples}-sample record at {fs} Hz")
    shape = rms.shape + (3, freq.size)
    coeff = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * inside
    acc = np.moveaxis(np.fft.irfft(coeff, n=n_samples, axis=-1), -2, -1)
    omega2 = (2.0 * np.pi * np.where(inside, freq, 1.0)) ** 2
    pos = np.moveaxis(np.fft.irfft(-coeff / omega2, n=n_samples, axis=-1), -2, -1)
    scale = rms / np.sqrt(np.mean(np.sum(acc**2, axis=-1), axis=-1))
    return acc * scale[..., None, None], pos * scale[..., None, None]


def dipole_field_ut(moment_am2, position_m) -> np.ndarray:
    """Field of a point magnetic dipole (µT) at ``position_m`` relative to it.

    Parameters
    ----------
    moment_am2 : array_like, shape (..., 3)
        Dipole moment (A·m²).
    position_m : array_like, shape (..., 3)
        Where the field is evaluated, relative to the dipole (m); distances below
        :data:`DIPOLE_MIN_DISTANCE_M` are clipped to it.

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        ``0.1 · (3 (m·r̂) r̂ − m) / r³`` µT (Jackson eq. 5.56).
    """
    m = np.asarray(moment_am2, dtype=float)
    r = np.asarray(position_m, dtype=float)
    dist = np.linalg.norm(r, axis=-1, keepdims=True)
    unit = r / np.where(dist > 0.0, dist, 1.0)
    dist = np.maximum(dist, DIPOLE_MIN_DISTANCE_M)
    m_dot_r = np.sum(m * unit, axis=-1, keepdims=True)
    return DIPOLE_CONSTANT_UT_M3_PER_AM2 * (3.0 * m_dot_r * unit - m) / dist**3


def _random_unit(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    v = rng.standard_normal(shape + (3,))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def draw_disturbance(disturbance: Disturbance, node_pos_enu, fs: float, batch: tuple[int, ...] = (), *,
                     rng: np.random.Generator) -> DisturbanceSignals:
    """Draw one realisation of the disturbance per run.

    Parameters
    ----------
    disturbance : Disturbance
    node_pos_enu : array_like, shape (N, T, 3)
        Node positions without the translation (m, earth frame), e.g.
        :attr:`wsnlib.sim.arm.ArmTruth.pos`.
    fs : float
        Sampling rate (Hz).
    batch : tuple of int
        Batch shape ``B`` (``()`` or ``(n_runs,)``).
    rng : numpy.random.Generator
        Source of every draw, in a fixed order and shape whatever the levels.

    Returns
    -------
    DisturbanceSignals
    """
    if not isinstance(disturbance, Disturbance):
        raise ValueError(f"disturbance must be a Disturbance, got {type(disturbance).__name__}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    pos = np.asarray(node_pos_enu, dtype=float)
    if pos.ndim != 3 or pos.shape[-1] != 3:
        raise ValueError(f"node_pos_enu must have shape (N, T, 3), got {pos.shape}")
    n_nodes, n_samples = pos.shape[:2]
    d = disturbance

    # Translation: one log-normal level per run, shared by the nodes.
    level = d.translation_acc_rms_m_s2 * np.exp(d.translation_acc_log_sd * rng.standard_normal(batch))
    acc, disp = translation_motion(n_samples, fs, level, d.translation_band_hz, rng=rng)
    acc, disp = acc[..., None, :, :], disp[..., None, :, :]

    # Hard iron: random direction, log-normal magnitude per run and node.
    direction = _random_unit(rng, batch + (n_nodes, 1))
    magnitude = d.hard_iron_ut * np.exp(d.hard_iron_log_sd * rng.standard_normal(batch + (n_nodes, 1, 1)))
    hard_iron = direction * magnitude

    # Soft iron: S = I + E, E symmetric.
    upper = rng.standard_normal(batch + (n_nodes, 1, 3, 3))
    sym = np.triu(upper) + np.swapaxes(np.triu(upper, 1), -1, -2)
    soft_iron = np.eye(3) + d.soft_iron_std * sym

    # A dipole passing the body on a straight line, closest to the nodes' centre at t0.
    centre = pos.mean(axis=(0, 1))
    towards = _random_unit(rng, batch)
    along = _random_unit(rng, batch)
    along = along - np.sum(along * towards, axis=-1, keepdims=True) * towards
    along_norm = np.linalg.norm(along, axis=-1, keepdims=True)
    along = along / np.where(along_norm > 1e-9, along_norm, 1.0)
    low, high = d.dipole_distance_m
    distance = rng.uniform(low, high, batch + (1,))
    t_closest = rng.uniform(0.0, n_samples / fs, batch + (1,))
    moment = d.dipole_moment_am2 * _random_unit(rng, batch)
    time_s = np.arange(n_samples) / fs
    path = (centre + distance * towards)[..., None, :] + (
        d.dipole_speed_m_s * (time_s - t_closest)[..., :, None] * along[..., None, :])       # (*B, T, 3)
    relative = pos + disp - path[..., None, :, :]                                            # (*B, N, T, 3)
    field = dipole_field_ut(moment[..., None, None, :], relative)
    return DisturbanceSignals(acc, disp, field, hard_iron, soft_iron)


def apply_disturbance(quat, acc, mag, signals: DisturbanceSignals) -> tuple[np.ndarray, np.ndarray]:
    """Add a drawn disturbance to exact body-frame readings.

    Parameters
    ----------
    quat : array_like, shape (N, T, 4)
        True orientations (body → ENU).
    acc, mag : array_like, shape (*B, N, T, 3)
        Specific force (m/s²) and magnetic field (µT), body frame, before sensor errors.
    signals : DisturbanceSignals

    Returns
    -------
    acc, mag : numpy.ndarray, shape (*B, N, T, 3)
        ``acc + q* ⊗ a_translation ⊗ q`` and ``S · (mag + q* ⊗ B_dipole ⊗ q) + h``.
    """
    q = np.asarray(quat, dtype=float)
    acc_out = acc + Q.rotate_inverse(q, signals.translation_acc_enu)
    field = mag + Q.rotate_inverse(q, signals.dipole_field_enu)
    mag_out = np.einsum("...ij,...j->...i", signals.soft_iron, field) + signals.hard_iron_body
    return acc_out, mag_out
