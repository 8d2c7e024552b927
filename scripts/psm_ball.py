"""Photometric stereo on a real photographed ball of the psmImages data (Goldman et al. 2005: the
``gray`` object, 12 lights), against the normals of the sphere that the mask outlines.

    python scripts/psm_ball.py DATA_DIR/psmImages/gray [--methods woodham1980 wu2010 ...]

The folder is read by :func:`pbrbench.datasets.psm.load_psm` (TGA images, ``lights.txt`` one
folder up, the mask); nothing is fetched.  No ground truth comes with the data: the sphere's
centre is the mask's centroid and its radius ``sqrt(area / pi)``, the normal of pixel ``(x, y)``
is ``((x - cx) / r, -(y - cy) / r, sqrt(1 - ...))`` (camera frame: x right, y up).  That fit is
uncertain by about a pixel, which near the outline (``r > 0.95``) moves the true normal by many
degrees, so the errors are printed per band of the normalised radius as well as over the mask.
An unsolved pixel counts as 90 degrees.
"""

from __future__ import annotations

import argparse
import sys
import time

BANDS = (0.0, 0.5, 0.7, 0.8, 0.9, 0.95, 1.0, 1.2)


def sphere_normals(mask):
    import numpy as np

    h, w = mask.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    cx, cy = xx[mask].mean(), yy[mask].mean()
    r = float(np.sqrt(mask.sum() / np.pi))
    nx, ny = (xx - cx) / r, -(yy - cy) / r
    rho = np.hypot(nx, ny)
    nz = np.sqrt(np.clip(1.0 - rho ** 2, 0.0, 1.0))
    n = np.stack([nx, ny, nz], -1)
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12), rho, (cx, cy, r)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--methods", nargs="+", default=["woodham1980", "ikehata2012_l1", "ikehata2012_sbl", "wu2010"])
    a = ap.parse_args(argv)
    import numpy as np

    from pbrbench.datasets.psm import load_psm
    from pbrbench.infer.photometric_stereo import METHODS

    obj = load_psm(a.folder)
    imgs = obj.images.mean(axis=-1) if obj.images.ndim == 4 else obj.images
    mask = obj.mask
    truth, rho, (cx, cy, r) = sphere_normals(mask)
    print(f"{a.folder}: {imgs.shape[0]} images {imgs.shape[1]}x{imgs.shape[2]}, {int(mask.sum())} mask pixels, "
          f"circle centre ({cx:.1f}, {cy:.1f}) radius {r:.1f} px")
    bands = list(zip(BANDS[:-1], BANDS[1:], strict=True))
    print(f"{'method':16s} {'mask':>6s} " + " ".join(f"{lo:.2f}-{hi:.2f}" for lo, hi in bands) + "   seconds")
    counts = [int((mask & (rho >= lo) & (rho < hi)).sum()) for lo, hi in bands]
    print(f"{'(pixels)':16s} {int(mask.sum()):6d} " + " ".join(f"{c:9d}" for c in counts))
    for m in a.methods:
        t = time.perf_counter()
        res = METHODS[m](imgs, obj.lights, mask=mask)
        dt = time.perf_counter() - t
        err = np.degrees(np.arccos(np.clip((res.normals * truth).sum(-1), -1.0, 1.0)))
        err = np.where(res.valid, err, 90.0)
        per = [err[mask & (rho >= lo) & (rho < hi)] for lo, hi in bands]
        print(f"{m:16s} {err[mask].mean():6.3f} " + " ".join(f"{e.mean():9.2f}" if e.size else f"{'-':>9s}" for e in per)
              + f"   {dt:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
