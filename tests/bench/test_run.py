"""The benchmark runner on a tiny fake task (no renders), plus one draft-quality end-to-end run
of a real task through the command line."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import pbrbench.bench.plan as planning
from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.bench.store import Store
from pbrbench.quality import DRAFT
from pbrbench.tasks.base import Job
from tests.fakes import FakeSource, FakeTask, fake_run, settings_for


# ----------------------------------------------------------------------------- tests
def test_plan_orders_by_scene_and_rejects_duplicates():
    jobs = planning.plan({"fake": FakeTask()}, DRAFT)
    assert [j.scene for j in jobs] == ["scene_a", "scene_a", "scene_b", "scene_b"]
    assert planning.needed_scenes(jobs) == ["scene_a", "scene_b"]

    class Dup(FakeTask):
        def jobs(self, quality):
            return [Job("fake", "s", "local")] * 2

    with pytest.raises(ValueError, match="duplicate job keys"):
        planning.plan({"fake": Dup()}, DRAFT)

    class Wrong(FakeTask):
        def jobs(self, quality):
            return [Job("other", "s", "local")]

    with pytest.raises(ValueError, match="Job.task"):
        planning.plan({"fake": Wrong()}, DRAFT)


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
        assert run["quality"] == "draft" and run["config"]["task_info"]["fake"]["headline_metric"] == "height_rmse"
        lock = run["config"]["environment"]["lock"]
        assert len(lock["lock_sha256"]) == 64 and "numpy" in lock["packages"]
        versions = run["config"]["task_info"]["fake"]["algorithm_versions"]
        assert set(versions) == {"good", "baseline:zero"} and all("+" in v for v in versions.values())
        assert {g["scene"] for g in s.ground_truths(o.run_id)} == {"scene_a", "scene_b"}
        cpu = [r[0] for r in s.conn.execute("SELECT cpu_seconds FROM jobs WHERE run = ?", (o.run_id,))]
        assert len(cpu) == 4 and all(c is not None and c >= 0 for c in cpu)
        assert o.job_cpu_seconds == pytest.approx(sum(cpu))
    # second run: ground truths come from the (fake) cache
    o2 = fake_run(tmp_path)
    assert o2.renders == 0
    assert [x["value"] for x in o2.scores] == [x["value"] for x in o.scores]  # same seed: same scores
    assert o2.n_cached == 4 and o2.job_cpu_seconds == 0.0 and o2.render_cpu_seconds == 0.0   # nothing ran again


def test_a_report_written_to_another_folder_brings_the_run_s_figures(tmp_path, capsys):
    """``pbrbench report --out ELSEWHERE``: the figures the run wrote under its own reports
    directory are copied beside the new report and its task page links them; with that
    directory gone, one line says so and the report is still written."""
    import shutil

    from pbrbench.cli.main import main

    o = fake_run(tmp_path)
    store = str(tmp_path / "h.sqlite")
    page = "task-fake.html"
    assert "Figures:" in (tmp_path / "reports" / o.run_id / page).read_text()
    other = tmp_path / "elsewhere"
    assert main(["report", o.run_id, "--store", store, "--out", str(other)]) == 0
    out = capsys.readouterr().out
    assert "figures copied from" in out
    new = other / o.run_id
    assert sorted(p.relative_to(new / "figures") for p in (new / "figures").rglob("*.png")) == \
        sorted(p.relative_to(tmp_path / "reports" / o.run_id / "figures")
               for p in (tmp_path / "reports" / o.run_id / "figures").rglob("*.png"))
    assert "Figures:" in (new / page).read_text()
    # its own folder without figures: nothing to bring, and no line claiming the folder moved
    shutil.rmtree(tmp_path / "reports" / o.run_id / "figures")
    assert main(["report", o.run_id, "--store", store, "--out", str(tmp_path / "reports")]) == 0
    assert "figures" not in capsys.readouterr().out.splitlines()[0]
    # the run's own folder gone: the report still comes, without figures, and says why
    shutil.rmtree(tmp_path / "reports")
    third = tmp_path / "third"
    assert main(["report", o.run_id, "--store", store, "--out", str(third)]) == 0
    out = capsys.readouterr().out
    assert "figures are not in" in out and "--out" in out
    assert "Figures:" not in (third / o.run_id / page).read_text()


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
    t2.run_job = lambda job, gts, **kw: calls.append(job.key) or orig(job, gts, **kw)
    o2 = fake_run(tmp_path, task=t2, resume=o.run_id)
    assert o2.run_id == o.run_id and o2.n_skipped == 2 and not o2.errors
    assert sorted(calls) == sorted(k for k in o.errors)
    assert len(o2.scores) == 16


def test_interrupted_run_keeps_scores_and_resumes(tmp_path):
    class Interrupt(FakeTask):
        n = 0

        def run_job(self, job, gts, **kw):
            Interrupt.n += 1
            if Interrupt.n == 3:
                raise KeyboardInterrupt
            return super().run_job(job, gts, **kw)

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
        run_benchmark(RunConfig(quality="draft", tasks=["nope"]), settings=settings_for(tmp_path),
                      source=FakeSource(tmp_path / "c"))
    with pytest.raises(UserError, match="--quality"):
        run_benchmark(RunConfig(quality="ultra"), settings=settings_for(tmp_path), tasks={"fake": FakeTask()},
                      source=FakeSource(tmp_path / "c"))


@pytest.mark.render
def test_end_to_end_draft_cli(tmp_path, cache_dir):
    """`pbrbench run --quality draft` on one real task, then report / history / compare."""
    name = "lightness"  # the cheapest task: this test is about the plumbing, not the science
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
    # --check without baselines is a user mistake: exit code 1 and one line saying how to create them
    q = subprocess.run(base + ["run", "--quality", "draft", "--tasks", name, "--check", "--no-report"] + common,
                       capture_output=True, text=True, env=env, timeout=900)
    assert q.returncode == 1 and "--update-baselines" in q.stderr, q.stderr[-2000:]


def test_source_without_a_cache_says_what_to_pass():
    # a script that handed cache=None on (its --cache left out) failed only at the first load,
    # with an AttributeError deep in the render cache
    from pbrbench.bench.source import GroundTruthSource

    with pytest.raises(TypeError, match="RenderCache"):
        GroundTruthSource(DRAFT, None)
