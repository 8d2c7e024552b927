"""``pbrbench report [RUN]``: write the HTML report of a stored run again."""

from __future__ import annotations

from pathlib import Path


def register(sub):
    p = sub.add_parser("report", help="re-render the HTML report of a stored run")
    p.add_argument("run", nargs="?", default=None, help="run id or unique prefix (default: the latest; -2 the one before)")
    p.add_argument("--out", default="reports", metavar="DIR", help="reports directory (default: reports)")
    p.add_argument("--store", default=None, metavar="PATH", help="results database (default: PBRBENCH_STORE or DIR/history.sqlite)")
    p.set_defaults(func=run)


def store_path(args) -> Path:
    from pbrbench.bench.store import resolve_store_path

    return resolve_store_path(args.store, args.out)


def open_store(args):
    from pbrbench.bench.store import Store
    from pbrbench.errors import UserError

    p = store_path(args)
    if not p.is_file():
        raise UserError(f"--store {p}: no results database there; run `pbrbench run` first or pass --store")
    return Store(p)


def run(args) -> int:
    from pbrbench.bench import regress
    from pbrbench.report.html import write_report

    with open_store(args) as store:
        run_id = store.resolve_run(args.run)
        r = store.get_run(run_id)
        run_dir = Path(args.out) / run_id
        store.export_json(run_id, run_dir / "scores.json")
        base = regress.load_baselines(regress.baseline_path(r["quality"]))
        path = write_report(store, run_id, out_dir=run_dir, baselines=base)
    print(f"report: {path.resolve()}")
    return 0
