"""In-process memos: bounded, and cleared or turned off in one place (pbrbench.memo)."""

from __future__ import annotations

import pbrbench.memo as M


def test_a_memo_is_bounded_least_recently_used_first():
    m = M.Memo("test lru", 2)
    m["a"], m["b"] = 1, 2
    assert m["a"] == 1          # a is now the most recent
    m["c"] = 3
    assert "b" not in m and "a" in m and "c" in m and len(m) == 2


def test_clear_and_disabled_reach_every_memo_of_the_package():
    import pbrbench.radiosity.forward_models  # noqa: F401 - their memos register on import
    import pbrbench.registry
    import pbrbench.scene.load  # noqa: F401

    names = {m.name for m in M.memos()}
    assert {"radiosity scene models", "scene specs by (library, name)", "source hashes of algorithm modules"} <= names
    calls = []
    m = M.Memo("test compute", 4)
    assert m.compute("k", lambda: calls.append(1) or 7) == 7 and m.compute("k", lambda: calls.append(1) or 8) == 7
    assert calls == [1]
    pbrbench.registry._module_source_hash("pbrbench.memo", "Memo")
    with M.disabled():
        assert all(len(x) == 0 for x in M.memos())
        assert m.compute("k", lambda: calls.append(1) or 9) == 9 and "k" not in m and len(calls) == 2
    m["k"] = 1
    M.clear()
    assert "k" not in m
