"""Every notebook: committed clean, parameterised, and executed in quick mode — twice.

The second run goes to another folder; every table and figure must come out byte-identical.
The solutions notebooks (``notebooks/solutions/``) are held to the same rules, except that
they need not write a figure.
"""

import json
import os
import subprocess
import sys

import nbformat
import pytest

from wsnlib import paths, reproduce

NOTEBOOKS = reproduce.list_notebooks()
EVERY_NOTEBOOK = reproduce.list_batch()  # the notebooks and the solutions notebooks


@pytest.mark.parametrize("notebook", EVERY_NOTEBOOK, ids=reproduce.notebook_name)
def test_notebook_is_committed_without_outputs(notebook):
    nb = nbformat.read(notebook, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert not cell.outputs, f"{notebook.name}: a code cell has outputs"
            assert cell.execution_count is None, f"{notebook.name}: a code cell has an execution count"


@pytest.mark.parametrize("notebook", EVERY_NOTEBOOK, ids=reproduce.notebook_name)
def test_notebook_has_a_parameters_cell_with_quick_and_seed(notebook):
    nb = nbformat.read(notebook, as_version=4)
    tagged = [c for c in nb.cells if "parameters" in c.metadata.get("tags", [])]
    assert len(tagged) == 1, f"{notebook.name}: expected exactly one cell tagged 'parameters'"
    names = {}
    exec(tagged[0].source, {}, names)  # plain literals only, so this is safe and side-effect free
    assert "quick" in names and isinstance(names["quick"], bool)
    assert "seed" in names and isinstance(names["seed"], int)


def test_notebook_defines_no_functions():
    """Logic belongs in wsnlib: notebooks call it but define no functions or classes."""
    for notebook in NOTEBOOKS:
        nb = nbformat.read(notebook, as_version=4)
        for cell in nb.cells:
            if cell.cell_type == "code":
                lines = cell.source.splitlines()
                assert not any(line.lstrip().startswith(("def ", "class ")) for line in lines), notebook.name


def _run_batch(output_dir):
    env = {**os.environ, paths.OUTPUT_ENV_VAR: str(output_dir)}
    result = subprocess.run([sys.executable, "-m", "wsnlib.reproduce", "--quick"], env=env,
                            capture_output=True, text=True, timeout=1800)
    assert result.returncode == 0, result.stderr[-4000:]
    return json.loads((output_dir / "data" / "processed" / "manifest.json").read_text())


@pytest.mark.notebook
def test_batch_runs_in_quick_mode_and_is_reproducible(tmp_path):
    first = _run_batch(tmp_path / "run1")
    second = _run_batch(tmp_path / "run2")
    ran = [entry["notebook"] for entry in first["notebooks"]]
    assert ran == [reproduce.notebook_name(nb) for nb in EVERY_NOTEBOOK]
    for entry in first["notebooks"]:
        assert entry["status"] == "ok", entry
        if entry["notebook"].startswith(f"{reproduce.SOLUTIONS}/"):
            continue  # a solutions notebook may write nothing
        assert entry["outputs"], f"{entry['notebook']} wrote no figure or table"
        kinds = {o["path"].split("/")[0] for o in entry["outputs"]}
        assert "figures" in kinds, f"{entry['notebook']} wrote no figure"
    hashes = [{o["path"]: o["sha256"] for e in m["notebooks"] for o in e["outputs"]} for m in (first, second)]
    assert hashes[0] == hashes[1]
    # The manifest's list is complete: nothing in data/processed/ escaped it.
    listed = {p for p in hashes[0] if p.startswith("data/processed/")}
    on_disk = {f"data/processed/{p.name}" for p in (tmp_path / "run1" / "data" / "processed").iterdir()
               if p.name != reproduce.MANIFEST_NAME}
    assert listed == on_disk
