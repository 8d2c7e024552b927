"""Run the benchmark: plan, ground truths, jobs, store, regression check, report.

Flow of :func:`run_benchmark`:

1. the plan: every task's jobs at the quality profile (:mod:`pbrbench.bench.plan`), and the
   algorithms of each task from the registry (:mod:`pbrbench.registry`);
2. every ground truth the plan needs is looked up in the render cache and the missing ones are
   rendered (:mod:`pbrbench.bench.source`, on the executor);
3. the jobs run (:mod:`pbrbench.bench.executors`), each a pure function of (task, job, ground
   truths, algorithms, seed, quality); as each finishes its scores go into the store in one
   transaction and its figures into ``<out>/<run>/figures/<job>/``, so an interrupted run keeps
   everything completed.  With the pool executor steps 2 and 3 overlap: the renders stay in
   this process, and each job goes to a worker as soon as its scenes are rendered (the scenes of
   the longest jobs first);
4. the scores are compared with the regression baselines once, and the comparison is stored with
   the run; the run is exported as ``<out>/<run>/scores.json``, the HTML report (which reads only
   the store) is written, and only then is the run marked complete.

Resuming (``--resume RUN``) reuses the run's stored configuration and skips the jobs it has
already stored.
"""

from __future__ import annotations

import sys
import time
import traceback
from dataclasses import asdict, dataclass, field
from pathlib import Path

from pbrbench.bench import lifecycle
from pbrbench.bench.executors import (
    LocalExecutor,
    blas_threads,
    job_threads,
    make_executor,
    worker_source,
)
from pbrbench.bench.jobcache import JobCache, fingerprint
from pbrbench.bench.plan import load_tasks, needed_scenes, plan, task_info
from pbrbench.bench.source import RENDER_LOCK, GroundTruthSource
from pbrbench.bench.store import Store
from pbrbench.errors import UserError
from pbrbench.registry import DEFAULT_TIME_LIMIT


@dataclass
class RunConfig:
    """Everything that decides what a run computes (stored with the run as JSON)."""

    tasks: list[str] | None = None
    quality: str = "standard"
    seed: int = 0
    render_seed: int = 0           # added to every scene's render.seed: an independent set of renders
    executor: str = "local"
    scheduler: str | None = None
    workers: int | None = None
    resume: str | None = None
    report: bool = True
    check: bool = False
    update_baselines: bool = False
    algorithms: list[str] = field(default_factory=list)   # --algorithm TASK=MODULE:FUNCTION[:NAME]
    job_cache: bool = True         # reuse finished jobs whose inputs and code are unchanged
    uncertainty: bool = True       # score the delete-one-group replicates (standard errors, bias)
    algorithm_time_limit: float | None = DEFAULT_TIME_LIMIT   # seconds per plugin per job; None: in-process
    entry_points: bool = True                     # load the installed plugins (entry points)

    def recorded(self) -> dict:
        return {"tasks": self.tasks, "quality": self.quality, "seed": self.seed, "render_seed": self.render_seed,
                "executor": self.executor,
                "workers": self.workers, "algorithms": list(self.algorithms),
                "algorithm_time_limit": self.algorithm_time_limit, "entry_points": self.entry_points}


@dataclass
class RunOutcome:
    run_id: str
    report: Path | None
    scores: list[dict]
    n_jobs: int
    n_skipped: int
    errors: dict[str, str]
    comparison: object | None = None
    render_seconds: float = 0.0   # wall time until every scene is rendered
    job_seconds: float = 0.0      # wall time from then until the last job (the pool runs jobs during the renders too)
    render_cpu_seconds: float = 0.0   # CPU time of this run's renders (every thread; cached scenes: none)
    job_cpu_seconds: float = 0.0      # CPU time of this run's jobs, summed over their processes (cached jobs: none)
    wall_seconds: float = 0.0
    renders: int = 0
    n_cached: int = 0
    task_info: dict = field(default_factory=dict)


def _log(msg: str):
    print(f"pbrbench: {msg}", file=sys.stderr, flush=True)


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


def _noise_hashes(specs: dict, gts: dict) -> dict:
    """``{scene hash: noise hash}`` of a job's ground truths (:func:`pbrbench.bench.uncertainty.scaled_scores`),
    keyed by the scene hash each ground truth records, the one its scores carry: the noise scales
    measured over render seeds hold at any render seed of the same content.  A source whose specs
    are not scene files (``GroundTruthSource.specs`` overridden, as the test fakes do) gives none."""
    from pbrbench.tasks.common.scoring import scene_hash

    return {scene_hash(g): specs[n].noise_hash() for n, g in gts.items() if hasattr(specs[n], "noise_hash")}


