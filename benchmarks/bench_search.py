"""Run time of the exhaustive search behind paper 002's Tables 2 and 3 (:mod:`wsnlib.optimize`).

Run from the repository root::

    .venv/bin/python benchmarks/bench_search.py            # full sizes (about 30 s)
    .venv/bin/python benchmarks/bench_search.py --quick    # small sizes, a few seconds

Times (best of 2) :func:`wsnlib.optimize.paper_tables` — both approaches, both targets (target 1, then
target 2 twice: with the per-movement and the global elbow of target 1), all users, the
paper's grid (6,350 kNN + 635 p-kNN settings), estimator fits included — against a naive
loop that fits one estimator per setting: ``sklearn.neighbors.KNeighborsRegressor`` with the
Shepard weight callable on the radio map (kNN) and ``ProbabilisticKNN(anchors=…)`` (p-kNN),
followed by :func:`wsnlib.posture.recursive_chain` per movement and the PE.  The naive loop
runs over a random sample of settings (each timed as its best of 3, BLAS/OpenMP pools
limited to one thread, its fastest setting on this problem size) and is extrapolated to the
full search.  Prints both,
the ratio, the agreement of the two on the sampled settings, and PASS/MISS for the target
(full search under 10 s).  Always exits 0: this is a measurement, not a test.

Data: random, shaped like the paper's experiment (Section 4.1): 5 users × 2 targets,
7 anchors, 5 fingerprint positions (Table 1) with ~900 training vectors each, 8 movements
of 2–4 s at 30 Hz between fingerprint positions (60–120 online vectors each).  RSS =
per-(position, anchor) means (uniform in −90…−50 dBm) interpolated along the movement, plus
Gaussian noise, rounded to 1 dBm.  Timing does not depend on the values.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

N_USERS = 5
N_ANCHORS = 7
RATE_HZ = 30.0
TARGET_SECONDS = 10.0
#: (from, to) fingerprint positions (Table 1 indices: P1 … P5 = 0 … 4) of the four movements
#: of Section 4.1, via a middle position where the paper has one; repeated twice (1–4, 5–8).
MOVEMENTS = ((1, 2, 0), (3, 2, 4), (0, 2), (2, 3))
TABLE1_DIRECTIONS = np.array([[0, 0, -1], [0, 0, 1], [0, 1, 0], [1, 0, 0], [-11, 11, 0]], dtype=float)

FULL = {"n_train": 900, "n_users": N_USERS, "naive_knn": 200, "naive_pknn": 40}
QUICK = {"n_train": 200, "n_users": 2, "naive_knn": 30, "naive_pknn": 6}


def machine_info() -> dict:
    import sklearn

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count()
    return {"cpu_count": os.cpu_count(), "usable_cpus": usable,
            "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
            "python": platform.python_version(), "numpy": np.__version__, "sklearn": sklearn.__version__}  # fmt: skip


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _movement_directions(path, n, rng):
    """Unit arm directions along a path of Table 1 postures, (n, 3), by normalised interpolation."""
    knots = _unit(TABLE1_DIRECTIONS[list(path)])
    s = np.linspace(0.0, len(path) - 1.0, n)
    i = np.minimum(s.astype(int), len(path) - 2)
    t = (s - i)[:, None]
    direction = (1 - t) * knots[i] + t * knots[i + 1] + rng.normal(0, 1e-3, (n, 3))  # slight wobble
    return _unit(direction), i, t


def make_users(n_users: int, n_train: int, rng: np.random.Generator):
    """``(target1, target2)``: lists of :class:`wsnlib.optimize.SearchData`, one per user."""
    from wsnlib.optimize import SearchData
    from wsnlib.posture import PAPER_ARM_CHAIN as chain

    target1, target2 = [], []
    for _ in range(n_users):
        dirs, moves, idx_a, idx_b, frac = [], [], [], [], []
        for repetition in range(2):
            for j, path in enumerate(MOVEMENTS):
                n = int(rng.integers(60, 121))                       # 2–4 s at 30 Hz
                d, i, t = _movement_directions(path, n, rng)
                dirs.append(d)
                moves.append(np.full(n, 4 * repetition + j + 1))
                idx_a.append(np.asarray(path)[i])
                idx_b.append(np.asarray(path)[i + 1])
                frac.append(t)
        direction = np.concatenate(dirs)
        movement = np.concatenate(moves)
        a, b, t = np.concatenate(idx_a), np.concatenate(idx_b), np.concatenate(frac)
        pitch = np.clip(np.arcsin(direction[:, 2]) + rng.normal(0, 0.02, direction.shape[0]), -np.pi / 2, np.pi / 2)
        elbow = chain.segment_lengths_m[0] * direction
        fp_dirs = _unit(TABLE1_DIRECTIONS)
        for seg, out in ((0, target1), (1, target2)):
            offset = chain.device_offsets_m[seg]
            fp = fp_dirs * offset if seg == 0 else fp_dirs * (chain.segment_lengths_m[0] + offset)
            truth = offset * direction if seg == 0 else elbow + offset * direction
            means = rng.uniform(-90, -50, (5, N_ANCHORS))
            train = np.round(np.repeat(means, n_train, axis=0) + rng.normal(0, 3, (5 * n_train, N_ANCHORS)))
            online = np.round((1 - t) * means[a] + t * means[b] + rng.normal(0, 3, (direction.shape[0], N_ANCHORS)))
            out.append(SearchData(online_rss=online, movement=movement, true_positions=truth, pitch=pitch,
                                  chain=chain, segment=seg, training_rss=train,
                                  training_positions=np.repeat(fp, n_train, axis=0)))
    return target1, target2


def time_search(target1, target2, repeats: int = 2) -> tuple[float, object]:
    """Best seconds of ``repeats`` :func:`paper_tables` calls (fits included) and the result."""
    from wsnlib.optimize import paper_tables

    best, tables = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        tables = paper_tables(target1, target2)
        best = min(best, time.perf_counter() - start)
    return best, tables


def _hybrid_pe_cm(radio, data):
    """The naive path: recursive_chain per movement, then mean PE per movement (cm)."""
    from wsnlib.posture import ArmChain, recursive_chain

    chain = ArmChain((data.segment_length_m,), (data.device_offset_m,))
    out = {}
    for m in np.unique(data.movement):
        rows = data.movement == m
        devices = recursive_chain(radio[rows][:, None], data.pitch[rows][:, None], chain,
                                  origin=data.proximal[rows])["devices"][:, 0]
        out[int(m)] = 100 * np.linalg.norm(devices - data.true_positions[rows], axis=-1).mean()
    return out


def naive_knn(data, setting, radio_map, positions):
    """One ``KNeighborsRegressor`` fit + predict with Shepard weights (eq. (2)), then eqs. (8)–(11)."""
    from sklearn.neighbors import KNeighborsRegressor

    mask = setting.mask(data.n_anchors)
    power = 1.0 if setting.p_s is None else float(setting.p_s)
    reg = KNeighborsRegressor(n_neighbors=setting.k, metric=setting.metric, algorithm="brute",
                              weights=lambda d: 1.0 / (d**power + 1e-4))
    radio = reg.fit(radio_map[:, mask], positions).predict(data.online_rss[:, mask])
    return _hybrid_pe_cm(radio, data)


def naive_pknn(data, setting):
    """One ``ProbabilisticKNN(anchors=…)`` fit + predict, then eqs. (8)–(11)."""
    from wsnlib.radio import ProbabilisticKNN

    est = ProbabilisticKNN(n_neighbors=setting.k, anchors=setting.mask(data.n_anchors))
    radio = est.fit(data.training_rss, data.training_positions).predict(data.online_rss)
    return _hybrid_pe_cm(radio, data)


def time_naive(target1, results, n_knn: int, n_pknn: int, rng, repeats: int = 3) -> dict:
    """Seconds per setting (mean of each setting's best of ``repeats``) of the naive loops on
    target 1, and the largest PE difference (cm) from the search."""
    from threadpoolctl import threadpool_limits  # installed with scikit-learn

    from wsnlib.optimize import Setting
    from wsnlib.radio import KNNFingerprint

    fitted = [u.fitted() for u in target1]
    maps = [KNNFingerprint().fit(u.training_rss, u.training_positions) for u in target1]
    out = {}
    for approach, n_sample in (("deterministic", n_knn), ("probabilistic", n_pknn)):
        part = results[results["approach"] == approach]
        configs = part["config"].unique()
        picks = rng.choice(configs, size=min(n_sample, configs.size), replace=False)
        users = rng.integers(0, len(target1), size=picks.size)
        rows = part.drop_duplicates("config").set_index("config").loc[picks]
        settings = [Setting.from_row(r | {"approach": approach}) for r in rows.reset_index().to_dict("records")]
        got, total = [], 0.0
        # one thread: on a 5-row radio map sklearn's threaded kernel only adds overhead, and
        # under other load its spin-waits made the per-setting time swing 1.5-30 ms
        with threadpool_limits(limits=1):
            for setting, u in zip(settings, users, strict=True):
                best = np.inf
                for _ in range(repeats):
                    start = time.perf_counter()
                    if approach == "deterministic":
                        pe = naive_knn(fitted[u], setting, maps[u].radio_map_, maps[u].positions_)
                    else:
                        pe = naive_pknn(fitted[u], setting)
                    best = min(best, time.perf_counter() - start)
                got.append(pe)
                total += best
        seconds = total / picks.size
        labels = results["user"].unique()
        diff, n_tied = 0.0, 0
        for pe, config, u, setting in zip(got, picks, users, settings, strict=True):
            ref = part[(part["config"] == config) & (part["user"] == labels[u])].set_index("movement")["pe_cm"]
            d = max(abs(ref[m] - v) for m, v in pe.items())
            if d > 1e-9 and approach == "deterministic" and _boundary_tie(fitted[u], setting):
                n_tied += 1  # sklearn breaks distance ties differently; wsnlib: lower fingerprint index
                continue
            diff = max(diff, d)
        out[approach] = {"seconds_per_setting": seconds, "n_sampled": int(picks.size), "max_abs_diff_cm": diff,
                         "n_tied": n_tied}
    return out


def _boundary_tie(data, setting) -> bool:
    """Whether some online vector has equal k-th and (k+1)-th neighbour distances under ``setting``."""
    from wsnlib.radio import KNNFingerprint

    n_fp = data.knn.positions_.shape[0]
    if setting.k >= n_fp:
        return False
    est = KNNFingerprint(n_neighbors=setting.k + 1, metric=setting.metric, anchors=setting.mask(data.n_anchors))
    dist, _ = est.fit(data.training_rss, data.training_positions).kneighbors(data.online_rss)
    return bool(np.any(np.abs(dist[:, setting.k - 1] - dist[:, setting.k]) < 1e-9))


def run(quick: bool = False, seed: int = 20240602, log=print) -> dict:
    """Measure everything; returns a dict of results (seconds, ratio, target flag)."""
    from wsnlib.optimize import SearchGrid

    sizes = QUICK if quick else FULL
    rng = np.random.default_rng(seed)
    log(f"simulating {sizes['n_users']} users x 2 targets, {sizes['n_train']} training vectors per position ...")
    target1, target2 = make_users(sizes["n_users"], sizes["n_train"], rng)
    n_online = [u.online_rss.shape[0] for u in target1]
    log("full search (paper_tables: both approaches, both targets) ...")
    seconds, tables = time_search(target1, target2, repeats=1 if quick else 2)
    log(f"  {seconds:.2f} s")
    grid = SearchGrid()
    n_settings = {a: grid.n_settings(N_ANCHORS, a) for a in ("deterministic", "probabilistic")}
    # settings evaluated by the full search: per user, target 1 once and target 2 under two elbows
    n_evaluations = {a: n * len(target1) * 3 for a, n in n_settings.items()}
    log(f"naive loops over {sizes['naive_knn']} kNN + {sizes['naive_pknn']} p-kNN sampled settings ...")
    naive = time_naive(target1, tables.target1, sizes["naive_knn"], sizes["naive_pknn"], rng)
    naive_total = sum(naive[a]["seconds_per_setting"] * n_evaluations[a] for a in n_evaluations)
    return {
        "machine": machine_info(), "quick": quick, "n_users": len(target1), "n_online": n_online,
        "n_train": sizes["n_train"], "n_settings": n_settings, "n_evaluations": n_evaluations,
        "search_seconds": seconds, "naive": naive, "naive_seconds": naive_total,
        "ratio": naive_total / seconds, "table3": tables.table3,
        "targets": {f"full search under {TARGET_SECONDS:.0f} s": seconds < TARGET_SECONDS},
    }  # fmt: skip


def report(results: dict) -> str:
    m = results["machine"]
    naive = results["naive"]
    ev = results["n_evaluations"]
    lines = [
        "",
        f"machine: {m['machine']}, {m['cpu_count']} CPUs ({m['usable_cpus']} usable), Python {m['python']}, "
        f"numpy {m['numpy']}, scikit-learn {m['sklearn']}",
        f"data: {results['n_users']} users x 2 targets, {min(results['n_online'])}-{max(results['n_online'])} "
        f"online vectors per user, {results['n_train']} training vectors per position",
        f"settings: {results['n_settings']['deterministic']:,} kNN + {results['n_settings']['probabilistic']:,} "
        f"p-kNN; evaluated (users x 3 target searches): {ev['deterministic']:,} + {ev['probabilistic']:,}",
        "",
        f"{'method':<58}{'seconds':>12}",
        f"{'wsnlib.optimize.paper_tables (vectorised, fits included)':<58}{results['search_seconds']:>12.2f}",
    ]
    for approach, label in (("deterministic", "KNeighborsRegressor fit+predict"),
                            ("probabilistic", "ProbabilisticKNN(anchors=...) fit+predict")):
        n = naive[approach]
        tied = f", {n['n_tied']} differ by a distance tie" if n["n_tied"] else ""
        lines.append(f"{'naive ' + label + ', per setting':<58}{n['seconds_per_setting']:>12.4f}"
                     f"   ({n['n_sampled']} sampled; max |PE diff| {n['max_abs_diff_cm']:.1e} cm{tied})")
    lines += [
        f"{'naive loop, extrapolated to the full search':<58}{results['naive_seconds']:>12.1f}",
        "",
        f"ratio naive / vectorised: {results['ratio']:.0f}x",
        "(PE diff: search vs naive loop on the sampled settings; a tie between the k-th and (k+1)-th RSS",
        " distance is broken to the lower fingerprint index by wsnlib, arbitrarily by sklearn)",
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
