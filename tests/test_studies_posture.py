"""wsnlib.studies.posture: paper 002's posture study."""

import numpy as np
import pytest

from wsnlib.sim.campaign import simulate_dynamic_campaign
from wsnlib.studies.posture import study_inputs


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
    from wsnlib.studies.posture import kinect_errors, selected_errors

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
    # Per-row user labels, in the users' order, for intervals over users.
    assert errors["user"].tolist() == sum(([u] * s for u, s in zip(users, sizes, strict=True)), [])
    np.testing.assert_array_equal(kinect_errors(inputs)["user"], errors["user"])


def test_pitch_errors_are_small_at_rest(campaign):
    from wsnlib.studies.posture import pitch_errors_deg

    errors = pitch_errors_deg(campaign.data, method="none")
    at_rest = errors[errors["movement"] == 0]
    assert set(errors["target"]) == {"T1", "T2"}
    assert np.median(np.abs(at_rest["error_deg"])) < 2.0


def test_true_joints_of_the_straight_arm_contain_both_targets(campaign):
    from wsnlib.studies.posture import true_joints_straight_arm

    inputs = study_inputs(campaign)
    joints = true_joints_straight_arm(inputs, "U1")
    t2 = inputs.target2["U1"].true_positions
    # Target 2 lies on the segment from the true elbow to the true wrist (collinear, in between).
    a, b = joints["elbow"], joints["wrist"]
    cross = np.linalg.norm(np.cross(b - a, t2 - a), axis=1) / np.linalg.norm(b - a, axis=1)
    assert np.median(cross) < 0.02


def test_reference_error_moves_every_system_against_the_same_reference(campaign):
    from wsnlib.studies.posture import kinect_errors, with_reference_error

    inputs = study_inputs(campaign)
    same = with_reference_error(inputs, rng=np.random.default_rng(0), rotation_std_deg=0.0, timing_std_s=0.0)
    for user in inputs.target1:
        np.testing.assert_array_equal(same.target1[user].true_positions, inputs.target1[user].true_positions)
    for key in ("T1", "T2"):
        np.testing.assert_array_equal(kinect_errors(same)[key], kinect_errors(inputs)[key])
    noisy = with_reference_error(inputs, rng=np.random.default_rng(1))
    again = with_reference_error(inputs, rng=np.random.default_rng(1))
    for user in inputs.target1:
        for target in ("target1", "target2"):
            ref = getattr(noisy, target)[user].true_positions
            np.testing.assert_array_equal(ref, getattr(again, target)[user].true_positions)
            assert ref.shape == getattr(inputs, target)[user].true_positions.shape
        # Only the reference changes: RSS, pitch and Kinect are the same objects' values.
        np.testing.assert_array_equal(noisy.target1[user].online_rss, inputs.target1[user].online_rss)
        np.testing.assert_array_equal(noisy.kinect[user], inputs.kinect[user])
    # The Kinect scored against a noisy reference looks worse, by "a few centimetres" at most.
    clean, dirty = kinect_errors(inputs)["T2"].mean(), kinect_errors(noisy)["T2"].mean()
    assert clean < dirty < clean + 6.0
    with pytest.raises(ValueError, match="StudyInputs"):
        with_reference_error({"U1": None}, rng=np.random.default_rng(0))


def test_perturbed_channel_ranges():
    from wsnlib.sim.radio import RadioChannel
    from wsnlib.studies.posture import RADIO_ASSUMPTIONS, perturbed_channel

    nominal = RadioChannel()
    assert perturbed_channel({}) == nominal
    assert perturbed_channel({name: 0.0 for name, _, _ in RADIO_ASSUMPTIONS}) == nominal
    high = perturbed_channel({"creeping_db_per_cm": 1.0, "onbody_los.exponent": -1.0, "link_loss_rate": 1.0,
                              "antenna_floor_db": 1.0, "sensitivity_dbm": 1.0})
    assert high.creeping_db_per_cm == pytest.approx(1.5 * nominal.creeping_db_per_cm)
    assert high.onbody_los.exponent == pytest.approx(0.8 * nominal.onbody_los.exponent)
    assert high.onbody_los.pl0_db == nominal.onbody_los.pl0_db
    assert high.link_loss_rate == pytest.approx(2 * nominal.link_loss_rate)
    assert high.antenna_floor_db == pytest.approx(-5.0)
    assert high.sensitivity_dbm == pytest.approx(nominal.sensitivity_dbm + 3.0)
    assert len(RADIO_ASSUMPTIONS) >= 20
    with pytest.raises(ValueError, match="unknown"):
        perturbed_channel({"frequency_hz": 0.5})
    with pytest.raises(ValueError, match=r"\[-1, 1\]"):
        perturbed_channel({"rssi_noise_db": 2.0})


