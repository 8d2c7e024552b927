"""``pbrbench validate``: prove the ground truth right (closed forms and statistical render tests)."""

from __future__ import annotations

import sys
import time

from pbrbench.cli.common import add_cache, add_quality, add_variant, settings


def register(sub):
    from pbrbench.render.proofs import CHECKS

    p = sub.add_parser("validate", help="check the renderer against closed forms and statistical tests (exit 2 on failure)")
    add_quality(p, default="draft")
    add_variant(p)
    add_cache(p)
    p.add_argument("--checks", nargs="+", metavar="CHECK", default=None,
                   help=f"run only these checks (default: all): {', '.join(CHECKS)}")
    p.add_argument("--diagnostics", default=None, metavar="DIR",
                   help="write diagnostic images of failed statistical comparisons here")
    p.set_defaults(func=run)


def format_table(records: list[dict]) -> str:
    rows = [("check", "measured", "bound", "result")]
    for r in records:
        rows.append((r["check"], f"{r['measured']:.3g}", f"{r['bound']:.3g}", "pass" if r["passed"] else "FAIL"))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = []
    for k, row in enumerate(rows):
        lines.append("  ".join(c.ljust(widths[i]) if i == 0 else c.rjust(widths[i]) for i, c in enumerate(row)))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def run(args) -> int:
    st = settings(args)
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

    records = run_checks(args.quality, args.checks, RenderCache(st.cache), progress=progress,
                         diagnostics_dir=args.diagnostics)
    print(format_table(records))
    n_bad = sum(not r["passed"] for r in records)
    print(f"{len(records) - n_bad}/{len(records)} checks passed ({args.quality}, {time.perf_counter() - t0:.1f}s)", file=sys.stderr)
    for r in records:
        if not r["passed"]:
            print(f"FAIL {r['check']}: {r['detail']}", file=sys.stderr)
    return 0 if n_bad == 0 else 2
