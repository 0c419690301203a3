"""Tests for wsnlib.orientation.peers (x-io Fusion and VQF under packet loss, with the hybrid)
and for the output blend they share with Madgwick's hybrid,
:func:`wsnlib.orientation.hybrid_blend.blend_with_single_frame`.

References: static data at known orientations (pins the frames), the simulated arm's ground
truth, the libraries called directly (``imufusion.Ahrs``, ``vqf.VQF.updateBatch``) and
:func:`estimate_orientation` for the blend.
"""

import platform
import sys

import imufusion
import numpy as np
import pytest
import vqf

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.loss import gilbert_elliott, packets_to_samples
from wsnlib.orientation import (
    _fusion_updates,
    _vqf_updates,
    estimate_orientation,
    fusion_orientation,
    gaps,
    madgwick,
    triad,
    vqf_orientation,
)
from wsnlib.orientation.hybrid_blend import blend_with_single_frame
from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu

FS = 50.0
G_ENU = frames.gravity_specific_force_enu()
M_ENU = frames.magnetic_field_enu()
WRAPPERS = [fusion_orientation, vqf_orientation]
BLEND_CHOICES = [None, "output", "feedback"]


def angle_deg(q_a, q_b):
    return np.degrees(Q.angle_between(q_a, q_b))


@pytest.fixture(scope="module")
def arm():
    """Both nodes of the simulated arm extension, 10 s (500 samples), 2 Monte Carlo runs."""
    truth = arm_kinematics(arm_extension(fs=FS, duration_s=10.0))
    imu = simulate_imu(truth, rng=np.random.default_rng(7), n_runs=2)
    return truth.quat, imu.gyr, imu.acc, imu.mag  # (2, T, 4), (2, 2, T, 3) each


@pytest.fixture(scope="module")
def masks():
    """Bursty masks (2, 2, 500) with a gap at the start of one row and at the end of another."""
    packets = gilbert_elliott(84, 0.2, 3.0, rng=np.random.default_rng(3), shape=(2, 2))
    packets[0, 0, :2] = False
    packets[1, 1, -2:] = False
    return packets_to_samples(packets, 6, 500)


# --------------------------------------------------------------------------------------------
# Frames and accuracy
# --------------------------------------------------------------------------------------------

ORIENTATIONS = [
    [1.0, 0.0, 0.0, 0.0],
    Q.from_axis_angle([0.0, 0.0, 1.0], np.radians(90.0)),  # heading: east ↔ north
    Q.from_axis_angle([1.0, 0.0, 0.0], np.radians(120.0)),
    Q.normalize([0.3, -0.5, 0.6, 0.55]),
    Q.from_axis_angle([0.2, 1.0, 0.1], np.radians(170.0)),  # nearly upside down
]


def static(q_true, n_t=500):
    acc = np.tile(Q.rotate_inverse(q_true, G_ENU), (n_t, 1))
    mag = np.tile(Q.rotate_inverse(q_true, M_ENU), (n_t, 1))
    return np.zeros((n_t, 3)), acc, mag


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("q_true", ORIENTATIONS)
def test_static_data_give_the_known_enu_orientation(wrapper, q_true):
    gyr, acc, mag = static(q_true)
    quat = wrapper(gyr, acc, mag, fs=FS)
    assert quat.shape == (500, 4)
    assert angle_deg(quat[-100:], q_true).max() < 1.0


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("q_true", ORIENTATIONS)
def test_static_imu_form_gets_the_inclination(wrapper, q_true):
    gyr, acc, _ = static(q_true)
    quat = wrapper(gyr, acc, None, fs=FS)
    up = Q.rotate(quat[-1], acc[-1]) / frames.STANDARD_GRAVITY
    assert np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0))) < 1.0


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_simulated_arm_is_tracked(arm, wrapper):
    q_true, gyr, acc, mag = arm
    quat = wrapper(gyr, acc, mag, fs=FS)
    assert quat.shape == (2, 2, 500, 4)
    np.testing.assert_allclose(np.linalg.norm(quat, axis=-1), 1.0, atol=1e-12)
    err = angle_deg(quat, q_true)[..., 150:]  # after 3 s of convergence
    assert err.mean(axis=-1).max() < 2.0
    assert err.max() < 4.0


