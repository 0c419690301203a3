"""Tests for wsnlib.orientation.loss_handling: eq. (3), the λ schedules and every option of
estimate_orientation (method, gap, replay, output_on_lost, blend).

References: :func:`wsnlib.orientation.madgwick` (the baseline), and a slow per-sample
restatement of each option's documented rule built from :func:`madgwick_step`,
:func:`triad` and :func:`wsnlib.quaternion.slerp`, which replays gyroscope gaps literally at
their end.  The vocabulary across filters: test_loss_vocabulary.py.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.loss import burst_mask, gilbert_elliott, lost_run_length, packets_to_samples
from wsnlib.orientation import (
    _kernels,
    effective_lost_run,
    estimate_orientation,
    madgwick,
    madgwick_step,
    slerp_weight,
    triad,
)
from wsnlib.orientation._batch import BLENDS
from wsnlib.orientation.lost_run import SCHEDULES
from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu

FS = 50.0
G_ENU = frames.gravity_specific_force_enu()
M_ENU = frames.magnetic_field_enu()


def mask_of(text: str) -> np.ndarray:
    return np.array([c == "1" for c in text])


def angle_deg(q_a, q_b):
    return np.degrees(Q.angle_between(q_a, q_b))


@pytest.fixture(scope="module")
def arm():
    """Simulated humerus of the paper's arm extension (300 samples), 4 Monte Carlo runs."""
    truth = arm_kinematics(arm_extension(fs=FS))
    imu = simulate_imu(truth, rng=np.random.default_rng(7), n_runs=4)
    return truth.quat[0], imu.gyr[:, 0], imu.acc[:, 0], imu.mag[:, 0]


@pytest.fixture(scope="module")
def masks():
    """Bursty masks (4, 300) with gaps at the start and at the end of some rows."""
    rng = np.random.default_rng(3)
    packets = gilbert_elliott(50, 0.25, 3.0, rng=rng, shape=(4,))
    packets[0, :2] = False  # gap at the start
    packets[1, -2:] = False  # gap at the end
    packets[2, 10:12] = [False, True]  # isolated loss then back-to-back gaps
    packets[2, 12:14] = False
    return packets_to_samples(packets, 6, 300)


def rotation_at_rate(rate_fn, n, q_start=None, axis=(1.0, 2.0, -0.5)):
    """Noise-free data for a rotation about a fixed body axis at rate ``rate_fn(t)`` (rad/s).

    Returns true quaternions (n, 4) and gyr, acc, mag (n, 3); exact, since the axis is fixed.
    """
    t = np.arange(n) / FS
    axis = np.asarray(axis) / np.linalg.norm(axis)
    fine = np.linspace(0.0, t[-1], 20 * (n - 1) + 1)
    angle = np.concatenate([[0.0], np.cumsum(np.diff(fine) * 0.5 * (rate_fn(fine[1:]) + rate_fn(fine[:-1])))])
    q_start = Q.normalize([0.9, 0.1, -0.3, 0.2]) if q_start is None else q_start
    q = Q.multiply(q_start, Q.from_rotation_vector(angle[::20, None] * axis))
    gyr = rate_fn(t)[:, None] * axis
    return q, gyr, Q.rotate_inverse(q, G_ENU), Q.rotate_inverse(q, M_ENU)


# ================================================================ eq. (3)


def test_slerp_weight_known_values():
    assert slerp_weight(0, 2, 6) == 1.0
    assert slerp_weight(12, 2, 6) == pytest.approx(0.5)  # μ = 1/2 at λ = ρτ
    assert slerp_weight(24, 3, 2) == pytest.approx(3 / 15)
    lam = np.arange(50.0)
    np.testing.assert_allclose(slerp_weight(lam, 2, 6), 12 / (lam + 12), rtol=1e-15)
    # Eq. (5) prints ρ/(λ + ρ): eq. (3) with τ = 1.
    np.testing.assert_allclose(slerp_weight(lam, 4, 1), 4 / (lam + 4), rtol=1e-15)
    assert slerp_weight(1e12, 2, 6) < 1e-10
    assert slerp_weight(lam[:, None, None], [1, 2, 3], [[1], [2]]).shape == (50, 2, 3)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0, 1e6),
    st.floats(1e-3, 1e6),
    st.floats(1e-3, 1e3),
    st.floats(1e-3, 1e3),
    st.floats(1.01, 10.0),
)
def test_slerp_weight_monotone(lam, extra, rho, tau, factor):
    mu = slerp_weight(lam, rho, tau)
    assert 0.0 < mu <= 1.0
    assert slerp_weight(lam + extra, rho, tau) < mu or mu < 1e-12  # falls with λ
    if lam > 0:
        assert slerp_weight(lam, rho * factor, tau) >= mu  # rises with ρ
        assert slerp_weight(lam, rho, tau * factor) >= mu  # rises with τ
        assert slerp_weight(lam, rho * factor, tau) > mu or mu > 1 - 1e-12


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"rho": 0}, "rho"),
        ({"rho": -1.0}, "rho"),
        ({"rho": np.nan}, "rho"),
        ({"rho": np.inf}, "rho"),
        ({"tau": 0}, "tau"),
        ({"tau": [1.0, -2.0]}, "tau"),
        ({"tau": np.nan}, "tau"),
        ({"tau": np.inf}, "tau"),
        ({"lost_run": -1}, "lost_run"),
        ({"lost_run": np.inf}, "lost_run"),
        ({"lost_run": np.nan}, "lost_run"),
        ({"lost_run": np.ones(3), "rho": np.ones(4)}, "rho"),
    ],
)
def test_slerp_weight_errors(kwargs, name):
    with pytest.raises(ValueError, match=name):
        slerp_weight(**({"lost_run": 3.0, "rho": 2.0, "tau": 6.0} | kwargs))


