"""A run's life in the store: its process and heartbeat are recorded, a dead run reads
``interrupted`` (SIGKILL), SIGTERM ends a run as interrupted and removes the scratch directories,
a live run cannot be resumed twice, and the final status never hides the error that ended a run."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from datetime import UTC, datetime, timedelta

import pytest

from pbrbench.bench import lifecycle as L
from pbrbench.bench import liveness as V
from pbrbench.bench.store import Store
from pbrbench.errors import DiskError, UserError


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _iso(dt):
    return dt.isoformat(timespec="microseconds")


def test_effective_status_of_running_runs():
    now = datetime.now(UTC)
    me = V.this_process()
    host = socket.gethostname()
    live = {"status": "running", **me, "heartbeat": _iso(now)}
    assert V.effective_status(live) == "running"
    assert V.effective_status(dict(live, pid=_dead_pid())) == "interrupted"
    if me["pid_start"]:  # a reused pid: same number, another process
        assert V.effective_status(dict(live, pid_start="other-boot:1")) == "interrupted"
    far = {"status": "running", "host": host + "-elsewhere", "pid": 1, "pid_start": None}
    assert V.effective_status(dict(far, heartbeat=_iso(now - timedelta(seconds=30)))) == "running"
    assert V.effective_status(dict(far, heartbeat=_iso(now - timedelta(seconds=V.STALE_S + 60)))) == "interrupted"
    old = {"status": "running", "time": _iso(now - timedelta(hours=3))}   # recorded by an older pbrbench
    assert V.effective_status(old) == "interrupted"
    assert V.effective_status({"status": "running", "time": _iso(now)}) == "running"
    for st in ("complete", "failed", "interrupted", "complete-with-errors"):
        assert V.effective_status({"status": st, "pid": _dead_pid(), "host": host}) == st


def test_store_reads_liveness_and_heartbeat_beats(tmp_path):
    with Store(tmp_path / "h.sqlite") as s:
        rid = s.create_run(quality_name="draft", env={})
        hb = L.start(s, rid, interval=0.05)
        run = s.get_run(rid)
        assert run["pid"] == os.getpid() and run["host"] == socket.gethostname() and run["status"] == "running"
        first = run["heartbeat"]
        time.sleep(0.4)
        assert s.get_run(rid)["heartbeat"] > first
        with pytest.raises(UserError, match="still running"):
            L.check_resumable(s, rid)
        assert L.finish(s, rid, "complete", heartbeat=hb)
        assert s.get_run(rid)["status"] == "complete"
        # a run of a dead process
        rid2 = s.create_run(quality_name="draft", env={})
        s.set_process(rid2, host=socket.gethostname(), pid=_dead_pid(), pid_start=None)
        r = s.get_run(rid2)
        assert r["status"] == "interrupted" and r["stored_status"] == "running"
        assert [x["status"] for x in s.runs()] == ["complete", "interrupted"]
        assert L.check_resumable(s, rid2)["id"] == rid2


def test_finish_reports_a_store_that_cannot_be_written(tmp_path):
    class Broken:
        path = tmp_path / "h.sqlite"

        def set_status(self, *a, **k):
            raise DiskError("results database h.sqlite: cannot write (database or disk is full); ...")

    said = []
    assert not L.finish(Broken(), "r1", "complete", log=said.append)
    assert len(said) == 1 and "could not record status 'complete' of run r1" in said[0] and "\n" not in said[0]


def test_preflight_refuses_an_unwritable_out(tmp_path, monkeypatch):
    from pbrbench.settings import Settings

    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(DiskError, match=r"--out .*file.*Not a directory"):
        L.preflight(Settings.from_env(out=f))
    import pathlib

    def ro(self, data):
        raise OSError(30, "Read-only file system", str(self))

    monkeypatch.setattr(pathlib.Path, "write_bytes", ro)
    with pytest.raises(DiskError, match="Read-only file system; the file system is read-only"):
        L.preflight(Settings.from_env(out=tmp_path / "out"))


SLOW_RUN = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from pbrbench.cli.main import signals_as_interrupts
    from pbrbench.scratch import scratch_dir
    from tests.fakes import FakeTask, fake_run

    class Slow(FakeTask):
        def run_job(self, job, gts, **kw):
            print("JOB", scratch_dir("mesh"), flush=True)
            time.sleep(120)

    with signals_as_interrupts():
        try:
            fake_run(Path(sys.argv[1]), Slow())
        except KeyboardInterrupt:
            sys.exit(130)
""")


