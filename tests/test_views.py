"""wsnlib.views: the draw helpers behind the notebooks' explore cells."""

import time

import numpy as np
import pytest
from matplotlib.figure import Figure

from wsnlib import fingerprint, metrics, views
from wsnlib.rss import rss_vectors
from wsnlib.sim import arm_extension, simulate_recording
from wsnlib.sim.campaign import simulate_campaign


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
    ax = _axes()
    started = time.perf_counter()
    views.draw_loss_recovery(ax, recording=recording, beta=0.1, loss_packets=4, loss_start=80)
    assert time.perf_counter() - started < 2.0
    lines = _lines(ax)
    assert {"data fusion", "single frame", "data fusion, no loss"} <= set(lines)
    assert all(np.all(np.asarray(y) >= 0) for label, y in lines.items() if label != "_child")
    # The loss makes data fusion worse than without it.
    assert lines["data fusion"].max() > lines["data fusion, no loss"].max()
    assert "data fusion: max" in ax.texts[0].get_text()
    ax = _axes()
    views.draw_loss_recovery(ax, recording=recording, beta=0.1, loss_packets=0, loss_start=80)
    lines = _lines(ax)
    np.testing.assert_allclose(lines["data fusion"], lines["data fusion, no loss"])
    assert ax.texts[0].get_text() == "data fusion: no loss"


def test_hybrid_vs_fusion_tends_to_data_fusion_for_a_large_rho(recording):
    ax = _axes()
    views.draw_hybrid_vs_fusion(ax, recording=recording, rho=1.0, tau=6.0, loss_packets=4, beta=0.041, loss_start=80)
    lines = _lines(ax)
    truth = metrics.elbow_angle_deg(recording.quat_true[0], recording.quat_true[1])
    np.testing.assert_allclose(lines["truth"], truth)
    error = {name: np.abs(lines[name] - truth).mean() for name in ("data fusion", "hybrid")}
    assert error["hybrid"] < error["data fusion"]
    ax = _axes()
    views.draw_hybrid_vs_fusion(ax, recording=recording, rho=1e9, tau=6.0, loss_packets=4, beta=0.041,
                                loss_start=80, blend="feedback")
    lines = _lines(ax)
    np.testing.assert_allclose(lines["hybrid"], lines["data fusion"], atol=1e-3)
    assert ax.texts[0].get_text().count("max") == 2


def test_static_fingerprinting_bars_match_knn(campaign_vectors):
    train, online = campaign_vectors
    ax = _axes()
    views.draw_static_fingerprinting(ax, train=train, online=online, n_neighbors=1, power=1, anchors=("A1", "A4"))
    heights = sorted(round(patch.get_height(), 6) for patch in ax.patches)
    assert len(heights) == 10  # five postures, two targets
    estimate = fingerprint.fit_predict_by_group(
        fingerprint.KNNFingerprint(1, anchors=[0, 3]), train.rss, train.position,
        np.char.add(train.user.astype(str), train.target.astype(str)), online.rss,
        np.char.add(online.user.astype(str), online.target.astype(str)))
    error_cm = 100 * metrics.position_error(estimate, online.position)
    expected = sorted(round(error_cm[(online.label == p) & (online.target == t)].mean(), 6)
                      for p in np.unique(online.label) for t in ("T1", "T2"))
    np.testing.assert_allclose(heights, expected)
    ax = _axes()
    views.draw_static_fingerprinting(ax, train=train, online=online, n_neighbors=3, power=1, anchors=())
    assert not ax.patches and "at least one anchor" in ax.texts[0].get_text()
