"""Batch runner: execute every notebook with papermill and record what it produced.

Usage::

    python -m wsnlib.reproduce [--quick] [--only PATTERN] [-p NAME VALUE ...] [--cell-timeout SECONDS] [--jobs N]

Notebooks ``notebooks/NN_*.ipynb`` run in name order with the project's Jupyter kernel
(:data:`wsnlib.paths.KERNEL_NAME`), then the solutions ``notebooks/solutions/NN_*.ipynb``
in name order; ``--jobs N`` runs up to N of them at a time, each in its own kernel (they
do not depend on one another), the longest first by the run time each states
(:func:`longest_first`; the manifest keeps name order).  Executed copies go to
``build/executed/`` and ``build/executed/solutions/`` (gitignored).
``data/processed/manifest.json`` records, per notebook (a solutions notebook as
``solutions/<name>``), the parameters, the run time, the status and every file it wrote
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
figure or table left by an earlier run is never mistaken for a fresh one; so are the files in
the journal (``build/journal/``) of a notebook whose batch was killed before the manifest
could list them (each notebook's journal records every file as it is written and is deleted
once the manifest lists them).  An unreadable manifest is said in a warning.

One batch at a time per output folder: a second one exits at once with status
:data:`EXIT_BATCH_RUNNING` (75) and a message naming the running one (its process id and
command line, from ``build/batch.lock``).  ``-p`` names must
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

With ``--jobs N`` (N > 1) each kernel also gets the machine's cores ÷ N (at least 1) as the size of the
thread pools it may start, unless the environment sets them already: ``OMP_NUM_THREADS`` (OpenMP, on
which numba's ``prange`` runs here), ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` and
``NUMBA_NUM_THREADS`` (:data:`THREAD_VARS`), as joblib does for its worker processes.  N notebooks
side by side, each with a pool of a thread per core, would make their threads take turns on the cores
and spin while they wait for work.  (Every output of ``make figures`` was the same bytes with and
without these limits.)

The kernel talks to the runner over local IPC sockets (in a private temporary folder), not
TCP, so nothing listens on the network and ipykernel has no unencrypted-TCP warning to print.

The manifest holds run times, so it is the one file in ``data/processed/`` that differs
between two runs; reproducibility is judged on the hashes it lists.

This module runs the kernels; which notebooks and parameters is :mod:`wsnlib.batch_selection`,
the manifest and output bookkeeping :mod:`wsnlib.batch_manifest`.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

from wsnlib import paths
from wsnlib._arguments import positive_number, whole_number
from wsnlib._files import WRITTEN_LOG_ENV
from wsnlib._validation import check_count
from wsnlib.batch_manifest import (
    BatchRunning,
    describe_outputs,
    failing_cell,
    files_written_since,
    initial_entries,
    journal_path,
    last_started_cell,
    logged_files,
    manifest_path,
    output_lock,
    write_manifest,
)
from wsnlib.batch_selection import check_parameters, list_batch, notebook_name, parse_value
from wsnlib.parallel import local_workers
from wsnlib.run_times import stated_seconds

#: Default limit (s) on the run time of one cell: generous (the slowest cell of a full,
#: non-quick run takes minutes), it only stops a batch that would otherwise hang forever.
DEFAULT_CELL_TIMEOUT_S = 3600.0

#: Environment of the kernel during the batch (see the module docstring).
BATCH_ENV = {"MPLBACKEND": "module://matplotlib_inline.backend_inline", paths.BATCH_ENV_VAR: "1"}
#: The thread pools' sizes a kernel of a batch with ``--jobs`` > 1 gets (:func:`thread_limits`).
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

_EXIT_FAILED = 1
#: Exit status when another batch holds the output folder (EX_TEMPFAIL: try again later).
EXIT_BATCH_RUNNING = 75


class BatchInterrupted(KeyboardInterrupt):
    """Raised in the runner by SIGINT or SIGTERM while the batch runs."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


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


