"""The loss vocabulary shared by every filter of wsnlib.orientation (its module docstring):
``gap``, ``replay``, ``output_on_lost``, ``blend`` and the keywords they use, checked across
Madgwick's family (:func:`estimate_orientation`), the Kalman filter, the smoother and the peers.

References: each filter's own output with the option off (what an option may and may not
change), and, for the replay, paper 001's gyroscope interpolation written out by hand from
:func:`madgwick_step` and a first-order quaternion integration in numpy.
"""

import functools

import numpy as np
import pytest
from _recordings import error_deg, turning_recording

from wsnlib import quaternion as Q
from wsnlib.orientation import (
    KalmanSettings,
    estimate_orientation,
    fusion_orientation,
    gaps,
    kalman_orientation,
    madgwick,
    madgwick_step,
    smooth_orientation,
    triad,
    vqf_orientation,
)
from wsnlib.orientation.loss_handling import PAPER_OPTIONS

FS = 50.0
N = 300
BETA = 0.05


def _named(function, name, **fixed):
    """``function`` with keywords ``fixed``, under ``name`` (for the ids and the messages)."""
    wrapped = functools.partial(function, **fixed)
    wrapped.__name__ = name
    return wrapped


MADGWICK = _named(estimate_orientation, "estimate_orientation", beta=BETA)
#: The Kalman filter with a short linear prediction (order 8 on 1 s), so that the gaps below
#: use both its "ar" prediction and, where less than a window precedes them, its fall-back.
KALMAN = _named(kalman_orientation, "kalman_orientation",
                settings=KalmanSettings(gap_rate_prediction_span_s=0.16, gap_rate_prediction_window_s=1.0))
SMOOTHER = _named(smooth_orientation, "smooth_orientation")
PEERS = [fusion_orientation, vqf_orientation]
#: Every filter that runs over time.
FILTERS = [MADGWICK, KALMAN, SMOOTHER, *PEERS]
#: Filters, by the ``gap`` values they support.
GAP_SUPPORT = {"estimate_orientation": ("hold", "constant_rate", "ar"),
               "kalman_orientation": ("hold", "constant_rate", "ar"),
               "smooth_orientation": ("hold", "constant_rate", "ar"),
               "fusion_orientation": ("hold", "constant_rate", "ar"),
               "vqf_orientation": ("hold", "constant_rate", "ar")}
#: The peers' linear prediction on the Kalman filter's short span and window (see KALMAN).
PEER_AR = {"gap": "ar", "gap_rate_prediction_span_s": 0.16, "gap_rate_prediction_window_s": 1.0}


def _ids(value):
    return getattr(value, "__name__", None) or "-".join(f"{k}={v}" for k, v in value.items()) or "defaults"


@pytest.fixture(scope="module")
def rec():
    """A turning sensor with slightly noisy signals, 6 s, and two masks with gaps of 6 to 24 samples:
    row 0 after 40, 120 and 200 samples and at the end, row 1 at the start and after 150 samples."""
    gyr, acc, mag, quat = turning_recording(n=N, noise=0.01)
    received = np.ones((2, N), bool)
    received[0, 40:58] = received[0, 120:126] = received[0, 200:224] = received[0, 290:] = False
    received[1, :3] = received[1, 150:170] = False
    return gyr, acc, mag, quat, received


def _gap_ends(received):
    """(row, t) of the first received sample after each gap after the start (with ``q0=None`` a gap
    before the first received sample is none of the filter's)."""
    after = received[:, 1:] & ~received[:, :-1] & np.logical_or.accumulate(received, axis=1)[:, :-1]
    rows, t = np.nonzero(after)
    return rows, t + 1


# ================================================================ (1) gap values each filter supports


