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
from dataclasses import dataclass

__all__ = ["PluginSource", "PluginFunction", "file_source", "PluginLoadError", "probe", "load_time_limit", "LOAD_TIME_LIMIT"]

LOAD_TIME_LIMIT = 60.0   # seconds to import and register one plugin (PBRBENCH_PLUGIN_LOAD_LIMIT)


def load_time_limit() -> float:
    """Seconds one plugin may take to import and register: ``PBRBENCH_PLUGIN_LOAD_LIMIT``, else
    :data:`LOAD_TIME_LIMIT`."""
    try:
        v = float(os.environ.get("PBRBENCH_PLUGIN_LOAD_LIMIT", LOAD_TIME_LIMIT))
    except ValueError:
        return LOAD_TIME_LIMIT
    return v if v > 0 else LOAD_TIME_LIMIT


class PluginLoadError(RuntimeError):
    """The plugin could not be imported or registered (its entries are scored as failed)."""


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


_LOADED: dict = {}   # PluginSource -> (Registry of the plugin's entries, skipped, unknown) in this process


def _register(src: PluginSource, tasks, known):
    """The plugin's entries, registered in a private registry of this process (cached)."""
    from pbrbench.registry import PluginRegistry, Registry

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
