"""Robust photometric stereo on the rendered bunny sets of Matsushita's RobustPhotometricStereo
(https://github.com/yasumat/RobustPhotometricStereo, ``data/bunny``); docs/peers.md sets the
figures beside that repository's.

    python scripts/rps_bunny.py DATA_DIR [--methods woodham1980 ikehata2012_l1 ...]

``DATA_DIR`` is that repository's ``data/bunny`` folder: ``lights.npy`` (K x 3 unit vectors),
``gt_normal.npy`` (H x W x 3), ``mask.png`` and one sub-folder per set (``bunny_lambert``,
``bunny_lambert_noshadow``, ``bunny_specular``) of ``imageNNN.npy`` (H x W x 3 radiance, averaged
to grey as that repository's loader does).  Nothing is fetched.  Prints per set and method the
mean angular error over the mask and, as that repository's demo computes it, over the whole
image with the background counted as 0 (the figures of the peer's own metric), the coverage, and
the seconds.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import time


def load(data_dir: str, name: str):
    import numpy as np
    from PIL import Image

    files = sorted(glob.glob(os.path.join(data_dir, name, "*.npy")))
    if not files:
        raise SystemExit(f"{data_dir}/{name}: no imageNNN.npy files; give the repository's data/bunny folder")
    imgs = np.stack([np.load(f) for f in files]).astype(np.float64)
    if imgs.ndim == 4:
        imgs = imgs.mean(axis=-1)
    lights = np.load(os.path.join(data_dir, "lights.npy")).astype(np.float64)
    if lights.shape != (imgs.shape[0], 3):
        raise SystemExit(f"{data_dir}/lights.npy: shape {lights.shape}, expected ({imgs.shape[0]}, 3)")
    mask = np.asarray(Image.open(os.path.join(data_dir, "mask.png")).convert("L")) > 0
    normals = np.load(os.path.join(data_dir, "gt_normal.npy")).astype(np.float64)
    return imgs, lights, mask, normals


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir")
    ap.add_argument("--sets", nargs="+", default=["bunny_lambert_noshadow", "bunny_lambert", "bunny_specular"])
    ap.add_argument("--methods", nargs="+", default=["woodham1980", "ikehata2012_l1", "ikehata2012_sbl", "wu2010"])
    a = ap.parse_args(argv)
    import numpy as np

    from pbrbench.infer.photometric_stereo import METHODS

    for name in a.sets:
        imgs, lights, mask, n_gt = load(a.data_dir, name)
        print(f"{name}: {imgs.shape[0]} images {imgs.shape[1]}x{imgs.shape[2]}, {int(mask.sum())} masked pixels")
        for m in a.methods:
            t = time.perf_counter()
            r = METHODS[m](imgs, lights, mask=mask)
            dt = time.perf_counter() - t
            cos = np.clip(np.einsum("hwc,hwc->hw", r.normals, n_gt), -1.0, 1.0)
            err = np.degrees(np.arccos(cos))
            err = np.where(r.valid, err, 90.0)         # an unsolved pixel counts as 90 degrees
            whole = np.where(mask, err, 0.0)
            print(f"  {m:18s} mask mean {err[mask].mean():6.3f} deg   whole-image mean {whole.mean():6.3f} deg   "
                  f"coverage {r.valid[mask].mean():.3f}   {dt:6.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
