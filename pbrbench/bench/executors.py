"""Executors: where renders and jobs run.

``local`` runs everything in this process, in order (Mitsuba itself uses all cores).  ``dask``
sends renders and jobs to a Dask distributed cluster (``--scheduler ADDR``, or a LocalCluster of
``--workers N`` processes with one thread each).  A worker plugin sets the Mitsuba variant (the
client's, so every worker renders the same ground truth) and the Dr.Jit thread count once per
worker, and keeps the worker's ground-truth sources, so consecutive jobs on one worker share a
source's memory cache.  Ground truths go into the render cache at the same path on every worker
(shared when the workers share a file system; otherwise each worker renders what it lacks);
scores and figures (PNG bytes) come back to the client, which alone writes the store and the
report.  A worker lost mid-run costs only time: Dask runs its tasks again elsewhere
(:meth:`DaskExecutor.imap`), and since a job is a pure function its scores are the same.
"""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager

from pbrbench.bench.source import RENDER_LOCK
from pbrbench.errors import UserError

PLUGIN_NAME = "pbrbench-mitsuba"


def _plugin():
    """This Dask worker's pbrbench plugin, or None outside a worker."""
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


def worker_setup(variant: str | None, threads: int | None, env: dict, worker=None):
    """Once per worker process: environment, Mitsuba variant and Dr.Jit thread count."""
    os.environ.update(env)
    with RENDER_LOCK:
        from pbrbench.render.variant import mitsuba

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


def make_worker_plugin(variant: str | None, threads: int | None, env: dict | None = None):
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

    return MitsubaWorkerPlugin((variant, threads, dict(env or {})))


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

    def __init__(self, *, scheduler: str | None, workers: int | None, variant: str | None, settings=None):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise UserError("--executor dask needs Dask distributed; install it with "
                            "`pip install 'dask[distributed]'` (or `pip install pbrbench[distributed]`)") from None
        from pbrbench.settings import Settings

        settings = settings or Settings.from_env()
        self.cluster = None
        threads = settings.worker_threads
        if scheduler:
            self.client = Client(scheduler, timeout="30s")
        else:
            n = workers or max(1, (os.cpu_count() or 2) // 2)
            threads = threads or max(1, (os.cpu_count() or 1) // n)
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=40)
            self.client = Client(self.cluster)
        plugin = make_worker_plugin(variant, threads, settings.worker_env())
        if hasattr(self.client, "register_plugin"):
            self.client.register_plugin(plugin, name=plugin.name)
        else:  # pragma: no cover - older distributed
            self.client.register_worker_plugin(plugin, name=plugin.name)

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
        """
        from distributed import as_completed
        from distributed.scheduler import KilledWorker

        futures = [self.client.submit(fn, *args, pure=False) for args in arglists]
        lost: list[KilledWorker] = []
        try:
            for fut in as_completed(futures):
                try:
                    result = fut.result()
                except KilledWorker as exc:
                    lost.append(exc)
                    continue
                yield result
        finally:
            for f in futures:
                if not f.done():
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
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_executor(name: str, *, scheduler=None, workers=None, variant=None, settings=None):
    if name == "local":
        return LocalExecutor()
    if name == "dask":
        return DaskExecutor(scheduler=scheduler, workers=workers, variant=variant, settings=settings)
    raise UserError(f"--executor {name!r}: choose local or dask")