def execute_job(task, job, specs: dict, source, seed: int, job_dir: str, algorithms, quality,
                uncertainty: bool = True) -> dict:
    """Run one job, its replicates (the standard errors: :mod:`pbrbench.bench.uncertainty`) and
    draw its figures (in this process or on a worker); never raises."""
    from pbrbench.bench.uncertainty import attach, replicate_scores
    from pbrbench.isolation import job_budget
    from pbrbench.report.figures import job_figures

    t0 = time.perf_counter()
    c0 = time.process_time()
    try:
        src = worker_source(source)
        _form_factor_cache(src)
        with RENDER_LOCK, blas_threads(job_threads()), job_budget():   # a plugin's time limit: per job
            gts = {n: src.load(specs[n]) for n in (job.scene, *job.extra_scenes)}
            for g in gts.values():
                g.reads.clear()      # what this job reads (a replicate that changes none of it is not rescored)
            result = task.run_job(job, gts, seed=seed, algorithms=algorithms, quality=quality)
            reps = {}
            if uncertainty and result.scores:
                reps = replicate_scores(task, job, gts, seed=seed, algorithms=algorithms, quality=quality,
                                        full=result.scores, noise_hashes=_noise_hashes(specs, gts))
        scores = attach(_check_scores(job, result.scores), reps)
        files, manifest = job_figures(result, job_dir)
        error = None
    except Exception:  # noqa: BLE001 - a failing job is recorded, the run goes on
        scores, files, manifest = [], {}, None
        error = traceback.format_exc(limit=8)
    return {"key": job.key, "task": job.task, "scores": scores, "files": files, "manifest": manifest,
            "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0, "error": error}


def _expected_cost(job, algorithms, quality) -> int:
    """A job's rank by expected time: 1 where a scene-interface algorithm (inverse rendering: each
    call a series of Mitsuba renders) runs on it, else 0."""
    return int(any(a.interface == "scene" and a.applies_to_job(job, quality) for a in algorithms))


def _form_factor_cache(source) -> None:
    """The radiosity models' form factors live beside the render cache (``form_factors/``)."""
    root = getattr(getattr(source, "cache", None), "root", None)
    if root is not None:
        from pbrbench.radiosity.forward_models import set_disk_cache

        set_disk_cache(Path(root) / "form_factors")


def _render_task(source, spec) -> tuple[str, dict, bool]:
    meta, cached = worker_source(source).render(spec)
    return spec.name, meta, cached


def _write_files(run_dir: Path, files: dict[str, bytes]):
    """A job's figures under ``<run_dir>/figures``, each written atomically (a full disk leaves no
    partial file and says which figure, and that --out is the place)."""
    from pbrbench.errors import disk_error
    from pbrbench.io import write_bytes

    for rel, data in files.items():
        p = run_dir / "figures" / rel
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
            write_bytes(p, data)
        except OSError as exc:
            raise disk_error(exc, f"figure {p}", option="--out") from None


def comparison_record(comparison) -> dict:
    """A stored form of a :class:`pbrbench.bench.regress.Comparison`."""
    return {"regressions": [asdict(c) for c in comparison.regressions],
            "improvements": [asdict(c) for c in comparison.improvements],
            "unstable": [asdict(c) for c in comparison.unstable],
            "missing": list(comparison.missing), "new": list(comparison.new),
            "n_checked": comparison.n_checked, "no_noise": comparison.no_noise,
            "strong": [asdict(c) for c in comparison.strong], "allowed": comparison.allowed,
            "expected_false": comparison.expected_false, "ok": comparison.ok}


# ----------------------------------------------------------------------------- the run
def run_benchmark(cfg: RunConfig, *, settings, tasks: dict | None = None, source=None, executor=None,
                  registry=None, log=None) -> RunOutcome:
    """Run (or resume) a benchmark; see the module docstring.  ``tasks``: name -> Task instance;
    ``registry``: the algorithms (default: the tasks' built-ins plus installed plugins)."""
    from pbrbench.bench import regress
    from pbrbench.plugins import plugin_registry
    from pbrbench.quality import get_quality
    from pbrbench.registry import normalize_algorithm_spec
    from pbrbench.report.figures import slug
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.tasks.base import Task

    log = log or _log
    t_start = time.perf_counter()
    lifecycle.preflight(settings)  # an unwritable --out: one line, and no junk run in the store
    store = Store(settings.store_path())
    prior_done: set[str] = set()
    prior_plugins: dict | None = None
    if cfg.resume:
        run_id = store.resolve_run(cfg.resume)
        run = lifecycle.check_resumable(store, run_id)
        rc = run["config"]
        cfg.tasks, cfg.quality, cfg.seed = rc.get("tasks"), rc.get("quality", cfg.quality), rc.get("seed", cfg.seed)
        cfg.render_seed = rc.get("render_seed", 0)
        cfg.algorithms = list(rc.get("algorithms") or cfg.algorithms)
        cfg.algorithm_time_limit = rc.get("algorithm_time_limit", cfg.algorithm_time_limit)
        cfg.entry_points = rc.get("entry_points", cfg.entry_points)
        settings = settings.with_(variant=settings.variant or rc.get("variant"))
        prior_done = store.done_jobs(run_id)
        prior_plugins = rc.get("plugin_versions")
    quality = get_quality(cfg.quality)
    library = SceneLibrary.from_settings(settings)
    if tasks is None:
        tasks = load_tasks(cfg.tasks)
    if not tasks:
        raise UserError("no task to run; pass --tasks NAME (see `pbrbench run --help`)")
    # every task reads the settings' scene library (a task already bound, or a wrapper, keeps its own)
    tasks = {n: t.bind(library) if isinstance(t, Task) and t.library is None else t for n, t in tasks.items()}
    if registry is None:   # the built-ins, the installed plugins and the --algorithm specs
        cfg.algorithms = [normalize_algorithm_spec(a) for a in cfg.algorithms]
        registry = plugin_registry(tasks, cfg.algorithms, entry_points=cfg.entry_points,
                                   time_limit=cfg.algorithm_time_limit, log=log,
                                   load_limit=settings.plugin_load_limit)
    source = source or GroundTruthSource(quality, cache=_cache(settings), variant=settings.variant,
                                         library=library, render_seed=cfg.render_seed)
    plugins = plugin_versions(registry, tasks)
    if prior_plugins is not None:
        check_plugins_unchanged(run_id, prior_plugins, plugins)
    variant = source.resolve_variant()
    info = task_info(tasks, registry)
    from pbrbench.lock import locked_versions

    config = dict(cfg.recorded(), tasks=list(tasks), variant=variant, task_info=info, plugin_versions=plugins,
                  quality_profile=quality.render_key(), environment={"lock": locked_versions()},
                  out=str(Path(settings.out).resolve()))   # where its figures are (pbrbench report --out elsewhere copies them)
    jobs = plan(tasks, quality)          # planned (and the scene files loaded) before the run exists,
    todo = [j for j in jobs if j.key not in prior_done]  # so a bad scene file leaves no junk run
    names = needed_scenes(jobs)
    specs = source.specs(names)
    if cfg.resume:
        store.set_status(run_id, "running")
    else:
        run_id = store.create_run(quality_name=quality.name, config=config, variant=variant)
    heartbeat = lifecycle.start(store, run_id)   # process and heartbeat: a dead run reads interrupted
    run_dir = Path(settings.out) / run_id
    run_dir.mkdir(parents=True, exist_ok=True)
    bars = settings.progress_bars(sys.stderr)

    from pbrbench.progress import Progress

    outcome = RunOutcome(run_id, None, [], len(jobs), len(jobs) - len(todo), {}, task_info=info)
    ex = None
    status = "failed"
    try:
        # an executor that fails to start fails the run it was started for (recorded, not left running)
        ex = executor or make_executor(cfg.executor, scheduler=cfg.scheduler, workers=cfg.workers, variant=variant,
                                       settings=settings)
        # ---- ground truths and jobs (finished ones with unchanged inputs come from the job cache)
        t0 = time.perf_counter()
        metas: dict[str, tuple[dict, bool]] = {}
        missing = []
        for n in names:
            m = source.cached_meta(specs[n])
            if m is None:
                missing.append(n)
            else:
                metas[n] = (m, True)
        algs = {t: registry.for_task(t) for t in tasks}
        jcache = JobCache(Path(settings.cache) / "jobs" if cfg.job_cache else None)
        fps, cached_results, args = {}, [], []
        for j in todo:    # a ground truth's cache key needs no render
            fp = fingerprint(j, seed=cfg.seed, quality=quality, algorithms=algs[j.task], task=tasks[j.task],
                             gt_keys=[source.gt_key(specs[n]) for n in (j.scene, *j.extra_scenes)],
                             uncertainty=cfg.uncertainty)
            fps[j.key] = fp
            hit = jcache.get(fp)
            if hit is not None:
                cached_results.append({**hit, "from_job_cache": True})
            else:
                args.append((tasks[j.task], j, {n: specs[n] for n in (j.scene, *j.extra_scenes)}, source, cfg.seed,
                             slug(j.key), algs[j.task], quality, cfg.uncertainty))
        outcome.n_cached = len(cached_results)
        if getattr(ex, "name", "local") != "local":   # parallel workers: the longest jobs first, so that none is left alone at the end
            args.sort(key=lambda a: -_expected_cost(a[1], a[6], quality))
        renders_here = getattr(ex, "renders_in_process", False)
        # pipelined: renders in this process and workers that take work as it comes (the pool): a
        # job starts as soon as its scenes are rendered, so the workers use the cores that a
        # render's single-threaded kernel compiles leave idle; the scenes of the first jobs first
        pipeline = bool(missing) and renders_here and hasattr(ex, "submit")
        waiting: list = []
        if pipeline:
            first = {}
            for i, a in enumerate(args):
                for n in (a[1].scene, *a[1].extra_scenes):
                    first.setdefault(n, i)
            missing.sort(key=lambda n: first.get(n, len(args)))
            pending_scenes = set(missing)
            for a in args:
                if pending_scenes.isdisjoint((a[1].scene, *a[1].extra_scenes)):
                    ex.submit(execute_job, a)
                else:
                    waiting.append(a)

        def keep(res, bar):
            if res["files"]:
                _write_files(run_dir, res["files"])
            store.add_job_result(run_id, res["key"], res["task"], res["scores"], seconds=res["seconds"],
                                 error=res["error"], cpu_seconds=res.get("cpu_seconds"))
            if not res.get("from_job_cache"):
                outcome.job_cpu_seconds += float(res.get("cpu_seconds") or 0.0)
            if res["error"]:
                outcome.errors[res["key"]] = res["error"]
                last = [ln for ln in res["error"].strip().splitlines() if ln.strip()][-1:]
                bar.write(f"pbrbench: job failed: {res['key'][:100]}: {last[0] if last else ''}")
            bar.update(1, res["key"])

        jbar = None
        try:
            if missing:
                if pipeline:
                    jbar = Progress(len(todo), "jobs", bars=bars, unit="job")
                with Progress(len(missing), f"render ({quality.name})", bars=bars, unit="scene") as bar:
                    rex = LocalExecutor() if renders_here else ex
                    for name, meta, cached in rex.imap(_render_task, [(source, specs[n]) for n in missing]):
                        metas[name] = (meta, cached)
                        outcome.renders += int(not cached)
                        outcome.render_cpu_seconds += 0.0 if cached else float(meta.get("cpu_s") or 0.0)
                        bar.update(1, name)
                        if pipeline:
                            pending_scenes.discard(name)
                            still = []
                            for a in waiting:
                                if pending_scenes.isdisjoint((a[1].scene, *a[1].extra_scenes)):
                                    ex.submit(execute_job, a)
                                else:
                                    still.append(a)
                            waiting = still
                            for res in ex.finished(block=False):
                                jcache.put(fps[res["key"]], res)
                                keep(res, jbar)
            for n in names:
                store.add_ground_truth(run_id, n, metas[n][0], from_cache=metas[n][1], spp_file=specs[n].render.spp)
            outcome.render_seconds = time.perf_counter() - t0
            t_jobs = time.perf_counter()
            for a in waiting:   # (none: every scene is rendered by now)
                ex.submit(execute_job, a)

            def results():
                yield from cached_results
                for res in ex.finished(block=True) if pipeline else ex.imap(execute_job, args):
                    jcache.put(fps[res["key"]], res)
                    yield res

            if jbar is None:
                jbar = Progress(len(todo), "jobs", bars=bars, unit="job")
            with jbar:
                for res in results():
                    keep(res, jbar)
        finally:
            if jbar is not None:
                jbar.close()
        outcome.job_seconds = time.perf_counter() - t_jobs
        final = "complete" if not outcome.errors else "complete-with-errors"

        # ---- regression check, export, report; only then is the run complete
        outcome.scores = store.scores(run_id)
        bpath = settings.baseline_path(quality)
        baselines = regress.load_baselines(bpath) if bpath is not None else None
        if baselines is not None:
            outcome.comparison = regress.compare(outcome.scores, baselines)
            store.set_comparison(run_id, dict(comparison_record(outcome.comparison), baseline=str(bpath),
                                              baseline_quality=baselines.get("quality")))
        # the exported scores and the report show the final status; the store takes it last
        store.export_json(run_id, run_dir / "scores.json", status=final)
        if cfg.report:
            from pbrbench.report.html import write_report

            outcome.report = write_report(store, run_id, out_dir=run_dir, status=final)
        status = final
    except KeyboardInterrupt:
        status = "interrupted"
        log(f"run {run_id} interrupted; resume it with `pbrbench run --resume {run_id}`")
        raise
    finally:
        lifecycle.finish(store, run_id, status, variant=variant, heartbeat=heartbeat, log=log)
        if executor is None and ex is not None:
            ex.close()
    outcome.wall_seconds = time.perf_counter() - t_start
    store.close()
    return outcome


def plugin_versions(registry, tasks) -> dict[str, str]:
    """``{"TASK/NAME": version}`` of the plugins of ``tasks`` (stored with the run)."""
    return {f"{a.task}/{a.name}": a.full_version for t in tasks for a in registry.for_task(t, kinds=["plugin"])}


def check_plugins_unchanged(run_id: str, before: dict, now: dict) -> None:
    """``UserError`` (one line) when a plugin changed, appeared or went since the run began: a
    resumed run would mix two versions of it."""
    changed = [f"{k} ({before[k]} -> {now[k]})" for k in before if k in now and before[k] != now[k]]
    changed += [f"{k} (gone)" for k in before if k not in now]
    changed += [f"{k} (new)" for k in now if k not in before]
    if changed:
        raise UserError(f"--resume {run_id}: plugin {', '.join(changed)} changed since the run began; put the "
                        "plugin back as it was, or start a new run (without --resume)")


def _cache(settings):
    from pbrbench.render.cache import RenderCache

    return RenderCache(settings.cache)


def update_baselines(cfg: RunConfig, first: RunOutcome, *, settings, tasks: dict | None = None, source=None,
                     executor=None, registry=None, log=None) -> Path:
    """Run :data:`regress.N_SEEDS` - 1 more runs, each with its own render seed (every scene's
    ``render.seed`` offset) and job seed, and rewrite the baseline file from all of them."""
    from pbrbench.bench import regress
    from pbrbench.quality import get_quality

    log = log or _log
    quality = get_quality(cfg.quality)
    path = settings.baseline_path(quality)
    if path is None:
        raise UserError("--update-baselines: no baselines directory (run from a source checkout or set "
                        "PBRBENCH_BASELINES)")
    runs = [first.scores]
    seeds = [{"seed": cfg.seed, "render_seed": cfg.render_seed}]
    for i in range(1, regress.N_SEEDS):
        c = RunConfig(**{**cfg.__dict__, "seed": cfg.seed + i, "render_seed": cfg.render_seed + i, "resume": None,
                         "report": False, "update_baselines": False, "check": False})
        log(f"baseline spread: render seed +{c.render_seed}, seed {c.seed} ({i + 1}/{regress.N_SEEDS})")
        o = run_benchmark(c, settings=settings, tasks=tasks, source=source, executor=executor, registry=registry,
                          log=log)
        runs.append(o.scores)
        seeds.append({"seed": c.seed, "render_seed": c.render_seed})
    data = regress.build_baselines(runs, quality=quality, seeds=seeds,
                                   note=f"runs {first.run_id} (+{regress.N_SEEDS - 1} seeds)")
    if cfg.tasks:   # only these tasks were rerun: the other tasks' entries stay as they were
        try:
            old = regress.load_baselines(path)
        except UserError:
            old = None
        if old is not None and old.get("seeds") == data["seeds"]:
            ran = set(cfg.tasks)
            for name in ("entries", "scene_hashes", "algorithm_versions"):
                keep = {k: v for k, v in old.get(name, {}).items()
                        if (k.split("|", 1)[0] if name == "entries" else k.split("/", 1)[0]) not in ran}
                data[name] = {**keep, **data[name]} if name != "scene_hashes" else {**old.get(name, {}), **data[name]}
            data["note"] = f"{old.get('note', '')}; tasks {', '.join(sorted(ran))}: {data['note']}"
    return regress.write_baselines(data, path)
