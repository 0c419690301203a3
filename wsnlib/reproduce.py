"""Batch runner: execute every notebook with papermill and record what it produced.

Usage::

    python -m wsnlib.reproduce [--quick] [--only PATTERN] [-p NAME VALUE ...] [--cell-timeout SECONDS] [--jobs N]

Notebooks ``notebooks/NN_*.ipynb`` run in name order with the project's Jupyter kernel
(:data:`wsnlib.paths.KERNEL_NAME`), then the solutions ``notebooks/solutions/NN_*.ipynb``
in name order; ``--jobs N`` runs up to N of them at a time, each in its own kernel (they
do not depend on one another).  Executed copies go to ``build/executed/`` and ``build/executed/solutions/``
(gitignored).  ``data/processed/manifest.json`` records, per notebook (a solutions notebook
as ``solutions/<name>``), the parameters, the run time, the status and every file it wrote
below ``figures/``, ``data/processed/`` or ``data/raw/`` with its SHA-256:

``ok``
    every cell ran; ``outputs`` lists the files the notebook wrote.
``failed``
    a cell raised, or the kernel died (``error`` gives ``ename``, ``evalue`` and the cell:
    ``cell_index`` in the executed copy and ``cell_first_line``); ``outputs`` lists every
    file written before the failure.
``timeout``
    a cell ran longer than ``--cell-timeout`` seconds (default
    :data:`DEFAULT_CELL_TIMEOUT_S`); ``error`` names the cell and the limit; ``outputs`` as
    for ``failed``.
``interrupted``
    the batch received SIGINT (Ctrl-C) or SIGTERM; ``error`` names the signal and the cell
    that was running; ``outputs`` as for ``failed``.
``not run``
    the batch stopped before this notebook.

The manifest is written before the first notebook and after every notebook (atomically),
so a batch that stops leaves a manifest that says how far it got.  At the first notebook
that does not end ``ok`` the runner stops (with ``--jobs``, no further notebook starts and
the running ones finish; a signal stops them all), prints the notebook and the cell, and
exits with status 1 (``failed``, ``timeout``) or 128 + the signal number (``interrupted``).
Which files a notebook wrote is known from the time they were written, or with ``--jobs``
from the notebook's write log (:data:`wsnlib._files.WRITTEN_LOG_ENV`), since every wsnlib
writer goes through :func:`wsnlib._files.atomic_path`.

Before the batch runs, the files that the previous manifest listed for each selected
notebook are moved aside to ``build/stale/`` (the entry's ``moved_aside`` lists them), so a
figure or table left by an earlier run is never mistaken for a fresh one.  ``-p`` names must
be parameters of every selected notebook (assigned in its cell tagged ``parameters``);
anything else is refused before a notebook runs.

The kernel runs with two environment variables set for the batch (and only for it):

``MPLBACKEND=module://matplotlib_inline.backend_inline``
    matplotlib's inline backend, non-interactive: every figure a cell leaves open is stored
    in the executed copy as a PNG output (so ``make book`` can show it); files written by
    :func:`wsnlib.plotting.savefig` are the same bytes from run to run.
``WSNLIB_BATCH=1``
    "running unattended": code that would show interactive widgets (``wsnlib.interactive``)
    draws static figures instead.

The kernel talks to the runner over local IPC sockets (in a private temporary folder), not
TCP, so nothing listens on the network and ipykernel has no unencrypted-TCP warning to print.

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
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from wsnlib import paths
from wsnlib._files import WRITTEN_LOG_ENV, atomic_write_text, is_temporary, sha256_of

MANIFEST_NAME = "manifest.json"
SOLUTIONS = "solutions"

#: Default limit (s) on the run time of one cell: generous (the slowest cell of a full,
#: non-quick run takes minutes), it only stops a batch that would otherwise hang forever.
DEFAULT_CELL_TIMEOUT_S = 3600.0

#: Environment of the kernel during the batch (see the module docstring).
BATCH_ENV = {"MPLBACKEND": "module://matplotlib_inline.backend_inline", "WSNLIB_BATCH": "1"}

#: Folder (below the output root) that receives the previous outputs of a notebook about to run.
STALE_FOLDER = Path("build") / "stale"

_EXIT_FAILED = 1


class BatchInterrupted(KeyboardInterrupt):
    """Raised in the runner by SIGINT or SIGTERM while the batch runs."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


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
            problems.append(
                f"{notebook_name(notebook)} has no parameter {', '.join(map(repr, unknown))}; "
                f"its parameters are {', '.join(known) if known else '(none)'}"
            )
    if problems:
        raise ValueError("unknown -p parameter: " + "; ".join(problems))


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


