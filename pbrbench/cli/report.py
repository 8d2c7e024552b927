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
            note = bring_figures(store.get_run(run_id)["config"].get("out"), run_id, run_dir)
            store.export_json(run_id, run_dir / "scores.json")
            path = write_report(store, run_id, out_dir=run_dir)
        except OSError as exc:
            raise disk_error(exc, f"--out {run_dir}", option="--out") from None
    if note:
        print(note)
    print(f"report: {path.resolve()}")
    return 0


def bring_figures(recorded_out, run_id: str, run_dir: Path) -> str | None:
    """Copy the run's figures into ``run_dir`` when it has none and the reports directory the
    run wrote them to (``recorded_out``, the run's ``config["out"]``) still has them, so a report
    written to another ``--out`` links its figures and can be moved on its own.  Returns a line
    saying what was done, or None when nothing needed doing."""
    import shutil

    dest = run_dir / "figures"
    if dest.is_dir() or not recorded_out:
        return None
    src = Path(recorded_out) / run_id / "figures"
    if src.resolve() == dest.resolve():     # the run's own folder: nothing to bring from elsewhere
        return None
    if not src.is_dir():
        return (f"report: the run's figures are not in {src} (its reports directory moved or was cleaned): "
                "the task pages have no figures; give that directory as --out to link them")
    shutil.copytree(src, dest)
    return f"report: figures copied from {src}"
