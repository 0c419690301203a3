import dataclasses

import numpy as np
import pytest
from _sim_helpers import paper_user

from wsnlib import quaternion as Q
from wsnlib import testbed as T
from wsnlib.sim import arm_motion as M
from wsnlib.sim import body as B

X = np.array([1.0, 0.0, 0.0])


@pytest.fixture
def user():
    return paper_user()


# --------------------------------------------------------------------------------------------
# Postures and Table 1
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("posture", ["P1", "P2", "P3", "P4"])
def test_paper_user_reproduces_table1(user, posture):
    expected = np.array(T.TABLE1_POSITIONS_CM[posture]) / 100.0
    np.testing.assert_allclose(user.target_positions(posture), expected, atol=1e-12)


def test_p5_is_the_least_squares_straight_arm(user):
    table = np.array(T.TABLE1_POSITIONS_CM["P5"]) / 100.0
    ours = user.target_positions("P5")
    miss = np.linalg.norm(ours - table, axis=1)
    assert np.all(miss < 0.035)
    # No other horizontal straight arm fits Table 1's two P5 points better.
    for deg in np.linspace(30.0, 80.0, 201):
        u = np.array([-np.sin(np.radians(deg)), np.cos(np.radians(deg)), 0.0])
        other = np.outer(T.PAPER_TARGET_DISTANCES_M, u)
        assert np.sum((other - table) ** 2) >= np.sum((ours - table) ** 2) - 1e-12


@pytest.mark.parametrize("posture", T.POSTURES)
def test_posture_orientation_points_the_segment_x_axis_along_the_arm(posture):
    u = T.posture_direction(posture)
    assert np.linalg.norm(u) == pytest.approx(1.0)
    np.testing.assert_allclose(Q.rotate(M.posture_orientation(posture), X), u, atol=1e-12)


def test_frame_signs_follow_table1():
    assert T.posture_direction("P4")[0] > 0  # sideways = to the user's right = +x
    assert T.posture_direction("P5")[0] < 0 < T.posture_direction("P5")[1]  # across the body, forward
    assert T.posture_direction("P2")[2] > 0  # up = +z


def test_unknown_posture_raises():
    with pytest.raises(ValueError, match="posture"):
        T.posture_direction("P6")


# --------------------------------------------------------------------------------------------
# Users
# --------------------------------------------------------------------------------------------


def test_make_users_is_deterministic_and_plausible():
    a = B.make_users(5, rng=np.random.default_rng(7))
    b = B.make_users(5, rng=np.random.default_rng(7))
    assert [u.name for u in a] == ["U1", "U2", "U3", "U4", "U5"]
    for ua, ub in zip(a, b, strict=True):
        assert ua.height_m == ub.height_m
        np.testing.assert_array_equal(ua.anchor_positions_m, ub.anchor_positions_m)
        assert ua.environment_seed == ub.environment_seed
    heights = np.array([u.height_m for u in a])
    assert np.all((heights >= 1.60) & (heights <= 1.90))
    assert len(set(np.round(heights, 6))) == 5
    for u in a:
        assert u.upper_arm_m == pytest.approx(0.186 * u.height_m)
        assert u.forearm_m == pytest.approx(0.146 * u.height_m)
        assert u.target_distances_m[0] == pytest.approx(0.5 * u.upper_arm_m)
        assert u.target_distances_m[1] == pytest.approx(u.upper_arm_m + 0.5 * u.forearm_m)
        offset = np.linalg.norm(u.anchor_positions_m - B.nominal_anchor_positions(u.height_m), axis=1)
        assert np.all(offset < 0.12)  # a few cm of jitter
    assert len({u.environment_seed for u in a}) == 5


def test_anchor_layout():
    pos = B.nominal_anchor_positions(1.75)
    worn = np.array([T.ANCHOR_WORN[a] for a in T.ANCHOR_NAMES])
    assert worn.tolist() == [True, False, False, True, False, True, True]  # paper 002, Fig. 4 caption
    dist = np.linalg.norm(pos, axis=1)
    assert np.all(dist[worn] < 0.6)
    horizontal = np.linalg.norm(pos[~worn, :2], axis=1)
    assert np.all((horizontal >= 1.0) & (horizontal <= 3.0))  # room anchors 1–3 m away
    heights = pos[~worn, 2] + B.SHOULDER_HEIGHT_FRACTION * 1.75
    assert len(set(np.round(heights, 3))) == 3  # different heights


