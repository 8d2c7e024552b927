"""The Dask executor on a cluster of separate processes: the test starts ``dask scheduler`` and two
``dask worker`` processes on localhost, runs the benchmark on them, kills one worker (SIGKILL, its
nanny with it) while it is running a job, and checks that the job was run again on the other
worker, that every job's scores were stored exactly once and that they equal a local run's."""

from __future__ import annotations

import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="Dask distributed is not installed (pip install 'dask[distributed]')")

from pbrbench.bench.executors import DaskExecutor  # noqa: E402
from pbrbench.bench.run import RunConfig, run_benchmark  # noqa: E402
from pbrbench.settings import Settings  # noqa: E402
from tests.fakes import FakeSource, SlowTask, settings_for  # noqa: E402

pytestmark = pytest.mark.slow

ROOT = str(Path(__file__).resolve().parents[2])
DELAY = 1.0        # seconds each job sleeps on the cluster, so that a worker dies mid-job
START_TIMEOUT = 120
RUN_TIMEOUT = 300


class CountingDaskExecutor(DaskExecutor):
    """Counts the results the executor hands to the run, per job."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.yielded: dict[str, int] = {}

    def imap(self, fn, arglists):
        for res in super().imap(fn, arglists):
            if isinstance(res, dict) and "key" in res:
                self.yielded[res["key"]] = self.yielded.get(res["key"], 0) + 1
            yield res


def _dask_cli() -> str:
    exe = Path(sys.executable).with_name("dask")
    found = str(exe) if exe.is_file() else shutil.which("dask")
    if not found:
        pytest.skip("the `dask` command is not installed")
    return found


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PBRBENCH_")}
    env["PYTHONPATH"] = os.pathsep.join([ROOT, *filter(None, [env.get("PYTHONPATH")])])  # tests.fakes
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="3")
    return env


def _start(args: list[str], log: Path) -> subprocess.Popen:
    """A process in its own session (so that killing its group kills a worker's nanny and the
    worker together), stdout and stderr to ``log``."""
    with open(log, "w") as f:
        return subprocess.Popen(args, stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=_env(),
                                cwd=ROOT, start_new_session=True)


def _wait_for(log: Path, pattern: str, proc: subprocess.Popen, timeout: float) -> re.Match:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        m = re.search(pattern, log.read_text(errors="replace"))
        if m:
            return m
        if proc.poll() is not None:
            break
        time.sleep(0.2)
    pytest.fail(f"{log.name}: no {pattern!r} within {timeout} s (exit code {proc.poll()}):\n"
                f"{log.read_text(errors='replace')[-3000:]}")


def _stop(proc: subprocess.Popen):
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:  # pragma: no cover - SIGKILL does not wait for anything
        pass


def _starts(log: Path) -> list[tuple[int, int, str]]:
    if not log.is_file():
        return []
    out = []
    for line in log.read_text().split("\n")[:-1]:  # whole lines only (a job may be writing one)
        pid, ppid, key = line.split(" ", 2)
        out.append((int(pid), int(ppid), key))
    return out


def _score_table(outcome) -> dict:
    """Each score's value, standard error and replicates as ``repr`` strings (round-trip exact
    for floats, and NaN equals NaN)."""
    return {(s["task"], s["scene"], s["condition"], s["algorithm"], s["metric"], s["job"]):
            tuple(repr(s[f]) for f in ("value", "uncertainty", "replicates", "rep_noise", "dof", "bias"))
            for s in outcome.scores}


@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_a_worker_killed_mid_run_loses_no_scores(tmp_path):
    dask = _dask_cli()
    procs: list[subprocess.Popen] = []
    starts = tmp_path / "starts.log"
    killed: dict = {}
    ex = None
    t0 = time.monotonic()
    try:
        sched_log = tmp_path / "scheduler.log"
        sched = _start([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"], sched_log)
        procs.append(sched)
        addr = _wait_for(sched_log, r"Scheduler at:\s+(tcp://127\.0\.0\.1:\d+)", sched, START_TIMEOUT).group(1)
        workers = []
        for i in range(2):
            wlog = tmp_path / f"worker{i}.log"
            w = _start([dask, "worker", addr, "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
                        "--no-dashboard", "--death-timeout", "60"], wlog)
            procs.append(w)
            workers.append(w)
        ex = CountingDaskExecutor(scheduler=addr, workers=None, variant="scalar_rgb", settings=Settings.from_env())
        ex.client.wait_for_workers(2, timeout=START_TIMEOUT)
        victim = workers[0]

        def kill_mid_job():
            """Once the victim's worker (a child of its nanny) has started its second job, kill it
            a moment into that job."""
            t_end = time.monotonic() + RUN_TIMEOUT
            while time.monotonic() < t_end and victim.poll() is None:
                mine = [(pid, key) for pid, ppid, key in _starts(starts) if victim.pid in (pid, ppid)]
                if len(mine) >= 2:
                    time.sleep(DELAY / 4)
                    os.killpg(victim.pid, signal.SIGKILL)
                    killed.update(pid=mine[-1][0], key=mine[-1][1], at=time.monotonic() - t0)
                    return
                time.sleep(0.05)

        killer = threading.Thread(target=kill_mid_job, daemon=True)
        killer.start()
        cfg = RunConfig(quality="draft", executor="dask", job_cache=False, report=False)
        ran: dict = {}

        def run():
            try:
                ran["outcome"] = run_benchmark(cfg, settings=settings_for(tmp_path / "dask"),
                                               tasks={"fake": SlowTask(DELAY, str(starts))},
                                               source=FakeSource(tmp_path / "gt-dask"), executor=ex, log=lambda m: None)
            except BaseException as exc:  # noqa: BLE001 - re-raised below, in the test's thread
                ran["error"] = exc

        runner = threading.Thread(target=run, daemon=True)  # so that a hung cluster fails the test
        runner.start()
        runner.join(timeout=RUN_TIMEOUT)
        if runner.is_alive():
            pytest.fail(f"the run on the cluster did not finish within {RUN_TIMEOUT} s; worker starts: "
                        f"{_starts(starts)}")
        if "error" in ran:
            raise ran["error"]
        o_d = ran["outcome"]
        killer.join(timeout=10)
        wall = time.monotonic() - t0
        n_alive = len(ex.client.scheduler_info()["workers"])
    finally:
        if ex is not None:
            ex.close()
        for p in procs:
            _stop(p)
    print(f"\ncluster run: {wall:.1f} s from the scheduler's start; worker killed at {killed.get('at', 0):.1f} s")

    # the victim died while it was running a job, and that job started again on the other worker
    assert killed, f"the victim never started a second job: {_starts(starts)}"
    assert victim.returncode == -signal.SIGKILL and n_alive == 1
    reruns = [(pid, ppid) for pid, ppid, key in _starts(starts) if key == killed["key"]]
    assert len(reruns) == 2 and reruns[0][0] == killed["pid"] and victim.pid not in reruns[1], reruns
    jobs = [j.key for j in SlowTask().jobs(None)]
    assert {key for _, _, key in _starts(starts)} == set(jobs)

    # every job's result came back once, was stored once, and without an error
    assert not o_d.errors and o_d.n_jobs == len(jobs) == 12
    assert ex.yielded == dict.fromkeys(jobs, 1)
    with sqlite3.connect(tmp_path / "dask" / "h.sqlite") as db:
        dup = db.execute("SELECT job, algorithm, metric, COUNT(*) FROM scores WHERE run = ? "
                         "GROUP BY job, scene, condition, algorithm, metric HAVING COUNT(*) > 1", (o_d.run_id,)).fetchall()
        done = db.execute("SELECT job FROM jobs WHERE run = ? AND error IS NULL", (o_d.run_id,)).fetchall()
    assert dup == [] and sorted(r[0] for r in done) == sorted(jobs)

    # the same scores as a local run of the same configuration (no delay: it changes no score)
    o_l = run_benchmark(RunConfig(quality="draft", job_cache=False, report=False), settings=settings_for(tmp_path / "local"),
                        tasks={"fake": SlowTask()}, source=FakeSource(tmp_path / "gt-local"), log=lambda m: None)
    d, loc = _score_table(o_d), _score_table(o_l)
    assert len(d) == 12 * 2 * 2 and d == loc  # bit-identical, not approximately equal
