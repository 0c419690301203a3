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