def test_moved_user_keeps_environment_and_moves_anchors_a_little():
    rng = np.random.default_rng(3)
    user = B.make_users(1, rng=rng)[0]
    later = user.moved(rng)
    assert later.day == user.day + 1
    assert later.environment_seed == user.environment_seed
    assert later.height_m == user.height_m
    shift = later.anchor_positions_m - user.anchor_positions_m
    assert np.all(np.linalg.norm(shift, axis=1) < 0.10)
    assert np.any(np.linalg.norm(shift, axis=1) > 0.001)
    room = ~user.worn
    np.testing.assert_allclose(shift[room], shift[room][:1].repeat(room.sum(), axis=0))  # the user moved
    np.testing.assert_allclose(shift[room][:, 2], 0.0)
    assert 0.0 < later.target_distances_m[0] < later.upper_arm_m < later.target_distances_m[1]


def test_user_validation():
    user = paper_user()
    with pytest.raises(ValueError, match="target_distances_m"):
        dataclasses.replace(user, target_distances_m=(0.35, 0.40))
    with pytest.raises(ValueError, match="anchor_positions_m"):
        dataclasses.replace(user, anchor_positions_m=np.zeros((6, 3)))
    with pytest.raises(ValueError, match="name"):
        dataclasses.replace(user, name="a,b")


# --------------------------------------------------------------------------------------------
# Arcs and movements
# --------------------------------------------------------------------------------------------

MOVEMENT_ANGLES_DEG = {
    "lower_P2_P3_P1": 180.0,
    "horizontal_P4_P3_P5": 90.0 + 56.70,
    "raise_P1_P3": 90.0,
    "horizontal_P3_P4": 90.0,
}


@pytest.mark.parametrize("name", list(T.MOVEMENTS))
def test_movement_endpoints_are_the_postures(user, name):
    postures = T.MOVEMENTS[name]
    motion = M.movement(name, 3.0)
    kin = motion.sample(user, fs=30.0)
    assert kin.n_samples == 91
    np.testing.assert_allclose(kin.pos[:, 0], user.target_positions(postures[0]), atol=1e-12)
    np.testing.assert_allclose(kin.pos[:, -1], user.target_positions(postures[-1]), atol=1e-12)
    # The arm ends in the posture's own orientation (axial twist included).
    assert Q.angle_between(motion.quat_end, M.posture_orientation(postures[-1])) < 1e-9
    np.testing.assert_allclose(kin.quat[0, 0], M.posture_orientation(postures[0]), atol=1e-12)
    # Straight arm: both segments point the same way, targets at their distances.
    np.testing.assert_allclose(kin.directions[0], kin.directions[1])
    distances = np.array(user.target_distances_m)[:, None]
    np.testing.assert_allclose(np.linalg.norm(kin.pos, axis=-1), np.tile(distances, (1, 91)))
    if len(postures) == 3:  # passes through the via posture
        gaps = np.linalg.norm(kin.pos[0] - user.target_positions(postures[1])[0], axis=-1)
        assert gaps.min() < 0.01


@pytest.mark.parametrize("name", list(T.MOVEMENTS))
def test_movement_has_constant_angular_speed(user, name):
    duration = 2.5
    kin = M.movement(name, duration).sample(user, fs=30.0)
    u = kin.directions[0]
    steps = np.degrees(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=-1), -1.0, 1.0)))
    total = MOVEMENT_ANGLES_DEG[name]
    np.testing.assert_allclose(steps, total / duration / 30.0, rtol=1e-4)
    speed = np.degrees(np.linalg.norm(kin.gyr[:, :-1], axis=-1))
    np.testing.assert_allclose(speed, total / duration, rtol=1e-3)
    np.testing.assert_allclose(kin.ang_acc, 0.0)


def test_arc_is_slerp_of_directions(user):
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=3), rng.normal(size=3)
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    kin = M.arc(a, b, 2.0).sample(user, fs=50.0)
    omega = np.arccos(a @ b)
    mu = np.linspace(0.0, 1.0, kin.n_samples)[:, None]
    slerp = (np.sin((1 - mu) * omega) * a + np.sin(mu * omega) * b) / np.sin(omega)
    np.testing.assert_allclose(kin.directions[0], slerp, atol=1e-9)


def test_arc_between_opposite_directions_needs_a_via():
    with pytest.raises(ValueError, match="via"):
        M.arc("P1", "P2", 3.0)
    M.arc("P1", "P2", 3.0, via="P3")


