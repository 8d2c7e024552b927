"""The benchmark runner on a tiny fake task (no renders), plus one draft-quality end-to-end run
of a real task through the command line."""

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from pbrbench.bench import runner
from pbrbench.bench.runner import GroundTruthSource, RunConfig, run_benchmark
from pbrbench.bench.store import Store
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.report.figures import slug
from pbrbench.tasks.base import Job, JobResult, Score, Task

EVIL = "<script>alert('x')</script>"


# ----------------------------------------------------------------------------- fakes
@dataclass(frozen=True)
class FakeSpec:
    name: str

    def content_hash(self) -> str:
        return "hash-" + self.name


class FakeSource(GroundTruthSource):
    """Synthetic ground truths; 'rendering' writes a marker file so the cache check is real."""

    def __init__(self, root, quality="draft"):
        super().__init__(quality, cache_root=str(root), variant="fake")

    def specs(self, names):
        return {n: FakeSpec(n) for n in names}

    def _file(self, spec):
        return Path(self.cache_root) / f"{slug(spec.name)}.json"

    def cached_meta(self, spec):
        p = self._file(spec)
        return json.loads(p.read_text()) if p.is_file() else None

    def render(self, spec):
        meta = self.cached_meta(spec)
        if meta is not None:
            return meta, True
        meta = {"scene_hash": spec.content_hash(), "quality": self.quality, "spp": 4, "resolution": [16, 12],
                "noise": {"radiance_rel_sd_rms": 0.01, "radiance_rel_sd_median": 0.005}, "wall_s": 0.0}
        Path(self.cache_root).mkdir(parents=True, exist_ok=True)
        self._file(spec).write_text(json.dumps(meta))
        return meta, False

    def load(self, spec):
        rng = np.random.default_rng(sum(map(ord, spec.name)))
        rad = rng.uniform(0.1, 1.0, (12, 16, 3)).astype(np.float32)
        return GroundTruth({"radiance": rad, "direct": 0.8 * rad}, {"scene_hash": spec.content_hash()})


class FakeTask(Task):
    name = "fake"
    description = f"A fake task {EVIL}"
    algorithms = ("good", "baseline:zero")
    conditions = ("local", "global")
    headline_metric = "rmse"
    headline_better = "lower"
    scenes = ("scene_a", "scene_b")
    fail_scene = None

    def jobs(self, quality):
        return [Job(self.name, s, c) for s in self.scenes for c in self.conditions]

    def run_job(self, job, gts, *, seed=0):
        if job.scene == self.fail_scene:
            raise RuntimeError("deliberate failure")
        gt = gts[job.scene]
        truth = gt["radiance"] if job.condition == "global" else gt["direct"]
        rng = np.random.default_rng([seed, len(job.scene), len(job.condition)])
        out = JobResult(job)
        ests = {"good": truth + 0.01 * rng.standard_normal(truth.shape), "baseline:zero": np.zeros_like(truth)}
        for alg, est in ests.items():
            err = np.abs(est - truth).mean(-1)
            out.scores.append(Score(self.name, job.scene, gt.meta["scene_hash"], job.condition, alg, "1", "rmse",
                                    float(np.sqrt((err ** 2).mean())), 0.001))
            out.scores.append(Score(self.name, job.scene, gt.meta["scene_hash"], job.condition, alg, "1", "psnr",
                                    float(-20 * np.log10(np.sqrt((err ** 2).mean()) + 1e-12)), 0.001, "higher"))
            out.error_maps[f"{alg} |error|"] = err
        out.images["input"] = np.clip(truth, 0, 1)
        out.images["linear:truth"] = truth
        out.images[EVIL] = np.clip(truth[..., 0], 0, 1)
        out.plots["profile"] = {"x": list(range(16)), "series": {"truth": truth[6, :, 0].tolist(),
                                                                   "good": ests["good"][6, :, 0].tolist()},
                                "xlabel": "column", "ylabel": "radiance"}
        return out


def cfg_for(tmp_path, **kw):
    return RunConfig(quality="draft", out=str(tmp_path / "reports"), store=str(tmp_path / "h.sqlite"),
                     progress=False, **kw)


def fake_run(tmp_path, task=None, **kw):
    task = task or FakeTask()
    return run_benchmark(cfg_for(tmp_path, **kw), tasks={"fake": task}, source=FakeSource(tmp_path / "cache"),
                         log=lambda m: None)


# ----------------------------------------------------------------------------- tests
def test_plan_orders_by_scene_and_rejects_duplicates():
    jobs = runner.plan({"fake": FakeTask()}, "draft")
    assert [j.scene for j in jobs] == ["scene_a", "scene_a", "scene_b", "scene_b"]
    assert runner.needed_scenes(jobs) == ["scene_a", "scene_b"]

    class Dup(FakeTask):
        def jobs(self, quality):
            return [Job("fake", "s", "local")] * 2

    with pytest.raises(ValueError, match="duplicate job keys"):
        runner.plan({"fake": Dup()}, "draft")

    class Wrong(FakeTask):
        def jobs(self, quality):
            return [Job("other", "s", "local")]

    with pytest.raises(ValueError, match="Job.task"):
        runner.plan({"fake": Wrong()}, "draft")


