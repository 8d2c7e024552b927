"""The results store: schema and migrations, runs and scores, resume bookkeeping, JSON export,
and two processes writing at once."""

import json
import math
import multiprocessing as mp
import sqlite3

import pytest

from pbrbench.bench import store as st
from pbrbench.bench.store import SCHEMA_VERSION, Store
from pbrbench.errors import UserError

ENV = {"git_revision": "abc", "pbrbench_version": "0", "mitsuba_version": "3", "drjit_version": "1",
       "numpy_version": "2", "machine": "test"}


def score(metric="rmse", value=1.0, scene="s", alg="a", cond="local", task="t", better="lower"):
    return {"task": task, "scene": scene, "scene_hash": "h", "condition": cond, "algorithm": alg,
            "algorithm_version": "1", "metric": metric, "value": value, "seconds": 0.1, "better": better}


def test_schema_created_with_migration_record(tmp_path):
    p = tmp_path / "h.sqlite"
    with Store(p) as s:
        assert s.schema_version() == SCHEMA_VERSION
        tables = {r[0] for r in s.conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        assert {"runs", "scores", "jobs", "ground_truths", "schema_migrations"} <= tables
        assert s.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    # reopening applies nothing twice
    with Store(p) as s:
        assert s.migrate() == []
        assert s.conn.execute("SELECT count(*) FROM schema_migrations").fetchone()[0] == len(st.MIGRATIONS)


def test_newer_schema_is_refused(tmp_path):
    p = tmp_path / "h.sqlite"
    Store(p).close()
    c = sqlite3.connect(p)
    c.execute("INSERT INTO schema_migrations VALUES (999, 'future', 'now')")
    c.commit()
    c.close()
    with pytest.raises(UserError, match="newer than this"):
        Store(p)


def test_migration_added_later_is_applied(tmp_path, monkeypatch):
    p = tmp_path / "h.sqlite"
    Store(p).close()
    extra = (SCHEMA_VERSION + 1, "add a note column", "ALTER TABLE runs ADD COLUMN note TEXT")
    monkeypatch.setattr(st, "MIGRATIONS", st.MIGRATIONS + [extra])
    monkeypatch.setattr(st, "SCHEMA_VERSION", extra[0])
    with Store(p) as s:
        assert s.schema_version() == extra[0]
        cols = {r[1] for r in s.conn.execute("PRAGMA table_info(runs)")}
        assert "note" in cols


def test_runs_scores_roundtrip_and_export(tmp_path):
    with Store(tmp_path / "h.sqlite") as s:
        rid = s.create_run(quality_name="draft", config={"tasks": ["t"]}, variant="scalar_rgb", env=ENV)
        s.add_job_result(rid, "t|s|local|", "t", [score(value=0.5), score("nan_metric", float("nan")),
                                                 dict(score("noisy", 0.7), rep_noise=[0.6, 0.8, 0.7], noise_mean=True),
                                                 dict(score("jumpy", 25.6), perturbed=25.2, chaotic=True)],
                         seconds=1.0)
        s.add_ground_truth(rid, "s", {"scene_hash": "h", "quality": "draft", "spp": 4, "resolution": [32, 32],
                                      "noise": {"radiance_rel_sd_rms": 0.01}, "wall_s": 0.2}, from_cache=False,
                           spp_file=48)
        s.set_status(rid, "complete")
        r = s.get_run(rid)
        assert r["status"] == "complete" and r["finished"] and r["config"] == {"tasks": ["t"]}
        assert r["git_revision"] == "abc" and r["variant"] == "scalar_rgb"
        sc = {x["metric"]: x for x in s.scores(rid)}
        assert sc["rmse"]["value"] == 0.5 and sc["rmse"]["job"] == "t|s|local|"
        assert math.isnan(sc["nan_metric"]["value"])
        # a seed-dependent score's value is the mean over its seeds; the flag comes back (NULL: False)
        assert sc["noisy"]["noise_mean"] is True and sc["noisy"]["rep_noise"] == [0.6, 0.8, 0.7]
        assert sc["rmse"]["noise_mean"] is False
        # the chaos test: the perturbed value and the flag come back (NULL: not tested)
        assert (sc["jumpy"]["perturbed"], sc["jumpy"]["chaotic"]) == (25.2, True)
        assert sc["rmse"]["perturbed"] is None and sc["rmse"]["chaotic"] is None
        assert s.ground_truths(rid)[0]["noise"]["radiance_rel_sd_rms"] == 0.01
        assert (s.ground_truths(rid)[0]["spp"], s.ground_truths(rid)[0]["spp_file"]) == (4, 48)
        out = s.export_json(rid, tmp_path / "run" / "scores.json")
        data = json.loads(out.read_text())  # strict JSON: NaN written as null
        assert data["run"]["id"] == rid and len(data["scores"]) == 4
        assert {x["value"] for x in data["scores"]} == {0.5, 0.7, 25.6, None}


def test_job_result_replaces_and_resume_bookkeeping(tmp_path):
    with Store(tmp_path / "h.sqlite") as s:
        rid = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(rid, "k1", "t", [score(value=1.0)])
        s.add_job_result(rid, "k1", "t", [score(value=2.0)])  # rerun of the same job: no duplicate
        s.add_job_result(rid, "k2", "t", [], error="boom")
        assert [x["value"] for x in s.scores(rid)] == [2.0]
        assert s.done_jobs(rid) == {"k1"}
        assert s.job_errors(rid) == {"k2": "boom"}
        s.add_job_result(rid, "k3", "t", [score(value=3.0)], seconds=2.0, cpu_seconds=3.5)   # two threads
        row = s.conn.execute("SELECT seconds, cpu_seconds FROM jobs WHERE job = 'k3'").fetchone()
        assert tuple(row) == (2.0, 3.5)
        s.add_ground_truth(rid, "scene", {"wall_s": 1.0, "cpu_s": 1.8}, from_cache=False)
        row = s.conn.execute("SELECT render_seconds, render_cpu_seconds FROM ground_truths").fetchone()
        assert tuple(row) == (1.0, 1.8)


def test_resolve_run_references(tmp_path):
    with Store(tmp_path / "h.sqlite") as s:
        with pytest.raises(UserError, match="no runs"):
            s.resolve_run(None)
        a = s.create_run(quality_name="draft", run_id="20250101-000000-aaaa", env=ENV)
        b = s.create_run(quality_name="draft", run_id="20250102-000000-bbbb", env=ENV)
        assert s.resolve_run(None) == b == s.resolve_run("latest")
        assert s.resolve_run("-2") == a
        assert s.resolve_run("20250101") == a
        with pytest.raises(UserError, match="ambiguous"):
            s.resolve_run("2025")
        with pytest.raises(UserError, match="not in"):
            s.resolve_run("nope")


def test_history_and_runs_filter(tmp_path):
    with Store(tmp_path / "h.sqlite") as s:
        for v in (1.0, 3.0):
            rid = s.create_run(quality_name="draft", env=ENV)
            s.add_job_result(rid, "k", "t", [score(value=v, scene="x"), score(value=v + 1, scene="y")])
        s.create_run(quality_name="standard", env=ENV)
        h = s.metric_history("t", "rmse", quality_name="draft")
        assert [r["value"] for r in h] == [1.5, 3.5]
        assert len(s.runs(task="t")) == 2 and len(s.runs()) == 3 and len(s.runs(quality_name="standard")) == 1


def _writer(path, tag, n):
    with Store(path) as s:
        rid = s.create_run(quality_name="draft", config={"w": tag}, env=ENV)
        for i in range(n):
            s.add_job_result(rid, f"{tag}-{i}", "t", [score(value=float(i), scene=f"{tag}{i}", metric=m)
                                                      for m in ("a", "b", "c")])
        s.set_status(rid, "complete")


def test_two_processes_writing_at_once(tmp_path):
    p = tmp_path / "h.sqlite"
    Store(p).close()
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_writer, args=(str(p), tag, 150)) for tag in ("p", "q")]
    for pr in procs:
        pr.start()
    for pr in procs:
        pr.join(60)
    assert [pr.exitcode for pr in procs] == [0, 0]
    with Store(p) as s:
        assert s.integrity_ok()
        runs = s.runs()
        assert len(runs) == 2 and all(r["status"] == "complete" for r in runs)
        assert sorted(r["n_scores"] for r in runs) == [450, 450]
        assert all(len(s.done_jobs(r["id"])) == 150 for r in runs)


