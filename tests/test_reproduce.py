"""The batch runner: parameter parsing, notebook discovery and failure reporting."""

import json

import nbformat
import pytest

from wsnlib import paths, reproduce


@pytest.mark.parametrize(("text", "value"), [("3", 3), ("0.5", 0.5), ("True", True),
                                             ("[1, 2]", [1, 2]), ("madgwick", "madgwick")])
def test_parse_value(text, value):
    assert reproduce.parse_value(text) == value


def test_notebooks_are_listed_in_order():
    found = reproduce.list_notebooks()
    assert found, "no numbered notebooks found"
    assert [nb.name for nb in found] == sorted(nb.name for nb in found)
    assert reproduce.list_notebooks("no-such-notebook") == []


def test_a_failing_cell_stops_the_batch_and_is_recorded(output_dir, tmp_path, monkeypatch):
    nb_dir = tmp_path / "nbs"
    nb_dir.mkdir()
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": paths.KERNEL_NAME, "language": "python", "display_name": "x"}
    nb.metadata["language_info"] = {"name": "python"}
    params = nbformat.v4.new_code_cell("quick = False\nseed = 0")
    params.metadata["tags"] = ["parameters"]
    nb.cells = [
        params,
        nbformat.v4.new_code_cell(
            "from wsnlib import paths\n(paths.data_processed() / 'partial.csv').write_text('a\\n1\\n')"
        ),
        nbformat.v4.new_code_cell("raise RuntimeError('deliberate failure')"),
    ]
    nbformat.write(nb, nb_dir / "01_fails.ipynb")
    nbformat.write(nb, nb_dir / "02_never_runs.ipynb")
    monkeypatch.setattr(paths, "NOTEBOOKS", nb_dir)

    status = reproduce.main(["--quick"])

    assert status == 1
    manifest = json.loads((output_dir / "data" / "processed" / "manifest.json").read_text())
    first, second = manifest["notebooks"]
    assert first["status"] == "failed"
    assert first["error"]["ename"] == "RuntimeError"
    assert "deliberate" in first["error"]["evalue"]
    assert first["error"]["cell_first_line"].startswith("raise RuntimeError")
    assert [o["path"] for o in first["outputs"]] == ["data/processed/partial.csv"]
    assert second["status"] == "not run"
    assert first["parameters"] == {"quick": True}
