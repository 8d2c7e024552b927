"""``pbrbench history [--task T]``: list the stored runs."""

from __future__ import annotations


def register(sub):
    p = sub.add_parser("history", help="list the stored benchmark runs")
    p.add_argument("--task", default=None, help="only runs that scored this task")
    from pbrbench.cli.common import add_store
    from pbrbench.quality import names

    p.add_argument("--quality", default=None, choices=names())
    from pbrbench.cli.common import int_at_least

    p.add_argument("--limit", type=int_at_least(1), default=30, help="show the last N runs (default 30)")
    add_store(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.cli.common import open_store, settings

    with open_store(settings(args)) as store:
        runs = store.runs(task=args.task, quality_name=args.quality, limit=args.limit)
    if not runs:
        print("no runs stored" + (f" for task {args.task}" if args.task else ""))
        return 0
    from pbrbench.errors import printable

    print(f"{'run':22s} {'time (UTC)':20s} {'quality':8s} {'status':21s} {'scores':>6s}  {'git':14s} tasks")
    for r in runs:
        print(printable(f"{r['id']:22s} {r['time'][:19]:20s} {r['quality'] or '':8s} {r['status'] or '?':21s} "
                        f"{r['n_scores']:6d}  {(r['git_revision'] or '-')[:14]:14s} {r['tasks'] or ''}"))
    dead = [r["id"] for r in runs if r["status"] == "interrupted"]
    if dead:
        print(f"{len(dead)} run(s) interrupted (their process is gone); continue one with "
              f"`pbrbench run --resume {dead[-1]}`")
    return 0
