"""wsnlib.io.alignment on a synthetic IMU + optical reference whose lag and rotations are known.

The truth: an IMU body S turns along a smooth random trajectory ``R_ES(t) = exp(θ(t))``; its gyro is the
central difference of that trajectory over 1 ms, its accelerometer ``R_ESᵀ (g ẑ + a_lin)``, its
magnetometer ``R_ESᵀ m_E``.  The reference (another lab's motion capture, 120 Hz against the IMU's
100 Hz, its clock 0.137 s behind) records a marker cluster M mounted on the IMU by a known rotation,
in a lab frame L with y up and an arbitrary heading:
``q_ref(t') = R_LE · R_ES(t' + lag) · R_SM``, with noise, marker swaps (stretches of wrong
quaternions) and 11 % NaN rows.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import frames, paths
from wsnlib import quaternion as Q
from wsnlib.io import broad
from wsnlib.io.alignment import Alignment, align_reference, estimate_alignment

FS_IMU = 100.0
FS_REF = 120.0
LAG_S = 0.137
DURATION_S = 60.0
REF_SPAN_S = (2.0, 58.0)  # the reference starts later and stops earlier than the IMU
GYRO_BIAS = np.array([0.01, -0.02, 0.015])
SWAPS_S = [(10.0, 0.3), (23.5, 0.25), (37.0, 0.4), (49.2, 0.3)]  # (start, duration) on the reference clock
TRUE_SENSOR_TO_MARKER = Rotation.from_euler("zyx", [-121.0, 34.0, 77.0], degrees=True)
# The lab: y up, x at 37° from east.  Rx(+90°) takes the lab's y (up) to ENU z.
TRUE_REFERENCE_TO_ENU = Rotation.from_euler("z", 37.0, degrees=True) * Rotation.from_euler("x", 90.0, degrees=True)


def _smooth(rng, t, n_axes, amplitude, f_lo, f_hi, n_terms=5):
    """Sum of random sinusoids per axis, shape (len(t), n_axes)."""
    freq = rng.uniform(f_lo, f_hi, (n_terms, n_axes))
    phase = rng.uniform(0.0, 2 * np.pi, (n_terms, n_axes))
    amp = amplitude * rng.uniform(0.5, 1.0, (n_terms, n_axes)) / np.sqrt(n_terms)
    return np.sum(amp * np.sin(2 * np.pi * freq * t[:, None, None] + phase), axis=1)


class Truth:
    """The smooth random trajectory R_ES(t) at any time, and its body rate."""

    def __init__(self, rng):
        self.terms = [(rng.uniform(0.05, 0.8, (5, 3)), rng.uniform(0, 2 * np.pi, (5, 3)),
                       rng.uniform(0.4, 0.9, (5, 3)))]
        self.offset = rng.normal(size=3)

    def rotvec(self, t):
        freq, phase, amp = self.terms[0]
        return self.offset + np.sum(amp * np.sin(2 * np.pi * freq * t[:, None, None] + phase), axis=1)

    def orientation(self, t) -> Rotation:  # body → ENU
        return Rotation.from_rotvec(self.rotvec(t))

    def body_rate(self, t, h=5e-4):
        return (self.orientation(t - h).inv() * self.orientation(t + h)).as_rotvec() / (2 * h)


def _scenario(seed=24):
    rng = np.random.default_rng(seed)
    truth = Truth(rng)
    t = np.arange(int(DURATION_S * FS_IMU)) / FS_IMU
    r_es = truth.orientation(t)
    linear_acc = _smooth(rng, t, 3, 0.3, 0.2, 2.0)
    gyr = truth.body_rate(t) + GYRO_BIAS + rng.normal(0, 0.005, (t.size, 3))
    acc = r_es.inv().apply(frames.gravity_specific_force_enu() + linear_acc) + rng.normal(0, 0.05, (t.size, 3))
    mag = r_es.inv().apply(frames.magnetic_field_enu()) + rng.normal(0, 0.3, (t.size, 3))

    t_ref = np.arange(REF_SPAN_S[0], REF_SPAN_S[1], 1 / FS_REF)
    r_lm = TRUE_REFERENCE_TO_ENU.inv() * truth.orientation(t_ref + LAG_S) * TRUE_SENSOR_TO_MARKER.inv()
    r_lm = r_lm * Rotation.from_rotvec(rng.normal(0, np.radians(0.2), (t_ref.size, 3)))  # marker noise
    quat_ref = Q.from_scipy(r_lm)
    swapped = np.zeros(t_ref.size, bool)
    for start, duration in SWAPS_S:  # a marker swap: the cluster's frame jumps by a large rotation
        rows = (t_ref >= start) & (t_ref < start + duration)
        wrong = Rotation.from_rotvec(rng.normal(size=3) * 0.3 + [0.0, 0.0, np.radians(rng.uniform(60, 150))])
        quat_ref[rows] = Q.from_scipy(r_lm[rows] * wrong)
        swapped |= rows
    missing = np.zeros(t_ref.size, bool)
    for start in rng.uniform(REF_SPAN_S[0], REF_SPAN_S[1] - 1.0, 8):  # occlusions
        missing |= (t_ref >= start) & (t_ref < start + rng.uniform(0.2, 0.6))
    while missing.mean() < 0.11:  # and single dropped frames
        missing[rng.integers(t_ref.size)] = True
    quat_ref[missing] = np.nan
    quat_ref = Q.canonical(quat_ref) * rng.choice([-1.0, 1.0], (t_ref.size, 1))  # q and −q mixed
    return dict(t=t, gyr=gyr, acc=acc, mag=mag, t_ref=t_ref, quat_ref=quat_ref, truth=truth, swapped=swapped,
                missing=missing)


@pytest.fixture(scope="module")
def scenario():
    return _scenario()


@pytest.fixture(scope="module")
def alignment(scenario):
    s = scenario
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the plain reading must not warn
        return estimate_alignment(s["gyr"], s["acc"], s["mag"], s["t"], s["quat_ref"], s["t_ref"])


def _angle_deg(q_wxyz, rotation: Rotation) -> float:
    return float(np.degrees((Q.to_scipy(q_wxyz) * rotation.inv()).magnitude()))


def test_the_scenario_has_what_the_test_claims(scenario):
    assert 0.11 <= scenario["missing"].mean() < 0.13
    assert 0.015 < scenario["swapped"].mean() < 0.03


def test_lag_within_half_a_sample(alignment):
    assert abs(alignment.lag_s - LAG_S) <= 0.5 / FS_IMU
    assert alignment.lag_correlation > 0.9


def test_rotations_within_one_degree(alignment):
    assert _angle_deg(alignment.sensor_to_marker, TRUE_SENSOR_TO_MARKER) < 1.0
    assert _angle_deg(alignment.reference_to_enu, TRUE_REFERENCE_TO_ENU) < 1.0
    # the quaternions are [w, x, y, z], unit, w >= 0
    for q in (alignment.sensor_to_marker, alignment.reference_to_enu):
        assert q.shape == (4,) and q[0] >= 0.0
        np.testing.assert_allclose(np.linalg.norm(q), 1.0, atol=1e-12)


def test_gyro_bias_and_diagnostics(alignment):
    np.testing.assert_allclose(alignment.gyro_bias, GYRO_BIAS, atol=0.005)
    assert not alignment.reference_read_as_inverse
    # the marker swaps (about 2 % of the reference) are found as outliers, and little else is
    assert 0.005 < alignment.rate_outlier_fraction < 0.06
    assert alignment.rate_residual_rms < 0.15 and alignment.rate_residual_median < 0.15
    assert alignment.rate_residual_p95 > alignment.rate_residual_median
    # 0.3 m/s² of linear acceleration tilts the specific force by about 1.7° at most
    assert alignment.gravity_residual_median_deg < 2.0
    assert alignment.gravity_residual_p95_deg < 4.0
    assert alignment.north_residual_median_deg < 3.0
    assert 0.0 < alignment.world_outlier_fraction < 0.1


def _aligned_error_deg(scenario, aligned):
    t = scenario["t"]
    truth = Q.from_scipy(scenario["truth"].orientation(t))
    ok = ~np.isnan(aligned[:, 0])
    error = np.full(t.size, np.nan)
    error[ok] = np.degrees(Q.angle_between(aligned[ok], truth[ok]))
    return error


def _in_swap(t_imu):
    """IMU samples whose reference time (t − lag) is inside or next to a marker swap."""
    t_ref = t_imu - LAG_S
    return np.any([(t_ref > start - 0.1) & (t_ref < start + duration + 0.1) for start, duration in SWAPS_S], axis=0)


def test_aligned_reference_matches_the_truth(scenario, alignment):
    s = scenario
    aligned = align_reference(s["quat_ref"], s["t_ref"], s["t"], alignment)
    assert aligned.shape == (s["t"].size, 4)
    error = _aligned_error_deg(s, aligned)
    clean = ~np.isnan(error) & ~_in_swap(s["t"])
    assert clean.mean() > 0.6
    assert np.median(error[clean]) < 0.5
    assert np.percentile(error[clean], 99) < 1.0


def test_aligned_reference_is_nan_where_the_reference_is_missing(scenario, alignment):
    s = scenario
    aligned = align_reference(s["quat_ref"], s["t_ref"], s["t"], alignment)
    t_ref_of_imu = s["t"] - alignment.lag_s
    outside = (t_ref_of_imu < s["t_ref"][0]) | (t_ref_of_imu > s["t_ref"][-1])
    assert np.isnan(aligned[outside]).all()
    inside = np.flatnonzero(~outside)
    left = np.searchsorted(s["t_ref"], t_ref_of_imu[inside], side="right") - 1
    right = np.minimum(left + 1, s["t_ref"].size - 1)
    neighbour_missing = s["missing"][left] | s["missing"][right]
    np.testing.assert_array_equal(np.isnan(aligned[inside, 0]), neighbour_missing)
    # whole rows are NaN or none of them, and the present rows are unit quaternions
    assert (np.isnan(aligned).all(axis=1) | ~np.isnan(aligned).any(axis=1)).all()
    present = ~np.isnan(aligned[:, 0])
    np.testing.assert_allclose(np.linalg.norm(aligned[present], axis=1), 1.0, atol=1e-12)


def test_a_time_stamp_gap_is_not_bridged(scenario, alignment):
    """Rows dropped from the reference (time stamps jump) give NaN, not a SLERP across the jump."""
    s = scenario
    keep = (s["t_ref"] < 30.0) | (s["t_ref"] >= 31.0)
    aligned = align_reference(s["quat_ref"][keep], s["t_ref"][keep], s["t"], alignment)
    t_ref_of_imu = s["t"] - alignment.lag_s
    assert np.isnan(aligned[(t_ref_of_imu > 30.0) & (t_ref_of_imu < 31.0 - 1 / FS_REF)]).all()


def test_an_inverse_reference_is_detected_and_read_as_such(scenario):
    """World → marker quaternions: the warning says so, and the lag and both rotations are recovered."""
    s = scenario
    quat = Q.conjugate(s["quat_ref"])
    with pytest.warns(UserWarning, match="only when it is read as the inverse rotation"):
        result = estimate_alignment(s["gyr"], s["acc"], s["mag"], s["t"], quat, s["t_ref"])
    assert result.reference_read_as_inverse
    assert abs(result.lag_s - LAG_S) <= 0.5 / FS_IMU
    assert _angle_deg(result.sensor_to_marker, TRUE_SENSOR_TO_MARKER) < 1.0
    assert _angle_deg(result.reference_to_enu, TRUE_REFERENCE_TO_ENU) < 1.0
    error = _aligned_error_deg(s, align_reference(quat, s["t_ref"], s["t"], result))
    clean = ~np.isnan(error) & ~_in_swap(s["t"])
    assert np.percentile(error[clean], 99) < 1.0


def test_a_scalar_last_reference_is_detected_and_still_aligns(scenario):
    """[x, y, z, w] rows: the warning names scalar-last; the rates cannot tell it from an inverse
    (module docstring), so only the lag and the aligned reference are held to the truth."""
    s = scenario
    quat = s["quat_ref"][:, [1, 2, 3, 0]]  # [w, x, y, z] → [x, y, z, w]
    with pytest.warns(UserWarning, match=r"scalar-last \[x, y, z, w\]"):
        result = estimate_alignment(s["gyr"], s["acc"], s["mag"], s["t"], quat, s["t_ref"])
    assert result.reference_read_as_inverse
    assert abs(result.lag_s - LAG_S) <= 0.5 / FS_IMU
    error = _aligned_error_deg(s, align_reference(quat, s["t_ref"], s["t"], result))
    clean = ~np.isnan(error) & ~_in_swap(s["t"])
    assert np.percentile(error[clean], 99) < 1.0
    # read as given ([w, x, y, z]), the same array would be far off
    plain = dataclasses.replace(result, reference_read_as_inverse=False)
    error = _aligned_error_deg(s, align_reference(quat, s["t_ref"], s["t"], plain))
    assert np.nanmedian(error) > 10.0


def test_the_lag_sign_and_clock_offset(scenario):
    """A reference stamped 0.4 s later than in the scenario: the lag is 0.4 s smaller."""
    s = scenario
    result = estimate_alignment(s["gyr"], s["acc"], s["mag"], s["t"], s["quat_ref"], s["t_ref"] + 0.4)
    assert abs(result.lag_s - (LAG_S - 0.4)) <= 0.5 / FS_IMU


def test_a_lag_beyond_the_search_range_is_refused(scenario):
    s = scenario
    with pytest.raises(ValueError, match="edge of the search range"):
        estimate_alignment(s["gyr"], s["acc"], s["mag"], s["t"], s["quat_ref"], s["t_ref"], max_lag_s=0.08)


def _with_nan(x):
    x = x.copy()
    x[5, 1] = np.nan
    return x


def _with_swapped_stamps(t):
    t = t.copy()
    t[[10, 11]] = t[[11, 10]]
    return t


#: (what to change, given the scenario; the error message expected)
_BAD_INPUTS = [
    (lambda s: {"gyr": s["gyr"][:, :2]}, "gyr must have shape"),
    (lambda s: {"acc": s["acc"][:-1]}, "same shape"),
    (lambda s: {"mag": s["mag"][None]}, "mag must have shape"),
    (lambda s: {"gyr": _with_nan(s["gyr"])}, "gyr contains NaN"),
    (lambda s: {"time_s": s["t"][:-1]}, "time_s must have one time stamp per sample"),
    (lambda s: {"time_s": _with_swapped_stamps(s["t"])}, "time_s must be strictly increasing"),
    (lambda s: {"quat_ref": s["quat_ref"][:, :3]}, "quat_ref must have shape"),
    (lambda s: {"quat_ref": np.full_like(s["quat_ref"], np.nan)}, "every row is NaN"),
    (lambda s: {"ref_time_s": s["t_ref"][::-1]}, "ref_time_s must be strictly increasing"),
    (lambda s: {"ref_time_s": s["t_ref"] + 500.0}, "overlap"),
    (lambda s: {"acc": s["mag"], "mag": s["acc"]}, "swapped"),
    (lambda s: {"max_lag_s": 0.0}, "max_lag_s"),
    (lambda s: {"rate_smoothing_s": -1.0}, "rate_smoothing_s"),
]


@pytest.mark.parametrize(("change", "match"), _BAD_INPUTS, ids=[match for _, match in _BAD_INPUTS])
def test_bad_inputs(scenario, change, match):
    s = scenario
    kwargs = dict(gyr=s["gyr"], acc=s["acc"], mag=s["mag"], time_s=s["t"], quat_ref=s["quat_ref"],
                  ref_time_s=s["t_ref"])
    with pytest.raises(ValueError, match=match):
        estimate_alignment(**{**kwargs, **change(s)})


def test_align_reference_bad_inputs(scenario, alignment):
    s = scenario
    with pytest.raises(ValueError, match="alignment must be an Alignment"):
        align_reference(s["quat_ref"], s["t_ref"], s["t"], {"lag_s": 0.1})
    with pytest.raises(ValueError, match="ref_time_s must have one time stamp per sample"):
        align_reference(s["quat_ref"], s["t_ref"][1:], s["t"], alignment)
    with pytest.raises(ValueError, match="time_s must be 1-D"):
        align_reference(s["quat_ref"], s["t_ref"], s["t"][:, None], alignment)
    assert isinstance(alignment, Alignment)


def test_broad_real_recording():
    """BROAD's reference comes aligned to its IMU by the dataset's authors (lag and both rotations
    near zero), and a known lag and known rotations put on it are found on top of that."""
    source = Path(os.environ.get(broad.BROAD_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "broad")
    if not (source / "02_undisturbed_slow_rotation_B.mat").exists():
        pytest.skip(f"BROAD files not found in {source}")
    trial = broad.load_broad(2, source, download=False)
    imu = (trial.gyr, trial.acc, trial.mag, trial.time_s)
    base = estimate_alignment(*imu, trial.quat_ref, trial.time_s)
    assert abs(base.lag_s) < 2.0 / trial.fs
    assert _angle_deg(base.sensor_to_marker, Rotation.identity()) < 1.0
    assert _angle_deg(base.reference_to_enu, Rotation.identity()) < 2.0
    assert not base.reference_read_as_inverse

    # q_ref'(t') = R_LE ⊗ q_ref(t' + lag) ⊗ R_MS, on the reference's own clock
    moved = Q.multiply(Q.multiply(Q.from_scipy(TRUE_REFERENCE_TO_ENU.inv()), trial.quat_ref),
                       Q.from_scipy(TRUE_SENSOR_TO_MARKER.inv()))
    result = estimate_alignment(*imu, moved, trial.time_s - LAG_S)
    assert abs(result.lag_s - (base.lag_s + LAG_S)) < 0.05 / trial.fs
    assert _angle_deg(result.sensor_to_marker, TRUE_SENSOR_TO_MARKER * Q.to_scipy(base.sensor_to_marker)) < 0.01
    assert _angle_deg(result.reference_to_enu, Q.to_scipy(base.reference_to_enu) * TRUE_REFERENCE_TO_ENU) < 0.01
