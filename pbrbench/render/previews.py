"""PNG previews of every ground-truth channel, so a person can look at what the testbed produces."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbrbench.io import ensure_dir, write_colormap_png, write_normals_png, write_preview
from pbrbench.render.groundtruth import JK, GroundTruth

RADIANCE_LIKE = ("radiance", "direct", "indirect", "diffuse_only", "direct_unoccluded")


def write_previews(gt: GroundTruth, out: str | Path) -> list[Path]:
    """Write one PNG per channel into ``out``; radiance-like images share one exposure."""
    out = ensure_dir(out)
    written = []
    rad = gt.arrays["radiance"]
    pos = rad[rad > 0]
    exposure = 1.0 / float(np.percentile(pos, 99.5)) if pos.size else 1.0
    mask = gt.arrays["coverage"] > 0
    for name, a in sorted(gt.arrays.items()):
        p = out / f"{name}.png"
        if JK in name:
            if not name.endswith(f"{JK}0") or name.startswith("mask"):
                continue   # one map of the jackknife sd per array (written with the first deviation)
            stem = name[: -len(JK) - 1]
            p = out / f"{stem}_sd.png"
            base = gt.arrays[stem]
            sd = gt[f"{stem}_sd"]
            if base.ndim == 3 and stem != "normals":
                b = base.mean(-1)
                with np.errstate(divide="ignore", invalid="ignore"):
                    rel = np.where(b > 1e-3 * b.max(), sd.mean(-1) / b, np.nan)
                write_colormap_png(p, rel, label="relative sd (Monte Carlo noise)", cmap="magma")
            else:
                sd = np.linalg.norm(sd, axis=-1) if sd.ndim == 3 else sd
                write_colormap_png(p, sd, label="sd (Monte Carlo noise)", cmap="magma", mask=mask)
        elif name in RADIANCE_LIKE or name.startswith("light"):
            write_preview(p, np.maximum(a, 0), exposure=exposure)
        elif name == "albedo":
            write_preview(p, a, exposure=1.0)
        elif name == "normals":
            write_normals_png(p, a, mask)
        elif name == "depth":
            write_colormap_png(p, a, label="depth along the view axis", mask=mask)
        elif name == "unoccluded_fraction":
            write_colormap_png(p, a, label="unoccluded fraction", cmap="gray", vmin=0, vmax=1)
        elif name == "object_id":
            write_colormap_png(p, a, label="object id", cmap="tab10")
        elif name in ("mask", "coverage"):
            write_colormap_png(p, a, label=name, cmap="gray", vmin=0, vmax=1)
        elif name == "position":
            continue
        else:
            write_preview(p, np.maximum(a, 0))
        written.append(p)
    return written
