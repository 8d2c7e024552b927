"""``pbrbench validate``: prove the ground truth right (closed forms and statistical render tests).

The records (check, measured, bound, pass) are printed, stored in the results store as a run whose
scores have task ``validate`` (scene = the check's record name, algorithm ``renderer``, metrics
``measured``, ``bound`` and ``passed``; as ``pbrbench perf`` stores its rows), and written with the
checks' figures (profile plots) to a folder, ``--out DIR`` (default ``reports/validate-<run>/``):
``records.json``, one PNG per figure and an ``index.html`` that shows them.
"""

from __future__ import annotations

import html
import json
import sys
import time
from pathlib import Path

from pbrbench.cli.common import add_cache, add_quality, add_variant, settings


def register(sub):
    # the checks (render.proofs: the scene schema, pydantic) are imported only when `pbrbench
    # validate` is parsed or its help shown (main.Parser's fill)
    sub.add_parser("validate", help="check the renderer against closed forms and statistical tests (exit 2 on failure)",
                   fill=_add_options)


def _add_options(p):
    from pbrbench.render.proofs import CHECKS

    add_quality(p, default="draft")
    add_variant(p)
    add_cache(p)
    p.add_argument("--checks", nargs="+", metavar="CHECK", default=None,
                   help=f"run only these checks (default: all): {', '.join(CHECKS)}")
    p.add_argument("--diagnostics", default=None, metavar="DIR",
                   help="write diagnostic images of failed statistical comparisons here")
    p.add_argument("--out", dest="figures_dir", default=None, metavar="DIR",
                   help="folder for the records and figures (default: reports/validate-<run>/)")
    p.add_argument("--store", default=None, metavar="PATH",
                   help="results database (default: PBRBENCH_STORE or reports/history.sqlite)")
    p.add_argument("--no-store", action="store_true", help="do not store the records as a run")
    p.set_defaults(func=run)


def format_table(records: list[dict]) -> str:
    from pbrbench.text import text_table

    rows = [(r["check"], f"{r['measured']:.3g}", f"{r['bound']:.3g}", "pass" if r["passed"] else "FAIL") for r in records]
    return "\n".join(text_table(rows, header=("check", "measured", "bound", "result"), rule=True))


def to_scores(records: list[dict], quality: str, seconds: float) -> list[dict]:
    """Store rows of the records: per record its measured value, its bound and whether it passed."""
    out = []
    for r in records:
        base = {"task": "validate", "scene": r["check"], "scene_hash": "", "condition": quality,
                "algorithm": "renderer", "algorithm_version": "", "seconds": seconds, "unit": ""}
        out.append(dict(base, metric="measured", value=float(r["measured"]), better="lower"))
        out.append(dict(base, metric="bound", value=float(r["bound"]), better="lower"))
        out.append(dict(base, metric="passed", value=float(bool(r["passed"])), better="higher", unit="0/1"))
    return out


def write_folder(folder: Path, records: list[dict], figures: dict, *, quality: str, run_id: str | None) -> Path:
    """``records.json``, one PNG per figure and ``index.html`` in ``folder``."""
    from pbrbench.report.figures import plot_png, slug

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "records.json").write_text(json.dumps({"run": run_id, "quality": quality, "records": records},
                                                    indent=1, default=float))
    files = []
    for name, plot in figures.items():
        fn = f"{slug(name, 50)}.png"
        (folder / fn).write_bytes(plot_png(name, plot))
        (folder / f"{slug(name, 50)}.json").write_text(json.dumps(plot, default=float))
        files.append((name, fn))
    rows = "\n".join(
        f"<tr class='{'ok' if r['passed'] else 'bad'}'><td>{html.escape(r['check'])}</td><td>{r['measured']:.3g}</td>"
        f"<td>{r['bound']:.3g}</td><td>{'pass' if r['passed'] else 'FAIL'}</td><td>{html.escape(r['detail'])}</td></tr>"
        for r in records)
    figs = "\n".join(f"<figure><img src='{fn}' width='630' height='400' alt='{html.escape(n)}'>"
                     f"<figcaption>{html.escape(n)}</figcaption></figure>" for n, fn in files)
    n_bad = sum(not r["passed"] for r in records)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>pbrbench validate {html.escape(str(run_id or ''))}</title>
<style>body{{font-family:sans-serif;margin:1.5em}} table{{border-collapse:collapse;font-size:13px}}
td,th{{border:1px solid #ccc;padding:3px 6px;vertical-align:top}} tr.bad td{{background:#fdd}}
figure{{display:inline-block;margin:0.5em}} figcaption{{font-size:13px;max-width:630px}}</style></head><body>
<h1>pbrbench validate ({html.escape(quality)})</h1>
<p>{len(records) - n_bad} of {len(records)} checks passed{'; run ' + html.escape(run_id) if run_id else ''}.</p>
<h2>Figures</h2>{figs or '<p>none</p>'}
<h2>Records</h2><table><tr><th>check</th><th>measured</th><th>bound</th><th>result</th><th>detail</th></tr>
{rows}</table></body></html>"""
    (folder / "index.html").write_text(page)
    return folder


def run(args) -> int:
    st = settings(args)
    from pbrbench.infer.photometric_stereo import METHODS
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache
    from pbrbench.render.proofs import CHECKS, run_checks

    if args.checks:
        unknown = [c for c in args.checks if c not in CHECKS]
        if unknown:
            from pbrbench.errors import UserError

            raise UserError(f"--checks: unknown check(s) {', '.join(unknown)}; choose from {', '.join(CHECKS)}")
    t0 = time.perf_counter()

    def progress(name, recs):
        bad = sum(not r["passed"] for r in recs)
        print(f"  {name}: {len(recs)} record(s), {bad} failed ({time.perf_counter() - t0:.1f}s)", file=sys.stderr, flush=True)

    figures: dict = {}
    records = run_checks(get_quality(args.quality), args.checks, RenderCache(st.cache), progress=progress,
                         diagnostics_dir=args.diagnostics, figures=figures,
                         photometric_stereo=METHODS["woodham1980"])
    seconds = time.perf_counter() - t0
    print(format_table(records))
    n_bad = sum(not r["passed"] for r in records)
    print(f"{len(records) - n_bad}/{len(records)} checks passed ({args.quality}, {seconds:.1f}s)", file=sys.stderr)
    for r in records:
        if not r["passed"]:
            print(f"FAIL {r['check']}: {r['detail']}", file=sys.stderr)
    run_id = None
    if not args.no_store:
        from pbrbench.bench.store import Store

        with Store(st.store_path()) as store:
            run_id = store.create_run(quality_name="validate", variant=None,
                                      config={"validate_quality": args.quality, "checks": args.checks or list(CHECKS)})
            store.add_job_result(run_id, f"validate|{args.quality}", "validate", to_scores(records, args.quality, seconds),
                                 seconds=seconds)
            store.set_status(run_id, "complete")
        print(f"stored as run {run_id} in {st.store_path()}", file=sys.stderr)
    if run_id is None:
        from pbrbench.bench.store import new_run_id

        run_id = new_run_id()
    folder = Path(args.figures_dir) if args.figures_dir else Path(st.out) / f"validate-{run_id}"
    write_folder(folder, records, figures, quality=args.quality, run_id=run_id)
    print(f"records and {len(figures)} figure(s) in {folder}/ (index.html)", file=sys.stderr)
    return 0 if n_bad == 0 else 2
