"""Dask faults, each met by a run of the benchmark: a scheduler killed (SIGKILL) at different
moments of a run, and a ``--scheduler`` address that never answers (nothing listens there, or a
socket accepts and never speaks).

Each case is a :class:`Case`: how to reach the fault (``kill``: when the scheduler is killed,
``address``: an address that never answers) and the fewest jobs the run must have stored by then.
:func:`run_case` runs it and returns a :class:`Result` (the error, what reached stderr, the run's
status and stored jobs) that the tests of ``tests/corpus/test_dask_corpus.py`` assert: one line
naming the address and ``--resume RUN``, the status ``interrupted``, no traceback, and a resume
(locally or on a new scheduler) whose scores equal those of a local run.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from pbrbench.settings import Settings
from tests.fakes import FakeSource, settings_for
from tests.fakes import SlowTask as _SlowTask

ROOT = str(Path(__file__).resolve().parents[2])
DELAY = 0.3            # seconds each job sleeps on the cluster, so that a kill lands mid-run
START_TIMEOUT = 120
CONNECT_TIMEOUT = "2s"  # Dask's connect timeout in the cases (an address that never answers)


class SlowTask(_SlowTask):
    """:class:`tests.fakes.SlowTask` on 4 scenes (8 jobs)."""

    scenes = tuple(f"scene_{c}" for c in "abcd")


N_JOBS = len(SlowTask().jobs(None))


def source(root) -> FakeSource:
    """The fake ground truths at draft quality (rendered into ``root``, shared with the workers)."""
    try:
        from pbrbench.quality import get_quality
    except ImportError:  # pragma: no cover - the profiles' older home
        from pbrbench.render.quality import get_quality
    return FakeSource(root, quality=get_quality("draft"))


def dask_cli() -> str | None:
    """The ``dask`` command beside this Python, or on the PATH."""
    exe = Path(sys.executable).with_name("dask")
    return str(exe) if exe.is_file() else shutil.which("dask")


def env() -> dict:
    e = {k: v for k, v in os.environ.items() if not k.startswith("PBRBENCH_")}
    e["PYTHONPATH"] = os.pathsep.join([ROOT, *filter(None, [e.get("PYTHONPATH")])])  # tests.fakes
    e.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    return e


class Cluster:
    """``dask scheduler`` and one ``dask worker`` on localhost, each in its own session."""

    def __init__(self, tmp: Path, name: str = "cluster"):
        dask = dask_cli()
        self.procs: list[subprocess.Popen] = []
        slog = tmp / f"{name}-scheduler.log"
        self.scheduler = self._start([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"],
                                     slog)
        self.address = _wait_for(slog, r"Scheduler at:\s+(tcp://127\.0\.0\.1:\d+)", self.scheduler).group(1)
        self._start([dask, "worker", self.address, "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
                     "--no-dashboard", "--death-timeout", "10"], tmp / f"{name}-worker.log")

    def _start(self, args, log: Path) -> subprocess.Popen:
        with open(log, "w") as f:
            p = subprocess.Popen(args, stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env(),
                                 cwd=ROOT, start_new_session=True)
        self.procs.append(p)
        return p

    def kill_scheduler(self):
        _kill(self.scheduler)

    def stop(self):
        for p in self.procs:
            _kill(p)


def _kill(p: subprocess.Popen):
    if p.poll() is None:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    try:
        p.wait(timeout=30)
    except subprocess.TimeoutExpired:  # pragma: no cover
        pass


def _wait_for(log: Path, pattern: str, proc: subprocess.Popen, timeout: float = START_TIMEOUT) -> re.Match:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        m = re.search(pattern, log.read_text(errors="replace"))
        if m:
            return m
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    raise RuntimeError(f"{log.name}: no {pattern!r} within {timeout} s:\n{log.read_text(errors='replace')[-2000:]}")


def stored_jobs(db: Path, run_id: str | None = None) -> int:
    """Jobs stored without error (of ``run_id``, or of every run)."""
    if not db.is_file():
        return 0
    try:
        with sqlite3.connect(db, timeout=5) as c:
            q, a = ("SELECT count(*) FROM jobs WHERE error IS NULL", ())
            if run_id:
                q, a = q + " AND run = ?", (run_id,)
            return int(c.execute(q, a).fetchone()[0])
    except sqlite3.Error:
        return 0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ----------------------------------------------------------------------------- the cases
@dataclass(frozen=True)
class Case:
    """A fault: ``kill`` names when the scheduler is killed ("connected": once the client is
    connected, before anything runs; "jobs:N": once N jobs are stored; "mid-job:N": a moment into
    the N-th job), ``address`` one that never answers ("closed": nothing listens; "silent": a socket
    accepts connections and never speaks).  ``min_done``: jobs the run must have kept."""

    name: str
    kill: str | None = None
    address: str | None = None
    min_done: int = 0


CASES = [
    Case("scheduler killed before the first render", kill="connected"),
    Case("scheduler killed after 2 jobs", kill="jobs:2", min_done=2),
    Case("scheduler killed in the middle of a job", kill="mid-job:4", min_done=1),
    Case("scheduler address where nothing listens", address="closed"),
    Case("scheduler address that accepts and never answers", address="silent"),
]


@dataclass
class Result:
    """What a case left: the error that ended the run, the run's id, stored status and jobs."""

    error: BaseException | None
    run_id: str | None
    status: str | None
    done: int
    address: str
    settings: object = None
    cluster: Cluster | None = None
    extra: dict = field(default_factory=dict)


