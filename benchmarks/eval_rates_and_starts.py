"""Does one ``KalmanSettings`` object behave the same at any rate and from any start? (issue 24)

Run from the repository root (BROAD trials in ``$WSNLIB_BROAD_DIR``; ``make`` sets it)::

    .venv/bin/python benchmarks/eval_rates_and_starts.py            # 17 trials, about 1 min
    .venv/bin/python benchmarks/eval_rates_and_starts.py --quick    # 3 trials
    .venv/bin/python benchmarks/eval_rates_and_starts.py --draws 10 # more loss draws for the starts

Every BROAD trial present, the filter with its default settings (:class:`wsnlib.orientation.KalmanSettings`),
BROAD's RMSE on the movement phase (:func:`wsnlib.metrics.broad_rmse_deg`):

1. **Rates**: each trial resampled to 40, 50 and 100 Hz (:func:`wsnlib.io.resample.resample_broad`)
   and at its native 2000/7 Hz; lossless and Gilbert–Elliott 10 % (mean burst 3 packets of 6
   samples, 3 seeded draws).  The loss is the same *in time* at every rate: drawn at 50 Hz, each
   sample takes the 50 Hz sample it falls in (a packet is 0.12 s); with 6-sample packets at every
   rate the gaps would shrink with the rate and the loss, not the filter, would change the error.
   Target: mean RMSE within 1° (lossless) and 2° (GE 10 %) of 50 Hz.
2. **Starts** (50 Hz): the trial started 10 s late (in motion) and the trial with its magnetometer
   scaled by a slow factor ``0.8 + 0.4 cos(2π t / 60 s)`` (1.2 → 0.4 → 1.2 each minute).  Scored:
   the heading RMSE from 10 s on, minus the unperturbed run's on the same samples (what the start
   or the scale costs), lossless and under GE 10 % (``--draws`` seeded masks per trial, 20 by
   default; each draw's perturbed and unperturbed runs share the mask).  Target: at most 5° on
   every trial and every draw; the table shows each trial's mean and worst draw.

Prints the tables and PASS/MISS with the margins.  Always exits 0: a measurement, not a test.
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
from wsnlib.metrics import broad_errors_deg, broad_rmse_deg
from wsnlib.orientation import kalman_orientation

RATES = {"40 Hz": 40.0, "50 Hz": 50.0, "100 Hz": 100.0, "native": None}
LOSS = LossProfile.gilbert_elliott(0.10)
DRAWS = 3
START_DRAWS = 20
CUT_S, SETTLE_S = 10.0, 10.0
RATE_TARGETS_DEG = {"lossless": 1.0, "GE 10 %": 2.0}
START_TARGET_DEG = 5.0


def loss_in_time(n_samples_50: int, n_samples: int, fs: float, rng: np.random.Generator, draws: int) -> np.ndarray:
    """``draws`` GE 10 % masks drawn at 50 Hz, mapped onto ``n_samples`` at ``fs`` by time."""
    masks = LOSS.mask(n_samples_50, 50.0, rng, shape=(draws,))
    index = np.minimum(np.floor(np.arange(n_samples) * 50.0 / fs + 1e-9).astype(int), n_samples_50 - 1)
    return masks[:, index]


def slow_scale(n_samples: int, fs: float) -> np.ndarray:
    """The magnetometer's slow scale factor, 1.2 → 0.4 → 1.2 each minute."""
    return 0.8 + 0.4 * np.cos(2 * np.pi * np.arange(n_samples) / fs / 60.0)


def heading_rms(error: np.ndarray, movement: np.ndarray) -> float:
    ok = movement & np.isfinite(error)
    return float(np.sqrt(np.mean(error[ok] ** 2)))


def rate_table(trials: dict) -> pd.DataFrame:
    rows = []
    for i, (name, by_rate) in enumerate(tqdm(trials.items(), desc="rates")):
        base = by_rate["50 Hz"]
        for label, rec in by_rate.items():
            masks = loss_in_time(base.n_samples, rec.n_samples, rec.fs, np.random.default_rng(1000 + i), DRAWS)
            lossless = kalman_orientation(rec.gyr, rec.acc, rec.mag, fs=rec.fs)
            lossy = kalman_orientation(rec.gyr, rec.acc, rec.mag, fs=rec.fs, received=masks)
            rows.append({"trial": name, "rate": label,
                         "lossless": float(broad_rmse_deg(lossless, rec.quat_ref, rec.movement)["total"]),
                         "GE 10 %": float(np.mean(broad_rmse_deg(lossy, rec.quat_ref, rec.movement)["total"]))})
    return pd.DataFrame(rows)


