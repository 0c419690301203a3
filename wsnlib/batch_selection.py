"""Which notebooks the batch runner (:mod:`wsnlib.reproduce`) runs, under which names, and
which parameters they accept (``-p NAME VALUE`` is checked before anything runs).
"""

from __future__ import annotations

import ast
import fnmatch
from pathlib import Path

from wsnlib import paths
from wsnlib._gc_pause import paused_collector

#: Sub-folder of ``notebooks/`` with the solutions notebooks (run after the notebooks).
SOLUTIONS = "solutions"


def list_notebooks(pattern: str | None = None) -> list[Path]:
    """Numbered notebooks in ``notebooks/`` in run order, optionally filtered by a glob."""
    return _numbered(paths.NOTEBOOKS, pattern)


def list_solutions(pattern: str | None = None) -> list[Path]:
    """Numbered solutions notebooks in ``notebooks/solutions/`` in run order, optionally filtered."""
    return _numbered(paths.NOTEBOOKS / SOLUTIONS, pattern)


def list_batch(pattern: str | None = None) -> list[Path]:
    """What the batch runs: the notebooks, then the solutions notebooks."""
    return list_notebooks(pattern) + list_solutions(pattern)


def notebook_name(notebook: Path) -> str:
    """Name in the manifest and below ``build/executed/``: ``01_x.ipynb``, ``solutions/01_y.ipynb``."""
    try:
        return notebook.relative_to(paths.NOTEBOOKS).as_posix()
    except ValueError:  # a notebook from elsewhere
        return notebook.name


def _numbered(folder: Path, pattern: str | None) -> list[Path]:
    found = sorted(folder.glob("[0-9][0-9]_*.ipynb"))
    if pattern:
        # the manifest's own names (``02_x.ipynb``, ``solutions/02_y.ipynb``) match too
        stem = pattern[: -len(".ipynb")] if pattern.endswith(".ipynb") else pattern
        found = [nb for nb in found if fnmatch.fnmatch(notebook_name(nb)[: -len(".ipynb")], f"*{stem}*")]
    return found


def notebook_parameters(notebook: Path) -> list[str]:
    """Names assigned in ``notebook``'s cell tagged ``parameters``, in order (``[]`` if it has none).

    Raises ``ValueError`` naming the notebook when that cell is not valid Python.
    """
    import nbformat

    nb = nbformat.read(notebook, as_version=4)
    names: list[str] = []
    for cell in nb.cells:
        if cell.cell_type != "code" or "parameters" not in cell.get("metadata", {}).get("tags", []):
            continue
        try:
            with paused_collector():  # no finalizer that parses runs inside this parse (wsnlib._gc_pause)
                tree = ast.parse(cell.source)
        except SyntaxError as exc:
            raise ValueError(f"{notebook}: the parameters cell is not valid Python ({exc})") from exc
        for node in tree.body:
            targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
            for target in targets:
                for name in ast.walk(target) if target is not None else ():
                    if isinstance(name, ast.Name) and name.id not in names:
                        names.append(name.id)
    return names


def check_parameters(notebooks: list[Path], parameters: dict) -> None:
    """``ValueError`` unless every name in ``parameters`` is a parameter of every notebook.

    The message names the unknown parameter, each notebook that lacks it and the parameters
    that notebook has (papermill itself would only warn and run on).
    """
    problems = []
    for notebook in notebooks:
        known = notebook_parameters(notebook)
        unknown = [name for name in parameters if name not in known]
        if unknown:
            problems.append(f"{notebook_name(notebook)} has no parameter {', '.join(map(repr, unknown))}; "
                            f"its parameters are {', '.join(known) if known else '(none)'}")
    if problems:
        raise ValueError("unknown -p parameter: " + "; ".join(problems))


def parse_value(text: str):
    """Parse a ``-p NAME VALUE`` value: a Python literal if it is one, else the string."""
    try:
        with paused_collector():  # no finalizer that parses runs inside this parse (wsnlib._gc_pause)
            return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text
