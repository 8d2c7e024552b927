"""``pbrbench report [RUN]``: write the HTML report of a stored run again."""

from __future__ import annotations

from pathlib import Path

from pbrbench.cli.common import add_store, open_store, settings


def register(sub):
    p = sub.add_parser("report", help="re-render the HTML report of a stored run")
    p.add_argument("run", nargs="?", default=None, help="run id or unique prefix (default: the latest; -2 the one before)")
    add_store(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.report.html import write_report

    st = settings(args)
    from pbrbench.errors import disk_error

    with open_store(st) as store:
        run_id = store.resolve_run(args.run)
        run_dir = Path(st.out) / run_id
        try:
            store.export_json(run_id, run_dir / "scores.json")
            path = write_report(store, run_id, out_dir=run_dir)
        except OSError as exc:
            raise disk_error(exc, f"--out {run_dir}", option="--out") from None
    print(f"report: {path.resolve()}")
    return 0
