"""The versions a result records: one place that asks the installed packages.

:func:`version` of one distribution (None when it is not installed), :func:`versions` of the
ones every ground truth records, :func:`installed_versions` of every distribution the
interpreter imports (what :mod:`pbrbench.lock` compares with the lock).  Only the standard library.
"""

from __future__ import annotations

import importlib.metadata as md
import platform
import re

RECORDED = ("pbrbench", "mitsuba", "drjit", "numpy", "scipy")   # with every ground truth and run


def normalize(name: str) -> str:
    """A distribution name in its canonical form (PEP 503: lower case, runs of -_. as one -)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def version(pkg: str) -> str | None:
    """The installed version of distribution ``pkg``, or None."""
    try:
        return md.version(pkg)
    except md.PackageNotFoundError:
        return None


def versions(pkgs=RECORDED) -> dict[str, str | None]:
    """``{"python": ..., pkg: version or None}`` for ``pkgs``."""
    return {"python": platform.python_version(), **{p: version(p) for p in pkgs}}


def installed_versions() -> dict[str, str]:
    """``{normalized name: version}`` of the distributions this interpreter imports (the first
    one on ``sys.path`` where a name is installed twice, as the import system would pick)."""
    out: dict[str, str] = {}
    for dist in md.distributions():
        name = dist.metadata["Name"]
        if name:
            out.setdefault(normalize(name), dist.version)
    return out
