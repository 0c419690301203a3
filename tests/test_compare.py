import numpy as np

from wsnlib import loss, metrics
from wsnlib.orientation import fusion_ahrs, madgwick, vqf_orientation
from wsnlib.orientation.compare import OUR_METHODS, PEER_ESTIMATORS, SINGLE_FRAME, run_estimators
from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu


def test_every_estimator_runs_on_the_same_masks(rng):
    truth = arm_kinematics(arm_extension(duration_s=5.0))
    gyr, acc, mag = (x[0, 0] for x in simulate_imu(truth, rng=rng, n_runs=1))
    n = gyr.shape[0]
    masks = np.stack([np.ones(n, bool), loss.burst_mask(n, 80, 4)])
    setting = {"rho": 3.0, "tau": 6.0, "schedule": "decay", "blend": "feedback"}
    out = run_estimators(gyr, acc, mag, fs=50.0, beta=0.041, received=masks, hybrid=setting)
    assert list(out) == list(OUR_METHODS) + [SINGLE_FRAME] + list(PEER_ESTIMATORS)
    assert all(q.shape == (2, n, 4) for q in out.values())
    plain = madgwick(gyr, acc, mag, fs=50.0, beta=0.041)
    for name in OUR_METHODS:           # no loss: every option is plain Madgwick
        np.testing.assert_allclose(out[name][0], plain, atol=1e-12)
    for library in ("Fusion", "VQF"):  # no loss: the hybrid changes nothing
        np.testing.assert_allclose(out[f"{library} + hybrid (feedback)"][0], out[library][0], atol=1e-9)
    # After the burst, the hybrids are nearer the truth than their plain filters.
    first_after = int(np.argmin(masks[1])) + 24
    for library in ("Fusion", "VQF"):
        err = {k: metrics.orientation_error_deg(out[k][1, first_after], truth.quat[0, first_after])
               for k in (library, f"{library} + hybrid (feedback)")}
        assert err[f"{library} + hybrid (feedback)"] < err[library]


def test_output_hybrids_equal_the_wrappers_own_output_stage(rng):
    # run_estimators blends the plain peer output instead of running the peer a second time.
    truth = arm_kinematics(arm_extension(duration_s=4.0))
    gyr, acc, mag = (x[0, 0] for x in simulate_imu(truth, rng=rng, n_runs=1))
    n = gyr.shape[0]
    masks = np.stack([loss.burst_mask(n, 60, 4), loss.burst_mask(n, 20, 8)])
    setting = {"rho": 3.0, "tau": 6.0, "schedule": "decay", "blend": "output"}
    out = run_estimators(gyr, acc, mag, fs=50.0, beta=0.041, received=masks, hybrid=setting)
    per_mask = [np.broadcast_to(x, masks.shape + (3,)) for x in (gyr, acc, mag)]
    for library, run in (("Fusion", fusion_ahrs), ("VQF", vqf_orientation)):
        direct = run(*per_mask, fs=50.0, received=masks, hybrid="output", rho=3.0, tau=6.0, schedule="decay")
        np.testing.assert_array_equal(out[f"{library} + hybrid (output)"], direct)


def test_peer_settings_reach_the_peers_and_their_hybrids(rng):
    truth = arm_kinematics(arm_extension(duration_s=3.0))
    gyr, acc, mag = (x[0, 0] for x in simulate_imu(truth, rng=rng, n_runs=1))
    n = gyr.shape[0]
    masks = np.stack([np.ones(n, bool), loss.burst_mask(n, 60, 4)])
    setting = {"rho": 3.0, "tau": 6.0, "schedule": "decay", "blend": "feedback"}
    out = run_estimators(gyr, acc, mag, fs=50.0, beta=0.041, received=masks, hybrid=setting,
                         fusion_gain=2.0, vqf_params={"tauAcc": 0.5})
    per_mask = [np.broadcast_to(x, masks.shape + (3,)) for x in (gyr, acc, mag)]
    shape = {"rho": 3.0, "tau": 6.0, "schedule": "decay"}
    for library, run, option in (("Fusion", fusion_ahrs, {"gain": 2.0}),
                                 ("VQF", vqf_orientation, {"params": {"tauAcc": 0.5}})):
        np.testing.assert_array_equal(out[library], run(*per_mask, fs=50.0, received=masks, **option))
        np.testing.assert_array_equal(out[f"{library} + hybrid (feedback)"],
                                      run(*per_mask, fs=50.0, received=masks, hybrid="feedback", **shape, **option))
    default = run_estimators(gyr, acc, mag, fs=50.0, beta=0.041, received=masks, hybrid=setting)
    for library in ("Fusion", "VQF"):  # the settings change the result
        assert not np.allclose(out[library], default[library])