# ================================================================ λ schedules

SCHEDULE_TABLE = [
    # mask, decay, hold (window 3), instant
    ("111111", [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]),
    ("0000", [1, 2, 3, 4], [1, 2, 3, 4], [1, 2, 3, 4]),
    ("0011111", [1, 2, 2, 1, 0, 0, 0], [1, 2, 2, 2, 2, 0, 0], [1, 2, 0, 0, 0, 0, 0]),
    ("1111100", [0, 0, 0, 0, 0, 1, 2], [0, 0, 0, 0, 0, 1, 2], [0, 0, 0, 0, 0, 1, 2]),
    ("1000111111", [0, 1, 2, 3, 3, 2, 1, 0, 0, 0], [0, 1, 2, 3, 3, 3, 3, 0, 0, 0], [0, 1, 2, 3, 0, 0, 0, 0, 0, 0]),
    # Back to back: the second gap adds to what is left of the first.
    (
        "1000110011111",
        [0, 1, 2, 3, 3, 2, 3, 4, 4, 3, 2, 1, 0],
        [0, 1, 2, 3, 3, 3, 4, 5, 5, 5, 5, 0, 0],
        [0, 1, 2, 3, 0, 0, 1, 2, 0, 0, 0, 0, 0],
    ),
    # A second gap after the hold window has expired starts from 0 again.
    (
        "10011110011",
        [0, 1, 2, 2, 1, 0, 0, 1, 2, 2, 1],
        [0, 1, 2, 2, 2, 2, 0, 1, 2, 2, 2],
        [0, 1, 2, 0, 0, 0, 0, 1, 2, 0, 0],
    ),
    ("0101", [1, 1, 2, 2], [1, 1, 2, 2], [1, 0, 1, 0]),
]


@pytest.mark.parametrize("text, decay, hold, instant", SCHEDULE_TABLE)
def test_schedules_table(text, decay, hold, instant):
    mask = mask_of(text)
    np.testing.assert_array_equal(effective_lost_run(mask), decay)
    np.testing.assert_array_equal(effective_lost_run(mask, "decay"), decay)
    np.testing.assert_array_equal(effective_lost_run(mask, "hold", hold_window=3), hold)
    np.testing.assert_array_equal(effective_lost_run(mask, "instant"), instant)
    assert effective_lost_run(mask).dtype == float


def test_schedules_on_lost_samples_count_and_instant_is_lost_run_length(masks):
    np.testing.assert_array_equal(effective_lost_run(masks, "instant"), lost_run_length(masks))
    for schedule, kwargs in (("decay", {}), ("hold", {"hold_window": 20})):
        lam = effective_lost_run(masks, schedule, **kwargs)
        assert np.all(lam >= lost_run_length(masks))
        # On a lost sample λ grows by one; after a long enough run of receptions it is 0.
        prev = np.concatenate([np.zeros((4, 1)), lam[:, :-1]], axis=1)
        np.testing.assert_array_equal(lam[~masks], prev[~masks] + 1)


def test_hold_default_window_and_gap_length():
    mask = np.ones(200, bool)
    mask[10:34] = False
    lam = effective_lost_run(mask, "hold")
    np.testing.assert_array_equal(lam[34 : 34 + 50], 24.0)
    np.testing.assert_array_equal(lam[34 + 50 :], 0.0)
    lam = effective_lost_run(mask, "decay")
    np.testing.assert_array_equal(lam[34:59], np.arange(24.0, -1.0, -1.0))