@contextlib.contextmanager
def _signals_interrupt() -> Iterator[None]:
    """Turn SIGINT and SIGTERM into :class:`BatchInterrupted` while the batch runs (main thread only)."""

    def handler(signum, frame):
        raise BatchInterrupted(signum)

    saved = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            saved[signum] = signal.signal(signum, handler)
        except ValueError:  # not the main thread: leave signals alone
            break
    try:
        yield
    finally:
        for signum, previous in saved.items():
            signal.signal(signum, previous)


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
            if (path.is_file() and path.name != MANIFEST_NAME and not is_temporary(path)
                    and path.stat().st_mtime_ns >= start_ns):
                written.append(path)
    return sorted(written)


def _manifest_path() -> Path:
    return paths.data_processed() / MANIFEST_NAME


def _write_manifest(entries: list[dict], quick: bool, jobs: int = 1) -> Path:
    manifest = {"quick": quick, "jobs": jobs, "kernel": paths.KERNEL_NAME, "notebooks": entries}
    return atomic_write_text(_manifest_path(), json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def _previous_outputs() -> dict[str, list[str]]:
    """Output paths (relative to the output root) per notebook in the existing manifest, if any."""
    try:
        manifest = json.loads(_manifest_path().read_text(encoding="utf-8"))
        return {e["notebook"]: [o["path"] for o in e.get("outputs", [])] for e in manifest["notebooks"]}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def _move_aside(relative_paths: list[str]) -> list[str]:
    """Move the listed outputs (if still there) to ``build/stale/``; return those moved."""
    root = paths.output_root().resolve()
    folders = [folder.resolve() for folder in _output_folders()]
    moved = []
    for relative in relative_paths:
        source = (root / relative).resolve()
        if not source.is_file() or not any(source.is_relative_to(folder) for folder in folders):
            continue  # gone already, or not one of ours (never touch anything else)
        target = root / STALE_FOLDER / source.relative_to(root)
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(source, target)
        moved.append(source.relative_to(root).as_posix())
    return moved


def _last_started_cell(executed: Path) -> dict:
    """Index and first line of the last cell papermill started in the executed copy ({} if unknown)."""
    import nbformat

    try:
        nb = nbformat.read(executed, as_version=4)
    except Exception:  # missing or half-written copy
        return {}
    started = [i for i, cell in enumerate(nb.cells)
               if cell.get("metadata", {}).get("papermill", {}).get("start_time")]
    if not started:
        return {}
    index = started[-1]
    source = nb.cells[index].source
    return {"cell_index": index, "cell_first_line": source.splitlines()[0] if source else ""}


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


def _ipc_kernel_manager(folder: Path, env: dict | None = None, started: list | None = None):
    """A kernel manager class whose kernels use IPC sockets in ``folder`` instead of TCP.

    ``env``: variables added to the kernel's environment (e.g. the notebook's write log);
    ``started``: a list that receives every manager created (to stop kernels on a signal).
    """
    from jupyter_client.manager import AsyncKernelManager

    class IPCKernelManager(AsyncKernelManager):
        def __init__(self, **kwargs):
            kwargs.setdefault("transport", "ipc")
            kwargs.setdefault("ip", str(folder / "kernel"))
            super().__init__(**kwargs)
            if started is not None:
                started.append(self)

        async def _async_pre_start_kernel(self, **kw):
            if env:
                kw["env"] = {**(kw.get("env") or os.environ), **env}
            return await super()._async_pre_start_kernel(**kw)

    return IPCKernelManager


def run(notebooks: list[Path], parameters: dict, quick: bool, kernel: str = paths.KERNEL_NAME,
        cell_timeout: float = DEFAULT_CELL_TIMEOUT_S, jobs: int = 1) -> int:
    """Execute ``notebooks`` (in order; with ``jobs`` > 1, that many at a time) and write the manifest.

    Returns 0 if all ran, 1 at the first failure or cell timeout, 128 + the signal number
    when SIGINT or SIGTERM stopped the batch.
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    socket_folder = Path(tempfile.mkdtemp(prefix="wsnlib-kernel-"))
    try:
        with _batch_environment(), _signals_interrupt():
            if jobs > 1 and len(notebooks) > 1:
                return _run_parallel(notebooks, parameters, quick, kernel, cell_timeout, socket_folder, jobs)
            return _run(notebooks, parameters, quick, kernel, cell_timeout, socket_folder)
    finally:
        shutil.rmtree(socket_folder, ignore_errors=True)


def _initial_entries(notebooks: list[Path], quick: bool, jobs: int = 1) -> list[dict]:
    """Manifest entries, all "not run", after moving aside what the last run listed for them."""
    previous = _previous_outputs()
    entries = [
        {"notebook": notebook_name(nb), "status": "not run", "parameters": {}, "seconds": None, "outputs": []}
        for nb in notebooks
    ]
    for entry in entries:  # before anything runs: nothing stale is left to look fresh
        moved = _move_aside(previous.get(entry["notebook"], []))
        if moved:
            entry["moved_aside"] = moved
    _write_manifest(entries, quick, jobs)
    return entries


def _run(notebooks, parameters, quick, kernel, cell_timeout, socket_folder) -> int:
    from tqdm.auto import tqdm

    entries = _initial_entries(notebooks, quick)
    kernel_manager_class = _ipc_kernel_manager(socket_folder)
    progress = tqdm(notebooks, desc="notebooks", unit="nb", file=sys.stderr)
    for entry, notebook in zip(entries, progress, strict=True):
        progress.set_postfix_str(entry["notebook"])
        params = {"quick": quick, **parameters}
        executed = paths.executed_notebooks() / notebook_name(notebook)
        executed.parent.mkdir(parents=True, exist_ok=True)
        entry["parameters"] = params
        start_ns = time.time_ns()
        started = time.perf_counter()
        status, error, exit_code = _execute(notebook, executed, params, kernel, cell_timeout, kernel_manager_class)
        entry.update(status=status, seconds=round(time.perf_counter() - started, 1),
                     outputs=_describe(_files_written_since(start_ns)))
        if error is not None:
            entry["error"] = error
        _write_manifest(entries, quick)
        if status != "ok":
            progress.close()
            _report_failure(entry, executed)
            return exit_code
    progress.close()
    return 0


def _execute(notebook: Path, executed: Path, params: dict, kernel: str, cell_timeout: float,
             kernel_manager_class) -> tuple[str, dict | None, int]:
    """Run one notebook with papermill: ``(status, error, exit code)`` as the manifest records them."""
    import papermill
    from nbclient.exceptions import CellTimeoutError

    try:
        papermill.execute_notebook(
            str(notebook), str(executed), parameters=params, kernel_name=kernel,
            cwd=str(notebook.parent), progress_bar=False, log_output=False,
            execution_timeout=cell_timeout, kernel_manager_class=kernel_manager_class,
        )
    except papermill.PapermillExecutionError as exc:
        return "failed", {"cell_index": exc.cell_index, "ename": exc.ename, "evalue": exc.evalue,
                          **_failing_cell(executed)}, _EXIT_FAILED
    except CellTimeoutError as exc:
        return "timeout", {"ename": "CellTimeoutError", "evalue": f"a cell ran longer than {cell_timeout:g} s ({exc})",
                           "timeout_s": cell_timeout, **_last_started_cell(executed)}, _EXIT_FAILED
    except BatchInterrupted as exc:
        return "interrupted", {"ename": "BatchInterrupted", "evalue": f"stopped by {signal.Signals(exc.signum).name}",
                               **_last_started_cell(executed)}, 128 + exc.signum
    except Exception as exc:  # kernel died, missing kernel, unreadable notebook
        return "failed", {"ename": type(exc).__name__, "evalue": str(exc).strip(),
                          **_last_started_cell(executed)}, _EXIT_FAILED
    return "ok", None, 0


def _report_failure(entry: dict, executed: Path) -> None:
    error = entry["error"]
    cell = (f", cell {error['cell_index']} of the executed copy ({error.get('cell_first_line', '')!r})"
            if "cell_index" in error else "")
    print(f"\n{entry['status'].upper()}: {entry['notebook']}{cell}: {error['ename']}: {error['evalue']}\n"
          f"Executed copy: {executed}\nManifest: {_manifest_path()}", file=sys.stderr)


def _logged_files(log: Path) -> list[Path]:
    """The files a notebook wrote, from its write log (:data:`wsnlib._files.WRITTEN_LOG_ENV`)."""
    if not log.exists():
        return []
    folders = [folder.resolve() for folder in _output_folders()]
    written = {Path(line) for line in log.read_text(encoding="utf-8").splitlines() if line}
    return sorted(p for p in written if p.is_file() and any(p.is_relative_to(f) for f in folders))


def _run_parallel(notebooks, parameters, quick, kernel, cell_timeout, socket_folder, jobs) -> int:
    """:func:`_run` with up to ``jobs`` notebooks at a time (each in its own kernel).

    Which files a notebook wrote comes from its write log (every wsnlib writer goes through
    :func:`wsnlib._files.atomic_path`), not from times, since neighbours write meanwhile.  At
    the first notebook that does not end ``ok`` no further notebook starts; those running
    finish.  SIGINT/SIGTERM stops every running kernel and records them ``interrupted``.
    """
    import threading
    from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

    from tqdm.auto import tqdm

    entries = _initial_entries(notebooks, quick, jobs)
    stop, lock = threading.Event(), threading.Lock()
    managers: list = []
    running: set[int] = set()
    progress = tqdm(total=len(notebooks), desc="notebooks", unit="nb", file=sys.stderr)

    def one(index: int, notebook: Path) -> int:
        if stop.is_set():
            return 0
        entry = entries[index]
        executed = paths.executed_notebooks() / notebook_name(notebook)
        executed.parent.mkdir(parents=True, exist_ok=True)
        folder = socket_folder / f"nb{index}"
        folder.mkdir()
        log = folder / "written.txt"
        manager_class = _ipc_kernel_manager(folder, {WRITTEN_LOG_ENV: str(log)}, managers)
        params = {"quick": quick, **parameters}
        with lock:
            entry["parameters"] = params
            running.add(index)
        started = time.perf_counter()
        status, error, exit_code = _execute(notebook, executed, params, kernel, cell_timeout, manager_class)
        with lock:
            running.discard(index)
            if entry["status"] == "interrupted":  # the signal handler got here first
                return entry.get("exit_code", 130)
            entry.update(status=status, seconds=round(time.perf_counter() - started, 1),
                         outputs=_describe(_logged_files(log)))
            if error is not None:
                entry["error"] = error
                stop.set()
                _report_failure(entry, executed)
            _write_manifest(entries, quick, jobs)
            progress.update(1)
        return exit_code

    pool = ThreadPoolExecutor(max_workers=jobs)
    futures = [pool.submit(one, i, nb) for i, nb in enumerate(notebooks)]
    try:
        pending = set(futures)
        while pending:
            _, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
    except BatchInterrupted as exc:
        stop.set()
        with lock:
            for index in running:
                entries[index].update(status="interrupted", exit_code=128 + exc.signum, error={
                    "ename": "BatchInterrupted", "evalue": f"stopped by {signal.Signals(exc.signum).name}",
                    **_last_started_cell(paths.executed_notebooks() / notebook_name(notebooks[index]))})
                log = socket_folder / f"nb{index}" / "written.txt"
                entries[index]["outputs"] = _describe(_logged_files(log))
            _write_manifest(entries, quick, jobs)
        for manager in list(managers):  # the running kernels end; their threads then return
            with contextlib.suppress(Exception):
                manager.provisioner.process.kill()
        pool.shutdown(wait=True, cancel_futures=True)
        progress.close()
        for entry in entries:
            entry.pop("exit_code", None)
        _write_manifest(entries, quick, jobs)
        return 128 + exc.signum
    pool.shutdown(wait=True)
    progress.close()
    return max((f.result() for f in futures), default=0)


def _describe(files: list[Path]) -> list[dict]:
    root = paths.output_root()
    return [{"path": f.relative_to(root).as_posix(), "sha256": sha256_of(f)} for f in files if f.is_file()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.reproduce", description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="pass quick=True (small sweeps, for tests)")
    parser.add_argument("--only", metavar="PATTERN",
                        help="run only notebooks (and solutions) whose name contains PATTERN (glob)")
    parser.add_argument("-p", "--parameter", nargs=2, action="append", default=[], metavar=("NAME", "VALUE"),
                        help="override a notebook parameter (VALUE is a Python literal); repeatable")
    parser.add_argument("--kernel", default=paths.KERNEL_NAME, help="Jupyter kernel name (default: %(default)s)")
    parser.add_argument("--cell-timeout", type=float, default=DEFAULT_CELL_TIMEOUT_S, metavar="SECONDS",
                        help="stop the batch when one cell runs longer than this (default: %(default)g s)")
    parser.add_argument("--jobs", type=int, default=1, metavar="N",
                        help="run up to N notebooks at a time, each in its own kernel (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.only is not None and not args.only.strip():
        parser.error("--only needs a non-empty PATTERN (leave --only out to run every notebook)")
    if args.jobs < 1:
        parser.error(f"--jobs must be at least 1, got {args.jobs}")
    if not args.cell_timeout > 0 or args.cell_timeout == float("inf"):
        parser.error(f"--cell-timeout must be a positive number of seconds, got {args.cell_timeout!r}")
    notebooks = list_batch(args.only)
    if not notebooks:
        parser.error(f"no notebook matches {args.only!r} in {paths.NOTEBOOKS}")
    parameters = {name: parse_value(value) for name, value in args.parameter}
    if "quick" in parameters:
        parser.error("use --quick rather than -p quick ...")
    try:
        check_parameters(notebooks, parameters)
    except ValueError as exc:
        parser.error(str(exc))
    status = run(notebooks, parameters, quick=args.quick, kernel=args.kernel, cell_timeout=args.cell_timeout,
                 jobs=args.jobs)
    if status == 0:
        print(f"Ran {len(notebooks)} notebook(s); manifest: {_manifest_path()}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
