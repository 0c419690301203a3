"""The io layer (wsnlib.io) stands alone."""

import json
import subprocess
import sys

import pytest

import wsnlib.io

#: Packages the io layer must never import (simulators, estimators, study and notebook glue).
FORBIDDEN_PREFIXES = ("wsnlib.sim", "wsnlib.orientation", "wsnlib.studies", "wsnlib.plotting", "wsnlib.optimize",
                      "wsnlib.radio")

IO_MODULES = ("accel", "broad", "download", "pabr", "recording",
              "resample", "rss", "sidecar", "vectors")


def test_every_io_module_is_listed():
    import pkgutil

    assert sorted(m.name for m in pkgutil.iter_modules(wsnlib.io.__path__)) == sorted(IO_MODULES)


@pytest.mark.parametrize("module", ["wsnlib.io", *(f"wsnlib.io.{name}" for name in IO_MODULES)])
def test_io_imports_no_simulator(module):
    """In a fresh interpreter, importing the module pulls in no simulator or study module."""
    code = (
        "import importlib, json, sys\n"
        f"importlib.import_module({module!r})\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.startswith('wsnlib'))))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = json.loads(result.stdout.strip().splitlines()[-1])
    assert module in loaded
    assert [m for m in loaded if m.startswith(FORBIDDEN_PREFIXES)] == []

