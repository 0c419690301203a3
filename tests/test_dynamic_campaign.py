"""Dynamic campaign of paper 002: Sun SPOT accelerometer, Kinect, RSS on one clock."""

import numpy as np
import pandas as pd
import pytest
from _sim_helpers import paper_user

from wsnlib import quaternion as Q
from wsnlib.frames import STANDARD_GRAVITY
from wsnlib.io import accel
from wsnlib.posture import gravity_gate, pitch_from_acc
from wsnlib.sim.arm_motion import concatenate, hold, movement
from wsnlib.sim.campaign import (
    DYNAMIC_SESSION,
    movement_number,
    read_dynamic_campaign,
    simulate_campaign,
    simulate_dynamic_campaign,
    simulate_kinect_stream,
    write_dynamic_campaign,
)
from wsnlib.sim.optical import KinectModel
from wsnlib.sim.sunspot import SunspotAccSpec, ideal_specific_force, segment_axis_in_device, simulate_sunspot_acc
from wsnlib.testbed import POSTURES, posture_direction

G = STANDARD_GRAVITY


@pytest.fixture(scope="module")
def noise_free():
    return simulate_dynamic_campaign(
        2,
        rng=np.random.default_rng(11),
        hold_s=1.0,
        acc_spec=SunspotAccSpec.noise_free(),
        kinect_model=KinectModel.noise_free(),
    )


@pytest.fixture(scope="module")
def noisy():
    return simulate_dynamic_campaign(2, rng=np.random.default_rng(5), hold_s=1.0)


def _window_truth(motion, acc, user, target):
    """Max |linear acceleration| and mean true pitch over each output sample's 100 Hz window."""
    kin = motion.kinematics(acc.raw_time_s, user)
    window = np.floor(np.round(acc.raw_time_s * 100.0) * 30.0 / 100.0 + 1e-9).astype(int) + 1
    n = acc.time_s.size
    peak = np.zeros(n)
    np.maximum.at(peak, window, np.linalg.norm(kin.acc_lin[target], axis=1))
    pitch = np.arcsin(np.clip(kin.directions[target, :, 2], -1.0, 1.0))
    mean_pitch = np.bincount(window, pitch, minlength=n) / np.bincount(window, minlength=n)
    return peak, mean_pitch


# --- accelerometer model --------------------------------------------------------------------


@pytest.mark.parametrize("posture", POSTURES)
def test_noise_free_reading_at_rest_is_gravity_in_the_body_frame(posture):
    user = paper_user()
    acc = simulate_sunspot_acc(hold(posture, 1.0), user, rng=np.random.default_rng(0), spec=SunspotAccSpec.noise_free())
    kin = hold(posture, 1.0).kinematics(acc.raw_time_s, user)
    expected = Q.rotate_inverse(np.moveaxis(kin.quat, 0, 1), np.array([0.0, 0.0, G]))  # (T, 2, 3)
    np.testing.assert_allclose(acc.raw_acc, expected, atol=1e-12)
    np.testing.assert_allclose(acc.acc, np.broadcast_to(expected[0], acc.acc.shape), atol=1e-12)
    # The segment axis (body x) reads g·sin(pitch): +g arm up, −g arm down, 0 horizontal.
    np.testing.assert_allclose(acc.acc[..., 0], G * posture_direction(posture)[2], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(acc.acc, axis=-1), G, atol=1e-12)


def test_specific_force_includes_the_centripetal_acceleration():
    user = paper_user()
    motion = movement("raise_P1_P3", 2.0)
    kin = motion.kinematics(np.array([1.0]), user)
    force = ideal_specific_force(kin)
    # Constant-speed rotation: ω² d towards the shoulder, i.e. along −x of the segment.
    omega = (np.pi / 2) / 2.0
    radial = force[0, :, 0] - G * kin.directions[0, 0, 2]  # force (T, 2, 3), directions (2, T, 3)
    np.testing.assert_allclose(radial, -(omega**2) * np.array(user.target_distances_m), atol=1e-12)