def _killer(case: Case, cluster: Cluster, db: Path, starts: Path, stop: threading.Event):
    kind, _, n = case.kill.partition(":")
    n = int(n or 0)
    while not stop.is_set():
        if kind == "jobs" and stored_jobs(db) >= n:
            break
        if kind == "mid-job" and starts.is_file() and len(starts.read_text().splitlines()) >= n:
            time.sleep(DELAY / 3)
            break
        time.sleep(0.02)
    cluster.kill_scheduler()


def run_case(case: Case, tmp: Path) -> Result:
    """Run the fake benchmark into the fault of ``case`` (on a fresh cluster where it needs one)."""
    import dask

    from pbrbench.bench.executors import DaskExecutor
    from pbrbench.bench.run import RunConfig, run_benchmark

    st = settings_for(tmp / "run")
    db = Path(st.store_path())
    starts = tmp / "starts.log"
    cluster = listener = None
    stop = threading.Event()
    killer = None
    if case.address == "closed":
        address = f"tcp://127.0.0.1:{free_port()}"
    elif case.address == "silent":
        listener = socket.socket()
        listener.bind(("127.0.0.1", 0))
        listener.listen(8)
        address = f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    else:
        cluster = Cluster(tmp)
        address = cluster.address
    error = None
    try:
        with dask.config.set({"distributed.comm.timeouts.connect": CONNECT_TIMEOUT}):
            ex = DaskExecutor(scheduler=address, workers=None, variant="scalar_rgb", settings=Settings.from_env())
            try:
                if cluster is not None:
                    ex.client.wait_for_workers(1, timeout=START_TIMEOUT)
                    if case.kill == "connected":
                        cluster.kill_scheduler()
                    else:
                        killer = threading.Thread(target=_killer, args=(case, cluster, db, starts, stop), daemon=True)
                        killer.start()
                run_benchmark(RunConfig(quality="draft", executor="dask", job_cache=False, report=False),
                              settings=st, tasks={"fake": SlowTask(DELAY, str(starts))},
                              source=source(tmp / "gt"), executor=ex, log=lambda m: None)
            except Exception as exc:  # noqa: BLE001 - the case's outcome, asserted by the tests
                error = exc
            finally:
                ex.close()
    finally:
        stop.set()
        if killer is not None:
            killer.join(timeout=30)
        if listener is not None:
            listener.close()
        if cluster is not None:
            cluster.stop()
    run_id = getattr(error, "run_id", None)
    status = None
    if run_id:
        from pbrbench.bench.store import Store

        with Store(db) as s:
            status = s.get_run(run_id)["status"]
    return Result(error, run_id, status, stored_jobs(db, run_id) if run_id else 0, address, settings=st)


def resume(result: Result, tmp: Path, *, on_new_scheduler: bool = False):
    """Resume the case's run, locally or on a new cluster; returns the outcome."""
    from pbrbench.bench.executors import DaskExecutor
    from pbrbench.bench.run import RunConfig, run_benchmark

    cfg = RunConfig(resume=result.run_id, job_cache=False, report=False)
    if not on_new_scheduler:
        return run_benchmark(cfg, settings=result.settings, tasks={"fake": SlowTask()},
                             source=source(tmp / "gt"), log=lambda m: None)
    cluster = Cluster(tmp, "new")
    try:
        ex = DaskExecutor(scheduler=cluster.address, workers=None, variant="scalar_rgb", settings=Settings.from_env())
        try:
            ex.client.wait_for_workers(1, timeout=START_TIMEOUT)
            cfg.executor = "dask"
            return run_benchmark(cfg, settings=result.settings, tasks={"fake": SlowTask()},
                                 source=source(tmp / "gt"), executor=ex, log=lambda m: None)
        finally:
            ex.close()
    finally:
        cluster.stop()


def local_run(tmp: Path):
    """The same benchmark run locally, start to end (the scores a resume must give)."""
    from pbrbench.bench.run import RunConfig, run_benchmark

    return run_benchmark(RunConfig(quality="draft", job_cache=False, report=False), settings=settings_for(tmp),
                         tasks={"fake": SlowTask()}, source=source(tmp / "gt"), log=lambda m: None)


def score_table(outcome) -> dict:
    """Each score's value, standard error and replicates as ``repr`` strings (exact, NaN == NaN)."""
    return {(s["task"], s["scene"], s["condition"], s["algorithm"], s["metric"], s["job"]):
            tuple(repr(s[f]) for f in ("value", "uncertainty", "replicates", "rep_noise", "dof", "bias"))
            for s in outcome.scores}