def test_schedules_vectorised_over_batch_and_window(masks):
    windows = np.array([[1], [5], [40]])  # (3, 1) against masks (4, T)
    lam = effective_lost_run(masks, "hold", hold_window=windows)
    assert lam.shape == (3, 4, 300)
    for i, w in enumerate(windows[:, 0]):
        for j in range(4):
            np.testing.assert_array_equal(lam[i, j], effective_lost_run(masks[j], "hold", hold_window=int(w)))
    decay = effective_lost_run(masks)
    for j in range(4):
        np.testing.assert_array_equal(decay[j], effective_lost_run(masks[j]))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"schedule": "linear"}, "schedule.*'decay'.*'hold'.*'instant'"),
        ({"schedule": "hold", "hold_window": 0}, "hold_window"),
        ({"schedule": "hold", "hold_window": -3}, "hold_window"),
        ({"schedule": "hold", "hold_window": 2.5}, "hold_window"),
        ({"schedule": "hold", "hold_window": True}, "hold_window"),
        ({"schedule": "decay", "hold_window": 10}, "hold_window"),
        ({"received": np.ones(5)}, "received"),
        ({"schedule": "hold", "hold_window": np.ones(3, int), "received": np.ones((4, 5), bool)}, "hold_window"),
    ],
)
def test_effective_lost_run_errors(kwargs, name):
    with pytest.raises(ValueError, match=name):
        effective_lost_run(**({"received": np.ones(5, bool)} | kwargs))


# ================================================================ SLERP helper


def _slerp_first(q_a, q_b, mu):
    """The compiled SLERP sample by sample, component axis first (4, N)."""
    mu = np.broadcast_to(mu, q_a.shape[1:])
    return np.array([_kernels.slerp(tuple(a), tuple(b), float(m))
                     for a, b, m in zip(q_a.T, q_b.T, mu, strict=True)]).T


def test_compiled_slerp_matches_quaternion_slerp(rng):
    q_a = Q.normalize(rng.normal(size=(500, 4)))
    q_b = Q.normalize(rng.normal(size=(500, 4)))
    q_b[:5] = q_a[:5] + 1e-9  # the small-angle branch
    mu = rng.random(500)
    mu[5:10] = [0.0, 1.0, 0.0, 1.0, 0.5]
    ours = _slerp_first(q_a.T, q_b.T, mu).T
    ref = Q.slerp(q_a, q_b, mu)
    np.testing.assert_allclose(np.abs(np.sum(ours * ref, axis=-1)), 1.0, atol=1e-12)
    assert np.all(np.sum(ours * q_b, axis=-1) >= -1e-12)  # stays in q_b's hemisphere
    np.testing.assert_allclose(_slerp_first(q_a.T, q_b.T, 1.0).T[10:], q_b[10:], atol=1e-15, rtol=0)


# ================================================================ estimate_orientation: baselines

#: Options of estimate_orientation (the vocabulary of wsnlib.orientation), each a dict of keywords.
OPTIONS = {
    "madgwick": {},
    "dt_extension": {"method": "dt_extension"},
    "replay": {"replay": True},
    "adaptive_beta": {"method": "adaptive_beta"},
    "blend output": {"blend": "output"},
    "blend feedback": {"blend": "feedback"},
    "adaptive_beta + blend": {"method": "adaptive_beta", "blend": "feedback"},
    "constant_rate": {"gap": "constant_rate"},
    "constant_rate + replay": {"gap": "constant_rate", "replay": True},
    "constant_rate, output held": {"gap": "constant_rate", "output_on_lost": "hold"},
    "replay + blend": {"replay": True, "blend": "output"},
}


def uses_mu(options):
    """Whether the options use μ of eq. (3) (ρ, τ, schedule, hold_window): the hybrid and adaptive β."""
    return "blend" in options or options.get("method") == "adaptive_beta"


def holds_on_lost(options):
    """Whether the output on a lost sample is the previous output (the state holds, or the output does)."""
    return options.get("gap", "hold") == "hold" or options.get("output_on_lost") == "hold"


ALL_VARIANTS = [(name, schedule) for name, options in OPTIONS.items()
                for schedule in (SCHEDULES if uses_mu(options) else (None,))]


def variant_kwargs(name, schedule):
    kwargs = dict(OPTIONS[name])
    if schedule is not None:
        kwargs["schedule"] = schedule
        if schedule == "hold":
            kwargs["hold_window"] = 7
    return kwargs


@pytest.mark.parametrize("name, schedule", ALL_VARIANTS)
@pytest.mark.parametrize("with_q0", [False, True])
def test_no_loss_every_option_equals_madgwick(arm, name, schedule, with_q0):
    _, gyr, acc, mag = arm
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2]) if with_q0 else None
    ref = madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=q0)
    kwargs = variant_kwargs(name, schedule)
    for received in (None, np.ones(300, bool)):
        out, mu = estimate_orientation(
            gyr, acc, mag, fs=FS, beta=0.1, q0=q0, received=received, return_weight=True, **kwargs
        )
        np.testing.assert_allclose(out, ref, atol=1e-12, rtol=0)
        np.testing.assert_array_equal(mu, 1.0)


