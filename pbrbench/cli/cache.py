"""``pbrbench cache info|clear``: inspect or empty the render cache."""

from __future__ import annotations

from pbrbench.cli.common import add_cache, settings


def register(sub):
    p = sub.add_parser("cache", help="inspect or clear the render cache")
    p.add_argument("action", choices=["info", "clear"])
    add_cache(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.render.cache import RenderCache

    c = RenderCache(settings(args).cache)
    if args.action == "info":
        i = c.info()
        print(f"root     {i['root']}\nentries  {i['entries']}\nsize     {i['bytes'] / 1e6:.1f} MB")
        if i["stale_temporaries"]:
            print(f"stale    {i['stale_temporaries']} unfinished write(s) from interrupted renders (removed by `cache clear`)")
    else:
        print(f"removed {c.clear()} entries from {c.root}")
    return 0
