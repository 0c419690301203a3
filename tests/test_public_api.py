"""Users' scripts keep working: every public name of every module at commit f52b355 (before the
issue-13 restructuring) still imports from the same path.

``tests/data/public_api_f52b355.json`` lists, per module, its ``__all__`` or else the names
that module itself defined (functions, classes, top-level assignments), read from that commit.
A name may have moved (the old path then re-exports it), but it may not disappear silently.
"""

import importlib
import json
from pathlib import Path

import pytest

API = json.loads((Path(__file__).parent / "data" / "public_api_f52b355.json").read_text(encoding="utf-8"))


def test_the_snapshot_is_not_empty():
    assert len(API) > 50 and sum(map(len, API.values())) > 600


@pytest.mark.parametrize("module", sorted(API))
def test_old_public_names_still_import(module):
    imported = importlib.import_module(module)
    assert [name for name in API[module] if not hasattr(imported, name)] == []
