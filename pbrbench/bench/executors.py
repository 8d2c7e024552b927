"""Executors: where renders and jobs run.

``local`` runs everything in this process, in order (Mitsuba itself uses all cores).  ``pool``
runs the jobs in ``--workers N`` processes of this machine (default: one per core), one thread
each, and the renders here: the jobs' NumPy code is single-threaded, so a pool of one process per
core is what makes a benchmark's jobs use the machine (:class:`PoolExecutor`).  ``dask``
sends renders and jobs to a Dask distributed cluster (``--scheduler ADDR``, or a LocalCluster of
``--workers N`` processes with one thread each).  A worker plugin sets the Mitsuba variant (the
client's, so every worker renders the same ground truth) and the Dr.Jit thread count once per
worker, and keeps the worker's ground-truth sources, so consecutive jobs on one worker share a
source's memory cache.  Ground truths go into the render cache at the same path on every worker
(shared when the workers share a file system; otherwise each worker renders what it lacks);
scores and figures (PNG bytes) come back to the client, which alone writes the store and the
report.  A worker lost mid-run costs only time: Dask runs its tasks again elsewhere
(:meth:`DaskExecutor.imap`), and since a job is a pure function its scores are the same.  A
scheduler lost mid-run (killed, its machine gone) or one that never answers ends the run with
:class:`SchedulerLost`: one line naming the address and how to resume; the run is recorded as
``interrupted`` (:func:`pbrbench.bench.lifecycle.finish`) and keeps every job stored before.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from contextlib import contextmanager

from pbrbench.bench.source import RENDER_LOCK
from pbrbench.errors import UserError

PLUGIN_NAME = "pbrbench-mitsuba"
CLOSE_TIMEOUT_S = 10      # how long closing a client whose scheduler is gone may take


class SchedulerLost(UserError):
    """The Dask scheduler stopped answering (or never answered); the run can be resumed.

    ``run_status`` is the status the run is recorded with (:func:`pbrbench.bench.lifecycle.finish`
    reads it from the exception that ends the run), and ``run_id`` is set there too, so that the
    message names the run to resume.

    Parameters
    ----------
    address : str
        The scheduler's address (``--scheduler``).
    what : str
        What happened, e.g. ``"lost the connection after 3 of 12 tasks"``.
    """

    run_status = "interrupted"

    def __init__(self, address: str, what: str):
        super().__init__(address, what)
        self.address, self.what = address, what
        self.run_id: str | None = None

    def __str__(self) -> str:
        run = self.run_id or "RUN"
        kept = f"run {self.run_id} is marked interrupted and keeps every job it stored; " if self.run_id else ""
        return (f"--scheduler {self.address}: the Dask scheduler {self.what}; {kept}resume it with `pbrbench run "
                f"--resume {run} --executor dask --scheduler ADDR` once a scheduler runs (`dask scheduler`), or "
                f"`pbrbench run --resume {run}` to finish it locally")


_QUIET = ("distributed", "distributed.client", "distributed.comm", "distributed.core", "distributed.utils",
          "tornado", "asyncio")


def silence_distributed(level: int = logging.CRITICAL) -> list[tuple[logging.Logger, int]]:
    """Silence the ``distributed`` loggers (their tracebacks of a lost connection); returns what
    :func:`restore_loggers` needs to undo it."""
    old = [(lg, lg.level) for lg in map(logging.getLogger, _QUIET)]
    for lg, _ in old:
        lg.setLevel(level)
    return old


def restore_loggers(old: list[tuple[logging.Logger, int]]) -> None:
    """Undo :func:`silence_distributed`."""
    for lg, level in old:
        lg.setLevel(level)


@contextmanager
def quiet_distributed(level: int = logging.CRITICAL):
    """The ``distributed`` loggers silenced while the block runs."""
    old = silence_distributed(level)
    try:
        yield
    finally:
        restore_loggers(old)


def _plugin():
    """This Dask worker's pbrbench plugin, or None outside a worker."""
    if "distributed" not in sys.modules:
        return None          # a Dask worker has imported distributed; a pool or local process need not (0.4 s)
    try:
        from distributed import get_worker

        return get_worker().plugins.get(PLUGIN_NAME)
    except (ImportError, ValueError):
        return None


def job_threads() -> int:
    """BLAS / OpenMP threads a job may use: the worker's share of the cores on a Dask worker,
    1 in a local run (see :func:`blas_threads`)."""
    plugin = _plugin()
    return max(1, int(getattr(plugin, "threads", None) or 1)) if plugin is not None else 1


