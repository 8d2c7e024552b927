"""Run the benchmark: plan jobs, render missing ground truths, run and score, store, report.

Flow of :func:`run_benchmark`:

1. the tasks' :meth:`~pbrbench.tasks.base.Task.jobs` at the chosen quality (the plan);
2. every ground truth the plan needs is looked up in the render cache and the missing ones are
   rendered (progress bar over scenes);
3. the jobs run (progress bar), each a pure function of (task, job, ground truths, seed); as
   each finishes its scores go into the store in one transaction and its figures into
   ``<out>/<run>/figures/<job>/``, so an interrupted run keeps everything completed;
4. the run is marked complete, exported as ``<out>/<run>/scores.json`` and the HTML report
   written to ``<out>/<run>/index.html``; scores are compared with the baselines.

Resuming (``--resume RUN``) reuses the run's stored configuration and skips the jobs it has
already stored.

Executors: ``local`` runs everything in this process (Mitsuba itself uses all cores).
``dask`` sends renders and jobs to a Dask distributed cluster (``--scheduler ADDR``, or a
LocalCluster of ``--workers N`` processes with one thread each).  A worker plugin sets the
Mitsuba variant (the client's, so every worker renders the same ground truth) and the Dr.Jit
thread count once per worker, and a process-wide lock guarantees no two Python threads of a
worker ever render or run a job at once (Mitsuba is not safe to drive from several threads,
notes/mitsuba.md §8.3).  Ground truths go into the render cache at the same path on every
worker (shared when the workers share a file system; otherwise each worker renders what it
lacks); scores and figures (PNG bytes) are shipped back to the client, which alone writes the
store and the report.
"""

from __future__ import annotations

import os
import sys
import threading
import time
import traceback
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

from pbrbench.bench.store import Store
from pbrbench.errors import UserError

_LOCK = threading.RLock()          # one render / job at a time per process
_GT_LRU: OrderedDict = OrderedDict()
_GT_LRU_SIZE = 4


# ----------------------------------------------------------------------------- configuration
@dataclass
class RunConfig:
    """Everything that decides what a run computes (stored with the run as JSON)."""

    tasks: list[str] | None = None
    quality: str = "standard"
    seed: int = 0
    executor: str = "local"
    scheduler: str | None = None
    workers: int | None = None
    out: str = "reports"
    store: str | None = None
    cache: str | None = None
    variant: str | None = None
    resume: str | None = None
    report: bool = True
    check: bool = False
    update_baselines: bool = False
    progress: bool | None = None     # None: bars when stderr is a terminal (or PBRBENCH_PROGRESS=1)

    def store_path(self) -> Path:
        from pbrbench.bench.store import resolve_store_path

        return resolve_store_path(self.store, self.out)

    def recorded(self) -> dict:
        return {"tasks": self.tasks, "quality": self.quality, "seed": self.seed, "executor": self.executor,
                "workers": self.workers, "variant": self.variant}


@dataclass
class RunOutcome:
    run_id: str
    report: Path | None
    scores: list[dict]
    n_jobs: int
    n_skipped: int
    errors: dict[str, str]
    comparison: object | None = None
    render_seconds: float = 0.0
    job_seconds: float = 0.0
    wall_seconds: float = 0.0
    renders: int = 0
    task_info: dict = field(default_factory=dict)


def _log(msg: str):
    print(f"pbrbench: {msg}", file=sys.stderr, flush=True)


def _progress_enabled(flag: bool | None) -> bool:
    if flag is not None:
        return flag
    return sys.stderr.isatty() or os.environ.get("PBRBENCH_PROGRESS") == "1"


def _bar(total: int, desc: str, unit: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not enabled, leave=True, dynamic_ncols=True)


