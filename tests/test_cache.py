"""The on-disk memo: same key, same result; any change of arguments or source, a new computation."""

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
