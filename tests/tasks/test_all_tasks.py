"""What every task must do: unique jobs of its own conditions, and built-in algorithms."""

from __future__ import annotations

from pbrbench.quality import get_quality


def test_every_task_lists_unique_jobs_of_its_conditions():
    from pbrbench.tasks import get_tasks

    for name, task in get_tasks().items():
        algs = task.builtin_algorithms()
        assert task.name == name and task.headline_metric and algs
        assert all(a.task == name for a in algs) and len({a.name for a in algs}) == len(algs)
        assert any(a.kind == "method" for a in algs) and any(a.kind == "baseline" for a in algs)
        jobs = task.jobs(get_quality("draft"))
        assert len({j.key for j in jobs}) == len(jobs)
        for j in jobs:
            assert j.task == name and j.condition.split("+")[0] in ("local", "area", "global", "near")
            assert all(isinstance(hash(v), int) for _, v in j.params)
        if name == "sfs" and jobs:
            assert {j.param("label") for j in jobs if j.param("plot") is None} == {"view", "oblique"}
        if jobs:
            assert {j.condition for j in jobs if j.param("plot") is None} <= set(task.conditions)