@pytest.mark.parametrize("with_q0", [False, True])
@pytest.mark.parametrize("form", ["MARG", "IMU"])
def test_the_defaults_are_madgwick_with_the_mask(arm, masks, with_q0, form):
    """Every option at its default is the paper's receiver ("hold last"): madgwick itself."""
    _, gyr, acc, mag = arm
    mag = mag if form == "MARG" else None
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2]) if with_q0 else None
    ref = madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=masks, q0=q0)
    out = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, q0=q0)
    np.testing.assert_allclose(out, ref, atol=1e-12, rtol=0)
    spelled = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, q0=q0, method="madgwick",
                                   gap="hold", replay=False, output_on_lost="estimate", blend=None)
    np.testing.assert_array_equal(spelled, out)


@pytest.mark.parametrize("name, schedule", [v for v in ALL_VARIANTS if holds_on_lost(OPTIONS[v[0]])])
def test_lost_samples_hold_the_previous_output(arm, masks, name, schedule):
    _, gyr, acc, mag = arm
    gyr, acc, mag = gyr.copy(), acc.copy(), mag.copy()
    gyr[~masks], acc[~masks] = np.nan, 0.0  # lost samples are never read
    out = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, **variant_kwargs(name, schedule))
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    b, t = np.nonzero(~masks[:, 1:])
    np.testing.assert_array_equal(out[b, t + 1], out[b, t])
    # Row 0 starts with a gap: it holds the initial estimate, TRIAD of the first received sample.
    first = np.argmax(masks[0])
    np.testing.assert_allclose(np.abs(np.sum(out[0, :first] * triad(acc[0, first], mag[0, first]), -1)), 1.0)


def test_constant_rate_moves_on_lost_samples_and_never_reads_them(arm, masks):
    _, gyr, acc, mag = arm
    poisoned = [np.where(masks[..., None], x, np.nan) for x in (gyr, acc, mag)]
    out = estimate_orientation(*poisoned, fs=FS, beta=0.1, received=masks, gap="constant_rate")
    np.testing.assert_array_equal(out, estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks,
                                                            gap="constant_rate"))
    b, t = np.nonzero(~masks[:, 1:] & masks[:, :-1])  # first lost sample of each gap after a received one
    assert np.min(angle_deg(out[b, t + 1], out[b, t])) > 1e-6


# ================================================================ slow reference


def reference(
    gyr,
    acc,
    mag,
    mask,
    *,
    method="madgwick",
    replay=False,
    gap="hold",
    gap_time_constant=None,
    output_on_lost="estimate",
    blend=None,
    schedule="decay",
    hold_window=None,
    fs=FS,
    beta=0.1,
    rho=2.0,
    tau=6.0,
    beta_max=None,
    q0=None,
):
    """One recording, sample by sample, following each option's documented rule literally."""
    dt = 1.0 / fs
    n = len(mask)
    first = int(np.argmax(mask))
    gap_mask = mask | (np.arange(n) < first) if q0 is None else mask
    mu = slerp_weight(effective_lost_run(gap_mask, schedule, hold_window), rho, tau)
    beta_max = 10 * beta if beta_max is None else beta_max
    factor = 1.0 if gap_time_constant is None else np.exp(-dt / gap_time_constant)
    q = triad(acc[first], mag[first]) if q0 is None else q0
    shown, run, last, out = q, 0, None, []
    q_last, w_gap = q, np.zeros(3)  # the state at the last received sample, the rate a predicted gap turns at
    for t in range(n):
        if q0 is None and t <= first:
            out.append(q)
            last = t
            continue
        if not mask[t]:
            run += 1
            if gap == "constant_rate" and last is not None:  # dead reckoning, gyroscope only
                w_gap = w_gap * factor
                q = madgwick_step(q, w_gap, [0.0, 0.0, 1.0], None, dt, 0.0)
                shown = q
            out.append(out[-1] if output_on_lost == "hold" and out else shown)
            continue
        if replay and run > 0:  # re-run the gap now from the state at its start, gyro only
            q = q_last
            for s in range(t - run, t):
                w = gyr[t] if last is None else gyr[last] + (gyr[t] - gyr[last]) * (s - last) / (t - last)
                q = madgwick_step(q, w, [0.0, 0.0, 1.0], None, dt, 0.0)
        # dt_extension: the gyroscope term over (1 + run)Δt, the correction over Δt.
        w = gyr[t] * (1 + run) if method == "dt_extension" else gyr[t]
        b = beta + (beta_max - beta) * (1 - mu[t]) if method == "adaptive_beta" else beta
        q = madgwick_step(q, w, acc[t], None if mag is None else mag[t], dt, b)
        shown = q
        if blend is not None and mu[t] < 1:
            q_f = Q.slerp(triad(acc[t], mag[t]), q, mu[t])
            shown = q_f
            if blend == "feedback":
                q = q_f
        out.append(shown)
        run, last, q_last, w_gap = 0, t, q, gyr[t]
    return np.array(out)