def test_compare_directions(tmp_path, capsys):
    from pbrbench.cli.compare import differences
    from pbrbench.cli.main import main

    a = [score("rmse", 1.0), score("psnr", 20.0, better="higher"), score("same", 3.0), score("gone", 1.0)]
    b = [score("rmse", 0.5), score("psnr", 18.0, better="higher"), score("same", 3.0), score("new", 1.0)]
    d = {r["metric"]: r["direction"] for r in differences(a, b)}
    assert d == {"rmse": "better", "psnr": "worse", "same": "same", "gone": "only-a", "new": "only-b"}
    p = tmp_path / "h.sqlite"
    with Store(p) as s:
        ra = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(ra, "k", "t", a)
        rb = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(rb, "k", "t", b)
    assert main(["compare", ra, rb, "--store", str(p)]) == 0
    out = capsys.readouterr().out
    assert "1 better" in out and "1 worse" in out and "rmse" in out and "same" not in out.split("\n", 1)[1]


def test_perf_rows_become_scores():
    from pbrbench.cli.perf import direction, to_scores
    from pbrbench.perf import row

    rows = [row("b", "c", "m", "time", 0.5, "s", better="lower"), row("b", "c", "m", "mask IoU", 0.9, better="higher"),
            row("b", "c", "m", "speedup", 2.0, "x", better="higher")]
    assert [direction(r) for r in rows] == ["lower", "higher", "higher"]
    # nothing is guessed from a name: a row without a declared direction is refused
    with pytest.raises(ValueError, match="no direction"):
        direction({"benchmark": "b", "case": "c", "method": "m", "metric": "speedup", "value": 2.0, "unit": "x"})
    with pytest.raises(ValueError, match="better"):
        row("b", "c", "m", "t", 1.0, better="smaller")
    s = to_scores(rows, 1.0)
    assert s[0]["task"] == "perf" and s[0]["scene"] == "b:c" and s[0]["algorithm"] == "m" and s[0]["unit"] == "s"


