"""Plugin loading that runs none of a plugin's code in the benchmark process.

A plugin (``--algorithm TASK=MODULE:FUNCTION[:NAME]`` or an installed entry point of the group
:data:`pbrbench.registry.ENTRY_POINT_GROUP`) is described by a :class:`PluginSource`: what to
import and which attribute to take, plus, for a ``.py`` file given by path, the file's bytes,
read once when the run begins.  The benchmark process never imports it:

* registration is a *probe* (:func:`probe`) run in the isolated child of :mod:`pbrbench.isolation`
  within :func:`load_time_limit` seconds: the child imports the plugin, runs its
  ``register(registry)`` (or reads the marked callable) and sends back plain data (names, tasks,
  declared versions, source hashes, options).  A plugin that hangs, exits (``sys.exit``,
  ``os._exit``), crashes or raises while it is imported or registered costs that child, not the
  run;
* each registry entry's callable is a :class:`PluginFunction`, a picklable reference
  (source, task, name) that loads the plugin where it is called: in the child, or, with
  ``--algorithm-time-limit 0``, in the calling process (which the user then chose);
* a file plugin always runs the bytes read when the run began, so its hash (the version its
  scores carry) is that of the code that ran, even if the file is edited during the run.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import sys
import types
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from pbrbench.errors import UserError
from pbrbench.memo import Memo
from pbrbench.registry import (
    DEFAULT_TIME_LIMIT,
    ENTRY_POINT_GROUP,
    Algorithm,
    PluginLoadError,
    PluginRegistry,
    Registry,
    builtin_registry,
    is_path,
    normalize_algorithm_spec,
    parse_algorithm_spec,
)
from pbrbench.settings import PLUGIN_LOAD_LIMIT

__all__ = ["PluginSource", "PluginFunction", "file_source", "probe",
           "plugin_registry", "add_algorithm_spec", "add_entry_points"]



@dataclass(frozen=True)
class PluginSource:
    """Where a plugin's code is.

    Attributes
    ----------
    kind : str
        ``"file"`` (a ``.py`` file given by path), ``"module"`` (a dotted module) or ``"entry"``
        (an installed entry point).
    target : str
        The file's absolute path, the dotted module, or the entry point's value
        (``module:attr``).
    attr : str
        The function's (dotted) name in the module; empty for an entry point.
    name : str
        The entry point's name (``TASK:NAME``, or any name for the other forms); for a spec,
        ``TASK:NAME`` with the NAME given by the spec (empty when it gives none).
    source : bytes
        The file's bytes (kind ``"file"``), read when the run began.
    """

    kind: str
    target: str
    attr: str = ""
    name: str = ""
    source: bytes = b""

    @property
    def digest(self) -> str:
        """sha256 of the file's bytes (kind ``"file"``), 10 hex digits; empty otherwise."""
        return hashlib.sha256(self.source).hexdigest()[:10] if self.kind == "file" else ""

    @property
    def module_name(self) -> str:
        """The name the plugin's module is loaded under (kind ``"file"``: from path and bytes)."""
        if self.kind != "file":
            return self.target.partition(":")[0]
        stem = "".join(c if c.isalnum() else "_" for c in os.path.splitext(os.path.basename(self.target))[0])
        h = hashlib.sha256(self.target.encode() + b"\0" + self.source).hexdigest()[:10]
        return f"pbrbench_plugin_{stem}_{h}"


def file_source(path: str, attr: str, name: str) -> PluginSource:
    """A :class:`PluginSource` of a ``.py`` file (its bytes read now)."""
    with open(path, "rb") as f:
        data = f.read()
    return PluginSource("file", path, attr, name, data)


class _Missing(Exception):
    """The plugin's own module is not importable (not an error inside it)."""


class _NoAttr(Exception):
    """The module has no such attribute, or it is not callable."""


def _exec_file(src: PluginSource):
    name = src.module_name
    mod = sys.modules.get(name)
    if mod is not None:
        return mod
    mod = types.ModuleType(name)
    mod.__file__ = src.target
    sys.modules[name] = mod
    try:
        import linecache

        text = src.source.decode("utf-8", "replace")
        linecache.cache[src.target] = (len(text), None, text.splitlines(True), src.target)
        exec(compile(src.source, src.target, "exec"), mod.__dict__)   # noqa: S102 - the user's plugin
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return mod


def _import(module: str):
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name and (module == e.name or module.startswith(e.name + ".")):
            raise _Missing(f"plugin module {module!r} cannot be imported ({e}); put its folder on PYTHONPATH "
                           "or give a path to a .py file") from None
        raise