# --------------------------------------------------------------------------------------------
# Loss semantics and the libraries themselves
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("with_mag", [True, False])
def test_all_received_equals_no_mask(arm, wrapper, with_mag):
    _, gyr, acc, mag = arm
    mag = mag if with_mag else None
    ref = wrapper(gyr, acc, mag, fs=FS)
    out = wrapper(gyr, acc, mag, fs=FS, received=np.ones(500, dtype=bool))
    np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("blend", BLEND_CHOICES)
def test_lost_samples_hold_the_previous_output(arm, masks, wrapper, blend):
    _, gyr, acc, mag = arm
    gyr, acc, mag = gyr.copy(), acc.copy(), mag.copy()
    gyr[~masks], acc[~masks], mag[~masks] = np.nan, 0.0, np.inf  # lost samples are never read
    out = wrapper(gyr, acc, mag, fs=FS, received=masks, blend=blend)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    lost_after = np.nonzero(~masks[..., 1:])
    before = lost_after[:-1] + (lost_after[-1],)
    after = lost_after[:-1] + (lost_after[-1] + 1,)
    np.testing.assert_array_equal(out[after], out[before])
    first = np.argmax(masks[0, 0])  # row (0, 0) starts with a gap: it shows the first output
    assert first > 0
    np.testing.assert_array_equal(out[0, 0, :first], np.broadcast_to(out[0, 0, first], (first, 4)))


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("blend", BLEND_CHOICES)
def test_batch_equals_per_element_calls(arm, masks, wrapper, blend):
    _, gyr, acc, mag = arm
    out = wrapper(gyr, acc, mag, fs=FS, received=masks, blend=blend)
    for idx in np.ndindex(2, 2):
        one = wrapper(gyr[idx], acc[idx], mag[idx], fs=FS, received=masks[idx], blend=blend)
        np.testing.assert_array_equal(out[idx], one)
    # One recording with a batch of masks broadcasts.
    out = wrapper(gyr[0, 0], acc[0, 0], mag[0, 0], fs=FS, received=masks[0])
    assert out.shape == (2, 500, 4)
    np.testing.assert_array_equal(out[1], wrapper(gyr[0, 0], acc[0, 0], mag[0, 0], fs=FS, received=masks[0, 1]))


@pytest.mark.parametrize("with_mag", [True, False])
def test_vqf_equals_update_batch_on_the_received_samples(arm, masks, with_mag):
    _, gyr, acc, mag = arm
    gyr, acc, mag = gyr[0, 0], acc[0, 0], mag[0, 0] if with_mag else None
    key = "quat9D" if with_mag else "quat6D"

    def reference(sel):
        m = None if mag is None else np.ascontiguousarray(mag[sel])
        return vqf.VQF(1.0 / FS).updateBatch(np.ascontiguousarray(gyr[sel]), np.ascontiguousarray(acc[sel]), m)[key]

    # One contiguous run: a plain updateBatch on it (the causal filter, not offlineVQF).
    run = np.zeros(500, dtype=bool)
    run[40:400] = True
    out = vqf_orientation(gyr, acc, mag, fs=FS, received=run)
    ref = reference(run)
    np.testing.assert_array_equal(out[40:400], ref)
    np.testing.assert_array_equal(out[:40], np.broadcast_to(ref[0], (40, 4)))
    np.testing.assert_array_equal(out[400:], np.broadcast_to(ref[-1], (100, 4)))
    # Many runs: the state carries over, so it is updateBatch on the received samples only.
    mask = masks[0, 0]
    out = vqf_orientation(gyr, acc, mag, fs=FS, received=mask)
    np.testing.assert_array_equal(out[mask], reference(mask))


@pytest.mark.parametrize("with_mag", [True, False])
def test_fusion_equals_the_library_on_the_received_samples(arm, masks, with_mag):
    _, gyr, acc, mag = arm
    gyr, acc, mag, mask = gyr[0, 0], acc[0, 0], mag[0, 0], masks[0, 0]
    settings = imufusion.AhrsSettings()
    settings.sample_rate, settings.convention, settings.gain = FS, imufusion.CONVENTION_ENU, 0.5
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(settings)
    ref = []
    for t in np.flatnonzero(mask):
        g, a = np.degrees(gyr[t]), acc[t] / frames.STANDARD_GRAVITY
        ahrs.update(g, a, mag[t]) if with_mag else ahrs.update_no_magnetometer(g, a)
        ref.append(ahrs.get_quaternion())
    ref = np.array(ref, dtype=float)
    ref /= np.linalg.norm(ref, axis=-1, keepdims=True)
    out = fusion_orientation(gyr, acc, mag if with_mag else None, fs=FS, received=mask)
    np.testing.assert_array_equal(out[mask], ref)