REFERENCE_CASES = [
    {},
    {"method": "dt_extension"},
    {"replay": True},
    {"method": "adaptive_beta"},
    {"method": "adaptive_beta", "schedule": "hold", "hold_window": 10, "beta_max": 0.5},
    {"blend": "output"},
    {"blend": "feedback"},
    {"blend": "output", "schedule": "hold", "hold_window": 20, "rho": 1.0, "tau": 3.0},
    {"blend": "feedback", "schedule": "hold", "hold_window": 20},
    {"gap": "constant_rate"},
    {"gap": "constant_rate", "gap_time_constant": 0.1},
    {"gap": "constant_rate", "replay": True},
    {"gap": "constant_rate", "output_on_lost": "hold"},
    {"output_on_lost": "hold", "replay": True, "blend": "feedback"},
    {"replay": True, "blend": "output", "gap": "constant_rate"},
    {"method": "adaptive_beta", "blend": "output"},
    {"method": "adaptive_beta", "blend": "feedback", "gap": "constant_rate", "replay": True},
]


@pytest.mark.parametrize("case", REFERENCE_CASES, ids=lambda c: "-".join(str(v) for v in c.values()) or "defaults")
@pytest.mark.parametrize("with_q0", [False, True])
def test_batch_filter_equals_slow_reference(arm, masks, case, with_q0):
    """Includes the equivalence of the one-pass compiled replay with a replay at the gap's end."""
    _, gyr, acc, mag = arm
    n = 150
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2]) if with_q0 else None
    out = estimate_orientation(
        gyr[:, :n], acc[:, :n], mag[:, :n], fs=FS, beta=0.1, received=masks[:, :n], q0=q0, **case
    )
    for i in range(4):
        ref = reference(gyr[i, :n], acc[i, :n], mag[i, :n], masks[i, :n], q0=q0, **case)
        assert np.max(angle_deg(out[i], ref)) < 1e-9


@pytest.mark.parametrize("case", [{"method": "dt_extension"}, {"replay": True}, {"method": "adaptive_beta"},
                                  {"gap": "constant_rate"}, {"gap": "constant_rate", "replay": True}],
                         ids=lambda c: "-".join(str(v) for v in c.values()))
def test_imu_form_equals_slow_reference(arm, masks, case):
    _, gyr, acc, _ = arm
    n = 120
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2])
    out = estimate_orientation(
        gyr[:, :n], acc[:, :n], None, fs=FS, beta=0.1, received=masks[:, :n], q0=q0, **case
    )
    for i in range(4):
        ref = reference(gyr[i, :n], acc[i, :n], None, masks[i, :n], q0=q0, **case)
        assert np.max(angle_deg(out[i], ref)) < 1e-9


# ================================================================ the options do what they promise


def test_dt_extension_recovers_constant_rate_motion():
    q_true, gyr, acc, mag = rotation_at_rate(lambda t: np.full_like(t, 1.0), 200)
    mask = burst_mask(200, 80, 4, align="exact")  # samples 80-103 lost
    kwargs = {"fs": FS, "beta": 0.05, "received": mask}
    hold = estimate_orientation(gyr, acc, mag, **kwargs)
    ext = estimate_orientation(gyr, acc, mag, method="dt_extension", **kwargs)
    err_hold, err_ext = angle_deg(hold, q_true)[104], angle_deg(ext, q_true)[104]
    assert err_hold > 20.0  # 24 samples at 1 rad/s ≈ 27°, minus one correction step
    assert err_ext < 1.0  # first-order step over 0.5 rad: 2·atan(0.25) = 0.49 rad
    assert err_ext < 0.05 * err_hold


@pytest.mark.parametrize("rate", [lambda t: np.full_like(t, 1.0), lambda t: 0.2 + 0.6 * t], ids=["constant", "linear"])
def test_replay_recovers_the_missed_rotation(rate):
    """Paper 001's gyroscope interpolation (replay=True) recovers what the gap turned."""
    q_true, gyr, acc, mag = rotation_at_rate(rate, 200)
    mask = burst_mask(200, 80, 4, align="exact")
    kwargs = {"fs": FS, "beta": 0.05, "received": mask}
    hold = estimate_orientation(gyr, acc, mag, **kwargs)
    interp = estimate_orientation(gyr, acc, mag, replay=True, **kwargs)
    lossless = madgwick(gyr, acc, mag, fs=FS, beta=0.05)
    err_hold, err_interp = angle_deg(hold, q_true)[104], angle_deg(interp, q_true)[104]
    assert err_hold > 15.0
    assert err_interp < 0.05 * err_hold
    # Exact interpolation of ω: as good as never losing anything, up to the skipped corrections.
    assert angle_deg(interp, lossless)[104] < 0.5
    # Held during the gap (gap="hold"): nothing is known there yet.
    np.testing.assert_array_equal(interp[80:104], np.broadcast_to(interp[79], (24, 4)))


