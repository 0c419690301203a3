"""The benchmark script runs (its numbers are reported, not asserted: timing is no test)."""

import importlib.util
from pathlib import Path

import pytest

from wsnlib import paths


def _load(name):
    spec = importlib.util.spec_from_file_location(name, paths.ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_benchmark_runs_in_quick_mode_and_agrees_with_ahrs():
    bench = _load("bench_madgwick")
    results = bench.run(quick=True, log=lambda *args: None)
    assert all(rate > 0 for rate in results["stream"].values())
    assert all(rate > 0 for rate in results["options"].values()) and results["batch"] > 0
    assert set(results["options"]) >= {"hold_last", "hybrid (feedback)", "gyro_interpolation"}
    assert results["ahrs_max_abs_diff"] < 1e-9
    text = bench.report(results)
    assert text.count("PASS") + text.count("MISS") == len(results["targets"]) == 5


def test_search_benchmark_runs_in_quick_mode():
    bench = _load("bench_search")
    results = bench.run(quick=True, log=lambda *args: None)
    text = bench.report(results)
    assert "PASS" in text or "MISS" in text


def test_loss_tolerance_evaluation_runs_in_quick_mode():
    """Two BROAD trials, tiny grids: the script runs end to end and prints a verdict per target."""
    import os
    import subprocess
    import sys

    shared = paths.ROOT.parent / "shared" / "data" / "broad"
    folder = os.environ.get("WSNLIB_BROAD_DIR") or (str(shared) if shared.is_dir() else "")
    if not folder or len(list(Path(folder).glob("*.mat"))) < 2:
        pytest.skip("needs two BROAD trials (set WSNLIB_BROAD_DIR; `make test` does on CI)")
    result = subprocess.run([sys.executable, str(paths.ROOT / "benchmarks" / "eval_loss_tolerance.py"), "--quick"],
                            env={**os.environ, "WSNLIB_BROAD_DIR": folder}, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    verdicts = [line for line in result.stdout.splitlines() if "PASS" in line or "MISS" in line]
    assert len(verdicts) == 3, result.stdout[-3000:]