NATIVE_HERE = (platform.machine().lower() in ("x86_64", "amd64") and sys.platform != "win32"
               and sys.implementation.name == "cpython")


@pytest.mark.skipif(not NATIVE_HERE, reason="the compiled loop passes Fusion's vectors as x86-64 System V does")
def test_fusion_runs_its_c_update_in_a_compiled_loop_here():
    assert _fusion_updates._native_calls() is not None


@pytest.mark.parametrize("with_mag", [True, False])
def test_compiled_fusion_updates_give_the_bits_of_ahrs_update(arm, with_mag):
    """Runs cut at arbitrary samples, the state set between them, rejection and the gyroscope range on, and
    the feedback hybrid's blends."""
    _, gyr, acc, mag = arm
    gyr_deg, acc_g = np.degrees(gyr[0, 0]), acc[0, 0] / frames.STANDARD_GRAVITY
    acc_g[100:110] = 0.0  # Fusion skips a zero accelerometer
    settings = imufusion.AhrsSettings()
    settings.sample_rate, settings.gain, settings.gyroscope_range = FS, 0.5, 100.0
    settings.convention = imufusion.CONVENTION_ENU
    settings.acceleration_rejection, settings.magnetic_rejection, settings.rejection_timeout = 3.0, 3.0, 1.0
    cuts = [0, 1, 37, 200, 201, 350, 500]
    blend_at = np.zeros(500, dtype=bool)
    blend_at[[5, 36, 37, 120, 121, 122, 499]] = True
    q_s = Q.normalize(np.column_stack((2.0 + acc_g[:, 2], acc_g)))  # unit quaternions that move with the data
    feedback = (blend_at, q_s, np.linspace(0.0, 1.0, 500))
    outs = []
    for native in (_fusion_updates.CHECKED, None):  # the compiled loop here, Ahrs.update from Python
        ahrs = imufusion.Ahrs()
        ahrs.set_settings(settings)
        out = np.empty((500, 4))
        updates = _fusion_updates.FusionUpdates(ahrs, gyr_deg, acc_g, mag[0, 0] if with_mag else None, out,
                                                feedback, native=native)
        for start, end in zip(cuts[:-1], cuts[1:], strict=True):
            updates.run(start, end)
            ahrs.set_quaternion(Q.normalize(out[end - 1] + [0.0, 0.1, 0.0, 0.0]))
        outs.append(out)
    np.testing.assert_array_equal(outs[0], outs[1])


def test_options_reach_the_libraries(arm, masks):
    _, gyr, acc, mag = arm
    args = (gyr[0, 0], acc[0, 0], mag[0, 0])
    run = fusion_orientation
    assert not np.array_equal(run(*args, fs=FS), run(*args, fs=FS, gain=0.1))
    assert not np.array_equal(run(*args, fs=FS), run(*args, fs=FS, settings={"gyroscope_range": 20.0}))
    assert not np.array_equal(vqf_orientation(*args, fs=FS), vqf_orientation(*args, fs=FS, params={"tauAcc": 1.0}))
    # ... also inside the hybrids, under loss (the gain and parameters reach the wrapped filter)
    for blend in ("output", "feedback"):
        hybrid = {"received": masks[0, 0], "blend": blend, "rho": 3.0, "tau": 6.0}
        assert not np.allclose(run(*args, fs=FS, **hybrid), run(*args, fs=FS, gain=2.0, **hybrid))
        assert not np.allclose(vqf_orientation(*args, fs=FS, **hybrid),
                               vqf_orientation(*args, fs=FS, params={"tauAcc": 0.5}, **hybrid))


# --------------------------------------------------------------------------------------------
# Hybrid
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_hybrid_without_loss_is_the_plain_filter(arm, wrapper):
    _, gyr, acc, mag = arm
    plain = wrapper(gyr, acc, mag, fs=FS)
    np.testing.assert_allclose(wrapper(gyr, acc, mag, fs=FS, blend="output"), plain, atol=1e-15, rtol=0)
    np.testing.assert_array_equal(wrapper(gyr, acc, mag, fs=FS, blend="feedback"), plain)