def test_constant_rate_recovers_constant_rate_motion_and_replay_ignores_the_prediction():
    q_true, gyr, acc, mag = rotation_at_rate(lambda t: 0.2 + 0.6 * t, 200)
    mask = burst_mask(200, 80, 4, align="exact")
    kwargs = {"fs": FS, "beta": 0.05, "received": mask}
    hold = estimate_orientation(gyr, acc, mag, **kwargs)
    predicted = estimate_orientation(gyr, acc, mag, gap="constant_rate", **kwargs)
    err_hold, err_pred = angle_deg(hold, q_true)[80:104], angle_deg(predicted, q_true)[80:104]
    assert err_hold[-1] > 15.0 and err_pred[-1] < 0.3 * err_hold[-1]  # the rate rose in the gap: not exact
    # The replay starts from the state at the gap's start: what the state did in the gap no longer matters.
    replay_hold = estimate_orientation(gyr, acc, mag, replay=True, **kwargs)
    replay_pred = estimate_orientation(gyr, acc, mag, gap="constant_rate", replay=True, **kwargs)
    np.testing.assert_array_equal(replay_pred[80:104], predicted[80:104])  # causal: the gap's output stays
    np.testing.assert_allclose(replay_pred[104:], replay_hold[104:], atol=1e-12, rtol=0)
    assert angle_deg(replay_pred, q_true)[104] < angle_deg(predicted, q_true)[104]


def test_adaptive_beta_recovers_faster_than_plain_madgwick(arm):
    q_true, gyr, acc, mag = arm
    mask = burst_mask(300, 80, 4)  # samples 84-107 lost, the paper's case
    kwargs = {"fs": FS, "beta": 0.1, "received": mask}
    hold = angle_deg(estimate_orientation(gyr, acc, mag, **kwargs), q_true)
    adapt = angle_deg(estimate_orientation(gyr, acc, mag, method="adaptive_beta", **kwargs), q_true)
    after = slice(113, 160)  # from a few samples after the gap until the arm is up
    assert np.mean(adapt[:, after]) < 0.6 * np.mean(hold[:, after])
    # Same before the gap: β_eff = β while nothing has been lost.
    np.testing.assert_allclose(adapt[:, :84], hold[:, :84], atol=1e-12)


@pytest.mark.parametrize("blend", BLENDS)
def test_hybrid_with_mu_near_zero_outputs_triad_after_a_gap(arm, blend):
    _, gyr, acc, mag = arm
    mask = burst_mask(300, 80, 4)
    out, mu = estimate_orientation(
        gyr, acc, mag, fs=FS, beta=0.1, received=mask, rho=1e-9, blend=blend, return_weight=True
    )
    after = (mu < 1.0) & mask  # received samples with λ_eff > 0: the 24 after the gap (decay)
    assert after.sum() == 4 * 24
    b, t = np.nonzero(after)
    assert np.max(angle_deg(out[b, t], triad(acc[b, t], mag[b, t]))) < 1e-6
    # Before the gap, μ = 1: plain Madgwick.
    np.testing.assert_allclose(out[:, :84], madgwick(gyr, acc, mag, fs=FS, beta=0.1)[:, :84], atol=1e-12)


def test_hybrid_feedback_and_output_differ_only_after_a_gap(arm):
    _, gyr, acc, mag = arm
    mask = burst_mask(300, 80, 4)
    kwargs = {"fs": FS, "beta": 0.1}
    output = estimate_orientation(gyr, acc, mag, received=mask, blend="output", **kwargs)
    feedback = estimate_orientation(gyr, acc, mag, received=mask, blend="feedback", **kwargs)
    np.testing.assert_allclose(output[:, :108], feedback[:, :108], atol=1e-12)  # up to the first blend
    assert np.min(np.max(angle_deg(output[:, 108:], feedback[:, 108:]), axis=-1)) > 0.5
    # Long after the gap (μ = 1 again) output-blend is exactly Madgwick's run.
    np.testing.assert_allclose(
        output[:, 132:], madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=mask)[:, 132:], atol=1e-12
    )