@pytest.mark.parametrize("run", FILTERS, ids=_ids)
def test_every_filter_refuses_an_unsupported_gap_naming_itself(rec, run):
    gyr, acc, mag, _, received = rec
    supported = GAP_SUPPORT[run.__name__]
    for gap in ("hold", "constant_rate", "ar"):
        if gap in supported:
            out = run(gyr, acc, mag, fs=FS, received=received, gap=gap)
            assert out.shape == (2, N, 4) and np.all(np.isfinite(out))
        else:
            with pytest.raises(ValueError, match=rf"gap='{gap}' is not available for {run.__name__} \(it supports"):
                run(gyr, acc, mag, fs=FS, received=received, gap=gap)
    for wrong in ("linear", "Hold", None, 1):
        with pytest.raises(ValueError, match=r"gap must be one of 'hold', 'constant_rate', 'ar'"):
            run(gyr, acc, mag, fs=FS, received=received, gap=wrong)


def test_madgwick_itself_is_the_receiver_only():
    """madgwick takes no loss option: they are estimate_orientation's (the defaults give madgwick)."""
    gyr, acc, mag, _ = turning_recording(n=20)
    for keyword in ("gap", "gap_time_constant", "replay", "output_on_lost", "blend"):
        with pytest.raises(TypeError, match=keyword):
            madgwick(gyr, acc, mag, fs=FS, beta=BETA, **{keyword: None})


@pytest.mark.parametrize("run", [MADGWICK, KALMAN, *PEERS], ids=_ids)
def test_output_on_lost_and_blend_values_are_checked(rec, run):
    gyr, acc, mag, _, received = rec
    with pytest.raises(ValueError, match=r"output_on_lost must be one of 'estimate', 'hold'; got 'previous'"):
        run(gyr, acc, mag, fs=FS, received=received, output_on_lost="previous")
    if run is not KALMAN:
        with pytest.raises(ValueError, match=r"blend must be one of 'output', 'feedback'; got 'both'"):
            run(gyr, acc, mag, fs=FS, received=received, blend="both")
        with pytest.raises(ValueError, match=f"mag is required for blend='feedback' in {run.__name__}"):
            run(gyr, acc, None, fs=FS, received=received, blend="feedback")


# ================================================================ no loss: no option changes anything

NO_LOSS_OPTIONS = {
    MADGWICK: [{"gap": "constant_rate"}, {"replay": True}, {"output_on_lost": "hold"}, {"blend": "feedback"},
               {"gap": "constant_rate", "replay": True, "blend": "output", "method": "adaptive_beta"},
               {**PEER_AR, "replay": True}],
    KALMAN: [{"gap": "constant_rate"}, {"gap": "hold"}, {"replay": False}, {"output_on_lost": "hold"}],
    SMOOTHER: [{"gap": "constant_rate"}, {"gap": "hold"}, {"interpolate_gaps": False}],
    fusion_orientation: [{"gap": "constant_rate"}, {"output_on_lost": "hold"}, {"blend": "feedback"},
                         {"blend": "output"}, {**PEER_AR, "replay": True}],
    vqf_orientation: [{"gap": "constant_rate"}, {"output_on_lost": "hold"}, {"blend": "feedback"},
                      {"blend": "output"}, {**PEER_AR, "replay": True}],
}


@pytest.mark.parametrize("run, options", [(run, o) for run, opts in NO_LOSS_OPTIONS.items() for o in opts],
                         ids=lambda v: _ids(v))
def test_without_loss_no_option_changes_the_output(rec, run, options):
    gyr, acc, mag, _, _ = rec
    plain = run(gyr, acc, mag, fs=FS)
    np.testing.assert_allclose(run(gyr, acc, mag, fs=FS, received=np.ones(N, bool), **options), plain,
                               atol=1e-12, rtol=0)


# ================================================================ (2) output_on_lost="hold"

HOLD_OUTPUT_CASES = [
    (MADGWICK, {"gap": "constant_rate"}),
    (MADGWICK, {"gap": "constant_rate", "gap_time_constant": 0.2, "replay": True, "blend": "feedback"}),
    (MADGWICK, {"gap": "constant_rate", "method": "adaptive_beta", "blend": "output"}),
    (MADGWICK, {**PEER_AR, "replay": True}),
    (KALMAN, {}),
    (KALMAN, {"gap": "constant_rate", "replay": False}),
    (fusion_orientation, {"gap": "constant_rate"}),
    (fusion_orientation, {"gap": "constant_rate", "blend": "output"}),
    (vqf_orientation, {"gap": "constant_rate"}),
    (vqf_orientation, {"gap": "constant_rate", "blend": "feedback"}),
]


