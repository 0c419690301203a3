"""The benchmark scripts run and measure the right thing (their timings are reported, never asserted)."""

import importlib.util

from wsnlib import paths


def _load(name):
    spec = importlib.util.spec_from_file_location(name, paths.ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_madgwick_benchmark_times_every_loss_option_on_a_lossy_mask_and_agrees_with_ahrs():
    bench = _load("bench_madgwick")
    results = bench.run(quick=True, log=lambda *args: None)
    assert set(results["options"]) == set(bench.OPTIONS)       # every paper option, by its label
    assert 0.5 < results["received"] < 1.0                    # timed under loss, not on a lossless mask
    assert results["ahrs_max_abs_diff"] < 1e-9                # the filter timed is Madgwick's (ahrs as oracle)
    text = bench.report(results)
    assert text.count("PASS") + text.count("MISS") == len(results["targets"]) == 5


def test_search_benchmark_times_the_same_results_as_the_naive_loop():
    bench = _load("bench_search")
    results = bench.run(quick=True, log=lambda *args: None)
    for approach in ("deterministic", "probabilistic"):
        naive = results["naive"][approach]
        assert naive["n_sampled"] > 0
        assert naive["max_abs_diff_cm"] < 1e-6, (approach, naive)  # the vectorised search = one fit per setting
    assert results["n_settings"] == {"deterministic": 6350, "probabilistic": 635}  # the paper's grid
    assert results["table3"].shape[0] == 2                                      # Table 3: one row per target


def test_stream_benchmark_outputs_every_sample_of_every_node_and_meets_deadlines_with_its_own_timing():
    from _recordings import turning_recording

    bench = _load("bench_stream")
    gyr, acc, mag, _ = turning_recording(1500, seed=3, noise=0.01)
    # 1 s of stream (real time: the quick mode's 3 s would mostly wait), 10,000 samples over 200 nodes
    results = bench.run(quick=True, seconds=1.0, log=lambda *args: None, signals=(gyr, acc, mag))
    live = results["live"]
    assert live["read"] == live["sent"] > 0                             # over UDP, every datagram read
    assert live["samples"] == results["nodes"] * int(results["seconds"] * bench.FS)  # every sample out, once
    counts = live["counters"]
    assert counts["received"] == live["sent"] and counts["duplicate"] == counts["corrupt"] == 0
    assert 0.05 < results["lost_share"] < 0.15                          # timed under GE 10 %, not lossless
    for name, setting in results["offline"].items():
        assert setting["late"] == 0, name                               # the algorithm's own deadlines
        assert setting["samples"] == live["samples"], name
    text = bench.report(results)
    assert text.count("PASS") + text.count("MISS") == len(results["targets"]) == 2
