"""Options and helpers shared by several subcommands.

Every subcommand resolves one :class:`pbrbench.settings.Settings` from its arguments
(:func:`settings`) and passes it on; quality choices come from the quality profiles.
"""

from __future__ import annotations

from pathlib import Path


def add_quality(p, default="standard"):
    from pbrbench.quality import PRESETS

    # argparse %-formats help strings: a literal % in a description must be doubled
    descr = "; ".join(f"{q.name}: {q.description}" for q in PRESETS.values() if q.description).replace("%", "%%")
    p.add_argument("--quality", choices=list(PRESETS), default=default,
                   help=f"quality profile (default: {default}). {descr}")


def add_variant(p):
    p.add_argument("--variant", default=None,
                   help="Mitsuba variant (default: PBRBENCH_VARIANT, else cuda_ad_rgb / llvm_ad_rgb / scalar_rgb, whichever works)")


def add_cache(p):
    p.add_argument("--cache", default=None, help="render cache directory (default: PBRBENCH_CACHE or ~/.cache/pbrbench)")


def add_store(p):
    p.add_argument("--out", default=None, metavar="DIR", help="reports directory (default: reports)")
    p.add_argument("--store", default=None, metavar="PATH",
                   help="results database (default: PBRBENCH_STORE or DIR/history.sqlite)")


def int_at_least(lo: int, hi: int | None = None):
    """An argparse type: an integer in [lo, hi] (a usage error, exit 1, otherwise)."""
    import argparse

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"{v} is out of range: give an integer >= {lo}"
                                             + (f" and <= {hi}" if hi is not None else ""))
        return v
    parse.__name__ = "integer"
    return parse


def nonnegative_float(text: str) -> float:
    """An argparse type: a finite number >= 0."""
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a finite number >= 0")
    return v


def settings(args):
    """The settings of this invocation (argument, else environment, else default); the Mitsuba
    variant choice is configured with them before anything renders."""
    from pbrbench.errors import UserError
    from pbrbench.render import variant
    from pbrbench.settings import Settings

    for opt in ("cache", "out", "store", "variant"):
        v = getattr(args, opt, None)
        if isinstance(v, str) and not v.strip():
            raise UserError(f"--{opt} is empty; give a {'variant name' if opt == 'variant' else 'path'}")
    s = Settings.resolve(args)
    if s.variant:
        variant.check_variant_name(s.variant)  # before anything runs: no junk run, no half render
    variant.configure(s)
    return s


def open_store(s):
    """The results database of settings ``s`` for reading: opened for writing when it can be
    (a migration may be due), else read-only (an archived or read-only database still reads);
    a one-line error when there is none yet or it is not a results database."""
    from pbrbench.bench.store import Store
    from pbrbench.errors import UserError

    p = Path(s.store_path())
    if p.is_dir():
        raise UserError(f"--store {p}: is a directory; give the path of a results database file")
    if not p.is_file():
        raise UserError(f"--store {p}: no results database there; run `pbrbench run` first or pass --store")
    return Store(p, readonly=None)
