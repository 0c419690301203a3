"""The live receiver on real recordings: the latency dial and packets that carry their own redundancy (issue 27).

The study behind notebook 11.  Every unit (a BROAD trial at 50 Hz, or a node of a recording file:
:func:`wsnlib.studies.loss_tolerance.load_recordings`) is sent as a node's packets
(:func:`wsnlib.stream.node_stream`: int16 readings, 6 samples per packet) through a
Gilbert–Elliott channel, and received by :class:`wsnlib.stream.Receiver` — simulated packet by
packet by :func:`wsnlib.stream.receiver_output`, the receiver's own compiled code — with the
filter's default settings (:class:`~wsnlib.orientation.KalmanSettings`).  Scored as BROAD scores:
the total error against the optical reference on movement samples with a reference, RMSE per unit
(:func:`wsnlib.metrics.broad_errors_deg`), over all samples, over the received ones and over the
lost ones.

Schemes (:class:`Scheme`): no redundancy; every packet sent twice, the copy one packet slot later
on the same channel (a packet is lost only if both slots are: :func:`wsnlib.stream.packets_sent_twice`;
100 % overhead); and summaries of the previous packets (``K`` entries of ``bits`` bits, layout
consecutive or doubling).  Overhead: the bytes a summary adds to a full packet of 140 bytes
(mean over the recording's packets).

Channel: Gilbert–Elliott at each of :data:`LOSS_RATES`, mean burst :data:`MEAN_BURST_PACKETS`
packets, one chain per unit, loss rate and draw (drawn from children of the ``rng`` passed in,
keyed by the unit's position, so every scheme sees the same slots: a paired comparison).

References on the same masks: the receiver without loss (*lossless*, scored on the samples the
mask receives), the causal receiver without redundancy (latency 0), the offline smoother
without redundancy (:func:`~wsnlib.orientation.smooth_orientation`, curves across gaps), and
paper 001's receiver (Madgwick's filter, output held over gaps, its β chosen leave-one-group-out among
:data:`PAPER001_BETAS`).

Choosing a scheme: the issue's targets ask for *a* scheme within 25 % overhead; the scheme each
unit is scored with is chosen leave-one-group-out (:func:`wsnlib.loto.leave_one_out_choice`,
BROAD's kinds of motion held out together) among the grid's schemes within the limit, by the
target's own metric at the headline loss rate — never on the unit it scores.  Beside it,
:func:`design_redundancy` gives the scheme a designer would pick from the channel model alone.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from wsnlib import loto, metrics, parallel, stats
from wsnlib._validation import check_rng
from wsnlib.loss import burst_lengths, gilbert_elliott, packets_to_samples
from wsnlib.orientation import kalman_orientation, madgwick, smooth_orientation
from wsnlib.stream import Receiver, ReceiverOutput, encode_stream, node_stream, packets_sent_twice, receiver_output
from wsnlib.tuning import pareto_front

#: Gilbert–Elliott loss rates studied, the headline one, the mean burst (packets).
LOSS_RATES = (0.05, 0.10, 0.20)
HEADLINE_RATE = 0.10
MEAN_BURST_PACKETS = 3.0
#: Latencies (s) of the latency curve; the redundancy study's; the issue's "latency ≤ 0.5 s".
CURVE_LATENCIES_S = (0.0, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0)
REDUNDANCY_LATENCIES_S = (0.0, 0.5)
TARGET_LATENCY_S = 0.5
#: Paper 001's receiver: Madgwick's filter holding its output over gaps, with β (rad/s) chosen
#: leave-one-group-out from these eight (the tuning budget of notebook 10's peers; Madgwick's
#: recommended 0.041 among them).
PAPER001_BETAS = np.array([0.01, 0.02, 0.041, 0.07, 0.1, 0.2, 0.4, 0.8])
#: The issue's budget of overhead per packet (share of a 140-byte packet).
OVERHEAD_LIMIT = 0.25
#: The issue's targets: received samples within this × lossless; overall within this × causal.
RECEIVED_FACTOR, OVERALL_FACTOR = 1.5, 0.4


@dataclasses.dataclass(frozen=True)
class Scheme:
    """How a node sends: ``redundancy`` summary entries (0: none) of ``bits`` bits in ``layout``, or
    every packet ``twice``."""

    redundancy: int = 0
    bits: int = 12
    layout: str = "doubling"
    twice: bool = False

    @property
    def name(self) -> str:
        if self.twice:
            return "send twice"
        if self.redundancy == 0:
            return "no redundancy"
        return f"{self.layout} K={self.redundancy}, {self.bits} bits"


NONE, TWICE = Scheme(), Scheme(twice=True)


def scheme_grid(ks: Sequence[int] = (1, 2, 3, 4, 5, 6), bits: Sequence[int] = (8, 10, 12),
                consecutive: Sequence[int] = (2, 4)) -> list[Scheme]:
    """The baselines, then doubling summaries ``K × bits``, then consecutive ones (``consecutive`` K, 12 bits)."""
    return ([NONE, TWICE] + [Scheme(k, b, "doubling") for k in ks for b in bits]
            + [Scheme(k, 12, "consecutive") for k in consecutive])


def lost_share_in_longer_bursts(n_packets: int, mean_burst_packets: float = MEAN_BURST_PACKETS) -> float:
    """Share of the lost packets that sit in bursts longer than ``n_packets`` when bursts are geometric
    with mean ``m`` (Gilbert–Elliott): ``(1 − 1/m)^n (1 + n/m)``."""
    m = float(mean_burst_packets)
    return (1.0 - 1.0 / m) ** n_packets * (1.0 + n_packets / m)


def design_redundancy(mean_burst_packets: float = MEAN_BURST_PACKETS, *, coverage: float = 0.99,
                      step_deg: float = 0.5) -> Scheme:
    """The summary a designer picks from the channel model alone: doubling layout, the smallest ``K``
    whose longest fully bridged burst (``2^(K−1)`` packets) holds ≥ ``coverage`` of the lost packets
    (:func:`lost_share_in_longer_bursts`), and the fewest bits whose step on a rotation component of
    up to π rad is ≤ ``step_deg``."""
    k = 1
    while lost_share_in_longer_bursts(2 ** (k - 1), mean_burst_packets) > 1.0 - coverage:
        k += 1
    bits = 4
    while math.degrees(math.pi / (2 ** (bits - 1) - 1)) > step_deg:
        bits += 1
    return Scheme(k, bits, "doubling")


def _rmse(error: np.ndarray, where: np.ndarray) -> float:
    return float(np.sqrt(np.mean(error[where] ** 2))) if np.any(where) else np.nan


def draw_slots(units: Mapping, *, rng: np.random.Generator, loss_rates=LOSS_RATES, draws: int = 1,
               samples_per_packet: int = 6) -> dict:
    """Channel slots ``slots[(unit, rate, draw)]`` (P + 1,) bool, good = delivered, one Gilbert–Elliott chain
    each (P packets of the unit, one slot more for a copy of the last)."""
    rng = check_rng(rng)
    children = rng.spawn(len(units))
    out = {}
    for child, (name, unit) in zip(children, units.items(), strict=True):
        n_packets = -(-unit.n_samples // samples_per_packet)
        for rate, rate_rng in zip(loss_rates, child.spawn(len(loss_rates)), strict=True):
            chains = gilbert_elliott(n_packets + 1, rate, MEAN_BURST_PACKETS, rng=rate_rng, shape=(draws,))
            for d in range(draws):
                out[(name, rate, d)] = chains[d]
    return out


def _unit_job(name, unit, slots, schemes, latencies_s, curve_schemes, curve_latencies_s, headline, settings):
    """Every scheme on one unit under its slots: result rows, reference rows, latency-curve rows."""
    fs = unit.fs
    valid = unit.movement & unit.reference_valid
    plain = node_stream(unit.gyr, unit.acc, unit.mag, fs=fs)
    spp, n_t = plain.samples_per_packet, plain.n_samples
    full = np.flatnonzero(np.minimum(spp, n_t - np.arange(plain.n_packets) * spp) == spp)
    base_bytes = plain.packet_bytes(int(full[0]))

    def errors(quat):
        return metrics.broad_errors_deg(quat, unit.quat_ref)["total"]

    lossless = errors(receiver_output(plain, np.ones(plain.n_packets, bool), settings=settings)[0])
    lags = [int(round(s * fs)) for s in latencies_s]
    curve_lags = [int(round(s * fs)) for s in curve_latencies_s]
    streams = {}
    rows, references, curve = [], [], []
    for (rate, draw), slot in slots.items():
        packets = slot[:-1]
        mask = packets_to_samples(packets, spp, n_t)
        smoothed = errors(smooth_orientation(plain.gyr, plain.acc, plain.mag, fs=fs, received=mask, settings=settings))
        held = [madgwick(plain.gyr, plain.acc, plain.mag, fs=fs, beta=float(beta), received=mask)
                for beta in PAPER001_BETAS]
        references.append({"trial": name, "loss_rate": rate, "draw": draw,
                           "lossless_total": _rmse(lossless, valid), "lossless_received": _rmse(lossless, valid & mask),
                           "smoother_total": _rmse(smoothed, valid), "lost_share": float(1.0 - packets.mean()),
                           **{f"paper001_beta{i}": _rmse(errors(q), valid) for i, q in enumerate(held)}})
        for scheme in dict.fromkeys(list(schemes) + (list(curve_schemes) if rate == headline else [])):
            key = (scheme.redundancy, scheme.bits, scheme.layout)
            if key not in streams:
                streams[key] = plain if scheme.redundancy == 0 else node_stream(
                    unit.gyr, unit.acc, unit.mag, fs=fs, redundancy=scheme.redundancy, bits=scheme.bits,
                    layout=scheme.layout)
            stream = streams[key]
            got = packets_sent_twice(slot) if scheme.twice else packets
            if not got.any():
                continue
            got_mask = packets_to_samples(got, spp, n_t)
            sizes = [stream.packet_bytes(int(p)) for p in full]
            extra = base_bytes if scheme.twice else float(np.mean(sizes)) - base_bytes
            wanted = (lags if scheme in schemes else []) + (curve_lags if scheme in curve_schemes and rate == headline
                                                            else [])
            quats = receiver_output(stream, got, latencies=sorted(set(wanted)), settings=settings)
            by_lag = dict(zip(sorted(set(wanted)), quats, strict=True))
            if scheme in schemes:
                for latency_s, lag in zip(latencies_s, lags, strict=True):
                    e = errors(by_lag[lag])
                    rows.append({"trial": name, "loss_rate": rate, "draw": draw, "scheme": scheme.name,
                                 "redundancy": scheme.redundancy, "bits": scheme.bits, "layout": scheme.layout,
                                 "twice": scheme.twice, "overhead_bytes": extra, "overhead_share": extra / base_bytes,
                                 "latency_s": latency_s, "rmse_total": _rmse(e, valid),
                                 "rmse_received": _rmse(e, valid & got_mask), "rmse_lost": _rmse(e, valid & ~got_mask),
                                 "lossless_received": _rmse(lossless, valid & got_mask)})
            if scheme in curve_schemes and rate == headline:
                for latency_s, lag in zip(curve_latencies_s, curve_lags, strict=True):
                    curve.append({"trial": name, "draw": draw, "scheme": scheme.name, "latency_s": latency_s,
                                  "rmse_total": _rmse(errors(by_lag[lag]), valid)})
    return rows, references, curve


@dataclasses.dataclass
class StreamingResult:
    """What :func:`evaluate` returns.

    Attributes
    ----------
    per_trial : pandas.DataFrame
        One row per unit × loss rate × draw × scheme × latency: trial, loss_rate, draw, scheme,
        redundancy, bits, layout, twice, overhead_bytes, overhead_share, latency_s, rmse_total,
        rmse_received, rmse_lost (°), lossless_received (° of the lossless receiver on the same
        received samples).
    references : pandas.DataFrame
        Per unit × loss rate × draw: lossless_total, lossless_received, smoother_total, lost_share, and
        ``paper001_beta<i>``: Madgwick's filter holding its output over gaps (paper 001's receiver)
        with the i-th β of :data:`PAPER001_BETAS` (°).
    curve : pandas.DataFrame
        The latency curve at the headline rate: trial, draw, scheme, latency_s, rmse_total.
    slots : dict
        The channel slots (:func:`draw_slots`).
    groups : dict
        Unit → group held out together.
    schemes : list of Scheme
    headline : float
        The loss rate of the latency curve and of the targets.
    """

    per_trial: pd.DataFrame
    references: pd.DataFrame
    curve: pd.DataFrame
    slots: dict
    groups: dict
    schemes: list
    headline: float


def evaluate(units: Mapping, *, rng: np.random.Generator, groups: Mapping, schemes=None, loss_rates=LOSS_RATES,
             latencies_s=REDUNDANCY_LATENCIES_S, curve_schemes=None, curve_latencies_s=CURVE_LATENCIES_S,
             draws: int = 1, headline: float = HEADLINE_RATE, settings=None, n_jobs: int = -1,
             progress: bool = True) -> StreamingResult:
    """Run every scheme on every unit under every loss rate (module docstring).

    ``schemes`` default :func:`scheme_grid` plus :func:`design_redundancy`; ``curve_schemes`` (the
    latency curve at ``headline``): no redundancy and the designed scheme.  One job per unit
    (:func:`wsnlib.parallel.run_jobs`, ``n_jobs`` processes).
    """
    designed = design_redundancy()
    schemes = list(dict.fromkeys(scheme_grid() + [designed] if schemes is None else schemes))
    curve_schemes = [NONE, designed] if curve_schemes is None else list(curve_schemes)
    if headline not in loss_rates:
        raise ValueError(f"headline {headline!r} must be one of loss_rates {tuple(loss_rates)}")
    slots = draw_slots(units, rng=rng, loss_rates=loss_rates, draws=draws)
    jobs = [(name, unit, {(r, d): slots[(name, r, d)] for r in loss_rates for d in range(draws)}, schemes,
             tuple(latencies_s), curve_schemes, tuple(curve_latencies_s), headline, settings)
            for name, unit in units.items()]
    results = parallel.run_jobs(_unit_job, jobs, n_jobs=n_jobs, in_process_first=1, progress=progress,
                                desc="units")
    frames = [pd.DataFrame([row for result in results for row in result[i]]) for i in range(3)]
    return StreamingResult(per_trial=frames[0], references=frames[1], curve=frames[2], slots=slots,
                           groups=dict(groups), schemes=schemes, headline=headline)


# ------------------------------------------------------------------------------------------
# Reading the results
# ------------------------------------------------------------------------------------------


def _matrix(table: pd.DataFrame, column: str, trials: list[str]) -> np.ndarray:
    """``(n_trials, n_draws)`` of ``column`` from rows with trial and draw."""
    wide = table.pivot_table(index="trial", columns="draw", values=column, aggfunc="first")
    return wide.loc[trials].to_numpy(dtype=float)


def _labels(result: StreamingResult, trials) -> np.ndarray:
    return np.array([result.groups[t] for t in trials])


def scheme_means(result: StreamingResult, *, rng: np.random.Generator, n_boot: int = 2000) -> pd.DataFrame:
    """Per loss rate, scheme and latency: overhead (bytes, share) and the mean over units of the RMSE
    (total, on received, on lost samples) with 95 % intervals (:func:`wsnlib.stats.grouped_bootstrap_ci`)."""
    out = []
    trials = sorted(result.per_trial["trial"].unique())
    labels = _labels(result, trials)
    for (rate, scheme, latency), rows in result.per_trial.groupby(["loss_rate", "scheme", "latency_s"], sort=False):
        row = {"loss_rate": rate, "scheme": scheme, "latency_s": latency,
               "overhead_bytes": float(rows["overhead_bytes"].mean()),
               "overhead_share": float(rows["overhead_share"].mean())}
        for metric in ("rmse_total", "rmse_received", "rmse_lost"):
            values = _matrix(rows, metric, trials)
            if np.isfinite(values).all():
                ci = stats.grouped_bootstrap_ci(values, labels, rng=rng, n_boot=n_boot)
                row |= {metric: float(ci.estimate), f"{metric}_low": float(ci.low), f"{metric}_high": float(ci.high)}
            else:
                row |= {metric: float(np.nanmean(values)), f"{metric}_low": np.nan, f"{metric}_high": np.nan}
        out.append(row)
    return pd.DataFrame(out)


def curve_means(result: StreamingResult, *, rng: np.random.Generator, n_boot: int = 2000) -> pd.DataFrame:
    """The latency curve: per scheme and latency the mean RMSE over units with its interval, plus the
    offline smoother (``latency_s`` inf) and the lossless receiver at the headline rate."""
    trials = sorted(result.curve["trial"].unique())
    labels = _labels(result, trials)
    rows = []
    for (scheme, latency), part in result.curve.groupby(["scheme", "latency_s"], sort=False):
        ci = stats.grouped_bootstrap_ci(_matrix(part, "rmse_total", trials), labels, rng=rng, n_boot=n_boot)
        rows.append({"scheme": scheme, "latency_s": latency, "rmse_total": float(ci.estimate),
                     "low": float(ci.low), "high": float(ci.high)})
    headline = result.references[result.references["loss_rate"] == result.headline]
    for name, column in (("offline smoother (no redundancy)", "smoother_total"), ("lossless", "lossless_total")):
        ci = stats.grouped_bootstrap_ci(_matrix(headline, column, trials), labels, rng=rng, n_boot=n_boot)
        rows.append({"scheme": name, "latency_s": np.inf, "rmse_total": float(ci.estimate), "low": float(ci.low),
                     "high": float(ci.high)})
    return pd.DataFrame(rows)


def pareto_table(means: pd.DataFrame) -> pd.DataFrame:
    """``means`` with a column ``pareto``: on the front of (overhead bytes, total RMSE) within each loss
    rate and latency (the baselines included)."""
    out = means.copy()
    out["pareto"] = False
    for _, rows in out.groupby(["loss_rate", "latency_s"]):
        out.loc[rows.index, "pareto"] = pareto_front(rows["overhead_bytes"].to_numpy(), rows["rmse_total"].to_numpy())
    return out


def burst_coverage(result: StreamingResult, spans=(1, 2, 4, 8, 16, 32)) -> pd.DataFrame:
    """Per loss rate, the share of the lost packets in bursts of at most ``n`` packets (bridged whole by
    ``K = log2(n) + 1`` doubling entries, or by ``n`` consecutive ones), in the drawn slots and in the
    channel model, and the mean and longest burst."""
    rows = []
    for rate in sorted({key[1] for key in result.slots}):
        lengths = np.concatenate([burst_lengths(slot[:-1]) for key, slot in result.slots.items()
                                  if key[1] == rate])
        total = max(int(lengths.sum()), 1)
        row = {"loss_rate": rate, "bursts": int(lengths.size), "mean_burst_packets": float(lengths.mean()),
               "longest_burst_packets": int(lengths.max()) if lengths.size else 0}
        for n in spans:
            row[f"<= {n}"] = float(lengths[lengths <= n].sum() / total)
            row[f"<= {n} (model)"] = 1.0 - lost_share_in_longer_bursts(n)
        rows.append(row)
    return pd.DataFrame(rows)


def chosen_schemes(result: StreamingResult, *, metric: str, latency_s: float, loss_rate: float = HEADLINE_RATE,
                   limit: float = OVERHEAD_LIMIT) -> pd.Series:
    """Per unit, the redundancy scheme within ``limit`` overhead with the lowest mean ``metric`` at
    ``loss_rate`` and ``latency_s`` over the units of the other groups (leave-one-group-out)."""
    rows = result.per_trial[(result.per_trial["loss_rate"] == loss_rate) & (result.per_trial["latency_s"] == latency_s)
                            & ~result.per_trial["twice"] & (result.per_trial["redundancy"] > 0)
                            & (result.per_trial["overhead_share"] <= limit)]
    wide = rows.groupby(["scheme", "trial"])[metric].mean().unstack("trial")
    trials = list(wide.columns)
    choice = loto.leave_one_out_choice(wide.to_numpy(), groups=_labels(result, trials))
    return pd.Series([wide.index[c] for c in choice], index=pd.Index(trials, name="trial"), name="scheme")


def _scored(result, chosen: pd.Series, metric: str, latency_s: float, loss_rate: float) -> pd.DataFrame:
    rows = result.per_trial[(result.per_trial["loss_rate"] == loss_rate) & (result.per_trial["latency_s"] == latency_s)]
    picked = rows[rows["scheme"] == rows["trial"].map(chosen)]
    return picked[["trial", "draw", metric, "overhead_share"]]


def targets(result: StreamingResult, *, rng: np.random.Generator, n_boot: int = 2000) -> pd.DataFrame:
    """The issue's targets at the headline loss rate as rows: target, value, ci_low, ci_high, threshold, met (bool)
    and a sentence generated from the numbers; each redundancy scheme chosen leave-one-group-out
    (:func:`chosen_schemes`) among those within :data:`OVERHEAD_LIMIT`."""
    loss_rate = result.headline
    trials = sorted(result.per_trial["trial"].unique())
    labels = _labels(result, trials)
    per = result.per_trial
    refs = result.references[result.references["loss_rate"] == loss_rate]
    causal_none = per[(per["loss_rate"] == loss_rate) & (per["scheme"] == NONE.name) & (per["latency_s"] == 0.0)]
    out = []

    def ratio(a_rows, a_col, b_rows, b_col):
        return stats.grouped_ratio_ci(_matrix(a_rows, a_col, trials), _matrix(b_rows, b_col, trials), labels, rng=rng,
                                      n_boot=n_boot)

    received_choice = chosen_schemes(result, metric="rmse_received", latency_s=0.0, loss_rate=loss_rate)
    picked = _scored(result, received_choice, "rmse_received", 0.0, loss_rate)
    lossless = per[(per["loss_rate"] == loss_rate) & (per["latency_s"] == 0.0)]
    lossless = lossless[lossless["scheme"] == lossless["trial"].map(received_choice)][["trial", "draw",
                                                                                        "lossless_received"]]
    ci = ratio(picked, "rmse_received", lossless, "lossless_received")
    out.append(_target_row(
        f"GE {loss_rate:.0%}, redundancy ≤ {OVERHEAD_LIMIT:.0%} overhead: causal error on received samples ≤ "
        f"{RECEIVED_FACTOR:g} × lossless", ci, RECEIVED_FACTOR, picked, received_choice, "× the lossless receiver's"))
    overall_choice = chosen_schemes(result, metric="rmse_total", latency_s=TARGET_LATENCY_S, loss_rate=loss_rate)
    picked = _scored(result, overall_choice, "rmse_total", TARGET_LATENCY_S, loss_rate)
    ci = ratio(picked, "rmse_total", causal_none, "rmse_total")
    out.append(_target_row(
        f"… and latency {TARGET_LATENCY_S:g} s: overall error ≤ {OVERALL_FACTOR:g} × the causal filter without "
        f"redundancy", ci, OVERALL_FACTOR, picked, overall_choice, "× the causal receiver without redundancy's"))
    ci = ratio(picked, "rmse_total", refs, "smoother_total")
    out.append(_target_row("… and below the offline smoother without redundancy", ci, 1.0, picked, overall_choice,
                           "× the offline smoother's", strict=True))
    return pd.DataFrame(out)


def _target_row(target, ci, threshold, picked, choice, what, strict=False) -> dict:
    value, low, high = float(ci.estimate), float(ci.low), float(ci.high)
    met = value < threshold if strict else value <= threshold
    counts = choice.value_counts()
    schemes = ", ".join(f"{name} ({n})" for name, n in counts.items())
    overhead = float(picked["overhead_share"].max())
    verdict = "PASS" if met else f"MISS by {value - threshold:.2f}"
    sentence = (f"{verdict}: {value:.2f} {what} [{low:.2f}, {high:.2f}] (threshold {threshold:g}; schemes chosen "
                f"leave-one-group-out: {schemes}; overhead at most {overhead:.0%}).")
    return {"target": target, "value": value, "ci_low": low, "ci_high": high, "threshold": threshold, "met": met,
            "sentence": sentence}


def paper_vs_ours(result: StreamingResult, scheme: Scheme, *, rng: np.random.Generator,
                  n_boot: int = 2000) -> pd.DataFrame:
    """At the headline rate, the mean total RMSE (°) with its interval of: paper 001's receiver, ours
    causal without redundancy, with ``scheme`` causal and with a latency of :data:`TARGET_LATENCY_S`,
    the offline smoother and the lossless receiver."""
    rate = result.headline
    trials = sorted(result.per_trial["trial"].unique())
    labels = _labels(result, trials)
    refs = result.references[result.references["loss_rate"] == rate]
    per = result.per_trial[result.per_trial["loss_rate"] == rate]
    betas = [c for c in refs.columns if c.startswith("paper001_beta")]
    scores = np.array([[refs[refs["trial"] == t][c].mean() for t in trials] for c in betas])
    choice = loto.leave_one_out_choice(scores, groups=labels)
    held = refs.copy()
    held["paper001"] = [row[betas[choice[trials.index(row["trial"])]]] for _, row in refs.iterrows()]
    rows = {"paper 001's receiver (Madgwick, output held over gaps; β leave-one-group-out)": (held, "paper001"),
            "ours, causal (latency 0), no redundancy": (per[(per["scheme"] == NONE.name) & (per["latency_s"] == 0.0)],
                                                        "rmse_total"),
            f"ours, causal, {scheme.name}": (per[(per["scheme"] == scheme.name) & (per["latency_s"] == 0.0)],
                                             "rmse_total"),
            f"ours, latency {TARGET_LATENCY_S:g} s, {scheme.name}": (
                per[(per["scheme"] == scheme.name) & (per["latency_s"] == TARGET_LATENCY_S)], "rmse_total"),
            "offline smoother, no redundancy": (refs, "smoother_total"),
            "lossless": (refs, "lossless_total")}
    out = []
    for name, (table, column) in rows.items():
        ci = stats.grouped_bootstrap_ci(_matrix(table, column, trials), labels, rng=rng, n_boot=n_boot)
        out.append({"receiver": name, "rmse_total_deg": float(ci.estimate), "ci_low": float(ci.low),
                    "ci_high": float(ci.high)})
    return pd.DataFrame(out).set_index("receiver")


def online_equals_batch(unit, *, rng: np.random.Generator, loss_rate: float = HEADLINE_RATE, reorder: int = 3,
                        duplicate_share: float = 0.05, corrupt_share: float = 0.05) -> dict:
    """The receiver against the batch filter on one unit, through a disorderly network.

    The unit's packets under a Gilbert–Elliott draw are shuffled so that none is overtaken by one
    ``reorder`` or more sequence numbers ahead, a ``duplicate_share`` of them sent again shortly
    after, and damaged copies (a flipped bit, a cut, a trailing byte) of ``corrupt_share`` added;
    the receiver (latency 0, no redundancy) must output exactly
    :func:`~wsnlib.orientation.kalman_orientation` on the dequantised samples with the same loss
    mask, and count every duplicate and damaged datagram.  Returns the largest absolute difference
    of the quaternions, the datagrams sent, duplicated and damaged, the receiver's counters and its
    rejections by reason.
    """
    rng = check_rng(rng)
    stream = node_stream(unit.gyr, unit.acc, unit.mag, fs=unit.fs)
    packets = gilbert_elliott(stream.n_packets, loss_rate, MEAN_BURST_PACKETS, rng=rng)
    packets[0] = True  # the first packet to arrive starts the stream
    sent = np.flatnonzero(packets)
    datagrams = encode_stream(stream, packets=sent)
    keys = sent + rng.uniform(0.0, reorder, sent.size)
    keys[0] = -1.0
    order = [datagrams[i] for i in np.argsort(keys, kind="stable")]
    n_dup, n_bad = int(round(duplicate_share * len(order))), int(round(corrupt_share * len(order)))
    for _ in range(n_dup):
        i = int(rng.integers(len(order)))
        order.insert(min(len(order), i + 1 + int(rng.integers(0, 20))), order[i])
    for _ in range(n_bad):
        i = int(rng.integers(1, len(order)))
        data = bytearray(order[i])
        kind = int(rng.integers(3))
        if kind == 0:
            bit = int(rng.integers(8 * len(data)))
            data[bit // 8] ^= 1 << (bit % 8)
        elif kind == 1:
            data = data[: int(rng.integers(0, len(data)))]
        else:
            data += b"\x00"
        order.insert(i + 1, bytes(data))
    receiver = Receiver(unit.fs, reorder=reorder)
    out = ReceiverOutput.concatenate([receiver.receive(order), receiver.flush()])
    mask = packets_to_samples(packets, stream.samples_per_packet, stream.n_samples)
    batch = kalman_orientation(stream.gyr, stream.acc, stream.mag, fs=unit.fs, received=mask)
    last = int(np.flatnonzero(mask)[-1])
    complete = bool(np.array_equal(out.sample, np.arange(last + 1)) and np.array_equal(out.received, mask[: last + 1]))
    return {"max_abs_difference": float(np.abs(out.quat - batch[out.sample]).max()), "complete": complete,
            "datagrams": len(order), "packets_sent": int(sent.size), "duplicated": n_dup, "damaged": n_bad,
            "counters": receiver.counters.iloc[0].to_dict(), "rejected": receiver.rejected}


# ------------------------------------------------------------------------------------------
# Tables and sentences for the notebook (generated from the numbers)
# ------------------------------------------------------------------------------------------


def packet_layout_table(schemes, samples_per_packet: int = 6) -> pd.DataFrame:
    """Bytes of a full packet with magnetometer per scheme: header, samples, summary block, CRC, total,
    overhead (bytes and share of the packet without summary; sending twice doubles it)."""
    from wsnlib.stream import Summary
    from wsnlib.stream.packet import HEADER_SIZE

    samples = 2 * 9 * samples_per_packet
    base = HEADER_SIZE + samples + 2
    rows = []
    for scheme in schemes:
        block = 0
        if scheme.redundancy:
            block = Summary.quantise(np.zeros((scheme.redundancy, 3)), bits=scheme.bits, layout=scheme.layout).size
        total = base + block
        overhead = base if scheme.twice else block
        rows.append({"scheme": scheme.name, "header": HEADER_SIZE, "samples": samples, "summary": block, "crc": 2,
                     "bytes per packet": total, "overhead bytes": overhead, "overhead": f"{overhead / base:.0%}"})
    return pd.DataFrame(rows).set_index("scheme")


def latency_sentence(curve: pd.DataFrame, designed: Scheme) -> str:
    """What the latency curve shows, from its numbers."""
    def at(scheme, latency):
        row = curve[(curve["scheme"] == scheme) & (curve["latency_s"] == latency)]
        return float(row["rmse_total"].iloc[0])

    smoother = float(curve[curve["scheme"].str.startswith("offline smoother")]["rmse_total"].iloc[0])
    lossless = float(curve[curve["scheme"] == "lossless"]["rmse_total"].iloc[0])
    longest = float(curve[np.isfinite(curve["latency_s"])]["latency_s"].max())
    causal, half, end = at(NONE.name, 0.0), at(NONE.name, TARGET_LATENCY_S), at(NONE.name, longest)
    d0, dh, de = at(designed.name, 0.0), at(designed.name, TARGET_LATENCY_S), at(designed.name, longest)
    below = [lat for lat in sorted(curve[curve["scheme"] == designed.name]["latency_s"])
             if at(designed.name, lat) < smoother]
    ending = (f"; it is below the offline smoother from a latency of {below[0]:g} s on." if below
              else "; it never gets below the offline smoother here.")
    return (f"Without redundancy the causal receiver's error is {causal:.1f}°; waiting {TARGET_LATENCY_S:g} s brings "
            f"it to {half:.1f}° and {longest:g} s to {end:.1f}°, against {smoother:.1f}° for the offline smoother "
            f"(which waits for the whole recording) and {lossless:.1f}° without loss. With {designed.name} the same "
            f"dial reads {d0:.1f}°, {dh:.1f}° and {de:.1f}°" + ending)


def coverage_sentence(coverage: pd.DataFrame, designed: Scheme, headline: float = HEADLINE_RATE) -> str:
    """How much of the loss bursts a summary of ``designed`` bridges whole, drawn and in the model."""
    row = coverage[coverage["loss_rate"] == headline].iloc[0]
    span = 2 ** (designed.redundancy - 1)
    drawn, model = row.get(f"<= {span}", np.nan), 1.0 - lost_share_in_longer_bursts(span)
    within3 = row.get("<= 2", np.nan), row.get("<= 4", np.nan)
    return (f"At GE {headline:.0%} the drawn bursts average {row['mean_burst_packets']:.1f} packets (longest "
            f"{row['longest_burst_packets']:.0f}); only {within3[0]:.0%} of the lost packets sit in bursts of at most "
            f"2 packets and {within3[1]:.0%} in bursts of at most 4, so a summary of the last 3 packets leaves most "
            f"lost packets to prediction. {designed.name} bridges bursts of up to {span} packets whole: "
            f"{drawn:.1%} of the lost packets drawn here ({model:.1%} in the channel model, which chose it).")


def tradeoff_sentence(table: pd.DataFrame, loss_rate: float, latency_s: float, limit: float = OVERHEAD_LIMIT) -> str:
    """The cheapest scheme on the Pareto front within ``limit`` overhead that beats sending twice, at one
    loss rate and latency."""
    rows = table[(table["loss_rate"] == loss_rate) & (table["latency_s"] == latency_s)]
    twice = float(rows[rows["scheme"] == TWICE.name]["rmse_total"].iloc[0])
    none = float(rows[rows["scheme"] == NONE.name]["rmse_total"].iloc[0])
    front = rows[rows["pareto"] & (rows["overhead_share"] <= limit)].sort_values("overhead_bytes")
    better = front[front["rmse_total"] < twice]
    best = rows[rows["overhead_share"] <= limit].sort_values("rmse_total").iloc[0]
    if len(better):
        cheapest = better.iloc[0]
        first = (f"the cheapest summary that beats sending every packet twice ({twice:.1f}°, 140 bytes) is "
                 f"{cheapest['scheme']} ({cheapest['rmse_total']:.1f}° for {cheapest['overhead_bytes']:.0f} bytes)")
    else:
        first = f"no summary within {limit:.0%} beats sending twice ({twice:.1f}°)"
    return (f"At GE {loss_rate:.0%} and latency {latency_s:g} s (no redundancy: {none:.1f}°), {first}; the best "
            f"within {limit:.0%} overhead is {best['scheme']} ({best['rmse_total']:.1f}°, "
            f"{best['overhead_bytes']:.0f} bytes).")
