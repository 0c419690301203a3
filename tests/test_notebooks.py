"""Every notebook: committed clean, parameterised, and executed in quick mode.

Notebook 04 runs a second time into another folder; every table and figure it writes must come
out byte-identical.  The executed copies must show no warning, no stderr output and no list of
paths, and the run times the notebooks state must match what the batch measured (on a fresh
clone, whose first batch also compiles the filters, after a second, warm batch).
The solutions notebooks (``notebooks/solutions/``) are held to the same rules, except that
they need not write a figure.
"""

import json
import os
import re
import subprocess
import sys
import time

import nbformat
import pytest

from wsnlib import batch_manifest, batch_selection, paths
from wsnlib.run_times import stated_seconds

NOTEBOOKS = batch_selection.list_notebooks()
EVERY_NOTEBOOK = batch_selection.list_batch()  # the notebooks and the solutions notebooks


@pytest.mark.parametrize("notebook", EVERY_NOTEBOOK, ids=batch_selection.notebook_name)
def test_notebook_is_committed_without_outputs(notebook):
    nb = nbformat.read(notebook, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert not cell.outputs, f"{notebook.name}: a code cell has outputs"
            assert cell.execution_count is None, f"{notebook.name}: a code cell has an execution count"


@pytest.mark.parametrize("notebook", EVERY_NOTEBOOK, ids=batch_selection.notebook_name)
def test_notebook_has_a_parameters_cell_with_quick_and_seed(notebook):
    nb = nbformat.read(notebook, as_version=4)
    tagged = [c for c in nb.cells if "parameters" in c.metadata.get("tags", [])]
    assert len(tagged) == 1, f"{notebook.name}: expected exactly one cell tagged 'parameters'"
    names = {}
    exec(tagged[0].source, {}, names)  # plain literals only, so this is safe and side-effect free
    assert "quick" in names and isinstance(names["quick"], bool)
    assert "seed" in names and isinstance(names["seed"], int)


@pytest.mark.parametrize("notebook", EVERY_NOTEBOOK, ids=batch_selection.notebook_name)
def test_parameters_cell_lines_papermill_can_read(notebook):
    """papermill reads a parameters cell line by line and warns on a line with two '=' (e.g. in a comment)."""
    nb = nbformat.read(notebook, as_version=4)
    cell = next(c for c in nb.cells if "parameters" in c.metadata.get("tags", []))
    bad = [line for line in cell.source.splitlines() if line.count("=") > 1]
    assert not bad, f"{notebook.name}: papermill cannot parse {bad}"


def test_notebook_defines_no_functions():
    """Logic belongs in wsnlib: notebooks call it but define no functions or classes."""
    for notebook in NOTEBOOKS:
        nb = nbformat.read(notebook, as_version=4)
        for cell in nb.cells:
            if cell.cell_type == "code":
                lines = cell.source.splitlines()
                assert not any(line.lstrip().startswith(("def ", "class ")) for line in lines), notebook.name


def _start_batch(output_dir, *options) -> subprocess.Popen:
    env = {**os.environ, paths.OUTPUT_ENV_VAR: str(output_dir)}
    return subprocess.Popen([sys.executable, "-m", "wsnlib.reproduce", "--quick", "--jobs", "2", *options], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish_batch(process: subprocess.Popen, output_dir):
    """The manifest of a batch started by :func:`_start_batch`, once it ended well."""
    _, stderr = process.communicate(timeout=1800)
    assert process.returncode == 0, stderr[-4000:]
    return json.loads((output_dir / "data" / "processed" / "manifest.json").read_text())


def _compiled_since(start: float) -> bool:
    """Whether numba wrote compiled filters to its on-disk cache after ``start`` (a time.time())."""
    from wsnlib.orientation import _kernels, _numba_cache

    folder = _numba_cache.cache_dir(_kernels.filter_stream)
    return any(path.stat().st_mtime >= start for path in folder.glob("*.nb[ic]"))


#: The notebook run a second time for the reproducibility check (cheap, and it writes tables and figures).
RERUN = "04_loss_alternatives"


@pytest.fixture(scope="module")
def quick_batch(tmp_path_factory):
    """The batch in quick mode: ``(folder, manifest, compiled, rerun)``, ``compiled`` whether numba
    wrote compiled kernels to its cache meanwhile (a fresh clone, edited sources, or another test
    process compiling): then the batch's seconds include compilation.  ``rerun`` is the manifest of
    :data:`RERUN` run again into another folder, beside the batch (a third kernel for its first
    seconds, rather than an idle core after it)."""
    start = time.time()
    folder, rerun_folder = tmp_path_factory.mktemp("quick-batch"), tmp_path_factory.mktemp("quick-rerun")
    rerun = _start_batch(rerun_folder, "--only", f"{RERUN}*")
    try:
        manifest = _finish_batch(_start_batch(folder), folder)
    except BaseException:
        rerun.kill()
        rerun.wait()
        raise
    return folder, manifest, _compiled_since(start), _finish_batch(rerun, rerun_folder)


@pytest.mark.notebook
def test_batch_runs_in_quick_mode_and_is_reproducible(quick_batch):
    run1, first, _, second = quick_batch
    ran = [entry["notebook"] for entry in first["notebooks"]]
    assert ran == [batch_selection.notebook_name(nb) for nb in EVERY_NOTEBOOK]
    for entry in first["notebooks"]:
        assert entry["status"] == "ok", entry
        if entry["notebook"].startswith(f"{batch_selection.SOLUTIONS}/"):
            continue  # a solutions notebook may write nothing
        assert entry["outputs"], f"{entry['notebook']} wrote no figure or table"
        kinds = {o["path"].split("/")[0] for o in entry["outputs"]}
        assert "figures" in kinds, f"{entry['notebook']} wrote no figure"
    hashes = [{o["path"]: o["sha256"] for e in m["notebooks"] for o in e["outputs"]} for m in (first, second)]
    assert hashes[1] and hashes[1].items() <= hashes[0].items()  # the same bytes the second time
    # The manifest's list is complete: nothing in data/processed/ escaped it.
    listed = {p for p in hashes[0] if p.startswith("data/processed/")}
    on_disk = {f"data/processed/{p.name}" for p in (run1 / "data" / "processed").iterdir()
               if p.name != batch_manifest.MANIFEST_NAME}
    assert listed == on_disk


#: Tag of a code cell allowed to write to stderr; the cell must say why in a comment naming stderr.
EXPECTED_STDERR_TAG = "expected-stderr"
_WARNING = re.compile(r"\b[A-Z]\w*Warning\b")


def _clutter(cell) -> list[str]:
    """What a student should not see in an executed cell's outputs."""
    found = []
    for output in cell.get("outputs", []):
        if output.get("output_type") == "stream":
            text = output.get("text", "")
            if output.get("name") == "stderr":
                found.append(f"stderr output {text[:200]!r}")
        else:
            text = output.get("data", {}).get("text/plain", "")
        if _WARNING.search(text):
            found.append(f"a warning {text[:200]!r}")
        if "PosixPath(" in text:
            found.append(f"a list of paths {text[:120]!r} (end the savefig line with ';')")
    return found


@pytest.mark.notebook
def test_executed_notebooks_show_no_warning_stderr_or_path_list(quick_batch):
    """The student sees results only: no warning, no stderr, no ``[PosixPath(...)]`` from savefig."""
    run1, _, _, _ = quick_batch
    problems = []
    for notebook in EVERY_NOTEBOOK:
        executed = nbformat.read(run1 / "build" / "executed" / batch_selection.notebook_name(notebook), as_version=4)
        for index, cell in enumerate(executed.cells):
            if cell.cell_type != "code":
                continue
            if EXPECTED_STDERR_TAG in cell.metadata.get("tags", []):
                explained = any(line.lstrip().startswith("#") and "stderr" in line for line in cell.source.splitlines())
                if not explained:
                    problems.append(f"{notebook.name}, cell {index}: tagged {EXPECTED_STDERR_TAG!r} without a "
                                    "comment saying why it writes to stderr")
                continue
            problems += [f"{notebook.name}, cell {index}: {item}" for item in _clutter(cell)]
    assert not problems, "\n".join(problems)


#: The run-time sentence of every notebook's first cell (seconds measured by the batch runner).


def test_every_notebook_states_its_measured_run_time():
    for notebook in EVERY_NOTEBOOK:
        assert stated_seconds(notebook), f"{notebook.name}: no measured run time in the first cell"


@pytest.mark.notebook
def test_stated_quick_run_times_match_the_batch(quick_batch):
    """The quick-mode seconds the notebooks state are within 2x of what the batch measures (or 3 s).

    The stated seconds are first scaled by the ratio of the measured to the stated total, so a
    faster or busier machine than the one that measured them does not fail the test; a notebook
    whose share of the batch changed (a hand-written or stale number) does.
    """
    _, manifest, compiled, _ = quick_batch
    if compiled:
        pytest.skip("numba compiled kernels during the batch (a fresh clone or edited sources): its seconds "
                    "include compilation; .ci/run runs `make figures` first, which fills the cache")
    measured = {entry["notebook"]: entry["seconds"] for entry in manifest["notebooks"]}
    statements = {batch_selection.notebook_name(nb): stated_seconds(nb) for nb in EVERY_NOTEBOOK}
    missing = [name for name, statement in statements.items() if statement is None]
    assert not missing, f"no measured run time in the first cell of {missing}"
    stated = {name: float(statement["quick"]) for name, statement in statements.items()}
    machine_speed = sum(measured[name] for name in stated) / sum(stated.values())
    off = []
    for name, seconds in stated.items():
        expected = seconds * machine_speed
        if not (measured[name] / 2 <= expected <= 2 * measured[name] or abs(expected - measured[name]) <= 3):
            off.append(f"{name}: states {seconds:g} s in quick mode (x{machine_speed:.2f} for this machine: "
                       f"{expected:.1f} s), the batch took {measured[name]:g} s")
    assert not off, "\n".join(off) + "\n(measure again: the manifest holds each notebook's seconds)"


def test_notebook_10_runs_on_recording_files(tmp_path, monkeypatch):
    """Issue 24: notebook 10 takes ``recordings`` (files) instead of BROAD ``trials``; two simulated
    two-node recordings at 50 and 40 Hz (one with a gap in its reference and a movement column)."""
    import dataclasses

    import numpy as np
    import pandas as pd
    import papermill

    from wsnlib import reproduce
    from wsnlib.io.recording import write_recording
    from wsnlib.sim import pitch_ramp, simulate_recording

    ramp = simulate_recording(pitch_ramp(fs=50.0, duration_s=10.0), rng=np.random.default_rng(1))
    quat = ramp.quat_true.copy()
    quat[:, 300:320] = np.nan
    ramp = dataclasses.replace(ramp, quat_true=quat, movement=np.arange(ramp.n_samples)[None, :].repeat(2, 0) >= 50)
    write_recording(ramp, tmp_path / "ramp.csv")
    lift = simulate_recording(pitch_ramp(fs=40.0, duration_s=10.0, pitch_start_deg=-30.0, pitch_end_deg=80.0),
                              rng=np.random.default_rng(2))
    write_recording(lift, tmp_path / "lift.csv")
    for name, value in {**reproduce.BATCH_ENV, paths.OUTPUT_ENV_VAR: str(tmp_path / "out")}.items():
        monkeypatch.setenv(name, value)
    notebook = next(nb for nb in NOTEBOOKS if nb.name.startswith("10_"))
    executed = tmp_path / notebook.name
    papermill.execute_notebook(str(notebook), str(executed), kernel_name=paths.KERNEL_NAME, cwd=str(notebook.parent),
                               progress_bar=False, shutdown_kernel="immediate",  # as wsnlib.reproduce does
                               parameters={"quick": True, "recordings": [
                                   str(tmp_path / "ramp.csv"), str(tmp_path / "lift.json")]})
    per_trial = pd.read_csv(tmp_path / "out" / "data" / "processed" / "a10_per_trial.csv")
    assert set(per_trial["trial"]) == {"ramp/humerus", "ramp/forearm", "lift/humerus", "lift/forearm"}
    text = " ".join(output.get("data", {}).get("text/markdown", "") for cell in nbformat.read(executed, 4).cells
                    for output in cell.get("outputs", []))
    assert "at 40, 50 Hz" in text and "Settings: leave-one-recording-out" in text and "On these recordings" in text
    assert "BROAD" not in text
