"""Run times in the notebooks come from the batch manifests, not from the keyboard."""

import json

import nbformat
import pytest

from wsnlib import paths, run_times

INTRO = ("# Title\n\n**Run time** (measured by the batch runner, `python -m wsnlib.reproduce`, on a shared 2-core\n"
         "machine in May 2020): 1 s in full mode, 2 s in quick mode.\n\nMore text.")


@pytest.fixture
def notebooks(tmp_path, monkeypatch):
    folder = tmp_path / "notebooks"
    folder.mkdir()
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_markdown_cell(INTRO), nbformat.v4.new_code_cell("x = 1")])
    nbformat.write(nb, folder / "01_a.ipynb")
    monkeypatch.setattr(paths, "NOTEBOOKS", folder)
    return folder


def _manifest(path, seconds, status="ok"):
    path.write_text(json.dumps({"notebooks": [{"notebook": "01_a.ipynb", "seconds": seconds, "status": status}]}))
    return path


def test_the_sentence_takes_the_manifests_seconds(notebooks, tmp_path):
    full, quick = _manifest(tmp_path / "f.json", 61.4), _manifest(tmp_path / "q.json", 7.6)
    assert run_times.update_run_times(full, quick, month="November 2026") == ["01_a.ipynb"]
    intro = nbformat.read(notebooks / "01_a.ipynb", as_version=4).cells[0].source
    assert "machine in November 2026): 61 s in full mode, 8 s in quick mode." in intro
    assert intro.startswith("# Title") and intro.endswith("More text.")
    assert run_times.update_run_times(full, quick, month="November 2026") == []  # nothing left to change


def test_a_failed_run_or_a_missing_sentence_is_refused(notebooks, tmp_path, capsys):
    with pytest.raises(ValueError, match="not every notebook ran ok"):
        run_times.update_run_times(_manifest(tmp_path / "f.json", 3, "failed"), _manifest(tmp_path / "q.json", 1))
    nb = nbformat.read(notebooks / "01_a.ipynb", as_version=4)
    nb.cells[0].source = "# Title"
    nbformat.write(nb, notebooks / "01_a.ipynb")
    with pytest.raises(ValueError, match="no run-time sentence"):
        run_times.update_run_times(_manifest(tmp_path / "f.json", 3), _manifest(tmp_path / "q.json", 1))
    with pytest.raises(SystemExit):  # the command line names a missing manifest (no traceback)
        run_times.main([str(tmp_path / "f.json"), str(tmp_path / "missing.json")])
    assert "missing.json: no such file" in capsys.readouterr().err


def test_side_by_side_runs_are_named_in_the_sentence(notebooks, tmp_path):
    def manifest(path, seconds, jobs):
        path.write_text(json.dumps({"jobs": jobs, "notebooks": [
            {"notebook": "01_a.ipynb", "seconds": seconds, "status": "ok"}]}))
        return path

    run_times.update_run_times(manifest(tmp_path / "f.json", 20, 2), manifest(tmp_path / "q.json", 5, 2),
                               month="November 2026")
    intro = nbformat.read(notebooks / "01_a.ipynb", as_version=4).cells[0].source
    assert "`python -m wsnlib.reproduce --jobs 2`, on a shared 2-core\nmachine in November 2026): 20 s" in intro
    with pytest.raises(ValueError, match="different --jobs"):
        run_times.update_run_times(manifest(tmp_path / "f.json", 20, 2), manifest(tmp_path / "q.json", 5, 1))
