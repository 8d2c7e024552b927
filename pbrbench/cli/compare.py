"""``pbrbench compare RUN_A RUN_B``: per-metric differences between two runs, better or worse."""

from __future__ import annotations


def register(sub):
    p = sub.add_parser("compare", help="per-metric differences between two stored runs")
    p.add_argument("run_a", help="the earlier / reference run (id, prefix, latest, -2)")
    p.add_argument("run_b", help="the run to compare with it")
    p.add_argument("--task", default=None, help="only this task")
    p.add_argument("--all", action="store_true", help="also list unchanged scores")
    from pbrbench.cli.common import nonnegative_float

    p.add_argument("--rel", type=nonnegative_float, default=0.0, metavar="R",
                   help="also call a change unchanged when |b - a| <= R * |a| (default 0)")
    p.add_argument("--store-b", default=None, metavar="PATH",
                   help="read RUN_B from this results database (default: the same store as RUN_A)")
    p.add_argument("--html", nargs="?", const="", default=None, metavar="PATH",
                   help="also write a comparison page (default: <out>/compare-<A>-<B>/index.html)")
    from pbrbench.cli.common import add_store

    add_store(p)
    p.set_defaults(func=run)


KEY = ("task", "scene", "condition", "algorithm", "metric")


def _num(x) -> float:
    return float("nan") if x is None else float(x)


def differences(a_scores: list[dict], b_scores: list[dict], *, rel: float = 0.0) -> list[dict]:
    """Rows {key fields, a, b, delta, se, limit, direction, scene_changed, estimator_changed} with
    ``estimator_changed`` True where a seed-dependent score is one seed's draw in one run and the
    mean over its seeds in the other (``noise_mean``: runs stored before and after that change),
    and direction better /
    worse / same / only-a / only-b / unstable.  The rule is the regression check's
    (:func:`pbrbench.uncertainty.change` with one measurement on each side): a change is better or
    worse only beyond ``t_{1 - alpha/2}(dof) * sd * sqrt(2)``, ``sd`` pooled from the two scores'
    jackknife standard errors, plus the float32 rounding floor and ``rel * |a|``; below that it is
    "same" (within the noise).  A pair either of whose replicates are bimodal is "unstable"
    rather than better or worse.  Both NaN is "same"; NaN on one side only is worse (or better)."""
    from pbrbench.bench.regress import judge, unstable_of
    from pbrbench.uncertainty import combined_se, dof_of

    A = {tuple(s[k] for k in KEY): s for s in a_scores}
    B = {tuple(s[k] for k in KEY): s for s in b_scores}
    rows = []
    for key in sorted(set(A) | set(B)):
        sa, sb = A.get(key), B.get(key)
        va = sa["value"] if sa else float("nan")
        vb = sb["value"] if sb else float("nan")
        better = (sb or sa)["better"]
        se = combined_se(sa.get("uncertainty"), sb.get("uncertainty")) if sa and sb else float("nan")
        lim = float("nan")
        if sa is None:
            d = "only-b"
        elif sb is None:
            d = "only-a"
        else:
            d, lim, _ = judge(va, vb, sd_old=_num(sa.get("uncertainty")), dof_old=dof_of(sa),
                              sd_cur=_num(sb.get("uncertainty")), dof_cur=dof_of(sb), better=better, n_old=1,
                              unstable=bool(unstable_of(sa) or unstable_of(sb)), rel=rel)
        changed = bool(sa and sb and sa.get("scene_hash") and sb.get("scene_hash")
                       and sa["scene_hash"] != sb["scene_hash"])
        estimator = bool(sa and sb and sa.get("rep_noise") and sb.get("rep_noise")
                         and bool(sa.get("noise_mean")) != bool(sb.get("noise_mean")))
        rows.append(dict(zip(KEY, key, strict=True), a=va, b=vb, delta=vb - va, se=se, limit=lim, better=better,
                         direction=d, scene_changed=changed, estimator_changed=estimator))
    return rows


