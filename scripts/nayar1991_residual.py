"""Does the fit residual tell the local model from nayar1991's interreflection model?

    python scripts/nayar1991_residual.py [--cache DIR] [SCENE ...]

Per scene and condition (``local``, ``global``, ``local+noise0.01``; standard renders, render
seed 0, the task's own inputs and domain): the mean normal error of woodham1980 and of nayar1991
with its premise test off (``shadow_light_min=0``), the RMS residual of each one's last local
solve over the pixels both solve (relative to the median brightest measurement there), and
nayar1991's per-iteration mean normal change.  The figures of docs/nayar1991.md ("Without
shadows") come from this script.  A scene missing from the cache is rendered.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

SCENES = ["ps_groove[albedo=0.9]", "ps_cap[albedo=0.9]", "ps_cup[albedo=0.9]"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=SCENES)
    ap.add_argument("--cache", default=None, help="render cache (default: pbrbench's)")
    a = ap.parse_args(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # the helper beside this script
    from _ps_inputs import ps_inputs

    from pbrbench.infer.photometric_stereo import (
        photometric_stereo_nayar1991,
        photometric_stereo_woodham1980,
    )
    from pbrbench.metrics.normals import normal_scores

    for name, cond, images, lights, mask, domain, n_true in ps_inputs(a.scenes, a.cache):
        w = photometric_stereo_woodham1980(images, lights, mask=mask)
        y = photometric_stereo_nayar1991(images, lights, mask=mask, shadow_light_min=0)
        both = w.valid & y.valid
        scale = float(np.median(images.max(axis=0)[both]))

        def rms(r, _b=both, _s=scale):
            return float(np.sqrt(np.mean(r.residual[_b] ** 2))) / _s

        def err(r, _n=n_true, _d=domain):
            return normal_scores(r.normals, _n, _d, r.valid)[0]["normal_mean_deg"]

        print(f"{name:22s} {cond:16s} woodham1980 {err(w):6.2f} deg residual {rms(w):.5f} | nayar1991 "
              f"{err(y):6.2f} deg residual {rms(y):.5f}, changes {np.round(y.changes, 3).tolist()}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