@pytest.fixture(scope="module")
def burst():
    """Humerus during a later arm extension (rise 5–7 s), 24 samples lost at 5.6 s."""
    truth = arm_kinematics(arm_extension(fs=FS, duration_s=10.0, start_s=5.0))
    imu = simulate_imu(truth, rng=np.random.default_rng(1), n_runs=2)
    mask = np.ones(500, dtype=bool)
    mask[280:304] = False
    return truth.quat[0], imu.gyr[:, 0], imu.acc[:, 0], imu.mag[:, 0], mask


@pytest.mark.parametrize("wrapper", WRAPPERS)
def test_hybrid_after_a_burst_is_closer_to_triad(burst, wrapper):
    q_true, gyr, acc, mag, mask = burst
    first = 304  # first sample after the gap
    q_s = triad(acc[:, first], mag[:, first])
    out = {h: wrapper(gyr, acc, mag, fs=FS, received=mask, blend=h) for h in BLEND_CHOICES}
    to_triad = {h: angle_deg(q[:, first], q_s) for h, q in out.items()}
    assert np.all(to_triad[None] > 20.0)  # the gap left the plain filter far behind
    assert np.all(to_triad["output"] < 0.5 * to_triad[None])
    # Until the first blend both variants are the same filter: identical there.
    np.testing.assert_allclose(out["feedback"][:, : first + 1], out["output"][:, : first + 1], atol=1e-12, rtol=0)
    # Feedback moves the state itself, so the filter recovers; the output blend only hides the lag.
    err = {h: angle_deg(q[:, first : first + 50], q_true[first : first + 50]).mean() for h, q in out.items()}
    assert err["output"] < err[None]
    assert err["feedback"] < 0.25 * err[None]


def test_vqf_state_read_is_a_snapshot_the_replay_can_restore(arm):
    """The VQF replay saves ``filt.state`` at a gap's start without copying it: each read must build
    new objects, which later updates leave as they were, and writing it back restores the filter."""
    _, gyr, acc, mag = arm
    filt = vqf.VQF(1.0 / FS)
    filt.updateBatch(gyr[0, 0, :100].copy(), acc[0, 0, :100].copy(), mag[0, 0, :100].copy())
    saved = filt.state
    frozen = repr(saved)
    after = filt.updateBatch(gyr[0, 0, 100:150].copy(), acc[0, 0, 100:150].copy(), mag[0, 0, 100:150].copy())
    assert repr(filt.state) != frozen  # the filter moved on ...
    assert repr(saved) == frozen  # ... and the saved state did not
    filt.state = saved
    again = filt.updateBatch(gyr[0, 0, 100:150].copy(), acc[0, 0, 100:150].copy(), mag[0, 0, 100:150].copy())
    np.testing.assert_array_equal(again["quat9D"], after["quat9D"])


def test_a_read_only_recording_compiles_the_gap_rates_once(arm, masks):
    # A broadcast recording's rows are read-only; numba would compile gap_rates again for them.
    _, gyr, acc, mag = arm
    signals = [np.broadcast_to(x[0, 0], masks.shape + (3,)) for x in (gyr, acc, mag)]
    for run in (vqf_orientation, fusion_orientation):
        run(*signals, fs=FS, received=masks, gap="ar", replay=True)
    assert all(signature[2].mutable for signature in gaps.gap_rates.signatures)


@pytest.mark.parametrize("native", [_vqf_updates.CHECKED, None])
@pytest.mark.parametrize("with_mag", [True, False])
def test_vqf_output_set_through_gyr_quat(arm, native, with_mag):
    _, gyr, acc, mag = arm
    filt = vqf.VQF(1.0 / FS)
    out = np.empty((500, 4))
    updates = _vqf_updates.VQFUpdates(filt, gyr[0, 0], acc[0, 0], mag[0, 0] if with_mag else None, out, native=native)
    updates.run(0, 100)
    q_f = Q.normalize([0.3, 0.2, -0.5, 0.7])
    updates.set_output(q_f)
    assert angle_deg(filt.getQuat9D() if with_mag else filt.getQuat6D(), q_f) < 1e-6


