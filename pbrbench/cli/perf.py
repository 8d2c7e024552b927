"""``pbrbench perf [AREA...]``: speed benchmarks of the inference kernels and renders.

Each area is a module ``pbrbench.perf.<area>`` with ``run(quick=False) -> list[dict]`` (rows
``{"benchmark", "case", "method", "metric", "value", "unit"}``).  The rows are printed and
stored in the results store as a run whose scores have task ``perf`` (scene = benchmark:case,
algorithm = method).
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import time


def areas() -> list[str]:
    import pbrbench.perf as perf_pkg

    return sorted(m.name for m in pkgutil.iter_modules(perf_pkg.__path__) if not m.name.startswith("_"))


def register(sub):
    p = sub.add_parser("perf", help="speed benchmarks of inference kernels and renders (stored like scores)")
    p.add_argument("areas", nargs="*", metavar="AREA", help="perf modules to run (default: all in pbrbench/perf/)")
    p.add_argument("--quick", action="store_true", help="smaller problem sizes (seconds instead of minutes)")
    from pbrbench.cli.common import add_store

    add_store(p)
    p.add_argument("--no-store", action="store_true", help="print only")
    p.set_defaults(func=run)


def direction(row: dict) -> str:
    """'lower' or 'higher' is better, as the row declares it (:func:`pbrbench.perf.row`)."""
    better = row.get("better")
    if better not in ("lower", "higher"):
        raise ValueError(f"perf row {row.get('benchmark')}/{row.get('metric')}: no direction declared; "
                         "make rows with pbrbench.perf.row(..., better='lower'|'higher')")
    return better


def to_scores(rows: list[dict], seconds: float) -> list[dict]:
    return [{"task": "perf", "scene": f"{r['benchmark']}:{r['case']}", "scene_hash": "", "condition": "",
             "algorithm": str(r["method"]), "algorithm_version": "", "metric": str(r["metric"]),
             "value": float(r["value"]), "seconds": seconds, "better": direction(r), "unit": str(r.get("unit", ""))}
            for r in rows]


def run(args) -> int:
    from pbrbench.errors import UserError
    from pbrbench.report.html import fmt

    known = areas()
    chosen = args.areas or known
    bad = [a for a in chosen if a not in known]
    if bad:
        raise UserError(f"perf: unknown area(s) {', '.join(bad)}; choose from {', '.join(known) or '(none installed)'}")
    store = run_id = None
    if not args.no_store:
        from pbrbench.bench.store import Store
        from pbrbench.cli.common import settings

        store = Store(settings(args).store_path())
        run_id = store.create_run(quality_name="perf", config={"perf_areas": chosen, "quick": args.quick})
    failed = []
    for area in chosen:
        t0 = time.perf_counter()
        try:
            mod = importlib.import_module(f"pbrbench.perf.{area}")
            rows = mod.run(quick=args.quick)
        except Exception as e:  # noqa: BLE001 - one broken area must not hide the others
            failed.append(area)
            print(f"perf {area}: failed: {type(e).__name__}: {e}", file=sys.stderr)
            if store:
                store.add_job_result(run_id, f"perf|{area}", "perf", [], error=f"{type(e).__name__}: {e}")
            continue
        dt = time.perf_counter() - t0
        print(f"\n== {area} ({dt:.1f}s)")
        print(f"{'case':40s} {'method':28s} {'metric':24s} {'value':>12s} unit")
        for r in rows:
            print(f"{str(r['case'])[:40]:40s} {str(r['method'])[:28]:28s} {str(r['metric'])[:24]:24s} "
                  f"{fmt(r['value']):>12s} {r.get('unit', '')}")
        if store:
            store.add_job_result(run_id, f"perf|{area}", "perf", to_scores(rows, dt), seconds=dt)
    if store:
        store.set_status(run_id, "complete" if not failed else "complete-with-errors")
        print(f"\nstored as run {run_id} in {store.path}")
        store.close()
    return 1 if failed else 0