def test_adc_grid_noise_and_time_stamps():
    user = paper_user()
    spec = SunspotAccSpec()
    assert spec.counts_per_g == pytest.approx(204.8)
    acc = simulate_sunspot_acc(hold("P3", 5.0), user, rng=np.random.default_rng(1), spec=spec)
    codes = acc.raw_acc / (G / spec.counts_per_g)
    np.testing.assert_allclose(codes, np.rint(codes), atol=1e-9)  # every raw reading is an ADC code
    np.testing.assert_allclose(acc.acc.mean(axis=0), [[0.0, 0.0, G]] * 2, atol=0.25)  # bias σ = 5 mg = 0.05 m/s²
    assert acc.acc.std(axis=0).max() < 0.03
    np.testing.assert_array_equal(acc.time_s, np.round(np.arange(acc.time_s.size) / 30.0, 6))
    assert acc.time_s[-1] <= 5.0 < acc.time_s[-1] + 1 / 30
    assert acc.raw_time_s[0] == pytest.approx(-0.03)  # the node was sampling before the session


@pytest.mark.parametrize("method", ["mean", "latest"])
def test_downsampling_uses_only_the_samples_of_the_previous_window(method):
    user = paper_user()
    spec = SunspotAccSpec.noise_free(downsample=method)
    acc = simulate_sunspot_acc(movement("lower_P2_P3_P1", 2.5), user, rng=np.random.default_rng(0), spec=spec)
    for k in (0, 1, 2, 7, 40, acc.time_s.size - 1):
        inside = (acc.raw_time_s >= k / 30 - 1 / 30 - 1e-9) & (acc.raw_time_s < k / 30 - 1e-9)
        assert 3 <= inside.sum() <= 4
        assert acc.raw_time_s[inside].max() < acc.time_s[k]  # causal
        expected = acc.raw_acc[inside].mean(axis=0) if method == "mean" else acc.raw_acc[inside][-1]
        np.testing.assert_allclose(acc.acc[k], expected, atol=1e-12)


def test_mounting_and_segment_axis_give_the_same_pitch():
    user = paper_user()
    motion = concatenate([hold("P3", 0.5), movement("horizontal_P3_P4", 2.0), hold("P4", 0.5)])
    mounting = Q.from_axis_angle([0.0, 0.0, 1.0], -np.pi / 2)  # the SPOT's long edge (its y) along the arm
    np.testing.assert_allclose(segment_axis_in_device(mounting), [0.0, 1.0, 0.0], atol=1e-12)
    plain = simulate_sunspot_acc(motion, user, rng=np.random.default_rng(0), spec=SunspotAccSpec.noise_free())
    mounted = simulate_sunspot_acc(
        motion, user, rng=np.random.default_rng(0), spec=SunspotAccSpec.noise_free(), mounting=mounting
    )
    assert not np.allclose(plain.acc, mounted.acc)
    np.testing.assert_allclose(
        pitch_from_acc(mounted.acc[:, 1], method="none", segment_axis=segment_axis_in_device(mounting)),
        pitch_from_acc(plain.acc[:, 1], method="none"),
        atol=1e-12,
    )


def test_spec_validation():
    with pytest.raises(ValueError, match="downsample"):
        SunspotAccSpec(downsample="median")
    with pytest.raises(ValueError, match="adc_bits"):
        SunspotAccSpec(adc_bits=1)
    with pytest.raises(ValueError, match="full_scale_g"):
        SunspotAccSpec(full_scale_g=6.0)  # needs the ±6 g sensitivity: SunspotAccSpec.six_g()
    assert SunspotAccSpec.six_g().counts_per_g == pytest.approx(1024 / 15)


# --- pitch from the simulated accelerometer ---------------------------------------------------


