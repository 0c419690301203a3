"""The batch runner: parameter parsing, notebook discovery and failure reporting."""

import ast
import gc
import json
import os
import signal
import time

import nbformat
import pandas as pd
import pytest

from wsnlib import batch_selection, paths, reproduce


def _write_notebook(path, *sources):
    """A notebook for the project kernel: a ``parameters`` cell, then one code cell per source."""
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": paths.KERNEL_NAME, "language": "python", "display_name": "x"}
    nb.metadata["language_info"] = {"name": "python"}
    params = nbformat.v4.new_code_cell("quick = False\nseed = 0")
    params.metadata["tags"] = ["parameters"]
    nb.cells = [params, *(nbformat.v4.new_code_cell(source) for source in sources)]
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)


@pytest.mark.parametrize(("text", "value"), [("3", 3), ("0.5", 0.5), ("True", True),
                                             ("[1, 2]", [1, 2]), ("madgwick", "madgwick")])
def test_parse_value(text, value):
    assert batch_selection.parse_value(text) == value


class _ParsesWhenCollected:
    """Cyclic garbage whose finalizer parses source (as formatting a traceback does in Python 3.11) and
    leaves more of the same: every collection from now on runs one."""

    def __init__(self):
        self.cycle = self

    def __del__(self):
        ast.parse("x = [1, (2, 3)]\n" * 20)
        _ParsesWhenCollected()


def test_parameters_are_parsed_while_finalizers_that_parse_wait(tmp_path):
    """A collection inside ``ast.parse`` would run such a finalizer, and a parse nested in another's
    tree construction fails ("AST constructor recursion depth mismatch", python/cpython#106905): a
    value or parameters cell large enough to start collections is parsed with the collector paused."""
    values = "[" + ", ".join(f"('a{i}', {i}.5)" for i in range(300)) + "]"
    cell = "\n".join(f"p{i} = [{i}, ({i}, 'x')]" for i in range(300))
    notebook = tmp_path / "01_big.ipynb"
    _write_notebook(notebook)
    nb = nbformat.read(notebook, as_version=4)
    nb.cells[0].source = cell
    nbformat.write(nb, notebook)
    _ParsesWhenCollected()
    try:
        for _ in range(20):
            assert batch_selection.parse_value(values)[-1] == ("a299", 299.5)
            assert batch_selection.notebook_parameters(notebook)[-1] == "p299"
    finally:
        _ParsesWhenCollected.__del__ = lambda self: None  # the chain ends
        gc.collect()


def test_notebooks_are_listed_in_order():
    found = batch_selection.list_notebooks()
    assert found, "no numbered notebooks found"
    assert [nb.name for nb in found] == sorted(nb.name for nb in found)
    assert batch_selection.list_notebooks("no-such-notebook") == []