def _attr(mod, dotted: str):
    obj = mod
    for part in dotted.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            names = ", ".join(n for n in dir(mod) if not n.startswith("_") and callable(getattr(mod, n)))
            raise _NoAttr(f"{getattr(mod, '__name__', mod)} has no {dotted!r} (it has {names or 'no callables'})") \
                from None
    if not callable(obj):
        raise _NoAttr(f"{dotted!r} is not callable")
    return obj


def _target(src: PluginSource):
    """The object the source names (imports the plugin: only in the process that runs it)."""
    if src.kind == "file":
        return _attr(_exec_file(src), src.attr)
    if src.kind == "module":
        return _attr(_import(src.target), src.attr)
    module, _, attr = src.target.partition(":")
    mod = _import(module.strip())
    return _attr(mod, attr.strip()) if attr.strip() else mod


_LOADED = Memo("plugins loaded in this process (entries, skipped, unknown)", 64)   # by PluginSource


def _register(src: PluginSource, tasks, known):
    """The plugin's entries, registered in a private registry of this process (cached)."""

    hit = _LOADED.get(src)
    if hit is not None:
        return hit
    obj = _target(src)
    reg = Registry()
    pr = PluginRegistry(reg, tasks, origin=src.target, time_limit=None, known=known)
    if src.kind in ("file", "module"):
        task, _, name = src.name.partition(":")
        pr.add(task, name or getattr(obj, "pbrbench_name", None) or src.attr.rsplit(".", 1)[-1], obj,
               version=getattr(obj, "pbrbench_version", None), options=getattr(obj, "pbrbench_options", None))
    elif ":" in src.name:                         # "TASK:NAME" = "module:callable"
        task, _, name = src.name.partition(":")
        pr.add(task, name, obj, version=getattr(obj, "pbrbench_version", None),
               options=getattr(obj, "pbrbench_options", None))
    elif hasattr(obj, "pbrbench_task"):           # a callable marked with @algorithm
        pr.add(obj.pbrbench_task, obj.pbrbench_name, obj, version=obj.pbrbench_version,
               options=obj.pbrbench_options)
    elif callable(obj):                           # register(registry)
        obj(pr)
    else:
        raise _NoAttr(f"{type(obj).__name__} is not callable; point it at register(registry) or at an algorithm")
    _LOADED[src] = out = (reg, list(pr.skipped), list(pr.unknown))
    return out


def _line(e: BaseException) -> str:
    if isinstance(e, SystemExit):
        return f"it called sys.exit({e.code!r})"
    return f"{type(e).__name__}: {' '.join(str(e).split())}"[:300]


def probe(src: PluginSource, tasks, known) -> dict:
    """Import and register the plugin in this process (the isolated child) and describe its
    entries as plain data.

    Parameters
    ----------
    src : PluginSource
        The plugin.
    tasks : sequence of str
        The tasks of the run (entries of other tasks are skipped).
    known : sequence of str
        Every task name pbrbench knows (an entry of another task is a mistyped name).

    Returns
    -------
    dict
        ``{"entries": [...], "skipped": [...], "unknown": [...]}`` (each entry a dict of the
        :class:`pbrbench.registry.Algorithm` fields but ``fn``), or ``{"error": KIND,
        "message": LINE}`` with KIND ``"missing"`` (the module is not importable), ``"attr"`` (no
        such function) or ``"load"`` (the plugin raised or exited while imported or registered).
    """
    try:
        reg, skipped, unknown = _register(src, tuple(tasks), tuple(known))
    except _Missing as e:
        return {"error": "missing", "message": str(e)}
    except _NoAttr as e:
        return {"error": "attr", "message": str(e)}
    except BaseException as e:  # noqa: BLE001 - SystemExit too: the plugin's failure, not the run's
        if isinstance(e, KeyboardInterrupt):
            raise
        return {"error": "load", "message": _line(e)}
    entries = [{"name": a.name, "task": a.task, "version": a.version, "fingerprint": a.fingerprint,
                "options": dict(a.options), "conditions": a.conditions, "description": a.description,
                "interface": a.interface, "figures": a.figures} for a in reg]
    return {"entries": entries, "skipped": skipped, "unknown": unknown}


