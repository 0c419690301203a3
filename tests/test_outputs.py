import pandas as pd
import pytest

from wsnlib import paths
from wsnlib.outputs import save_table


def test_save_table_writes_processed_csv_atomically(tmp_path, monkeypatch):
    monkeypatch.setenv(paths.OUTPUT_ENV_VAR, str(tmp_path))
    path = save_table(pd.DataFrame({"a": [1.5, 2.0]}), "a00_demo", index=False)
    assert path == tmp_path / "data" / "processed" / "a00_demo.csv"
    assert path.read_text() == "a\n1.5\n2.0\n"
    assert [p.name for p in path.parent.iterdir()] == ["a00_demo.csv"]  # no temporary file left


@pytest.mark.parametrize(("frame", "name", "match"), [(pd.DataFrame(), "../x", "name"), ([1, 2], "ok", "frame")])
def test_save_table_rejects_bad_arguments(tmp_path, monkeypatch, frame, name, match):
    monkeypatch.setenv(paths.OUTPUT_ENV_VAR, str(tmp_path))
    with pytest.raises(ValueError, match=match):
        save_table(frame, name)
