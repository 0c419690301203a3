"""The on-disk memo: same key, same result; any change of arguments or source, a new computation."""

import os
from pathlib import Path

import numpy as np
import pytest

from wsnlib import cache, paths


@pytest.fixture(autouse=True)
def output_dir(tmp_path, monkeypatch):
    monkeypatch.setenv(paths.OUTPUT_ENV_VAR, str(tmp_path))
    return tmp_path


def test_computes_once_then_reads(output_dir):
    calls = []

    def compute(seed, size):
        calls.append(seed)
        return np.random.default_rng(seed).normal(size=size)

    first = cache.cached("draws", {"seed": 3, "size": 5}, compute)
    second = cache.cached("draws", {"seed": 3, "size": 5}, compute)
    np.testing.assert_array_equal(first, second)
    assert calls == [3]
    other = cache.cached("draws", {"seed": 4, "size": 5}, compute)
    assert calls == [3, 4] and not np.array_equal(first, other)
    assert len(list((output_dir / "build" / "cache").glob("draws-*.pkl"))) == 2


def test_the_key_covers_name_arguments_and_source(monkeypatch):
    key = cache.cache_key("a", {"x": 1})
    assert key != cache.cache_key("b", {"x": 1}) and key != cache.cache_key("a", {"x": 2})
    monkeypatch.setattr(cache, "source_hash", lambda: "changed")
    assert key != cache.cache_key("a", {"x": 1})


@pytest.mark.parametrize(("name", "arguments"), [("a b", {}), ("ok", {"rng": object()}), ("ok", {"x": float("nan")})])
def test_bad_keys_are_rejected(name, arguments):
    with pytest.raises(ValueError, match="name|arguments"):
        cache.cached(name, arguments, lambda **kw: None)


def test_dynamic_campaign_is_the_seeded_simulation():
    from wsnlib.sim.campaign import dynamic_campaign, simulate_dynamic_campaign

    direct = simulate_dynamic_campaign(1, rng=np.random.default_rng(7), hold_s=2.0)
    for _ in range(2):  # computed, then read back
        memo = dynamic_campaign(1, seed=7, hold_s=2.0)
        np.testing.assert_array_equal(memo.data.rss, direct.data.rss)
        np.testing.assert_array_equal(memo.acc.to_numpy(), direct.acc.to_numpy())
    with pytest.raises(ValueError, match="seed"):
        dynamic_campaign(1, seed=np.random.default_rng(7), hold_s=2.0)


@pytest.mark.parametrize("damage", ["empty", "truncated", "garbage"])
def test_an_unreadable_file_is_named_and_computed_again(output_dir, damage):
    """Issue 23: a raw UnpicklingError/EOFError told the user nothing."""
    first = cache.cached("draws", {"seed": 3}, lambda seed: np.arange(seed, seed + 100.0))
    (path,) = (output_dir / "build" / "cache").glob("draws-*.pkl")
    data = path.read_bytes()
    path.write_bytes({"empty": b"", "truncated": data[: len(data) // 2], "garbage": b"not a pickle"}[damage])
    with pytest.warns(UserWarning, match=rf"{path.name}: unreadable cache file.*computing draws again"):
        again = cache.cached("draws", {"seed": 3}, lambda seed: np.arange(seed, seed + 100.0))
    np.testing.assert_array_equal(again, first)
    assert path.read_bytes() == data  # stored anew


def test_the_key_is_the_source_this_process_imported(tmp_path):
    """Issue 23: a kernel left open across an edit must not file its (old code's) result under
    the edited source's key, which a fresh process would then read."""
    import shutil
    import subprocess
    import sys

    import wsnlib

    copy = tmp_path / "wsnlib"
    shutil.copytree(Path(wsnlib.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nb[ic]"))
    script = (
        "import sys, pathlib; import wsnlib.cache as c\n"
        "if sys.argv[1] == 'edit':\n"
        "    p = pathlib.Path(c.__file__).with_name('paths.py'); p.write_text(p.read_text() + '# edited\\n')\n"
        "print(c.cache_key('x', {}))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}

    def key(mode):
        return subprocess.run([sys.executable, "-c", script, mode], env=env, cwd=tmp_path, capture_output=True,
                              text=True, check=True).stdout.strip()

    old = key("none")
    kept_open = key("edit")  # imported, then the source changes under it
    fresh = key("none")  # a process that imports the edited source
    assert kept_open == old and fresh != old