def test_run_stores_scores_figures_export_and_report(tmp_path):
    o = fake_run(tmp_path)
    assert o.renders == 2 and o.n_jobs == 4 and not o.errors
    assert len(o.scores) == 4 * 2 * 2
    run_dir = tmp_path / "reports" / o.run_id
    assert o.report == run_dir / "index.html" and o.report.is_file()
    data = json.loads((run_dir / "scores.json").read_text())
    assert len(data["scores"]) == 16 and data["run"]["status"] == "complete"
    manifests = sorted((run_dir / "figures").glob("*/manifest.json"))
    assert len(manifests) == 4
    m = json.loads(manifests[0].read_text())
    kinds = sorted(f["kind"] for f in m["figures"])
    assert kinds == ["error_map", "error_map", "image", "image", "image", "plot"]
    assert all((run_dir / "figures" / f["file"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for f in m["figures"])
    with Store(tmp_path / "h.sqlite") as s:
        run = s.get_run(o.run_id)
        assert run["quality"] == "draft" and run["config"]["task_info"]["fake"]["headline_metric"] == "rmse"
        assert {g["scene"] for g in s.ground_truths(o.run_id)} == {"scene_a", "scene_b"}
    # second run: ground truths come from the (fake) cache
    o2 = fake_run(tmp_path)
    assert o2.renders == 0
    assert [x["value"] for x in o2.scores] == [x["value"] for x in o.scores]  # same seed: same scores


def test_seed_changes_only_seed_dependent_scores(tmp_path):
    a = {(x["scene"], x["condition"], x["algorithm"], x["metric"]): x["value"] for x in fake_run(tmp_path, seed=0).scores}
    b = {(x["scene"], x["condition"], x["algorithm"], x["metric"]): x["value"] for x in fake_run(tmp_path, seed=1).scores}
    assert a.keys() == b.keys()
    assert all(a[k] == b[k] for k in a if k[2] == "baseline:zero")
    assert any(a[k] != b[k] for k in a if k[2] == "good")


def test_failed_job_is_recorded_and_resume_completes_it(tmp_path):
    t = FakeTask()
    t.fail_scene = "scene_b"
    o = fake_run(tmp_path, task=t)
    assert len(o.errors) == 2 and all("deliberate failure" in e for e in o.errors.values())
    assert len(o.scores) == 8
    with Store(tmp_path / "h.sqlite") as s:
        assert s.get_run(o.run_id)["status"] == "complete-with-errors"
    assert "deliberate failure" in o.report.read_text()
    # the bug is fixed: resuming runs only the two failed jobs
    calls = []
    t2 = FakeTask()
    orig = t2.run_job
    t2.run_job = lambda job, gts, seed=0: calls.append(job.key) or orig(job, gts, seed=seed)
    o2 = fake_run(tmp_path, task=t2, resume=o.run_id)
    assert o2.run_id == o.run_id and o2.n_skipped == 2 and not o2.errors
    assert sorted(calls) == sorted(k for k in o.errors)
    assert len(o2.scores) == 16


def test_interrupted_run_keeps_scores_and_resumes(tmp_path):
    class Interrupt(FakeTask):
        n = 0

        def run_job(self, job, gts, *, seed=0):
            Interrupt.n += 1
            if Interrupt.n == 3:
                raise KeyboardInterrupt
            return super().run_job(job, gts, seed=seed)

    with pytest.raises(KeyboardInterrupt):
        fake_run(tmp_path, task=Interrupt())
    with Store(tmp_path / "h.sqlite") as s:
        rid = s.resolve_run(None)
        assert s.get_run(rid)["status"] == "interrupted"
        assert len(s.done_jobs(rid)) == 2 and len(s.scores(rid)) == 8
    o = fake_run(tmp_path, resume=rid)
    assert o.n_skipped == 2 and len(o.scores) == 16


def test_unknown_task_and_quality_are_user_errors(tmp_path):
    from pbrbench.errors import UserError

    with pytest.raises(UserError, match="--tasks"):
        run_benchmark(cfg_for(tmp_path, tasks=["nope"]), source=FakeSource(tmp_path / "c"))
    with pytest.raises(UserError, match="--quality"):
        run_benchmark(RunConfig(quality="ultra", out=str(tmp_path), progress=False), tasks={"fake": FakeTask()},
                      source=FakeSource(tmp_path / "c"))


def _real_task():
    from pbrbench.tasks import TASK_MODULES

    # the cheapest task first: this test is about the plumbing, not the science
    for name in ("lightness",) + tuple(TASK_MODULES):
        try:
            __import__(f"pbrbench.tasks.{name}")
            return name
        except ImportError:
            continue
    return None


@pytest.mark.render
def test_end_to_end_draft_cli(tmp_path, cache_dir):
    """`pbrbench run --quality draft` on one real task, then report / history / compare."""
    name = _real_task()
    if name is None:
        pytest.skip("no task module is importable yet")
    env = dict(os.environ, PBRBENCH_CACHE=str(cache_dir), PBRBENCH_BASELINES=str(tmp_path / "no-baselines"))
    base = [sys.executable, "-m", "pbrbench"]
    common = ["--out", str(tmp_path / "r"), "--store", str(tmp_path / "h.sqlite")]
    p = subprocess.run(base + ["run", "--quality", "draft", "--tasks", name] + common, capture_output=True, text=True,
                       env=env, timeout=900)
    assert p.returncode in (0, 1), p.stderr[-3000:]
    assert "report: " in p.stdout
    report = Path(p.stdout.split("report: ")[-1].strip())
    assert report.is_file() and report.stat().st_size > 1000
    with Store(tmp_path / "h.sqlite") as s:
        rid = s.resolve_run(None)
        assert len(s.scores(rid, task=name)) > 0 and s.ground_truths(rid)
    for cmd in (["report"], ["history"], ["compare", rid, rid]):
        q = subprocess.run(base + cmd + common, capture_output=True, text=True, env=env, timeout=300)
        assert q.returncode == 0, q.stderr[-2000:]
    # --check without baselines is a failure with exit code 2
    q = subprocess.run(base + ["run", "--quality", "draft", "--tasks", name, "--check", "--no-report"] + common,
                       capture_output=True, text=True, env=env, timeout=900)
    assert q.returncode == 2, q.stderr[-2000:]
