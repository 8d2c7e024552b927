"""Planning a run: which tasks, which jobs at a quality, which ground truths they need.

A plan is a pure function of the task list and the quality profile: no renderer, no store.
"""

from __future__ import annotations

from pbrbench.errors import UserError
from pbrbench.quality import Quality, require


def load_tasks(names: list[str] | None = None) -> dict:
    """Task instances by name (every task when ``names`` is empty)."""
    from pbrbench.tasks import get_tasks

    if not names:
        return get_tasks(None)
    try:
        return get_tasks(names)
    except ModuleNotFoundError as e:
        raise UserError(f"--tasks: task module {e.name!r} is not available ({e})") from None


def plan(tasks: dict, quality: Quality) -> list:
    """Every job of every task, ordered by scene (so consecutive jobs share ground truths)."""
    q = require(quality)
    jobs = []
    for name, task in tasks.items():
        tj = task.jobs(q)
        for j in tj:
            if j.task != name:
                raise ValueError(f"task {name!r}: job {j.key!r} names task {j.task!r}; Job.task must be the task's name")
        jobs += tj
    keys = [j.key for j in jobs]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"duplicate job keys {dup[:3]}: give jobs distinct params")
    return sorted(jobs, key=lambda j: (j.scene, j.extra_scenes, j.task, j.condition, j.params))


def needed_scenes(jobs) -> list[str]:
    """Scene names the jobs need, in first-use order."""
    seen: dict[str, None] = {}
    for j in jobs:
        seen.setdefault(j.scene)
        for e in j.extra_scenes:
            seen.setdefault(e)
    return list(seen)


def task_info(tasks: dict, registry) -> dict:
    """What the report needs to know about each task (stored with the run's configuration)."""
    out = {}
    for n, t in tasks.items():
        algs = registry.for_task(n)
        out[n] = {"description": t.description, "conditions": list(t.conditions),
                  "headline_metric": t.headline_metric, "reference_condition": t.reference_condition,
                  "notes": t.notes, "cost_notes": {a.name: a.cost_note for a in t.builtin_algorithms() if a.cost_note},
                  "algorithms": [a.name for a in algs],
                  "algorithm_kinds": {a.name: a.kind for a in algs},
                  "algorithm_versions": {a.name: a.full_version for a in algs},
                  "algorithm_origins": {a.name: a.origin for a in algs}}
    return out