def test_blend_with_adaptive_beta_blends_the_adaptive_state(arm):
    """blend="output" on adaptive β: the state is adaptive β's, the output its SLERP towards TRIAD."""
    _, gyr, acc, mag = arm
    mask = burst_mask(300, 80, 4)
    kwargs = {"fs": FS, "beta": 0.1, "received": mask, "method": "adaptive_beta"}
    adaptive = estimate_orientation(gyr, acc, mag, **kwargs)
    both, mu = estimate_orientation(gyr, acc, mag, blend="output", return_weight=True, **kwargs)
    blended = (mu < 1.0) & mask
    np.testing.assert_array_equal(both[~blended], adaptive[~blended])
    b, t = np.nonzero(blended)
    ref = Q.slerp(triad(acc[b, t], mag[b, t]), adaptive[b, t], mu[b, t])
    assert np.max(angle_deg(both[b, t], ref)) < 1e-9
    assert np.max(angle_deg(both[b, t], adaptive[b, t])) > 0.5


@pytest.mark.parametrize("blend", ["output", "feedback"])
def test_hybrid_on_one_unbatched_recording_equals_its_row_of_a_batch(arm, blend):
    _, gyr, acc, mag = arm
    mask = burst_mask(300, 80, 4)
    kwargs = {"fs": FS, "beta": 0.1, "blend": blend, "received": mask}
    batched = estimate_orientation(gyr, acc, mag, **kwargs)
    one = estimate_orientation(gyr[1], acc[1], mag[1], **kwargs)  # (T, 3) signals: no batch dimension
    assert one.shape == (300, 4)
    np.testing.assert_allclose(one, batched[1], atol=1e-12)


@pytest.mark.parametrize(
    "case",
    [
        {"blend": "output"},
        {"blend": "feedback"},
        {"method": "adaptive_beta"},
        {"method": "adaptive_beta", "blend": "feedback"},
        {"blend": "feedback", "schedule": "hold", "hold_window": np.array([[[5]], [[30]]])},
        {"blend": "output", "schedule": "hold", "hold_window": np.array([[[5]], [[30]]])},
    ],
    ids=["output", "feedback", "adaptive_beta", "adaptive_beta-feedback", "feedback-hold", "output-hold"],
)
def test_parameter_grid_in_one_pass_equals_separate_runs(arm, masks, case):
    _, gyr, acc, mag = arm
    rho = np.array([1.0, 4.0]).reshape(2, 1, 1)
    tau = np.array([1.0, 3.0, 10.0]).reshape(1, 3, 1)
    beta = np.array([0.05, 0.1, 0.2, 0.1])  # one per run
    n = 120
    data = (gyr[:, :n], acc[:, :n], mag[:, :n])
    out, mu = estimate_orientation(
        *data, fs=FS, beta=beta, received=masks[:, :n], rho=rho, tau=tau, return_weight=True, **case
    )
    assert out.shape == (2, 3, 4, n, 4)
    assert mu.shape == (2, 3, 4, n)
    for i in range(2):
        for j in range(3):
            one = case | ({"hold_window": int(case["hold_window"][i, 0, 0])} if "hold_window" in case else {})
            ref = estimate_orientation(
                *data, fs=FS, beta=beta, received=masks[:, :n], rho=rho[i, 0, 0], tau=tau[0, j, 0], **one
            )
            np.testing.assert_allclose(out[i, j], ref, atol=1e-12)


def test_options_without_mu_are_not_broadcast_over_rho(arm, masks):
    """With return_weight, ρ shapes μ only; the quaternions of an option without μ keep their shape."""
    _, gyr, acc, mag = arm
    rho = np.ones((5, 1))
    for options in ({}, {"method": "dt_extension"}, {"replay": True}, {"gap": "constant_rate"}):
        out, mu = estimate_orientation(
            gyr, acc, mag, fs=FS, beta=0.1, received=masks, rho=rho, return_weight=True, **options
        )
        assert out.shape == (4, 300, 4)
        assert mu.shape == (5, 4, 300)
    out = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, blend="output", rho=rho)
    assert out.shape == (5, 4, 300, 4)


@pytest.mark.parametrize("name", list(OPTIONS))
def test_empty_recording_with_q0(name):
    q0 = [1.0, 0.0, 0.0, 0.0]
    empty = np.zeros((3, 0, 3))
    out, mu = estimate_orientation(empty, empty, empty, fs=FS, beta=0.1, q0=q0, return_weight=True,
                                   received=np.zeros((3, 0), bool), **OPTIONS[name])
    assert out.shape == (3, 0, 4)
    assert mu.shape == (3, 0)


def test_deterministic(arm, masks):
    _, gyr, acc, mag = arm
    kwargs = {"fs": FS, "beta": 0.1, "received": masks, "blend": "feedback", "gap": "constant_rate", "replay": True}
    np.testing.assert_array_equal(
        estimate_orientation(gyr, acc, mag, **kwargs), estimate_orientation(gyr, acc, mag, **kwargs)
    )


# ================================================================ errors