def test_pitch_from_noise_free_acc_matches_truth_outside_acceleration_peaks(noise_free):
    for motion, acc, user in zip(noise_free.motions, noise_free.acc_streams, noise_free.online_users, strict=True):
        for target in (0, 1):
            peak, truth = _window_truth(motion, acc, user, target)
            pitch = pitch_from_acc(acc.acc[:, target], method="none")
            error = np.degrees(np.abs(pitch - truth))
            calm = peak < 0.15  # m/s²: asin(0.15 / g) = 0.88°
            assert calm.sum() > 0.3 * calm.size
            assert error[calm].max() < 1.0
            # Still windows (no linear acceleration at all): exact.
            assert error[peak == 0.0].max() < 1e-9
            # During movements the centripetal ω²d along the arm biases eq. (6): bounded by asin(|a|/g).
            assert np.all(error <= np.degrees(np.arcsin(np.minimum(peak / G, 1.0))) + 1.0)


def test_gating_rejects_the_dynamic_samples(noise_free):
    motion, acc, user = noise_free.motions[0], noise_free.acc_streams[0], noise_free.online_users[0]
    peak, truth = _window_truth(motion, acc, user, 1)
    forearm = acc.acc[:, 1]
    xi = 0.2
    accepted = gravity_gate(forearm, xi=xi)
    deviation = np.abs(np.linalg.norm(forearm, axis=-1) - G)
    np.testing.assert_array_equal(accepted, deviation <= xi)
    assert accepted[peak == 0.0].all()  # every still sample passes
    assert (~accepted).sum() > 10  # some movement samples of T2 do not
    assert np.all(peak[~accepted] > xi / 2)
    gated = pitch_from_acc(forearm, method="gating", xi=xi)
    held = np.maximum.accumulate(np.where(accepted, np.arange(accepted.size), -1))
    np.testing.assert_allclose(gated, pitch_from_acc(forearm, method="none")[held], atol=0.0)


def test_pitch_from_noisy_acc_in_still_windows(noisy):
    for motion, acc, user in zip(noisy.motions, noisy.acc_streams, noisy.online_users, strict=True):
        for target in (0, 1):
            peak, truth = _window_truth(motion, acc, user, target)
            still = peak == 0.0
            error = np.degrees(np.abs(pitch_from_acc(acc.acc[:, target], method="none") - truth))
            assert error[still].max() < 1.0
            assert gravity_gate(acc.acc[still, target]).all()


def test_aligned_pitch_in_holds(noise_free):
    data = noise_free.data
    hold_rows = (data.movement == 0) & (data.label != "transition")
    pitch = pitch_from_acc(data.acc, method="none")
    error = np.degrees(np.abs(pitch - data.pitch_true_rad))
    # Apart from the first packet or two after a movement ends (their sample still averages
    # the end of the movement), the aligned sample gives the true pitch.
    assert np.median(error[hold_rows]) < 1e-6
    assert np.mean(error[hold_rows] < 1.0) > 0.95


# --- campaign: clock, alignment, labels, determinism ------------------------------------------


def test_every_rss_vector_has_an_earlier_or_simultaneous_sample(noisy):
    data = noisy.data
    lag_acc = data.time_s - data.acc_time_s
    lag_kinect = data.time_s - data.kinect_time_s
    assert lag_acc.min() >= 0.0 and lag_kinect.min() >= 0.0
    # ... and it is the latest one (the next sample is after the packet).
    assert lag_acc.max() < 1 / 30 and lag_kinect.max() < 1 / 30
    for user in noisy.online_users:
        for t, target in enumerate(("T1", "T2")):
            rows = (data.user == user.name) & (data.target == target)
            table = noisy.acc[(noisy.acc["user"] == user.name) & (noisy.acc["target"] == target)]
            index = np.searchsorted(table["time_s"].to_numpy(), data.time_s[rows], side="right") - 1
            cols = list(accel.VALUE_COLUMNS["acc"])
            np.testing.assert_array_equal(data.acc[rows], table[cols].to_numpy()[index])
            np.testing.assert_array_equal(data.target_index[rows], t)