def test_solutions_run_after_the_notebooks_with_their_own_entries(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    figure = "import matplotlib.pyplot as plt\nplt.plot([0, 1])"
    _write_notebook(nb_dir / "02_second.ipynb", figure)
    _write_notebook(nb_dir / "01_first.ipynb", "import os\nprint(os.environ['WSNLIB_BATCH'])", figure)
    _write_notebook(nb_dir / "solutions" / "01_first_solutions.ipynb",
                    "from wsnlib import paths\n(paths.data_processed() / 'answer.csv').write_text('a\\n1\\n')")
    (nb_dir / "solutions" / "notes.ipynb").write_text("{}")  # not numbered: not run
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    monkeypatch.delenv("WSNLIB_BATCH", raising=False)

    assert [batch_selection.notebook_name(nb) for nb in batch_selection.list_batch("01")] == [
        "01_first.ipynb", "solutions/01_first_solutions.ipynb"]
    assert [batch_selection.notebook_name(nb) for nb in batch_selection.list_batch("solutions")] == [
        "solutions/01_first_solutions.ipynb"]

    assert reproduce.main(["--quick"]) == 0

    manifest = json.loads((output_dir / "data" / "processed" / "manifest.json").read_text())
    entries = {e["notebook"]: e for e in manifest["notebooks"]}
    assert list(entries) == ["01_first.ipynb", "02_second.ipynb", "solutions/01_first_solutions.ipynb"]
    assert all(e["status"] == "ok" for e in entries.values())
    assert [o["path"] for o in entries["solutions/01_first_solutions.ipynb"]["outputs"]] == [
        "data/processed/answer.csv"]
    executed = output_dir / "build" / "executed"
    assert (executed / "solutions" / "01_first_solutions.ipynb").is_file()
    # The kernel saw WSNLIB_BATCH and the inline backend: the figure is in the executed copy.
    first = nbformat.read(executed / "01_first.ipynb", as_version=4)
    assert first.cells[-2].outputs[0]["text"].strip() == "1"
    assert any("image/png" in o.get("data", {}) for o in first.cells[-1].outputs)
    assert "WSNLIB_BATCH" not in os.environ  # set for the batch only


def test_a_failing_cell_stops_the_batch_and_is_recorded(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    sources = ("from wsnlib import paths\n(paths.data_processed() / 'partial.csv').write_text('a\\n1\\n')",
               "raise RuntimeError('deliberate failure')")
    _write_notebook(nb_dir / "01_fails.ipynb", *sources)
    _write_notebook(nb_dir / "02_never_runs.ipynb", *sources)
    _write_notebook(nb_dir / "solutions" / "01_fails_solutions.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    status = reproduce.main(["--quick"])

    assert status == 1
    manifest = json.loads((output_dir / "data" / "processed" / "manifest.json").read_text())
    first, second, solutions = manifest["notebooks"]
    assert first["status"] == "failed"
    assert first["error"]["ename"] == "RuntimeError"
    assert "deliberate" in first["error"]["evalue"]
    assert first["error"]["cell_first_line"].startswith("raise RuntimeError")
    assert [o["path"] for o in first["outputs"]] == ["data/processed/partial.csv"]
    assert second["status"] == "not run"
    assert solutions == {"notebook": "solutions/01_fails_solutions.ipynb", "status": "not run",
                         "parameters": {}, "seconds": None, "outputs": []}
    assert first["parameters"] == {"quick": True}


# --------------------------------------------------------------------------------------------
# Faults: a stuck cell, a dead kernel, a signal; stale outputs; bad command lines
# --------------------------------------------------------------------------------------------

_WRITE_PARTIAL = "from wsnlib import paths\n(paths.data_processed() / 'partial.csv').write_text('a\\n1\\n')"


def _manifest(output_dir):
    return json.loads((output_dir / "data" / "processed" / "manifest.json").read_text())


def test_a_stuck_cell_times_out_and_is_recorded(output_dir, tmp_path, monkeypatch, capfd):
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_stuck.ipynb", _WRITE_PARTIAL, "import time\ntime.sleep(120)")
    _write_notebook(nb_dir / "02_after.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    started = time.perf_counter()
    assert reproduce.main(["--quick", "--cell-timeout", "3"]) == 1
    assert time.perf_counter() - started < 60

    stuck, after = _manifest(output_dir)["notebooks"]
    assert stuck["status"] == "timeout"
    assert stuck["error"]["timeout_s"] == 3
    assert stuck["error"]["cell_first_line"] == "import time"
    assert [o["path"] for o in stuck["outputs"]] == ["data/processed/partial.csv"]
    assert after["status"] == "not run"
    err = capfd.readouterr().err
    assert "TIMEOUT: 01_stuck.ipynb" in err and "import time" in err
    assert "without encryption" not in err  # the kernel runs over IPC, not plain TCP


def test_a_dead_kernel_names_the_cell_and_the_files_written(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_dies.ipynb", _WRITE_PARTIAL, "import os\nos._exit(1)", "print('never')")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    assert reproduce.main(["--quick"]) == 1

    (entry,) = _manifest(output_dir)["notebooks"]
    assert entry["status"] == "failed"
    assert entry["error"]["ename"] == "DeadKernelError"
    assert entry["error"]["cell_first_line"] == "import os"
    assert [o["path"] for o in entry["outputs"]] == ["data/processed/partial.csv"]


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_a_signal_marks_the_notebook_interrupted(output_dir, tmp_path, monkeypatch, signame):
    nb_dir = tmp_path / "nbs"
    # The kernel is a child of the runner: the cell signals its parent, as `kill` or Ctrl-C would.
    _write_notebook(nb_dir / "01_killed.ipynb", _WRITE_PARTIAL,
                    f"import os, signal, time\nos.kill(os.getppid(), signal.{signame})\ntime.sleep(60)")
    _write_notebook(nb_dir / "02_after.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    before = signal.getsignal(getattr(signal, signame))

    assert reproduce.main(["--quick"]) == 128 + getattr(signal, signame)

    killed, after = _manifest(output_dir)["notebooks"]
    assert killed["status"] == "interrupted"
    assert signame in killed["error"]["evalue"]
    assert killed["error"]["cell_first_line"] == "import os, signal, time"
    assert [o["path"] for o in killed["outputs"]] == ["data/processed/partial.csv"]
    assert after["status"] == "not run"
    assert signal.getsignal(getattr(signal, signame)) == before  # handlers restored


def test_outputs_of_the_previous_run_are_moved_aside(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    write_old = "from wsnlib import paths\n(paths.figures() / 'old.png').write_bytes(b'old')"
    _write_notebook(nb_dir / "01_changes.ipynb", write_old)
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    assert reproduce.main(["--quick"]) == 0
    assert (output_dir / "figures" / "old.png").is_file()

    _write_notebook(nb_dir / "01_changes.ipynb", "raise RuntimeError('now it fails')")
    assert reproduce.main(["--quick"]) == 1

    (entry,) = _manifest(output_dir)["notebooks"]
    assert entry["status"] == "failed"
    assert entry["moved_aside"] == ["figures/old.png"]
    assert entry["outputs"] == []
    assert not (output_dir / "figures" / "old.png").exists()  # nothing stale beside the new outputs
    assert (output_dir / "build" / "stale" / "figures" / "old.png").read_bytes() == b"old"


def test_unknown_parameters_and_an_empty_only_are_refused(output_dir, tmp_path, monkeypatch, capsys):
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_first.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    with pytest.raises(SystemExit) as exit_info:
        reproduce.main(["--quick", "-p", "sede", "3"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "'sede'" in err and "01_first.ipynb" in err and "quick, seed" in err
    assert not (output_dir / "data" / "processed" / "manifest.json").exists()  # nothing ran

    with pytest.raises(SystemExit):
        reproduce.main(["--quick", "--only", ""])
    assert "--only" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        reproduce.main(["--quick", "--cell-timeout", "0"])
    assert "--cell-timeout" in capsys.readouterr().err

    assert batch_selection.notebook_parameters(nb_dir / "01_first.ipynb") == ["quick", "seed"]
    batch_selection.check_parameters(batch_selection.list_batch(), {"seed": 3})  # a known name passes


def _save(name, sleep_s=0.0):
    return (f"import time\ntime.sleep({sleep_s})\nimport pandas as pd\nfrom wsnlib.outputs import save_table\n"
            f"save_table(pd.DataFrame({{'a': [1]}}), {name!r})")


def test_notebooks_side_by_side_each_list_only_what_they_wrote(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    for i, sleep_s in enumerate((1.5, 0.0, 0.5), start=1):
        _write_notebook(nb_dir / f"0{i}_n.ipynb", _save(f"a0{i}_early"), _save(f"a0{i}_late", sleep_s))
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    assert reproduce.main(["--quick", "--jobs", "2"]) == 0

    entries = _manifest(output_dir)["notebooks"]
    assert [e["notebook"] for e in entries] == ["01_n.ipynb", "02_n.ipynb", "03_n.ipynb"]
    for i, entry in enumerate(entries, start=1):
        assert entry["status"] == "ok"
        assert [o["path"] for o in entry["outputs"]] == [f"data/processed/a0{i}_early.csv",
                                                          f"data/processed/a0{i}_late.csv"]


def _save_thread_vars(name):
    return ("import os\nimport pandas as pd\nfrom wsnlib.outputs import save_table\n"
            f"seen = {{v: [os.environ.get(v, 'unset')] for v in {reproduce.THREAD_VARS!r}}}\n"
            f"save_table(pd.DataFrame(seen), {name!r})")


@pytest.mark.parametrize("jobs", [1, 2])
def test_side_by_side_kernels_share_the_cores_thread_pools(output_dir, tmp_path, monkeypatch, jobs):
    """With --jobs N each kernel's thread pools get the cores ÷ N (at least 1), except where the user set
    a size; one job leaves them alone; the runner's own environment is as it was after the batch."""
    nb_dir = tmp_path / "nbs"
    for i in (1, 2):
        _write_notebook(nb_dir / f"0{i}_n.ipynb", _save_thread_vars(f"a0{i}_threads"))
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    for name in reproduce.THREAD_VARS:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    before = dict(os.environ)

    assert reproduce.main(["--quick", "--jobs", str(jobs)]) == 0

    assert dict(os.environ) == before
    share = str(max(1, reproduce.local_workers(-1) // 2))
    expected = {name: share if jobs == 2 else "unset" for name in reproduce.THREAD_VARS} | {"MKL_NUM_THREADS": "3"}
    for i in (1, 2):
        table = output_dir / "data" / "processed" / f"a0{i}_threads.csv"
        assert pd.read_csv(table, dtype=str, index_col=0).iloc[0].to_dict() == expected


def test_side_by_side_the_longest_stated_notebooks_start_first(tmp_path):
    def stating(name, full, quick):
        path = tmp_path / name
        _write_notebook(path, "pass")
        nb = nbformat.read(path, as_version=4)
        nb.cells.insert(0, nbformat.v4.new_markdown_cell(
            "**Run time** (measured by the batch runner, `python -m wsnlib.reproduce --jobs 2`, on a shared 2-core\n"
            f"machine in November 2026): {full} s in full mode, {quick} s in quick mode."))
        nbformat.write(nb, path)
        return path

    notebooks = [stating("01_a.ipynb", 20, 9), stating("02_b.ipynb", 300, 3), tmp_path / "03_c.ipynb",
                 stating("04_d.ipynb", 20, 30)]
    _write_notebook(notebooks[2], "pass")  # states nothing: last
    assert reproduce.longest_first(notebooks, quick=False) == [1, 0, 3, 2]  # name order among equals
    assert reproduce.longest_first(notebooks, quick=True) == [3, 0, 1, 2]


def test_side_by_side_a_failure_starts_nothing_more(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_fails.ipynb", "raise RuntimeError('deliberate failure')")
    _write_notebook(nb_dir / "02_running.ipynb", _save("a02_table", 3.0))
    _write_notebook(nb_dir / "03_waiting.ipynb", _save("a03_table"))
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    assert reproduce.main(["--quick", "--jobs", "2"]) == 1

    fails, running, waiting = _manifest(output_dir)["notebooks"]
    assert fails["status"] == "failed" and fails["error"]["evalue"] == "deliberate failure"
    assert running["status"] == "ok"  # already running: it finishes
    assert [o["path"] for o in running["outputs"]] == ["data/processed/a02_table.csv"]
    assert waiting["status"] == "not run"


def test_side_by_side_a_signal_stops_every_running_kernel(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_signals.ipynb", _save("a01_table"),
                    "import os, signal, time\ntime.sleep(1.0)\nos.kill(os.getppid(), signal.SIGTERM)\ntime.sleep(60)")
    _write_notebook(nb_dir / "02_sleeps.ipynb", "import time\ntime.sleep(60)")
    _write_notebook(nb_dir / "03_waits.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    started = time.monotonic()

    assert reproduce.main(["--quick", "--jobs", "2"]) == 128 + signal.SIGTERM

    assert time.monotonic() - started < 50  # the sleeping kernels were stopped, not waited for
    signals, sleeps, waits = _manifest(output_dir)["notebooks"]
    assert signals["status"] == sleeps["status"] == "interrupted"
    assert "SIGTERM" in sleeps["error"]["evalue"]
    assert [o["path"] for o in signals["outputs"]] == ["data/processed/a01_table.csv"]
    assert waits["status"] == "not run"
    assert all("exit_code" not in e for e in (signals, sleeps, waits))


def test_jobs_must_be_positive(output_dir, capsys):
    with pytest.raises(SystemExit):
        reproduce.main(["--quick", "--jobs", "0"])
    assert "--jobs" in capsys.readouterr().err
    with pytest.raises(ValueError, match="jobs"):
        reproduce.run([], {}, quick=True, jobs=0)


# ------------------------------------------------------------------ issue 23: concurrent and killed batches


def test_a_second_batch_on_the_same_output_folder_exits_at_once(output_dir, tmp_path, monkeypatch, capsys):
    from wsnlib import batch_manifest

    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_first.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    with batch_manifest.output_lock():  # the running batch
        started = time.perf_counter()
        assert reproduce.main(["--quick"]) == reproduce.EXIT_BATCH_RUNNING
        assert time.perf_counter() - started < 5.0
        err = capsys.readouterr().err
        assert "another batch is running" in err and f"pid {os.getpid()}" in err
        assert not (output_dir / "data" / "processed" / "manifest.json").exists()  # it touched nothing
    assert reproduce.main(["--quick"]) == 0  # free again


def test_files_of_a_killed_batch_are_moved_aside_from_its_journal(output_dir, tmp_path, monkeypatch):
    """A SIGKILLed batch wrote files that no manifest lists: its notebook's journal does."""
    import pandas as pd

    from wsnlib import _files, batch_manifest
    from wsnlib.outputs import save_table

    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_first.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    journal = batch_manifest.journal_path("01_first.ipynb")
    journal.parent.mkdir(parents=True)
    monkeypatch.setenv(_files.WRITTEN_LOG_ENV, str(journal))  # as the killed kernel had it
    written = save_table(pd.DataFrame({"a": [1]}), "a01_killed")
    monkeypatch.delenv(_files.WRITTEN_LOG_ENV)
    assert written.is_file() and not batch_manifest.manifest_path().exists()

    assert reproduce.main(["--quick"]) == 0
    (entry,) = _manifest(output_dir)["notebooks"]
    assert entry["moved_aside"] == [written.relative_to(output_dir).as_posix()]
    assert not written.exists() and not journal.exists()


def test_an_unreadable_manifest_is_said(output_dir):
    from wsnlib import batch_manifest

    path = batch_manifest.manifest_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('{"quick": true, "notebooks": [{"notebook": "01')  # cut short
    with pytest.warns(UserWarning, match="manifest.json is unreadable"):
        assert batch_manifest.previous_outputs() == {}


def test_a_run_of_some_notebooks_keeps_the_others_entries(output_dir, tmp_path, monkeypatch):
    """Issue 23: the manifest is read, merged and replaced (under the lock), not overwritten by the last run."""
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_first.ipynb", "pass")
    _write_notebook(nb_dir / "02_second.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    assert reproduce.main(["--quick", "--only", "02_second.ipynb"]) == 0
    assert reproduce.main(["--quick", "--only", "01"]) == 0
    entries = _manifest(output_dir)["notebooks"]
    assert [e["notebook"] for e in entries] == ["01_first.ipynb", "02_second.ipynb"]
    assert all(e["status"] == "ok" for e in entries)


def test_only_accepts_the_manifests_names_and_a_miss_lists_the_notebooks(output_dir, tmp_path, monkeypatch, capsys):
    """Issue 23: ``--only 02_x.ipynb`` (the manifest's own name) said "no notebook matches" and listed nothing."""
    nb_dir = tmp_path / "nbs"
    _write_notebook(nb_dir / "01_first.ipynb", "pass")
    _write_notebook(nb_dir / "02_second.ipynb", "pass")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)
    assert [nb.name for nb in batch_selection.list_batch("02_second.ipynb")] == ["02_second.ipynb"]
    with pytest.raises(SystemExit):
        reproduce.main(["--quick", "--only", "03_third.ipynb"])
    assert "the notebooks are: 01_first.ipynb, 02_second.ipynb" in capsys.readouterr().err

