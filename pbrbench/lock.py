"""The locked dependency set: which exact package versions a run used.

``requirements.lock`` at the root of a source checkout pins every Python package of the set-up
(pyproject.toml's dependencies with the ``dev`` and ``distributed`` extras, and the set-up's own
tools) to one version with the sha256 of each of its files; ``scripts/setup.sh`` installs exactly
those and ``make lock`` refreshes the file (docs/install.md).  :func:`locked_versions` describes
the running interpreter against it: the lock's sha256, the installed version of every locked
package (:mod:`importlib.metadata`) and each package whose installed version is not the locked
one, so two runs of one commit can be traced to the same (or a different) dependency set.

Imports nothing outside the standard library.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

from pbrbench.versions import installed_versions, normalize

__all__ = ["LOCK_FILE", "default_lock_path", "installed_versions", "locked_versions", "normalize", "parse_lock"]

LOCK_FILE = "requirements.lock"

# ``name[extras]==version`` at the start of a line; hashes, markers and comments follow
_PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)(?:\[[^\]]*\])?\s*==\s*([^\s;\\#]+)")




def default_lock_path() -> Path | None:
    """``requirements.lock`` of the source checkout this package is imported from, or None (an
    installed wheel has no lock)."""
    p = Path(__file__).resolve().parents[1] / LOCK_FILE
    return p if p.is_file() else None


def parse_lock(text: str) -> dict[str, str]:
    """``{normalized name: version}`` of the ``name==version`` pins of a requirements lock (the
    format ``uv pip compile`` and ``pip-compile`` write; hash, comment and option lines are
    skipped)."""
    pins = {}
    for line in text.splitlines():
        m = _PIN.match(line)
        if m:
            pins[normalize(m.group(1))] = m.group(2)
    return pins




def locked_versions(path: str | os.PathLike | None = None) -> dict:
    """The lock file's sha256 and the installed version of each package it pins.

    Parameters
    ----------
    path : path-like, optional
        The lock file; by default the source checkout's ``requirements.lock``.

    Returns
    -------
    dict
        ``{"lock_file": str | None, "lock_sha256": str | None, "packages": {name: installed
        version or None}, "mismatches": [{"name", "locked", "installed"}, ...]}``; names are
        normalized (PEP 503).  Without a lock (``path`` None and no checkout lock) the sha256 is
        None and both collections are empty.

    Raises
    ------
    ValueError
        ``path`` is not a file or pins nothing.
    """
    if path is None:
        p = default_lock_path()
        if p is None:
            return {"lock_file": None, "lock_sha256": None, "packages": {}, "mismatches": []}
    else:
        p = Path(path)
        if not p.is_file():
            raise ValueError(f"path: {str(p)!r} is not a file; pass the lock file (`make lock` writes "
                             f"{LOCK_FILE} at the repository root) or None for the checkout's")
    data = p.read_bytes()
    pins = parse_lock(data.decode("utf-8"))
    if not pins:
        raise ValueError(f"path: {str(p)!r} pins no package (no `name==version` line); pass a requirements "
                         f"lock such as {LOCK_FILE}")
    have = installed_versions()
    packages = {name: have.get(name) for name in sorted(pins)}
    mismatches = [{"name": name, "locked": pins[name], "installed": packages[name]}
                  for name in sorted(pins) if packages[name] != pins[name]]
    return {"lock_file": str(p), "lock_sha256": hashlib.sha256(data).hexdigest(), "packages": packages,
            "mismatches": mismatches}