def test_movement_labels_for_every_user(noisy):
    for user in noisy.online_users:
        rows = noisy.data.user == user.name
        assert set(noisy.data.movement[rows]) == set(range(9))
        labels = set(noisy.dynamic_rss.loc[noisy.dynamic_rss["user"] == user.name, "label"])
        assert {movement_number([label])[0] for label in labels} == set(range(9))
        assert {"P1", "P2", "P3", "P4", "P5", "transition"} <= labels
        acc_labels = set(noisy.acc.loc[noisy.acc["user"] == user.name, "label"])
        assert {f"M{k}" for k in range(1, 9)} == {lab.split("_")[0] for lab in acc_labels if lab.startswith("M")}
    assert set(noisy.dynamic_rss["session"]) == {DYNAMIC_SESSION}
    assert set(noisy.training_rss["label"]) == set(POSTURES)
    np.testing.assert_array_equal(movement_number(["M3_raise_P1_P3", "P1", "transition", "M10_x"]), [3, 0, 0, 10])


def test_shapes_and_geometry(noisy):
    data = noisy.data
    n = len(data)
    assert n > 0
    assert data.rss.shape == (n, 7) and not np.isnan(data.rss).any()
    for name in ("position", "acc", "kinect"):
        assert getattr(data, name).shape == (n, 3)
    for name in ("time_s", "acc_time_s", "kinect_time_s", "pitch_true_rad", "segment_length_m", "device_offset_m"):
        assert getattr(data, name).shape == (n,)
    assert list(noisy.acc.columns) == list(accel.columns("acc"))
    assert list(noisy.kinect.columns) == list(accel.columns("kinect"))
    assert noisy.acc.attrs["rate_hz"] == 30.0
    for user, motion, acc, kinect in zip(
        noisy.online_users, noisy.motions, noisy.acc_streams, noisy.kinect_streams, strict=True
    ):
        chain = user.geometry
        assert chain.segment_lengths_m == (user.upper_arm_m, user.forearm_m)
        rows = data.select(user=user.name)
        np.testing.assert_array_equal(rows.segment_length_m, np.asarray(chain.segment_lengths_m)[rows.target_index])
        np.testing.assert_array_equal(rows.device_offset_m, np.asarray(chain.device_offsets_m)[rows.target_index])
        k = int(np.floor(motion.total_duration_s * 30 + 1e-9)) + 1
        assert acc.acc.shape == (k, 2, 3) and kinect.targets.shape == (k, 2, 3)
        assert kinect.joints.shape == (k, 3, 3)
        # Radio, accelerometer and Kinect follow the same motion: truth agrees at shared times.
        sub = data.select(user=user.name)
        distances = np.asarray(user.target_distances_m)[sub.target_index]
        np.testing.assert_allclose(np.linalg.norm(sub.position, axis=1), distances, atol=1e-12)
    # The Kinect sits 3 m in front, looking back at the user.
    np.testing.assert_allclose(noisy.kinect_streams[0].camera_axis, [0.0, -1.0, 0.0])
    assert noisy.kinect_streams[0].camera_position[1] == 3.0


def test_noise_free_kinect_reports_the_truth(noise_free):
    stream = noise_free.kinect_streams[0]
    np.testing.assert_allclose(stream.targets, stream.true_targets, atol=1e-12)
    data = noise_free.data
    # Aligned: the true position of the latest frame, so within one frame's motion of the packet's truth.
    assert np.max(np.linalg.norm(data.kinect - data.position, axis=1)) < 0.05
    holds = (data.movement == 0) & (data.label != "transition")
    assert np.mean(np.linalg.norm(data.kinect - data.position, axis=1)[holds] < 1e-6) > 0.9
    user = noise_free.online_users[0]
    again = simulate_kinect_stream(
        noise_free.motions[0], user, rng=np.random.default_rng(0), model=KinectModel.noise_free()
    )
    np.testing.assert_allclose(again.joints, stream.true_joints, atol=1e-12)


