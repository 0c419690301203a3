"""Bookkeeping of the batch runner (:mod:`wsnlib.reproduce`): the manifest
``data/processed/manifest.json`` (its statuses are documented in :mod:`wsnlib.reproduce`),
the files each notebook wrote (with SHA-256), moving a previous run's outputs aside before a
notebook runs again, and locating the failing cell in an executed copy.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from wsnlib import paths
from wsnlib._files import atomic_write_text, is_temporary, sha256_of
from wsnlib.batch_selection import notebook_name

MANIFEST_NAME = "manifest.json"

#: Folder (below the output root) that receives the previous outputs of a notebook about to run.
STALE_FOLDER = Path("build") / "stale"


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
    """Write the manifest (atomically) with these notebook entries."""
    manifest = {"quick": quick, "jobs": jobs, "kernel": paths.KERNEL_NAME, "notebooks": entries}
    return atomic_write_text(manifest_path(), json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def previous_outputs() -> dict[str, list[str]]:
    """Output paths (relative to the output root) per notebook in the existing manifest, if any."""
    try:
        manifest = json.loads(manifest_path().read_text(encoding="utf-8"))
        return {e["notebook"]: [o["path"] for o in e.get("outputs", [])] for e in manifest["notebooks"]}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


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
