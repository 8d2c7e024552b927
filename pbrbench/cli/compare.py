"""``pbrbench compare RUN_A RUN_B``: per-metric differences between two runs, better or worse."""

from __future__ import annotations

import math


def register(sub):
    p = sub.add_parser("compare", help="per-metric differences between two stored runs")
    p.add_argument("run_a", help="the earlier / reference run (id, prefix, latest, -2)")
    p.add_argument("run_b", help="the run to compare with it")
    p.add_argument("--task", default=None, help="only this task")
    p.add_argument("--all", action="store_true", help="also list unchanged scores")
    from pbrbench.cli.common import nonnegative_float

    p.add_argument("--rel", type=nonnegative_float, default=0.0, metavar="R",
                   help="also call a change unchanged when |b - a| <= R * |a| (default 0)")
    p.add_argument("--html", nargs="?", const="", default=None, metavar="PATH",
                   help="also write a comparison page (default: <out>/compare-<A>-<B>/index.html)")
    from pbrbench.cli.common import add_store

    add_store(p)
    p.set_defaults(func=run)


KEY = ("task", "scene", "condition", "algorithm", "metric")


def differences(a_scores: list[dict], b_scores: list[dict], *, rel: float = 0.0) -> list[dict]:
    """Rows {key fields, a, b, delta, se, direction} with direction better / worse / same / only-a /
    only-b.  A change is better or worse only beyond 2 combined standard errors of the two scores
    (:data:`pbrbench.uncertainty.SIGNIFICANCE`; when both have one) plus ``rel * |a|``; below that
    it is "same" (within the noise)."""
    from pbrbench.uncertainty import SIGNIFICANCE, combined_se, finite

    A = {tuple(s[k] for k in KEY): s for s in a_scores}
    B = {tuple(s[k] for k in KEY): s for s in b_scores}
    rows = []
    for key in sorted(set(A) | set(B)):
        sa, sb = A.get(key), B.get(key)
        va = sa["value"] if sa else float("nan")
        vb = sb["value"] if sb else float("nan")
        better = (sb or sa)["better"]
        se = combined_se(sa.get("uncertainty"), sb.get("uncertainty")) if sa and sb else float("nan")
        noise = SIGNIFICANCE * se if finite(se) else 0.0
        if sa is None:
            d = "only-b"
        elif sb is None:
            d = "only-a"
        elif math.isnan(va) and math.isnan(vb):
            d = "same"
        elif math.isnan(va) or math.isnan(vb):
            d = "better" if math.isnan(va) else "worse"
        elif abs(vb - va) <= rel * abs(va) + noise or vb == va:
            d = "same"
        else:
            d = "better" if (vb < va) == (better == "lower") else "worse"
        rows.append(dict(zip(KEY, key, strict=True), a=va, b=vb, delta=vb - va, se=se, better=better, direction=d))
    return rows


def run(args) -> int:
    from pbrbench.cli.common import open_store, settings
    from pbrbench.report.html import fmt

    st = settings(args)
    with open_store(st) as store:
        a, b = store.resolve_run(args.run_a), store.resolve_run(args.run_b)
        rows = differences(store.scores(a, task=args.task), store.scores(b, task=args.task), rel=args.rel)
        runs = (store.get_run(a), store.get_run(b))
    counts = {}
    for r in rows:
        counts[r["direction"]] = counts.get(r["direction"], 0) + 1
    shown = [r for r in rows if args.all or r["direction"] != "same"]
    print(f"compare {a} -> {b}: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    if shown:
        cols = ("task", "scene", "condition", "algorithm", "metric")
        w = {c: max([len(c)] + [len(str(r[c])) for r in shown]) for c in cols}
        print("  ".join(c.ljust(w[c]) for c in cols) + f"  {'a':>10s} {'b':>10s} {'delta':>10s} {'± 2 SE':>9s}  direction")
        for r in shown:
            print("  ".join(str(r[c]).ljust(w[c]) for c in cols)
                  + f"  {fmt(r['a']):>10s} {fmt(r['b']):>10s} {fmt(r['delta']):>10s} {fmt(2 * r['se']):>9s}  "
                  f"{r['direction']} ({r['better']} is better)")
    if args.html is not None:
        from pathlib import Path

        from pbrbench.report.html import write_compare

        path = Path(args.html) if args.html else Path(st.out) / f"compare-{a}-{b}" / "index.html"
        print(f"comparison page: {write_compare(path, runs, rows, counts).resolve()}")
    return 0
