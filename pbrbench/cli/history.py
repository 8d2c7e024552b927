"""``pbrbench history [--task T]``: list the stored runs."""

from __future__ import annotations


def register(sub):
    p = sub.add_parser("history", help="list the stored benchmark runs")
    p.add_argument("--task", default=None, help="only runs that scored this task")
    p.add_argument("--quality", default=None, choices=["draft", "standard", "high"])
    p.add_argument("--limit", type=int, default=30, help="show the last N runs (default 30)")
    p.add_argument("--out", default="reports", metavar="DIR", help="reports directory (default: reports)")
    p.add_argument("--store", default=None, metavar="PATH", help="results database")
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.cli.report import open_store

    with open_store(args) as store:
        runs = store.runs(task=args.task, quality=args.quality, limit=args.limit)
    if not runs:
        print("no runs stored" + (f" for task {args.task}" if args.task else ""))
        return 0
    print(f"{'run':22s} {'time (UTC)':20s} {'quality':8s} {'status':21s} {'scores':>6s}  {'git':14s} tasks")
    for r in runs:
        print(f"{r['id']:22s} {r['time'][:19]:20s} {r['quality'] or '':8s} {r['status']:21s} {r['n_scores']:6d}  "
              f"{(r['git_revision'] or '-')[:14]:14s} {r['tasks'] or ''}")
    return 0
