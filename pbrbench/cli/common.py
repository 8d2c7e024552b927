"""Options and helpers shared by several subcommands."""

from __future__ import annotations

import os
import sys
import time


def add_quality(p, default="standard"):
    p.add_argument("--quality", choices=["draft", "standard", "high"], default=default,
                   help=f"render quality preset (default: {default})")


def add_variant(p):
    p.add_argument("--variant", default=None,
                   help="Mitsuba variant (default: PBRBENCH_VARIANT, else cuda_ad_rgb / llvm_ad_rgb / scalar_rgb, whichever works)")


def add_cache(p):
    p.add_argument("--cache", default=None, help="render cache directory (default: PBRBENCH_CACHE or ~/.cache/pbrbench)")


def apply_env(args):
    """Options that must be in the environment before mitsuba is imported."""
    if getattr(args, "variant", None):
        os.environ["PBRBENCH_VARIANT"] = args.variant
    if getattr(args, "cache", None):
        os.environ["PBRBENCH_CACHE"] = args.cache


class RenderProgress:
    """A tqdm bar over render passes, shown only once a render has run longer than a second."""

    def __init__(self, total: int, desc: str):
        self.total, self.desc = total, desc
        self.t0 = time.perf_counter()
        self.bar = None
        self.n = 0

    def __call__(self, what: str):
        self.n += 1
        wanted = sys.stderr.isatty() or os.environ.get("PBRBENCH_PROGRESS") == "1"
        if self.bar is None and wanted and time.perf_counter() - self.t0 > 1.0:
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, desc=self.desc, unit="pass", leave=False, initial=self.n - 1)
        if self.bar is not None:
            self.bar.set_postfix_str(what)
            self.bar.update(1)

    def close(self):
        if self.bar is not None:
            self.bar.close()