def test_compare_uses_the_noise_rule_reads_two_stores_and_names_changed_scenes(tmp_path, capsys):
    from pbrbench.cli.compare import differences
    from pbrbench.cli.main import main

    def noisy(metric, value, se, **kw):
        reps = [value + se * d for d in (-1.2, 0.4, 0.9, -0.1)]
        return dict(score(metric, value, **kw), uncertainty=se, dof=3, replicates=reps)

    a = [noisy("within", 10.0, 0.1), noisy("beyond", 10.0, 0.1), score("rounding", 1e-6), noisy("flip", 3.1, 0.01)]
    b = [noisy("within", 10.25, 0.1), noisy("beyond", 12.0, 0.1), score("rounding", 4e-6),
         dict(noisy("flip", 5.8, 0.01), unstable=True)]
    d = {r["metric"]: r for r in differences(a, b)}
    # 0.25 is 1.8 combined SE: inside t(0.995, 6) * 0.1 * sqrt(2) = 0.52; 2.0 is far outside
    assert d["within"]["direction"] == "same" and d["beyond"]["direction"] == "worse"
    assert d["within"]["limit"] == pytest.approx(3.707 * 0.1 * 2 ** 0.5 + 1e-5 + 1e-4 * 10, rel=1e-3)
    assert d["rounding"]["direction"] == "same" and d["flip"]["direction"] == "unstable"
    pa, pb = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    with Store(pa) as s:
        ra = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(ra, "k", "t", a)
    with Store(pb) as s:
        rb = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(rb, "k", "t", [dict(x, scene_hash="other") for x in b])
    assert main(["compare", ra, rb, "--store", str(pa), "--store-b", str(pb)]) == 0
    out = capsys.readouterr().out
    assert "1 worse" in out and "1 unstable" in out and "different content hashes" in out and "[scene changed]" in out


def test_compare_says_when_one_run_holds_draws_and_the_other_means(tmp_path, capsys):
    # a seed-dependent score stored before the mean over the seeds (the own seed's draw) against
    # one stored after it: the difference includes the change of estimator, and compare says so
    from pbrbench.cli.compare import differences
    from pbrbench.cli.main import main

    draw = dict(score("noisy", 0.70), uncertainty=0.1, dof=3, rep_noise=[0.6, 0.8, 0.75])
    mean = dict(score("noisy", 0.7125), uncertainty=0.05, dof=3, rep_noise=[0.6, 0.8, 0.75], noise_mean=True)
    plain = score("plain", 1.0)
    (dn, dp) = sorted(differences([draw, plain], [mean, plain]), key=lambda r: r["metric"])
    assert dn["estimator_changed"] and not dp["estimator_changed"]
    assert not differences([mean], [mean])[0]["estimator_changed"]
    p = tmp_path / "h.sqlite"
    with Store(p) as s:
        ra = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(ra, "k", "t", [draw])
        rb = s.create_run(quality_name="draft", env=ENV)
        s.add_job_result(rb, "k", "t", [mean])
    assert main(["compare", ra, rb, "--store", str(p), "--all"]) == 0
    out = capsys.readouterr().out
    assert "one seed's draw in one run and the mean over the seeds in the other" in out and "[estimator changed]" in out
