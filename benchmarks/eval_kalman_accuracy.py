"""Accuracy of the Kalman filter and smoother on the BROAD trials, default settings (issue 22's speed work).

Run from the repository root (BROAD trials in ``$WSNLIB_BROAD_DIR``; ``make`` sets it)::

    .venv/bin/python benchmarks/eval_kalman_accuracy.py                     # 17 trials, 5 draws, ~1 min
    .venv/bin/python benchmarks/eval_kalman_accuracy.py --out after.csv     # also the per-run table
    .venv/bin/python benchmarks/eval_kalman_accuracy.py --compare before.csv after.csv

What a change for speed must keep: every BROAD trial present, resampled to 50 Hz, run through
:func:`wsnlib.orientation.kalman_orientation` and :func:`wsnlib.orientation.smooth_orientation`
with their defaults, lossless and under Gilbert–Elliott 10 % (mean burst 3 packets of 6 samples,
``--draws`` seeded masks per trial, seed 2021 + trial index); scored by BROAD's total RMSE over the
movement samples (:func:`wsnlib.metrics.broad_rmse_deg`).  Printed: the mean over trials (and
draws) per method and profile, and the largest amount by which the smoother is worse than its
filter on one trial and draw (the property test's bound is 0.5°).  ``--compare A B`` prints the
paired difference B − A per method and profile (mean, and the largest change on one run) from two
saved tables.  Always exits 0: a measurement, not a test.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from wsnlib.io.broad import broad_trials, load_broad
from wsnlib.io.resample import resample_broad
from wsnlib.loss import LossProfile
from wsnlib.metrics import broad_rmse_deg
from wsnlib.orientation import kalman_orientation, smooth_orientation

FS = 50.0
LOSS = LossProfile.gilbert_elliott(0.10)
SEED = 2021


def run(draws: int = 5, trials=None) -> pd.DataFrame:
    """One row per trial, profile ("lossless" or "GE 10 %"), draw and method ("kalman", "smoother"): the RMSE (°)."""
    rows = []
    names = list(trials or broad_trials(present_only=True))
    for i, name in enumerate(tqdm(names, desc="trials")):
        rec = resample_broad(load_broad(name), FS)
        masks = LOSS.mask(rec.n_samples, FS, np.random.default_rng(SEED + i), shape=(draws,))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # e.g. the attached-magnet trials' magnetometer warning
            runs = {("lossless", 0): None, **{("GE 10 %", d): masks[d] for d in range(draws)}}
            for (profile, draw), received in runs.items():
                for method, estimate in (("kalman", kalman_orientation), ("smoother", smooth_orientation)):
                    quat = estimate(rec.gyr, rec.acc, rec.mag, fs=FS, received=received)
                    rmse = float(broad_rmse_deg(quat, rec.quat_ref, rec.movement)["total"])
                    rows.append({"trial": name, "profile": profile, "draw": draw, "method": method, "rmse_deg": rmse})
    return pd.DataFrame(rows)


def summary(table: pd.DataFrame) -> str:
    means = table.groupby(["method", "profile"])["rmse_deg"].mean().unstack("profile")
    wide = table.pivot_table(index=["trial", "profile", "draw"], columns="method", values="rmse_deg")
    worse = (wide["smoother"] - wide["kalman"]).groupby(level="profile").max()
    lines = ["mean total RMSE (°) over trials (and draws), default settings, 50 Hz:", means.round(3).to_string(), "",
             "largest smoother − filter on one run (°; bound 0.5):", worse.round(3).to_string()]
    return "\n".join(lines)


def compare(before: pd.DataFrame, after: pd.DataFrame) -> str:
    keys = ["trial", "profile", "draw", "method"]
    both = before.merge(after, on=keys, suffixes=("_before", "_after"))
    both["change"] = both["rmse_deg_after"] - both["rmse_deg_before"]
    grouped = both.groupby(["method", "profile"])
    table = pd.DataFrame({"before": grouped["rmse_deg_before"].mean(), "after": grouped["rmse_deg_after"].mean(),
                          "mean change": grouped["change"].mean(), "largest worse": grouped["change"].max(),
                          "largest better": grouped["change"].min(), "runs": grouped.size()})
    return "paired change after − before (°):\n" + table.round(4).to_string()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=5, help="GE 10 %% masks per trial (default 5)")
    parser.add_argument("--out", help="write the per-run table to this CSV")
    parser.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"), help="compare two saved tables")
    args = parser.parse_args(argv)
    if args.compare:
        print(compare(*(pd.read_csv(path) for path in args.compare)))
        return 0
    table = run(draws=args.draws)
    if args.out:
        table.to_csv(args.out, index=False)
    print(summary(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
