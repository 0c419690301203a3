import dataclasses

import numpy as np
import pandas as pd
import pytest
from _sim_helpers import paper_user, posture_mean_rss
from scipy.stats import spearmanr

from wsnlib import testbed as T
from wsnlib.io import rss as RSS
from wsnlib.sim import arm_motion as M
from wsnlib.sim import body as B
from wsnlib.sim import radio as R

QUIET = dataclasses.replace(R.RadioChannel(), slow_sigma_db=0.0, interference_fraction=0.0, rssi_noise_db=0.0)


@pytest.fixture(scope="module")
def users():
    return B.make_users(5, rng=np.random.default_rng(2024))


@pytest.fixture(scope="module")
def training(users):
    return R.static_session(users[0], rng=np.random.default_rng(11), hold_s=30.0, session="training")


@pytest.fixture(scope="module")
def static_run():
    """Two minutes holding P3, without slow shadowing, interference and read noise."""
    user = paper_user(environment_seed=3)
    return R.simulate_rss(M.hold("P3", 120.0), user, rng=np.random.default_rng(5), channel=QUIET)


def _acf(x, lag):
    x = np.asarray(x, dtype=float) - np.mean(x)
    return float(np.mean(x[lag:] * x[:-lag]) / np.var(x))


# --------------------------------------------------------------------------------------------
# Geometry: shadowing and antenna pattern
# --------------------------------------------------------------------------------------------


def _user_with_anchors(a1, a2):
    user = paper_user()
    anchors = np.array(user.anchor_positions_m)
    anchors[0] = a1  # A1: worn → on-body link
    anchors[1] = a2  # A2: room → off-body link
    return dataclasses.replace(user, anchor_positions_m=anchors)


def test_link_through_the_torso_is_nlos_and_shadowed():
    # Arm down: T2 on the lateral side of the forearm; an anchor beyond the left side of the
    # body at the same height: the link crosses the forearm, the torso and the left arm.
    through = np.array([-0.60, 0.0, -0.425])
    user = _user_with_anchors(through, through)
    kin = M.hold("P1", 1.0).kinematics(np.array([0.5]), user)
    lb = R.link_budget(kin, user, target=1)
    assert lb.nlos[0, 0] and lb.nlos[0, 1]
    assert lb.chord_m[0, 0] > 0.30
    ch = R.RadioChannel()
    d = lb.distance_m[0, 0]
    onbody_cap = ch.onbody_nlos.mean_db(d) - ch.onbody_los.mean_db(d)
    assert lb.body_loss_db[0, 0] == pytest.approx(onbody_cap)  # fully shadowed: the NLOS fit
    assert lb.nlos_weight[0, 0] == pytest.approx(1.0)
    assert lb.body_loss_db[0, 1] == pytest.approx(ch.offbody_shadow_cap_db)
    assert lb.k_factor_db[0, 0] == pytest.approx(ch.fading_k_db)


def test_link_in_free_space_has_no_body_loss():
    # Arm down, an anchor straight in front of the forearm node: nothing in between.
    free = np.array([0.05, 1.0, -0.425])
    user = _user_with_anchors(free, free)
    kin = M.hold("P1", 1.0).kinematics(np.array([0.5]), user)
    lb = R.link_budget(kin, user, target=1)
    assert not lb.nlos[0, 0] and not lb.nlos[0, 1]
    assert lb.body_loss_db[0, 0] == 0.0 and lb.body_loss_db[0, 1] == 0.0
    assert lb.k_factor_db[0, 0] == pytest.approx(R.RadioChannel().fading_k_onbody_los_db)
    np.testing.assert_allclose(lb.path_loss_db[0, 1], R.OFFBODY.mean_db(lb.distance_m[0, 1]))


def test_dipole_gain_is_maximal_broadside_and_minimal_along_the_axis():
    axis = np.array([0.0, 0.0, 1.0])
    angles = np.radians(np.linspace(0.0, 90.0, 91))
    links = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=-1)
    gain = R.dipole_gain_db(links, axis, peak_dbi=0.0, floor_db=-10.0)
    assert gain[0] == pytest.approx(-10.0)
    assert gain[-1] == pytest.approx(0.0)
    assert np.all(np.diff(gain) >= 0.0)
    assert R.dipole_gain_db([0.0, 0.0, -3.0], axis) == pytest.approx(-10.0)  # both ways along the axis


