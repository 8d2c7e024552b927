"""The Dask executor: a LocalCluster of 2 worker processes renders and scores a small sweep, and
every score equals the local executor's (ground truths rendered independently on each side)."""

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed", reason="Dask distributed is not installed (pip install 'dask[distributed]')")

from pbrbench.bench.executors import DaskExecutor  # noqa: E402
from pbrbench.bench.run import RunConfig, run_benchmark  # noqa: E402
from pbrbench.bench.source import GroundTruthSource  # noqa: E402
from pbrbench.quality import DRAFT  # noqa: E402
from pbrbench.registry import Algorithm  # noqa: E402
from pbrbench.render.cache import RenderCache  # noqa: E402
from pbrbench.settings import Settings  # noqa: E402
from pbrbench.tasks.base import Job, JobResult, Task  # noqa: E402
from pbrbench.tasks.common.scoring import ScoreBook  # noqa: E402
from tests.fakes import FakeSource, FakeTask, settings_for  # noqa: E402

ROOT = str(Path(__file__).resolve().parents[2])


def image_mean(img, *, mask, k, rng):
    return float(img[mask].mean()) * k


def noisy_mean(img, *, mask, k, rng):
    return float((img + 0.01 * rng.standard_normal(img.shape)).mean())


class RenderedStats(Task):
    """Scores straight from a real ground truth plus seeded noise: any difference between two
    renders or two executors shows up in the numbers."""

    name = "rstats"
    conditions = ("local", "global")
    headline_metric = "height_rmse"

    def builtin_algorithms(self):
        return [Algorithm("mean", self.name, image_mean), Algorithm("noisy", self.name, noisy_mean)]

    def jobs(self, quality):
        return [Job(self.name, "sphere_5lights", c, (("k", k),)) for c in self.conditions for k in (1, 2)]

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        gt = gts[job.scene]
        img = gt["direct"] if job.condition == "local" else gt["radiance"]
        out = JobResult(job)
        book = ScoreBook(job, gt.meta["scene_hash"], algorithms)
        for alg in algorithms:
            rng = np.random.default_rng([seed, job.param("k")])
            book.add(alg.name, {"height_rmse": alg(img, mask=gt.mask, k=job.param("k"), rng=rng)}, 0.0)
        out.scores = book.scores
        return out


def _add_path(p):
    if p not in sys.path:
        sys.path.insert(0, p)


def _key(s):
    return (s["task"], s["scene"], s["condition"], s["algorithm"], s["metric"], s["job"])


@pytest.mark.render
@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_local_cluster_matches_local_executor(tmp_path):
    ex = DaskExecutor(scheduler=None, workers=2, variant=None, settings=Settings.from_env())
    try:
        ex.client.run(_add_path, ROOT)  # the fake task and source live in the tests package
        probes = ex.probe()
        assert len(probes) == 2 and len({p["pid"] for p in probes}) == 2
        src_d = GroundTruthSource(DRAFT, cache=RenderCache(tmp_path / "cache-dask"))
        variant = src_d.resolve_variant()
        assert all(p["variant"] == variant and p["threads"] == 1 for p in probes)
        # one run per source: the real renders (on the workers) and the synthetic ones
        o_r = run_benchmark(RunConfig(quality="draft", executor="dask"), settings=settings_for(tmp_path / "d1"),
                            tasks={"rstats": RenderedStats()}, source=src_d, executor=ex, log=lambda m: None)
        o_f = run_benchmark(RunConfig(quality="draft", executor="dask"), settings=settings_for(tmp_path / "d2"),
                            tasks={"fake": FakeTask()}, source=FakeSource(tmp_path / "fake-cache"), executor=ex,
                            log=lambda m: None)
    finally:
        ex.close()
    assert o_r.renders == 1 and not o_r.errors and not o_f.errors
    assert (tmp_path / "cache-dask" / "gt").is_dir()
    # local executor, ground truth rendered again here in a separate cache
    l_r = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path / "l1"),
                        tasks={"rstats": RenderedStats()},
                        source=GroundTruthSource(DRAFT, cache=RenderCache(tmp_path / "cache-local")),
                        log=lambda m: None)
    l_f = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path / "l2"), tasks={"fake": FakeTask()},
                        source=FakeSource(tmp_path / "fake-cache-2"), log=lambda m: None)
    assert l_r.renders == 1
    for a, b in ((o_r, l_r), (o_f, l_f)):
        da = {_key(s): s["value"] for s in a.scores}
        db = {_key(s): s["value"] for s in b.scores}
        assert len(da) > 0 and da == db  # bit-identical, not approximately equal
    assert len(o_r.scores) == 8 and len(o_f.scores) == 16
    # figures came back from the workers
    assert len(list((tmp_path / "d2" / "reports" / o_f.run_id / "figures").glob("*/manifest.json"))) == 4


@pytest.mark.slow
def test_a_task_that_kills_its_workers_is_given_up_and_the_others_are_kept():
    """A task whose worker dies each time it runs is given up after allowed-failures + 1 deaths
    (0 + 1 here); the executor still yields every other task's result, then names the lost one."""
    import operator
    import os

    import dask

    from pbrbench.errors import UserError

    # one task per worker thread (Dask marks every task assigned to a dying worker as suspect)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0, "distributed.scheduler.worker-saturation": 1.0}):
        ex = DaskExecutor(scheduler=None, workers=1, variant="scalar_rgb", settings=Settings.from_env())
    try:
        got = []
        # operator.call(f, *args): builtins only, so a restarted worker needs no path to the tests
        # the crashing task is given up; a task the scheduler had already handed to the same worker
        # when it died may be given up with it (a race the scheduler decides), never more
        with pytest.raises(UserError, match=r"^Dask: ([12]) of 4 tasks given up, each was running on 1 worker that died") as e:
            for r in ex.imap(operator.call, [(abs, -1), (os._exit, 3), (abs, -2), (abs, -3)]):
                got.append(r)
    finally:
        ex.close()
    lost = int(str(e.value).split()[1])
    assert len(got) == 4 - lost and set(got) <= {1, 2, 3} and len(set(got)) == len(got)
