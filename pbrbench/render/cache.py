"""Content-addressed render cache: one directory per ground truth, written atomically.

Key: sha256 of (canonical scene spec hash, the quality profile's render settings, variant, mitsuba
version, ground-truth format).
Entry: ``<root>/<key[:2]>/<key>/gt.exr`` (float32 multichannel, lossless) and ``gt.json``
(metadata, with the EXR's size and sha256).  An entry is written into a temporary directory
beside its final place and renamed into place in one step, so a render killed at any moment
leaves either no entry or a complete one; a reader also checks the EXR's checksum before
trusting it, and throws away anything that does not match.

Root: ``--cache`` / ``PBRBENCH_CACHE``, else ``$XDG_CACHE_HOME/pbrbench`` (``~/.cache/pbrbench``).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from pbrbench.errors import UserError, disk_error
from pbrbench.io import read_exr, write_exr, write_text
from pbrbench.quality import Quality, require
from pbrbench.render.groundtruth import GT_FORMAT, GroundTruth, render_ground_truth
from pbrbench.render.variant import choose_variant, current_choice
from pbrbench.scene.spec import SceneSpec
from pbrbench.versions import version


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def cache_key(spec: SceneSpec, quality: Quality, variant: str) -> str:
    mv = version("mitsuba") or "?"
    blob = json.dumps({"scene": spec.content_hash(), "quality": require(quality).render_key(), "variant": variant,
                       "mitsuba": mv, "format": GT_FORMAT}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()


class RenderCache:
    """Ground truths on disk, keyed by content."""

    def __init__(self, root: str | os.PathLike):
        """``root``: the cache directory (the ``cache`` setting, :class:`pbrbench.settings.Settings`)."""
        self.root = Path(root)

    def entry_dir(self, key: str) -> Path:
        return self.root / "gt" / key[:2] / key

    def meta(self, key: str) -> dict | None:
        """The metadata of a complete entry without reading its images (None when the entry is
        absent or its metadata unreadable; :meth:`get` still verifies the images' checksum)."""
        d = self.entry_dir(key)
        if not ((d / "gt.json").is_file() and (d / "gt.exr").is_file()):
            return None
        try:
            return json.loads((d / "gt.json").read_text())
        except (OSError, ValueError):
            return None

    def get(self, key: str) -> GroundTruth | None:
        """The cached ground truth, or None if absent or not intact (then it is removed)."""
        d = self.entry_dir(key)
        meta_p, exr_p = d / "gt.json", d / "gt.exr"
        if not (meta_p.is_file() and exr_p.is_file()):
            return None
        try:
            meta = json.loads(meta_p.read_text())
            if meta.get("exr_size") != exr_p.stat().st_size or meta.get("exr_sha256") != _sha256(exr_p):
                raise ValueError("checksum mismatch")
            arrays = read_exr(exr_p)
        except Exception:  # a damaged entry is never read as valid
            shutil.rmtree(d, ignore_errors=True)
            return None
        return GroundTruth(arrays, meta)

    def put(self, key: str, gt: GroundTruth) -> Path:
        """Store ``gt`` under ``key``: written into a temporary directory, read back and compared,
        then renamed into place.  A disk fault (full, read-only, no permission) raises a one-line
        :class:`~pbrbench.errors.DiskError` and leaves no entry."""
        final = self.entry_dir(key)
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=f".tmp-{key[:12]}-", dir=final.parent))
        except OSError as exc:
            raise disk_error(exc, f"render cache {self.root}", option="--cache or PBRBENCH_CACHE") from None
        try:
            exr = tmp / "gt.exr"
            write_exr(exr, gt.arrays)
            back = read_exr(exr)  # what a later reader will see must be what was rendered
            if set(back) != set(gt.arrays) or any(back[k].tobytes() != np.asarray(gt.arrays[k], np.float32).tobytes()
                                                   for k in back):
                raise OSError(f"{exr}: the written EXR does not read back identically")
            meta = dict(gt.meta, cache_key=key, exr_size=exr.stat().st_size, exr_sha256=_sha256(exr))
            write_text(tmp / "gt.json", json.dumps(meta, indent=1, sort_keys=True))
            try:
                os.rename(tmp, final)
            except OSError:
                # another process finished the same entry first: keep theirs
                shutil.rmtree(tmp, ignore_errors=True)
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            raise disk_error(exc, f"render cache {self.root}", option="--cache or PBRBENCH_CACHE") from None
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return final

    def _check_root(self):
        if self.root.exists() and not self.root.is_dir():
            from pbrbench.errors import DiskError

            raise DiskError(f"render cache {self.root}: is a file, not a directory; choose another with --cache or "
                            "PBRBENCH_CACHE")

    def entries(self) -> list[Path]:
        self._check_root()
        return sorted(p for p in (self.root / "gt").glob("*/*") if p.is_dir() and not p.name.startswith(".tmp-"))

    def info(self) -> dict:
        entries = self.entries()
        size = sum(f.stat().st_size for e in entries for f in e.iterdir() if f.is_file())
        stale = [p for p in (self.root / "gt").glob("*/.tmp-*")]
        return {"root": str(self.root), "entries": len(entries), "bytes": size, "stale_temporaries": len(stale)}

    def clear(self) -> int:
        """Remove every entry (and unfinished temporaries); returns how many entries there were.
        A cache that cannot be emptied (read-only, no permission) raises a one-line DiskError."""
        n = len(self.entries())
        gt = self.root / "gt"
        if gt.exists() and not gt.is_dir():
            raise disk_error(NotADirectoryError(20, "Not a directory", str(gt)), f"render cache {self.root}",
                             option="--cache or PBRBENCH_CACHE")
        if not gt.exists():
            return n
        errors: list[OSError] = []
        shutil.rmtree(gt, onexc=lambda fn, path, exc: errors.append(exc)) if sys.version_info >= (3, 12) else \
            shutil.rmtree(gt, onerror=lambda fn, path, info: errors.append(info[1]))
        if errors or gt.exists():
            exc = errors[0] if errors else OSError(f"{gt} could not be removed")
            raise disk_error(exc, f"render cache {self.root}", option="--cache or PBRBENCH_CACHE")
        return n


