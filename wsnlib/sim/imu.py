"""The paper's IMU node simulated: the sensor spec (ST L3GD20 gyroscope, ST LSM303DLHC
accelerometer and magnetometer; :class:`ImuSpec`) and its readings — ideal, noisy and
quantised — and whole recordings.

Paper 001 (De Vito et al.), Section IV: "a 9-degree-of-freedom IMU packing an ST-L3GD20
digital gyroscope with 16 bits and an ST-LSM303DLHC chip including a 12-bit accelerometer
and a 16-bit magnetometer sampling at 50 Hz".  :class:`ImuSpec` holds the numbers; each one
is cited in its docstring with how far it was checked:

* *verified*: read in a copy of the datasheet text or in a statement by ST staff;
* *quoted*: a datasheet value seen only as quoted by a third party (named);
* *unverified*: a datasheet value recalled but not found in any source consulted;
* *assumed*: no datasheet number exists; the reasoning is given.

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

Sources
-------
* [L3GD20] STMicroelectronics, *L3GD20 MEMS motion sensor: three-axis digital output
  gyroscope*, datasheet DocID022116 (Rev 1, Aug 2011; Rev 2, Feb 2013), Table 3/4
  "Mechanical characteristics".
* [LSM303DLHC] STMicroelectronics, *LSM303DLHC Ultra compact high performance e-compass 3D
  accelerometer and 3D magnetometer module*, datasheet DocID018771, Table 3 "Sensor
  characteristics".
* [ST-forum-2013] ST community thread "Data output format of the LSM303DLHC" (2013), answer
  by ST staff: accelerometer data 12-bit left-justified in normal mode, magnetometer data
  12-bit right-justified.
* [Pololu-forum] Pololu forum thread "LSM303DLHC. Should there be a value's jitter?",
  quoting LSM303DLHC Table 3: acceleration noise density 220 µg/√Hz (normal mode, ±2 g).
* Third-party quotations of datasheet values (see "quoted" below): Stack Overflow question
  19161872 "Meaning of LSB/Unit and Unit/LSB" (LSM303DLHC, 2013); documentation of the Rust
  crate ``f3`` 0.2.0, module ``f3::lsm303dlhc``; RIOT-OS ``lsm303dlhc`` driver
  documentation; documentation of a Rust L3GD20 driver (``Bandwidth`` enum).
* Earth field and gravity: :mod:`wsnlib.frames` (WMM2020 at Benevento; ISO 80000-3).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib._validation import as_float_array, check_count, check_fields, check_positive, check_rng, check_type
from wsnlib.arm_model import ArmGeometry, ArmKinematics
from wsnlib.io.recording import Recording
from wsnlib.sim.arm import ArmTrajectory, arm_kinematics
from wsnlib.sim.disturbance import Disturbance, disturb

#: 1 gauss = 100 µT.
UT_PER_GAUSS = 100.0

#: The noise and bias fields of :class:`ImuSpec` (>= 0; zero in :meth:`ImuSpec.noise_free`).
_NOISE_FIELDS = ("gyr_noise_density_dps", "gyr_bias_dps", "gyr_bias_walk_dps", "acc_noise_density_ug", "acc_bias_mg",
                 "mag_noise_ut", "mag_bias_ut")


@dataclass(frozen=True)
class ImuSpec:
    """Parameters of the simulated IMU, defaulting to the paper's L3GD20 + LSM303DLHC.

    Units are those of the datasheets (dps, mg, gauss) so that each number can be checked
    against its source; the ``*_si`` properties convert.  ``dataclasses.replace`` changes
    single fields; :meth:`noise_free` gives the deterministic sensor.

    Parameters
    ----------
    gyr_full_scale_dps : float
        Gyro measurement range ± (dps).  250 — [L3GD20] Table 3, FS = ±250/±500/±2000 dps,
        the smallest range; *verified*.  Arm movements stay well inside it.
    gyr_sensitivity_mdps : float
        Gyro resolution (mdps/digit).  8.75 at FS = 250 dps — [L3GD20] Table 3, So;
        *verified*.
    gyr_bits : int
        Gyro output word (bits, two's complement).  16 — [L3GD20] features, "16 bit-rate
        value data output"; *verified*.
    gyr_noise_density_dps : float
        Rate noise density (dps/√Hz).  0.03 — [L3GD20] Table 3, Rn; *quoted* (documentation
        of an L3GD20 Rust driver's bandwidth setting: "Rate noise density: 0.03 dps/√Hz").
        ≈ 0.15 dps rms per sample at B = 25 Hz.
    gyr_bias_dps : float
        Standard deviation (dps) of the constant residual bias per run, node and axis.
        0.2 — *assumed*.  The datasheet zero-rate level is ±10 dps at FS = 250 dps
        ([L3GD20] Table 3, DVoff; *unverified*; a firmware note *quotes* "up to about ±15 dps
        at ±500 dps", the same table's next column), far too large to use raw, so we assume
        the node is calibrated at rest before each run; what remains is the calibration
        error plus the zero-rate change with temperature, ±0.03 dps/°C at FS = 250 dps
        ([L3GD20] Table 3, OffDr; *unverified*), i.e. ~0.15 dps for a 5 °C warm-up of a
        body-worn node.  Drawn once per run: ``b_0 ~ N(0, gyr_bias_dps²)``.
    gyr_bias_walk_dps : float
        Bias random walk (dps/√s): the bias moves by ``N(0, (gyr_bias_walk_dps² · Δt))`` per
        sample, starting at ``b_0``.  0.005 — *assumed* (the datasheet gives no bias
        instability); it makes the bias "change unpredictably in time" as paper 001,
        Section II, says, by ~0.04 dps over a minute.
    acc_full_scale_g : float
        Accelerometer range ± (g).  2 — [LSM303DLHC] Table 3, LA_FS = ±2/±4/±8/±16 g; the
        smallest range, which with 1 mg/LSB fits the paper's "12-bit accelerometer"
        (±2048 codes); the range list is *quoted* (RIOT-OS driver documentation: scales
        2/4/8/16 g).
    acc_sensitivity_mg : float
        Accelerometer resolution (mg/LSB).  1 at ±2 g — [LSM303DLHC] Table 3, LA_So;
        *quoted* (Stack Overflow question 19161872 citing the datasheet, page 9, "1 mg/LSB").
    acc_bits : int
        Accelerometer output word (bits).  12 — paper 001 and [ST-forum-2013] (12-bit
        left-justified in normal mode); *verified*.
    acc_noise_density_ug : float
        Acceleration noise density (µg/√Hz).  220 — [LSM303DLHC] Table 3 as quoted in
        [Pololu-forum] (normal mode, ±2 g); *quoted*.  ≈ 1.1 mg rms per sample at B = 25 Hz.
    acc_bias_mg : float
        Standard deviation (mg) of a constant residual accelerometer bias per run, node
        and axis.  0 — *assumed* calibrated (the datasheet zero-g level, LA_TyOff, is
        ±60 mg typical before calibration; *unverified*).
    mag_full_scale_gauss : float
        Magnetometer range ± (gauss).  1.3 — [LSM303DLHC] Table 3, M_FS (±1.3 … ±8.1
        gauss), the smallest range; *quoted* (documentation of the Rust ``f3`` crate: "Input
        range [-1.3G, +1.3G], Gain X, Y: 1100 LSB / Gauss, Gain Z: 980 LSB / Gauss").  The
        earth field (≈ 0.46 gauss) fits.
    mag_gain_xy_lsb_per_gauss, mag_gain_z_lsb_per_gauss : float
        Magnetometer gain (LSB/gauss) at ±1.3 gauss: 1100 (x, y) and 980 (z) — [LSM303DLHC]
        Table 3, GN; *quoted* (same ``f3`` documentation; the Stack Overflow question above
        quotes "1100 LSB/gauss"; one answer there has x/y and z swapped, which we do not
        follow).  Resolution 0.091 µT (x, y), 0.102 µT (z).
    mag_bits : int
        Magnetometer output range (bits): 12 ([ST-forum-2013]: 12-bit right-justified data
        in 16-bit registers, *verified*; the paper's "16-bit magnetometer" counts the
        register).  With ±1.3 gauss at 1100 LSB/gauss (1430 codes) the range never binds.
    mag_noise_ut : float
        Magnetometer noise, rms per sample and axis (µT).  0.3 — *assumed*: the
        [LSM303DLHC] datasheet gives no magnetic noise figure; 0.3 µT (3 mgauss) is the
        order of the rms noise of ST's later e-compass parts (recalled, not checked) and
        ~3 LSB at this gain.
    mag_bias_ut : float
        Standard deviation (µT) of a constant residual hard-iron offset per run, node and
        axis.  0 — *assumed* calibrated.
    noise_bandwidth_hz : float or None
        Noise bandwidth ``B`` (Hz) for all three sensors; None means ``fs / 2``.
    quantize : bool
        Round to the sensor resolution (default True).
    saturate : bool
        Clip at ± full scale (default True).
    """

    gyr_full_scale_dps: float = 250.0
    gyr_sensitivity_mdps: float = 8.75
    gyr_bits: int = 16
    gyr_noise_density_dps: float = 0.03
    gyr_bias_dps: float = 0.2
    gyr_bias_walk_dps: float = 0.005
    acc_full_scale_g: float = 2.0
    acc_sensitivity_mg: float = 1.0
    acc_bits: int = 12
    acc_noise_density_ug: float = 220.0
    acc_bias_mg: float = 0.0
    mag_full_scale_gauss: float = 1.3
    mag_gain_xy_lsb_per_gauss: float = 1100.0
    mag_gain_z_lsb_per_gauss: float = 980.0
    mag_bits: int = 12
    mag_noise_ut: float = 0.3
    mag_bias_ut: float = 0.0
    noise_bandwidth_hz: float | None = None
    quantize: bool = True
    saturate: bool = True

    def __post_init__(self):
        check_fields(self, positive=("gyr_full_scale_dps", "gyr_sensitivity_mdps", "acc_full_scale_g",
                                     "acc_sensitivity_mg", "mag_full_scale_gauss", "mag_gain_xy_lsb_per_gauss",
                                     "mag_gain_z_lsb_per_gauss"), nonnegative=_NOISE_FIELDS,
                     flags=("quantize", "saturate"))
        for name in ("gyr_bits", "acc_bits", "mag_bits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (2 <= value <= 32):
                raise ValueError(f"{name} must be an integer in [2, 32], got {value!r}")
        if self.noise_bandwidth_hz is not None:
            bandwidth = check_positive(self.noise_bandwidth_hz, "noise_bandwidth_hz")
            object.__setattr__(self, "noise_bandwidth_hz", bandwidth)

    @classmethod
    def noise_free(cls, quantize: bool = False, saturate: bool = False, **changes) -> ImuSpec:
        """A spec without noise or bias (and, by default, without quantisation/saturation).

        Keyword ``changes`` override any field, e.g. ``ImuSpec.noise_free(gyr_bias_dps=0.5)``
        for a bias-only gyro.
        """
        return cls(**{**dict.fromkeys(_NOISE_FIELDS, 0.0), "quantize": quantize, "saturate": saturate, **changes})

    # ---- SI conversions --------------------------------------------------------------------

    @property
    def gyr_step_si(self) -> float:
        """Gyro resolution (rad/s per digit)."""
        return np.radians(self.gyr_sensitivity_mdps * 1e-3)

    @property
    def gyr_full_scale_si(self) -> float:
        """Gyro full scale (rad/s)."""
        return np.radians(self.gyr_full_scale_dps)

    @property
    def acc_step_si(self) -> float:
        """Accelerometer resolution (m/s² per LSB); 1 g = standard gravity."""
        return self.acc_sensitivity_mg * 1e-3 * frames.STANDARD_GRAVITY

    @property
    def acc_full_scale_si(self) -> float:
        """Accelerometer full scale (m/s²)."""
        return self.acc_full_scale_g * frames.STANDARD_GRAVITY

    @property
    def mag_step_si(self) -> np.ndarray:
        """Magnetometer resolution per axis (µT per LSB), shape (3,)."""
        xy, z = self.mag_gain_xy_lsb_per_gauss, self.mag_gain_z_lsb_per_gauss
        return UT_PER_GAUSS / np.array([xy, xy, z])

    @property
    def mag_full_scale_si(self) -> float:
        """Magnetometer full scale (µT)."""
        return self.mag_full_scale_gauss * UT_PER_GAUSS

    def noise_bandwidth(self, fs: float) -> float:
        """Noise bandwidth ``B`` (Hz) used at sampling rate ``fs``."""
        fs = check_positive(fs, "fs")
        return 0.5 * fs if self.noise_bandwidth_hz is None else self.noise_bandwidth_hz

    def gyr_noise_std_si(self, fs: float) -> float:
        """Per-sample gyro white-noise standard deviation (rad/s) at ``fs``."""
        return np.radians(self.gyr_noise_density_dps) * np.sqrt(self.noise_bandwidth(fs))

    def acc_noise_std_si(self, fs: float) -> float:
        """Per-sample accelerometer white-noise standard deviation (m/s²) at ``fs``."""
        return self.acc_noise_density_ug * 1e-6 * frames.STANDARD_GRAVITY * np.sqrt(self.noise_bandwidth(fs))


# --------------------------------------------------------------------------------------------
# Readings
# --------------------------------------------------------------------------------------------


class ImuSamples(NamedTuple):
    """Simulated readings; each field has shape ``(..., N_nodes, T, 3)``.

    ``gyr`` in rad/s, ``acc`` in m/s² (specific force), ``mag`` in µT, all body frame.
    Unpacks as ``gyr, acc, mag = simulate_imu(...)``.
    """

    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray


def ideal_imu(truth: ArmKinematics, *, gravity: float = frames.STANDARD_GRAVITY, mag_field_enu=None) -> ImuSamples:
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
    check_type(truth, ArmKinematics, "truth")
    gravity = check_positive(gravity, "gravity")
    mag_field = as_float_array(frames.magnetic_field_enu() if mag_field_enu is None else mag_field_enu, "mag_field_enu")
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


def simulate_imu(truth: ArmKinematics, spec: ImuSpec | None = None, *, rng: np.random.Generator,
                 n_runs: int | None = None, gravity: float = frames.STANDARD_GRAVITY, mag_field_enu=None,
                 disturbance: Disturbance | None = None) -> ImuSamples:
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
    spec = check_type(ImuSpec() if spec is None else spec, ImuSpec, "spec")
    check_rng(rng)
    batch: tuple[int, ...] = () if n_runs is None else (check_count(n_runs, "n_runs"),)
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
    mag_noise = spec.mag_noise_ut * rng.standard_normal(shape)  # per sample, whatever fs

    acc_exact, mag_exact = ideal.acc, ideal.mag
    if disturbance is not None:
        acc_exact, mag_exact = disturb(disturbance, truth, acc_exact, mag_exact, batch, rng=rng)
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
        return {"rng_bit_generator": type(rng.bit_generator).__name__, "rng_entropy": int(entropy),
                "rng_spawn_key": [int(k) for k in seed_seq.spawn_key]}
    return {}


def simulate_recording(trajectory: ArmTrajectory, *, rng: np.random.Generator, geometry: ArmGeometry | None = None,
                       spec: ImuSpec | None = None, gravity: float = frames.STANDARD_GRAVITY, mag_field_enu=None,
                       metadata: dict | None = None) -> Recording:
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
    gyr, acc, mag = simulate_imu(truth, spec, rng=rng, gravity=gravity, mag_field_enu=mag_field_enu)
    info = {"generator": "wsnlib.sim.imu.simulate_recording", "trajectory": dict(trajectory.metadata),
            "geometry": geometry.to_dict(), "imu_spec": dataclasses.asdict(spec), "gravity_m_s2": float(gravity),
            "mag_field_enu_uT": [float(v) for v in np.asarray(mag_field_enu, dtype=float)], **_rng_provenance(rng)}
    if metadata is not None:
        check_type(metadata, dict, "metadata")
        info.update(metadata)
    return Recording(fs=truth.fs, time_s=truth.time_s, nodes=truth.nodes, gyr=gyr, acc=acc, mag=mag,
                     quat_true=truth.quat, metadata=info)
