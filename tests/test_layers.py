"""The README's layer picture holds: every wsnlib module imports only its own layer or those below.

The picture (README, "How the library is layered"), bottom to top:

core → io → algorithms → sim → report → studies → compat (the old module paths, re-exports only).

A module's layer is given by its first name under ``wsnlib`` (``wsnlib.sim.radio_channel`` → ``sim``),
so a new top-level module or package must be placed in :data:`LAYERS` before the test passes.
The scan reads ``import`` statements with :mod:`ast` (also those inside functions), so a lazy
import that runs upward is caught as well.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import wsnlib

ROOT = Path(wsnlib.__file__).parent

#: Layers from the bottom up, and the top-level modules / packages of each.
LAYERS = {
    "core": ("__init__", "quaternion", "frames", "testbed", "arm_model", "loss", "metrics", "paths", "_files",
             "_validation", "paper_values", "cache", "fixed_order"),
    "io": ("io",),
    "algorithms": ("orientation", "radio", "posture", "optimize", "tuning", "loto", "stats"),
    "sim": ("sim",),
    "report": ("plotting", "outputs", "reproduce", "batch_selection", "batch_manifest", "run_times", "book"),
    "studies": ("studies", "interactive", "exercises"),
    "compat": ("datasets", "rss", "accel_format", "pabr", "resample", "fingerprint", "posture_study", "views"),
}
RANK = {name: rank for rank, name in enumerate(LAYERS)}
LAYER_OF = {top: name for name, tops in LAYERS.items() for top in tops}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__" and len(parts) > 2:
        parts = parts[:-1]
    return ".".join(parts)


def _layer(module: str) -> str:
    parts = module.split(".")
    top = parts[1] if len(parts) > 1 else "__init__"
    if top not in LAYER_OF:
        raise KeyError(f"{module}: top-level name {top!r} is in no layer of tests/test_layers.py")
    return LAYER_OF[top]


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every wsnlib import in the file, relative imports resolved."""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "wsnlib":  # from wsnlib import x: x is the module imported
                found += [(node.lineno, f"wsnlib.{alias.name}") for alias in node.names]
            else:
                found.append((node.lineno, target))
    return [(line, name) for line, name in found if name == "wsnlib" or name.startswith("wsnlib.")]


MODULE_FILES = sorted(ROOT.rglob("*.py"))


def test_every_module_has_a_layer():
    unplaced = []
    for path in MODULE_FILES:
        try:
            _layer(_module_name(path))
        except KeyError as error:
            unplaced.append(str(error))
    assert unplaced == []


@pytest.mark.parametrize("path", MODULE_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down(path):
    here = _layer(_module_name(path))
    upward = [f"line {line}: {name} ({_layer(name)})" for line, name in _imports(path)
              if name != "wsnlib" and RANK[_layer(name)] > RANK[here]]
    assert upward == [], f"{_module_name(path)} ({here}) imports from a layer above it"


def test_the_scan_sees_an_upward_import(tmp_path, monkeypatch):
    """The check can fail: a core module importing a simulator is reported."""
    fake = ROOT / "quaternion.py"
    source = "from wsnlib.sim import radio\nimport wsnlib.studies.posture\n"
    monkeypatch.setattr(Path, "read_text", lambda self, encoding=None: source if self == fake else "")
    names = [name for _, name in _imports(fake)]
    assert names == ["wsnlib.sim", "wsnlib.studies.posture"]
    assert all(RANK[_layer(name)] > RANK["core"] for name in names)