# ----------------------------------------------------------------------------- ground truths
class GroundTruthSource:
    """Where ground truths come from: the render cache, rendering what is missing.

    Picklable (it is shipped to Dask workers).  Tests substitute a subclass that synthesises
    ground truths without rendering.
    """

    def __init__(self, quality: str, cache_root: str | None = None, variant: str | None = None):
        self.quality = quality
        self.cache_root = str(cache_root) if cache_root else None
        self.variant = variant

    def identity(self) -> str:
        return f"cache:{self.cache_root}:{self.quality}:{self.variant}"

    def resolve_variant(self) -> str:
        """The variant the renders use (decided without importing mitsuba)."""
        from pbrbench.render.variant import choose_variant, current_choice

        if self.variant is None:
            choice = current_choice() or choose_variant(None)
            self.variant = choice.variant
        return self.variant

    def specs(self, names: list[str]) -> dict:
        """Scene name -> SceneSpec for every name (library names, sweep members, families of one)."""
        from pbrbench.scene.load import load_library, resolve

        lib = load_library()
        out = {}
        for n in names:
            if n in lib:
                out[n] = lib[n]
                continue
            got = resolve([n])
            if len(got) != 1:
                raise UserError(f"scene {n!r} names a family of {len(got)} scenes; a job needs one scene")
            out[n] = got[0]
        return out

    def _cache(self):
        from pbrbench.render.cache import RenderCache

        return RenderCache(self.cache_root)

    def cached_meta(self, spec) -> dict | None:
        """The cached ground truth's metadata, or None if it has to be rendered (no render here)."""
        import json

        from pbrbench.render.cache import cache_key

        cache = self._cache()
        d = cache.entry_dir(cache_key(spec, self.quality, self.resolve_variant()))
        if (d / "gt.json").is_file() and (d / "gt.exr").is_file():
            try:
                return json.loads((d / "gt.json").read_text())
            except (OSError, ValueError):
                return None
        return None

    def render(self, spec) -> tuple[dict, bool]:
        """Render ``spec`` into the cache if missing; returns (metadata, from_cache)."""
        from pbrbench.render.cache import ground_truth

        with _LOCK:
            gt, cached = ground_truth(spec, self.quality, cache=self._cache(), variant=self.resolve_variant())
        _remember(self, spec, gt)
        return dict(gt.meta), cached

    def load(self, spec):
        """The ground truth (from the cache; rendered if missing or damaged)."""
        from pbrbench.render.cache import ground_truth

        with _LOCK:
            gt, _ = ground_truth(spec, self.quality, cache=self._cache(), variant=self.resolve_variant())
        return gt


def _remember(source, spec, gt):
    key = (source.identity(), spec.content_hash())
    _GT_LRU[key] = gt
    _GT_LRU.move_to_end(key)
    while len(_GT_LRU) > _GT_LRU_SIZE:
        _GT_LRU.popitem(last=False)


def _load_gt(source, spec):
    key = (source.identity(), spec.content_hash())
    if key in _GT_LRU:
        _GT_LRU.move_to_end(key)
        return _GT_LRU[key]
    gt = source.load(spec)
    _remember(source, spec, gt)
    return gt


# ----------------------------------------------------------------------------- planning
def load_tasks(names: list[str] | None, log=None) -> dict:
    """Task instances by name.  Without names: every task module that is installed (a module not
    written yet is skipped with a notice); a named task that cannot be imported is an error."""
    from pbrbench.tasks import TASK_MODULES, get_tasks

    if names:
        try:
            return get_tasks(names)
        except ModuleNotFoundError as e:
            raise UserError(f"--tasks: task module {e.name!r} is not available ({e})") from None
    out, skipped = {}, []
    for n in TASK_MODULES:
        try:
            out.update(get_tasks([n]))
        except ModuleNotFoundError as e:
            if e.name != f"pbrbench.tasks.{n}":
                raise
            skipped.append(n)
    if skipped and log:
        log(f"task module(s) not available, skipped: {', '.join(skipped)}")
    return out


def plan(tasks: dict, quality: str) -> list:
    """Every job of every task, ordered by scene (so consecutive jobs share ground truths)."""
    jobs = []
    for name, task in tasks.items():
        tj = task.jobs(quality)
        for j in tj:
            if j.task != name:
                raise ValueError(f"task {name!r}: job {j.key!r} names task {j.task!r}; Job.task must be the task's name")
        jobs += tj
    keys = [j.key for j in jobs]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"duplicate job keys {dup[:3]}: give jobs distinct params")
    return sorted(jobs, key=lambda j: (j.scene, j.extra_scenes, j.task, j.condition, j.params))