@pytest.mark.parametrize("run, options", HOLD_OUTPUT_CASES, ids=_ids)
def test_output_on_lost_hold_repeats_the_previous_output_and_changes_nothing_received(rec, run, options):
    gyr, acc, mag, _, received = rec
    estimate = run(gyr, acc, mag, fs=FS, received=received, output_on_lost="estimate", **options)
    held = run(gyr, acc, mag, fs=FS, received=received, output_on_lost="hold", **options)
    # the state is not affected: every received sample shows what "estimate" shows
    np.testing.assert_array_equal(held[received], estimate[received])
    # every lost sample (after the first sample) shows the output before it
    rows, t = np.nonzero(~received[:, 1:])
    np.testing.assert_array_equal(held[rows, t + 1], held[rows, t])
    # ... which is not what the filter estimates there: it predicts in the gap
    lost = ~received
    lost[:, 0] = False
    assert np.max(error_deg(held[lost], estimate[lost])) > 0.5


# ================================================================ (3) replay is causal, and acts after the gap

REPLAY_CASES = [
    (MADGWICK, {}),
    (MADGWICK, {"gap": "constant_rate"}),
    (MADGWICK, {"gap": "constant_rate", "gap_time_constant": 0.1, "blend": "feedback"}),
    (MADGWICK, {"method": "adaptive_beta", "output_on_lost": "hold"}),
    (MADGWICK, PEER_AR),
    (MADGWICK, {**PEER_AR, "blend": "feedback"}),
    (KALMAN, {}),
    (KALMAN, {"gap": "constant_rate"}),
    (KALMAN, {"gap": "hold"}),
    *[(peer, options) for peer in PEERS for options in ({}, {"gap": "constant_rate"}, PEER_AR,
                                                         {**PEER_AR, "blend": "feedback"})],
]


@pytest.mark.parametrize("run, options", REPLAY_CASES, ids=_ids)
def test_replay_never_changes_the_lost_samples_but_changes_the_state_after_the_gap(rec, run, options):
    gyr, acc, mag, _, received = rec
    off = run(gyr, acc, mag, fs=FS, received=received, replay=False, **options)
    on = run(gyr, acc, mag, fs=FS, received=received, replay=True, **options)
    rows, ends = _gap_ends(received)
    assert rows.size == 4
    # up to the end of the first gap (its lost samples included) nothing changes
    for row in range(2):
        end = ends[rows == row][0]
        np.testing.assert_array_equal(on[row, :end], off[row, :end])
    # causal: what was output on a gap's lost samples does not depend on how the gap ends, i.e.
    # it is what the same call outputs on the recording cut at the gap's end (no replay there:
    # a gap at the end is never replayed)
    for row, end in zip(rows, ends, strict=True):
        cut = run(gyr[:end], acc[:end], mag[:end], fs=FS, received=received[row, :end], replay=True, **options)
        np.testing.assert_array_equal(cut, on[row, :end])
    # from the first received sample after each gap on, the state is the replayed one
    assert np.min(error_deg(on[rows, ends], off[rows, ends])) > 1e-3


def test_madgwick_replay_ignores_what_the_state_did_in_the_gap(rec):
    """The replay starts from the state at the gap's start: after the gap, "hold" and "constant_rate" agree."""
    gyr, acc, mag, _, received = rec
    hold = MADGWICK(gyr, acc, mag, fs=FS, received=received, replay=True)
    predicted = MADGWICK(gyr, acc, mag, fs=FS, received=received, replay=True, gap="constant_rate")
    np.testing.assert_allclose(hold[received], predicted[received], atol=1e-12, rtol=0)
    assert np.max(error_deg(hold[~received], predicted[~received])) > 0.5  # (not in the gap)


# ========================================================= (4) replay with gap="hold": the gyroscope interpolation


def _rotate_first_order(q, omega, dt):
    """One gyroscope-only step of Madgwick's filter, eqs. (11)–(12): q + ½ q ⊗ [0, ω] Δt, normalised."""
    q_dot = 0.5 * Q.multiply(q, np.concatenate([[0.0], omega]))
    return Q.normalize(q + q_dot * dt)


