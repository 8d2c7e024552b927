"""``pbrbench run``: render what is missing, run every algorithm, score, store, report."""

from __future__ import annotations

import sys

from pbrbench.cli.common import (
    add_cache,
    add_quality,
    add_store,
    add_variant,
    int_at_least,
    settings,
)

EXIT_OK, EXIT_FAILED_JOBS, EXIT_REGRESSION = 0, 1, 2


def register(sub):
    from pbrbench.tasks import task_names

    p = sub.add_parser("run", help="run the benchmark: render (cached), infer, score, store, report",
                       description="Run the benchmark tasks, store every score and write the HTML report. "
                                   f"Tasks: {', '.join(task_names())}.")
    p.add_argument("--tasks", nargs="+", metavar="TASK", default=None, help="tasks to run (default: all)")
    add_quality(p)
    p.add_argument("--executor", choices=["local", "pool", "dask"], default="local",
                   help="local: this process; pool: --workers processes of this machine (default: one per "
                        "core); dask: a Dask distributed cluster")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="Dask scheduler address (default: start a LocalCluster)")
    p.add_argument("--workers", type=int_at_least(1), default=None, metavar="N",
                   help="worker processes of --executor pool (default: one per core) or of dask's LocalCluster (one "
                        "thread each; default: cores / 2)")
    add_store(p)
    p.add_argument("--seed", type=int_at_least(0, (1 << 63) - 1), default=0, help="seed handed to every job (default 0)")
    p.add_argument("--render-seed", type=int_at_least(0, (1 << 21) - 1), default=0, metavar="N",
                   help="add N to every scene's render.seed: an independent set of renders of the same scenes "
                        "(default 0; the baselines are measured over render seeds 0 to 3)")
    p.add_argument("--check", action="store_true",
                   help="compare with the regression baselines (tests/baselines/<quality>.json) and exit 2 on a regression")
    p.add_argument("--update-baselines", action="store_true",
                   help="rerun with more render seeds and seeds, measure the noise and rewrite "
                        "tests/baselines/<quality>.json")
    p.add_argument("--resume", default=None, metavar="RUN", help="continue an interrupted run (its id)")
    p.add_argument("--no-report", action="store_true", help="store scores but write no HTML report")
    p.add_argument("--algorithm", action="append", default=[], metavar="TASK=MODULE:FUNCTION[:NAME]",
                   help="score your own algorithm beside the built-in ones (repeatable): MODULE is a dotted module "
                        "on sys.path or a path to a .py file, FUNCTION has the task's signature (docs/plugins.md), "
                        "NAME defaults to FUNCTION; e.g. photometric_stereo=./mine.py:solve")
    p.add_argument("--algorithm-time-limit", type=float, default=None, metavar="SECONDS",
                   help="time limit of a plugin per job (all its calls together); a plugin past it is killed and "
                        "scored as failed "
                        "(default 600; 0: run plugins in this process, without a limit)")
    p.add_argument("--no-plugins", action="store_true",
                   help="do not load the installed plugins (entry points of the group pbrbench.algorithms)")
    add_variant(p)
    add_cache(p)
    p.set_defaults(func=run)


def summary_lines(outcome) -> list[str]:
    from pbrbench.report.html import headline_tables
    from pbrbench.text import text_table

    lines = []
    for h in headline_tables(outcome.scores, outcome.task_info):
        conds = h["conditions"]
        texts = [[(f"({c['text']})" if "ns" in c.get("cls", "").split() else c["text"]) + (" !" if c["mark"] == "regression" else "")
                  for c in r["cells"]] for r in h["rows"]]
        lines.append(f"{h['task']}: {h['metric']} ({h['better']} is better; {h['reference']} and the cost of each "
                     "effect, mean over matched scenes ± 1 SE; ( ) = inside the 95 % t interval of zero; "
                     "\"bias\": noise-limited, |Monte Carlo bias| > SE; ! = regression)")
        names = [r["algorithm"] + (f" ({r['subset'][0]} of {r['subset'][1]} scenes)" if r.get("subset") else "")
                 for r in h["rows"]]
        lines += text_table([[n, *t] for n, t in zip(names, texts, strict=True)],
                            header=["algorithm", *conds], indent="  ", gap="  ")
        if any(r.get("subset") for r in h["rows"]):
            lines.append("  (n of N scenes): its row's means are over its own scenes; the report gives it beside the "
                         "others on those scenes")
    return lines


def failure_lines(scores) -> list[str]:
    """One line per algorithm scored as failed somewhere (the messages are in the report)."""
    failed, total = {}, {}
    for s in scores:
        if s["metric"] == "failed":
            key = (s["task"], s["algorithm"])
            total[key] = total.get(key, 0) + 1
            failed[key] = failed.get(key, 0) + int(s["value"] == 1.0)
    return [f"pbrbench: {a} ({t}) scored as failed on {n} of {total[(t, a)]} job(s); the reasons are in the report's "
            "'Algorithms scored as failed'" for (t, a), n in failed.items() if n]


