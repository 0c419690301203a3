"""Batch runner: execute every notebook with papermill and record what it produced.

Usage::

    python -m wsnlib.reproduce [--quick] [--only PATTERN] [-p NAME VALUE ...]

Notebooks ``notebooks/NN_*.ipynb`` run in name order with the project's Jupyter kernel
(:data:`wsnlib.paths.KERNEL_NAME`), then the solutions ``notebooks/solutions/NN_*.ipynb``
in name order.  Executed copies go to ``build/executed/`` and ``build/executed/solutions/``
(gitignored).  ``data/processed/manifest.json`` records, per notebook (a solutions notebook
as ``solutions/<name>``), the parameters, the run time, the status (``ok`` / ``failed`` /
``not run``) and every file it wrote below ``figures/``, ``data/processed/`` or
``data/raw/`` with its SHA-256.  The manifest is written after every notebook, so an
interrupted batch leaves a manifest that says how far it got.  On a cell error the runner
stops, prints the notebook and the failing cell, marks the manifest and exits with status 1.

The kernel runs with two environment variables set for the batch (and only for it):

``MPLBACKEND=module://matplotlib_inline.backend_inline``
    matplotlib's inline backend, non-interactive: every figure a cell leaves open is stored
    in the executed copy as a PNG output (so ``make book`` can show it); files written by
    :func:`wsnlib.plotting.savefig` are the same bytes from run to run.
``WSNLIB_BATCH=1``
    "running unattended": code that would show interactive widgets (``wsnlib.interactive``)
    draws static figures instead.

The manifest holds run times, so it is the one file in ``data/processed/`` that differs
between two runs; reproducibility is judged on the hashes it lists.
"""
from __future__ import annotations

import argparse
import ast
import contextlib
import fnmatch
import json
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from wsnlib import paths
from wsnlib._files import sha256_of

MANIFEST_NAME = "manifest.json"
SOLUTIONS = "solutions"

#: Environment of the kernel during the batch (see the module docstring).
BATCH_ENV = {"MPLBACKEND": "module://matplotlib_inline.backend_inline", "WSNLIB_BATCH": "1"}


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
        found = [nb for nb in found if fnmatch.fnmatch(notebook_name(nb)[: -len(".ipynb")], f"*{pattern}*")]
    return found


@contextlib.contextmanager
def _batch_environment() -> Iterator[None]:
    """Set :data:`BATCH_ENV` (the kernel inherits it) and restore the previous values after."""
    saved = {name: os.environ.get(name) for name in BATCH_ENV}
    os.environ.update(BATCH_ENV)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def parse_value(text: str):
    """Parse a ``-p NAME VALUE`` value: a Python literal if it is one, else the string."""
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def _output_folders() -> list[Path]:
    return [paths.figures(), paths.data_processed(), paths.data_raw()]


def _files_written_since(start_ns: int) -> list[Path]:
    written = []
    for folder in _output_folders():
        for path in folder.rglob("*"):
            if path.is_file() and path.name != MANIFEST_NAME and path.stat().st_mtime_ns >= start_ns:
                written.append(path)
    return sorted(written)


def _write_manifest(entries: list[dict], quick: bool) -> Path:
    manifest_path = paths.data_processed() / MANIFEST_NAME
    manifest = {"quick": quick, "kernel": paths.KERNEL_NAME, "notebooks": entries}
    tmp = manifest_path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    tmp.replace(manifest_path)
    return manifest_path


def _failing_cell(executed: Path) -> dict:
    """Locate the first cell whose outputs hold an error in an executed notebook."""
    import nbformat

    try:
        nb = nbformat.read(executed, as_version=4)
    except (OSError, ValueError):
        return {}
    for index, cell in enumerate(nb.cells):
        for output in cell.get("outputs", []):
            if output.get("output_type") == "error":
                first_line = cell.source.splitlines()[0] if cell.source else ""
                return {"cell_index": index, "cell_first_line": first_line,
                        "ename": output.get("ename"), "evalue": output.get("evalue")}
    return {}