def _start_slow(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.getcwd(), os.environ.get("PYTHONPATH", "")]))
    p = subprocess.Popen([sys.executable, "-c", SLOW_RUN, str(tmp_path)], stdout=subprocess.PIPE, text=True, env=env,
                         cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    line = p.stdout.readline()
    assert line.startswith("JOB "), line
    return p, line.split(" ", 1)[1].strip()


@pytest.mark.slow
def test_sigkill_leaves_an_interrupted_run_that_resumes(tmp_path):
    from tests.fakes import fake_run

    p, scratch = _start_slow(tmp_path)
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    with Store(tmp_path / "h.sqlite") as s:
        (run,) = s.runs()
        assert run["stored_status"] == "running" and run["status"] == "interrupted"
    from pbrbench.scratch import remove_stale

    assert scratch in remove_stale(os.path.dirname(scratch))  # a killed process's scratch is swept
    out = fake_run(tmp_path, resume=run["id"])
    with Store(tmp_path / "h.sqlite") as s:
        assert s.get_run(out.run_id)["status"] == "complete"


def test_history_shows_interrupted_and_offers_resume(tmp_path, capsys):
    from pbrbench.cli.main import main

    with Store(tmp_path / "h.sqlite") as s:
        rid = s.create_run(quality_name="draft", env={})
        s.set_process(rid, host=socket.gethostname(), pid=_dead_pid(), pid_start=None)
    assert main(["history", "--store", str(tmp_path / "h.sqlite")]) == 0
    out = capsys.readouterr().out
    assert "interrupted" in out and f"pbrbench run --resume {rid}" in out


@pytest.mark.slow
def test_sigterm_marks_interrupted_and_removes_scratch(tmp_path):
    p, scratch = _start_slow(tmp_path)
    assert os.path.isdir(scratch)
    os.kill(p.pid, signal.SIGTERM)
    assert p.wait(timeout=60) == 130
    assert not os.path.exists(scratch)
    with Store(tmp_path / "h.sqlite") as s:
        (run,) = s.runs()
        assert run["stored_status"] == "interrupted" and run["status"] == "interrupted"


def test_stale_scratch_of_dead_processes_is_swept(tmp_path):
    from pbrbench.scratch import remove_stale

    dead = tmp_path / f"pbrbench-mesh-{_dead_pid()}-abc"
    mine = tmp_path / f"pbrbench-mesh-{os.getpid()}-abc"
    other = tmp_path / "unrelated-dir"
    for d in (dead, mine, other):
        d.mkdir()
    removed = remove_stale(str(tmp_path))
    assert removed == [str(dead)] and mine.is_dir() and other.is_dir()


def test_compare_with_an_interrupted_run_says_so_in_one_line(tmp_path, capsys):
    """The interrupted run B's missing scores are not silently 'only-a': one line says B is
    interrupted, how many jobs it stored, and how to finish it."""
    from pbrbench.cli.main import main
    from tests.fakes import fake_run

    full = fake_run(tmp_path)
    with Store(tmp_path / "h.sqlite") as s:
        rid = s.create_run(quality_name="draft", env={})
        first = next(r for r in s.scores(full.run_id))
        s.add_job_result(rid, first["job"], first["task"], [r for r in s.scores(full.run_id) if r["job"] == first["job"]])
        s.set_process(rid, host=socket.gethostname(), pid=_dead_pid(), pid_start=None)
    assert main(["compare", full.run_id, rid, "--store", str(tmp_path / "h.sqlite")]) == 0
    out = capsys.readouterr().out
    notes = [ln for ln in out.splitlines() if ln.startswith("note: run")]
    assert notes == [f"note: run B {rid} is interrupted (1 job stored): the scores it lacks show as only-a; "
                     f"finish it with `pbrbench run --resume {rid}` and compare again"], out
    assert "only-a" in out.splitlines()[0]
    capsys.readouterr()
    assert main(["compare", full.run_id, full.run_id, "--store", str(tmp_path / "h.sqlite")]) == 0
    assert "note: run" not in capsys.readouterr().out   # two finished runs: no note


def test_a_lost_scheduler_records_interrupted_not_failed(tmp_path):
    """lifecycle.finish, called while SchedulerLost propagates, records 'interrupted' and names the run."""
    from pbrbench.bench.executors import SchedulerLost

    with Store(tmp_path / "h.sqlite") as s:
        rid = s.create_run(quality_name="draft", env={})
        exc = SchedulerLost("tcp://127.0.0.1:1", "lost the connection")
        try:
            try:
                raise exc
            finally:
                L.finish(s, rid, "failed")
        except SchedulerLost:
            pass
        assert s.get_run(rid)["status"] == "interrupted" and f"--resume {rid}" in str(exc)
        try:
            try:
                raise RuntimeError("a bug")
            finally:
                L.finish(s, rid, "failed")
        except RuntimeError:
            pass
        assert s.get_run(rid)["status"] == "failed"
