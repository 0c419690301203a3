"""Is a recording fit for a study?  A health check to run before any filter sees it.

:func:`recording_health` measures, per node (batch element), what silently spoils an
orientation study, and says in plain sentences what to do about it:

* **time base**: the effective rate (from the median time step) against the nominal ``fs`` the
  filters will assume, the time-step jitter, the share of gaps and of steps that do not advance;
* **repeated samples**: consecutive samples whose inertial reading (``gyr`` and ``acc``
  together) is identical, which a noisy sensor never produces: a radio node or a logger that
  sends its last reading again when it has no new one (sample-and-hold).  ``mag`` is left out:
  magnetometers often update more slowly than the inertial sensors and are held on purpose;
* **reference vs gyroscope**: the angular rate the reference orientation implies (body frame,
  the rotation between finite reference rows :data:`REF_AGREEMENT_WINDOW_S` apart, at least one
  step, so that the reference's noise counts about as much at 285 Hz as at 50 Hz) against the
  gyroscope's mean over the same interval; and the reference's jumps (marker swaps, mislabelled
  markers), one step at a time: a step turning more than :data:`REF_JUMP_MIN_DEG` and more than
  :data:`REF_JUMP_RATIO` × the gyroscope's turn over that step;
* **magnetic field**: the spread of ‖mag‖ and the share of samples off its median by more than
  :data:`MAG_DISTURBED_FRACTION` (a disturbed field or an uncalibrated magnetometer; the norm
  only: the dip angle needs the orientation and is not used);
* **units and single samples**: exactly the checks the filters run on their inputs
  (:mod:`wsnlib.plausibility`: :func:`~wsnlib.plausibility.imu_unit_problems` with standard
  gravity, :func:`~wsnlib.plausibility.implausible_samples`,
  :func:`~wsnlib.plausibility.magnetometer_problem`), so that the bounds live in one place.

Thresholds (module constants; crossing one is a finding)
--------------------------------------------------------
=======================================  ========================================================
:data:`RATE_TOLERANCE` = 1 %             effective vs nominal rate
:data:`JITTER_MAX` = 5 %                 robust s.d. of the time step (1.4826 × median absolute
                                         deviation) relative to the median step
:data:`GAP_STEP_FACTOR` = 1.5            a step longer than 1.5 median steps is a gap (any gap
                                         is reported)
:data:`REPEATED_SHARE_MAX` = 0.1 %       samples repeating the previous gyr and acc exactly (a
                                         noisy 16-bit sensor repeats 6 axes by chance far less;
                                         some BROAD trials hold 0.1–0.9 %, in runs)
:data:`REF_AGREEMENT_WINDOW_S` = 0.02 s  interval of the reference's rate (at least one step)
:data:`REF_COVERAGE_MIN` = 90 %          finite reference rows
:data:`REF_GYRO_MEDIAN_MAX_RAD_S` = 0.3  median ‖ω_ref − ω_gyr‖ (rad/s): a reference not aligned
                                         to the IMU, offset in time, of another node, or a biased
                                         gyro (BROAD's trials: 0.03–0.21, at 285 Hz as at 50 Hz)
:data:`REF_JUMP_RATIO` = 3,              a reference step turning more than 5° and more than 3 ×
:data:`REF_JUMP_MIN_DEG` = 5°            the gyroscope's turn is a jump (5° per step is 4.4 rad/s
                                         at 50 Hz; a marker swap turns tens of degrees at once);
                                         any jump is reported
:data:`MAG_DISTURBED_FRACTION` = 10 %    a sample whose ‖mag‖ is this far from the median is
                                         disturbed
:data:`MAG_DISTURBED_SHARE_MAX` = 5 %    disturbed samples
:data:`MAG_SPREAD_MAX` = 20 %            (95th − 5th percentile of ‖mag‖) / median
=======================================  ========================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnlib import quaternion as quat_ops
from wsnlib._validation import as_float_array, check_positive
from wsnlib.frames import STANDARD_GRAVITY
from wsnlib.plausibility import SAMPLE_NORM_MAX, implausible_samples, imu_unit_problems, magnetometer_problem

__all__ = ["RecordingHealth", "recording_health"]

RATE_TOLERANCE = 0.01
JITTER_MAX = 0.05
GAP_STEP_FACTOR = 1.5
REPEATED_SHARE_MAX = 0.001
REF_COVERAGE_MIN = 0.90
REF_AGREEMENT_WINDOW_S = 0.02
REF_GYRO_MEDIAN_MAX_RAD_S = 0.3
REF_JUMP_RATIO = 3.0
REF_JUMP_MIN_DEG = 5.0
MAG_DISTURBED_FRACTION = 0.10
MAG_DISTURBED_SHARE_MAX = 0.05
MAG_SPREAD_MAX = 0.20

#: 1.4826 × the median absolute deviation estimates a normal distribution's standard deviation.
_MAD_TO_SD = 1.4826
#: At most this many jump times are listed in a finding.
_JUMPS_LISTED = 3


@dataclass(frozen=True)
class RecordingHealth:
    """The result of :func:`recording_health`.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per batch element (index ``element``: the ``names`` given, else the flat
        position in C order), the columns listed in :func:`recording_health`.
    findings : tuple of str
        Plain sentences, each saying what is wrong and what to do; empty when nothing is.

    ``print(health)`` prints the findings as a list.
    """

    table: pd.DataFrame
    findings: tuple[str, ...]

    def __str__(self) -> str:
        if not self.findings:
            return "Recording health: no problem found."
        return "\n".join([f"Recording health: {len(self.findings)} finding(s)"] + [f"- {f}" for f in self.findings])


def recording_health(time_s, gyr, acc, mag=None, quat_ref=None, *, fs=None, names=None) -> RecordingHealth:
    """Check a recording before a study: time base, repeated samples, reference, field, units.

    Parameters
    ----------
    time_s : array_like, shape (T,) or (..., T)
        Sample times (s), finite; broadcast against the signals' leading (batch) shape.
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s²), body frame, finite (loss is a mask
        applied later, never missing rows).
    mag : array_like, shape (..., T, 3), optional
        Magnetic field (µT), body frame, finite.
    quat_ref : array_like, shape (..., T, 4), optional
        Reference orientation ``[w, x, y, z]`` (body → ENU), e.g. optical; rows holding NaN are
        missing (markers lost).
    fs : float, optional
        Nominal sampling rate (Hz) the filters will be given; None: not compared.
    names : sequence of str, optional
        Labels of the batch elements in C order (e.g. a :class:`~wsnlib.io.recording.Recording`'s
        ``nodes``): the table's index and the findings' prefix.

    Returns
    -------
    RecordingHealth
        ``table`` columns per batch element: ``n_samples``; ``fs_nominal_hz`` (NaN without
        ``fs``), ``fs_effective_hz`` (1 / median positive step), ``step_jitter`` (robust s.d.
        of the step / median step), ``gap_share`` (steps > :data:`GAP_STEP_FACTOR` median
        steps), ``nonincreasing_share`` (steps ≤ 0), all shares of the T − 1 steps;
        ``repeated_share`` (of the T − 1 samples after the first) and ``new_data_rate_hz``
        (``fs_effective_hz`` × (1 − ``repeated_share``)); with ``quat_ref``: ``ref_coverage``
        (share of finite rows), ``ref_gyro_diff_median_rad_s``, ``ref_gyro_diff_p95_rad_s``
        (‖ω_ref − ω_gyr‖ over the intervals of :data:`REF_AGREEMENT_WINDOW_S` between two
        finite rows), ``ref_jumps`` (count), ``ref_jump_share`` (of the steps between two
        finite rows) and ``ref_first_jump_s`` (time of the first, NaN if none); with
        ``mag``: ``mag_norm_median_uT``, ``mag_norm_p5_uT``, ``mag_norm_p95_uT``,
        ``mag_norm_spread`` ((p95 − p5) / median), ``mag_disturbed_share``; always
        ``implausible_share`` (samples beyond :data:`wsnlib.plausibility.SAMPLE_NORM_MAX`),
        ``units_problem`` and, with ``mag``, ``mag_problem`` (text, ``""`` when fine).

    Raises
    ------
    ValueError
        A signal not of shape ``(..., T, 3)`` (``quat_ref`` ``(..., T, 4)``), lengths that
        disagree, leading shapes that do not broadcast, fewer than 2 samples, a non-finite
        time or IMU sample, ``fs`` not positive, ``names`` of the wrong length.

    Example: ``print(recording_health(rec.time_s, rec.gyr, rec.acc, rec.mag, rec.quat_true,
    fs=rec.fs, names=rec.nodes))`` for a :class:`~wsnlib.io.recording.Recording` ``rec``.
    """
    signals = {"gyr": gyr, "acc": acc} | ({} if mag is None else {"mag": mag})
    signals = {name: as_float_array(value, name, last_dim=3, min_ndim=2) for name, value in signals.items()}
    n_t = signals["gyr"].shape[-2]
    for name, arr in signals.items():
        if arr.shape[-2] != n_t:
            raise ValueError(f"{name} has {arr.shape[-2]} samples (axis -2), gyr has {n_t}")
    if n_t < 2:
        raise ValueError(f"gyr must have at least 2 samples along time (axis -2) for a time step, got {n_t}")
    time_s = as_float_array(time_s, "time_s")
    if time_s.shape[-1] != n_t:
        raise ValueError(f"time_s must have shape (..., {n_t}) like the signals' time axis, got {time_s.shape}")
    shapes = {name: arr.shape[:-2] for name, arr in signals.items()} | {"time_s": time_s.shape[:-1]}
    if quat_ref is not None:
        quat_ref = quat_ops.as_quat_with_gaps(quat_ref, "quat_ref")
        if quat_ref.ndim < 2 or quat_ref.shape[-2] != n_t:
            raise ValueError(f"quat_ref must have shape (..., {n_t}, 4), got {quat_ref.shape}")
        shapes["quat_ref"] = quat_ref.shape[:-2]
    try:
        batch = np.broadcast_shapes(*shapes.values())
    except ValueError:
        listed = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"leading (batch) dimensions do not broadcast: {listed}") from None
    fs = None if fs is None else check_positive(fs, "fs")
    n_elements = int(np.prod(batch, dtype=np.int64))
    labels = _labels(names, n_elements)

    def element(arr, core: int):  # (*batch, *core) → (n_elements, *core), a view
        core_shape = arr.shape[arr.ndim - core:]
        return np.broadcast_to(arr, batch + core_shape).reshape((n_elements,) + core_shape)

    times = element(time_s, 1)
    flat = {name: element(arr, 2) for name, arr in signals.items()}
    refs = None if quat_ref is None else element(quat_ref, 2)
    rows, findings = [], []
    for i in range(n_elements):
        values, found = _element_health(times[i], {name: arr[i] for name, arr in flat.items()},
                                        None if refs is None else refs[i], fs)
        rows.append(values)
        prefix = f"{labels[i]}: " if n_elements > 1 else ""
        findings += [prefix + sentence for sentence in found]
    table = pd.DataFrame(rows, index=pd.Index(labels, name="element"))
    return RecordingHealth(table=table, findings=tuple(findings))


def _labels(names, n_elements: int) -> list:
    if names is None:
        return list(range(n_elements))
    if isinstance(names, str) or not hasattr(names, "__len__"):
        raise ValueError(f"names must be a sequence of labels, one per batch element, got {names!r}")
    if len(names) != n_elements:
        raise ValueError(f"names has {len(names)} labels but the signals have {n_elements} batch element(s)")
    return list(names)


def _element_health(time_s: np.ndarray, signals: dict[str, np.ndarray], quat_ref: np.ndarray | None,
                    fs: float | None) -> tuple[dict, list[str]]:
    """The table row and the findings of one batch element (``time_s`` (T,), signals (T, 3))."""
    row: dict = {"n_samples": time_s.size}
    findings: list[str] = []
    steps = _time_base(time_s, fs, row, findings)
    _repeated(signals, row, findings)
    if quat_ref is not None:
        _reference(time_s, steps, signals["gyr"], quat_ref, row, findings)
    if "mag" in signals:
        _magnetic_field(signals["mag"], row, findings)
    _units(signals, row, findings)
    return row, findings


def _time_base(time_s, fs, row, findings) -> np.ndarray:
    steps = np.diff(time_s)
    forward = steps[steps > 0.0]
    if forward.size == 0:
        raise ValueError("time_s never increases: no time step to measure the rate from")
    median_step = float(np.median(forward))
    effective = 1.0 / median_step
    jitter = _MAD_TO_SD * float(np.median(np.abs(forward - median_step))) / median_step
    gap_share = float(np.mean(steps > GAP_STEP_FACTOR * median_step))
    backward_share = float(np.mean(steps <= 0.0))
    row |= {"fs_nominal_hz": np.nan if fs is None else fs, "fs_effective_hz": effective, "step_jitter": jitter,
            "gap_share": gap_share, "nonincreasing_share": backward_share}
    if fs is not None and abs(effective / fs - 1.0) > RATE_TOLERANCE:
        findings.append(f"the time stamps run at {effective:.6g} Hz (median step), not the nominal {fs:.6g} Hz "
                        f"({effective / fs - 1.0:+.1%}): give the filters fs={effective:.6g}, or resample onto "
                        f"the nominal grid (wsnlib.io.resample_timestamps)")
    if jitter > JITTER_MAX:
        findings.append(f"the time step jitters by {jitter:.1%} of a step (robust s.d.): the filters assume a "
                        f"constant step 1/fs; resample onto a uniform grid (wsnlib.io.resample_timestamps)")
    if gap_share > 0.0:
        findings.append(f"{gap_share:.2%} of the time steps are gaps (longer than {GAP_STEP_FACTOR:g} median steps, "
                        f"the longest {steps.max() / median_step:.3g} steps): rows are missing; put them back as "
                        f"lost samples (a received mask on a uniform grid) or resample (wsnlib.io.resample_timestamps)")
    if backward_share > 0.0:
        findings.append(f"{backward_share:.2%} of the time steps do not advance (duplicate or backward time "
                        f"stamps): sort the rows and drop duplicates before anything else")
    return steps


def _repeated(signals, row, findings) -> None:
    inertial = np.concatenate([signals["gyr"], signals["acc"]], axis=-1)
    share = float(np.mean(np.all(inertial[1:] == inertial[:-1], axis=-1)))
    row |= {"repeated_share": share, "new_data_rate_hz": row["fs_effective_hz"] * (1.0 - share)}
    if share > REPEATED_SHARE_MAX:
        findings.append(f"{share:.1%} of the samples repeat the previous gyr and acc reading exactly "
                        f"(sample-and-hold: no new data there, {row['new_data_rate_hz']:.4g} Hz of new readings): "
                        f"mark the repeats as not received (the received mask) instead of feeding them as data")


def _reference(time_s, steps, gyr, quat_ref, row, findings) -> None:
    finite = ~np.isnan(quat_ref[:, 0])
    coverage = float(np.mean(finite))
    q = np.where(finite[:, None], quat_ref, 1.0)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    # agreement: the rotation between rows REF_AGREEMENT_WINDOW_S apart against the mean gyro over it
    span = max(1, round(REF_AGREEMENT_WINDOW_S / float(np.median(steps[steps > 0.0]))))
    k = np.flatnonzero(finite[:-span] & finite[span:] & (time_s[span:] > time_s[:-span]))
    gyro_integral = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (gyr[1:] + gyr[:-1]) * steps[:, None], axis=0)])
    window = time_s[k + span] - time_s[k]
    omega_ref = _rotation_vector(q[k], q[k + span]) / window[:, None]
    omega_gyr = (gyro_integral[k + span] - gyro_integral[k]) / window[:, None]
    diff = np.linalg.norm(omega_ref - omega_gyr, axis=-1)
    median_diff, p95_diff = (float(v) for v in np.percentile(diff, [50.0, 95.0])) if k.size else (np.nan, np.nan)
    # jumps: one step at a time (a swap is instantaneous), angles per step
    j = np.flatnonzero(finite[:-1] & finite[1:])
    angle_ref = np.linalg.norm(_rotation_vector(q[j], q[j + 1]), axis=-1)
    angle_gyr = np.linalg.norm(0.5 * (gyr[j] + gyr[j + 1]), axis=-1) * np.abs(steps[j])
    jump_times = time_s[j[(angle_ref > REF_JUMP_RATIO * angle_gyr) & (angle_ref > np.radians(REF_JUMP_MIN_DEG))]]
    row |= {"ref_coverage": coverage, "ref_gyro_diff_median_rad_s": median_diff,
            "ref_gyro_diff_p95_rad_s": p95_diff, "ref_jumps": jump_times.size,
            "ref_jump_share": jump_times.size / max(j.size, 1),
            "ref_first_jump_s": float(jump_times[0]) if jump_times.size else np.nan}
    if coverage < REF_COVERAGE_MIN:
        findings.append(f"the reference covers {coverage:.1%} of the samples (the rest NaN: markers lost): "
                        f"errors are scored on the covered samples only; check that enough of each phase remains")
    if k.size == 0:
        findings.append(f"the reference has no two finite rows {REF_AGREEMENT_WINDOW_S:g} s apart: its agreement "
                        f"with the gyroscope cannot be checked")
    elif median_diff > REF_GYRO_MEDIAN_MAX_RAD_S:
        findings.append(f"the reference's angular rate differs from the gyroscope's by {median_diff:.3g} rad/s "
                        f"(median; 95th percentile {p95_diff:.3g}): the reference is not aligned to the IMU, "
                        f"offset in time, noisy, of another node, or the gyro is biased; align (and synchronise) "
                        f"them before scoring")
    if jump_times.size:
        listed = ", ".join(f"{t:.6g}" for t in jump_times[:_JUMPS_LISTED])
        more = ", …" if jump_times.size > _JUMPS_LISTED else ""
        findings.append(f"the reference jumps {jump_times.size} time(s) (a step turning > {REF_JUMP_MIN_DEG:g}° and "
                        f"> {REF_JUMP_RATIO:g} × the gyroscope's turn; at t = {listed}{more} s): marker swaps or "
                        f"mislabelled markers; set the reference to NaN over the affected segments before scoring")


def _rotation_vector(q_from: np.ndarray, q_to: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, body frame of ``q_from``) of ``q_from* ⊗ q_to``, unit quaternions (n, 4)."""
    if q_from.shape[0] == 0:
        return np.zeros((0, 3))
    return quat_ops.to_scipy(quat_ops.multiply(quat_ops.conjugate(q_from), q_to)).as_rotvec()


