"""Results that must not depend on the BLAS kernel OpenBLAS picks for the CPU.

A matrix product (``@``, ``np.dot``, ``np.linalg.norm`` of a 1-D vector) sums in an order
chosen by the kernel (``OPENBLAS_CORETYPE``) and the operands' shapes.  Tables 2–3 (the
exhaustive search and the simulated campaign it runs on), the bootstrap intervals and the
peers' outputs use :mod:`wsnlib.fixed_order` instead, so every kernel the CPU can run gives the
same bits.  Each kernel needs its own process: OpenBLAS reads ``OPENBLAS_CORETYPE`` when it loads.
What is *not* covered, by design, is stated in the README ("Same bits, which machine"): the
smoother's 9×9 solve (LAPACK) and numpy's CPU-specific elementwise functions (exp, log).
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

_SCRIPT = """
import hashlib, sys
import numpy as np
sys.path.insert(0, {tests!r})
from test_optimize import make_user
from wsnlib import stats
from wsnlib.optimize import paper_tables, search
from wsnlib.orientation import fusion_orientation, vqf_orientation
from wsnlib.posture import pitch_from_acc
from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu
from wsnlib.sim.campaign import simulate_dynamic_campaign

digest = hashlib.sha256()
def add(name, value):
    digest.update(name.encode())
    digest.update(value.encode() if isinstance(value, str) else np.ascontiguousarray(value).tobytes())

rng = np.random.default_rng(7)
t1 = [make_user(rng, samples=(23, 17, 31, 9)) for _ in range(3)]
t2 = [make_user(rng, samples=(23, 17, 31, 9), segment=1) for _ in range(3)]
for chunk in (1, 5_000, 1 << 18):
    add(f"search {{chunk}}", search(t1, chunk_elements=chunk)["pe_cm"].to_numpy())
tables = paper_tables(t1, t2)
add("table2", tables.table2.to_csv())
add("table3", tables.table3.to_csv())
ci = stats.bootstrap_ci(rng.normal(size=(13, 5)), rng=np.random.default_rng(1), n_boot=300)
add("bootstrap", np.stack([ci.estimate, ci.low, ci.high]))
campaign = simulate_dynamic_campaign(1, rng=np.random.default_rng(3), hold_s=2.0)
add("campaign rss", campaign.training_rss.to_csv())
imu = simulate_imu(arm_kinematics(arm_extension(fs=50.0, duration_s=4.0)), rng=np.random.default_rng(5))
add("pitch", pitch_from_acc(imu.acc[0], method="lowpass", fs=50.0))
add("fusion", fusion_orientation(imu.gyr[0], imu.acc[0], imu.mag[0], fs=50.0))
add("vqf", vqf_orientation(imu.gyr[0], imu.acc[0], imu.mag[0], fs=50.0))
print(digest.hexdigest())
"""

#: OpenBLAS kernel families and the CPU flags each needs (x86-64 Linux names).
_KERNELS = {"Prescott": {"sse3"}, "Haswell": {"avx2", "fma"}, "Zen": {"avx2", "fma"},
            "SkylakeX": {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"}}


def _cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            line = next(line for line in f if line.startswith("flags"))
    except (OSError, StopIteration):
        return set()
    flags = set(line.split(":", 1)[1].split())
    return flags | ({"sse3"} if "pni" in flags else set())  # Linux calls SSE3 "pni"


def test_tables_bootstrap_simulation_and_peers_do_not_depend_on_the_blas_kernel():
    flags = _cpu_flags()
    kernels = [name for name, needs in _KERNELS.items() if needs <= flags]
    if len(kernels) < 2:
        pytest.skip(f"fewer than two OpenBLAS kernels to compare on this CPU ({kernels})")
    script = _SCRIPT.format(tests=str(Path(__file__).parent))
    digests, cores = {}, set()
    for name in kernels:
        env = {**os.environ, "OPENBLAS_CORETYPE": name, "OPENBLAS_VERBOSE": "2"}
        run = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-3000:]
        core = [line for line in run.stderr.splitlines() if line.startswith("Core:")]  # what OpenBLAS loaded
        cores.update(core)
        digests[f"{name} ({', '.join(core) or 'core not reported'})"] = run.stdout.strip().splitlines()[-1]
    if len(cores) == 1:
        pytest.skip(f"OpenBLAS loaded the same kernel for every request here: {cores}")
    assert len(set(digests.values())) == 1, digests
