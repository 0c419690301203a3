"""Bookkeeping of the batch runner (:mod:`wsnlib.reproduce`): the manifest
``data/processed/manifest.json`` (its statuses are documented in :mod:`wsnlib.reproduce`),
the files each notebook wrote (with SHA-256), moving a previous run's outputs aside before a
notebook runs again, and locating the failing cell in an executed copy.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import sys
from collections.abc import Iterator
from pathlib import Path

from wsnlib import paths
from wsnlib._files import atomic_write_text, is_temporary, sha256_of
from wsnlib._user_warnings import warn_user
from wsnlib.batch_selection import list_batch, notebook_name

MANIFEST_NAME = "manifest.json"

#: Folder (below the output root) that receives the previous outputs of a notebook about to run.
STALE_FOLDER = Path("build") / "stale"
#: Folder (below the output root) of the running notebooks' journals: the files each has written so far.
JOURNAL_FOLDER = Path("build") / "journal"
#: File (below the output root) that one batch at a time holds locked.
LOCK_NAME = Path("build") / "batch.lock"


class BatchRunning(RuntimeError):
    """Another batch runs on the same output folder."""


@contextlib.contextmanager
def output_lock() -> Iterator[None]:
    """Hold the output folder for this batch; a second batch on it raises :class:`BatchRunning` at once.

    The lock (``build/batch.lock``, ``flock``) is released by the kernel when the process ends, even
    by SIGKILL; the file keeps the last holder's process id and command line, for the message.
    """
    path = paths.output_root() / LOCK_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+", encoding="utf-8") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            raise BatchRunning(f"another batch is running on {paths.output_root()} ({holder}); wait for it to end "
                               f"(or stop it) and run again") from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()}: {' '.join(sys.argv)}\n")
        handle.flush()
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def journal_path(notebook: str) -> Path:
    """The journal of the notebook named ``notebook`` (manifest name): one written file per line."""
    return paths.output_root() / JOURNAL_FOLDER / f"{notebook.replace('/', '__')}.txt"


def output_folders() -> list[Path]:
    """The folders whose files the manifest lists: ``figures/``, ``data/processed/``, ``data/raw/``."""
    return [paths.figures(), paths.data_processed(), paths.data_raw()]


def files_written_since(start_ns: int) -> list[Path]:
    """Files in :func:`output_folders` modified at or after ``start_ns`` (ns since the epoch), sorted."""
    written = []
    for folder in output_folders():
        for path in folder.rglob("*"):
            if (path.is_file() and path.name != MANIFEST_NAME and not is_temporary(path)
                    and path.stat().st_mtime_ns >= start_ns):
                written.append(path)
    return sorted(written)


def manifest_path() -> Path:
    """``data/processed/manifest.json`` below the output root."""
    return paths.data_processed() / MANIFEST_NAME


def write_manifest(entries: list[dict], quick: bool, jobs: int = 1) -> Path:
    """Write the manifest with these notebook entries: read, merge, replace (atomically).

    The entries of notebooks this run did not select (``--only``) stay as the manifest had them;
    all are listed in batch order.  Called under :func:`output_lock`, so no other run writes
    between the read and the replace.  ``quick`` and ``jobs`` describe this run (each entry's
    ``parameters`` say how it ran).
    """
    names = {entry["notebook"] for entry in entries}
    kept = [entry for entry in _manifest_entries() if entry.get("notebook") not in names]
    order = {notebook_name(nb): index for index, nb in enumerate(list_batch())}
    merged = sorted(entries + kept, key=lambda entry: order.get(entry["notebook"], len(order)))
    manifest = {"quick": quick, "jobs": jobs, "kernel": paths.KERNEL_NAME, "notebooks": merged}
    return atomic_write_text(manifest_path(), json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def _manifest_entries() -> list[dict]:
    """The notebook entries of the manifest on disk ([] if there is none or it is unreadable)."""
    try:
        entries = json.loads(manifest_path().read_text(encoding="utf-8"))["notebooks"]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    if not isinstance(entries, list):
        return []
    return [entry for entry in entries if isinstance(entry, dict) and "notebook" in entry]


def previous_outputs() -> dict[str, list[str]]:
    """Output paths (relative to the output root) per notebook in the existing manifest, if any, and
    in the journals a killed batch left (files it wrote that no manifest lists)."""
    previous: dict[str, list[str]] = {}
    path = manifest_path()
    if path.exists():
        try:
            manifest = json.loads(path.read_text(encoding="utf-8"))
            previous = {e["notebook"]: [o["path"] for o in e.get("outputs", [])] for e in manifest["notebooks"]}
        except (OSError, ValueError, KeyError, TypeError) as exc:
            warn_user(f"{path} is unreadable ({type(exc).__name__}: {exc}); the outputs it listed cannot be "
                      f"moved aside before their notebooks run again")
    root = paths.output_root().resolve()
    for journal in sorted((paths.output_root() / JOURNAL_FOLDER).glob("*.txt")):
        notebook = journal.stem.replace("__", "/")
        listed = [str(p.relative_to(root)) for p in logged_files(journal) if p.is_relative_to(root)]
        previous[notebook] = previous.get(notebook, []) + listed
    return previous


def move_aside(relative_paths: list[str]) -> list[str]:
    """Move the listed outputs (if still there) to ``build/stale/``; return those moved."""
    root = paths.output_root().resolve()
    folders = [folder.resolve() for folder in output_folders()]
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


def last_started_cell(executed: Path) -> dict:
    """Index and first line of the last cell papermill started in the executed copy ({} if unknown)."""
    import nbformat

    try:
        nb = nbformat.read(executed, as_version=4)
    except Exception:  # missing or half-written copy
        return {}
    started = [i for i, cell in enumerate(nb.cells) if cell.get("metadata", {}).get("papermill", {}).get("start_time")]
    if not started:
        return {}
    index = started[-1]
    source = nb.cells[index].source
    return {"cell_index": index, "cell_first_line": source.splitlines()[0] if source else ""}


def failing_cell(executed: Path) -> dict:
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


def initial_entries(notebooks: list[Path], quick: bool, jobs: int = 1) -> list[dict]:
    """Manifest entries, all "not run", after moving aside what the last run listed for them."""
    previous = previous_outputs()
    entries = [{"notebook": notebook_name(nb), "status": "not run", "parameters": {}, "seconds": None, "outputs": []}
               for nb in notebooks]
    for entry in entries:  # before anything runs: nothing stale is left to look fresh
        moved = move_aside(previous.get(entry["notebook"], []))
        if moved:
            entry["moved_aside"] = moved
        journal_path(entry["notebook"]).unlink(missing_ok=True)
    write_manifest(entries, quick, jobs)
    return entries


def logged_files(log: Path) -> list[Path]:
    """The files a notebook wrote, from its write log (:data:`wsnlib._files.WRITTEN_LOG_ENV`)."""
    if not log.exists():
        return []
    folders = [folder.resolve() for folder in output_folders()]
    written = {Path(line) for line in log.read_text(encoding="utf-8").splitlines() if line}
    return sorted(p for p in written if p.is_file() and any(p.is_relative_to(f) for f in folders))


def describe_outputs(files: list[Path]) -> list[dict]:
    """Manifest ``outputs`` entries: path relative to the output root and SHA-256 of each file."""
    root = paths.output_root()
    return [{"path": f.relative_to(root).as_posix(), "sha256": sha256_of(f)} for f in files if f.is_file()]