def _magnetic_field(mag, row, findings) -> None:
    norm = np.linalg.norm(mag, axis=-1)
    median, p5, p95 = (float(v) for v in np.percentile(norm, [50.0, 5.0, 95.0]))
    spread = (p95 - p5) / median if median > 0.0 else np.inf
    disturbed = float(np.mean(np.abs(norm - median) > MAG_DISTURBED_FRACTION * median))
    row |= {"mag_norm_median_uT": median, "mag_norm_p5_uT": p5, "mag_norm_p95_uT": p95,
            "mag_norm_spread": spread, "mag_disturbed_share": disturbed}
    if spread > MAG_SPREAD_MAX or disturbed > MAG_DISTURBED_SHARE_MAX:
        findings.append(f"the magnetic field's norm ranges from {p5:.3g} to {p95:.3g} µT (5th–95th percentile, "
                        f"median {median:.3g}), {disturbed:.1%} of the samples off the median by more than "
                        f"{MAG_DISTURBED_FRACTION:.0%}: a disturbed field (iron, electronics) or an uncalibrated "
                        f"magnetometer (a norm that follows the orientation: calibrate hard and soft iron); "
                        f"use a filter that rejects magnetic disturbances, or none for the heading")


def _units(signals, row, findings) -> None:
    problems = imu_unit_problems(signals["gyr"], signals["acc"], signals.get("mag"), gravity=STANDARD_GRAVITY)
    implausible = implausible_samples(signals)
    share = 0.0 if implausible is None else float(np.mean(implausible))
    row |= {"implausible_share": share, "units_problem": "; ".join(problems)}
    findings += problems
    if share > 0.0:
        limits = ", ".join(f"|{name}| > {SAMPLE_NORM_MAX[name]:g}" for name in signals)
        findings.append(f"{share:.2%} of the samples hold a reading no body-worn sensor gives ({limits}; rad/s, "
                        f"m/s², µT): the filters treat them as lost; find out what wrote them")
    if "mag" in signals:
        problem = magnetometer_problem(signals["mag"], np.ones(signals["mag"].shape[0], dtype=bool)) or ""
        row["mag_problem"] = problem
        if problem:
            findings.append(f"{problem}: the heading cannot rest on it; use the filters without mag")