def test_velocity_and_acceleration_match_finite_differences(user):
    fs = 1000.0
    kin = M.movement("horizontal_P4_P3_P5", 3.0).kinematics(np.arange(500, 2500) / fs, user)
    vel_fd = np.gradient(kin.pos, 1.0 / fs, axis=1)
    acc_fd = np.gradient(kin.vel, 1.0 / fs, axis=1)
    np.testing.assert_allclose(kin.vel[:, 1:-1], vel_fd[:, 1:-1], atol=1e-5)
    np.testing.assert_allclose(kin.acc_lin[:, 1:-1], acc_fd[:, 1:-1], atol=1e-4)


def test_body_rate_integrates_to_the_orientation(user):
    fs = 200.0
    kin = M.movement("lower_P2_P3_P1", 3.0).kinematics(np.arange(0, 590) / fs, user)
    q = kin.quat[0, 0]
    for k in range(kin.n_samples - 1):
        q = Q.multiply(q, Q.from_rotation_vector(kin.gyr[0, k] / fs))
    assert Q.angle_between(q, kin.quat[0, -1]) < 1e-9


def test_transition_arrives_in_the_posture_orientation_and_concatenation_checks_continuity():
    motion = M.concatenate([M.hold("P1", 1.0), M.transition("P1", "P2", 2.0), M.hold("P2", 1.0)])
    assert motion.total_duration_s == pytest.approx(4.0)
    assert Q.angle_between(motion.quat_end, M.posture_orientation("P2")) < 1e-9
    with pytest.raises(ValueError, match="starts"):
        M.concatenate([M.hold("P1", 1.0), M.hold("P2", 1.0)])


def test_labels_follow_the_pieces(user):
    motion = M.concatenate([M.hold("P2", 1.0), M.movement("lower_P2_P3_P1", 2.0), M.hold("P1", 1.0)])
    kin = motion.kinematics(np.array([0.5, 1.5, 2.5, 3.5]), user)
    assert kin.label.tolist() == ["P2", "lower_P2_P3_P1", "lower_P2_P3_P1", "P1"]


# --------------------------------------------------------------------------------------------
# Body solids
# --------------------------------------------------------------------------------------------


def test_chord_length_through_simple_solids():
    sphere = B.Solid("s", "sphere", np.zeros(3), 0.1)
    assert B.chord_length([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], sphere) == pytest.approx(0.2)
    assert B.chord_length([-1.0, 0.5, 0.0], [1.0, 0.5, 0.0], sphere) == 0.0
    assert B.chord_length([-1.0, 0.0, 0.0], [-0.5, 0.0, 0.0], sphere) == 0.0  # stops short
    ellipse = B.Solid("e", "cylinder", np.array([0.0, 0.0, -1.0]), 0.15, np.array([0.0, 0.0, 1.0]), 1.0,
                      np.array([1.0, 0.0, 0.0]), 0.10)
    assert B.chord_length([-1.0, 0.0, -0.5], [1.0, 0.0, -0.5], ellipse) == pytest.approx(0.30)
    assert B.chord_length([0.0, -1.0, -0.5], [0.0, 1.0, -0.5], ellipse) == pytest.approx(0.20)
    assert B.chord_length([-1.0, 0.0, 0.5], [1.0, 0.0, 0.5], ellipse) == 0.0  # above the top
    assert B.chord_length([0.0, 0.0, -2.0], [0.0, 0.0, 2.0], ellipse) == pytest.approx(1.0)  # along the axis
    # Trimming the ends of a segment that starts on the surface.
    assert B.chord_length([0.15, 0.0, -0.5], [1.0, 0.0, -0.5], ellipse, trim_m=0.02) == 0.0
    assert B.chord_length([0.15, 0.0, -0.5], [-1.0, 0.0, -0.5], ellipse, trim_m=0.02) == pytest.approx(0.28)


def test_body_solids_are_consistent_with_the_shoulder(user):
    solids = {s.name: s for s in B.body_solids(user, T.posture_direction("P1"))}
    assert set(solids) == {"torso", "legs", "neck", "head", "left_arm", "upper_arm", "forearm"}
    # The right shoulder joint is just outside the torso, the torso centre to its left.
    torso = solids["torso"]
    assert torso.base[0] < 0.0 < torso.base[0] + torso.radius + 0.05
    # Worn anchors sit on the body surface (within 2 cm outside a solid), not inside it.
    for i, name in enumerate(T.ANCHOR_NAMES):
        if not T.ANCHOR_WORN[name]:
            continue
        p = user.anchor_positions_m[i]
        outward = np.array([p[0] - torso.base[0], p[1], 0.0])
        outward = outward / np.linalg.norm(outward) if name != "A7" else np.array([0.0, 0.0, 1.0])
        inside = sum(B.chord_length(p - 0.05 * outward, p, s) for s in solids.values())
        assert 0.02 < inside <= 0.05, name
