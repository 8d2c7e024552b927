"""``pbrbench scenes``: list the scene library with one-line descriptions."""

from __future__ import annotations


def register(sub):
    p = sub.add_parser("scenes", help="list the scene library")
    p.add_argument("--expand", action="store_true", help="list every scene of a sweep, not one line per file")
    p.set_defaults(func=run)


def run(args) -> int:
    """One line per file (or per scene): text from the files is printed through
    :func:`pbrbench.errors.printable` (no terminal control sequences, no line breaks)."""
    from pbrbench.cli.common import settings
    from pbrbench.errors import UserError, printable
    from pbrbench.scene.load import SceneLibrary

    st = settings(args)
    lib = SceneLibrary.from_settings(st)
    files = lib.files()
    if not files:
        raise UserError(f"scene library {st.scenes}: no .toml scene files there; set PBRBENCH_SCENES to a directory "
                        "of scene files")
    for f in files:
        specs = lib.load_file(f)
        if args.expand:
            for s in specs:
                print(f"{printable(s.name):44s} {printable(s.description)}")
        else:
            n = f"  ({len(specs)} scenes)" if len(specs) > 1 else ""
            s = specs[0]
            ref = f" [{printable(s.reference)}]" if s.reference else ""
            print(f"{printable(f.stem):28s} {printable(s.description)}{ref}{n}")
    return 0
