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


def pytest_collection_modifyitems(items):
    """Order the files by the seconds their ``slow`` tests take, longest first (a stable sort).

    ``make test`` runs the unit tests under xdist with ``--dist loadfile``, which hands the files
    out in this order: with the long ones first, the two workers finish together instead of one
    running a 20 s test alone at the end.
    """
    seconds = {}
    for item in items:
        marker = item.get_closest_marker("slow")
        if marker is not None:
            seconds[item.path] = seconds.get(item.path, 0.0) + float(marker.args[0])
    items.sort(key=lambda item: -seconds.get(item.path, 0.0))
