"""Simulated IMU readings of the paper's nodes: ideal, noisy and quantised, and whole recordings.

The sensor's numbers (L3GD20 gyroscope, LSM303DLHC accelerometer and magnetometer) and their
sources are in :class:`ImuSpec` (:mod:`wsnlib.sim.imu_spec`, re-exported here).

Measurement model
-----------------
For each node (body frame ``B``, orientation ``q``), with ideal readings from
:func:`ideal_imu`::

    gyr = ω_B + b_g + w_g             b_g = b_0 + random walk, w_g white
    acc = q* ⊗ (a_lin + [0, 0, g]) ⊗ q + b_a + w_a
    mag = q* ⊗ m_E ⊗ q + b_m + w_m

then each axis is saturated at ± full scale and quantised to the sensor resolution
(rounded to the nearest code; codes also clipped to the signed ``bits`` range).  White noise
has per-sample standard deviation ``density · √B`` with noise bandwidth ``B = fs / 2``
unless :attr:`ImuSpec.noise_bandwidth_hz` is set (assumption: the on-chip filters are set
near the Nyquist frequency of the 50 Hz stream).  No scale-factor, misalignment, cross-axis
or soft-iron errors are modelled (assumed calibrated away), unless a
:class:`~wsnlib.sim.disturbance.Disturbance` is passed to :func:`simulate_imu` (hard/soft iron,
passing ferrous objects, body translation; calibrated against BROAD).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib._validation import as_float_array, check_positive
from wsnlib.arm_model import ArmGeometry, ArmKinematics
from wsnlib.io.recording import Recording
from wsnlib.sim.arm import ArmTrajectory, arm_kinematics
from wsnlib.sim.disturbance.model import Disturbance, apply_disturbance, draw_disturbance
from wsnlib.sim.imu_spec import UT_PER_GAUSS, ImuSpec  # noqa: F401  (UT_PER_GAUSS: kept importable from here)


class ImuSamples(NamedTuple):
    """Simulated readings; each field has shape ``(..., N_nodes, T, 3)``.

    ``gyr`` in rad/s, ``acc`` in m/s² (specific force), ``mag`` in µT, all body frame.
    Unpacks as ``gyr, acc, mag = simulate_imu(...)``.
    """

    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray


def ideal_imu(
    truth: ArmKinematics,
    *,
    gravity: float = frames.STANDARD_GRAVITY,
    mag_field_enu=None,
) -> ImuSamples:
    """Exact, continuous-valued readings of the nodes (no noise, bias or quantisation).

    Parameters
    ----------
    truth : wsnlib.arm_model.ArmKinematics
        From :func:`wsnlib.sim.arm.arm_kinematics` or any other motion generator.
    gravity : float
        Gravity magnitude (m/s²); the accelerometer reads ``+gravity`` along earth z at rest.
    mag_field_enu : array_like, shape (3,), optional
        Earth magnetic field in ENU (µT); default :func:`wsnlib.frames.magnetic_field_enu`.

    Returns
    -------
    ImuSamples
        ``gyr = ω_B``; ``acc = q* ⊗ (a_lin + [0, 0, g]) ⊗ q``; ``mag = q* ⊗ m_E ⊗ q``;
        each ``(N_nodes, T, 3)``.
    """
    if not isinstance(truth, ArmKinematics):
        raise ValueError(f"truth must be an ArmKinematics, got {type(truth).__name__}")
    gravity = check_positive(gravity, "gravity")
    if mag_field_enu is None:
        mag_field_enu = frames.magnetic_field_enu()
    mag_field = as_float_array(mag_field_enu, "mag_field_enu")
    if mag_field.shape != (3,):
        raise ValueError(f"mag_field_enu must have shape (3,), got {mag_field.shape}")
    acc = truth.specific_force(gravity)
    mag = Q.rotate_inverse(truth.quat, np.broadcast_to(mag_field, truth.acc_lin.shape))
    return ImuSamples(truth.gyr.copy(), acc, mag)


def _digitise(x: np.ndarray, step, full_scale: float, bits: int, spec: ImuSpec) -> np.ndarray:
    """Saturate at ±full_scale, then round to the nearest code (codes clipped to ``bits``)."""
    if spec.saturate:
        x = np.clip(x, -full_scale, full_scale)
    if spec.quantize:
        code = np.rint(x / step)
        code = np.clip(code, -(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
        if spec.saturate:
            # Rounding ±full_scale may land one code beyond it; stay inside the range.
            limit = np.floor(full_scale / np.asarray(step) + 1e-9)
            code = np.clip(code, -limit, limit)
        x = code * step
    return x


def simulate_imu(
    truth: ArmKinematics,
    spec: ImuSpec | None = None,
    *,
    rng: np.random.Generator,
    n_runs: int | None = None,
    gravity: float = frames.STANDARD_GRAVITY,
    mag_field_enu=None,
    disturbance: Disturbance | None = None,
) -> ImuSamples:
    """Simulate gyroscope, accelerometer and magnetometer readings of every node.

    Parameters
    ----------
    truth : wsnlib.arm_model.ArmKinematics
        Ground truth from :func:`wsnlib.sim.arm.arm_kinematics` (or any generator that
        records ``fs``, e.g. :meth:`wsnlib.sim.arm_motion.ArmMotion.sample`).
    spec : ImuSpec, optional
        Sensor parameters; default :class:`ImuSpec()` (the paper's sensors).
    rng : numpy.random.Generator
        Source of every random draw.  Draws happen in a fixed order and shape whatever the
        spec (zero standard deviations still consume their draws), so the same seed gives
        the same noise for a changed noise level.
    n_runs : int, optional
        Number of independent Monte Carlo runs; adds a leading axis of that length.  Each
        run has its own biases and noise.
    gravity : float
        Gravity magnitude (m/s²).
    mag_field_enu : array_like, shape (3,), optional
        Earth magnetic field (µT, ENU); default :func:`wsnlib.frames.magnetic_field_enu`.
    disturbance : Disturbance, optional
        Magnetic disturbance and body translation (:mod:`wsnlib.sim.disturbance`), drawn per
        run from ``rng`` *after* the sensor noise (so the noise is the same with and without
        it) and added to the exact readings before the sensor errors.  None (default) leaves
        the simulation exactly as without the argument.

    Returns
    -------
    ImuSamples
        ``gyr`` (rad/s), ``acc`` (m/s²), ``mag`` (µT), each of shape
        ``(n_runs, N_nodes, T, 3)``, or ``(N_nodes, T, 3)`` when ``n_runs`` is None;
        saturated and quantised as the spec says (module docstring).
    """
    spec = ImuSpec() if spec is None else spec
    if not isinstance(spec, ImuSpec):
        raise ValueError(f"spec must be an ImuSpec, got {type(spec).__name__}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    if n_runs is None:
        batch: tuple[int, ...] = ()
    else:
        if isinstance(n_runs, bool) or not isinstance(n_runs, (int, np.integer)) or n_runs < 1:
            raise ValueError(f"n_runs must be a positive integer or None, got {n_runs!r}")
        batch = (int(n_runs),)
    ideal = ideal_imu(truth, gravity=gravity, mag_field_enu=mag_field_enu)
    if truth.fs is None:
        raise ValueError("truth.fs is None: simulate_imu needs uniformly sampled kinematics with a sampling rate")
    fs = truth.fs
    dt = 1.0 / fs
    n_nodes, n_samples = truth.quat.shape[:2]
    shape = batch + (n_nodes, n_samples, 3)
    per_run = batch + (n_nodes, 1, 3)

    # Gyroscope: constant residual bias + random walk + white noise.
    bias0 = np.radians(spec.gyr_bias_dps) * rng.standard_normal(per_run)
    steps = np.radians(spec.gyr_bias_walk_dps) * np.sqrt(dt) * rng.standard_normal(shape)
    steps[..., 0, :] = 0.0  # the walk starts at b_0 on the first sample
    gyr_bias = bias0 + np.cumsum(steps, axis=-2)
    gyr = ideal.gyr + gyr_bias + spec.gyr_noise_std_si(fs) * rng.standard_normal(shape)

    acc_bias = spec.acc_bias_mg * 1e-3 * frames.STANDARD_GRAVITY * rng.standard_normal(per_run)
    acc_noise = spec.acc_noise_std_si(fs) * rng.standard_normal(shape)

    mag_bias = spec.mag_bias_ut * rng.standard_normal(per_run)
    mag_noise = spec.mag_noise_std_si(fs) * rng.standard_normal(shape)

    acc_exact, mag_exact = ideal.acc, ideal.mag
    if disturbance is not None:
        signals = draw_disturbance(disturbance, truth.pos, fs, batch, rng=rng)
        acc_exact, mag_exact = apply_disturbance(truth.quat, acc_exact, mag_exact, signals)
    acc = acc_exact + acc_bias + acc_noise
    mag = mag_exact + mag_bias + mag_noise

    return ImuSamples(
        _digitise(gyr, spec.gyr_step_si, spec.gyr_full_scale_si, spec.gyr_bits, spec),
        _digitise(acc, spec.acc_step_si, spec.acc_full_scale_si, spec.acc_bits, spec),
        _digitise(mag, spec.mag_step_si, spec.mag_full_scale_si, spec.mag_bits, spec),
    )


def _rng_provenance(rng: np.random.Generator) -> dict:
    """Seed information of ``rng`` when it was built from a SeedSequence (else empty)."""
    seed_seq = getattr(rng.bit_generator, "seed_seq", None)
    entropy = getattr(seed_seq, "entropy", None)
    if isinstance(entropy, (int, np.integer)):
        return {
            "rng_bit_generator": type(rng.bit_generator).__name__,
            "rng_entropy": int(entropy),
            "rng_spawn_key": [int(k) for k in seed_seq.spawn_key],
        }
    return {}


def simulate_recording(
    trajectory: ArmTrajectory,
    *,
    rng: np.random.Generator,
    geometry: ArmGeometry | None = None,
    spec: ImuSpec | None = None,
    gravity: float = frames.STANDARD_GRAVITY,
    mag_field_enu=None,
    metadata: dict | None = None,
) -> Recording:
    """One simulated recording of the two arm nodes, with ground-truth quaternions.

    Parameters
    ----------
    trajectory : ArmTrajectory
        Joint-angle trajectory (e.g. :func:`wsnlib.sim.arm.arm_extension`).
    rng : numpy.random.Generator
        Source of the sensor noise (see :func:`simulate_imu`).
    geometry : ArmGeometry, optional
    spec : ImuSpec, optional
    gravity : float
        Gravity magnitude (m/s²).
    mag_field_enu : array_like, shape (3,), optional
        Earth magnetic field (µT, ENU).
    metadata : dict, optional
        Extra provenance merged into the recording's metadata (e.g. ``{"seed": 7}``).

    Returns
    -------
    Recording
        Nodes ``("humerus", "forearm")``; ``quat_true`` from the kinematics; metadata holds
        the generator, trajectory parameters, geometry, IMU spec, gravity, earth field and
        the rng's seed entropy when available.
    """
    geometry = ArmGeometry.paper001() if geometry is None else geometry
    spec = ImuSpec() if spec is None else spec
    if mag_field_enu is None:
        mag_field_enu = frames.magnetic_field_enu()
    truth = arm_kinematics(trajectory, geometry)
    gyr, acc, mag = simulate_imu(
        truth, spec, rng=rng, gravity=gravity, mag_field_enu=mag_field_enu
    )
    info = {
        "generator": "wsnlib.sim.imu.simulate_recording",
        "trajectory": dict(trajectory.metadata),
        "geometry": geometry.to_dict(),
        "imu_spec": dataclasses.asdict(spec),
        "gravity_m_s2": float(gravity),
        "mag_field_enu_uT": [float(v) for v in np.asarray(mag_field_enu, dtype=float)],
        **_rng_provenance(rng),
    }
    if metadata is not None:
        if not isinstance(metadata, dict):
            raise ValueError(f"metadata must be a dict, got {type(metadata).__name__}")
        info.update(metadata)
    return Recording(
        fs=truth.fs,
        time_s=truth.time_s,
        nodes=truth.nodes,
        gyr=gyr,
        acc=acc,
        mag=mag,
        quat_true=truth.quat,
        metadata=info,
    )