@pytest.mark.skipif(not NATIVE_HERE, reason="the compiled loops call VQF's C++ functions as x86-64 System V does")
def test_vqf_runs_its_cpp_update_in_a_compiled_loop_here():
    assert _vqf_updates._native_calls() is not None


@pytest.mark.parametrize("with_mag", [True, False])
def test_compiled_vqf_updates_give_the_bits_of_its_python_methods(arm, with_mag):
    """Runs cut at arbitrary samples, rates turned by ``updateGyr`` (with and without outputs), the output
    set between runs, and the feedback hybrid's blends: outputs and the whole state bit for bit."""
    _, gyr, acc, mag = arm
    cuts = [0, 1, 37, 200, 201, 350, 500]
    blend_at = np.zeros(500, dtype=bool)
    blend_at[[5, 36, 37, 120, 121, 122, 499]] = True
    q_s = Q.normalize(np.column_stack((20.0 + acc[0, 0, :, 2], acc[0, 0])))  # unit quaternions that move with the data
    feedback = (blend_at, q_s, np.linspace(0.0, 1.0, 500)) if with_mag else None
    outs, states = [], []
    for native in (_vqf_updates.CHECKED, None):  # the compiled loops here, vqf's Python methods
        filt = vqf.VQF(1.0 / FS)
        out = np.empty((500, 4))
        turned = np.empty((10, 4))
        updates = _vqf_updates.VQFUpdates(filt, gyr[0, 0], acc[0, 0], mag[0, 0] if with_mag else None, out,
                                          feedback, native=native)
        for start, end in zip(cuts[:-1], cuts[1:], strict=True):
            updates.run(start, end)
            updates.turn(gyr[0, 0, start:start + 10] * 1.5, turned)
            updates.turn(gyr[0, 0, start:start + 3])
            updates.set_output(Q.normalize(out[end - 1] + [0.0, 0.1, 0.0, 0.0]))
        outs.append(np.concatenate((out, turned)))
        states.append(repr(filt.state))
    np.testing.assert_array_equal(outs[0], outs[1])
    assert states[0] == states[1]


#: A compiled path that must fall back to the library's Python calls, with a warning: the library, what the
#: case changes (the self-check's verdict, the version the package reports, or the symbol that gives VQF's
#: state) and the warning.
NATIVE_FALLBACKS = {
    "Fusion disagrees": ("fusion", "_agrees", "did not reproduce Ahrs.update: Fusion runs from Python"),
    "Fusion other version": ("fusion", "1.4.0",
                             r"imufusion 1.4.0: its C update is called only for versions 1.3.x .* runs from Python"),
    "VQF disagrees": ("vqf", "_agrees", "did not reproduce its Python methods: VQF runs from Python"),
    "VQF other version": ("vqf", "2.2.0",
                          r"vqf 2.2.0: its C\+\+ functions are called only for versions 2.1.x .* runs from Python"),
    # an address that is not the state's (here: the parameters')
    "VQF state elsewhere": ("vqf", "_ZNK3VQF9getParamsEv",
                            "did not reproduce its Python methods: VQF runs from Python"),
}


@pytest.mark.skipif(not NATIVE_HERE, reason="elsewhere the peers always run from Python")
@pytest.mark.parametrize("case", NATIVE_FALLBACKS)
def test_a_native_update_not_known_to_reproduce_the_library_is_not_used(arm, masks, monkeypatch, case):
    library, change, message = NATIVE_FALLBACKS[case]
    module, run = (_fusion_updates, fusion_orientation) if library == "fusion" else (_vqf_updates, vqf_orientation)
    _, gyr, acc, mag = arm
    args = (gyr[0, 0], acc[0, 0], mag[0, 0])
    options = {"fs": FS, "received": masks[0, 0], "gap": "ar", "replay": True, "blend": "feedback"}
    expected = run(*args, **options)
    if change == "_agrees":
        monkeypatch.setattr(module, "_agrees", lambda native, with_mag: False)
    elif change.startswith("_Z"):
        monkeypatch.setitem(module._SYMBOLS, "state", (change, module._SYMBOLS["state"][1]))
    else:
        monkeypatch.setattr(module.importlib.metadata, "version", lambda name: change)
    module._native_calls.cache_clear()
    try:
        with pytest.warns(UserWarning, match=message):
            assert module._native_calls() is None
        np.testing.assert_array_equal(run(*args, **options), expected)
    finally:
        module._native_calls.cache_clear()