def test_antenna_gain_follows_the_arm_segment(users):
    user = users[0]
    ups = R.link_budget(M.hold("P2", 1.0).kinematics(np.array([0.5]), user), user, 0)
    fwd = R.link_budget(M.hold("P3", 1.0).kinematics(np.array([0.5]), user), user, 0)
    assert not np.allclose(ups.gain_target_db, fwd.gain_target_db)
    # Arm up: the segment (antenna axis) is vertical, so the gain towards a room anchor level
    # with the node is near the broadside maximum; arm forward: the anchor straight ahead
    # (A5, 2.5 m in front) is close to the axis.
    a5 = T.ANCHOR_NAMES.index("A5")
    assert fwd.gain_target_db[0, a5] < ups.gain_target_db[0, a5] - 3.0


def test_short_unshadowed_onbody_links_beat_the_farthest_room_anchor():
    ch = R.RadioChannel()
    far_room = ch.offbody.mean_db(2.8)  # A5 is ~2.8 m from the shoulder
    assert ch.onbody_los.mean_db(0.25) < far_room
    assert ch.onbody_nlos.mean_db(0.40) > far_room  # … but a shadowed one does not


def test_closer_anchors_usually_read_higher(users):
    distance, power, worn = [], [], []
    for user in users:
        for posture in T.POSTURES:
            kin = M.hold(posture, 1.0).kinematics(np.array([0.5]), user)
            for target in (0, 1):
                lb = R.link_budget(kin, user, target)
                distance.extend(lb.distance_m[0])
                power.extend(lb.mean_rx_dbm[0])
                worn.extend(lb.worn)
    distance, power, worn = map(np.asarray, (distance, power, worn))
    assert spearmanr(distance[worn], power[worn])[0] < -0.3
    assert spearmanr(distance[~worn], power[~worn])[0] < -0.2


# --------------------------------------------------------------------------------------------
# Random processes
# --------------------------------------------------------------------------------------------


def test_gauss_markov_has_unit_variance_and_the_requested_correlation():
    rng = np.random.default_rng(0)
    x = R.gauss_markov(200_000, 0.6, rng=rng)
    assert np.var(x) == pytest.approx(1.0, abs=0.02)
    assert _acf(x, 1) == pytest.approx(0.6, abs=0.01)
    assert _acf(x, 3) == pytest.approx(0.6**3, abs=0.01)
    z = R.gauss_markov(200_000, 0.6, rng=rng, complex_valued=True)
    assert np.mean(np.abs(z) ** 2) == pytest.approx(1.0, abs=0.02)


def test_rician_fading_has_the_requested_k_factor():
    g = R.gauss_markov(400_000, 0.5, rng=np.random.default_rng(1), complex_valued=True)
    power = 10.0 ** (R.rician_fading_db(7.0, g) / 10.0)
    assert np.mean(power) == pytest.approx(1.0, abs=0.01)
    # Moment estimator of K from the power: γ = Var(P)/E[P]² = (1 + 2K)/(1 + K)².
    gamma = np.var(power) / np.mean(power) ** 2
    k_hat = np.sqrt(1.0 - gamma) / (1.0 - np.sqrt(1.0 - gamma))
    assert 10.0 * np.log10(k_hat) == pytest.approx(7.0, abs=0.3)
    np.testing.assert_allclose(R.rician_fading_db(np.inf, g[:10]), 0.0)