UNFINISHED = ("interrupted", "running", "failed")


def unfinished_lines(*runs: tuple[str, dict | None, int]) -> list[str]:
    """One line per run that did not finish (``interrupted``, ``running`` or ``failed``): its status,
    how many jobs it stored, and that its missing scores show as only-a / only-b.

    Parameters
    ----------
    runs : tuple of (str, dict or None, int)
        ``(run id, the stored run, jobs it stored)`` for run A, then run B.

    Returns
    -------
    list of str
        The lines, none when both runs finished.
    """
    out = []
    for (rid, run, n), side, other in zip(runs, ("A", "B"), ("only-b", "only-a"), strict=False):
        status = (run or {}).get("status")
        if status not in UNFINISHED:
            continue
        hint = ("wait for it to finish" if status == "running" else f"finish it with `pbrbench run --resume {rid}`")
        out.append(f"note: run {side} {rid} is {status} ({n} job{'s' if n != 1 else ''} stored): the scores it lacks "
                   f"show as {other}; {hint} and compare again")
    return out


def run(args) -> int:
    from pbrbench.cli.common import open_store, settings
    from pbrbench.report.html import fmt

    st = settings(args)
    with open_store(st) as store:
        a = store.resolve_run(args.run_a)
        a_scores, run_a, a_jobs = store.scores(a, task=args.task), store.get_run(a), len(store.done_jobs(a))
        if args.store_b is None:
            b = store.resolve_run(args.run_b)
            b_scores, run_b, b_jobs = store.scores(b, task=args.task), store.get_run(b), len(store.done_jobs(b))
    if args.store_b is not None:
        from pathlib import Path

        from pbrbench.errors import UserError

        if not Path(args.store_b).is_file():
            raise UserError(f"--store-b {args.store_b}: no results database there; pass the store of RUN_B")
        with open_store(st.with_(store=args.store_b)) as store_b:
            b = store_b.resolve_run(args.run_b)
            b_scores, run_b, b_jobs = store_b.scores(b, task=args.task), store_b.get_run(b), len(store_b.done_jobs(b))
    rows = differences(a_scores, b_scores, rel=args.rel)
    runs = (run_a, run_b)
    counts = {}
    for r in rows:
        counts[r["direction"]] = counts.get(r["direction"], 0) + 1
    shown = [r for r in rows if args.all or r["direction"] != "same"]
    print(f"compare {a} -> {b}: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    for line in unfinished_lines((a, run_a, a_jobs), (b, run_b, b_jobs)):
        print(line)
    n_hash = len({(r["scene"]) for r in rows if r["scene_changed"]})
    if n_hash:
        print(f"note: {n_hash} scene(s) have different content hashes in the two runs (scene file, data or render "
              "seed changed): their differences include that change")
    n_est = sum(1 for r in rows if r["estimator_changed"])
    if n_est:
        print(f"note: {n_est} score(s) of seed-dependent jobs are one seed's draw in one run and the mean over "
              "the seeds in the other (runs stored before and after 2026-12-04): their differences include "
              "that change of estimator")
    if shown:
        from pbrbench.text import text_table

        cols = ("task", "scene", "condition", "algorithm", "metric")
        table = [[str(r[c]) for c in cols] + [fmt(r["a"]), fmt(r["b"]), fmt(r["delta"]), fmt(r["limit"]),
                                              f"{r['direction']} ({r['better']} is better)"
                                              + (" [scene changed]" if r["scene_changed"] else "")
                                              + (" [estimator changed]" if r["estimator_changed"] else "")] for r in shown]
        for line in text_table(table, header=(*cols, "a", "b", "delta", "limit", "direction"), align="lllllrrrrl"):
            print(line)
    if args.html is not None:
        from pathlib import Path

        from pbrbench.report.html import write_compare

        path = Path(args.html) if args.html else Path(st.out) / f"compare-{a}-{b}" / "index.html"
        print(f"comparison page: {write_compare(path, runs, rows, counts).resolve()}")
    return 0
