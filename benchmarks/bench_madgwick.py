"""Throughput of wsnlib's compiled orientation filters against VQF, Fusion and ``ahrs``.

Run from the repository root::

    .venv/bin/python benchmarks/bench_madgwick.py            # full sizes (about 1 min, ~1.5 GB)
    .venv/bin/python benchmarks/bench_madgwick.py --quick    # small sizes, a few seconds

Prints samples per second (samples / wall-clock seconds of one call, validation and output
included, best of 3) for

* one stream, MARG, 50 Hz, 120,000 samples: ``wsnlib.orientation.madgwick`` beside
  ``vqf.VQF(…).updateBatch`` (compiled C++), ``imufusion.Ahrs.update`` (C, one Python call
  per sample) and ``ahrs.filters.Madgwick.updateMARG`` (Python, per sample), on the same data;
* one stream with a 10 % Gilbert–Elliott loss mask, every loss option of
  ``estimate_orientation`` (the hybrid with both blends);
* a batch of 10,000 × 3,000 samples (aggregated steps per second);
* the cost of the first call in a fresh process (compiled code loaded from numba's cache);

then the ratios and PASS/MISS for the targets of issue 10.  Always exits 0: this is a
measurement, not a test.  Timings vary with other load on the machine: run it on an idle one.

Data: the paper's arm extension (:mod:`wsnlib.sim`), 3,000 samples per distinct recording,
repeated (as real copies) to the length or batch needed; the filters' cost does not depend
on the values.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time

import numpy as np

FS = 50.0  # Hz, the paper's sampling rate
BETA = 0.1  # rad/s
SAMPLES_PER_PACKET = 6  # paper 001, Sec. IV
LOSS_RATE, MEAN_BURST = 0.10, 3.0  # Gilbert–Elliott: 10 % of packets lost, bursts of 3 on average
POOL = 200  # distinct simulated recordings at most

TARGET_ONE_STREAM = 10e6  # samples/s, one stream, MARG
TARGET_VQF_RATIO = 3.0  # × vqf updateBatch
TARGET_LOSS_OPTION = 5e6  # samples/s, one stream, every loss option
TARGET_BATCH = 10e6  # aggregated steps/s at batch 10,000 × 3,000
TARGET_FIRST_CALL = 1.0  # s, first call of a kernel in a fresh process

FULL = {"stream": 120_000, "batch": (10_000, 3_000), "fusion": 20_000, "ahrs": 3_000}
QUICK = {"stream": 6_000, "batch": (200, 300), "fusion": 2_000, "ahrs": 300}

#: Paper 001's loss options (label → keywords of estimate_orientation), as notebook 04 runs them.
OPTIONS = {"hold_last": {}, "dt_extension": {"method": "dt_extension"}, "gyro_interpolation": {"replay": True},
           "adaptive_beta": {"method": "adaptive_beta"}, "hybrid (output)": {"blend": "output"},
           "hybrid (feedback)": {"blend": "feedback"}}


def machine_info() -> dict:
    import ahrs
    import numba

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count()
    return {
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable,
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "ahrs": ahrs.__version__,
    }


def make_data(batch: int, n_samples: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Body-frame ``gyr``, ``acc``, ``mag``, each ``(batch, n_samples, 3)``, C-contiguous."""
    from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu

    piece = min(n_samples, 3_000)
    truth = arm_kinematics(arm_extension(fs=FS, duration_s=piece / FS))
    n_nodes = truth.quat.shape[0]
    n_distinct = min(batch, POOL)
    runs = -(-n_distinct // n_nodes)
    sim = simulate_imu(truth, rng=rng, n_runs=runs)
    data = {}
    for name in ("gyr", "acc", "mag"):
        pool = getattr(sim, name).reshape(runs * n_nodes, piece, 3)[:n_distinct]
        reps, reps_t = -(-batch // n_distinct), -(-n_samples // piece)
        data[name] = np.ascontiguousarray(np.tile(pool, (reps, reps_t, 1))[:batch, :n_samples])
    return data


def loss_mask(shape: tuple[int, ...], n_samples: int, rng: np.random.Generator) -> np.ndarray:
    """``shape + (n_samples,)`` received mask: Gilbert–Elliott packets of 6 samples."""
    from wsnlib.loss import gilbert_elliott, n_packets_for, packets_to_samples

    n_packets = n_packets_for(n_samples, SAMPLES_PER_PACKET)
    packets = gilbert_elliott(n_packets, LOSS_RATE, MEAN_BURST, rng=rng, shape=shape)
    return packets_to_samples(packets, SAMPLES_PER_PACKET, n_samples)


def best_time(call, repeats: int = 3) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best


def rate_ours(gyr, acc, mag, received=None, options=None) -> float:
    """Samples (or aggregated steps) per second of one wsnlib call, best of 3: ``madgwick``, or
    ``estimate_orientation`` with the loss ``options`` (keywords)."""
    from wsnlib.orientation import estimate_orientation, madgwick

    if options is None:
        def call():
            madgwick(gyr, acc, mag, fs=FS, beta=BETA, received=received)
    else:
        def call():
            estimate_orientation(gyr, acc, mag, fs=FS, beta=BETA, received=received, **options)
    call()  # compiled code loaded (or compiled) before timing
    return gyr[..., 0].size / best_time(call)


def rate_vqf(gyr, acc, mag) -> float:
    import vqf

    def call():
        vqf.VQF(1.0 / FS).updateBatch(gyr, acc, mag)

    return len(gyr) / best_time(call)


def rate_fusion(gyr, acc, mag) -> float:
    import imufusion

    gyr_deg, acc_g = np.degrees(gyr), acc / 9.80665

    def call():
        ahrs = imufusion.Ahrs()
        for t in range(len(gyr)):
            ahrs.update(gyr_deg[t], acc_g[t], mag[t])
            ahrs.get_quaternion()  # read the output, as a user would

    return len(gyr) / best_time(call)


def rate_ahrs(gyr, acc, mag) -> float:
    from ahrs.filters import Madgwick

    def call():
        filt = Madgwick(frequency=FS, gain=BETA)
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for t in range(len(gyr)):
            q = filt.updateMARG(q, gyr[t], acc[t], mag[t])

    return len(gyr) / best_time(call)


def agreement_with_ahrs(gyr, acc, mag) -> float:
    """Max |q_ours − q_ahrs| over one recording from the same start (a sanity check)."""
    from ahrs.filters import Madgwick

    from wsnlib import quaternion as Q
    from wsnlib.orientation import madgwick
    from wsnlib.orientation.madgwick import Q_ENU_FROM_NWU

    q0 = Q.normalize([0.9, 0.1, -0.2, 0.3])
    ours = madgwick(gyr, acc, mag, fs=FS, beta=BETA, q0=q0)
    filt = Madgwick(frequency=FS, gain=BETA)
    q = Q.multiply(Q.conjugate(Q_ENU_FROM_NWU), q0)  # ahrs works in NWU
    ref = np.empty_like(ours)
    for t in range(len(gyr)):
        q = filt.updateMARG(q, gyr[t], acc[t], mag[t])
        ref[t] = Q.multiply(Q_ENU_FROM_NWU, q)
    return float(np.max(np.abs(ours - ref)))


_FIRST_CALL = """
import time
import numpy as np
start = time.perf_counter()
from wsnlib.orientation import estimate_orientation, madgwick
imported = time.perf_counter()
gyr, acc, mag = np.zeros((50, 3)), np.tile([0, 0, 9.8], (50, 1)), np.tile([0, 20.0, -40.0], (50, 1))
received = np.arange(50) % 7 != 3
madgwick(gyr, acc, mag, fs=50.0, beta=0.1)
first = time.perf_counter()
estimate_orientation(np.stack([gyr, gyr]), acc, mag, fs=50.0, beta=0.1, received=received, blend="output")
batch = time.perf_counter()
print(imported - start, first - imported, batch - first)
"""


def first_call_seconds() -> dict:
    """Seconds in a fresh process: import, first one-stream call, first batched hybrid call."""
    subprocess.run([sys.executable, "-c", _FIRST_CALL], check=True, capture_output=True)  # fills the cache
    out = subprocess.run([sys.executable, "-c", _FIRST_CALL], check=True, capture_output=True, text=True)
    imported, first, batch = (float(x) for x in out.stdout.split())
    return {"import": imported, "first one-stream call": first, "first batched call": batch}


def run(quick: bool = False, seed: int = 20240601, log=print) -> dict:
    """Measure everything; returns a dict of results (samples/s, ratios, target flags)."""
    sizes = QUICK if quick else FULL
    rng = np.random.default_rng(seed)
    results = {"machine": machine_info(), "quick": quick, "sizes": sizes}

    n = sizes["stream"]
    log(f"one stream of {n:,} samples ...")
    one = {k: v[0] for k, v in make_data(1, n, rng).items()}
    sig = (one["gyr"], one["acc"], one["mag"])
    results["stream"] = {
        "wsnlib madgwick": rate_ours(*sig),
        "vqf VQF.updateBatch": rate_vqf(*sig),
        "imufusion Ahrs.update (per sample)": rate_fusion(*(x[: sizes["fusion"]] for x in sig)),
        "ahrs Madgwick.updateMARG (per sample)": rate_ahrs(*(x[: sizes["ahrs"]] for x in sig)),
    }
    results["ahrs_max_abs_diff"] = agreement_with_ahrs(*(x[: sizes["ahrs"]] for x in sig))

    received = loss_mask((), n, rng)
    results["received"] = float(received.mean())
    log("loss options ...")
    results["options"] = {label: rate_ours(*sig, received=received, options=options)
                          for label, options in OPTIONS.items()}
    del one, sig

    n_batch, n_t = sizes["batch"]
    log(f"batch {n_batch:,} x {n_t:,} ...")
    data = make_data(n_batch, n_t, rng)
    results["batch"] = rate_ours(data["gyr"], data["acc"], data["mag"])
    del data
    log("first call in a fresh process ...")
    results["first_call"] = first_call_seconds()

    ours, vqf_rate = results["stream"]["wsnlib madgwick"], results["stream"]["vqf VQF.updateBatch"]
    results["vqf_ratio"] = ours / vqf_rate
    slowest = min(results["options"], key=results["options"].get)
    first_calls = [s for label, s in results["first_call"].items() if label != "import"]
    results["targets"] = {
        f"one stream >= {TARGET_ONE_STREAM:,.0f} samples/s (measured {ours:,.0f})": ours >= TARGET_ONE_STREAM,
        f"one stream >= {TARGET_VQF_RATIO:.0f} x vqf updateBatch (measured {results['vqf_ratio']:.2f} x)":
            results["vqf_ratio"] >= TARGET_VQF_RATIO,
        f"every loss option, one stream >= {TARGET_LOSS_OPTION:,.0f} samples/s "
        f"(slowest: {slowest}, {results['options'][slowest]:,.0f})":
            results["options"][slowest] >= TARGET_LOSS_OPTION,
        f"batch {n_batch:,} x {n_t:,} >= {TARGET_BATCH:,.0f} steps/s (measured {results['batch']:,.0f})":
            results["batch"] >= TARGET_BATCH,
        f"first call in a fresh process < {TARGET_FIRST_CALL:.0f} s per kernel "
        f"(measured {max(first_calls):.2f} s)": max(first_calls) < TARGET_FIRST_CALL,
    }  # fmt: skip
    return results


def report(results: dict) -> str:
    m = results["machine"]
    sizes = results["sizes"]
    base = results["stream"]["vqf VQF.updateBatch"]
    lines = [
        "",
        f"machine: {m['machine']}, {m['cpu_count']} CPUs ({m['usable_cpus']} usable), Python {m['python']}, "
        f"numpy {m['numpy']}, numba {m['numba']}, ahrs {m['ahrs']}",
        "",
        f"one stream, MARG, {FS:.0f} Hz ({sizes['stream']:,} samples; Fusion on {sizes['fusion']:,}, "
        f"ahrs on {sizes['ahrs']:,})",
        f"{'filter':<48}{'samples/s':>14}{'x vqf':>9}",
    ]
    for label, rate in results["stream"].items():
        lines.append(f"{label:<48}{rate:>14,.0f}{rate / base:>9.2f}")
    lines += ["", f"one stream, {1 - results['received']:.0%} of samples lost (Gilbert-Elliott, packets of "
              f"{SAMPLES_PER_PACKET}), wsnlib estimate_orientation"]
    for label, rate in results["options"].items():
        lines.append(f"  {label:<46}{rate:>14,.0f}{rate / base:>9.2f}")
    n_batch, n_t = sizes["batch"]
    lines += ["", f"{f'batch {n_batch:,} x {n_t:,}, wsnlib madgwick (aggregated)':<48}{results['batch']:>14,.0f}"]
    lines += ["", "fresh process (compiled code from numba's cache):"]
    lines += [f"  {label:<46}{seconds:>10.2f} s" for label, seconds in results["first_call"].items()]
    lines += ["", f"agreement with ahrs on one recording: max |dq| = {results['ahrs_max_abs_diff']:.1e}", ""]
    note = "  (quick mode: smaller than the target configuration)" if results["quick"] else ""
    for what, met in results["targets"].items():
        lines.append(f"{'PASS' if met else 'MISS'}  {what}{note}")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes: runs in a few seconds")
    args = parser.parse_args(argv)
    print(report(run(quick=args.quick)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