class PluginFunction:
    """A plugin's algorithm by reference: loads the plugin where it is called.

    Parameters
    ----------
    source : PluginSource
        The plugin.
    task, name : str
        The entry of the plugin this calls.
    tasks : tuple of str
        The tasks the plugin was registered for (its ``register`` sees them).
    error : str, optional
        Why the plugin could not be loaded: every call raises :class:`PluginLoadError` with it.
    """

    def __init__(self, source: PluginSource, task: str, name: str, tasks=(), error: str | None = None):
        self.source, self.task, self.name, self.tasks, self.load_error = source, task, name, tuple(tasks), error
        self.__name__ = self.__qualname__ = name
        self.__module__ = __name__

    def resolve(self):
        """The plugin's own callable (imports the plugin into this process)."""
        reg, _, _ = _register(self.source, self.tasks or (self.task,), ())
        return reg.get(self.task, self.name).fn

    def __call__(self, *args, **kwargs):
        if self.load_error:
            raise PluginLoadError(self.load_error)
        try:
            return self.resolve()(*args, **kwargs)
        except SystemExit as e:   # in-process mode: the plugin's exit is its failure, not the run's
            raise PluginLoadError(f"{self.name}: {_line(e)}") from None

    def __repr__(self):
        return f"PluginFunction({self.source.kind}:{self.source.target}, {self.task}/{self.name})"


# ------------------------------------------------------------------ the run's registry
def _one_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {' '.join(str(e).split())}"[:300]


def _known_tasks(tasks: Iterable[str]) -> tuple[str, ...]:
    from pbrbench.tasks import task_names

    return tuple(dict.fromkeys([*task_names(), *tasks]))


def _probe(src, tasks, known, origin: str, limit: float) -> dict:
    """:func:`probe` in the isolated child, within ``limit`` seconds (the load time limit); a
    hang, an exit or a crash is ``{"error": "load", "message": ...}``."""
    from pbrbench.isolation import PluginCrash, PluginTimeout, call_isolated

    try:
        return call_isolated(probe, (src, tuple(tasks), tuple(known)), time_limit=limit, name=origin,
                             budget=False)
    except PluginTimeout:
        return {"error": "load", "message": f"it did not finish importing and registering within {limit:g} s "
                                            "(its process was killed; PBRBENCH_PLUGIN_LOAD_LIMIT sets the limit)"}
    except PluginCrash as e:
        return {"error": "load", "message": f"its process died while importing and registering it "
                                            f"({str(e).rpartition('(')[2].rstrip(')')})"}
    except Exception as e:  # noqa: BLE001 - e.g. options that cannot be sent back
        return {"error": "load", "message": _one_line(e)}


def _entries(src, info: dict, *, origin: str, tasks, time_limit: float | None) -> list[Algorithm]:
    out = []
    for d in info["entries"]:
        fn = PluginFunction(src, d["task"], d["name"], tasks)
        out.append(Algorithm(d["name"], d["task"], fn, kind="plugin", version=d["version"] or "1",
                             options=d["options"], conditions=d["conditions"], description=d["description"],
                             origin=origin, interface=d["interface"], figures=d["figures"],
                             fingerprint=src.digest or d["fingerprint"], time_limit=time_limit))
    return out


def _unknown_line(origin: str, unknown: list[str], known) -> str:
    return (f"{origin}: {'; '.join(unknown)} -- not a pbrbench task (tasks: {', '.join(known)}); "
            "fix the task name")


