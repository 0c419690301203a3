import numpy as np
import pytest

from wsnlib import tuning


def test_pareto_front_of_a_known_set():
    a = np.array([1.0, 2.0, 3.0, 2.0, 4.0])
    b = np.array([5.0, 3.0, 1.0, 4.0, 4.0])
    # (2,4) is beaten by (2,3); (4,4) by (3,1) and (2,3).
    np.testing.assert_array_equal(tuning.pareto_front(a, b), [True, True, True, False, False])


def test_knee_is_the_balanced_point():
    a = np.array([0.0, 0.2, 1.0])
    b = np.array([1.0, 0.2, 0.0])
    assert tuning.knee_point(a, b) == 1
    assert tuning.knee_point(np.array([1.0]), np.array([2.0])) == 0


def test_bootstrap_knee_is_stable_for_a_clear_optimum(rng):
    n_real = 200
    a = np.array([0.0, 0.2, 1.0])[:, None] + rng.normal(scale=0.01, size=(3, n_real))
    b = np.array([1.0, 0.2, 0.0])[:, None] + rng.normal(scale=0.01, size=(3, n_real))
    knees = tuning.bootstrap_knee(a, b, rng=rng, n_boot=100)
    assert knees.shape == (100,)
    assert np.all(knees == 1)


def test_bootstrap_is_reproducible_and_validates():
    a = np.random.default_rng(1).random((4, 30))
    b = np.random.default_rng(2).random((4, 30))
    first = tuning.bootstrap_knee(a, b, rng=np.random.default_rng(3), n_boot=20)
    second = tuning.bootstrap_knee(a, b, rng=np.random.default_rng(3), n_boot=20)
    np.testing.assert_array_equal(first, second)
    with pytest.raises(ValueError, match="n_boot"):
        tuning.bootstrap_knee(a, b, rng=np.random.default_rng(3), n_boot=0)
    with pytest.raises(ValueError, match="shape"):
        tuning.bootstrap_knee(a, b[:, :5], rng=np.random.default_rng(3))
    with pytest.raises(ValueError, match="cost_a"):
        tuning.pareto_front([1.0, np.nan], [1.0, 2.0])


def test_recommendation_round_trip(output_dir):
    with pytest.raises(FileNotFoundError, match="03"):
        tuning.read_recommendation()
    tuning.write_recommendation({"schedule": "decay", "blend": "feedback", "rho": 2.0, "tau": 6.0})
    assert tuning.read_recommendation() == {"schedule": "decay", "blend": "feedback", "rho": 2.0, "tau": 6.0}
    with pytest.raises(ValueError, match="tau"):
        tuning.write_recommendation({"schedule": "decay", "blend": "feedback", "rho": 2.0})


def test_hybrid_options_pass_hold_window_only_for_hold():
    setting = {"schedule": "decay", "blend": "output", "rho": 2, "tau": 6, "hold_window": 50}
    assert tuning.hybrid_options(setting) == {"method": "hybrid", "rho": 2.0, "tau": 6.0, "schedule": "decay",
                                              "blend": "output"}
    assert tuning.hybrid_options({**setting, "schedule": "hold"})["hold_window"] == 50


@pytest.fixture(scope="module")
def small_trials():
    from wsnlib.sim import movement_set
    from wsnlib.sim.trials import LossProfile, arm_loss_trials

    movements = dict(list(movement_set(fs=50.0, duration_s=4.0).items())[:2])
    return arm_loss_trials(movements, [LossProfile.burst(60, 4), LossProfile.gilbert_elliott(0.2)], 2,
                           rng=np.random.default_rng(11))


def test_hybrid_sweep_shapes_and_only_the_product_matters(small_trials):
    rho_grid, tau_grid = [1.0, 2.0, 4.0], [2.0, 1.0]
    foms, references = tuning.hybrid_sweep(small_trials, rho_grid, tau_grid, beta=0.041, hold_window=50,
                                           threshold_deg=5.0, configurations=[("decay", "feedback")])
    n_trials = len(small_trials.labels)
    error = foms["decay", "feedback"][tuning.CANDIDATE_COLUMNS["mean max error (°)"]]
    assert error.shape == (3, 2, n_trials)
    # (ρ, τ) = (1, 2) and (2, 1) have the same product, (4, 1) another one.
    assert np.allclose(error[0, 0], error[1, 1], atol=1e-6)
    assert not np.allclose(error[0, 0], error[2, 1])
    assert set(references) == {"data fusion", "single frame"}
    assert references["data fusion"][tuning.CANDIDATE_COLUMNS["mean max error (°)"]].shape == (n_trials,)


def test_candidate_table_and_recommendation_follow_the_costs(small_trials):
    rho_grid, tau_grid = [0.5, 4.0], [1.0, 6.0]
    configurations = [("hold", "output"), ("decay", "feedback")]
    foms, _ = tuning.hybrid_sweep(small_trials, rho_grid, tau_grid, beta=0.041, hold_window=50, threshold_deg=5.0,
                                  configurations=configurations)
    candidates, costs = tuning.candidate_table(foms, rho_grid, tau_grid, configurations)
    assert len(candidates) == 8 and list(candidates.columns[:4]) == ["schedule", "blend", "rho", "tau"]
    for column in tuning.CANDIDATE_COLUMNS:
        assert costs[column].shape == (8, len(small_trials.labels))
        assert np.allclose(candidates[column], costs[column].mean(axis=1))
    assert candidates.loc[4, "schedule"] == "decay" and candidates.loc[4, "rho"] == 0.5
    recommendation, knee, boot = tuning.recommend_hybrid(candidates, costs, rng=np.random.default_rng(0), n_boot=20,
                                                         beta=0.041)
    assert knee == tuning.knee_point(candidates["mean max error (°)"], candidates["mean jerk (°/s³)"])
    assert boot.shape == (20,)
    row = candidates.iloc[knee]
    assert (recommendation["schedule"], recommendation["rho"], recommendation["beta"]) == (
        row["schedule"], row["rho"], 0.041)
    assert recommendation["rho_tau_ci_low"] <= recommendation["rho_tau_ci_high"]