def _gyro_interpolation(gyr, acc, mag, received, beta, q0=None):
    """Paper 001 Sec. V's gyroscope interpolation as the earlier ``method="gyro_interpolation"`` ran it:
    Madgwick's update on received samples, the estimate held on lost ones, and at the first sample
    after a gap the lost samples integrated first (gyroscope only) with ω linear between the
    received samples on both sides; a gap at the start (with ``q0``) takes the first received ω.
    ``q0=None``: start from TRIAD at the first received sample, which only initialises."""
    dt = 1.0 / FS
    first = int(np.argmax(received))
    q = triad(acc[first], mag[first]) if q0 is None else np.asarray(q0, float)
    out, last, lost = [], None, []
    for t in range(len(received)):
        if q0 is None and t <= first:  # no filter yet (no gap), then the initialising sample
            out.append(q)
            last = t
            continue
        if not received[t]:
            lost.append(t)
            out.append(q)
            continue
        for s in lost:
            w = gyr[t] if last is None else gyr[last] + (gyr[t] - gyr[last]) * (s - last) / (t - last)
            q = _rotate_first_order(q, w, dt)
        q = madgwick_step(q, gyr[t], acc[t], mag[t], dt, beta)
        out.append(q)
        last, lost = t, []
    return np.array(out)


def test_first_order_rotation_is_madgwicks_gyroscope_term():
    rng = np.random.default_rng(2)
    q, omega = Q.normalize(rng.normal(size=4)), rng.normal(size=3)
    np.testing.assert_allclose(_rotate_first_order(q, omega, 1.0 / FS),
                               madgwick_step(q, omega, [0.0, 0.0, 1.0], None, 1.0 / FS, 0.0), atol=1e-15)


@pytest.mark.parametrize("with_q0", [True, False])
def test_replay_with_gap_hold_is_the_gyroscope_interpolation(with_q0):
    gyr, acc, mag, quat = turning_recording(n=80, seed=3, noise=0.01)
    received = np.ones(80, bool)
    received[[0, 1, 20, 41, 42, 43, 44, 45, 46, 60, 62, 63]] = False  # at the start, single, burst, back to back
    q0 = quat[0] if with_q0 else None
    out = estimate_orientation(gyr, acc, mag, fs=FS, beta=BETA, received=received, q0=q0, replay=True)
    ref = _gyro_interpolation(gyr, acc, mag, received, BETA, q0)
    np.testing.assert_allclose(Q.canonical(out), Q.canonical(ref), atol=1e-12)
    assert PAPER_OPTIONS["gyro_interpolation"] == {"replay": True}
    # it is not the plain receiver: the replay moved the state after the gaps
    plain = estimate_orientation(gyr, acc, mag, fs=FS, beta=BETA, received=received, q0=q0)
    assert error_deg(out[47], plain[47]) > 0.5


def test_madgwick_with_gap_ar_turns_by_the_gap_modules_rates(rec):
    """In a gap Madgwick's state turns, gyroscope only, by :func:`gaps.gap_rates`' AR prediction of the
    raw rates; with ``replay`` the gap is re-run at its end with its replay rates, then updated."""
    gyr, acc, mag, _, received = rec
    row, (start, end) = 0, (120, 126)  # row 0's second gap: a full 1-s window of rates precedes it
    order = round(PEER_AR["gap_rate_prediction_span_s"] * FS)
    window = round(PEER_AR["gap_rate_prediction_window_s"] * FS)
    history = gyr[:start].copy()  # the first gap's rows: what the module gave there (less than a window before it)
    history[40:58] = gaps.gap_rates(np.ascontiguousarray(gyr[:40]), 18, gyr[58], gaps.AR, 1.0, order, window)[0]
    predicted, replayed = gaps.gap_rates(np.ascontiguousarray(history), end - start, gyr[end], gaps.AR, 1.0, order,
                                         window)
    out = MADGWICK(gyr, acc, mag, fs=FS, received=received, **PEER_AR)
    q = out[row, start - 1]
    for k in range(end - start):
        q = _rotate_first_order(q, predicted[k], 1.0 / FS)
        np.testing.assert_allclose(Q.canonical(out[row, start + k]), Q.canonical(q), atol=1e-12)
    on = MADGWICK(gyr, acc, mag, fs=FS, received=received, replay=True, **PEER_AR)
    q = on[row, start - 1]
    for k in range(end - start):
        q = _rotate_first_order(q, replayed[k], 1.0 / FS)
    q = madgwick_step(q, gyr[end], acc[end], mag[end], 1.0 / FS, BETA)
    np.testing.assert_allclose(Q.canonical(on[row, end]), Q.canonical(q), atol=1e-12)
    # not the constant rate's prediction
    held_rate = MADGWICK(gyr, acc, mag, fs=FS, received=received, gap="constant_rate")
    assert error_deg(out[row, end - 1], held_rate[row, end - 1]) > 1e-3


