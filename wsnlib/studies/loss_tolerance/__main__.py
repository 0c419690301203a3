"""The loss-tolerance study from the command line: ``python -m wsnlib.studies.loss_tolerance``.

On the BROAD trials in ``$WSNLIB_BROAD_DIR`` (every one present, or those named with
``--trials``), resampled to 50 Hz, notebook 10's registry is tuned leave-one-trial-out at
Gilbert–Elliott 10 % and scored under every profile (:func:`~wsnlib.studies.loss_tolerance.evaluate`).
Printed: per-method mean total RMSE per profile with a paired 95 % bootstrap interval at the
headline, the run time per method, the setting chosen most often, the issue's three targets
with PASS/MISS and margins, the two side questions (does gating the single frame help the
hybrids, does predicting through a gap help the peers) and where the best causal filter's error
lies.  ``--out FILE.csv`` also writes the per-trial table.

The runs go to local worker processes (``--jobs``, default one per core), or to a Dask cluster
(``--scheduler tcp://host:8786``); ``--budget N`` gives every method N settings
(:func:`~wsnlib.studies.loss_tolerance.with_budget`), e.g. 1,000 over every BROAD trial on a cluster:

    python -m wsnlib.studies.loss_tolerance [--quick] [--seed 2021] [--draws 1] [--trials NAME ...]
        [--budget N] [--jobs N | --scheduler ADDRESS] [--out F.csv]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from wsnlib import parallel
from wsnlib.io.broad import broad_trials
from wsnlib.studies import loss_tolerance as study
from wsnlib.studies.loss_tolerance import summary


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.studies.loss_tolerance",
                                     description="Loss-tolerant orientation on BROAD recordings (notebook 10's study).")
    parser.add_argument("--quick", action="store_true", help="2 trials, 2 settings per method")
    parser.add_argument("--budget", type=int, metavar="N",
                        help="settings per method: the grid, then draws over its search space "
                             "(default: the hand-picked grids, at most 8)")
    parser.add_argument("--jobs", type=int, default=-1, metavar="N",
                        help="local worker processes (default -1: one per core; 1: none)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on the Dask cluster of this scheduler, e.g. tcp://host:8786")
    parser.add_argument("--seed", type=int, default=2021, help="seed of the loss masks and the bootstrap")
    parser.add_argument("--draws", type=int, default=1, help="Gilbert-Elliott masks per trial and profile")
    parser.add_argument("--trials", nargs="+", metavar="NAME", help="BROAD trial names (default: every one present)")
    parser.add_argument("--out", metavar="CSV", help="also write the per-trial table to this file")
    return parser


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    names = list(args.trials) if args.trials else broad_trials(present_only=True)
    if args.quick:
        names = names[:2]
    if len(names) < 2:
        raise SystemExit("need at least 2 BROAD trials (in $WSNLIB_BROAD_DIR, or --trials) for leave-one-trial-out")
    loss_rng, boot_rng, budget_rng = np.random.default_rng(args.seed).spawn(3)
    methods = study.default_methods()
    budget = 2 if args.quick and args.budget is None else args.budget
    if budget is not None:
        methods = study.with_budget(methods, budget, rng=budget_rng)
    where = f"Dask cluster {args.scheduler}" if args.scheduler else f"{args.jobs} local job(s)"
    print(f"{len(names)} BROAD trials, tuned at {study.HEADLINE} (mean burst 3 packets of 6 samples), "
          f"{args.draws} draw(s) per trial and random profile, seed {args.seed}, "
          f"{max(len(m.grid) for m in methods.values())} settings per method, on {where}")
    try:
        client = parallel.connect(args.scheduler) if args.scheduler else None
    except ValueError as exc:
        raise SystemExit(f"--scheduler: {exc}") from None
    start = time.perf_counter()
    recordings = study.load_recordings(names, progress=False)
    try:
        result = study.evaluate(recordings, rng=loss_rng, methods=methods, draws=args.draws, n_jobs=args.jobs,
                                scheduler=client, progress=True)
    finally:
        if client is not None:
            client.close()
    elapsed = time.perf_counter() - start
    if args.out:
        result.per_trial.to_csv(args.out, index=False)

    table = summary.summary_table(result.per_trial, rng=boot_rng, metrics=("rmse_total",))
    means = table.pivot(index="method", columns="profile", values="mean")
    means = means.loc[list(methods), [p.name for p in result.profiles]]
    print("\nMean total RMSE (°) over trials, LOTO setting of each trial (95 % interval at the headline):")
    print(f"  {'method':28s} " + " ".join(f"{p[:12]:>12s}" for p in means.columns) + "    interval     run s")
    headline = table[table["profile"] == study.HEADLINE].set_index("method")
    for method, row in means.iterrows():
        low, high = headline.loc[method, ["ci_low", "ci_high"]]
        print(f"  {method:28s} " + " ".join(f"{v:12.2f}" for v in row)
              + f"  [{low:6.2f}, {high:6.2f}] {result.seconds[method]:6.1f}")
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