def test_static_run_fading_spread_and_correlation_time(static_run):
    expected = np.std(R.rician_fading_db(7.0, R.gauss_markov(200_000, 0.5, rng=np.random.default_rng(2),
                                                               complex_valued=True)))
    rate = 30.0
    rho = np.exp(-1.0 / rate / R.RadioChannel().coherence_time_s)
    for (target, anchor), rows in static_run.groupby(["target", "anchor"]):
        x = rows["rss_dbm"].to_numpy()
        if anchor in ("A2", "A3", "A5"):  # off-body links: K = 7 dB
            assert np.std(x) == pytest.approx(np.hypot(expected, np.sqrt(1 / 12)), rel=0.15), (target, anchor)
            assert 0.6 * rho < _acf(x, 1) < 1.05 * rho  # correlation time ~50 ms at 30 packets/s
            assert abs(_acf(x, 10)) < 0.1  # gone after a third of a second
    stds = static_run.groupby(["target", "anchor"])["rss_dbm"].std()
    assert stds.min() < 1.0  # unshadowed on-body links hardly fluctuate (paper 002, Sec. 5)


def test_loss_fraction(static_run):
    packets = 120.0 * 30.0
    seen = static_run.groupby("target")["time_s"].nunique()
    assert np.all(seen / packets > 0.97) and np.all(seen / packets < 1.0)  # 1 % lost at all anchors
    strong = static_run.groupby(["target", "anchor"])["rss_dbm"].agg(["mean", "size"])
    strong = strong[strong["mean"] > -80.0]
    lost = 1.0 - strong["size"] / packets
    assert np.all((lost > 0.015) & (lost < 0.05))  # 2 % per link + 1 % per packet


def test_readings_below_sensitivity_are_lost():
    user = paper_user(environment_seed=4)
    channel = dataclasses.replace(R.RadioChannel().ideal(), sensitivity_dbm=-70.0)
    df = R.simulate_rss(M.hold("P1", 5.0), user, rng=np.random.default_rng(0), channel=channel)
    assert df["rss_dbm"].min() >= -70
    kin = M.hold("P1", 5.0).kinematics(np.array([1.0]), user)
    weak = (R.link_budget(kin, user, 0, channel).mean_rx_dbm[0] < -70.5).sum()
    assert weak > 0 and df[df["target"] == "T1"]["anchor"].nunique() == 7 - weak


# --------------------------------------------------------------------------------------------
# Sessions and outputs
# --------------------------------------------------------------------------------------------


def test_simulate_rss_is_deterministic_and_integer(users):
    motion = M.movement("raise_P1_P3", 3.0)
    a = R.simulate_rss(motion, users[1], rng=np.random.default_rng(8))
    b = R.simulate_rss(motion, users[1], rng=np.random.default_rng(8))
    c = R.simulate_rss(motion, users[1], rng=np.random.default_rng(9))
    pd.testing.assert_frame_equal(a, b)
    assert not a["rss_dbm"].equals(c["rss_dbm"])
    assert list(a.columns) == list(RSS.COLUMNS)
    assert a["rss_dbm"].dtype == np.int64
    assert a["time_s"].is_monotonic_increasing
    assert a.attrs["packet_rate_hz"] == 30.0


def test_training_session_structure(training, users):
    assert sorted(training["label"].unique()) == list(T.POSTURES)
    packets = training.groupby(["target", "label"])["time_s"].nunique()
    assert np.all((packets > 850) & (packets <= 900))  # ~30 s at 30 packets/s, 1 % lost
    assert training.groupby("target")["time_s"].apply(lambda t: np.median(np.diff(np.unique(t)))).between(
        0.030, 0.037
    ).all()
    rss = training["rss_dbm"]
    assert np.mean((rss >= -95) & (rss <= -35)) > 0.95
    assert rss.max() < -20
    # Positions: the held posture (within the jitter of a few degrees).
    for (target, label), rows in training.groupby(["target", "label"]):
        nominal = users[0].target_positions(label)[0 if target == "T1" else 1]
        miss = np.linalg.norm(rows[["x_m", "y_m", "z_m"]].to_numpy() - nominal, axis=1)
        assert miss.max() < 0.06