def test_radio_sensitivity_quick_zero_spread_and_determinism():
    from wsnlib import optimize
    from wsnlib.studies.posture import RADIO_ASSUMPTIONS, radio_sensitivity, sensitivity_grid

    result = radio_sensitivity(rng=np.random.default_rng(4), quick=True)
    assert result.factors.shape == (3, len(RADIO_ASSUMPTIONS))                 # nominal + 2 draws
    assert (result.factors.loc[0] == 0).all() and (result.factors.loc[1:].abs() <= 1).all().all()
    assert result.summary.shape[0] == 2 * 8 * 2                                # targets × movements × approaches
    assert np.isfinite(result.summary.to_numpy()).all()
    assert (result.summary["range_cm"] >= 0).all()
    again = radio_sensitivity(rng=np.random.default_rng(4), quick=True)
    np.testing.assert_array_equal(result.pe["pe_cm"], again.pe["pe_cm"])
    # Zero spread: every draw is the nominal channel and reproduces the unperturbed search.
    zero = radio_sensitivity(rng=np.random.default_rng(4), quick=True, spread=0.0)
    np.testing.assert_allclose(zero.summary["range_cm"], 0.0, atol=1e-12)
    campaign = simulate_dynamic_campaign(1, rng=np.random.default_rng(2023), hold_s=4.0)
    inputs = study_inputs(campaign)
    tables = optimize.paper_tables(inputs.target1, inputs.target2, grid=sensitivity_grid())
    want = tables.selection2.set_index(["target", "movement", "approach"])["pe_cm"].sort_index()
    np.testing.assert_allclose(zero.summary["nominal_cm"].sort_index().to_numpy(), want.to_numpy(), rtol=1e-12)
    np.testing.assert_allclose(zero.summary["median_cm"].sort_index().to_numpy(), want.to_numpy(), rtol=1e-12)
    # A real perturbation moves something.
    assert result.summary["range_cm"].max() > 0.01
    with pytest.raises(ValueError, match="spread"):
        radio_sensitivity(rng=np.random.default_rng(0), spread=2.0)
    with pytest.raises(ValueError, match="rng"):
        radio_sensitivity(rng=1)


def test_selected_errors_chain_target2_from_the_elbow_of_target1(campaign):
    """Per user, target 2's errors are evaluate_chain's: the forearm starts at target 1's estimated elbow."""
    from wsnlib import optimize
    from wsnlib.optimize import evaluate_chain
    from wsnlib.studies.posture import selected_errors

    inputs = study_inputs(campaign)
    grid = optimize.SearchGrid(metrics=("euclidean",), knn_neighbors=(1, 3), powers=(1,), pknn_neighbors=(1,))
    tables = optimize.paper_tables(inputs.target1, inputs.target2, grid=grid)
    errors = selected_errors(inputs, tables, approach="probabilistic", per_movement=True)
    selection = tables.selection2[tables.selection2["approach"] == "probabilistic"]
    user = "U2"
    rows = errors["user"] == user
    chain = evaluate_chain(inputs.target1[user], inputs.target2[user],
                           selection[selection["target"] == 1].drop(columns="target"),
                           selection[selection["target"] == 2].drop(columns="target"))
    np.testing.assert_array_equal(errors["T1"][rows], 100 * chain["T1"]["pe_m"])
    np.testing.assert_array_equal(errors["T2"][rows], 100 * chain["T2"]["pe_m"])
    # Started at the shoulder instead (no proximal joint), target 2's error would differ.
    shoulder_start = optimize.evaluate_selection(inputs.target2[user],
                                                 selection[selection["target"] == 2].drop(columns="target"))
    assert np.abs(shoulder_start["pe_m"] - chain["T2"]["pe_m"]).max() > 1e-3



def test_kinect_frames_point_at_the_rows_kinect_positions(campaign):
    inputs = study_inputs(campaign)
    for index, user in enumerate(inputs.target1):
        stream = campaign.kinect_streams[index]
        frames = inputs.kinect_frame[user]
        for t in (0, 1):   # the sample table keeps 1 µm
            np.testing.assert_allclose(stream.targets[frames[:, t], t], inputs.kinect[user][:, t], atol=1e-6)


