"""The compiled kernels: extreme parameters, memory, the on-disk cache, one stream vs batch.

The per-sample references of every option (test_loss_handling.py) and the agreement with
``ahrs`` (test_orientation.py) test the kernels' arithmetic; this file tests what the
compiled form adds.
"""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wsnlib import quaternion as Q
from wsnlib.orientation import _kernels, estimate_orientation, madgwick, madgwick_step
from wsnlib.orientation.hybrid_blend import blend_with_single_frame

FS = 50.0
#: Option sets of estimate_orientation that take each branch of the compiled loop.
OPTIONS = [
    {},
    {"method": "dt_extension"},
    {"replay": True},
    {"method": "adaptive_beta"},
    {"blend": "feedback"},
    {"method": "adaptive_beta", "blend": "output", "gap": "constant_rate", "replay": True},
    {"gap": "constant_rate", "gap_time_constant": 0.3, "output_on_lost": "hold"},
]


def _ids(options):
    return "-".join(f"{k}={v}" for k, v in options.items()) or "defaults"


@pytest.fixture
def data():
    rng = np.random.default_rng(3)
    n = 400
    gyr = 0.5 * rng.normal(size=(n, 3))
    acc = rng.normal(size=(n, 3)) + [0.0, 0.0, 9.8]
    mag = rng.normal(size=(n, 3)) + [0.0, 20.0, -40.0]
    received = rng.random(n) > 0.2
    return gyr, acc, mag, received


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"fs": 1e-300}, "fs"),
        ({"fs": 1e300}, "fs"),
        ({"beta": 1e308}, "beta"),
        ({"beta_max": 1e308, "method": "adaptive_beta"}, "beta_max"),
    ],
)
def test_extreme_finite_parameters_are_rejected(data, kwargs, name):
    gyr, acc, mag, received = data
    call = {"fs": FS, "beta": 0.1, "received": received} | kwargs
    with pytest.raises(ValueError, match=name):
        estimate_orientation(gyr, acc, mag, **call)
    if "method" not in kwargs:
        with pytest.raises(ValueError, match=name):
            madgwick(gyr, acc, mag, **{k: v for k, v in call.items() if k != "received"})


def test_inputs_at_any_scale_give_finite_unit_quaternions(data):
    gyr, acc, mag, received = data
    q0 = [1e300, 1e300, 0.0, 0.0]
    out = madgwick(gyr, acc * 100.0, mag * 1e-300, fs=FS, beta=0.1, q0=q0, received=received)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(out, madgwick(gyr, acc, mag, fs=FS, beta=0.1, q0=[1, 1, 0, 0], received=received),
                               atol=1e-12)
    step = madgwick_step(q0, gyr[0], acc[0] * 1e300, mag[0], 0.02, 0.1)
    assert np.all(np.isfinite(step))


def test_a_reading_no_sensor_gives_is_treated_as_lost_not_blamed_on_fs():
    """Issue 23: a gyro of 1e300 rad/s was reported as an overflow "of fs or the settings"; an acc
    of 1e200 (its norm overflows) as acc parallel to mag."""
    gyr = np.full((5, 3), 1e300)
    acc = np.tile([0.0, 0.0, 9.8], (5, 1))
    with pytest.warns(UserWarning, match=r"5 received sample\(s\) with an implausible reading .* treated as lost"):
        out = madgwick(gyr, acc, fs=1e-6, beta=0.1, q0=[1.0, 0, 0, 0])
    np.testing.assert_array_equal(out, np.tile([1.0, 0, 0, 0], (5, 1)))


def test_an_output_that_does_not_fit_fails_at_once_with_its_size(data):
    gyr, acc, mag, _ = data
    rho = np.ones((10**7, 1, 1))  # 10 M settings x 400 samples x 4 x 8 bytes = 128 GB
    with pytest.raises(MemoryError, match="GiB"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, blend="output", rho=rho[..., 0, 0])
    with pytest.raises(MemoryError, match="GiB"):
        blend_with_single_frame(Q.identity((gyr.shape[0],)), acc, mag, rho=np.ones(10**7))


@pytest.mark.parametrize("options", OPTIONS, ids=_ids)
def test_one_stream_equals_the_same_stream_in_a_batch(data, options):
    # One stream runs the loop directly, a batch through the parallel driver: same numbers.
    gyr, acc, mag, received = data
    masks = np.stack([received, np.roll(received, 7), received])
    kwargs = {"fs": FS, "beta": 0.1} | options
    batch = estimate_orientation(gyr, acc, mag, received=masks, **kwargs)
    for i in range(3):
        np.testing.assert_array_equal(batch[i], estimate_orientation(gyr, acc, mag, received=masks[i], **kwargs))


