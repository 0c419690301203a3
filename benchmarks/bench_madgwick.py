"""Throughput of :func:`wsnlib.orientation.madgwick` (MARG form) against ``ahrs``.

Run from the repository root::

    .venv/bin/python benchmarks/bench_madgwick.py            # full sizes (about 45 s)
    .venv/bin/python benchmarks/bench_madgwick.py --quick    # small sizes, a few seconds

Prints aggregated filter steps per second (batch × samples / wall-clock seconds of one
``madgwick`` call, validation and output included, best of 3) at several batch sizes, with and
without a 10 % Gilbert–Elliott loss mask, then ``ahrs.filters.Madgwick.updateMARG``
called sample by sample, their ratios, and whether the targets are met.  Always exits 0:
this is a measurement, not a test.

Data: the paper's arm extension (:mod:`wsnlib.sim`), both nodes, independent sensor noise
per run.  To keep set-up short, at most ``POOL`` distinct recordings are simulated and
repeated (as real copies, so memory traffic is that of distinct data) to fill the batch;
the filter's cost does not depend on the values.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

FS = 50.0  # Hz, the paper's sampling rate
BETA = 0.1  # rad/s
POOL = 500  # distinct simulated recordings at most
SAMPLES_PER_PACKET = 6  # paper 001, Sec. IV
LOSS_RATE, MEAN_BURST = 0.10, 3.0  # Gilbert–Elliott: 10 % of packets lost, bursts of 3 on average

TARGET_STEPS = 5e6  # aggregated steps/s at batch 10,000
TARGET_RATIO = 200.0  # × ahrs
TARGET_BATCH = 10_000

FULL = {"batches": (1, 100, 10_000), "n_samples": 3_000, "ahrs_samples": 3_000, "masked_batch": 10_000}
QUICK = {"batches": (1, 100, 1_000), "n_samples": 300, "ahrs_samples": 300, "masked_batch": 1_000}


def machine_info() -> dict:
    import ahrs

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
        "ahrs": ahrs.__version__,
    }


def make_data(batch: int, n_samples: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Body-frame ``gyr``, ``acc``, ``mag``, each ``(batch, n_samples, 3)``, C-contiguous."""
    from wsnlib.sim import arm_extension, arm_kinematics, simulate_imu

    truth = arm_kinematics(arm_extension(fs=FS, duration_s=n_samples / FS))
    n_nodes = truth.quat.shape[0]
    n_distinct = min(batch, POOL)
    runs = -(-n_distinct // n_nodes)
    sim = simulate_imu(truth, rng=rng, n_runs=runs)
    data = {}
    for name in ("gyr", "acc", "mag"):
        pool = getattr(sim, name).reshape(runs * n_nodes, n_samples, 3)[:n_distinct]
        reps = -(-batch // n_distinct)
        data[name] = np.ascontiguousarray(np.tile(pool, (reps, 1, 1))[:batch])
    return data


def loss_mask(batch: int, n_samples: int, rng: np.random.Generator) -> np.ndarray:
    """``(batch, n_samples)`` received mask: Gilbert–Elliott packets of 6 samples."""
    from wsnlib.loss import gilbert_elliott, n_packets_for, packets_to_samples

    n_packets = n_packets_for(n_samples, SAMPLES_PER_PACKET)
    packets = gilbert_elliott(n_packets, LOSS_RATE, MEAN_BURST, rng=rng, shape=(batch,))
    return packets_to_samples(packets, SAMPLES_PER_PACKET, n_samples)


def _best_time(call, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best


def time_ours(data: dict, received=None, repeats: int = 3) -> float:
    """Best wall-clock seconds of one ``madgwick`` call on ``data`` (MARG form)."""
    from wsnlib.orientation import madgwick

    def call():
        madgwick(data["gyr"], data["acc"], data["mag"], fs=FS, beta=BETA, received=received)

    return _best_time(call, repeats)


def time_ahrs(data: dict, repeats: int = 3) -> float:
    """Best seconds for ``ahrs`` to filter batch element 0 of ``data``, one sample at a time."""
    from ahrs.filters import Madgwick

    gyr, acc, mag = (data[name][0] for name in ("gyr", "acc", "mag"))

    def call():
        filt = Madgwick(frequency=FS, gain=BETA)
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for t in range(len(gyr)):
            q = filt.updateMARG(q, gyr[t], acc[t], mag[t])

    return _best_time(call, repeats)


def agreement_with_ahrs(data: dict) -> float:
    """Max |q_ours − q_ahrs| over batch element 0 from the same start (a sanity check)."""
    from ahrs.filters import Madgwick

    from wsnlib import quaternion as Q
    from wsnlib.orientation import madgwick
    from wsnlib.orientation.madgwick import Q_ENU_FROM_NWU

    gyr, acc, mag = (data[name][0] for name in ("gyr", "acc", "mag"))
    q0 = Q.normalize([0.9, 0.1, -0.2, 0.3])
    ours = madgwick(gyr, acc, mag, fs=FS, beta=BETA, q0=q0)
    filt = Madgwick(frequency=FS, gain=BETA)
    q = Q.multiply(Q.conjugate(Q_ENU_FROM_NWU), q0)  # ahrs works in NWU
    ref = np.empty_like(ours)
    for t in range(len(gyr)):
        q = filt.updateMARG(q, gyr[t], acc[t], mag[t])
        ref[t] = Q.multiply(Q_ENU_FROM_NWU, q)
    return float(np.max(np.abs(ours - ref)))


def run(quick: bool = False, seed: int = 20240601, log=print) -> dict:
    """Measure everything; returns a dict of results (steps/s, ratios, target flags)."""
    sizes = QUICK if quick else FULL
    rng = np.random.default_rng(seed)
    n_t = sizes["n_samples"]
    results = {"machine": machine_info(), "quick": quick, "n_samples": n_t, "ours": {}}

    largest = max(sizes["batches"])
    log(f"simulating {min(largest, POOL)} distinct recordings x {n_t} samples ...")
    data = make_data(largest, n_t, rng)
    for batch in sizes["batches"]:
        subset = {name: arr[:batch] for name, arr in data.items()}
        seconds = time_ours(subset)
        results["ours"][batch] = batch * n_t / seconds
        log(f"  ours  batch {batch:>6,}: {results['ours'][batch]:>14,.0f} steps/s")

    batch = sizes["masked_batch"]
    received = loss_mask(batch, n_t, rng)
    subset = {name: arr[:batch] for name, arr in data.items()}
    seconds = time_ours(subset, received=received)
    results["masked"] = {"batch": batch, "steps_per_s": batch * n_t / seconds,
                         "received": float(received.mean())}  # fmt: skip
    log(f"  ours  batch {batch:>6,} with loss mask: {results['masked']['steps_per_s']:>14,.0f} steps/s")
    del data, subset

    n_ahrs = sizes["ahrs_samples"]
    one = make_data(1, n_ahrs, rng)
    results["ahrs"] = n_ahrs / time_ahrs(one)
    results["ahrs_max_abs_diff"] = agreement_with_ahrs(one)
    log(f"  ahrs  batch      1: {results['ahrs']:>14,.0f} steps/s")

    ours_big = results["ours"][largest]
    results["ratio_big"] = ours_big / results["ahrs"]
    results["ratio_one"] = results["ours"][1] / results["ahrs"]
    results["ratio_masked"] = results["masked"]["steps_per_s"] / results["ahrs"]
    results["targets"] = {
        f"ours at batch {largest:,} >= {TARGET_STEPS:,.0f} steps/s": ours_big >= TARGET_STEPS,
        f"ours at batch {largest:,} >= {TARGET_RATIO:.0f} x ahrs": results["ratio_big"] >= TARGET_RATIO,
        f"ours at batch {batch:,} with loss mask >= {TARGET_STEPS:,.0f} steps/s":
            results["masked"]["steps_per_s"] >= TARGET_STEPS,
        f"ours at batch {batch:,} with loss mask >= {TARGET_RATIO:.0f} x ahrs":
            results["ratio_masked"] >= TARGET_RATIO,
    }  # fmt: skip
    return results


def report(results: dict) -> str:
    m = results["machine"]
    n_t = results["n_samples"]
    lines = [
        "",
        f"machine: {m['machine']}, {m['cpu_count']} CPUs ({m['usable_cpus']} usable), "
        f"Python {m['python']}, numpy {m['numpy']}, ahrs {m['ahrs']}",
        "",
        f"{'filter':<44}{'steps/s':>14}{'x ahrs':>10}",
    ]
    for batch, rate in results["ours"].items():
        label = f"wsnlib madgwick, batch {batch:,} x {n_t:,}"
        lines.append(f"{label:<44}{rate:>14,.0f}{rate / results['ahrs']:>10.1f}")
    masked = results["masked"]
    label = f"  same, batch {masked['batch']:,}, {1 - masked['received']:.0%} lost (G-E)"
    lines.append(f"{label:<44}{masked['steps_per_s']:>14,.0f}{results['ratio_masked']:>10.1f}")
    lines.append(f"{'ahrs Madgwick.updateMARG, per sample':<44}{results['ahrs']:>14,.0f}{1.0:>10.1f}")
    lines += [
        "",
        f"ratio ours (batch {max(results['ours']):,}) / ahrs: {results['ratio_big']:.0f}x",
        f"ratio ours (batch 1) / ahrs: {results['ratio_one']:.2f}x",
        f"agreement with ahrs on one recording: max |dq| = {results['ahrs_max_abs_diff']:.1e}",
        "",
    ]
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
