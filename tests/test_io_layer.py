"""The io layer (wsnlib.io) stands alone."""

import ast
import json
import subprocess
import sys
from pathlib import Path

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


@pytest.mark.parametrize(
    ("old", "new", "names"),
    [
        (wsnlib.io.recording, wsnlib.io.sidecar, ["sidecar_path", "load_sidecar", "write_table_with_sidecar",
                                                  "check_sidecar_units", "finite_column", "CSV_ROWS_KEY"]),
    ],
)
def test_old_paths_re_export_the_same_objects(old, new, names):
    for name in names:
        old_name, new_name = name if isinstance(name, tuple) else (name, name)
        assert getattr(old, old_name) is getattr(new, new_name), f"{old.__name__}.{old_name}"


@pytest.mark.parametrize(
    ("old", "new"),
    [
        (wsnlib.io.recording, wsnlib.io.sidecar),
    ],
)
def test_old_paths_re_export_every_public_name(old, new):
    """Every public name defined at the top level of the new module is reachable from the old one
    (the PABR dataset's code is split over three modules behind the one public path ``wsnlib.io.pabr``)."""
    tree = ast.parse(Path(new.__file__).read_text(encoding="utf-8"))
    defined = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            defined.add(node.name)
        elif isinstance(node, ast.Assign):
            defined.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            defined.add(node.target.id)
    # the PABR modules' helpers shared among themselves are not part of the dataset's public path
    internal = {"logger", "missing_message", "require_path", "registry_files"}
    public = {name for name in defined if not name.startswith("_") and name not in internal}
    assert len(public) > 3
    missing = sorted(name for name in public if getattr(old, name, None) is not getattr(new, name))
    assert missing == []
