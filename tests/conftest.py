"""Shared fixtures: seeded generators and an isolated output folder."""

import numpy as np
import pytest


@pytest.fixture
def rng():
    """A fresh, seeded generator per test (never the global numpy RNG)."""
    return np.random.default_rng(12345)


@pytest.fixture
def output_dir(tmp_path, monkeypatch):
    """Send every generated file of the test to a temporary folder."""
    monkeypatch.setenv("WSNLIB_OUTPUT_DIR", str(tmp_path))
    return tmp_path


#: The test files that take longest (seconds of one warm unit run on this 2-core machine, November
#: 2026), run first: ``make test`` hands whole files to its two processes in collection order
#: (``--dist loadfile --no-loadscope-reorder``), and with the long ones first the two finish
#: together instead of one running the last long file alone.  Only the wall time depends on it.
LONGEST_FILES_FIRST = ("test_loss_tolerance_study.py",  # 30 s
                       "test_reproduce.py",  # 27 s
                       "test_loss_handling.py",  # 20 s
                       "test_blas_kernels.py",  # 19 s
                       "test_kernels.py",  # 17 s
                       "test_notebooks.py",  # 13 s (its tests not marked notebook)
                       "test_benchmarks.py",  # 10 s
                       "test_stream_cli.py",  # 8 s
                       "test_kalman.py",  # 8 s
                       "test_studies_posture.py")  # 6 s


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(LONGEST_FILES_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest as collected