# --------------------------------------------------------------------------------------------
# blend_with_single_frame: the output blend of estimate_orientation, for any filter
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [{}, {"schedule": "hold", "hold_window": 20}, {"schedule": "instant"}, {"rho": 1.0, "tau": 3.0}],
)
def test_blend_equals_madgwick_hybrid_output(arm, masks, kwargs):
    _, gyr, acc, mag = arm
    ref = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, blend="output", **kwargs)
    q_d = madgwick(gyr, acc, mag, fs=FS, beta=0.1, received=masks)
    out = blend_with_single_frame(q_d, acc, mag, masks, **kwargs)
    np.testing.assert_allclose(out, ref, atol=1e-12, rtol=0)
    if kwargs.get("schedule") != "instant":
        assert np.abs(out - q_d).max() > 0.01  # it did blend


def test_blend_with_a_leading_gap_and_a_parameter_grid(arm, masks):
    _, gyr, acc, mag = arm
    q0 = Q.normalize([0.3, -0.1, 0.8, 0.2])
    kwargs = {"fs": FS, "beta": 0.1, "received": masks, "q0": q0}
    ref = estimate_orientation(gyr, acc, mag, blend="output", **kwargs)
    out = blend_with_single_frame(madgwick(gyr, acc, mag, **kwargs), acc, mag, masks, leading_gap=True)
    np.testing.assert_allclose(out, ref, atol=1e-12, rtol=0)
    rho = np.array([1.0, 4.0]).reshape(2, 1, 1)
    ref = estimate_orientation(gyr, acc, mag, blend="output", rho=rho, **kwargs)
    out = blend_with_single_frame(madgwick(gyr, acc, mag, **kwargs), acc, mag, masks, rho=rho, leading_gap=True)
    assert out.shape == (2, 2, 2, 500, 4)
    np.testing.assert_allclose(out, ref, atol=1e-12, rtol=0)


@pytest.mark.parametrize("wrapper", WRAPPERS)
@pytest.mark.parametrize("kwargs", [{"rho": 3.0, "tau": 6.0}, {"schedule": "hold", "hold_window": 20},
                                    {"single_frame_gate": True}])
def test_peers_output_blend_is_blend_with_single_frame_on_the_plain_output(arm, masks, wrapper, kwargs):
    """blend="output" runs the peer untouched and blends its output: the same as blending it afterwards."""
    _, gyr, acc, mag = arm
    plain = wrapper(gyr, acc, mag, fs=FS, received=masks)
    direct = wrapper(gyr, acc, mag, fs=FS, received=masks, blend="output", **kwargs)
    gate = {"gyr": gyr, "fs": FS} if "single_frame_gate" in kwargs else {}
    np.testing.assert_array_equal(direct, blend_with_single_frame(plain, acc, mag, masks, **kwargs, **gate))
    assert np.abs(direct - plain).max() > 0.01  # it did blend


def test_blend_without_loss_returns_quat_d(arm):
    _, gyr, acc, mag = arm
    q_d = madgwick(gyr, acc, mag, fs=FS, beta=0.1)
    np.testing.assert_allclose(blend_with_single_frame(q_d, acc, mag), q_d, atol=1e-15, rtol=0)


@pytest.mark.parametrize(
    "change, match",
    [
        ({"quat_d": np.ones((2, 2, 500, 3))}, "quat_d"),
        ({"quat_d": np.zeros((2, 2, 500, 4))}, "quat_d"),
        ({"acc": np.ones((2, 2, 499, 3))}, "acc"),
        ({"received": np.ones((2, 2, 500), dtype=int)}, "received"),
        ({"received": np.ones((2, 2, 499), dtype=bool)}, "received"),
        ({"schedule": "slow"}, "schedule"),
        ({"rho": 0.0}, "rho"),
        ({"hold_window": 5}, "hold_window"),
    ],
)
def test_blend_rejects_bad_inputs(arm, masks, change, match):
    _, gyr, acc, mag = arm
    args = {"quat_d": madgwick(gyr, acc, mag, fs=FS, beta=0.1), "acc": acc, "mag": mag, "received": masks}
    args |= change
    with pytest.raises(ValueError, match=match):
        blend_with_single_frame(**args)


