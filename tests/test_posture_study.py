import numpy as np
import pytest

from wsnlib.posture_study import study_inputs
from wsnlib.sim.campaign import simulate_dynamic_campaign


@pytest.fixture(scope="module")
def campaign():
    return simulate_dynamic_campaign(2, rng=np.random.default_rng(5), hold_s=3.0)


def test_rows_are_paired_causally_and_per_movement(campaign):
    inputs = study_inputs(campaign)
    assert set(inputs.target1) == set(inputs.target2) == {"U1", "U2"}
    for user, t1 in inputs.target1.items():
        t2 = inputs.target2[user]
        assert t1.online_rss.shape == t2.online_rss.shape
        np.testing.assert_array_equal(t1.movement, t2.movement)
        assert set(np.unique(t1.movement)) == set(range(1, 9))
        assert inputs.kinect[user].shape == (len(t1.movement), 2, 3)
        assert t1.segment == 0 and t2.segment == 1
        assert np.all(np.abs(t1.pitch) <= np.pi / 2)


def test_pitch_follows_the_truth_roughly(campaign):
    inputs = study_inputs(campaign, pitch_method="lowpass", cutoff_hz=5.0)
    data = campaign.data.select(user="U1", target="T1")
    t1 = inputs.target1["U1"]
    # Every paired row's true position is one of the T1 rows', and its pitch is near the true pitch there.
    true_pitch = np.arcsin(np.clip(t1.true_positions[:, 2] / np.linalg.norm(t1.true_positions, axis=1), -1, 1))
    assert np.median(np.abs(np.degrees(t1.pitch - true_pitch))) < 5.0
    assert len(data) >= len(t1.movement)


def test_selected_errors_reproduce_the_tables(campaign):
    from wsnlib import optimize
    from wsnlib.posture_study import kinect_errors, selected_errors

    inputs = study_inputs(campaign)
    grid = optimize.SearchGrid(metrics=("euclidean",), knn_neighbors=(1, 3), powers=(1,), pknn_neighbors=(1,))
    tables = optimize.paper_tables(inputs.target1, inputs.target2, grid=grid)
    errors = selected_errors(inputs, tables, approach="deterministic", per_movement=False)
    # Table 3's PE is the users' average of per-movement means, averaged over movements.
    row = tables.selection3[(tables.selection3["approach"] == "deterministic") & (tables.selection3["target"] == 1)]
    users = list(inputs.target1)
    sizes = [inputs.target1[u].movement.size for u in users]
    per_user = np.split(errors["T1"], np.cumsum(sizes)[:-1])
    movement = np.split(errors["movement"], np.cumsum(sizes)[:-1])
    per_movement_means = [[e[m == k].mean() for k in range(1, 9)] for e, m in zip(per_user, movement, strict=True)]
    expected = np.mean(np.mean(per_movement_means, axis=1))
    assert expected == pytest.approx(float(row["pe_cm"].iloc[0]), rel=1e-9)
    assert kinect_errors(inputs)["T2"].shape == errors["T2"].shape


def test_pitch_errors_are_small_at_rest(campaign):
    from wsnlib.posture_study import pitch_errors_deg

    errors = pitch_errors_deg(campaign.data, method="none")
    at_rest = errors[errors["movement"] == 0]
    assert set(errors["target"]) == {"T1", "T2"}
    assert np.median(np.abs(at_rest["error_deg"])) < 2.0


def test_true_joints_of_the_straight_arm_contain_both_targets(campaign):
    from wsnlib.posture_study import true_joints_straight_arm

    inputs = study_inputs(campaign)
    joints = true_joints_straight_arm(inputs, "U1")
    t2 = inputs.target2["U1"].true_positions
    # Target 2 lies on the segment from the true elbow to the true wrist (collinear, in between).
    a, b = joints["elbow"], joints["wrist"]
    cross = np.linalg.norm(np.cross(b - a, t2 - a), axis=1) / np.linalg.norm(b - a, axis=1)
    assert np.median(cross) < 0.02
