"""Write the batch's measured run times into the notebooks' "Run time" sentences.

Each notebook's first cell states how long it runs, in a fixed sentence that
``tests/test_notebooks.py`` checks against a fresh quick batch::

    **Run time** (measured by the batch runner, `python -m wsnlib.reproduce`, on a shared 2-core
    machine in <Month YYYY>): N s in full mode, M s in quick mode.

The numbers are not typed in: after a full and a quick batch (each writes ``manifest.json``),

    python -m wsnlib.run_times FULL_MANIFEST QUICK_MANIFEST

rewrites N and M of every notebook the two manifests list (rounded seconds), the month, and the
command (with ``--jobs N`` when the batch ran notebooks side by side: their seconds then include
sharing the two cores with a neighbour).
"""

from __future__ import annotations

import argparse
import datetime
import json
import re
import sys
from pathlib import Path

import nbformat

from wsnlib import paths

SENTENCE = re.compile(
    r"\*\*Run time\*\* \(measured by the batch runner, `python -m wsnlib\.reproduce(?: --jobs \d+)?`,"
    r" on a shared 2-core"
    r"(?P<space1>\s+)machine in (?P<month>[A-Z][a-z]+ \d{4})\): (?P<full>\d+) s in full mode,(?P<space2>\s+)"
    r"(?P<quick>\d+) s in quick mode\."
)


def stated_seconds(notebook) -> dict[str, float] | None:
    """The run time ``notebook`` states in its first cell: ``{"full": N, "quick": M}`` (s), or None.

    ``python -m wsnlib.reproduce --jobs N`` starts the longest notebooks first by these numbers.
    """
    intro = nbformat.read(notebook, as_version=4).cells[0].source
    match = SENTENCE.search(intro)
    return None if match is None else {"full": float(match["full"]), "quick": float(match["quick"])}


def _read(manifest: Path) -> dict:
    return json.loads(Path(manifest).read_text())


def _seconds(manifest: Path) -> dict[str, float]:
    entries = _read(manifest)["notebooks"]
    bad = [e["notebook"] for e in entries if e.get("status") != "ok"]
    if bad:
        raise ValueError(f"{manifest}: not every notebook ran ok ({', '.join(bad)}); rerun the batch first")
    return {e["notebook"]: float(e["seconds"]) for e in entries}


def update_run_times(full_manifest, quick_manifest, month: str | None = None) -> list[str]:
    """Rewrite the run-time sentence of every notebook in both manifests; returns those changed.

    Raises ``ValueError`` if a manifest holds a failed notebook, or a listed notebook has no
    run-time sentence in its first cell.
    """
    full, quick = _seconds(full_manifest), _seconds(quick_manifest)
    jobs = {_read(m).get("jobs", 1) for m in (full_manifest, quick_manifest)}
    if len(jobs) != 1:
        raise ValueError(f"the two manifests were run with different --jobs ({sorted(jobs)}): times would not compare")
    command = "python -m wsnlib.reproduce" + (f" --jobs {jobs.pop()}" if jobs != {1} else "")
    month = month or datetime.date.today().strftime("%B %Y")
    changed = []
    for name in sorted(set(full) & set(quick)):
        path = paths.NOTEBOOKS / name
        nb = nbformat.read(path, as_version=4)
        intro = nb.cells[0].source
        match = SENTENCE.search(intro)
        if match is None:
            raise ValueError(f"{name}: no run-time sentence in its first cell (see wsnlib.run_times)")
        sentence = (f"**Run time** (measured by the batch runner, `{command}`, on a shared 2-core"
                    f"{match['space1']}machine in {month}): {round(full[name])} s in full mode,{match['space2']}"
                    f"{round(quick[name])} s in quick mode.")
        updated = intro[: match.start()] + sentence + intro[match.end() :]
        if updated != intro:
            nb.cells[0].source = updated
            nbformat.write(nb, path)
            changed.append(name)
    return changed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.run_times", description=__doc__.splitlines()[0])
    parser.add_argument("full_manifest", type=Path)
    parser.add_argument("quick_manifest", type=Path)
    args = parser.parse_args(argv)
    for manifest in (args.full_manifest, args.quick_manifest):
        if not manifest.is_file():
            parser.error(f"{manifest}: no such file (a batch's data/processed/manifest.json)")
    for name in update_run_times(args.full_manifest, args.quick_manifest):
        print(f"updated {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
