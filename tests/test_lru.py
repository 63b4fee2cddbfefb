"""The one in-memory LRU: bounded, least recently used out, hits and misses counted."""

import pytest

from sensors._infra.lru import CACHE_SIZES, LRU


def test_lru_drops_the_least_recently_used_entry():
    cache = LRU(2)
    cache.put("a", 1)
    cache.put("b", 2)
    assert cache.get("a") == 1           # "a" is now the most recent
    cache.put("c", 3)                    # so "b" goes
    assert "b" not in cache and "a" in cache and "c" in cache and len(cache) == 2
    built = []
    assert cache.get_or_build("d", lambda: built.append(1) or 4) == 4
    assert cache.get_or_build("d", lambda: built.append(1) or 5) == 4
    assert built == [1] and cache.hits == 2 and cache.misses == 1


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "8", None])
def test_lru_refuses_a_size_that_is_not_a_whole_positive_number(bad):
    with pytest.raises(ValueError, match="max_size"):
        LRU(bad)


def test_every_named_size_is_a_usable_bound():
    assert CACHE_SIZES and all(LRU(n).max_size == n for n in CACHE_SIZES.values())
