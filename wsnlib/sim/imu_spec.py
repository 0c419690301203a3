"""Sensor models of the paper's IMU node: ST L3GD20 gyroscope and ST LSM303DLHC acc/mag.

Paper 001 (De Vito et al.), Section IV: "a 9-degree-of-freedom IMU packing an ST-L3GD20
digital gyroscope with 16 bits and an ST-LSM303DLHC chip including a 12-bit accelerometer
and a 16-bit magnetometer sampling at 50 Hz".  :class:`ImuSpec` holds the numbers; each one
is cited in its docstring with how far it was checked:

* *verified*: read in a copy of the datasheet text or in a statement by ST staff;
* *quoted*: a datasheet value seen only as quoted by a third party (named);
* *unverified*: a datasheet value recalled but not found in any source consulted;
* *assumed*: no datasheet number exists; the reasoning is given.

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

:mod:`wsnlib.sim.imu` simulates readings with this spec.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib import frames
from wsnlib._validation import check_nonnegative, check_positive

#: 1 gauss = 100 µT.
UT_PER_GAUSS = 100.0


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
        for name in (
            "gyr_full_scale_dps",
            "gyr_sensitivity_mdps",
            "acc_full_scale_g",
            "acc_sensitivity_mg",
            "mag_full_scale_gauss",
            "mag_gain_xy_lsb_per_gauss",
            "mag_gain_z_lsb_per_gauss",
        ):
            object.__setattr__(self, name, check_positive(getattr(self, name), name))
        for name in (
            "gyr_noise_density_dps",
            "gyr_bias_dps",
            "gyr_bias_walk_dps",
            "acc_noise_density_ug",
            "acc_bias_mg",
            "mag_noise_ut",
            "mag_bias_ut",
        ):
            object.__setattr__(self, name, check_nonnegative(getattr(self, name), name))
        for name in ("gyr_bits", "acc_bits", "mag_bits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (
                2 <= value <= 32
            ):
                raise ValueError(f"{name} must be an integer in [2, 32], got {value!r}")
        if self.noise_bandwidth_hz is not None:
            object.__setattr__(
                self,
                "noise_bandwidth_hz",
                check_positive(self.noise_bandwidth_hz, "noise_bandwidth_hz"),
            )
        for name in ("quantize", "saturate"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")

    @classmethod
    def noise_free(cls, quantize: bool = False, saturate: bool = False, **changes) -> ImuSpec:
        """A spec without noise or bias (and, by default, without quantisation/saturation).

        Keyword ``changes`` override any field, e.g. ``ImuSpec.noise_free(gyr_bias_dps=0.5)``
        for a bias-only gyro.
        """
        fields = {
            "gyr_noise_density_dps": 0.0,
            "gyr_bias_dps": 0.0,
            "gyr_bias_walk_dps": 0.0,
            "acc_noise_density_ug": 0.0,
            "acc_bias_mg": 0.0,
            "mag_noise_ut": 0.0,
            "mag_bias_ut": 0.0,
            "quantize": quantize,
            "saturate": saturate,
        }
        fields.update(changes)
        return cls(**fields)

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
        gains = np.array([xy, xy, z])
        return UT_PER_GAUSS / gains

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
        return self.acc_noise_density_ug * 1e-6 * frames.STANDARD_GRAVITY * np.sqrt(
            self.noise_bandwidth(fs)
        )

    def mag_noise_std_si(self, fs: float) -> float:
        """Per-sample magnetometer noise standard deviation (µT); independent of ``fs``."""
        check_positive(fs, "fs")
        return self.mag_noise_ut