def needed_scenes(jobs) -> list[str]:
    seen: dict[str, None] = {}
    for j in jobs:
        seen.setdefault(j.scene)
        for e in j.extra_scenes:
            seen.setdefault(e)
    return list(seen)


def task_info(tasks: dict) -> dict:
    """What the report needs to know about each task (stored with the run's configuration)."""
    return {n: {"description": t.description, "algorithms": list(t.algorithms), "conditions": list(t.conditions),
                "headline_metric": t.headline_metric, "headline_better": t.headline_better}
            for n, t in tasks.items()}


# ----------------------------------------------------------------------------- one job
def _check_scores(job, scores) -> list[dict]:
    out = []
    for s in scores:
        d = s.as_dict() if hasattr(s, "as_dict") else dict(s)
        if d["task"] != job.task:
            raise ValueError(f"score {d['metric']!r} names task {d['task']!r}, job is {job.task!r}")
        if d.get("better") not in ("lower", "higher"):
            raise ValueError(f"score {d['metric']!r}: better={d.get('better')!r}; use 'lower' or 'higher'")
        d["value"] = float(d["value"])
        d["seconds"] = float(d.get("seconds") or 0.0)
        out.append(d)
    return out


def execute_job(task, job, specs: dict, source, seed: int, job_dir: str) -> dict:
    """Run one job and draw its figures (in this process or on a worker); never raises."""
    from pbrbench.report.figures import job_figures

    t0 = time.perf_counter()
    c0 = time.process_time()
    try:
        with _LOCK:
            gts = {n: _load_gt(source, specs[n]) for n in (job.scene, *job.extra_scenes)}
            result = task.run_job(job, gts, seed=seed)
        scores = _check_scores(job, result.scores)
        files, manifest = job_figures(result, job_dir)
        error = None
    except Exception:  # noqa: BLE001 - a failing job is recorded, the run goes on
        scores, files, manifest = [], {}, None
        error = traceback.format_exc(limit=8)
    return {"key": job.key, "task": job.task, "scores": scores, "files": files, "manifest": manifest,
            "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0, "error": error}


def _render_task(source, spec) -> tuple[str, dict, bool]:
    meta, cached = source.render(spec)
    return spec.name, meta, cached


# ----------------------------------------------------------------------------- executors
class LocalExecutor:
    """Everything in this process, in order."""

    name = "local"

    def __init__(self, variant: str | None = None):
        self.variant = variant

    def imap(self, fn, arglists):
        for args in arglists:
            yield fn(*args)

    def close(self):
        pass


def worker_setup(variant: str | None, threads: int | None, cache_root: str | None, env: dict, worker=None):
    """Once per worker process: environment, Mitsuba variant and Dr.Jit thread count."""
    os.environ.update(env)
    if variant:
        os.environ["PBRBENCH_VARIANT"] = variant
    if cache_root:
        os.environ["PBRBENCH_CACHE"] = cache_root
    threads = threads or int(os.environ.get("PBRBENCH_WORKER_THREADS", "0")) or None
    with _LOCK:
        from pbrbench.render.variant import mitsuba

        mitsuba(variant)
        if threads:
            import drjit as dr

            dr.set_thread_count(threads)
    nthreads = getattr(getattr(worker, "state", None), "nthreads", 1)
    if nthreads > 1:
        print(f"pbrbench: worker {worker.address} has {nthreads} threads; pbrbench runs one render or job "
              "at a time per process (start workers with --nthreads 1)", file=sys.stderr)


def make_worker_plugin(variant: str | None, threads: int | None, cache_root: str | None, env: dict | None = None):
    """A Dask WorkerPlugin calling :func:`worker_setup` (class made here: distributed is optional)."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class MitsubaWorkerPlugin(WorkerPlugin):
        name = "pbrbench-mitsuba"

        def __init__(self, args):
            self.args = args

        def setup(self, worker):
            worker_setup(*self.args, worker=worker)

    return MitsubaWorkerPlugin((variant, threads, cache_root, dict(env or {})))


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

    def __init__(self, *, scheduler: str | None, workers: int | None, variant: str | None, cache_root: str | None):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise UserError("--executor dask needs Dask distributed; install it with "
                            "`pip install 'dask[distributed]'` (or `pip install pbrbench[distributed]`)") from None
        self.cluster = None
        if scheduler:
            self.client = Client(scheduler, timeout="30s")
            threads = None
        else:
            n = workers or max(1, (os.cpu_count() or 2) // 2)
            threads = max(1, (os.cpu_count() or 1) // n)
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=40)
            self.client = Client(self.cluster)
        env = {k: os.environ[k] for k in ("PBRBENCH_SCENES", "DRJIT_LIBLLVM_PATH") if k in os.environ}
        plugin = make_worker_plugin(variant, threads, cache_root, env)
        if hasattr(self.client, "register_plugin"):
            self.client.register_plugin(plugin, name=plugin.name)
        else:  # pragma: no cover - older distributed
            self.client.register_worker_plugin(plugin, name=plugin.name)

    def imap(self, fn, arglists):
        from distributed import as_completed

        futures = [self.client.submit(fn, *args, pure=False) for args in arglists]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        finally:
            for f in futures:
                if not f.done():
                    f.cancel()

    def probe(self) -> list[dict]:
        return list(self.client.run(worker_probe).values())

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_executor(cfg: RunConfig, variant: str | None):
    if cfg.executor == "local":
        return LocalExecutor(variant)
    if cfg.executor == "dask":
        return DaskExecutor(scheduler=cfg.scheduler, workers=cfg.workers, variant=variant, cache_root=cfg.cache)
    raise UserError(f"--executor {cfg.executor!r}: choose local or dask")


# ----------------------------------------------------------------------------- the run
def _write_files(run_dir: Path, files: dict[str, bytes]):
    for rel, data in files.items():
        p = run_dir / "figures" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(p.name + ".tmp")
        tmp.write_bytes(data)
        os.replace(tmp, p)


def run_benchmark(cfg: RunConfig, *, tasks: dict | None = None, source: GroundTruthSource | None = None,
                  executor=None, log=None) -> RunOutcome:
    """Run (or resume) a benchmark; see the module docstring.  ``tasks``: name -> Task instance."""
    from pbrbench.render.quality import get_quality
    from pbrbench.report.figures import slug

    log = log or _log
    t_start = time.perf_counter()
    store = Store(cfg.store_path())
    prior_done: set[str] = set()
    if cfg.resume:
        run_id = store.resolve_run(cfg.resume)
        run = store.get_run(run_id)
        rc = run["config"]
        cfg.tasks, cfg.quality, cfg.seed = rc.get("tasks"), rc.get("quality", cfg.quality), rc.get("seed", cfg.seed)
        cfg.variant = cfg.variant or rc.get("variant")
        prior_done = store.done_jobs(run_id)
    get_quality(cfg.quality)
    if tasks is None:
        tasks = load_tasks(cfg.tasks, log)
    if not tasks:
        raise UserError("no task to run; pass --tasks NAME (see `pbrbench run --help`)")
    source = source or GroundTruthSource(cfg.quality, cfg.cache, cfg.variant)
    source.quality = cfg.quality
    variant = source.resolve_variant()
    info = task_info(tasks)
    config = dict(cfg.recorded(), tasks=list(tasks), variant=variant, task_info=info)
    if cfg.resume:
        store.set_status(run_id, "running")
    else:
        run_id = store.create_run(quality=cfg.quality, config=config, variant=variant)
    run_dir = Path(cfg.out) / run_id
    run_dir.mkdir(parents=True, exist_ok=True)
    progress = _progress_enabled(cfg.progress)

    jobs = plan(tasks, cfg.quality)
    todo = [j for j in jobs if j.key not in prior_done]
    names = needed_scenes(jobs)
    specs = source.specs(names)
    outcome = RunOutcome(run_id, None, [], len(jobs), len(jobs) - len(todo), {}, task_info=info)
    ex = executor or make_executor(cfg, variant)
    status = "failed"
    try:
        # ---- ground truths
        t0 = time.perf_counter()
        metas: dict[str, tuple[dict, bool]] = {}
        missing = []
        for n in names:
            m = source.cached_meta(specs[n])
            if m is None:
                missing.append(n)
            else:
                metas[n] = (m, True)
        if missing:
            with _bar(len(missing), f"render ({cfg.quality})", "scene", progress) as bar:
                for name, meta, cached in ex.imap(_render_task, [(source, specs[n]) for n in missing]):
                    metas[name] = (meta, cached)
                    outcome.renders += int(not cached)
                    bar.set_postfix_str(name[:40])
                    bar.update(1)
        for n in names:
            store.add_ground_truth(run_id, n, metas[n][0], from_cache=metas[n][1])
        outcome.render_seconds = time.perf_counter() - t0

        # ---- jobs
        t0 = time.perf_counter()
        args = [(tasks[j.task], j, {n: specs[n] for n in (j.scene, *j.extra_scenes)}, source, cfg.seed, slug(j.key))
                for j in todo]
        with _bar(len(todo), "jobs", "job", progress) as bar:
            for res in ex.imap(execute_job, args):
                if res["files"]:
                    _write_files(run_dir, res["files"])
                store.add_job_result(run_id, res["key"], res["task"], res["scores"], seconds=res["seconds"],
                                     error=res["error"])
                if res["error"]:
                    outcome.errors[res["key"]] = res["error"]
                    last = [ln for ln in res["error"].strip().splitlines() if ln.strip()][-1:]
                    msg = f"job failed: {res['key'][:100]}: {last[0] if last else ''}"
                    if progress:
                        bar.write("pbrbench: " + msg, file=sys.stderr)
                    else:
                        log(msg)
                bar.set_postfix_str(res["key"][:40])
                bar.update(1)
        outcome.job_seconds = time.perf_counter() - t0
        status = "complete" if not outcome.errors else "complete-with-errors"
    except KeyboardInterrupt:
        status = "interrupted"
        log(f"run {run_id} interrupted; resume it with `pbrbench run --resume {run_id}`")
        raise
    finally:
        store.set_status(run_id, status, variant=variant)
        if executor is None:
            ex.close()

    outcome.scores = store.scores(run_id)
    store.export_json(run_id, run_dir / "scores.json")
    from pbrbench.bench import regress

    baselines = regress.load_baselines(regress.baseline_path(cfg.quality))
    if baselines is not None:
        outcome.comparison = regress.compare(outcome.scores, baselines)
    if cfg.report:
        from pbrbench.report.html import write_report

        outcome.report = write_report(store, run_id, out_dir=run_dir, baselines=baselines)
    outcome.wall_seconds = time.perf_counter() - t_start
    store.close()
    return outcome


def update_baselines(cfg: RunConfig, first: RunOutcome, *, tasks: dict | None = None, source=None,
                     executor=None, log=None) -> Path:
    """Run :data:`regress.N_SEEDS` - 1 more seeds, measure the spread and rewrite the baseline file."""
    from pbrbench.bench import regress

    log = log or _log
    runs = [first.scores]
    seeds = [cfg.seed]
    for i in range(1, regress.N_SEEDS):
        c = RunConfig(**{**cfg.__dict__, "seed": cfg.seed + i, "resume": None, "report": False,
                         "update_baselines": False, "check": False})
        log(f"baseline spread: seed {c.seed} ({i + 1}/{regress.N_SEEDS})")
        o = run_benchmark(c, tasks=tasks, source=source, executor=executor, log=log)
        runs.append(o.scores)
        seeds.append(c.seed)
    data = regress.build_baselines(runs, quality=cfg.quality, seeds=seeds,
                                   note=f"runs {first.run_id} (+{regress.N_SEEDS - 1} seeds)")
    return regress.write_baselines(data, regress.baseline_path(cfg.quality))
