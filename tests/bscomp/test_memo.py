"""bscomp.memo.kept: the bounded memo the engine keeps its modal models, FRFs and simulators in."""

import pytest

from bscomp.memo import kept


def test_kept_builds_once_while_kept_and_drops_the_first_inserted_beyond_its_size():
    cache, built = {}, []

    def make(k):
        built.append(k)
        return k * 10

    assert [kept(cache, k, lambda k=k: make(k), 3) for k in (1, 2, 1, 3, 4, 1)] == [10, 20, 10, 30, 40, 10]
    assert built == [1, 2, 3, 4, 1]            # 1 met again while kept, then dropped at 4 (first inserted) and rebuilt
    assert list(cache) == [3, 4, 1]


def test_a_build_that_raises_leaves_the_memo_as_it_was():
    cache = {"a": 1, "b": 2}

    def fail():
        raise RuntimeError("no")

    with pytest.raises(RuntimeError):
        kept(cache, "c", fail, 2)
    assert cache == {"a": 1, "b": 2}
