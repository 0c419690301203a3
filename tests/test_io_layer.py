"""The io layer (wsnlib.io) stands alone, and the old module paths re-export it."""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import wsnlib.accel_format
import wsnlib.datasets
import wsnlib.io
import wsnlib.pabr
import wsnlib.resample
import wsnlib.rss

#: Packages the io layer must never import (simulators, estimators, study and notebook glue).
FORBIDDEN_PREFIXES = ("wsnlib.sim", "wsnlib.orientation", "wsnlib.studies", "wsnlib.posture_study",
                      "wsnlib.views", "wsnlib.plotting", "wsnlib.optimize", "wsnlib.fingerprint", "wsnlib.radio")

IO_MODULES = ("accel", "broad", "download", "pabr", "pabr_download", "pabr_loaders", "pabr_windowing", "recording",
              "resample", "rss", "rss_table", "sidecar", "vectors")


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
        (wsnlib.rss, wsnlib.io.rss, ["rss_vectors", "read_rss", "write_rss", "RssVectors", "COLUMNS"]),
        (wsnlib.rss, wsnlib.io.recording, ["sidecar_path", "load_sidecar", "write_table_with_sidecar"]),
        (wsnlib.io.recording, wsnlib.io.sidecar, ["sidecar_path", "load_sidecar", "write_table_with_sidecar",
                                                  "check_sidecar_units", "finite_column", "CSV_ROWS_KEY"]),
        (wsnlib.accel_format, wsnlib.io.recording, ["sidecar_path", "load_sidecar", "write_table_with_sidecar"]),
        (wsnlib.resample, wsnlib.io.broad, ["BroadTrial"]),
        (wsnlib.accel_format, wsnlib.io.accel, ["read_acc", "write_acc", "write_samples", "VALUE_COLUMNS"]),
        (wsnlib.pabr, wsnlib.io.pabr, ["load_pabr_fingerprints", "pabr_vectors", "PABR_REGISTRY", "PabrVectors"]),
        (wsnlib.rss, wsnlib.io.vectors, ["RssVectors"]),
        (wsnlib.pabr, wsnlib.io.vectors, [("PabrVectors", "RssVectors")]),
        (wsnlib.resample, wsnlib.io.resample, ["resample_broad", "resample_signal", "resample_quaternion"]),
        (wsnlib.datasets, wsnlib.io.recording, ["Recording", "read_recording", "write_recording", "sidecar_path",
                                                "write_table_with_sidecar", "load_sidecar", "UNITS"]),
        (wsnlib.datasets, wsnlib.io.broad, ["load_broad", "BroadTrial", "broad_trials", "broad_trial_numbers",
                                            "BROAD_REGISTRY", "_broad_trial_name", "sha256_of"]),
        (wsnlib.datasets, wsnlib.io.download, ["RegistryEntry", "git_blob_sha1_of", "download_verified"]),
    ],
)
def test_old_paths_re_export_the_same_objects(old, new, names):
    for name in names:
        old_name, new_name = name if isinstance(name, tuple) else (name, name)
        assert getattr(old, old_name) is getattr(new, new_name), f"{old.__name__}.{old_name}"


@pytest.mark.parametrize(
    ("old", "new"),
    [
        (wsnlib.rss, wsnlib.io.rss),
        (wsnlib.accel_format, wsnlib.io.accel),
        (wsnlib.pabr, wsnlib.io.pabr_download),
        (wsnlib.pabr, wsnlib.io.pabr_loaders),
        (wsnlib.pabr, wsnlib.io.pabr_windowing),
        (wsnlib.io.pabr, wsnlib.io.pabr_download),
        (wsnlib.io.pabr, wsnlib.io.pabr_loaders),
        (wsnlib.io.pabr, wsnlib.io.pabr_windowing),
        (wsnlib.io.recording, wsnlib.io.sidecar),
        (wsnlib.resample, wsnlib.io.resample),
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
