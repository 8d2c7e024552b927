"""``pbrbench scenes``: list the scene library with one-line descriptions."""

from __future__ import annotations


def register(sub):
    p = sub.add_parser("scenes", help="list the scene library")
    p.add_argument("--expand", action="store_true", help="list every scene of a sweep, not one line per file")
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.cli.common import settings
    from pbrbench.scene.load import library_files, load_scene_file

    for f in library_files(settings(args).scenes):
        specs = load_scene_file(f)
        if args.expand:
            for s in specs:
                print(f"{s.name:44s} {s.description}")
        else:
            n = f"  ({len(specs)} scenes)" if len(specs) > 1 else ""
            s = specs[0]
            ref = f" [{s.reference}]" if s.reference else ""
            print(f"{f.stem:28s} {s.description}{ref}{n}")
    return 0