def run(notebooks: list[Path], parameters: dict, quick: bool, kernel: str = paths.KERNEL_NAME) -> int:
    """Execute ``notebooks`` in order; return 0 if all succeeded, 1 at the first failure."""
    with _batch_environment():
        return _run(notebooks, parameters, quick, kernel)


def _run(notebooks: list[Path], parameters: dict, quick: bool, kernel: str) -> int:
    import papermill
    from tqdm.auto import tqdm

    entries = [
        {"notebook": notebook_name(nb), "status": "not run", "parameters": {}, "seconds": None, "outputs": []}
        for nb in notebooks
    ]
    _write_manifest(entries, quick)
    progress = tqdm(notebooks, desc="notebooks", unit="nb", file=sys.stderr)
    for entry, notebook in zip(entries, progress, strict=True):
        progress.set_postfix_str(entry["notebook"])
        params = {"quick": quick, **parameters}
        executed = paths.executed_notebooks() / notebook_name(notebook)
        executed.parent.mkdir(parents=True, exist_ok=True)
        entry["parameters"] = params
        start_ns = time.time_ns()
        started = time.perf_counter()
        try:
            papermill.execute_notebook(
                str(notebook), str(executed), parameters=params, kernel_name=kernel,
                cwd=str(notebook.parent), progress_bar=False, log_output=False,
            )
        except papermill.PapermillExecutionError as exc:
            entry.update(status="failed", seconds=round(time.perf_counter() - started, 1),
                         error={"cell_index": exc.cell_index, "ename": exc.ename,
                                "evalue": exc.evalue, **_failing_cell(executed)})
            entry["outputs"] = _describe(_files_written_since(start_ns))
            _write_manifest(entries, quick)
            progress.close()
            print(f"\nFAILED: {entry['notebook']}, cell {exc.cell_index} (execution count "
                  f"{exc.exec_count}): {exc.ename}: {exc.evalue}\n"
                  f"Executed copy with the traceback: {executed}", file=sys.stderr)
            return 1
        except Exception as exc:  # kernel died, missing kernel, unreadable notebook
            entry.update(status="failed", seconds=round(time.perf_counter() - started, 1),
                         error={"ename": type(exc).__name__, "evalue": str(exc)})
            _write_manifest(entries, quick)
            progress.close()
            print(f"\nFAILED: {entry['notebook']}: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 1
        entry.update(status="ok", seconds=round(time.perf_counter() - started, 1),
                     outputs=_describe(_files_written_since(start_ns)))
        _write_manifest(entries, quick)
    progress.close()
    return 0


def _describe(files: list[Path]) -> list[dict]:
    root = paths.output_root()
    return [{"path": str(f.relative_to(root)), "sha256": sha256_of(f)} for f in files]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.reproduce", description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="pass quick=True (small sweeps, for tests)")
    parser.add_argument("--only", metavar="PATTERN",
                        help="run only notebooks (and solutions) whose name contains PATTERN (glob)")
    parser.add_argument("-p", "--parameter", nargs=2, action="append", default=[], metavar=("NAME", "VALUE"),
                        help="override a notebook parameter (VALUE is a Python literal); repeatable")
    parser.add_argument("--kernel", default=paths.KERNEL_NAME, help="Jupyter kernel name (default: %(default)s)")
    args = parser.parse_args(argv)
    notebooks = list_batch(args.only)
    if not notebooks:
        parser.error(f"no notebook matches {args.only!r} in {paths.NOTEBOOKS}")
    parameters = {name: parse_value(value) for name, value in args.parameter}
    if "quick" in parameters:
        parser.error("use --quick rather than -p quick ...")
    status = run(notebooks, parameters, quick=args.quick, kernel=args.kernel)
    if status == 0:
        print(f"Ran {len(notebooks)} notebook(s); manifest: {paths.data_processed() / MANIFEST_NAME}",
              file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
