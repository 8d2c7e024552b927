"""A cache of finished jobs, so a rerun with nothing changed takes seconds.

A job's result (scores with their uncertainties, figures) is a pure function of its inputs: the
job (task, scene, condition, parameters), the seed and quality profile, the ground truths it reads
(their render-cache keys: scene content, quality, variant, Mitsuba version, ground-truth format),
the algorithms it runs (names, options and versions: declared version plus a hash of their source;
their time limit and whether they run isolated or in-process, since an algorithm's failure, a
timeout, is a cached result too) and the code that scores them.  The fingerprint covers all of these; for the code it hashes every
source file of the installed pbrbench package, so any change to pbrbench re-runs every job (a
user's plugin is covered by its own version hash, a task defined outside pbrbench by the hash of
its module), and it includes the NumPy and SciPy versions.

Entries live under ``<render cache>/jobs/<fp[:2]>/<fp>.pkl``, written atomically; a damaged
entry is ignored and removed.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import pickle
import tempfile
from pathlib import Path

FORMAT = 1


@functools.lru_cache(maxsize=1)
def code_hash() -> str:
    """sha256 of every ``.py`` file of the pbrbench package (path and bytes) and of its noise scales."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode())
        h.update(p.read_bytes())
    from pbrbench.bench.uncertainty import SCALES_FILE
    from pbrbench.versions import version

    if SCALES_FILE.exists():     # the standard errors it gives replace replicates
        h.update(SCALES_FILE.read_bytes())

    for pkg in ("numpy", "scipy"):
        if version(pkg) is not None:
            h.update(f"{pkg}={version(pkg)}".encode())
    return h.hexdigest()


def fingerprint(job, *, seed: int, quality, gt_keys: list[str], algorithms, task=None, uncertainty=True) -> str:
    from pbrbench.registry import source_hash

    # the time limit and isolation mode too: a failure (a timeout) is cached, and is not replayed
    # under another limit
    algs = [(a.name, a.kind, a.interface, a.full_version, sorted((str(k), repr(v)) for k, v in a.options.items()),
             a.conditions, "in-process" if a.time_limit is None else f"isolated:{float(a.time_limit)!r}")
            for a in algorithms]
    blob = json.dumps({"format": FORMAT, "job": job.key, "extra": list(job.extra_scenes), "seed": int(seed),
                       "quality": getattr(quality, "name", str(quality)), "gts": list(gt_keys), "algorithms": algs,
                       "code": code_hash(), "task": source_hash(type(task)) if task is not None else "",
                       "uncertainty": uncertainty}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


class JobCache:
    """Finished job results by fingerprint (``root``: a directory; None disables the cache)."""

    def __init__(self, root):
        self.root = Path(root) if root is not None else None

    def _path(self, fp: str) -> Path:
        return self.root / fp[:2] / f"{fp}.pkl"

    def get(self, fp: str) -> dict | None:
        if self.root is None:
            return None
        p = self._path(fp)
        if not p.is_file():
            return None
        try:
            with open(p, "rb") as f:
                res = pickle.load(f)
            if not isinstance(res, dict) or res.get("fingerprint") != fp:
                raise ValueError("not an entry of this fingerprint")
            return res
        except Exception:  # noqa: BLE001 - a damaged entry is never read as valid
            p.unlink(missing_ok=True)
            return None

    def put(self, fp: str, result: dict) -> None:
        if self.root is None or result.get("error"):
            return
        p = self._path(fp)
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=p.parent)
            with os.fdopen(fd, "wb") as f:
                pickle.dump(dict(result, fingerprint=fp), f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, p)
        except OSError:
            # a cache that cannot be written only costs time next run
            try:
                os.unlink(tmp)
            except (OSError, UnboundLocalError):
                pass
