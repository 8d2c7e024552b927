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
(:attr:`Algorithm.budgets`, by quality profile name) and are merged by
:meth:`Algorithm.options_for`; an entry also carries its cost note, the entry it is a variant of,
whether it takes a seed and a predicate on the jobs it runs on, and :meth:`Algorithm.check`
validates every key when the registry is built.  The callable's signature is the task's (``docs/adding.md``).

Plugins (``docs/plugins.md``) are added by :func:`pbrbench.plugins.plugin_registry`: the built-ins, then every
entry point of the group :data:`ENTRY_POINT_GROUP` and every ``--algorithm`` spec
``TASK=MODULE:FUNCTION[:NAME]`` (:func:`parse_algorithm_spec`).  An entry point names either a
``register(registry)`` function, which receives a :class:`PluginRegistry` and adds entries, or an
algorithm callable (entry-point name ``TASK:NAME``, or a callable marked with :func:`algorithm`).
Plugin entries are kind ``plugin``, carry their version (declared, else ``"1"``) and the hash of
their source (a plugin file's bytes, else its module's source), frozen when they are loaded.  No
plugin code runs in the benchmark process: a plugin is imported and registered in the isolated
child, with the load time limit (:mod:`pbrbench.plugins`), and its entries' callables are
references (:class:`pbrbench.plugins.PluginFunction`) called in that child with the run's time
limit per job (:mod:`pbrbench.isolation`), so a plugin that hangs, exits or crashes, at import or
when called, is scored as failed and the run goes on.  With ``time_limit=None`` (``--algorithm-time-limit 0``)
the plugin is called in this process, on copies of its inputs.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import sys
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType

from pbrbench.errors import UserError
from pbrbench.memo import Memo

KINDS = ("method", "baseline", "floor", "plugin")
ENTRY_POINT_GROUP = "pbrbench.algorithms"
DEFAULT_TIME_LIMIT = 600.0   # seconds per plugin per job (all its calls of the job together)


def _unwrap(fn):
    while isinstance(fn, functools.partial):
        fn = fn.func
    return inspect.unwrap(fn)


_SOURCE_HASHES = Memo("source hashes of algorithm modules", 512)


def _module_source_hash(module_name: str, qualname: str) -> str:
    """sha256 of the source of the module defining a function (of the function alone when the
    module's source cannot be read), 10 hex digits (memoised)."""
    return _SOURCE_HASHES.compute((module_name, qualname), lambda: _source_hash_of(module_name, qualname))


# the packages whose modules are the algorithms' code: a helper module of these that an algorithm's
# module imports (photometric stereo's shared solvers, the Poisson integrator) is part of its version
HELPER_PACKAGES = ("pbrbench.infer", "pbrbench.inverse", "pbrbench.radiosity")
NOT_CODE = ("pbrbench.infer._docstring",)   # the shared docstring fragments: no number depends on them


def _module_source(module_name: str) -> str | None:
    """The source of ``module_name`` (imported if it is a helper module not imported yet), or None."""
    mod = sys.modules.get(module_name)
    if mod is None and _in_helpers(module_name):
        import importlib

        try:
            mod = importlib.import_module(module_name)
        except ImportError:
            return None
    if mod is None:
        return None
    try:
        return inspect.getsource(mod)
    except (OSError, TypeError):
        return None


def _in_helpers(name: str) -> bool:
    return name not in NOT_CODE and any(name == p or name.startswith(p + ".") for p in HELPER_PACKAGES)


def _imported_module(module: str, name: str) -> str:
    """The module that defines what ``from module import name`` binds (``module`` itself for a
    constant, a package's submodule for a function it re-exports)."""
    import importlib

    try:
        obj = getattr(importlib.import_module(module), name)
    except AttributeError:   # a submodule its package does not import itself (``from pkg import sub``)
        try:
            return importlib.import_module(f"{module}.{name}").__name__
        except ImportError:
            return module
    except ImportError:
        return module
    if inspect.ismodule(obj):
        return obj.__name__
    owner = getattr(obj, "__module__", None) if (inspect.isfunction(obj) or inspect.isclass(obj)) else None
    return owner if isinstance(owner, str) and _in_helpers(owner) else module