def start_table(trials: dict, draws: int) -> pd.DataFrame:
    """One row per trial, profile and draw (lossless: one row, draw 0) with the two heading costs (°)."""
    rows = []
    for i, (name, by_rate) in enumerate(tqdm(trials.items(), desc="starts")):
        rec = by_rate["50 Hz"]
        fs, n = rec.fs, rec.n_samples
        cut, settle = int(round(CUT_S * fs)), int(round(SETTLE_S * fs))
        masks = LOSS.mask(n, fs, np.random.default_rng(2000 + i), shape=(draws,))
        scaled_mag = rec.mag * slow_scale(n, fs)[:, None]
        after_cut, after = slice(cut + settle, None), slice(settle, None)
        for profile, received in (("lossless", None), ("GE 10 %", masks)):
            base = broad_errors_deg(kalman_orientation(rec.gyr, rec.acc, rec.mag, fs=fs, received=received),
                                    rec.quat_ref)["heading"]
            late = kalman_orientation(rec.gyr[cut:], rec.acc[cut:], rec.mag[cut:], fs=fs,
                                      received=None if received is None else received[:, cut:])
            late = broad_errors_deg(late, rec.quat_ref[cut:])["heading"]
            scaled = kalman_orientation(rec.gyr, rec.acc, scaled_mag, fs=fs, received=received)
            scaled = broad_errors_deg(scaled, rec.quat_ref)["heading"]
            # Lossless runs are (T,), lossy ones (draws, T): one row per draw.
            runs = zip(np.atleast_2d(base), np.atleast_2d(late), np.atleast_2d(scaled), strict=True)
            for draw, (b, lt, sc) in enumerate(runs):
                rows.append({"trial": name, "profile": profile, "draw": draw,
                             "started late": heading_rms(lt[settle:], rec.movement[after_cut])
                             - heading_rms(b[after_cut], rec.movement[after_cut]),
                             "scaled field": heading_rms(sc[after], rec.movement[after])
                             - heading_rms(b[after], rec.movement[after])})
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 trials")
    parser.add_argument("--draws", type=int, default=START_DRAWS,
                        help=f"GE 10 %% loss draws per trial for the starts (default {START_DRAWS})")
    args = parser.parse_args(argv)
    if args.draws < 1:
        parser.error(f"--draws must be at least 1, got {args.draws}")
    names = broad_trials(present_only=True)[: 3 if args.quick else None]
    if not names:
        print("no BROAD trial in $WSNLIB_BROAD_DIR: nothing measured")
        return 0
    trials = {}
    for name in tqdm(names, desc="load + resample"):
        trial = load_broad(name)
        trials[name] = {label: trial if fs is None else resample_broad(trial, fs) for label, fs in RATES.items()}
    warnings.simplefilter("ignore", UserWarning)  # the scaled field's rejections are the point, not news
    rates = rate_table(trials).groupby("rate", sort=False)[["lossless", "GE 10 %"]].mean()
    print(f"\nMean total RMSE (°) over {len(names)} trials, default KalmanSettings, loss the same in time:")
    print(rates.round(2).to_string())
    for profile, target in RATE_TARGETS_DEG.items():
        worst = float((rates[profile] - rates.loc["50 Hz", profile]).abs().max())
        print(f"  {profile}: largest change from 50 Hz {worst:.2f}° (target ≤ {target:g}°): "
              f"{'PASS' if worst <= target else f'MISS by {worst - target:.2f}°'}")
    starts = start_table(trials, args.draws)
    per_trial = starts.groupby(["trial", "profile"], sort=False)[["started late", "scaled field"]].agg(["mean", "max"])
    print(f"\nHeading RMSE (°) from {SETTLE_S:g} s on, minus the unperturbed run's (50 Hz); "
          f"GE 10 %: mean and worst of {args.draws} draws:")
    print(per_trial.unstack("profile").round(2).to_string())
    for column in ("started late", "scaled field"):
        for profile, group in starts.groupby("profile", sort=False):
            worst = group.loc[group[column].idxmax()]
            over = group[group[column] > START_TARGET_DEG]
            counts = over["trial"].value_counts(sort=False)
            by_trial = f" (trials {', '.join(f'{t[:2]} ×{k}' for t, k in counts.items())})" if len(over) else ""
            where = f"{worst['trial']}" + (f", draw {worst['draw']}" if profile != "lossless" else "")
            margin = worst[column] - START_TARGET_DEG
            verdict = "PASS" if margin <= 0 else f"MISS by {margin:.2f}°"
            print(f"  {column}, {profile}: worst +{worst[column]:.2f}° ({where}), mean {group[column].mean():+.2f}°, "
                  f"{len(over)} of {len(group)} runs over {START_TARGET_DEG:g}°{by_trial} "
                  f"(target ≤ {START_TARGET_DEG:g}° on every trial and draw): {verdict}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