def test_lost_samples_are_never_read(data):
    gyr, acc, mag, received = data
    poisoned = [np.where(received[:, None], x, np.nan) for x in (gyr, acc, mag)]
    for options in OPTIONS:
        clean = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=received, **options)
        dirty = estimate_orientation(*poisoned, fs=FS, beta=0.1, received=received, **options)
        np.testing.assert_array_equal(clean, dirty)


def test_compiled_triad_agrees_with_scipy_align_vectors():
    rng = np.random.default_rng(5)
    acc, mag = rng.normal(size=(2, 200, 3))
    acc, mag = (v / np.linalg.norm(v, axis=-1, keepdims=True) for v in (acc, mag))
    ours = np.array([_kernels.triad(tuple(a), tuple(m)) for a, m in zip(acc, mag, strict=True)])
    from wsnlib import frames
    from wsnlib.orientation import triad

    np.testing.assert_allclose(ours, triad(acc, mag), atol=1e-14)
    g, f = frames.gravity_specific_force_enu(), frames.magnetic_field_enu()
    for q, a, m in zip(ours[:20], acc[:20], mag[:20], strict=True):
        rot, _ = Q.to_scipy(q).__class__.align_vectors([g, np.cross(g, f)], [a, np.cross(a, m)], weights=[1e6, 1])
        assert np.degrees(Q.angle_between(q, Q.from_scipy(rot))) < 1e-3


def test_read_only_and_writable_inputs_share_one_machine_code(data):
    """numba types a read-only array (a cached trial, a broadcast) apart from a writable one; the
    kernels get read-only views of either (``_batch.kernel_input``), so neither adds a compilation."""
    from wsnlib.orientation import _kalman_kernels, kalman_orientation

    frozen = [arr.copy() for arr in data]
    for arr in frozen:
        arr.flags.writeable = False
    gyr, acc, mag, received = data
    estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=received)
    kalman_orientation(gyr, acc, mag, fs=FS, received=received)
    compiled = len(_kernels.filter_stream.signatures), len(_kalman_kernels.kalman_stream.signatures)
    estimate_orientation(*frozen[:3], fs=FS, beta=0.1, received=frozen[3])
    kalman_orientation(*frozen[:3], fs=FS, received=frozen[3])
    assert (len(_kernels.filter_stream.signatures), len(_kalman_kernels.kalman_stream.signatures)) == compiled


#: Kernel modules whose calls may pass literals: the packet codec's helpers are a few lines each, and
#: their literal byte offsets spell out the packet's layout.
LITERALS_ALLOWED = {"wsnlib.stream._kernels"}


def literal_arguments(module):
    """``(function, line, call)`` of each call inside a jitted function of ``module`` to another jitted
    function compiled on its own (not ``inline="always"``) with a Python ``bool`` or ``int`` as an
    argument, written out or a module constant."""
    import ast
    import inspect

    from numba.core.registry import CPUDispatcher

    def resolve(node):
        if isinstance(node, ast.Name):
            return getattr(module, node.id, None)
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            return getattr(getattr(module, node.value.id, None), node.attr, None)
        return None

    found = []
    for function in ast.parse(inspect.getsource(module)).body:
        if not (isinstance(function, ast.FunctionDef) and isinstance(getattr(module, function.name), CPUDispatcher)):
            continue
        for call in ast.walk(function):
            callee = resolve(call.func) if isinstance(call, ast.Call) else None
            if not isinstance(callee, CPUDispatcher) or callee.targetoptions.get("inline") == "always":
                continue
            for arg in call.args:
                value = arg.operand if isinstance(arg, ast.UnaryOp) and isinstance(arg.op, ast.USub) else arg
                if ((isinstance(value, ast.Constant) and type(value.value) in (bool, int))
                        or (isinstance(value, ast.Name) and type(getattr(module, value.id, None)) in (bool, int))):
                    found.append((function.name, call.lineno, ast.unparse(call)))
    return found


def test_jitted_calls_pass_no_literal_that_would_compile_the_callee_again():
    """numba compiles a jitted callee once per *literal* argument value (``Literal[bool](True)``,
    ``Literal[int](0)``), each copy with everything it calls: the receiver's literal flags and node index
    made six copies of its step into the Kalman filter, three of the filter's step and five of its
    prediction (what that cost notebook 11's first run: CHANGELOG, stop 50).  Kernels pass
    ``PLAIN_TRUE``, ``PLAIN_FALSE``, ``PLAIN_ZERO`` (numpy scalars) or variables instead."""
    import importlib

    import wsnlib

    modules = sorted({
        ".".join(path.relative_to(Path(wsnlib.__file__).parent.parent).with_suffix("").parts).removesuffix(".__init__")
        for path in Path(wsnlib.__file__).parent.rglob("*.py") if "@njit" in path.read_text(encoding="utf-8")})
    assert "wsnlib.stream._receiver_kernels" in modules and "wsnlib.orientation._kalman_kernels" in modules
    found = {name: literal_arguments(importlib.import_module(name)) for name in modules if name not in LITERALS_ALLOWED}
    assert not {name: calls for name, calls in found.items() if calls}
    # the check sees literals where they are: the packet codec passes its byte offsets
    assert literal_arguments(importlib.import_module("wsnlib.stream._kernels"))


