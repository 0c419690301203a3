"""Speed of the gap-aware Kalman filter and its smoother against VQF, one stream (issue 22).

Run from the repository root (BROAD trials in ``$WSNLIB_BROAD_DIR``; ``make`` sets it)::

    .venv/bin/python benchmarks/bench_kalman.py            # ~100k samples, best of 3
    .venv/bin/python benchmarks/bench_kalman.py --quick    # ~10k samples, best of 2
    .venv/bin/python benchmarks/bench_kalman.py --repeats 7   # best of 7 (a loaded machine)

Data: one BROAD trial (``02_undisturbed_slow_rotation_B``, a development trial of the study),
resampled to 50 Hz and tiled to about 100,000 samples (a mirrored copy after each copy, so the
motion is continuous); loss: Gilbert–Elliott 10 %, mean burst 3 packets of 6 samples, one seeded
draw.  Timed by CPU time (``time.process_time``: every thread of the process, not the time
spent waiting for a core on a shared machine), each the best of a few runs in this process after
a warm-up call (compiled code loaded), the runs interleaved (a round runs each call once):
``vqf.VQF.updateBatch`` without loss (the anchor), ``vqf.offlineVQF`` without loss,
:func:`wsnlib.orientation.kalman_orientation` without loss and under GE 10 %,
:func:`wsnlib.orientation.smooth_orientation` under GE 10 %, and Madgwick's filter for scale.
Printed: samples per second of each, the ratios, and PASS/MISS for the issue's targets (Kalman
≥ 0.8 × ``updateBatch``, lossless and under loss; smoother ≥ 0.8 × ``offlineVQF``).  Always
exits 0: this is a measurement, not a test.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time

import numpy as np

TRIAL = "02_undisturbed_slow_rotation_B"
FS = 50.0
TARGET = 0.8


def load_signals(n_samples: int):
    """The trial at 50 Hz, tiled (forward, then time-mirrored with negated rates) to ``n_samples``."""
    from wsnlib.io.broad import load_broad
    from wsnlib.io.resample import resample_broad

    rec = resample_broad(load_broad(TRIAL), FS)
    fwd = [np.asarray(x, dtype=float) for x in (rec.gyr, rec.acc, rec.mag)]
    bwd = [-fwd[0][::-1], fwd[1][::-1], fwd[2][::-1]]
    parts, n = [], 0
    while n < n_samples:
        parts.append(fwd if len(parts) % 2 == 0 else bwd)
        n += fwd[0].shape[0]
    return [np.ascontiguousarray(np.concatenate([p[i] for p in parts])[:n_samples]) for i in range(3)]


def loss_mask(n_samples: int, seed: int = 7) -> np.ndarray:
    from wsnlib.loss import LossProfile

    return LossProfile.gilbert_elliott(0.10).mask(n_samples, FS, np.random.default_rng(seed))


def best_rates(calls: dict, n_samples: int, repeats: int) -> dict:
    """Samples per second of each ``calls[name]()``: the best of ``repeats`` runs after one warm-up
    call, by the process's CPU time (all its threads; on a machine shared with other work, wall
    time also counts the time spent waiting for a core).  The runs are interleaved (one of each
    call per round), so that a change of load on the machine hits every call alike."""
    for call in calls.values():
        call()
    best = dict.fromkeys(calls, np.inf)
    for _ in range(repeats):
        for name, call in calls.items():
            start = time.process_time()
            call()
            best[name] = min(best[name], time.process_time() - start)
    return {name: n_samples / seconds for name, seconds in best.items()}


def run(quick: bool = False, log=print, repeats: int | None = None) -> dict:
    import vqf

    from wsnlib.orientation import kalman_orientation, madgwick, smooth_orientation

    n = 10_000 if quick else 100_000
    repeats = repeats or (2 if quick else 3)
    log(f"loading {TRIAL}, tiled to {n} samples at {FS:g} Hz ...")
    gyr, acc, mag = load_signals(n)
    received = loss_mask(n)
    ts = 1.0 / FS
    rates = best_rates({
        "vqf VQF.updateBatch, lossless": lambda: vqf.VQF(ts).updateBatch(gyr, acc, mag),
        "vqf offlineVQF, lossless": lambda: vqf.offlineVQF(gyr, acc, mag, ts),
        "kalman_orientation, lossless": lambda: kalman_orientation(gyr, acc, mag, fs=FS),
        "kalman_orientation, GE 10 %": lambda: kalman_orientation(gyr, acc, mag, fs=FS, received=received),
        "smooth_orientation, GE 10 %": lambda: smooth_orientation(gyr, acc, mag, fs=FS, received=received),
        "madgwick, GE 10 % (for scale)": lambda: madgwick(gyr, acc, mag, fs=FS, beta=0.041, received=received),
    }, n, repeats)
    anchor, offline = rates["vqf VQF.updateBatch, lossless"], rates["vqf offlineVQF, lossless"]
    ratios = {"kalman lossless / updateBatch": rates["kalman_orientation, lossless"] / anchor,
              "kalman GE 10 % / updateBatch": rates["kalman_orientation, GE 10 %"] / anchor,
              "smoother GE 10 % / offlineVQF": rates["smooth_orientation, GE 10 %"] / offline}
    return {"n": n, "quick": quick, "lost_share": float(1.0 - received.mean()), "rates": rates, "ratios": ratios,
            "machine": f"{platform.machine()} {platform.processor()}".strip(), "python": platform.python_version(),
            "targets": {f"{name} >= {TARGET}": value >= TARGET for name, value in ratios.items()}}


def report(results: dict) -> str:
    lines = ["", f"{results['n']:,} samples at {FS:g} Hz ({results['lost_share']:.1%} lost under GE 10 %); "
             f"{results['machine']}, Python {results['python']}", "", f"{'one stream':<36}{'samples/s':>14}"]
    lines += [f"{name:<36}{rate:>14,.0f}" for name, rate in results["rates"].items()]
    lines += ["", *(f"{name:<36}{value:>14.2f}" for name, value in results["ratios"].items()), ""]
    note = "  (quick mode: fewer samples)" if results["quick"] else ""
    lines += [f"{'PASS' if met else 'MISS'}  {what}{note}" for what, met in results["targets"].items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="~10k samples")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs per call (best of; default 3, quick 2)")
    args = parser.parse_args(argv)
    print(report(run(quick=args.quick, repeats=args.repeats)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