#: The hybrid, which uses ρ, τ, schedule and hold_window (without it they are refused: test_loss_vocabulary.py).
H = {"blend": "output"}


@pytest.mark.parametrize(
    "change, name",
    [
        ({"method": "slerp"}, "method.*'madgwick'.*'dt_extension'.*'adaptive_beta'"),
        ({"method": None}, "method"),
        ({**H, "schedule": "exp"}, "schedule.*'decay'"),
        ({"blend": "both"}, "blend.*'output'.*'feedback'"),
        ({"gap": "linear"}, "gap.*'hold'.*'constant_rate'"),
        ({"gap": "hold", "gap_rate_prediction_window_s": 3.0}, "gap_rate_prediction_window_s only apply to gap=.ar."),
        ({"output_on_lost": "previous"}, "output_on_lost.*'estimate'.*'hold'"),
        ({"replay": 1}, "replay"),
        ({"replay": "yes"}, "replay"),
        ({"gap": "constant_rate", "gap_time_constant": 0.0}, "gap_time_constant"),
        ({"gap": "constant_rate", "gap_time_constant": np.nan}, "gap_time_constant"),
        ({"method": "dt_extension", "gap": "constant_rate"}, "dt_extension.*constant_rate"),
        ({"method": "dt_extension", "replay": True}, "dt_extension.*replay"),
        ({**H, "rho": 0.0}, "rho"),
        ({**H, "rho": -2.0}, "rho"),
        ({**H, "rho": np.nan}, "rho"),
        ({**H, "rho": np.inf}, "rho"),
        ({**H, "tau": 0}, "tau"),
        ({**H, "tau": np.nan}, "tau"),
        ({**H, "tau": np.inf}, "tau"),
        ({**H, "tau": np.ones(3)}, "tau"),
        ({"beta": -0.1}, "beta"),
        ({"beta": np.nan}, "beta"),
        ({"method": "adaptive_beta", "beta_max": 0.05}, "beta_max"),
        ({"method": "adaptive_beta", "beta_max": np.nan}, "beta_max"),
        ({"method": "adaptive_beta", "beta": [0.1, 0.2], "beta_max": 0.15}, "beta_max"),
        ({**H, "schedule": "hold", "hold_window": 0}, "hold_window"),
        ({**H, "schedule": "hold", "hold_window": 2.5}, "hold_window"),
        ({**H, "schedule": "hold", "hold_window": [3, -1]}, "hold_window"),
        ({**H, "hold_window": 10}, "hold_window"),
        ({**H, "mag": None}, "mag"),
        ({**H, "single_frame_gate": True, "return_weight": True}, "return_weight"),
        ({**H, "single_frame_gate": "yes"}, "single_frame_gate"),
        ({"gyr": np.zeros((2, 100, 4))}, "gyr"),
        ({"acc": np.ones((2, 99, 3))}, "acc"),
        ({"received": np.ones((2, 100))}, "received"),
        ({"received": np.ones((2, 99), bool)}, "received"),
        ({"received": np.zeros((2, 100), bool)}, "received"),
        ({"fs": 0.0}, "fs"),
        ({"fs": np.nan}, "fs"),
        ({"q0": [0.0, 0.0, 0.0, 0.0]}, "q0"),
        ({"q0": [1.0, 0.0, 0.0]}, "q0"),
    ],
)
def test_estimate_orientation_bad_input(change, name):
    good = {
        "gyr": np.zeros((2, 100, 3)),
        "acc": np.tile([0.0, 0.0, 9.8], (2, 100, 1)),
        "mag": np.tile([0.0, 20.0, -30.0], (2, 100, 1)),
        "fs": FS,
        "beta": 0.1,
        "received": np.ones((2, 100), bool),
    }
    with pytest.raises(ValueError, match=name):
        estimate_orientation(**(good | change))


@pytest.mark.parametrize(
    "old, now",
    [("hold_last", "the default"), ("gyro_interpolation", "replay=True"), ("hybrid", "blend='output'"),
     ("kalman", "kalman_orientation")],
)
def test_earlier_method_names_are_refused_with_their_new_spelling(arm, old, now):
    _, gyr, acc, mag = arm
    with pytest.raises(ValueError, match=f"method={old!r} is now .*{now}"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, method=old)


def test_beta_is_required_and_earlier_keywords_are_gone(arm):
    _, gyr, acc, mag = arm
    with pytest.raises(TypeError, match="beta"):
        estimate_orientation(gyr, acc, mag, fs=FS)
    with pytest.raises(TypeError, match="kalman_settings"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, kalman_settings=None)


def test_received_sample_errors_are_madgwicks(arm):
    _, gyr, acc, mag = arm
    acc = acc.copy()
    acc[1, 7] = 0.0
    with pytest.raises(ValueError, match="acc is a zero vector"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, method="dt_extension")