# ================================================================ (5) keywords a call does not use are refused

#: (keywords, the keyword the message names); for estimate_orientation (method "madgwick").
MADGWICK_UNUSED = [
    ({"rho": 2.0}, "rho"),
    ({"tau": 6.0}, "tau"),
    ({"schedule": "decay"}, "schedule"),
    ({"schedule": "hold", "hold_window": 10}, "schedule, hold_window"),
    ({"rho": 2.0, "method": "dt_extension"}, "rho"),
    ({"rho": 2.0, "replay": True, "gap": "constant_rate"}, "rho"),
    ({"single_frame_gate": True}, "single_frame_gate"),
    ({"single_frame_gate": True, "method": "adaptive_beta"}, "single_frame_gate"),
    ({"single_frame_gate": True, "return_weight": True}, "single_frame_gate"),
    ({"beta_max": 0.5}, "beta_max"),
    ({"beta_max": 0.5, "blend": "output"}, "beta_max"),
    ({"beta_max": 0.5, "method": "dt_extension"}, "beta_max"),
    ({"gap_time_constant": 0.2}, "gap_time_constant"),
    ({"gap_time_constant": 0.2, "replay": True}, "gap_time_constant"),
    ({"gap_rate_prediction_span_s": 0.5}, "gap_rate_prediction_span_s"),
    ({"gap_rate_prediction_window_s": 3.0, "gap": "constant_rate"}, "gap_rate_prediction_window_s"),
]


@pytest.mark.parametrize("keywords, name", MADGWICK_UNUSED, ids=lambda v: v if isinstance(v, str) else _ids(v))
def test_estimate_orientation_refuses_keywords_it_would_ignore(rec, keywords, name):
    gyr, acc, mag, _, received = rec
    with pytest.raises(ValueError, match=f"^{name} (is|are) not used by estimate_orientation|^{name} is only used"
                                         f"|^{name} only apply to gap='ar'"):
        MADGWICK(gyr, acc, mag, fs=FS, received=received, **keywords)


@pytest.mark.parametrize(
    "keywords",
    [{"rho": 2.0, "blend": "output"}, {"rho": 2.0, "method": "adaptive_beta"}, {"rho": 2.0, "return_weight": True},
     {"schedule": "hold", "hold_window": 10, "method": "adaptive_beta"}, {"single_frame_gate": True, "blend": "output"},
     {"beta_max": 0.5, "method": "adaptive_beta"}, {"gap_time_constant": 0.2, "gap": "constant_rate"},
     {"rho": None, "tau": None, "schedule": None, "hold_window": None, "single_frame_gate": None, "beta_max": None,
      "gap_time_constant": None}, {"single_frame_gate": False}],
    ids=_ids,
)
def test_the_same_keywords_where_they_are_used_are_accepted(rec, keywords):
    gyr, acc, mag, _, received = rec
    out = MADGWICK(gyr, acc, mag, fs=FS, received=received, **keywords)
    assert np.all(np.isfinite(out[0] if isinstance(out, tuple) else out))


PEER_UNUSED = [({"rho": 2.0}, "rho"), ({"tau": 6.0}, "tau"), ({"schedule": "instant"}, "schedule"),
               ({"schedule": "hold", "hold_window": 10}, "schedule, hold_window"),
               ({"single_frame_gate": True}, "single_frame_gate"),
               ({"rho": 2.0, "gap": "constant_rate"}, "rho")]


