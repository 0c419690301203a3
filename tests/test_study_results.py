"""The explore panels: the studies compute (wsnlib.studies.burst_loss, .static_fingerprinting) and
wsnlib.plotting draws what they return."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from wsnlib import metrics, plotting, radio
from wsnlib.io.rss import rss_vectors
from wsnlib.sim import arm_extension, simulate_recording
from wsnlib.sim.campaign import simulate_campaign
from wsnlib.studies import burst_loss, static_fingerprinting


@pytest.fixture(scope="module")
def recording():
    trajectory = arm_extension(fs=50.0, duration_s=6.0, start_s=1.0, rise_s=3.0)
    return simulate_recording(trajectory, rng=np.random.default_rng(7))


@pytest.fixture(scope="module")
def campaign_vectors():
    campaign = simulate_campaign(1, rng=np.random.default_rng(3), hold_s=3.0, static_hold_s=2.0, dynamic=False)
    rss = campaign.rss
    return (rss_vectors(rss[rss["session"] == "training"]),
            rss_vectors(rss[rss["session"] == "online_static"], fill="last"))


def _axes():
    return Figure().subplots()


def _lines(ax):
    return {line.get_label(): line.get_ydata() for line in ax.get_lines()}


def test_loss_recovery_draws_both_estimators_and_the_lossless_reference(recording):
    result = burst_loss.burst_recovery(recording, beta=0.1, loss_packets=4, loss_start=80)
    ax = plotting.plot_burst_recovery(result, ax=_axes())
    lines = _lines(ax)
    assert {"data fusion", "single frame", "data fusion, no loss"} <= set(lines)
    assert all(np.all(np.asarray(y) >= 0) for label, y in lines.items() if label != "_child")
    # The loss makes data fusion worse than without it.
    assert lines["data fusion"].max() > lines["data fusion, no loss"].max()
    assert "data fusion: max" in ax.texts[0].get_text()
    result = burst_loss.burst_recovery(recording, beta=0.1, loss_packets=0, loss_start=80)
    ax = plotting.plot_burst_recovery(result, ax=_axes())
    lines = _lines(ax)
    np.testing.assert_allclose(lines["data fusion"], lines["data fusion, no loss"])
    assert ax.texts[0].get_text() == "data fusion: no loss"


def test_hybrid_vs_fusion_tends_to_data_fusion_for_a_large_rho(recording):
    result = burst_loss.hybrid_vs_fusion(recording, rho=1.0, tau=6.0, loss_packets=4, beta=0.041, loss_start=80)
    lines = _lines(plotting.plot_hybrid_vs_fusion(result, ax=_axes()))
    truth = metrics.elbow_angle_deg(recording.quat_true[0], recording.quat_true[1])
    np.testing.assert_allclose(lines["truth"], truth)
    error = {name: np.abs(lines[name] - truth).mean() for name in ("data fusion", "hybrid")}
    assert error["hybrid"] < error["data fusion"]
    result = burst_loss.hybrid_vs_fusion(recording, rho=1e9, tau=6.0, loss_packets=4, beta=0.041, loss_start=80,
                                         blend="feedback")
    ax = plotting.plot_hybrid_vs_fusion(result, ax=_axes())
    lines = _lines(ax)
    np.testing.assert_allclose(lines["hybrid"], lines["data fusion"], atol=1e-3)
    assert ax.texts[0].get_text().count("max") == 2


def test_static_fingerprinting_bars_match_knn(campaign_vectors):
    train, online = campaign_vectors
    result = static_fingerprinting.static_fingerprinting(train, online, n_neighbors=1, power=1, anchors=("A1", "A4"))
    ax = plotting.plot_static_fingerprinting(result, ax=_axes())
    heights = sorted(round(patch.get_height(), 6) for patch in ax.patches)
    assert len(heights) == 10  # five postures, two targets
    estimate = radio.fit_predict_by_group(
        radio.KNNFingerprint(1, anchors=[0, 3]), train.rss, train.position,
        np.char.add(train.user.astype(str), train.target.astype(str)), online.rss,
        np.char.add(online.user.astype(str), online.target.astype(str)))
    error_cm = 100 * metrics.position_error(estimate, online.position)
    expected = sorted(round(error_cm[(online.label == p) & (online.target == t)].mean(), 6)
                      for p in np.unique(online.label) for t in ("T1", "T2"))
    np.testing.assert_allclose(heights, expected)


def test_burst_recovery_returns_what_the_plot_draws(recording):
    result = burst_loss.burst_recovery(recording, beta=0.1, loss_packets=4, loss_start=80, threshold_deg=5.0)
    n_samples = recording.time_s.size
    assert result.received.shape == (n_samples,) and result.received.dtype == bool
    assert result.first_lost == int(np.flatnonzero(~result.received)[0])
    assert set(result.pitch_error_deg) == {"data fusion", "single frame", "data fusion, no loss"}
    assert all(error.shape == (n_samples,) and np.isfinite(error).all() for error in result.pitch_error_deg.values())
    assert result.recovery.peak_deg == pytest.approx(
        np.abs(result.pitch_error_deg["data fusion"][result.first_lost:][result.received[result.first_lost:]]).max())
    assert result.recovery.recovery_s >= 0.0
    ax = plotting.plot_burst_recovery(result, ax=_axes())
    lines = _lines(ax)
    for name, error in result.pitch_error_deg.items():
        np.testing.assert_array_equal(lines[name], np.abs(error))
    no_loss = burst_loss.burst_recovery(recording, beta=0.1, loss_packets=0, loss_start=80)
    assert no_loss.first_lost is None and no_loss.received.all()
    assert no_loss.recovery == burst_loss.RecoveryAfterBurst(peak_deg=None, recovery_s=None)


def test_hybrid_vs_fusion_returns_what_the_plot_draws(recording):
    result = burst_loss.hybrid_vs_fusion(recording, rho=1.0, tau=6.0, loss_packets=4, beta=0.041, loss_start=80)
    np.testing.assert_array_equal(result.elbow_deg["truth"],
                                  metrics.elbow_angle_deg(recording.quat_true[0], recording.quat_true[1]))
    assert set(result.recovery) == {"data fusion", "hybrid"}
    for name in ("data fusion", "hybrid"):
        error = result.elbow_deg[name] - result.elbow_deg["truth"]
        after = slice(result.first_lost, None)
        assert result.recovery[name].peak_deg == pytest.approx(np.abs(error[after][result.received[after]]).max())
    ax = plotting.plot_hybrid_vs_fusion(result, ax=_axes())
    lines = _lines(ax)
    for name, angle in result.elbow_deg.items():
        np.testing.assert_array_equal(lines[name], angle)
    assert ax.get_xlim()[0] == pytest.approx(result.time_s[result.first_lost] - 0.5)


def test_static_fingerprinting_returns_what_the_plot_draws(campaign_vectors):
    train, online = campaign_vectors
    result = static_fingerprinting.static_fingerprinting(train, online, n_neighbors=3, power=2,
                                                         anchors=("A1", "A4", "A6"))
    assert result.anchors == (0, 3, 5)
    assert result.error_cm.shape == result.posture.shape == result.target.shape == (len(online.label),)
    np.testing.assert_allclose(result.mean_by_target["T1"], result.error_cm[result.target == "T1"].mean())
    posture = result.mean_by_posture.index[0]
    np.testing.assert_allclose(result.mean_by_posture.loc[posture, "T2"],
                               result.error_cm[(result.posture == posture) & (result.target == "T2")].mean())
    ax = plotting.plot_static_fingerprinting(result, ax=_axes())
    heights = sorted(patch.get_height() for patch in ax.patches)
    np.testing.assert_allclose(heights, np.sort(result.mean_by_posture.to_numpy().ravel()))
    with pytest.raises(ValueError, match="at least one anchor"):
        static_fingerprinting.static_fingerprinting(train, online, n_neighbors=1, power=1, anchors=())
    with pytest.raises(ValueError, match="not in train.anchors"):
        static_fingerprinting.static_fingerprinting(train, online, n_neighbors=1, power=1, anchors=("A99",))


def test_own_posture_marks_the_estimates_at_the_vectors_own_fingerprint(campaign_vectors):
    train, online = campaign_vectors
    estimate = radio.fit_predict_by_group(radio.KNNFingerprint(1), train.rss, train.position, train.map_key,
                                          online.rss, online.map_key)
    own = static_fingerprinting.own_posture(train, online, estimate)
    assert own.dtype == bool and own.shape == (len(online),) and own.any()
    # An own-posture estimate is the training position of the same user, target and posture.
    row = int(np.flatnonzero(own)[0])
    same = (train.map_key == online.map_key[row]) & (train.label == online.label[row])
    np.testing.assert_array_equal(estimate[row], train.position[same][0])
    # The fingerprint of another posture is never "own"; an estimate between postures neither.
    other = (train.map_key == online.map_key[row]) & (train.label != online.label[row])
    moved = estimate.copy()
    moved[row] = train.position[other][0]
    assert not static_fingerprinting.own_posture(train, online, moved)[row]
    moved[row] = 0.5 * (train.position[same][0] + train.position[other][0])
    assert not static_fingerprinting.own_posture(train, online, moved)[row]
    with pytest.raises(ValueError, match="without training vectors"):
        static_fingerprinting.own_posture(train.select(label=["P1", "P2"]), online, estimate)