def test_compiled_code_is_cached_on_disk(tmp_path):
    """A fresh process writes the kernels' machine code to NUMBA_CACHE_DIR, so the next one loads it."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    code = ("import numpy as np; from wsnlib.orientation import madgwick; "
            "madgwick(np.zeros((3, 3)), np.tile([0, 0, 9.8], (3, 1)), fs=50.0, beta=0.1)")
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=600)
    cached = {p.name.split(".")[1].split("-")[0] for p in tmp_path.rglob("_kernels*.nbi")}
    assert {"filter_stream", "first_unusable"} <= cached, cached
    # the scalar kernels filter_stream calls live in another module and are cached there too
    scalar = {p.name.split(".")[1].split("-")[0] for p in tmp_path.rglob("_scalar_kernels*.nbi")}
    assert {"madgwick_update", "triad"} <= scalar, scalar


@pytest.mark.parametrize("options", [{}, {"blend": "output"}, {"blend": "feedback"}, {"replay": True},
                                     {"gap": "constant_rate", "output_on_lost": "hold"}], ids=_ids)
def test_scratch_memory_is_a_small_fraction_of_the_output(data, options):
    # numpy reports its allocations to tracemalloc: the peak during a call is the output plus
    # what the call needs besides (index arrays, per-element parameters).
    import tracemalloc

    gyr, acc, mag, received = data
    masks = np.stack([np.roll(received, k) for k in range(64)])
    if "blend" in options:
        options = options | {"rho": np.linspace(1.0, 8.0, 8)[:, None]}  # a (ρ) grid over 64 masks: batch (8, 64)
    else:  # (ρ is refused without the hybrid: the same batch as 8 × 64 masks)
        masks = np.stack([masks] * 8)
    estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, **options)
    tracemalloc.start()  # (after a first call: compiling or loading the kernels allocates too)
    out = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=masks, **options)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1.1 * out.nbytes, (peak, out.nbytes)


def _turning(n=300, rate=(0.3, -0.2, 0.8)):
    """Exact gyr/acc/mag of a constant body rate from the identity, and the true quaternions."""
    t = np.arange(n) / FS
    rotvec = np.outer(t, rate)
    q_true = Q.from_rotation_vector(rotvec)
    from wsnlib import frames

    acc = Q.rotate_inverse(q_true, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(q_true, frames.magnetic_field_enu())
    return np.tile(rate, (n, 1)), acc, mag, q_true


def test_constant_rate_prediction_follows_a_constant_turn_through_a_gap():
    gyr, acc, mag, q_true = _turning()
    received = np.ones(len(gyr), bool)
    received[100:160] = False
    q0 = q_true[0]
    held = madgwick(gyr, acc, mag, fs=FS, beta=0.05, q0=q0, received=received)
    predicted = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.05, q0=q0, received=received, gap="constant_rate")
    err_held = np.degrees(Q.angle_between(held[100:160], q_true[100:160]))
    err_pred = np.degrees(Q.angle_between(predicted[100:160], q_true[100:160]))
    before = np.degrees(Q.angle_between(held[99], q_true[99]))  # the filter's own steady error
    assert err_held.max() > 30.0  # frozen while the sensor turned ~0.9 rad/s for 1.2 s
    assert err_pred.max() < before + 0.2
    # Received samples before the gap are untouched; the same call without loss agrees.
    np.testing.assert_array_equal(held[:100], predicted[:100])
    # A decaying rate lies between the two.
    decayed = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.05, q0=q0, received=received, gap="constant_rate",
                                   gap_time_constant=0.3)
    err_decay = np.degrees(Q.angle_between(decayed[159], q_true[159]))
    assert err_pred[-1] < err_decay < err_held[-1]


def test_gap_prediction_arguments_are_checked(data):
    gyr, acc, mag, received = data
    with pytest.raises(ValueError, match="gap"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, gap="extrapolate")
    with pytest.raises(ValueError, match="gap_time_constant"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, gap_time_constant=0.5)
    with pytest.raises(ValueError, match="dt_extension"):
        estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, method="dt_extension", gap="constant_rate")
    with pytest.raises(TypeError, match="gap"):  # madgwick is the receiver only: options are estimate_orientation's
        madgwick(gyr, acc, mag, fs=FS, beta=0.1, gap="constant_rate")
    for options in ({}, {"replay": True}, {"method": "adaptive_beta"}):
        out = estimate_orientation(gyr, acc, mag, fs=FS, beta=0.1, received=received, gap="constant_rate",
                                   blend="feedback", **options)
        assert np.all(np.isfinite(out))


@pytest.mark.parametrize("threshold", [0, 2**40])
def test_the_parallel_and_serial_checks_report_the_same_sample(data, monkeypatch, threshold):
    from wsnlib.orientation import _batch

    monkeypatch.setattr(_batch, "PARALLEL_CHECK_SAMPLES", threshold)
    gyr, acc, mag, received = data
    masks = np.stack([received] * 5)
    bad = np.repeat(acc[None], 5, axis=0)
    t = int(np.flatnonzero(received)[10])
    bad[3, t] = 0.0
    bad[4, t - 1] = np.nan  # a later batch element: the first in (batch..., t) order is reported
    with pytest.raises(ValueError, match=rf"acc is a zero vector at received sample \(batch..., t\) = \(3, {t}\)"):
        estimate_orientation(gyr, bad, mag, fs=FS, beta=0.1, received=masks)


def test_each_version_of_the_sources_caches_apart(tmp_path):
    """Issue 23: a process that imported the old sources and compiles after an edit must not store
    its machine code where the edited sources look for theirs; other versions' files are dropped."""
    import shutil

    import wsnlib

    copy = tmp_path / "wsnlib"
    shutil.copytree(Path(wsnlib.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    env = {key: value for key, value in os.environ.items() if key != "NUMBA_CACHE_DIR"} | {"PYTHONPATH": str(tmp_path)}
    script = (
        "import sys, pathlib\n"
        "from wsnlib.orientation import _numba_cache as c, _scalar_kernels as s\n"
        "if sys.argv[1] == 'edit':  # the sources change under a running process\n"
        "    p = pathlib.Path(s.__file__).with_name('gaps.py'); p.write_text(p.read_text() + '# edited\\n')\n"
        "s.squared_norm3(1.0, 2.0, 3.0)\n"
        "print(c.cache_dir(s.squared_norm3))\n"
    )

    def cache_of(mode):
        done = subprocess.run([sys.executable, "-c", script, mode], env=env, cwd=tmp_path, check=True, timeout=600,
                              capture_output=True, text=True)
        return Path(done.stdout.strip())

    old = cache_of("none")
    kept_open = cache_of("edit")  # imported the old sources, compiled after the edit
    assert kept_open == old and list(old.glob("_scalar_kernels.squared_norm3-*.nbi"))
    fresh = cache_of("none")  # imports the edited sources: its own folder, the old one's files dropped
    assert fresh != old and fresh.parent.parent == old.parent.parent
    assert list(fresh.glob("_scalar_kernels.squared_norm3-*.nbi")) and not list(old.rglob("*.nb[ic]"))


@pytest.mark.parametrize("n_threads, n_items", [(1, 5), (2, 1), (2, 2), (2, 7), (2, 0)])
def test_batch_items_run_once_each_on_their_threads_slot(n_threads, n_items):
    """``_batch.in_threads`` (the Kalman filter's and the smoother's batches): every item exactly once, each
    thread a contiguous block in order with its own slot, numba's thread count respected, and one thread
    in this one (no pool) for a single thread or item."""
    import threading
    import time

    import numba

    from wsnlib.orientation import _batch

    seen = []
    lock = threading.Lock()

    def run_one(item, slot):
        with lock:
            seen.append((item, slot, threading.get_ident()))
        time.sleep(0.01)  # (the threads overlap: a slot shared by two would interleave its items)

    if n_threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"numba has {numba.config.NUMBA_NUM_THREADS} thread(s) here")
    previous = numba.get_num_threads()
    numba.set_num_threads(n_threads)
    try:
        _batch.in_threads(run_one, n_items)
        slots = _batch.thread_slots(n_items)
    finally:
        numba.set_num_threads(previous)
    assert sorted(item for item, _, _ in seen) == list(range(n_items))
    assert slots == max(1, min(n_threads, n_items))
    by_slot = {}
    for item, slot, ident in seen:
        by_slot.setdefault(slot, []).append((item, ident))
    assert set(by_slot) <= set(range(slots))
    for items in by_slot.values():
        assert [item for item, _ in items] == list(range(items[0][0], items[0][0] + len(items)))  # a block, in order
        assert len({ident for _, ident in items}) == 1  # one thread per slot
    if slots == 1:
        assert {ident for _, _, ident in seen} <= {threading.get_ident()}


def test_a_threads_exception_reaches_the_caller():
    import numba

    from wsnlib.orientation import _batch

    def run_one(item, slot):
        if item == 3:
            raise RuntimeError("item 3 failed")

    previous = numba.get_num_threads()
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    try:
        with pytest.raises(RuntimeError, match="item 3 failed"):
            _batch.in_threads(run_one, 6)
    finally:
        numba.set_num_threads(previous)