# --------------------------------------------------------------------------------------------
# Bad inputs
# --------------------------------------------------------------------------------------------


def _bad_sample(name, value):
    def change(args):
        arr = np.array(args[name])
        arr[0, 0, 10] = value
        return {name: arr}

    return change


def _all_lost(args):
    mask = np.ones((2, 2, 500), dtype=bool)
    mask[1, 0] = False
    return {"received": mask}


COMMON_BAD = [
    (lambda a: {"gyr": a["gyr"][..., :2]}, "gyr"),
    (lambda a: {"acc": a["acc"][..., :499, :]}, "acc"),
    (lambda a: {"acc": np.ones((3, 2, 500, 3))}, "broadcast"),
    (lambda a: {"received": np.ones(500, dtype=int)}, "received"),
    (lambda a: {"received": np.ones(499, dtype=bool)}, "received"),
    (lambda a: {"fs": 0.0}, "fs"),
    (lambda a: {"fs": -50.0}, "fs"),
    (_bad_sample("gyr", np.nan), "gyr"),
    (_bad_sample("acc", 0.0), "acc"),
    (_bad_sample("mag", np.inf), "mag"),
    (_all_lost, "no received sample"),
    (lambda a: {"blend": "both"}, "blend.*'output'.*'feedback'"),
    (lambda a: {"blend": "output", "mag": None}, "mag is required for blend='output'"),
    (lambda a: {"blend": "output", "schedule": "slow"}, "schedule"),
    (lambda a: {"blend": "output", "hold_window": 5}, "hold_window"),
    (lambda a: {"blend": "output", "schedule": "hold", "hold_window": 0}, "hold_window"),
    (lambda a: {"blend": "output", "schedule": "hold", "hold_window": [5, 6]}, "hold_window"),
    (lambda a: {"blend": "feedback", "rho": 0.0}, "rho"),
    (lambda a: {"blend": "output", "tau": np.nan}, "tau"),
    (lambda a: {"rho": 2.0}, "rho is not used by .* without blend"),
    (lambda a: {"schedule": "decay", "hold_window": 5}, "schedule, hold_window are not used by .* without blend"),
    (lambda a: {"gap": "freeze"}, "gap"),
    (lambda a: {"gap_rate_prediction_span_s": 0.5}, "gap_rate_prediction_span_s only apply to gap='ar'"),
    (lambda a: {"gap": "ar", "gap_rate_prediction_window_s": -1.0}, "gap_rate_prediction_window_s"),
    (lambda a: {"gap": "ar", "gap_rate_prediction_span_s": np.nan}, "gap_rate_prediction_span_s"),
    (lambda a: {"replay": 1}, "replay must be True or False"),
    (lambda a: {"gap": "constant_rate", "gap_time_constant": 0.0}, "gap_time_constant"),
    (lambda a: {"output_on_lost": "last"}, "output_on_lost"),
]
FUSION_BAD = [
    (lambda a: {"gain": -0.5}, "gain"),
    (lambda a: {"settings": {"acceleration_rejection": -1.0}}, "settings"),
    (lambda a: {"settings": {"convention": 0}}, "settings"),
    (lambda a: {"settings": {"recovery": 1.0}}, "settings"),
    (lambda a: {"settings": [("gain", 1.0)]}, "settings"),
]
VQF_BAD = [
    (lambda a: {"params": {"tau_acc": 1.0}}, "params"),
    (lambda a: {"params": {"gyrTs": 0.01}}, "params"),
    (lambda a: {"params": {"tauAcc": "slow"}}, "params"),
    (lambda a: {"params": "defaults"}, "params"),
]
CASES = [(fusion_orientation, *case) for case in COMMON_BAD + FUSION_BAD] + [
    (vqf_orientation, *case) for case in COMMON_BAD + VQF_BAD
]


@pytest.mark.parametrize("wrapper, change, match", CASES)
def test_bad_inputs_raise(arm, wrapper, change, match):
    _, gyr, acc, mag = arm
    args = {"gyr": gyr, "acc": acc, "mag": mag, "fs": FS}
    args |= change(args)
    with pytest.raises(ValueError, match=match):
        wrapper(**args)
