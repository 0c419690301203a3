"""The Sun SPOT's accelerometer on paper 002's target nodes (Giuberti et al., Sec. 4.1).

Paper 002, Sec. 4.1: "The acceleration, locally (at each target node) sampled at 100 Hz, is
also consistently down-sampled to the same rate (i.e., 30 Hz)" as the packets (~30 pck/s),
and all nodes share the base station's clock (time stamps in every packet).  This module
turns the exact arm kinematics of :mod:`wsnlib.sim.body` into such 30 Hz accelerometer
streams, one per target, on the clock of :func:`wsnlib.sim.radio.simulate_rss`.

Hardware and sources
--------------------
*verified* = read in a copy of the document; *quoted* = seen only as quoted or used by a
third party (named); *unverified* = recalled, not found in any source consulted; *assumed* =
our modelling choice, with the reasoning.

* [Goldman2007] R. Goldman, "Using the LIS3L02AQ Accelerometer", Sun SPOT application note
  (Sun Microsystems, 2007; copies on scribd.com and as a court exhibit on docketalarm.com):
  the Sun SPOT eDEMO sensor board carries an ST LIS3L02AQ three-axis accelerometer whose
  analog outputs are "read via the demo sensor board's analog-to-digital converter"; range
  "either ± 2g or ± 6g"; z normal to the boards, x along the row of LEDs, y along the long
  edge; +1 g on z lying flat (the specific-force convention of this package).  *Verified*.
* [ADT7411] Analog Devices, ADT7411 datasheet (Rev. B): "10-bit 8-channel ADC", LSB =
  VDD/1024 (or 2.25 V/1024 with the internal reference), straight binary; every channel
  averages 16 conversions unless averaging is switched off.  *Verified*.  That the eDEMO
  board (rev. 6) digitises the accelerometer with the ADT7411 is *quoted*: Sun's telemetry
  demo (``AccelMonitor.java``, R. Goldman, 2006–2010) switches the ADT7411 to fast
  conversion for the LIS3L02AQ ("need to sample faster than 58Hz").  Later eDEMO boards
  (rev. 8) carry an MMA7455L instead; paper 002 does not say which revision it used.
* [LIS3L02AQ] ST, LIS3L02AQ3 datasheet: Vdd = 3.3 V typical, factory calibrated at 3.3 V,
  output impedance 110 kΩ, "Sensor bandwidth = 1/(2π·110K·Cload)".  *Verified* (a copy of
  datasheet pages 4–6).  Its mechanical-characteristics table (sensitivity, noise) was not
  found; the numbers below come from ST's sister part:
* [LIS344ALH] ST, LIS344ALH datasheet (Rev 3, 2008), Table 3: ratiometric analog outputs,
  sensitivity Vdd/5 V/g at ±2 g and Vdd/15 V/g at ±6 g, zero-g level Vdd/2, acceleration
  noise density 50 µg/√Hz (±2 g, Vdd = 3.3 V).  *Verified* for the LIS344ALH; *unverified*
  (assumed the same) for the LIS3L02AQ, its predecessor in the same analog ±2/±6 g family.

Measurement model
-----------------
For target ``i`` (device frame ``D``, orientation ``q_D = q_segment ⊗ q_mount``)::

    f   = q_D* ⊗ (a_i + [0, 0, g]) ⊗ q_D          specific force (m/s²), exact kinematics
    y   = f + b_i + w                              b_i ~ N(0, bias²) per session, node, axis;
                                                    w white, σ = density · √(π/2 · bandwidth)
    code = clip(rint(2^(bits−1) + y / g · counts_per_g + n_adc), 0, 2^bits − 1)
    acc  = (code − 2^(bits−1)) / counts_per_g · g    (back in m/s², as the node reports it)

at 100 Hz (``y`` saturated at ± full scale first), with ``counts_per_g = 2^bits ·
sensitivity_per_vdd`` (the ADC's reference is the accelerometer's supply: ratiometric,
*assumed*) = 204.8 counts/g at ±2 g, i.e. a resolution of 4.88 mg = 0.048 m/s².  The white
noise of the sensor (≈ 0.44 mg rms at a 50 Hz bandwidth) is far below one ADC step; the
ADC's own noise (``adc_noise_lsb``) and the quantisation dominate.

Down-sampling to 30 Hz (documented choice): output sample ``k`` is time-stamped
``t_k = k / 30`` s and is the **mean of the 100 Hz samples in** ``[t_k − 1/30, t_k)`` (three
or four of them; ``downsample="mean"``, a boxcar anti-alias filter, the natural reading of
"consistently down-sampled", and what a node that sends one packet per 1/30 s would do with
the samples gathered since the last packet), or the last of them (``"latest"``, plain
decimation).  Window membership uses integer arithmetic (sample ``n`` at ``n / 100`` s falls
in window ``k = ⌊3n/10⌋ + 1``), so ``t_k`` is never earlier than the samples it summarises:
the stream is causal.  The node samples continuously, so the first output (``t_0 = 0``)
summarises ``[−1/30, 0)``, during which the arm holds its initial posture
(:meth:`ArmMotion.kinematics` holds before 0); every packet at ``τ ≥ 0`` thus has an
accelerometer sample at or before it.  Times are rounded to 1 µs (the CSV precision).

Device frame and pitch
----------------------
By default the device frame **is** the segment frame of :mod:`wsnlib.sim.body` (body x along
the segment, pointing distally; ``mounting=None``).  Then
``wsnlib.posture.pitch_from_acc(acc)`` with its default ``segment_axis = (1, 0, 0)`` returns
the segment pitch θ = asin(u_z) (positive above the horizontal): at rest
``acc = g (sin θ, ·, ·)``.  A real Sun SPOT strapped to the arm has its long edge (its y axis)
along the arm; model that with ``mounting`` (device → segment rotation) and call
``pitch_from_acc(acc, segment_axis=segment_axis_in_device(mounting))``.

What this does not model: scale-factor and cross-axis errors (assumed calibrated with
[Goldman2007]'s six-position procedure), temperature drift, vibration of the strap, and the
tangential acceleration at the start and end of a movement (:mod:`wsnlib.sim.body` idealises
the speed steps away; inside a constant-speed movement the only linear acceleration is the
centripetal ``ω²d`` along the arm, towards the shoulder).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib._validation import (
    as_float_array,
    check_choice,
    check_fields,
    check_nonnegative,
    check_positive,
    check_rng,
    check_type,
)
from wsnlib.arm_model import ArmKinematics
from wsnlib.sim.arm_motion import ArmMotion
from wsnlib.sim.body import User

#: Down-sampling methods of :class:`SunspotAccSpec`.
DOWNSAMPLE_METHODS = ("mean", "latest")

#: Decimals of every time stamp (1 µs, as in the CSV formats).
TIME_DECIMALS = 6


@dataclass(frozen=True)
class SunspotAccSpec:
    """Parameters of the simulated Sun SPOT accelerometer (LIS3L02AQ via a 10-bit ADC).

    Sources and status as in the module docstring.

    Parameters
    ----------
    full_scale_g : float
        Measurement range ± (g).  2 — the LIS3L02AQ's ±2 g setting [Goldman2007]
        (*verified*: "± 2g or ± 6g").  Arm movements of 2–4 s stay far inside it.
        :meth:`six_g` gives the other setting.
    sensitivity_per_vdd : float
        Sensitivity as a fraction of the supply voltage per g: 1/5 at ±2 g (1/15 at ±6 g) —
        [LIS344ALH] Table 3, *verified* for that part, *unverified* for the LIS3L02AQ.
    adc_bits : int
        ADC resolution (bits).  10 — [ADT7411], *verified*; that the eDEMO uses it for the
        accelerometer is *quoted* (module docstring).  With the ADC reference equal to the
        accelerometer supply (*assumed*), ``counts_per_g = 2^bits · sensitivity_per_vdd``
        = 204.8 at ±2 g, zero g at code 512.
    noise_density_ug : float
        Acceleration noise density (µg/√Hz).  50 — [LIS344ALH], *unverified* for the
        LIS3L02AQ.
    bandwidth_hz : float
        −3 dB bandwidth of the analog output (Hz), set on the board by ``Cload``
        (``1/(2π·110 kΩ·Cload)`` [LIS3L02AQ], *verified*).  50 — *assumed* (Nyquist of the
        100 Hz sampling; Cload ≈ 29 nF); the noise bandwidth of this one-pole filter is
        ``π/2 · bandwidth_hz``.
    adc_noise_lsb : float
        Additive ADC/board noise, rms in LSB per conversion.  0.5 — *assumed* (a 10-bit
        converter on a shared 3 V board with averaging switched off for speed).
    bias_mg : float
        Standard deviation (mg) of the residual zero-g offset per session, node and axis
        after the six-position calibration of [Goldman2007].  5 — *assumed* (about one ADC
        step; the uncalibrated zero-g tolerance is far larger).  5 mg moves the pitch by at
        most 0.3°.
    sample_rate_hz : float
        Sampling rate at the node (Hz).  100 — paper 002, Sec. 4.1.
    output_rate_hz : float
        Rate after down-sampling (Hz).  30 — paper 002, Sec. 4.1 (the packet rate).
    downsample : {"mean", "latest"}
        Down-sampling method (module docstring).  "mean" — *assumed*.
    quantize : bool
        Apply the ADC (rounding to codes, clipping to the code range).  Default True.
    saturate : bool
        Clip the sensor output at ± full scale.  Default True.
    """

    full_scale_g: float = 2.0
    sensitivity_per_vdd: float = 0.2
    adc_bits: int = 10
    noise_density_ug: float = 50.0
    bandwidth_hz: float = 50.0
    adc_noise_lsb: float = 0.5
    bias_mg: float = 5.0
    sample_rate_hz: float = 100.0
    output_rate_hz: float = 30.0
    downsample: str = "mean"
    quantize: bool = True
    saturate: bool = True

    def __post_init__(self):
        check_fields(self, positive=("full_scale_g", "sensitivity_per_vdd", "bandwidth_hz", "sample_rate_hz",
                                     "output_rate_hz"), nonnegative=("noise_density_ug", "adc_noise_lsb", "bias_mg"),
                     flags=("quantize", "saturate"))
        bits = self.adc_bits
        if isinstance(bits, bool) or not isinstance(bits, int | np.integer) or not 2 <= bits <= 24:
            raise ValueError(f"adc_bits must be an integer in [2, 24], got {bits!r}")
        object.__setattr__(self, "adc_bits", int(bits))
        check_choice(self.downsample, "downsample", DOWNSAMPLE_METHODS)
        if self.output_rate_hz > self.sample_rate_hz:
            raise ValueError("output_rate_hz must not exceed sample_rate_hz")
        if self.sensitivity_per_vdd * self.full_scale_g > 0.5 + 1e-12:
            raise ValueError("full_scale_g · sensitivity_per_vdd must be <= 1/2 (the output swings around Vdd/2)")

    @classmethod
    def six_g(cls, **changes) -> SunspotAccSpec:
        """The ±6 g setting: sensitivity Vdd/15 per g ([LIS344ALH]), 68.3 counts/g."""
        return cls(**{"full_scale_g": 6.0, "sensitivity_per_vdd": 1.0 / 15.0, **changes})

    @classmethod
    def noise_free(cls, quantize: bool = False, saturate: bool = False, **changes) -> SunspotAccSpec:
        """No noise or bias (and by default no ADC or saturation): the exact specific force,
        down-sampled."""
        return cls(**{"noise_density_ug": 0.0, "adc_noise_lsb": 0.0, "bias_mg": 0.0, "quantize": quantize,
                      "saturate": saturate, **changes})

    @property
    def counts_per_g(self) -> float:
        """ADC codes per g (204.8 at ±2 g)."""
        return float(2**self.adc_bits) * self.sensitivity_per_vdd

    @property
    def zero_code(self) -> int:
        """ADC code of zero acceleration (Vdd/2): ``2^(bits−1)``."""
        return 2 ** (self.adc_bits - 1)

    @property
    def noise_std_m_s2(self) -> float:
        """Sensor white noise per 100 Hz sample (m/s²): ``density · √(π/2 · bandwidth)``."""
        return self.noise_density_ug * 1e-6 * frames.STANDARD_GRAVITY * math.sqrt(0.5 * math.pi * self.bandwidth_hz)


@dataclass(frozen=True, eq=False)
class SunspotAcc:
    """Accelerometer streams of both targets on the session clock.

    Attributes
    ----------
    time_s : numpy.ndarray (K,)
        Output time stamps (s): ``k / output_rate_hz``, ``k = 0 … ⌊duration · rate⌋``,
        rounded to 1 µs.
    acc : numpy.ndarray (K, 2, 3)
        Down-sampled readings (m/s², specific force, device frame) of T1 and T2.
    label : numpy.ndarray (K,) object
        Label of the motion piece at ``time_s``.
    raw_time_s : numpy.ndarray (N,)
        The 100 Hz sampling times (s), from ``−1/output_rate_hz`` on.
    raw_acc : numpy.ndarray (N, 2, 3)
        The 100 Hz readings (m/s²) before down-sampling.
    """

    time_s: np.ndarray
    acc: np.ndarray
    label: np.ndarray
    raw_time_s: np.ndarray
    raw_acc: np.ndarray

    @property
    def n_samples(self) -> int:
        """Number of output samples K."""
        return self.time_s.size


def _mounting(mounting) -> np.ndarray | None:
    if mounting is None:
        return None
    q = as_float_array(mounting, "mounting", last_dim=4)
    if q.shape not in ((4,), (2, 4)):
        raise ValueError(f"mounting must have shape (4,) or (2, 4) (one per target), got {q.shape}")
    return Q.normalize(q)


def segment_axis_in_device(mounting=None) -> np.ndarray:
    """The segment's distal axis (body x of the segment frame) in device coordinates, (3,) or (2, 3).

    Pass it as ``segment_axis`` to :func:`wsnlib.posture.pitch_from_acc`.  ``mounting`` rotates
    device vectors into the segment frame (``v_S = q_m ⊗ v_D ⊗ q_m*``); None → ``(1, 0, 0)``.
    """
    q = _mounting(mounting)
    if q is None:
        return np.array([1.0, 0.0, 0.0])
    return Q.rotate_inverse(q, np.array([1.0, 0.0, 0.0]))


def ideal_specific_force(kin: ArmKinematics, *, gravity: float = frames.STANDARD_GRAVITY, mounting=None) -> np.ndarray:
    """Exact accelerometer reading (T, 2, 3) of T1 and T2: ``q_D* ⊗ (a + [0, 0, g]) ⊗ q_D`` (m/s²).

    :meth:`wsnlib.arm_model.ArmKinematics.specific_force`, with the time axis first (the
    layout of :class:`SunspotAcc`).

    Parameters
    ----------
    kin : wsnlib.arm_model.ArmKinematics
        E.g. from :meth:`wsnlib.sim.arm_motion.ArmMotion.kinematics` (shoulder frame, z up).
    gravity : float
        g (m/s²); the reading at rest is ``+g`` along the earth's up axis.
    mounting : array_like (4,) or (2, 4), optional
        Device → segment rotation per target; default identity (device frame = segment frame).
    """
    check_type(kin, ArmKinematics, "kin")
    _mounting(mounting)  # validates, with this module's messages
    return np.moveaxis(kin.specific_force(gravity, mounting=mounting), 0, 1)


def output_times(duration_s: float, output_rate_hz: float = 30.0) -> np.ndarray:
    """Output time stamps ``k / rate`` for ``k = 0 … ⌊duration · rate⌋`` (s, rounded to 1 µs)."""
    duration = check_nonnegative(duration_s, "duration_s")
    rate = check_positive(output_rate_hz, "output_rate_hz")
    n = int(math.floor(duration * rate + 1e-9)) + 1
    return np.round(np.arange(n) / rate, TIME_DECIMALS)


def _windows(n_out: int, fs: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Raw sample indices n (from the first in window 0) and their output window k."""
    ratio = rate / fs
    n_lo = int(math.ceil(-1.0 / ratio - 1e-9))  # first n with n/fs >= -1/rate
    n_hi = int(math.ceil((n_out - 1) / ratio - 1e-9)) - 1  # last n with n/fs < t_{K-1}
    n = np.arange(n_lo, n_hi + 1)
    k = np.floor(n * rate / fs + 1e-9).astype(int) + 1
    return n, k