def add_algorithm_spec(registry: Registry, spec: str, tasks: Iterable[str], *, time_limit: float | None,
                       log=None, load_limit: float = PLUGIN_LOAD_LIMIT) -> Algorithm:
    """Load one ``--algorithm`` spec into ``registry`` and return its entry.

    The plugin is imported and registered only in the isolated child, within ``load_limit``
    seconds.  A spec that cannot be used (a bad form, a task that is not run or
    does not exist, a missing file, module or function, a name taken) raises ``UserError``; a
    plugin that raises, exits, crashes or hangs while it is imported is added all the same, as an
    entry whose every call fails with that reason (one line to ``log``), and the run goes on.
    """
    task, module, func, name = parse_algorithm_spec(spec)
    tasks = tuple(tasks)
    known = _known_tasks(tasks)
    where = f"--algorithm {spec!r}"
    if task not in known:
        raise UserError(f"{where}: {task!r} is not a pbrbench task (tasks: {', '.join(known)}); fix the task name")
    if task not in tasks:
        raise UserError(f"{where}: task {task!r} is not part of this run (tasks: {', '.join(tasks)}); add it to --tasks")
    if is_path(module):
        path = Path(module).expanduser().resolve()
        if not path.is_file():
            raise UserError(f"{path}: no such plugin file")
        src = file_source(str(path), func, f"{task}:{name or ''}")
    else:
        src = PluginSource("module", module, func, f"{task}:{name or ''}")
    origin = f"--algorithm {normalize_algorithm_spec(spec)}"
    info = _probe(src, tasks, known, origin, load_limit)
    err = info.get("error")
    if err in ("missing", "attr"):
        raise UserError(f"{where}: {info['message']}")
    if err:
        msg = f"{origin}: the plugin failed to load ({info['message']}); it is scored as failed"
        if log is not None:
            log(f"plugin failed: {msg}")
        shown = name or func.rsplit(".", 1)[-1]
        alg = Algorithm(shown, task, PluginFunction(src, task, shown, tasks, error=msg),
                        kind="plugin", version="unloaded", origin=origin,
                        fingerprint=src.digest or hashlib.sha256(module.encode()).hexdigest()[:10],
                        time_limit=time_limit)
    else:
        (alg,) = _entries(src, info, origin=origin, tasks=tasks, time_limit=time_limit)
    if (alg.task, alg.name) in registry:
        old = registry.get(alg.task, alg.name)
        raise UserError(f"{where}: algorithm {alg.name!r} of task {alg.task!r} is already registered ({old.origin}); "
                        "give it another name; add :NAME to the spec")
    return registry.add(alg)


def add_entry_points(registry: Registry, tasks: Iterable[str], *, time_limit: float | None,
                     group: str = ENTRY_POINT_GROUP, load_limit: float = PLUGIN_LOAD_LIMIT) -> list[str]:
    """Add every installed entry point of ``group`` to ``registry``.

    Names and versions come from the entry point's metadata and from a probe in the isolated
    child (within ``load_limit`` seconds each), never from importing the plugin here.  Returns one line per
    entry point that could not be used (skipped, all its entries with it; the run goes on) or
    that names a task pbrbench does not have.
    """
    from importlib.metadata import entry_points

    tasks = tuple(tasks)
    known = _known_tasks(tasks)
    problems = []
    for ep in entry_points(group=group):
        dist = getattr(ep, "dist", None)
        origin = f"entry point {ep.name} = {ep.value}" + (f" ({dist.name} {dist.version})" if dist is not None else "")
        src = PluginSource("entry", ep.value, "", ep.name)
        info = _probe(src, tasks, known, origin, load_limit)
        if info.get("error"):
            what = "failed to load" if info["error"] != "attr" else "cannot be used"
            problems.append(f"{origin}: {what} ({info['message']})")
            continue
        if info["unknown"]:
            problems.append(_unknown_line(origin, info["unknown"], known))
        new = _entries(src, info, origin=origin, tasks=tasks, time_limit=time_limit)
        taken = [a for a in new if (a.task, a.name) in registry]
        if taken:
            a = taken[0]
            problems.append(f"{origin}: algorithm {a.name!r} of task {a.task!r} is already registered "
                            f"({registry.get(a.task, a.name).origin}); give it another name")
            continue
        for a in new:
            registry.add(a)
    return problems


def plugin_registry(tasks: Mapping, specs: Iterable[str] = (), *, entry_points: bool = True,
                    time_limit: float | None = DEFAULT_TIME_LIMIT, log=None,
                    load_limit: float = PLUGIN_LOAD_LIMIT) -> Registry:
    """The built-in algorithms of ``tasks`` plus the installed plugins (entry points of
    :data:`ENTRY_POINT_GROUP`, unless ``entry_points`` is false) plus the ``--algorithm``
    ``specs``.  ``time_limit``: seconds per plugin per job (None: plugins run in-process, without
    a limit); ``load_limit``: seconds to import and register each plugin
    (:attr:`pbrbench.settings.Settings.plugin_load_limit`).  No plugin code runs in this process
    while they are added.
    A broken entry point is skipped with a message to ``log``; a bad spec raises ``UserError``."""
    reg = builtin_registry(tasks)
    names = list(tasks)
    if entry_points:
        for msg in add_entry_points(reg, names, time_limit=time_limit, load_limit=load_limit):
            if log is not None:
                log(f"plugin skipped: {msg}" if "not a pbrbench task" not in msg else f"plugin: {msg}")
    for spec in specs:
        add_algorithm_spec(reg, spec, names, time_limit=time_limit, log=log, load_limit=load_limit)
    return reg