@functools.lru_cache(maxsize=512)
def _direct_helpers(src: str) -> tuple[str, ...]:
    """The helper modules the imports of the module source ``src`` name (parsed once per source:
    every algorithm of a package reaches the same helpers)."""
    import ast

    out = []
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.ImportFrom) and not node.level and node.module and _in_helpers(node.module):
            out += [_imported_module(node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [a.name for a in node.names if _in_helpers(a.name)]
    return tuple(out)


def helper_modules(module_name: str) -> list[str]:
    """The modules of :data:`HELPER_PACKAGES` that ``module_name``'s imports reach, directly or
    through each other (``module_name`` left out), sorted: the code an algorithm runs beyond its
    own module."""
    seen: set[str] = set()
    todo = [module_name]
    while todo:
        src = _module_source(todo.pop())
        for t in _direct_helpers(src) if src is not None else ():
            if t != module_name and t not in seen:
                seen.add(t)
                todo.append(t)
    return sorted(seen)


def _source_hash_of(module_name: str, qualname: str) -> str:
    src = _module_source(module_name)
    h = hashlib.sha256((src if src is not None else f"{module_name}.{qualname}").encode()).hexdigest()[:10]
    # an algorithm module's helpers (a task module's baselines and wrappers are hashed by their own
    # module, and a wrapper by the methods it binds)
    helpers = helper_modules(module_name) if src is not None and _in_helpers(module_name) else []
    if not helpers:    # a module that imports no helper: the hash of its source alone, as it always was
        return h
    parts = [h] + [f"{m}={hashlib.sha256((_module_source(m) or m).encode()).hexdigest()[:10]}" for m in helpers]
    return hashlib.sha256(":".join(parts).encode()).hexdigest()[:10]


def source_hash(fn: Callable) -> str:
    """Short hash of the source of the module that defines ``fn`` (partials unwrapped) and of the
    callables a partial binds (``functools.partial(with_estimated_light, method=kimmel2001)``
    changes with ``kimmel2001``'s module as well as with its own).

    The whole module, not only the function, so a change to one of its private helpers changes
    the hash too; and for a module of :data:`HELPER_PACKAGES`, every module of those packages its
    imports reach (:func:`helper_modules`: ``photometric_stereo._common``'s batched solvers, the
    Poisson integrator, and another method it calls: zheng_chellappa1991's horn1989, inverse
    rendering's woodham1980 and nayar1991 starts), so a change to code a method runs changes its
    version.
    """
    f = _unwrap(fn)
    module = getattr(f, "__module__", None) or type(f).__module__
    qual = getattr(f, "__qualname__", None) or type(f).__qualname__
    h = _module_source_hash(module, qual)
    deps = _bound_callables(fn)
    if not deps:   # the hash of a plain function (or a partial binding only values) as it always was
        return h
    return hashlib.sha256(":".join([h, *(source_hash(d) for d in deps)]).encode()).hexdigest()[:10]


def pipeline_hash(fn: Callable, *steps: Callable) -> str:
    """The source hash of ``fn`` joined with those of the ``steps`` a task applies to its output
    (the HDR task merges every calibration's response with a merge method): the fingerprint of a
    built-in entry whose scores depend on those steps' code as well as its own."""
    return hashlib.sha256(":".join([source_hash(fn), *(source_hash(s) for s in steps)]).encode()).hexdigest()[:10]


def _bound_callables(fn) -> list:
    """The callables bound as arguments by ``fn``'s partials (outermost first; keywords by name)."""
    out = []
    while isinstance(fn, functools.partial):
        out += [v for v in fn.args if callable(v)]
        out += [fn.keywords[k] for k in sorted(fn.keywords) if callable(fn.keywords[k])]
        fn = fn.func
    return out


def declared_version(fn: Callable) -> str:
    """``fn.version``, else the defining module's ``VERSION``, else ``"1"``."""
    f = _unwrap(fn)
    v = getattr(fn, "version", None) or getattr(f, "version", None)
    if v is None:
        mod = sys.modules.get(getattr(f, "__module__", "") or "")
        v = getattr(mod, "VERSION", None)
    return str(v) if v is not None else "1"


class PluginLoadError(RuntimeError):
    """The plugin could not be imported or registered (its entries are scored as failed)."""


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
    fingerprint: str | None = None        # source hash frozen at load time (plugins) or joined with the task's
    # steps on its output (registry.pipeline_hash: HDR's merge); None: computed
    time_limit: float | None = None       # seconds; set: each call runs in a child process (isolation)
    budgets: Mapping = field(default_factory=dict)   # quality profile name -> options at that profile
    cost_note: str = ""                   # why it takes the time it takes (the report shows it)
    variant_of: str | None = None         # the entry this one wraps (e.g. with an estimated light)
    seeded: bool = False                  # it takes ``seed`` (Monte Carlo, random starts)
    applies_to: Callable | None = None    # (job, quality) -> bool: whether it runs on a job (with conditions)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Algorithm {self.name!r}: kind={self.kind!r}; use one of {', '.join(KINDS)}")
        if not self.name or not isinstance(self.name, str) or "|" in self.name:
            raise ValueError(f"Algorithm name {self.name!r}: give a non-empty name without '|'")
        if not callable(self.fn):
            raise ValueError(f"Algorithm {self.name!r}: fn is not callable")
        if self.time_limit is not None and not float(self.time_limit) > 0:
            raise ValueError(f"Algorithm {self.name!r}: time_limit={self.time_limit!r}; give seconds > 0 or None")
        object.__setattr__(self, "options", MappingProxyType(dict(self.options)))
        object.__setattr__(self, "budgets", MappingProxyType({str(q): MappingProxyType(dict(o))
                                                              for q, o in dict(self.budgets).items()}))

    @property
    def full_version(self) -> str:
        """``<declared>+<source hash>``: what scores record as ``algorithm_version``."""
        v = self.version if self.version is not None else declared_version(self.fn)
        return f"{v}+{self.fingerprint or source_hash(self.fn)}"

    def options_for(self, quality=None) -> dict:
        """Fixed options plus this entry's budget at the quality profile ``quality``."""
        extra = dict(self.budgets.get(quality.name, {})) if quality is not None else {}
        return {**self.options, **extra}

    def applies(self, condition: str) -> bool:
        return self.conditions is None or condition in self.conditions

    def applies_to_job(self, job, quality=None) -> bool:
        """Whether it runs on ``job``: its conditions, then its own predicate (``applies_to``)."""
        return self.applies(job.condition) and (self.applies_to is None or bool(self.applies_to(job, quality)))

    def check(self, profiles) -> None:
        """Refuse an entry whose metadata does not fit: a budget for an unknown quality profile, or a
        fixed or budget option its callable does not take (``ValueError`` naming the key)."""
        unknown = [q for q in self.budgets if q not in profiles]
        if unknown:
            raise ValueError(f"algorithm {self.task}/{self.name}: budgets for unknown quality profile(s) "
                             f"{', '.join(unknown)}; use {', '.join(profiles)}")
        try:
            params = inspect.signature(_unwrap(self.fn)).parameters
        except (TypeError, ValueError):
            return
        if any(p.kind is p.VAR_KEYWORD for p in params.values()):
            return
        bound = set(self.fn.keywords) if isinstance(self.fn, functools.partial) else set()
        for where, opts in [("options", self.options), *((f"budgets[{q}]", o) for q, o in self.budgets.items())]:
            bad = [k for k in opts if k not in params and k not in bound]
            if bad:
                raise ValueError(f"algorithm {self.task}/{self.name}: {where} {', '.join(bad)} is not a parameter of "
                                 f"{getattr(_unwrap(self.fn), '__name__', self.fn)}; fix the key")

    def __call__(self, *args, quality=None, **kwargs):
        kw = {**self.options_for(quality), **kwargs}
        broken = getattr(self.fn, "load_error", None)
        if broken:                      # a plugin that failed to load: no process to start
            raise PluginLoadError(broken)
        if self.time_limit is not None:
            from pbrbench.isolation import call_isolated

            return call_isolated(self.fn, args, kw, time_limit=self.time_limit, name=self.name)
        if self.kind == "plugin":       # in-process: the plugin gets copies, the other algorithms' inputs stay
            import copy

            args, kw = copy.deepcopy((args, kw))
            try:
                return self.fn(*args, **kw)
            except SystemExit as e:
                raise RuntimeError(f"{self.name} called sys.exit({e.code!r}); the run goes on") from None
        return self.fn(*args, **kw)

    def __reduce__(self):  # MappingProxyType does not pickle (Dask ships entries to workers)
        return (_rebuild, (self.name, self.task, _portable(self.fn), self.kind, self.version, dict(self.options),
                           self.conditions, self.description, self.origin, self.interface, self.figures,
                           self.fingerprint, self.time_limit, {q: dict(o) for q, o in self.budgets.items()},
                           self.cost_note, self.variant_of, self.seeded, self.applies_to))


class _ByValue:
    """A callable pickled by value (cloudpickle): a plugin file loaded by path, a closure or a
    lambda, which another process (a Dask worker) could not import by name."""

    def __init__(self, data: bytes):
        self.data = data


def _portable(fn):
    f = _unwrap(fn)
    mod = getattr(f, "__module__", None)
    qual = getattr(f, "__qualname__", "") or ""
    if not (mod in _PATH_MODULES or mod == "__main__" or "<locals>" in qual or "<lambda>" in qual):
        return fn
    try:
        import cloudpickle
    except ImportError:  # pragma: no cover - cloudpickle ships with pbrbench's dependencies
        return fn
    for m in {mod, getattr(getattr(fn, "func", None), "__module__", None)} & set(_PATH_MODULES):
        if m in sys.modules:
            cloudpickle.register_pickle_by_value(sys.modules[m])
    return _ByValue(cloudpickle.dumps(fn))


def _rebuild(name, task, fn, *rest) -> Algorithm:
    if isinstance(fn, _ByValue):
        import pickle

        fn = pickle.loads(fn.data)
    return Algorithm(name, task, fn, *rest)


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

    def remove(self, task: str, name: str) -> None:
        self._entries.pop((task, name), None)

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
    from pbrbench.quality import PRESETS

    reg = Registry()
    for task in tasks.values():
        for alg in task.builtin_algorithms():
            alg.check(PRESETS)      # every metadata key validated before anything runs
            reg.add(alg)
    return reg


# ----------------------------------------------------------------------------------- plugins
_PATH_MODULES: dict[str, str] = {}   # module name -> file, for plugin files loaded by path


def path_module_file(module_name: str) -> str | None:
    """The file a plugin module was loaded from by path (None for an importable module)."""
    return _PATH_MODULES.get(module_name)


def algorithm(task: str, name: str | None = None, *, version: str | None = None, **options):
    """Mark a function as a pbrbench algorithm, so an entry point may point straight at it::

        @algorithm("photometric_stereo", "mine", version="2")
        def solve(images, lights, *, mask=None): ...

    (``[project.entry-points."pbrbench.algorithms"] mine = "mypkg.ps:solve"``).  ``options``
    are fixed keyword options passed at every call."""
    def mark(fn):
        fn.pbrbench_task = task
        fn.pbrbench_name = name or fn.__name__
        fn.pbrbench_version = version
        fn.pbrbench_options = dict(options)
        return fn
    return mark


def _task_name(task: str) -> str:
    return str(task).strip().replace("-", "_")


class PluginRegistry:
    """What a plugin's ``register(registry)`` function receives: it adds algorithms with
    :meth:`add` (or the :meth:`algorithm` decorator); ``tasks`` lists the tasks of this run.

    Entries for a task that is not part of the run are ignored (so one package can serve every
    task); an entry for a task that pbrbench does not have (not in ``known``, when given) is
    recorded in ``unknown`` (a mistyped name, reported in one line).  Every entry is kind
    ``plugin`` with the plugin's origin, its source hash frozen now, and the run's time limit."""

    def __init__(self, registry: Registry, tasks: Iterable[str], *, origin: str, time_limit: float | None,
                 strict: bool = True, known: Iterable[str] = ()):
        self._registry = registry
        self.tasks = tuple(tasks)
        self.known = tuple(known)
        self.unknown: list[str] = []
        self._origin = origin
        self._time_limit = time_limit
        self._strict = strict
        self.added: list[Algorithm] = []
        self.skipped: list[str] = []

    def add(self, task, name: str | None = None, fn: Callable | None = None, *, version: str | None = None,
            options: Mapping | None = None, conditions=None, description: str = "", interface: str = "",
            figures: bool = True) -> Algorithm | None:
        """Add ``fn`` as algorithm ``name`` of ``task`` (or pass a ready :class:`Algorithm` as the
        only argument).  Returns the entry, or None when the task is not part of this run."""
        if isinstance(task, Algorithm):
            alg = task
            if alg.kind != "plugin" or alg.origin == "pbrbench":
                alg = replace(alg, kind="plugin", origin=self._origin)
        else:
            if fn is None or not callable(fn):
                raise ValueError(f"{self._origin}: add({task!r}, {name!r}, fn): fn must be a callable")
            task = _task_name(task)
            alg = Algorithm(name or fn.__name__, task, fn, kind="plugin", version=version, options=dict(options or {}),
                            conditions=tuple(conditions) if conditions is not None else None,
                            description=description, origin=self._origin, interface=interface, figures=figures)
        if alg.task not in self.tasks:
            if self.known and alg.task not in self.known:
                self.unknown.append(f"{alg.name!r} is registered for task {alg.task!r}")
            self.skipped.append(f"{alg.name} (task {alg.task!r} is not in this run)")
            return None
        if alg.version is None:
            alg = replace(alg, version=declared_version(alg.fn))
        alg = replace(alg, fingerprint=alg.fingerprint or source_hash(alg.fn),
                      time_limit=alg.time_limit if alg.time_limit is not None else self._time_limit)
        if (alg.task, alg.name) in self._registry:
            old = self._registry.get(alg.task, alg.name)
            raise ValueError(f"{self._origin}: algorithm {alg.name!r} of task {alg.task!r} is already registered "
                             f"({old.origin}); give it another name")
        self._registry.add(alg)
        self.added.append(alg)
        return alg

    def algorithm(self, task: str, name: str | None = None, **kw):
        """Decorator form of :meth:`add`."""
        def deco(fn):
            self.add(task, name, fn, **kw)
            return fn
        return deco


def is_path(module: str) -> bool:
    return module.endswith(".py") or "/" in module or os.sep in module


def parse_algorithm_spec(spec: str) -> tuple[str, str, str, str | None]:
    """``TASK=MODULE:FUNCTION[:NAME]`` -> (task, module, function, name or None).  MODULE is a
    dotted module or a path to a ``.py`` file; FUNCTION may be dotted (``Class.method``)."""
    task, sep, rest = str(spec).partition("=")
    hint = ("write TASK=MODULE:FUNCTION[:NAME], e.g. photometric_stereo=./mine.py:solve "
            "or photometric_stereo=mypkg.ps:solve:mine")
    if not sep or not task.strip() or not rest:
        raise UserError(f"--algorithm {spec!r}: {hint}")
    i = rest.find(".py:")
    if i >= 0:
        module, tail = rest[:i + 3], rest[i + 4:]
    else:
        module, _, tail = rest.partition(":")
    func, _, name = tail.partition(":")
    if not module or not func or ":" in name:
        raise UserError(f"--algorithm {spec!r}: {hint}")
    return _task_name(task), module, func, (name or None)


def normalize_algorithm_spec(spec: str) -> str:
    """The spec with a plugin file's path made absolute (stored with a run, so ``--resume``
    reloads it from any directory)."""
    task, module, func, name = parse_algorithm_spec(spec)
    if is_path(module):
        module = str(Path(module).expanduser().resolve())
    return f"{task}={module}:{func}" + (f":{name}" if name else "")
