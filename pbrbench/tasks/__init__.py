"""Benchmark tasks, one module each; :data:`REGISTRY` maps task names to instances.

Modules are imported lazily by :func:`get_tasks` so a task whose inference module is missing
does not break the others.
"""

from __future__ import annotations

import importlib

from pbrbench.errors import UserError

TASK_MODULES = ("photometric_stereo", "lightness", "hdr", "sfs", "specular")


def get_tasks(names=None) -> dict:
    names = list(names) if names else list(TASK_MODULES)
    out = {}
    for n in names:
        if n not in TASK_MODULES:
            raise UserError(f"--tasks: unknown task {n!r}; choose from {', '.join(TASK_MODULES)}")
        mod = importlib.import_module(f"pbrbench.tasks.{n}")
        out[n] = mod.TASK
    return out