def test_same_seed_same_campaign(noisy):
    again = simulate_dynamic_campaign(2, rng=np.random.default_rng(5), hold_s=1.0)
    for name in ("training_rss", "dynamic_rss", "acc", "kinect"):
        assert getattr(noisy, name).equals(getattr(again, name)), name
    for name in ("rss", "acc", "kinect", "position", "time_s", "acc_time_s", "movement"):
        np.testing.assert_array_equal(getattr(noisy.data, name), getattr(again.data, name))
    other = simulate_dynamic_campaign(2, rng=np.random.default_rng(6), hold_s=1.0)
    assert not other.acc.equals(noisy.acc)


def test_simulate_campaign_unchanged():
    first = simulate_campaign(1, rng=np.random.default_rng(3), hold_s=1.0, static_hold_s=1.0, dynamic=False)
    assert set(first.rss["session"]) == {"training", "online_static"}
    with pytest.raises(ValueError, match="n_users"):
        simulate_dynamic_campaign(0, rng=np.random.default_rng(3))


# --- files ----------------------------------------------------------------------------------


def test_csv_round_trip_is_byte_identical(noisy, tmp_path):
    paths = write_dynamic_campaign(noisy, tmp_path / "a", {"seed": 5})
    tables, sidecars, data = read_dynamic_campaign(tmp_path / "a")
    for name in ("user", "target", "time_s", "rss", "label", "movement", "acc", "acc_time_s", "kinect"):
        np.testing.assert_array_equal(getattr(data, name), getattr(noisy.data, name), err_msg=name)
    np.testing.assert_allclose(data.position, noisy.data.position, atol=5e-7)
    pd.testing.assert_frame_equal(tables["acc"], noisy.acc, check_dtype=False)
    assert sidecars["acc"]["metadata"]["acc_spec"]["adc_bits"] == 10
    # Rewriting what was read gives the same bytes.
    from wsnlib.io.rss import write_rss

    rewritten = {
        "acc": accel.write_acc(tables["acc"], tmp_path / "b" / "acc.csv", sidecars["acc"]["metadata"]),
        "kinect": accel.write_kinect(
            tables["kinect"], tmp_path / "b" / "kinect.csv", sidecars["kinect"]["metadata"]
        ),
        "dynamic_rss": write_rss(
            tables["dynamic_rss"], tmp_path / "b" / "dynamic_rss.csv", sidecars["dynamic_rss"]["metadata"]
        ),
    }
    for key, path in rewritten.items():
        assert path.read_bytes() == paths[key].read_bytes(), key
        assert path.with_suffix(".json").read_bytes() == paths[key].with_suffix(".json").read_bytes(), key
    # Writing the same campaign twice gives the same bytes too.
    again = write_dynamic_campaign(noisy, tmp_path / "c", {"seed": 5})
    for key in paths:
        assert again[key].read_bytes() == paths[key].read_bytes(), key


def test_sample_tables_are_validated(noisy, tmp_path):
    table = noisy.acc.head(6).copy()
    table.attrs = {}
    with pytest.raises(ValueError, match="rate_hz"):
        accel.write_acc(table, tmp_path / "x.csv")
    with pytest.raises(ValueError, match="no data rows"):
        accel.write_acc(table.iloc[:0], tmp_path / "x.csv", rate_hz=30.0)
    with pytest.raises(ValueError, match="columns"):
        accel.write_acc(table.drop(columns=["label"]), tmp_path / "x.csv", rate_hz=30.0)
    duplicated = pd.concat([table, table.iloc[:1]], ignore_index=True)
    with pytest.raises(ValueError, match="duplicate"):
        accel.write_acc(duplicated, tmp_path / "x.csv", rate_hz=30.0)
    bad = table.copy()
    bad.loc[0, "acc_x_m_s2"] = np.nan
    with pytest.raises(ValueError, match="acc_x_m_s2"):
        accel.write_acc(bad, tmp_path / "x.csv", rate_hz=30.0)
    path = accel.write_acc(table, tmp_path / "ok.csv", rate_hz=30.0)
    with pytest.raises(ValueError, match="kinect"):
        accel.read_kinect(path)
    df, sidecar = accel.read_acc(path)
    assert sidecar["kind"] == "acc" and df.attrs == {"rate_hz": 30.0, "kind": "acc"}
