"""The loss-tolerance study from the command line: ``python -m wsnlib.studies.loss_tolerance``.

**Your own recordings** (files of :mod:`wsnlib.io.recording`, CSVs or their JSON sidecars; any
number of nodes, each file at its own rate)::

    python -m wsnlib.studies.loss_tolerance walk.csv run.csv [--loss ge:0.10:3 ...] [--draws N]
        [--methods Kalman VQF ...] [--out results.csv]

Every node with a reference is a unit (``"<file stem>/<node>"``, :func:`~wsnlib.studies.
loss_tolerance.load_recordings`); notebook 10's registry is tuned leave-one-recording-out (the
nodes of a file are held out together) at the first ``--loss`` profile and scored under every
profile, the lossless one first (:func:`~wsnlib.studies.loss_tolerance.evaluate`).  With a
single file there is nothing to tune on: every method runs with its default setting, and the
table says so (``setting_source``).  Printed, and written with ``--out``: one row per
recording, node, method, profile and draw with ``rmse_total_deg``, ``rmse_inclination_deg``,
``rmse_heading_deg`` (movement samples with a reference), ``setting_source`` and the setting
(:meth:`~wsnlib.studies.loss_tolerance.LossToleranceResult.rmse_table`); then the mean total RMSE per method
and profile.  Without ``--loss``, notebook 10's profiles (:data:`~wsnlib.studies.loss_tolerance.
PROFILES`, tuned at GE 10 %).

**BROAD** (no files): the trials in ``$WSNLIB_BROAD_DIR`` (every one present, or those named with
``--trials``), resampled to 50 Hz, tuned leave-one-trial-out at Gilbert–Elliott 10 % and scored
under notebook 10's profiles.  Printed: per-method mean total RMSE per profile with a paired
95 % bootstrap interval at the headline, the run time per method, the setting chosen most
often, the issue's targets with PASS/MISS and margins, the two side questions (does
gating the single frame help the hybrids, does each gap handling help each filter) and
where the best causal filter's error lies.  ``--out FILE.csv`` also writes the per-trial table.

Either way, the recording health check (:func:`~wsnlib.studies.loss_tolerance.units_health`:
repeated samples, reference vs gyroscope, magnetic field, units) is printed before the study
runs.  The runs go to local worker processes (``--jobs``, default one per core), or to a
Dask cluster (``--scheduler tcp://host:8786``); ``--budget N`` gives every method N settings
(:func:`~wsnlib.studies.loss_tolerance.space_grid`, log-spaced between the physical bounds of its
search space; default :data:`~wsnlib.studies.loss_tolerance.DEFAULT_BUDGET`), e.g. 1,000 over every BROAD trial on a
cluster::

    python -m wsnlib.studies.loss_tolerance [--quick] [--seed 2021] [--draws 1] [--trials NAME ...]
        [--methods NAME ...] [--budget N] [--jobs N | --scheduler ADDRESS] [--out F.csv]

``--methods`` runs only the named methods of the registry (names as in notebook 10's tables; a
smoother brings the filter whose setting it takes): a quick look at one's own recordings with the
methods one cares about.  On BROAD the targets and the diagnosis, which compare against the whole
registry, are then left out.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from wsnlib import parallel
from wsnlib._arguments import whole_number
from wsnlib.io.broad import broad_trials
from wsnlib.loss import SAMPLES_PER_PACKET, LossProfile
from wsnlib.studies import loss_tolerance as study
from wsnlib.studies.loss_tolerance import summary

LOSS_HELP = (f"a loss profile, repeatable (recording files only): 'ge:RATE[:MEAN_BURST[:PACKET]]' Gilbert-Elliott "
             f"loss at RATE (0-1) with bursts of MEAN_BURST packets on average (default 3) of PACKET samples "
             f"(default {SAMPLES_PER_PACKET}), e.g. ge:0.10:3; 'burst:START_S:PACKETS[:PERIOD_S[:PACKET]]' PACKETS "
             f"packets lost from START_S seconds on, once or every PERIOD_S seconds (paper 001: burst:4:4:8); "
             f"'none' (no loss: always run first, as the reference). The settings are tuned at the first profile "
             f"given. Default: notebook 10's profiles, tuned at GE 10 %%")


def loss_profile(spec: str) -> LossProfile:
    """The :class:`~wsnlib.loss.LossProfile` of a ``--loss`` spec (see :data:`LOSS_HELP`), named by the spec."""
    name = spec.strip()
    kind, *fields = name.split(":")
    try:
        numbers = [float(f) for f in fields]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{spec!r}: the fields after the kind must be numbers") from None
    if kind == "none" and not numbers:
        return LossProfile.none("lossless")
    if kind == "ge" and 1 <= len(numbers) <= 3:
        rate, burst, packet = (numbers + [3.0, SAMPLES_PER_PACKET][len(numbers) - 1:])[:3]
        if not (0.0 < rate < 1.0 and burst >= 1.0 and packet >= 1 and packet == int(packet)):
            raise argparse.ArgumentTypeError(f"{spec!r}: needs 0 < RATE < 1, MEAN_BURST >= 1 and a whole PACKET >= 1")
        return LossProfile.gilbert_elliott(rate, burst, samples_per_packet=int(packet), name=name)
    if kind == "burst" and 2 <= len(numbers) <= 4:
        start, packets, period, packet = (numbers + [None, SAMPLES_PER_PACKET][len(numbers) - 2:])[:4]
        if not (start >= 0 and packets >= 1 and packets == int(packets) and (period is None or period > 0)
                and packet >= 1 and packet == int(packet)):
            raise argparse.ArgumentTypeError(f"{spec!r}: needs START_S >= 0, whole PACKETS >= 1, PERIOD_S > 0 and a "
                                             f"whole PACKET >= 1")
        return LossProfile.burst(start, int(packets), period_s=period, samples_per_packet=int(packet), name=name)
    raise argparse.ArgumentTypeError(f"{spec!r} is not a loss profile: expected 'none', "
                                     f"'ge:RATE[:MEAN_BURST[:PACKET]]' or 'burst:START_S:PACKETS[:PERIOD_S[:PACKET]]'")


def _jobs(text: str) -> int:
    """``--jobs``: a whole number ≥ 1, or -1 (one per core)."""
    if text.strip() == "-1":
        return -1
    try:
        return whole_number(1)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text!r}: needs a whole number >= 1, or -1 (one per core)") from None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.studies.loss_tolerance",
                                     description="Loss-tolerant orientation on your recording files, or on BROAD "
                                                 "(notebook 10's study).")
    parser.add_argument("files", nargs="*", metavar="FILE",
                        help="recording files (wsnlib.io.recording: the CSV or its JSON sidecar); none: BROAD")
    parser.add_argument("--loss", action="append", type=loss_profile, metavar="SPEC", help=LOSS_HELP)
    parser.add_argument("--quick", action="store_true", help="2 settings per method (and 2 BROAD trials)")
    parser.add_argument("--budget", type=whole_number(1), metavar="N",
                        help="settings per method, log-spaced between the physical bounds of its search space "
                             f"(default {study.DEFAULT_BUDGET})")
    parser.add_argument("--jobs", type=_jobs, default=-1, metavar="N",
                        help="local worker processes (default -1: one per core; 1: none)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on the Dask cluster of this scheduler, e.g. tcp://host:8786")
    parser.add_argument("--seed", type=int, default=2021, help="seed of the loss masks and the bootstrap")
    parser.add_argument("--draws", type=whole_number(1), default=1,
                        help="Gilbert-Elliott masks per recording node and profile")
    parser.add_argument("--trials", nargs="+", metavar="NAME", help="BROAD trial names (default: every one present)")
    parser.add_argument("--methods", nargs="+", metavar="NAME",
                        help="only these methods of notebook 10's registry, e.g. 'Kalman' 'VQF' (default: every "
                             "one); a method that runs with another's setting (a smoother) brings that one too. "
                             "BROAD: the targets and the diagnosis, which need the whole registry, are left out")
    parser.add_argument("--out", metavar="CSV", help="also write the table (files) or the per-trial table (BROAD)")
    return parser


def _profiles(given) -> tuple[tuple[LossProfile, ...], str]:
    """Lossless first, then the given profiles (``none`` dropped: it is the first); the headline."""
    if not given:
        return study.PROFILES, study.HEADLINE
    lossy = [p for p in given if p.model != "none"]
    names = [p.name for p in lossy]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise SystemExit(f"--loss: {twice} given twice")
    profiles = (LossProfile.none("lossless"), *lossy)
    return profiles, profiles[min(1, len(profiles) - 1)].name


def _select(methods: dict, names) -> dict:
    """The registry's ``methods`` named in ``--methods`` (all without it), with each one whose setting a
    chosen method takes (:attr:`~wsnlib.studies.loss_tolerance.Method.setting_of`), in registry order."""
    if not names:
        return methods
    unknown = [name for name in names if name not in methods]
    if unknown:
        raise SystemExit(f"--methods: no method {', '.join(map(repr, unknown))}; the registry has "
                         + ", ".join(map(repr, methods)))
    chosen, todo = set(), list(names)
    while todo:
        name = todo.pop()
        if name not in chosen:
            chosen.add(name)
            if methods[name].setting_of is not None:
                todo.append(methods[name].setting_of)
    return {name: method for name, method in methods.items() if name in chosen}


def _evaluate(units, methods, args, loss_rng, **options):
    try:
        client = parallel.connect(args.scheduler) if args.scheduler else None
    except ValueError as exc:
        raise SystemExit(f"--scheduler: {exc}") from None
    try:
        return study.evaluate(units, rng=loss_rng, methods=methods, draws=args.draws, n_jobs=args.jobs,
                              scheduler=client, progress=True, **options)
    finally:
        if client is not None:
            client.close()


def _main_files(args, methods, loss_rng, where) -> int:
    profiles, headline = _profiles(args.loss)
    try:
        units = study.load_recordings(args.files, progress=False)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    sources = list(dict.fromkeys(unit.source for unit in units.values()))
    rates = sorted({unit.fs for unit in units.values()})
    print(f"{len(sources)} recording(s), {len(units)} node(s) with a reference, at "
          f"{', '.join(f'{r:g}' for r in rates)} Hz; profiles: {', '.join(p.name for p in profiles)}; "
          + (f"tuned leave-one-recording-out at {headline}" if len(sources) > 1 else
             "one recording: every method with its default setting (nothing to tune on)")
          + f"; {args.draws} draw(s) per random profile, seed {args.seed}, on {where}")
    print(study.units_health(units))
    start = time.perf_counter()
    result = _evaluate(units, methods, args, loss_rng, profiles=profiles, headline=headline)
    table = result.rmse_table()
    if args.out:
        table.to_csv(args.out, index=False)
    with pd.option_context("display.max_rows", None, "display.max_columns", None, "display.width", 200):
        # The settings are in --out; printed, they would make every line too wide to read.
        print("\n" + table.drop(columns="setting").to_string(index=False, float_format=lambda v: f"{v:.2f}"))
        means = table.pivot_table(index="method", columns="profile", values="rmse_total_deg", aggfunc="mean",
                                  sort=False)[[p.name for p in profiles]]
        print(f"\nMean total RMSE (°) over recordings, nodes and draws ({result.setting_source}):")
        print(means.round(2).to_string())
    print(f"\nTotal time {time.perf_counter() - start:.0f} s (load + evaluate).")
    return 0


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.files and args.trials:
        parser.error("give recording files or --trials (BROAD), not both")
    if args.loss and not args.files:
        parser.error("--loss applies to recording files; the BROAD study runs notebook 10's profiles")
    loss_rng, boot_rng = np.random.default_rng(args.seed).spawn(2)
    budget = 2 if args.quick and args.budget is None else args.budget
    registry = study.default_methods(study.DEFAULT_BUDGET if budget is None else budget)
    methods = _select(registry, args.methods)
    where = (f"Dask cluster {args.scheduler}" if args.scheduler else
             f"{parallel.local_workers(args.jobs)} local job(s){' (one per core)' if args.jobs == -1 else ''}")
    if args.files:
        return _main_files(args, methods, loss_rng, where)

    names = list(args.trials) if args.trials else broad_trials(present_only=True)
    if args.quick:
        names = names[:2]
    if len(names) < 2:
        raise SystemExit("need at least 2 BROAD trials (in $WSNLIB_BROAD_DIR, or --trials) for leave-one-trial-out")
    print(f"{len(names)} BROAD trials, tuned at {study.HEADLINE} (mean burst 3 packets of 6 samples), "
          f"{args.draws} draw(s) per trial and random profile, seed {args.seed}, "
          f"{min((len(m.grid) for m in methods.values() if m.space), default=1)} settings per method, on {where}"
          + (f" (ours also with their design chosen in the fold: × {len(study.KALMAN_DESIGNS)} designs)"
             if any(m.designs for m in methods.values()) else ""))
    start = time.perf_counter()
    recordings = study.load_recordings(names, progress=False)
    print(study.units_health(recordings))
    result = _evaluate(recordings, methods, args, loss_rng)
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
    if args.methods:
        print(f"\nTargets and diagnosis: not computed (they compare against the whole registry; --methods ran "
              f"{len(methods)} of its {len(registry)} methods).")
    else:
        # BROAD: our filter's defaults were chosen on these trials, its design-in-fold entries stand for it.
        targets = summary.targets_table(result.per_trial, rng=boot_rng, exclude=study.DESIGNED_ON_BROAD)
        print(f"\nTargets ({study.HEADLINE}; ratio of means or paired difference, 95 % bootstrap interval):")
        print(summary.format_targets(targets))
    for title, pairs, metrics in (("Does gating the single frame help?", study.GATING_PAIRS,
                                   ("rmse_total", "rms_after_gap")),
                                  ("Does a gap handling help each filter, over holding?", study.GAP_PREDICTION_PAIRS,
                                   ("rmse_total", "rms_lost"))):
        pairs = [pair for pair in pairs if set(pair) <= set(methods)]
        if pairs:
            comparisons = summary.paired_comparisons(result.per_trial, pairs, rng=boot_rng, metrics=metrics)
            print(f"\n{title} (paired difference with − without over trials, 95 % interval):")
            print("\n".join(f"  {line.replace('**', '')}" for line in summary.comparison_sentences(comparisons)))
    if not args.methods:
        best = summary.best_methods(result.per_trial, exclude=study.DESIGNED_ON_BROAD)
        print("\n" + summary.diagnosis_sentence(result.per_trial, best["causal"]))
    print(f"\nTotal time {elapsed:.0f} s (load + evaluate).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
