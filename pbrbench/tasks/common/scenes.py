"""The value a swept scene took.

A task reads its scenes from the library it is bound to (:attr:`pbrbench.tasks.base.Task.scenes`,
a :class:`pbrbench.scene.load.SceneLibrary`).  It resolves what it needs from the scene specs when
it *lists* jobs (:meth:`Task.jobs`) and stores it in the job's ``params``, so that
:meth:`Task.run_job` works from the job and the ground truths (jobs run in worker processes, where
the bound library travels with the task; tests build jobs from synthetic ground truths).
"""

from __future__ import annotations


def sweep_value(spec, key: str):
    """The value a swept spec took for ``key`` (the last part of a key path), parsed from its name
    ``family[key=value,...]``; None when the spec is not swept on it."""
    name = spec.name if not isinstance(spec, str) else spec
    if "[" not in name or not name.endswith("]"):
        return None
    for part in name[name.index("[") + 1:-1].split(","):
        k, _, v = part.partition("=")
        if k == key:
            try:
                return float(v)
            except ValueError:
                return v
    return None