@pytest.mark.parametrize("run", PEERS, ids=_ids)
@pytest.mark.parametrize("keywords, name", PEER_UNUSED, ids=lambda v: v if isinstance(v, str) else _ids(v))
def test_peers_refuse_hybrid_keywords_without_blend(rec, run, keywords, name):
    gyr, acc, mag, _, received = rec
    with pytest.raises(ValueError, match=f"^{name} (is|are) not used by {run.__name__} without blend"):
        run(gyr[:60], acc[:60], mag[:60], fs=FS, received=received[:, :60], **keywords)
    run(gyr[:60], acc[:60], mag[:60], fs=FS, received=received[:, :60], blend="output", **keywords)  # with it: fine


@pytest.mark.parametrize("run", FILTERS, ids=_ids)
def test_every_filter_refuses_a_gap_time_constant_with_gap_hold(rec, run):
    gyr, acc, mag, _, received = rec
    with pytest.raises(ValueError, match=r"^gap_time_constant is only used when the state turns in a gap, not with "
                                         r"gap='hold'"):
        run(gyr[:60], acc[:60], mag[:60], fs=FS, received=received[:, :60], gap="hold", gap_time_constant=0.2)
    with pytest.raises(ValueError, match="gap_time_constant"):
        run(gyr[:60], acc[:60], mag[:60], fs=FS, received=received[:, :60], gap="constant_rate",
            gap_time_constant=-0.2)


# ================================================================ (6) paper 001's five options

def test_paper_options_name_the_five_options_in_the_vocabulary():
    assert list(PAPER_OPTIONS) == ["hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid"]
    assert PAPER_OPTIONS["hold_last"] == {}
    assert PAPER_OPTIONS["gyro_interpolation"] == {"replay": True}
    assert PAPER_OPTIONS["hybrid"] == {"blend": "output"}


@pytest.mark.parametrize("mu", [{}, {"rho": 1.0, "tau": 12.0, "schedule": "hold", "hold_window": 20}], ids=_ids)
def test_paper_options_all_run_and_differ_only_under_loss(rec, mu):
    gyr, acc, mag, _, received = rec
    out = {}
    for name, options in PAPER_OPTIONS.items():
        extra = mu if "blend" in options or options.get("method") == "adaptive_beta" else {}
        lossless = MADGWICK(gyr, acc, mag, fs=FS, **options, **extra)
        np.testing.assert_allclose(lossless, madgwick(gyr, acc, mag, fs=FS, beta=BETA), atol=1e-12, rtol=0)
        out[name] = MADGWICK(gyr, acc, mag, fs=FS, received=received, **options, **extra)
        assert out[name].shape == (2, N, 4) and np.all(np.isfinite(out[name]))
    names = list(out)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            assert np.max(error_deg(out[a], out[b])) > 0.1, (a, b)


# ================================================================ (7) the Kalman filter's gap="hold"


def test_kalman_gap_hold_keeps_the_state_still_while_the_covariance_grows(rec):
    gyr, acc, mag, _, received = rec
    held = KALMAN(gyr, acc, mag, fs=FS, received=received, gap="hold", full_output=True)
    turning = KALMAN(gyr, acc, mag, fs=FS, received=received, gap="constant_rate", full_output=True)
    for row in range(2):
        lost = np.flatnonzero(~received[row])
        lost = lost[lost > np.argmax(received[row])]  # (before the first received sample: the initial estimate)
        previous = lost - 1
        while np.any(~received[row, previous]):  # the last received sample before each lost one
            previous = np.where(received[row, previous], previous, previous - 1)
        np.testing.assert_array_equal(held.quat[row, lost], held.quat[row, previous])
        assert np.min(error_deg(turning.quat[row, lost], turning.quat[row, previous])) > 0.0
        # the uncertainty still grows at every lost sample (the state did not turn, but it may have)
        tilt_var = held.covariance[row, :, 0, 0]
        assert np.all(tilt_var[lost] > tilt_var[lost - 1])
    # output_on_lost makes no difference when the state holds
    np.testing.assert_array_equal(KALMAN(gyr, acc, mag, fs=FS, received=received, gap="hold", output_on_lost="hold"),
                                  held.quat)