def check_ground_truth(spec: SceneSpec, gt: GroundTruth) -> None:
    """The last line of defence against a useless render: refuse (UserError naming the scene) a
    ground truth whose radiance is non-finite anywhere or zero in every pixel (every scene has a
    light that emits: the schema refuses the others).  Such a render is never cached.  The message
    says whether the camera sees geometry (the coverage pass) or not.  A black render of black
    surfaces (the albedo pass zero wherever the camera sees geometry, e.g. the albedo-0 end of a
    sweep, the local model's reference) is the right answer and passes."""
    where = f"scene {spec.name!r}" + (f" ({spec.source})" if spec.source else "")
    for name in ("radiance", "direct"):
        if name in gt:
            bad = int((~np.isfinite(gt[name])).sum())
            if bad:
                raise UserError(f"{where}: the rendered {name} has {bad} non-finite value(s) (NaN or inf); the scene's "
                                "numbers are out of the renderer's range (check sizes, positions and powers); not cached")
    if (gt["radiance"] > 0).any():
        return
    seen = (gt["coverage"] > 0) if "coverage" in gt else None
    if seen is not None and seen.any() and "albedo" in gt:
        albedo = np.asarray(gt["albedo"])
        if not (albedo[seen.reshape(albedo.shape[:2])] > 0).any():
            return  # every visible surface is black: zero radiance is correct
    if seen is not None and not seen.any():
        raise UserError(f"{where}: the rendered radiance is zero in every pixel and the camera sees no geometry: check "
                        "camera.origin / target / half_width and that the shapes lie between near_clip and far_clip; "
                        "not cached")
    raise UserError(f"{where}: the rendered radiance is zero in every pixel although the camera sees geometry: "
                    "no light reaches the visible surfaces (light directions point from the scene toward the "
                    "source; check the lights' positions and directions and the albedos); not cached")


def ground_truth(spec: SceneSpec, quality: Quality, *, cache: RenderCache,
                 variant: str | None = None, force: bool = False, progress=None) -> tuple[GroundTruth, bool]:
    """The ground truth of ``spec`` from the cache, rendering it if missing.

    Returns ``(ground_truth, from_cache)``.
    """
    choice = current_choice() or choose_variant(variant)
    var = variant or choice.variant
    key = cache_key(spec, quality, var)
    if not force:
        gt = cache.get(key)
        if gt is not None:
            return gt, True
    gt = render_ground_truth(spec, quality, variant=var, progress=progress)
    check_ground_truth(spec, gt)
    gt.meta["cache_key"] = key
    cache.put(key, gt)
    return gt, False
