"""The benchmark script runs (its numbers are reported, not asserted: timing is no test)."""

import importlib.util

from wsnlib import paths


def test_benchmark_runs_in_quick_mode_and_agrees_with_ahrs():
    spec = importlib.util.spec_from_file_location("bench_madgwick", paths.ROOT / "benchmarks" / "bench_madgwick.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    results = bench.run(quick=True, log=lambda *args: None)
    assert all(rate > 0 for rate in results["ours"].values())
    assert results["ahrs"] > 0 and results["masked"]["steps_per_s"] > 0
    assert results["ahrs_max_abs_diff"] < 1e-9
    assert "PASS" in bench.report(results) or "MISS" in bench.report(results)
