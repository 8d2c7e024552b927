"""Benchmark tasks, one module each (``pbrbench/tasks/<name>.py`` defining ``TASK``).

Task modules are discovered: a new module with a ``TASK`` is a new task, with no list to edit.
"""

from __future__ import annotations

import importlib
import pkgutil

from pbrbench.errors import UserError


def task_names() -> list[str]:
    """Names of the task modules of this package, in a fixed order (the chapter's order first)."""
    import pbrbench.tasks as pkg

    found = [m.name for m in pkgutil.iter_modules(pkg.__path__)
             if not m.ispkg and not m.name.startswith("_") and m.name != "base"]
    order = ("photometric_stereo", "lightness", "hdr", "sfs", "specular", "interreflection")
    return sorted(found, key=lambda n: (order.index(n) if n in order else len(order), n))


def get_tasks(names=None, *, library=None) -> dict:
    """Task instances by name (all when ``names`` is empty), bound to the scene library ``library``
    when it is given (:meth:`pbrbench.tasks.base.Task.bind`; else the library shipped)."""
    known = task_names()
    names = list(names) if names else known
    out = {}
    for n in names:
        if n not in known:
            raise UserError(f"--tasks: unknown task {n!r}; choose from {', '.join(known)}")
        task = importlib.import_module(f"pbrbench.tasks.{n}").TASK
        out[n] = task.bind(library) if library is not None else task
    return out
