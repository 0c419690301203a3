"""The library's layers hold: every wsnlib module imports only its own layer or those below.

A module's layer is given by its first name under ``wsnlib`` (``wsnlib.sim.radio`` →
``sim``), so a new top-level module or package must be placed in :data:`LAYERS` before the test
passes.  The scan reads ``import`` statements with :mod:`ast` (also those inside functions), so a
lazy import that runs upward is caught as well; a failure lists every offending arrow as
``file:line: importer (layer) → imported (layer)``.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import wsnlib
from wsnlib._gc_pause import paused_collector

ROOT = Path(wsnlib.__file__).parent

#: The layers from the bottom up, and the top-level modules and packages of wsnlib in each.
LAYERS = {
    "core":       "__init__ quaternion frames testbed arm_model loss metrics paths _files _validation _user_warnings "
                  "_arguments _gc_pause paper_values cache fixed_order parallel plausibility",
    "io":         "io",
    "algorithms": "orientation radio posture optimize tuning loto stats stream",
    "sim":        "sim",
    "report":     "plotting outputs reproduce batch_selection batch_manifest run_times book",
    "studies":    "studies interactive exercises live_view",
}  # fmt: skip
RANK = {layer: rank for rank, layer in enumerate(LAYERS)}
LAYER_OF = {top: layer for layer, tops in LAYERS.items() for top in tops.split()}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__" and len(parts) > 2:
        parts = parts[:-1]
    return ".".join(parts)


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return LAYER_OF.get(parts[1] if len(parts) > 1 else "__init__")


def _parse(source: str) -> ast.Module:
    """``ast.parse`` with the garbage collector paused (a finalizer that parses must not run inside it:
    :mod:`wsnlib._gc_pause`; asyncio logging a task of a notebook kernel an earlier test stopped did)."""
    with paused_collector():
        return ast.parse(source)


def _imports(module: str, is_package: bool, source: str) -> list[tuple[int, str]]:
    """(line, module) of every wsnlib import in ``source``, relative imports resolved."""
    package = module if is_package else module.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(_parse(source)):
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
    return [(line, name) for line, name in found if name.startswith("wsnlib.")]


def _violations(path: Path, source: str) -> list[str]:
    """Every way ``path`` (with text ``source``) breaks the layers, one line each."""
    module = _module_name(path)
    where = path.relative_to(ROOT.parent)
    here = _layer(module)
    if here is None:
        return [f"{where}: {module} is in no layer of tests/test_layers.py (add its top-level name to LAYERS)"]
    out = []
    for line, name in _imports(module, path.name == "__init__.py", source):
        there = _layer(name)
        if there is None:
            out.append(f"{where}:{line}: {module} ({here}) → {name} (in no layer)")
        elif RANK[there] > RANK[here]:
            out.append(f"{where}:{line}: {module} ({here}) → {name} ({there})")
    return out


def test_every_import_points_down():
    paths = sorted(ROOT.rglob("*.py"))
    assert len(paths) > 50  # the walk found the package
    found = [v for path in paths for v in _violations(path, path.read_text(encoding="utf-8"))]
    assert found == [], "imports that point up the layers:\n" + "\n".join(found)


def test_the_check_reports_an_upward_import_with_its_line():
    """The check can fail: a core module importing a simulator and a study is reported, arrow by arrow."""
    source = "import numpy\n\nfrom wsnlib.sim import radio\nimport wsnlib.studies.posture\nfrom wsnlib import frames\n"
    assert _violations(ROOT / "quaternion.py", source) == [
        "wsnlib/quaternion.py:3: wsnlib.quaternion (core) → wsnlib.sim (sim)",
        "wsnlib/quaternion.py:4: wsnlib.quaternion (core) → wsnlib.studies.posture (studies)",
    ]
    assert "is in no layer" in _violations(ROOT / "newthing.py", "")[0]


def test_the_io_layer_loads_nothing_above_it():
    """In a fresh interpreter, importing every io module pulls in no module of a higher layer
    (the scan above reads the source; this also sees what runs at import time)."""
    code = (
        "import importlib, json, pkgutil, sys\n"
        "import wsnlib.io\n"
        "for m in pkgutil.iter_modules(wsnlib.io.__path__):\n"
        "    importlib.import_module(f'wsnlib.io.{m.name}')\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.startswith('wsnlib'))))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = json.loads(result.stdout.strip().splitlines()[-1])
    assert "wsnlib.io.rss" in loaded and "wsnlib.io.pabr" in loaded
    assert [m for m in loaded if RANK[_layer(m)] > RANK["io"]] == []
