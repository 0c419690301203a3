"""Loss-tolerant orientation on real data (issue 11's targets): a thin CLI over the study.

The logic lives in :mod:`wsnlib.studies.loss_tolerance` (methods, loss profiles, leave-one-trial-
out tuning at GE 10 %, metrics) and :mod:`wsnlib.studies.loss_tolerance_summary` (bootstrap
intervals, targets).  On every BROAD trial present in ``$WSNLIB_BROAD_DIR`` (resampled to
50 Hz), each method's grid (at most 8 settings) is tuned leave-one-trial-out at Gilbert–Elliott
10 % (mean burst 3 packets of 6 samples, one seeded draw per trial); every other profile is
scored with the setting chosen for each trial there.  Printed: per-method mean total RMSE
with a paired 95 % bootstrap interval over trials under each profile, the run time per method,
the three targets with PASS/MISS and margins (≤ 0.5×, ≤ 0.25×, ≤ VQF + 1°), and whether
gating the single frame helps the hybrids and predicting through a gap helps the peers (paired
differences over trials).

Run:  ``WSNLIB_BROAD_DIR=../shared/data/broad .venv/bin/python benchmarks/eval_loss_tolerance.py [--quick]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from wsnlib.io.broad import broad_trials
from wsnlib.studies import loss_tolerance as study
from wsnlib.studies import loss_tolerance_summary as summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 trials, 2 settings per method")
    parser.add_argument("--seed", type=int, default=2021)
    args = parser.parse_args()
    names = broad_trials(present_only=True)
    if args.quick:
        names = names[:2]
    if len(names) < 2:
        raise SystemExit("need at least 2 BROAD trials in $WSNLIB_BROAD_DIR for leave-one-trial-out")
    methods = study.quick_methods() if args.quick else study.default_methods()
    print(f"{len(names)} BROAD trials, tuned at {study.HEADLINE} (mean burst 3 packets of 6 samples), "
          f"1 draw per trial and profile, seed {args.seed}")
    start = time.perf_counter()
    recordings = study.load_recordings(names, progress=False)
    loss_rng, boot_rng = np.random.default_rng(args.seed).spawn(2)
    result = study.evaluate(recordings, rng=loss_rng, methods=methods, progress=True)
    elapsed = time.perf_counter() - start

    table = summary.summary_table(result.per_trial, rng=boot_rng, metrics=("rmse_total",))
    means = table.pivot(index="method", columns="profile", values="mean")
    means = means.loc[list(methods), [p.name for p in result.profiles]]
    print("\nMean total RMSE (°) over trials, LOTO setting of each trial (95 % interval at the headline):")
    print(f"  {'method':28s} " + " ".join(f"{p[:12]:>12s}" for p in means.columns) + "    interval     run s")
    headline = table[table["profile"] == study.HEADLINE].set_index("method")
    for method, row in means.iterrows():
        low, high = headline.loc[method, ["ci_low", "ci_high"]]
        print(f"  {method:28s} " + " ".join(f"{v:12.2f}" for v in row) +
              f"  [{low:6.2f}, {high:6.2f}] {result.seconds[method]:6.1f}")
    chosen = result.choices.groupby("method", sort=False)["setting"].agg(lambda s: s.value_counts().index[0])
    print("\nSetting chosen most often (leave-one-trial-out at the headline):")
    for method, setting in chosen.items():
        print(f"  {method:28s} {setting}")
    targets = summary.targets_table(result.per_trial, rng=boot_rng)
    print(f"\nTargets ({study.HEADLINE}; ratio of means or paired difference, 95 % bootstrap interval):")
    print(summary.format_targets(targets))
    for title, pairs, metrics in (("Does gating the single frame help?", study.GATING_PAIRS,
                                   ("rmse_total", "rms_after_gap")),
                                  ("Does gap prediction help the peers?", study.GAP_PREDICTION_PAIRS,
                                   ("rmse_total", "rms_lost"))):
        pairs = [pair for pair in pairs if set(pair) <= set(methods)]
        if pairs:
            comparisons = summary.paired_comparisons(result.per_trial, pairs, rng=boot_rng, metrics=metrics)
            print(f"\n{title} (paired difference with − without over trials, 95 % interval):")
            print("\n".join(f"  {line.replace('**', '')}" for line in summary.comparison_sentences(comparisons)))
    best = summary.best_methods(result.per_trial)
    print("\n" + summary.diagnosis_sentence(result.per_trial, best["causal"]))
    print(f"\nTotal time {elapsed:.0f} s (load + evaluate).")


if __name__ == "__main__":
    main()