@contextmanager
def blas_threads(n: int):
    """Limit the BLAS and OpenMP thread pools (threadpoolctl) to ``n`` while a job runs.

    A job's algorithms are NumPy code on images of a few hundred pixels a side, where BLAS threads
    gain little and oversubscribe the machine when several runs or Dask workers share it (each
    process would start one thread per core).  Mitsuba's own pool is set per worker
    (:func:`worker_setup`); a local run renders with all cores.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a declared dependency
        yield
        return
    with threadpool_limits(limits=max(1, int(n))):
        yield


class LocalExecutor:
    """Everything in this process, in order."""

    name = "local"

    def imap(self, fn, arglists):
        for args in arglists:
            yield fn(*args)

    def close(self):
        pass


class PoolExecutor:
    """Jobs in ``workers`` processes of this machine (renders: see ``renders_in_process``), started afresh (``spawn``: the
    parent holds Mitsuba's threads, which a fork would not carry), each set up once by
    :func:`worker_setup` with one Dr.Jit thread.  Arguments and results travel by cloudpickle (an
    ``--algorithm`` loaded from a file path is not importable by name in a worker).

    Results are yielded as each finishes (in no particular order).  A worker that dies (killed, out
    of memory, a crash in a library) breaks the pool: the results yielded before are the caller's
    to keep, and :class:`pbrbench.errors.UserError` says how to resume.  The workers die with this
    process (``prctl(PR_SET_PDEATHSIG)`` on Linux), ``kill -9`` included."""

    name = "pool"
    # renders stay in the run's process: Mitsuba uses every core there, and one process compiles
    # each kernel once (measured on the draft library, 2 cores: 29 s here against 39 s in 2 workers)
    renders_in_process = True

    def __init__(self, *, workers: int | None, variant: str | None, settings):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self.workers = int(workers or os.cpu_count() or 1)
        self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_pool_setup, initargs=(variant, settings))
        self._pending: set = set()
        self._total = self._done = 0

    def imap(self, fn, arglists):
        for args in arglists:
            self.submit(fn, args)
        yield from self.finished(block=True)

    def submit(self, fn, args) -> None:
        """Queue ``fn(*args)`` on a worker now; its result comes from :meth:`finished`.  With
        :meth:`finished` this lets a caller hand out work as it becomes ready (a job as soon as
        its scenes are rendered) and collect what is done in between."""
        import cloudpickle

        self._pending.add(self._pool.submit(_pool_call, cloudpickle.dumps((fn, tuple(args)))))
        self._total += 1

    def finished(self, *, block: bool):
        """The results of the submitted tasks as they finish: those finished already
        (``block=False``), or every one (``block=True``, waiting for each)."""
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        import cloudpickle

        try:
            while self._pending:
                finished, self._pending = wait(self._pending, timeout=None if block else 0,
                                               return_when=FIRST_COMPLETED)
                if not finished:
                    return
                broken = False
                for fut in finished:    # every result that arrived is kept, whatever the set's order
                    try:
                        result = fut.result()
                    except BrokenProcessPool:
                        broken = True
                        continue
                    self._done += 1
                    yield cloudpickle.loads(result)
                if broken:
                    raise UserError(f"--executor pool: a worker process died ({self._done} of {self._total} tasks "
                                    "finished and kept; killed, out of memory or a crash in a library); "
                                    "`pbrbench run --resume RUN` reruns only the missing jobs")
        except BaseException:   # interrupted (Ctrl-C, an error, the consumer stopped): end the work now
            if self._pending:
                self._kill()
            raise

    def _kill(self):
        procs = list((getattr(self._pool, "_processes", None) or {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            with contextlib.suppress(Exception):
                proc.kill()

    def close(self):
        if any(not f.done() for f in self._pending):
            self._kill()
        else:
            self._pool.shutdown(wait=True, cancel_futures=True)


def _pool_setup(variant, settings):
    """A pool worker's set-up: die with the parent, then :func:`worker_setup` with one thread."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, 9)      # PR_SET_PDEATHSIG, SIGKILL
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C is the parent's to handle: it ends the pool
    worker_setup(variant, 1, settings)


def _pool_call(payload: bytes) -> bytes:
    import cloudpickle

    fn, args = cloudpickle.loads(payload)
    return cloudpickle.dumps(fn(*args))


def worker_setup(variant: str | None, threads: int | None, settings, worker=None):
    """Once per worker process: the run's settings (an object, not the environment: the variant
    choice reads them), the Mitsuba variant and the Dr.Jit thread count."""
    with RENDER_LOCK:
        from pbrbench.render import variant as variants
        from pbrbench.render.variant import mitsuba

        if settings is not None:
            variants.configure(settings)

        mitsuba(variant)
        if threads:
            import drjit as dr

            dr.set_thread_count(threads)
    nthreads = getattr(getattr(worker, "state", None), "nthreads", 1)
    if nthreads > 1:
        print(f"pbrbench: worker {worker.address} has {nthreads} threads; pbrbench runs one render or job "
              "at a time per process (start workers with --nthreads 1)", file=sys.stderr)


def worker_source(source):
    """The worker's own instance of ``source`` (so its memory cache survives between jobs)."""
    plugin = _plugin()
    if plugin is None:
        return source
    return plugin.sources.setdefault(source.identity(), source)


def make_worker_plugin(variant: str | None, threads: int | None, settings=None):
    """A Dask WorkerPlugin calling :func:`worker_setup` (class made here: distributed is optional)."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class MitsubaWorkerPlugin(WorkerPlugin):
        name = PLUGIN_NAME

        def __init__(self, args):
            self.args = args
            self.threads = args[1]
            self.sources = {}

        def setup(self, worker):
            self.sources = {}
            worker_setup(*self.args, worker=worker)

    return MitsubaWorkerPlugin((variant, threads, settings))


def worker_probe() -> dict:
    """What a worker process has set up (for tests and diagnostics)."""
    from pbrbench.render.variant import current_choice

    out = {"pid": os.getpid(), "variant": None, "threads": None}
    c = current_choice()
    if c:
        out["variant"] = c.variant
        import drjit as dr

        out["threads"] = dr.thread_count()
    return out


class DaskExecutor:
    """Renders and jobs on a Dask distributed cluster; results come back to this process."""

    name = "dask"

    def __init__(self, *, scheduler: str | None, workers: int | None, variant: str | None, settings):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise UserError("--executor dask needs Dask distributed; install it with "
                            "`pip install 'dask[distributed]'` (or `pip install pbrbench[distributed]`)") from None
        self.cluster = None
        threads = settings.worker_threads
        self.address = scheduler or "LocalCluster"
        self.lost = False
        self._quiet: list | None = None     # the loggers silenced since the scheduler was lost
        self._client = None
        self._client_cls = Client
        # a --scheduler is connected on first use, inside the run: one that never answers leaves an
        # interrupted run whose message says how to resume it, not a run that reads 'running'
        if scheduler:
            self._plugin = make_worker_plugin(variant, threads, settings)
        else:
            n = workers or max(1, (os.cpu_count() or 2) // 2)
            threads = threads or max(1, (os.cpu_count() or 1) // n)
            self._plugin = make_worker_plugin(variant, threads, settings)
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=40)
            self._setup(Client(self.cluster))

    @property
    def client(self):
        """The Dask client, connected to ``--scheduler`` on first use (:class:`SchedulerLost` when
        no scheduler answers there)."""
        if self._client is None:
            self._setup(_connect(self._client_cls, self.address))
        return self._client

    def _setup(self, client):
        """Keep ``client`` and register the worker plugin through it."""
        self._client = client
        plugin = self._plugin
        try:
            if hasattr(client, "register_plugin"):
                client.register_plugin(plugin, name=plugin.name)
            else:  # pragma: no cover - older distributed
                client.register_worker_plugin(plugin, name=plugin.name)
        except (OSError, TimeoutError) as exc:
            if self.cluster is not None:
                raise
            self._lose()
            self.close()
            raise SchedulerLost(self.address, f"stopped answering while the workers were set up "
                                f"({_why(exc)})") from None

    def _lose(self):
        """The scheduler is gone: the client's attempts to reconnect are not reported (the run
        says it in one line)."""
        self.lost = True
        if self._quiet is None:
            self._quiet = silence_distributed()

    def _check_connected(self, done: int, total: int, exc: BaseException | None = None):
        """Raise :class:`SchedulerLost` when the client has lost its scheduler."""
        status = getattr(self.client, "status", "running")
        reason = str(getattr(exc, "reason", "") or "")
        if status == "running" and "scheduler-connection-lost" not in reason:
            return      # connected: an error of a task is the caller's to raise
        self._lose()
        raise SchedulerLost(self.address, f"lost the connection after {done} of {total} task(s) had finished"
                            + (f" ({_why(exc)})" if exc is not None and "scheduler-connection-lost" not in reason
                               else "")) from None

    def imap(self, fn, arglists):
        """``fn(*args)`` for each of ``arglists`` on the cluster, yielded as each finishes (in no
        particular order), each exactly once.

        A worker that dies (killed, out of memory, a crash) loses nothing: the scheduler runs the
        tasks it was running, and the results it held that this process had not fetched yet, again
        on the other workers (or on the worker its nanny restarts); a result being fetched when its
        worker dies is recomputed and fetched again.  Only a task that was running each time
        ``distributed.scheduler.allowed-failures`` + 1 workers died (Dask's default: 3 + 1) is given
        up (``KilledWorker``): the other tasks still run and their results are yielded, then
        :class:`pbrbench.errors.UserError` names the tasks that were given up.

        A scheduler that is gone (before the tasks are sent, or while they run) raises
        :class:`SchedulerLost` at once: every result yielded before is the caller's to keep.
        """
        from concurrent.futures import CancelledError

        from distributed import as_completed
        from distributed.comm import CommClosedError
        from distributed.scheduler import KilledWorker

        arglists = list(arglists)
        if not arglists:
            return
        self._check_connected(0, len(arglists))
        try:
            futures = [self.client.submit(fn, *args, pure=False) for args in arglists]
        except (OSError, TimeoutError, CommClosedError, CancelledError) as exc:
            self._check_connected(0, len(arglists), exc)
            raise
        lost: list[KilledWorker] = []
        done = 0
        try:
            for fut in as_completed(futures):
                try:
                    result = fut.result()
                except KilledWorker as exc:
                    lost.append(exc)
                    continue
                except (CancelledError, CommClosedError, OSError, TimeoutError) as exc:
                    self._check_connected(done, len(futures), exc)
                    raise
                done += 1
                yield result
        finally:
            if not self.lost:
                for f in futures:
                    if not f.done():
                        with contextlib.suppress(Exception):
                            f.cancel()
        if lost:
            n = lost[0].allowed_failures + 1
            raise UserError(f"Dask: {len(lost)} of {len(futures)} tasks given up, each was running on {n} "
                            f"worker{'s' if n != 1 else ''} that died (distributed.scheduler.allowed-failures = "
                            f"{n - 1}): "
                            f"{', '.join(str(e.task) for e in lost)[:300]}; every other task finished. A worker "
                            "dies when it runs out of memory or a library crashes (see the worker logs); "
                            "`pbrbench run --resume RUN` reruns only a run's missing jobs")

    def probe(self) -> list[dict]:
        return list(self.client.run(worker_probe).values())

    def close(self):
        """Close the client (and the LocalCluster); a client whose scheduler is gone is closed
        within :data:`CLOSE_TIMEOUT_S` seconds, without the ``distributed`` loggers' tracebacks."""
        if self._client is None:
            if self.cluster is not None:
                self.cluster.close()
            return
        lost = self.lost or getattr(self._client, "status", "running") not in ("running", "closed")
        with quiet_distributed() if lost else contextlib.nullcontext():
            try:
                self._client.close(timeout=CLOSE_TIMEOUT_S if lost else "60s")
            except Exception:  # noqa: BLE001 - closing must never hide what ended the run
                if not lost:
                    raise
            if self.cluster is not None:
                self.cluster.close()
        if self._quiet is not None:
            restore_loggers(self._quiet)
            self._quiet = None


def _why(exc: BaseException) -> str:
    """The first line of an exception's message (``type: message``)."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0][:200]}" if text else type(exc).__name__


def _seconds(timeout) -> float:
    from dask.utils import parse_timedelta

    return float(parse_timedelta(timeout, default="s") or 30.0)


def _connect(client_cls, address: str):
    """A client of the scheduler at ``address``; :class:`SchedulerLost` when none answers within
    Dask's ``distributed.comm.timeouts.connect`` (e.g. ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=10s``)
    and a few seconds more (a socket that accepts and never speaks makes Dask's own connect wait
    for ever: the attempt is then abandoned in its daemon thread); :class:`UserError` when the
    address is not one."""
    import threading

    import dask

    timeout = dask.config.get("distributed.comm.timeouts.connect", "30s")
    deadline = _seconds(timeout) + 5.0
    got: dict = {}

    def attempt():
        try:
            got["client"] = client_cls(address, timeout=timeout)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            got["error"] = exc

    old = silence_distributed()
    try:
        t = threading.Thread(target=attempt, name="pbrbench-dask-connect", daemon=True)
        t.start()
        t.join(deadline)
    finally:
        restore_loggers(old)
    exc = got.get("error")
    if "client" in got:
        return got["client"]
    if exc is None:
        raise SchedulerLost(address, f"did not answer within {deadline:.0f} s (something there accepts "
                            "connections but does not speak Dask)")
    if isinstance(exc, (OSError, TimeoutError)):
        raise SchedulerLost(address, f"did not answer within {timeout} ({_why(exc)})") from None
    if isinstance(exc, (ValueError, TypeError)):
        raise UserError(f"--scheduler {address}: not a Dask scheduler address ({_why(exc)}); give one like "
                        "tcp://HOST:8786") from None
    raise exc


def make_executor(name: str, *, scheduler=None, workers=None, variant=None, settings):
    if name == "local":
        return LocalExecutor()
    if name == "pool":
        return PoolExecutor(workers=workers, variant=variant, settings=settings)
    if name == "dask":
        return DaskExecutor(scheduler=scheduler, workers=workers, variant=variant, settings=settings)
    raise UserError(f"--executor {name!r}: choose local, pool or dask")
