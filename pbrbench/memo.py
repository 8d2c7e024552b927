"""In-process memos: one mechanism for every cache the package keeps in memory.

A :class:`Memo` is a named, bounded mapping (least recently used entries dropped first).  Every
memo registers itself here, so :func:`clear` empties all of them and :func:`disabled` turns them
all off (nothing is stored, every lookup misses) -- in one place, e.g. to time a cold path or to
make sure a test computes what it checks.  On-disk caches (renders, form factors, jobs) are
separate: they have their own directories and the ``--cache`` setting.

Only the standard library.
"""

from __future__ import annotations

import contextlib
import threading
from collections import OrderedDict

_ALL: list[Memo] = []
_STATE = {"enabled": True}
_LOCK = threading.RLock()


class Memo:
    """A bounded in-process cache named ``name`` (``maxsize`` entries; ``None``: unbounded).

    Use it as a mapping (``key in memo``, ``memo[key]``, ``memo[key] = value``, ``memo.get``) or
    through :meth:`compute`.  While memos are :func:`disabled`, nothing is stored."""

    def __init__(self, name: str, maxsize: int | None = 256):
        self.name, self.maxsize = name, maxsize
        self._d: OrderedDict = OrderedDict()
        with _LOCK:
            _ALL.append(self)

    def __contains__(self, key) -> bool:
        return _STATE["enabled"] and key in self._d

    def __getitem__(self, key):
        with _LOCK:
            v = self._d[key]
            self._d.move_to_end(key)
            return v

    def get(self, key, default=None):
        return self[key] if key in self else default

    def __setitem__(self, key, value) -> None:
        if not _STATE["enabled"]:
            return
        with _LOCK:
            self._d[key] = value
            self._d.move_to_end(key)
            while self.maxsize is not None and len(self._d) > self.maxsize:
                self._d.popitem(last=False)

    def update(self, items) -> None:
        for k, v in dict(items).items():
            self[k] = v

    def compute(self, key, fn):
        """``self[key]``, computing it with ``fn()`` (and keeping it) when it is missing."""
        if key in self:
            return self[key]
        v = fn()
        self[key] = v
        return v

    def __len__(self) -> int:
        return len(self._d)

    def clear(self) -> None:
        with _LOCK:
            self._d.clear()

    def __repr__(self) -> str:
        return f"Memo({self.name!r}, {len(self._d)}/{self.maxsize} entries)"


def memos() -> list[Memo]:
    """Every memo of this process."""
    return list(_ALL)


def clear() -> None:
    """Empty every memo."""
    for m in memos():
        m.clear()


@contextlib.contextmanager
def disabled():
    """Within the block every memo is empty and stores nothing (they are cleared on entry)."""
    old = _STATE["enabled"]
    clear()
    _STATE["enabled"] = False
    try:
        yield
    finally:
        _STATE["enabled"] = old
