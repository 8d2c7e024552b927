"""Options and helpers shared by several subcommands.

Every subcommand resolves one :class:`pbrbench.settings.Settings` from its arguments
(:func:`settings`) and passes it on; quality choices come from the quality profiles.
"""

from __future__ import annotations

from pathlib import Path


def add_quality(p, default="standard"):
    from pbrbench.render.quality import PRESETS

    descr = "; ".join(f"{q.name}: {q.description}" for q in PRESETS.values() if q.description)
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


def settings(args):
    """The settings of this invocation (argument, else environment, else default); the Mitsuba
    variant choice is configured with them before anything renders."""
    from pbrbench.render import variant
    from pbrbench.settings import Settings

    s = Settings.resolve(args)
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
