"""One algorithm registry: every algorithm a benchmark task runs, built-in or a user's own.

An :class:`Algorithm` entry holds the name its scores carry, the callable, the task it serves,
a declared version plus a short hash of its source (so a changed algorithm never compares
silently with old scores), fixed options, the conditions it runs under, the calling convention
of the task it follows (``interface``; most tasks have one) and its kind:

* ``method``   -- an inference method from one of the methods tables of :mod:`pbrbench.infer`;
* ``baseline`` -- a trivial reference every method must beat (``baseline:flat``, ...);
* ``floor``    -- the best achievable score given the ground truth (``floor:true_response``, ...);
* ``plugin``   -- a user's algorithm (entry-point group ``pbrbench.algorithms`` or
  ``pbrbench run --algorithm``).

Built-in entries come from the tasks (:meth:`pbrbench.tasks.base.Task.builtin_algorithms`), which
read the methods tables: adding a method to a table adds it to the benchmark with no other edit.
Per-quality budgets (e.g. fewer iterations at draft) live in the quality profile
(:attr:`pbrbench.render.quality.Quality.algorithm_options`) and are merged by
:meth:`Algorithm.options_for`.  The callable's signature is the task's (``docs/adding.md``).
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import sys
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

KINDS = ("method", "baseline", "floor", "plugin")


def _unwrap(fn):
    while isinstance(fn, functools.partial):
        fn = fn.func
    return inspect.unwrap(fn)


@functools.lru_cache(maxsize=512)
def _module_source_hash(module_name: str, qualname: str) -> str:
    """sha256 of the source of the module defining a function (of the function alone when the
    module's source cannot be read), 10 hex digits."""
    mod = sys.modules.get(module_name)
    src = None
    if mod is not None:
        try:
            src = inspect.getsource(mod)
        except (OSError, TypeError):
            src = None
    if src is None:
        src = f"{module_name}.{qualname}"
    return hashlib.sha256(src.encode()).hexdigest()[:10]


def source_hash(fn: Callable) -> str:
    """Short hash of the source of the module that defines ``fn`` (partials unwrapped).

    The whole module, not only the function, so a change to one of its private helpers changes
    the hash too; shared helpers of other modules are not covered.
    """
    f = _unwrap(fn)
    module = getattr(f, "__module__", None) or type(f).__module__
    qual = getattr(f, "__qualname__", None) or type(f).__qualname__
    return _module_source_hash(module, qual)


def declared_version(fn: Callable) -> str:
    """``fn.version``, else the defining module's ``VERSION``, else ``"1"``."""
    f = _unwrap(fn)
    v = getattr(fn, "version", None) or getattr(f, "version", None)
    if v is None:
        mod = sys.modules.get(getattr(f, "__module__", "") or "")
        v = getattr(mod, "VERSION", None)
    return str(v) if v is not None else "1"


@dataclass(frozen=True)
class Algorithm:
    """One algorithm of one task (see the module docstring)."""

    name: str
    task: str
    fn: Callable
    kind: str = "method"
    version: str | None = None            # declared; None: from the function / its module
    options: Mapping = field(default_factory=dict)
    conditions: tuple[str, ...] | None = None   # None: every condition of the task
    description: str = ""
    origin: str = "pbrbench"              # where it came from (a module path, an entry point)
    interface: str = ""                   # which of the task's calling conventions ("": the main one)
    figures: bool = True                  # whether the report shows this algorithm's images

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Algorithm {self.name!r}: kind={self.kind!r}; use one of {', '.join(KINDS)}")
        if not self.name or not isinstance(self.name, str) or "|" in self.name:
            raise ValueError(f"Algorithm name {self.name!r}: give a non-empty name without '|'")
        if not callable(self.fn):
            raise ValueError(f"Algorithm {self.name!r}: fn is not callable")
        object.__setattr__(self, "options", MappingProxyType(dict(self.options)))

    @property
    def full_version(self) -> str:
        """``<declared>+<source hash>``: what scores record as ``algorithm_version``."""
        v = self.version if self.version is not None else declared_version(self.fn)
        return f"{v}+{source_hash(self.fn)}"

    def options_for(self, quality=None) -> dict:
        """Fixed options plus the quality profile's budget for this (task, algorithm)."""
        extra = {}
        if quality is not None:
            extra = dict(getattr(quality, "algorithm_options", {}).get(f"{self.task}/{self.name}", {}))
        return {**self.options, **extra}

    def applies(self, condition: str) -> bool:
        return self.conditions is None or condition in self.conditions

    def __call__(self, *args, quality=None, **kwargs):
        return self.fn(*args, **{**self.options_for(quality), **kwargs})

    def __reduce__(self):  # MappingProxyType does not pickle (Dask ships entries to workers)
        return (_rebuild, (self.name, self.task, self.fn, self.kind, self.version, dict(self.options),
                           self.conditions, self.description, self.origin, self.interface, self.figures))


def _rebuild(*args) -> Algorithm:
    return Algorithm(*args)


class Registry:
    """Algorithms by (task, name), in registration order."""

    def __init__(self, entries: Iterable[Algorithm] = ()):
        self._entries: dict[tuple[str, str], Algorithm] = {}
        for e in entries:
            self.add(e)

    def add(self, alg: Algorithm, *, replace: bool = False) -> Algorithm:
        key = (alg.task, alg.name)
        if key in self._entries and not replace:
            old = self._entries[key]
            raise ValueError(f"algorithm {alg.name!r} of task {alg.task!r} is registered twice "
                             f"({old.origin} and {alg.origin}); give one of them another name")
        self._entries[key] = alg
        return alg

    def for_task(self, task: str, *, kinds: Iterable[str] | None = None) -> list[Algorithm]:
        ks = tuple(kinds) if kinds is not None else KINDS
        return [a for (t, _), a in self._entries.items() if t == task and a.kind in ks]

    def get(self, task: str, name: str) -> Algorithm:
        try:
            return self._entries[(task, name)]
        except KeyError:
            names = ", ".join(a.name for a in self.for_task(task)) or "none"
            raise KeyError(f"task {task!r} has no algorithm {name!r}; it has {names}") from None

    def tasks(self) -> list[str]:
        return list(dict.fromkeys(t for t, _ in self._entries))

    def __iter__(self):
        return iter(self._entries.values())

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key) -> bool:
        return key in self._entries


def builtin_registry(tasks: Mapping) -> Registry:
    """The built-in algorithms of ``tasks`` (name -> Task), in each task's order."""
    reg = Registry()
    for task in tasks.values():
        for alg in task.builtin_algorithms():
            reg.add(alg)
    return reg