def test_kinect_sensitivity_equals_simulating_each_model_and_scoring_it(campaign):
    import dataclasses

    from wsnlib.sim.optical import kinect_target_positions, simulate_kinect
    from wsnlib.studies.posture import kinect_sensitivity, user_pe_cm

    inputs = study_inputs(campaign)
    sweep = kinect_sensitivity(campaign, inputs, bias_std_m=(0.0, 0.05), glitch_scales=(0.0, 3.0), n_draws=3, seed=4)
    assert len(sweep) == 2 * 2 * 3 * 2 and list(sweep.columns) == ["glitch_scale", "bias_std_m", "draw", "user", "T1",
                                                                   "T2", "pe_cm"]
    base = campaign.kinect_model
    model = dataclasses.replace(base, bias_std_m=0.05, glitch_rate_hz=3 * base.glitch_rate_hz,
                                glitch_rate_occluded_hz=3 * base.glitch_rate_occluded_hz)
    index, user = 1, "U2"
    stream, person = campaign.kinect_streams[index], campaign.online_users[index]
    truth = np.broadcast_to(stream.true_joints, (3,) + stream.true_joints.shape)
    joints = simulate_kinect(truth, rng=np.random.default_rng([4, index]), camera_position=stream.camera_position,
                             camera_axis=stream.camera_axis, model=model)
    d1, d2 = person.target_distances_m
    targets = kinect_target_positions(joints, fractions=(d1 / person.upper_arm_m,
                                                         (d2 - person.upper_arm_m) / person.forearm_m))
    frames, data1, data2 = inputs.kinect_frame[user], inputs.target1[user], inputs.target2[user]
    for draw in range(3):
        errors = {f"T{t + 1}": 100 * np.linalg.norm(targets[draw, frames[:, t], t] - data.true_positions, axis=-1)
                  for t, data in enumerate((data1, data2))}
        expected = user_pe_cm({**errors, "movement": data1.movement, "user": np.full(data1.movement.size, user)})
        row = sweep.query("glitch_scale == 3.0 and bias_std_m == 0.05 and draw == @draw and user == @user")
        np.testing.assert_allclose(row[["T1", "T2"]].to_numpy()[0], expected.loc[user].to_numpy(), rtol=1e-12)
    # More bias, more error (the same draws); without bias and glitches only the small jitter is left.
    wide = sweep.pivot_table(index=["glitch_scale", "draw", "user"], columns="bias_std_m", values="pe_cm")
    assert (wide[0.05] > wide[0.0]).all()
    assert sweep.query("glitch_scale == 0 and bias_std_m == 0")["pe_cm"].max() < 2.0


def test_joint_errors_split_height_from_horizontal_offset(campaign):
    from wsnlib import optimize
    from wsnlib.studies.posture import joint_errors_cm, true_joints_straight_arm

    inputs = study_inputs(campaign)
    setting = optimize.Setting("deterministic", anchors=(1, 2, 3, 4, 5, 6, 7), k=1, metric="euclidean")
    chains = {user: optimize.evaluate_chain(data1, inputs.target2[user], setting)
              for user, data1 in inputs.target1.items()}
    errors = joint_errors_cm(inputs, chains)
    assert list(errors["joint"].unique()) == ["elbow", "wrist"] and len(errors) == 2 * sum(
        d.movement.size for d in inputs.target1.values())
    np.testing.assert_allclose(np.hypot(errors["vertical_cm"], errors["horizontal_cm"]), errors["error_cm"])
    wrist = errors[(errors["user"] == "U1") & (errors["joint"] == "wrist")]
    truth = true_joints_straight_arm(inputs, "U1")["wrist"]
    np.testing.assert_allclose(wrist["vertical_cm"], 100 * np.abs(chains["U1"]["T2"]["joints"][:, 2] - truth[:, 2]))
    # The true joints themselves have no error.
    exact = {user: {"T1": {"joints": true_joints_straight_arm(inputs, user)["elbow"]},
                    "T2": {"joints": true_joints_straight_arm(inputs, user)["wrist"]}} for user in inputs.target1}
    assert joint_errors_cm(inputs, exact)["error_cm"].max() == 0.0


def test_kinect_crossing_interpolates_the_mean_curve():
    import pandas as pd

    from wsnlib.studies.posture import kinect_crossing

    # Mean over draws (and users) of the PE: 4, 6, 10 cm at 2, 4, 6 cm of bias; never 20 cm.
    sweep = pd.DataFrame({"glitch_scale": 1.0, "bias_std_m": np.repeat([0.02, 0.04, 0.06], 2), "draw": [0, 1] * 3,
                          "user": "U1", "pe_cm": [3.0, 5.0, 6.0, 6.0, 9.0, 11.0]})
    assert kinect_crossing(sweep, 8.0)[1.0] == pytest.approx(0.05)
    assert kinect_crossing(sweep, 6.0)[1.0] == pytest.approx(0.04)
    assert kinect_crossing(sweep, 2.0)[1.0] == pytest.approx(0.02)   # reached at the smallest bias already
    assert np.isnan(kinect_crossing(sweep, 20.0)[1.0])
