"""``pbrbench`` entry point: discovers the subcommand modules of :mod:`pbrbench.cli`."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

import pbrbench
from pbrbench.errors import UserError

EXIT_OK, EXIT_USER, EXIT_REGRESSION = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="pbrbench", description=(
        "Physically based rendering testbed for light-and-shading vision: renders ground truth "
        "with Mitsuba 3, runs NumPy inference, scores and reports."))
    p.add_argument("--version", action="version", version=f"pbrbench {pbrbench.__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    import pbrbench.cli as cli_pkg

    for info in sorted(pkgutil.iter_modules(cli_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_") or info.name in ("main", "common"):
            continue
        mod = importlib.import_module(f"pbrbench.cli.{info.name}")
        if hasattr(mod, "register"):
            mod.register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USER
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"pbrbench: error: {exc}", file=sys.stderr)
        return EXIT_USER
    except KeyboardInterrupt:
        print("pbrbench: interrupted; completed work is kept (renders in the cache, scores in the store)", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
