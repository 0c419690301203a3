"""Speed of the gap-aware Kalman filter and its smoother against VQF, one stream (issue 22).

Run from the repository root (BROAD trials in ``$WSNLIB_BROAD_DIR``; ``make`` sets it)::

    .venv/bin/python benchmarks/bench_kalman.py              # ~100k samples, 9 rounds
    .venv/bin/python benchmarks/bench_kalman.py --quick      # ~10k samples, 3 rounds
    .venv/bin/python benchmarks/bench_kalman.py --repeats 21   # 21 rounds (a loaded machine)

Data: one BROAD trial (``02_undisturbed_slow_rotation_B``, a development trial of the study),
resampled to 50 Hz and tiled to about 100,000 samples (a mirrored copy after each copy, so the
motion is continuous); loss: Gilbert–Elliott 10 %, mean burst 3 packets of 6 samples, one seeded
draw.  Timed by CPU time (``time.process_time``: every thread of the process, not the time spent
waiting for a core on a shared machine) in rounds after a warm-up call (compiled code loaded): a
round runs each call once, in this order: ``vqf.VQF.updateBatch`` without loss (the anchor),
``vqf.offlineVQF`` without loss, :func:`wsnlib.orientation.kalman_orientation` without loss and
under GE 10 %, :func:`wsnlib.orientation.smooth_orientation` under GE 10 %, and Madgwick's filter
for scale.  Printed: samples per second of each (its best round: load on the machine only ever adds
time), and each ratio to its anchor from their best rounds, with a 90 % interval: the rounds are
resampled with replacement (a bootstrap, seeded) and the ratio of the best rounds of each resample
taken.  A target is PASS when the whole interval meets it, MISS when none of it does, and TIE when
the interval straddles it: on this machine's noise the run cannot tell (more rounds, ``--repeats``,
or an idle machine may).  A load that lasts the whole run is not in the interval (seen on the
development VM: VQF at 1.4 M samples/s in every round of one run, 1.9–2.0 M in the next two), so run
it more than once.  Always exits 0: this is a measurement, not a test.
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


def timed_rounds(calls: dict, repeats: int) -> dict:
    """CPU seconds of each ``calls[name]()`` in each of ``repeats`` rounds, ``{name: (repeats,) array}``,
    after one warm-up call of each.  A round runs every call once, in order (on a machine shared
    with other work, wall time would also count the time spent waiting for a core)."""
    for call in calls.values():
        call()
    seconds = {name: np.empty(repeats) for name in calls}
    for r in range(repeats):
        for name, call in calls.items():
            start = time.process_time()
            call()
            seconds[name][r] = time.process_time() - start
    return seconds


def best_ratio_interval(ours, anchor, rng, n_boot: int = 2000, level: float = 0.90) -> dict:
    """The anchor's best round over ours (a ratio of rates) and its bootstrap interval: ``{"ratio", "low", "high"}``.

    ``ours`` and ``anchor``: CPU seconds per round, paired by round; each resample draws rounds with
    replacement and takes the ratio of the two best among them.  (The ratio of all rounds is that of
    a resample holding both best rounds, so it often lies at an end of the interval.)"""
    ours, anchor = np.asarray(ours, dtype=float), np.asarray(anchor, dtype=float)
    picks = rng.integers(0, ours.size, size=(n_boot, ours.size))
    boot = anchor[picks].min(axis=1) / ours[picks].min(axis=1)
    tail = 50.0 * (1.0 - level)
    low, high = np.percentile(boot, [tail, 100.0 - tail])
    return {"ratio": float(anchor.min() / ours.min()), "low": float(low), "high": float(high)}


def verdict(low: float, high: float, target: float) -> str:
    """PASS when the interval ``[low, high]`` meets ``target``, MISS when none of it does, else TIE."""
    if not low <= high:
        raise ValueError(f"the interval's low end {low} is above its high end {high}")
    return "PASS" if low >= target else "MISS" if high < target else "TIE"


def run(quick: bool = False, log=print, repeats: int | None = None) -> dict:
    import vqf

    from wsnlib.orientation import kalman_orientation, madgwick, smooth_orientation

    n = 10_000 if quick else 100_000
    repeats = repeats or (3 if quick else 9)
    log(f"loading {TRIAL}, tiled to {n} samples at {FS:g} Hz ...")
    gyr, acc, mag = load_signals(n)
    received = loss_mask(n)
    ts = 1.0 / FS
    seconds = timed_rounds({
        "vqf VQF.updateBatch, lossless": lambda: vqf.VQF(ts).updateBatch(gyr, acc, mag),
        "vqf offlineVQF, lossless": lambda: vqf.offlineVQF(gyr, acc, mag, ts),
        "kalman_orientation, lossless": lambda: kalman_orientation(gyr, acc, mag, fs=FS),
        "kalman_orientation, GE 10 %": lambda: kalman_orientation(gyr, acc, mag, fs=FS, received=received),
        "smooth_orientation, GE 10 %": lambda: smooth_orientation(gyr, acc, mag, fs=FS, received=received),
        "madgwick, GE 10 % (for scale)": lambda: madgwick(gyr, acc, mag, fs=FS, beta=0.041, received=received),
    }, repeats)
    rates = {name: n / float(s.min()) for name, s in seconds.items()}
    pairs = {"kalman lossless / updateBatch": ("kalman_orientation, lossless", "vqf VQF.updateBatch, lossless"),
             "kalman GE 10 % / updateBatch": ("kalman_orientation, GE 10 %", "vqf VQF.updateBatch, lossless"),
             "smoother GE 10 % / offlineVQF": ("smooth_orientation, GE 10 %", "vqf offlineVQF, lossless")}
    rng = np.random.default_rng(0)
    ratios = {name: best_ratio_interval(seconds[ours], seconds[anchor], rng) for name, (ours, anchor) in pairs.items()}
    return {"n": n, "quick": quick, "repeats": repeats, "lost_share": float(1.0 - received.mean()), "rates": rates,
            "ratios": ratios, "seconds": seconds,
            "machine": f"{platform.machine()} {platform.processor()}".strip(), "python": platform.python_version(),
            "targets": {f"{name} >= {TARGET}": verdict(r["low"], r["high"], TARGET) for name, r in ratios.items()}}


def report(results: dict) -> str:
    lines = ["", f"{results['n']:,} samples at {FS:g} Hz ({results['lost_share']:.1%} lost under GE 10 %); "
             f"{results['machine']}, Python {results['python']}; {results['repeats']} rounds", "",
             f"{'one stream (best round)':<36}{'samples/s':>14}"]
    lines += [f"{name:<36}{rate:>14,.0f}" for name, rate in results["rates"].items()]
    lines += ["", f"{'ratio of the best rounds':<36}{'ratio':>8}{'90 % interval':>16}"]
    lines += [f"{name:<36}{r['ratio']:>8.2f}{r['low']:>10.2f} – {r['high']:.2f}"
              for name, r in results["ratios"].items()]
    lines.append("")
    note = "  (quick mode: fewer samples)" if results["quick"] else ""
    lines += [f"{outcome:<4}  {what}{note}" for what, outcome in results["targets"].items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="~10k samples")
    parser.add_argument("--repeats", type=int, default=None, help="rounds (default 9, quick 3)")
    args = parser.parse_args(argv)
    print(report(run(quick=args.quick, repeats=args.repeats)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