def simulate_sunspot_acc(motion: ArmMotion, user: User, *, rng: np.random.Generator, spec: SunspotAccSpec | None = None,
                        mounting=None, gravity: float = frames.STANDARD_GRAVITY,
                        duration_s: float | None = None) -> SunspotAcc:
    """Accelerometer streams of T1 and T2 while the arm follows ``motion`` (module docstring).

    Parameters
    ----------
    motion : ArmMotion
        Arm motion; time 0 = start of the session (the RSS packets' clock).
    user : User
        For the target distances along the arm.
    rng : numpy.random.Generator
        Bias, sensor noise and ADC noise, drawn in that order with shapes that depend only on
        the duration (zero standard deviations still consume their draws).
    spec : SunspotAccSpec, optional
        Default :class:`SunspotAccSpec()`.
    mounting : array_like (4,) or (2, 4), optional
        Device → segment rotation (:func:`ideal_specific_force`); default identity.
    gravity : float
        g (m/s²).
    duration_s : float, optional
        Session length (s); default ``motion.total_duration_s``.

    Returns
    -------
    SunspotAcc
    """
    spec = check_type(SunspotAccSpec() if spec is None else spec, SunspotAccSpec, "spec")
    check_type(motion, ArmMotion, "motion")
    check_rng(rng)
    gravity = check_positive(gravity, "gravity")
    duration = motion.total_duration_s if duration_s is None else check_positive(duration_s, "duration_s")
    fs, rate = spec.sample_rate_hz, spec.output_rate_hz
    times = output_times(duration, rate)
    n, window = _windows(times.size, fs, rate)
    raw_time = n / fs
    kin = motion.kinematics(raw_time, user)
    force = ideal_specific_force(kin, gravity=gravity, mounting=mounting)  # (N, 2, 3)

    shape = force.shape
    g_unit = gravity  # the node is calibrated on gravity: its codes count units of the local g
    bias = spec.bias_mg * 1e-3 * g_unit * rng.standard_normal((1,) + shape[1:])
    sensor_noise = spec.noise_std_m_s2 * rng.standard_normal(shape)
    adc_noise = spec.adc_noise_lsb * rng.standard_normal(shape)
    y = force + bias + sensor_noise
    if spec.saturate:
        limit = spec.full_scale_g * g_unit
        y = np.clip(y, -limit, limit)
    if spec.quantize:
        code = np.rint(spec.zero_code + y / g_unit * spec.counts_per_g + adc_noise)
        code = np.clip(code, 0, 2**spec.adc_bits - 1)
        raw = (code - spec.zero_code) / spec.counts_per_g * g_unit
    else:
        raw = y + adc_noise / spec.counts_per_g * g_unit

    n_out = times.size
    starts = np.searchsorted(window, np.arange(n_out), side="left")  # windows are contiguous runs
    if spec.downsample == "mean":
        counts = np.diff(np.append(starts, window.size))
        out = np.add.reduceat(raw, starts, axis=0) / counts[:, None, None]
    else:
        out = raw[np.searchsorted(window, np.arange(n_out), side="right") - 1]
    label = motion.kinematics(times, user).label
    return SunspotAcc(time_s=times, acc=out, label=label, raw_time_s=raw_time, raw_acc=raw)