def thread_limits(jobs: int) -> dict[str, str]:
    """The variables of :data:`THREAD_VARS` that the environment does not set, each the cores ÷ ``jobs``
    (at least 1; the cores this process may use, :func:`wsnlib.parallel.local_workers`); none for one job."""
    if jobs == 1:
        return {}
    threads = str(max(1, local_workers(-1) // jobs))
    return {name: threads for name in THREAD_VARS if name not in os.environ}


def run(notebooks: list[Path], parameters: dict, quick: bool, kernel: str = paths.KERNEL_NAME,
        cell_timeout: float = DEFAULT_CELL_TIMEOUT_S, jobs: int = 1) -> int:
    """Execute ``notebooks`` (in order; with ``jobs`` > 1, that many at a time) and write the manifest.

    Returns 0 if all ran, 1 at the first failure or cell timeout, 128 + the signal number
    when SIGINT or SIGTERM stopped the batch.
    """
    check_count(jobs, "jobs")
    jobs = jobs if len(notebooks) > 1 else 1  # one notebook: nothing runs beside it
    socket_folder = Path(tempfile.mkdtemp(prefix="wsnlib-kernel-"))
    try:
        # BATCH_ENV and the thread limits for the kernels (they inherit them); the previous environment
        # comes back after.
        with output_lock(), mock.patch.dict(os.environ, BATCH_ENV | thread_limits(jobs)), _signals_interrupt():
            return _run(notebooks, parameters, quick, kernel, cell_timeout, socket_folder, jobs)
    finally:
        shutil.rmtree(socket_folder, ignore_errors=True)


def _execute(notebook: Path, executed: Path, params: dict, kernel: str, cell_timeout: float,
             kernel_manager_class) -> tuple[str, dict | None, int]:
    """Run one notebook with papermill: ``(status, error, exit code)`` as the manifest records them."""
    import papermill
    from nbclient.exceptions import CellTimeoutError

    try:
        # The kernel is killed once the last cell has run ("immediate"): every output is written by then,
        # and a graceful exit costs 0.5-1 s per notebook (the interpreter's finalisation, polled at 0.1 s).
        papermill.execute_notebook(str(notebook), str(executed), parameters=params, kernel_name=kernel,
                                   cwd=str(notebook.parent), progress_bar=False, log_output=False,
                                   execution_timeout=cell_timeout, kernel_manager_class=kernel_manager_class,
                                   shutdown_kernel="immediate")
    except papermill.PapermillExecutionError as exc:
        return "failed", {"cell_index": exc.cell_index, "ename": exc.ename, "evalue": exc.evalue,
                          **failing_cell(executed)}, _EXIT_FAILED
    except CellTimeoutError as exc:
        return "timeout", {"ename": "CellTimeoutError", "evalue": f"a cell ran longer than {cell_timeout:g} s ({exc})",
                           "timeout_s": cell_timeout, **last_started_cell(executed)}, _EXIT_FAILED
    except BatchInterrupted as exc:
        return "interrupted", {"ename": "BatchInterrupted", "evalue": f"stopped by {signal.Signals(exc.signum).name}",
                               **last_started_cell(executed)}, 128 + exc.signum
    except Exception as exc:  # kernel died, missing kernel, unreadable notebook
        return "failed", {"ename": type(exc).__name__, "evalue": str(exc).strip(),
                          **last_started_cell(executed)}, _EXIT_FAILED
    return "ok", None, 0


def _report_failure(entry: dict, executed: Path) -> None:
    error = entry["error"]
    cell = (f", cell {error['cell_index']} of the executed copy ({error.get('cell_first_line', '')!r})"
            if "cell_index" in error else "")
    print(f"\n{entry['status'].upper()}: {entry['notebook']}{cell}: {error['ename']}: {error['evalue']}\n"
          f"Executed copy: {executed}\nManifest: {manifest_path()}", file=sys.stderr)


def longest_first(notebooks, quick: bool) -> list[int]:
    """Indices of ``notebooks`` by the run time each states for the mode (:func:`wsnlib.run_times.
    stated_seconds`), longest first, name order among equals (none stated: 0 s).

    Side by side, a long notebook started last would run alone at the end while the other core
    idles; started first, the short ones fill the other core meanwhile.
    """
    mode = "quick" if quick else "full"
    seconds = [(stated_seconds(notebook) or {}).get(mode, 0.0) for notebook in notebooks]
    return sorted(range(len(notebooks)), key=lambda i: -seconds[i])


def _run(notebooks, parameters, quick, kernel, cell_timeout, socket_folder, jobs) -> int:
    """Run the notebooks one after the other, or up to ``jobs`` at a time (each in its own kernel).

    Which files a notebook wrote is known from the time they were written, or side by side from
    the notebook's write log (every wsnlib writer goes through :func:`wsnlib._files.atomic_path`),
    since neighbours write meanwhile.  At the first notebook that does not end ``ok`` no further
    notebook starts; those running finish.  Side by side, SIGINT/SIGTERM stops every running
    kernel and records them ``interrupted`` (one at a time, the running notebook records it).
    """
    import threading
    from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

    from tqdm.auto import tqdm

    entries = initial_entries(notebooks, quick, jobs)
    stop, lock = threading.Event(), threading.Lock()
    managers: list = []
    running: set[int] = set()
    progress = tqdm(total=len(notebooks), desc="notebooks", unit="nb", file=sys.stderr)

    def one(index: int, notebook: Path) -> int:
        if stop.is_set():
            return 0
        entry = entries[index]
        progress.set_postfix_str(entry["notebook"])
        executed = paths.executed_notebooks() / notebook_name(notebook)
        executed.parent.mkdir(parents=True, exist_ok=True)
        folder = socket_folder / f"nb{index}"
        folder.mkdir()
        log = journal_path(entry["notebook"])  # outlives a SIGKILL: the next run moves these files aside
        log.parent.mkdir(parents=True, exist_ok=True)
        manager_class = _ipc_kernel_manager(folder, {WRITTEN_LOG_ENV: str(log)}, managers)
        params = {"quick": quick, **parameters}
        with lock:
            entry["parameters"] = params
            running.add(index)
        start_ns = time.time_ns()
        started = time.perf_counter()
        status, error, exit_code = _execute(notebook, executed, params, kernel, cell_timeout, manager_class)
        with lock:
            running.discard(index)
            if entry["status"] == "interrupted":  # the signal handler got here first
                return entry.get("exit_code", 130)
            written = files_written_since(start_ns) if jobs == 1 else logged_files(log)
            entry.update(status=status, seconds=round(time.perf_counter() - started, 1),
                         outputs=describe_outputs(written))
            if error is not None:
                entry["error"] = error
                stop.set()
                progress.close()
                _report_failure(entry, executed)
            write_manifest(entries, quick, jobs)
            log.unlink(missing_ok=True)  # the manifest lists its files now
            progress.update(1)
        return exit_code

    if jobs == 1:  # in this thread: a signal interrupts the running notebook's cell
        codes = [one(index, notebook) for index, notebook in enumerate(notebooks)]
        progress.close()
        return max(codes, default=0)
    pool = ThreadPoolExecutor(max_workers=jobs)
    futures = [pool.submit(one, i, notebooks[i]) for i in longest_first(notebooks, quick)]
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
                    **last_started_cell(paths.executed_notebooks() / notebook_name(notebooks[index]))})
                entries[index]["outputs"] = describe_outputs(logged_files(journal_path(entries[index]["notebook"])))
            write_manifest(entries, quick, jobs)
            for index in running:
                journal_path(entries[index]["notebook"]).unlink(missing_ok=True)
        for manager in list(managers):  # the running kernels end; their threads then return
            with contextlib.suppress(Exception):
                manager.provisioner.process.kill()
        pool.shutdown(wait=True, cancel_futures=True)
        progress.close()
        for entry in entries:
            entry.pop("exit_code", None)
        write_manifest(entries, quick, jobs)
        return 128 + exc.signum
    pool.shutdown(wait=True)
    progress.close()
    return max((f.result() for f in futures), default=0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.reproduce", description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="pass quick=True (small sweeps, for tests)")
    parser.add_argument("--only", metavar="PATTERN",
                        help="run only notebooks (and solutions) whose name contains PATTERN (glob)")
    parser.add_argument("-p", "--parameter", nargs=2, action="append", default=[], metavar=("NAME", "VALUE"),
                        help="override a notebook parameter (VALUE is a Python literal); repeatable")
    parser.add_argument("--kernel", default=paths.KERNEL_NAME, help="Jupyter kernel name (default: %(default)s)")
    parser.add_argument("--cell-timeout", type=positive_number, default=DEFAULT_CELL_TIMEOUT_S, metavar="SECONDS",
                        help="stop the batch when one cell runs longer than this (default: %(default)g s)")
    parser.add_argument("--jobs", type=whole_number(1), default=1, metavar="N",
                        help="run up to N notebooks at a time, each in its own kernel (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.only is not None and not args.only.strip():
        parser.error("--only needs a non-empty PATTERN (leave --only out to run every notebook)")
    notebooks = list_batch(args.only)
    if not notebooks:
        names = ", ".join(notebook_name(nb) for nb in list_batch())
        parser.error(f"no notebook matches {args.only!r} in {paths.NOTEBOOKS}; the notebooks are: {names}")
    parameters = {name: parse_value(value) for name, value in args.parameter}
    if "quick" in parameters:
        parser.error("use --quick rather than -p quick ...")
    try:
        check_parameters(notebooks, parameters)
    except ValueError as exc:
        parser.error(str(exc))
    try:
        status = run(notebooks, parameters, quick=args.quick, kernel=args.kernel, cell_timeout=args.cell_timeout,
                     jobs=args.jobs)
    except BatchRunning as exc:
        print(f"python -m wsnlib.reproduce: {exc}", file=sys.stderr)
        return EXIT_BATCH_RUNNING
    if status == 0:
        print(f"Ran {len(notebooks)} notebook(s); manifest: {manifest_path()}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