def test_mean_rss_depends_on_posture_and_target(training):
    t1 = posture_mean_rss(training, "T1")
    t2 = posture_mean_rss(training, "T2")
    for table in (t1, t2):
        for i, a in enumerate(T.POSTURES):
            for b in T.POSTURES[i + 1 :]:
                diff = (table[a] - table[b]).abs().dropna()
                assert diff.sum() > 10.0, (a, b)
    assert ((t1 - t2).abs().sum() > 10.0).sum() >= 4


def test_some_posture_anchor_pairs_are_nearly_constant(training):
    std = training.groupby(["target", "label", "anchor"])["rss_dbm"].std()
    assert std.min() < 1.2
    assert std.max() > 2.5


def test_online_static_session_on_another_day(users, training):
    rng = np.random.default_rng(12)
    later = users[0].moved(rng)
    online = R.static_session(later, rng=rng, hold_s=10.0, session="online_static")
    assert set(online["session"]) == {"online_static"}
    assert sorted(online["label"].unique()) == list(T.POSTURES)
    # The same posture reads more alike on both days than different postures do.
    hits = 0
    for target in ("T1", "T2"):
        train_mean = posture_mean_rss(training, target).fillna(-100.0)
        online_mean = posture_mean_rss(online, target).fillna(-100.0)
        for posture in T.POSTURES:
            dist = (train_mean.sub(online_mean[posture], axis=0)).abs().sum()
            hits += dist.idxmin() == posture
    assert hits >= 8


def test_online_dynamic_session(users):
    rng = np.random.default_rng(13)
    later = users[2].moved(rng)
    df = R.online_dynamic_session(later, rng=rng)
    movements = [lab for lab in dict.fromkeys(df["label"]) if lab.startswith("M")]
    names = list(T.MOVEMENTS)
    assert movements == [R.movement_label(k + 1, names[k % 4]) for k in range(8)]
    t1 = df[df["target"] == "T1"]
    for label in movements:
        rows = t1[t1["label"] == label]
        span = rows["time_s"].max() - rows["time_s"].min()
        assert 1.8 < span < 4.0
        radius = np.linalg.norm(rows[["x_m", "y_m", "z_m"]].to_numpy(), axis=1)
        np.testing.assert_allclose(radius, later.target_distances_m[0], atol=1e-5)
    # Each label's rows are contiguous in time per target (movements are not interleaved).
    runs = (t1["label"] != t1["label"].shift()).cumsum()
    assert runs.groupby(t1["label"]).nunique().loc[movements].eq(1).all()


def test_concat_rss_merges_anchor_positions(users, training):
    other = R.simulate_rss(M.hold("P1", 2.0), users[1], rng=np.random.default_rng(1), session="extra")
    both = R.concat_rss([training, other])
    assert set(both.attrs["anchor_positions_m"]) == {users[0].name, users[1].name}
    assert len(both) == len(training) + len(other)


@pytest.mark.parametrize("change, message", [
    ({"link_loss_rate": 1.5}, r"link_loss_rate must lie in \[0, 1\], got 1.5"),
    ({"day_decorrelation": -0.1}, "day_decorrelation must be a non-negative"),
    ({"coherence_time_s": 0.0}, "coherence_time_s must be a positive"),
    ({"rssi_noise_db": float("nan")}, "rssi_noise_db must be a non-negative finite"),
    ({"shadow_features": 2.5}, "shadow_features must be a positive integer"),
    ({"offbody": "free space"}, "offbody must be a PathLossModel"),
])
def test_radio_channel_refuses_bad_fields(change, message):
    """The shared field checks (_validation.check_fields) name the field and the rule it breaks."""
    with pytest.raises(ValueError, match=message):
        R.RadioChannel(**change)
    assert isinstance(R.RadioChannel().link_loss_rate, float)


def test_sensor_specs_refuse_flags_that_are_not_bools():
    from wsnlib.sim.imu import ImuSpec
    from wsnlib.sim.sunspot import SunspotAccSpec

    with pytest.raises(ValueError, match="quantize must be True or False, got 1"):
        ImuSpec(quantize=1)
    with pytest.raises(ValueError, match="saturate must be True or False, got 'yes'"):
        SunspotAccSpec(saturate="yes")
    assert ImuSpec(quantize=np.True_).quantize is True