def run(args) -> int:
    from pbrbench.bench.run import RunConfig, run_benchmark, update_baselines
    from pbrbench.errors import UserError

    st = settings(args)
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers {args.workers}: give at least 1")
    if args.workers and args.executor not in ("pool", "dask"):
        raise UserError("--workers only applies to --executor pool or dask")
    if args.scheduler and args.executor != "dask":
        raise UserError("--scheduler only applies to --executor dask")
    if args.tasks:  # before anything is created on disk
        from pbrbench.tasks import task_names

        unknown = [t for t in args.tasks if t not in task_names()]
        if unknown:
            raise UserError(f"--tasks: unknown task(s) {', '.join(map(repr, unknown))}; choose from {', '.join(task_names())}")
    if args.resume and (args.tasks or args.update_baselines):
        raise UserError("--resume continues a stored run with its own tasks and quality; drop --tasks / --update-baselines")
    if args.resume and (args.algorithm or args.algorithm_time_limit is not None or args.no_plugins):
        raise UserError("--resume reloads the run's own --algorithm specs and plugin settings; drop --algorithm, "
                        "--algorithm-time-limit and --no-plugins")
    limit = args.algorithm_time_limit
    if limit is not None and limit < 0:
        raise UserError(f"--algorithm-time-limit {limit:g}: give seconds >= 0 (0: no limit)")
    from pbrbench.registry import DEFAULT_TIME_LIMIT

    limit = DEFAULT_TIME_LIMIT if limit is None else (None if limit == 0 else limit)
    tasks = [t.replace("-", "_") for t in args.tasks] if args.tasks else None
    cfg = RunConfig(tasks=tasks, quality=args.quality, seed=args.seed, render_seed=args.render_seed,
                    executor=args.executor,
                    scheduler=args.scheduler, workers=args.workers, resume=args.resume, report=not args.no_report,
                    check=args.check, update_baselines=args.update_baselines, algorithms=list(args.algorithm),
                    algorithm_time_limit=limit, entry_points=not args.no_plugins)
    o = run_benchmark(cfg, settings=st)
    from pbrbench.progress import peak_memory_mib

    print(f"run {o.run_id}: {o.n_jobs} jobs ({o.n_skipped} already done), {len(o.scores)} scores, "
          f"{o.renders} render(s) {o.render_seconds:.1f}s, jobs {o.job_seconds:.1f}s, total {o.wall_seconds:.1f}s, "
          f"peak memory {peak_memory_mib():.0f} MiB")
    if o.renders or o.job_cpu_seconds:
        ratio = f" ({o.job_cpu_seconds / o.render_cpu_seconds:.2f}x)" if o.render_cpu_seconds > 0 else ""
        print(f"  CPU time: renders {o.render_cpu_seconds:.1f}s, jobs {o.job_cpu_seconds:.1f}s{ratio} "
              "(every thread of each process; wall times beside other work run long)")
    for line in summary_lines(o):
        print(line)
    for line in failure_lines(o.scores):
        print(line, file=sys.stderr)
    code = EXIT_OK
    if o.errors:
        print(f"{len(o.errors)} job(s) failed (tracebacks in the report); rerun them with "
              f"`pbrbench run --resume {o.run_id}`", file=sys.stderr)
        code = EXIT_FAILED_JOBS
    comp = o.comparison
    if comp is not None:
        print(f"baselines: {comp.n_checked} scores checked, {len(comp.regressions)} regression(s), "
              f"{len(comp.improvements)} improvement(s), {len(comp.missing)} missing, {len(comp.new)} new"
              + (f", {len(comp.unstable)} unstable (bimodal replicates, not counted)" if comp.unstable else "")
              + (f", {comp.no_noise} without a noise estimate" if comp.no_noise else "")
              + (f", {len(comp.version_changed)} algorithm version(s) changed" if comp.version_changed else ""))
        for ch in comp.regressions[:20]:
            print("  " + str(ch))
        if len(comp.regressions) > 20:
            print(f"  ... and {len(comp.regressions) - 20} more (see the report)")
        if comp.regressions:
            print(f"  ({comp.expected_false:.1f} per-score regression(s) expected by chance, at most {comp.allowed}; "
                  f"{len(comp.strong)} beyond the family-wise limit)")
        if args.check and (not comp.ok or comp.missing):
            for k in comp.missing[:10]:
                print(f"  missing: {k}")
            code = EXIT_REGRESSION
    elif args.check:
        # no baselines is a set-up mistake, not a regression (exit 2 means regressions only)
        print(f"pbrbench: error: --check: no baselines for quality {cfg.quality}; create them with "
              f"`pbrbench run --quality {cfg.quality} --update-baselines`", file=sys.stderr)
        code = EXIT_FAILED_JOBS
    if args.update_baselines:
        path = update_baselines(cfg, o, settings=st)
        print(f"baselines written: {path}")
    if o.report:
        print(f"report: {o.report.resolve()}")
    return code
