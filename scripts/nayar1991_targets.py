"""Scores of nayar1991 beside woodham1980 on the photometric-stereo scenes, through the task.

Runs :meth:`pbrbench.tasks.photometric_stereo.PhotometricStereoTask.run_job` (the benchmark's own
evaluation domain and metrics) on the standard renders of the shared cache and prints, per scene
and condition, the mean normal error, the albedo error and the seconds per call.  The numbers of
``docs/nayar1991.md`` come from this script:

    PYTHONPATH=$PWD OPENBLAS_NUM_THREADS=1 python scripts/nayar1991_targets.py \
        --cache /work/ref/dcache/pbrbench ps_groove ps_cup ps_bumps ps_vase sphere_5lights

A scene that is not in the cache is rendered (about a minute each at standard quality).
"""

from __future__ import annotations

import argparse

import numpy as np


def _floor(task, gt, lights, sigma: float = 2.0):
    """(mean normal error, albedo error) of Woodham's solve (shadow threshold 0.2, as nayar1991
    uses on corrected images) on ``global - G_sigma * (global - direct)`` inside the mask."""
    from scipy.ndimage import gaussian_filter

    from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980
    from pbrbench.metrics.normals import albedo_scores, normal_scores
    from pbrbench.tasks.common.inputs import grey

    glob, direct = task._stack(gt, "radiance"), task._stack(gt, "direct")
    m = gt.mask
    w = np.maximum(gaussian_filter(m.astype(float), sigma), 1e-12)
    smooth = np.stack([gaussian_filter(np.where(m, r, 0.0), sigma) / w for r in glob - direct])
    r = photometric_stereo_woodham1980(glob - np.where(m, smooth, 0.0), lights, mask=m, shadow_threshold=0.2)
    domain = task._domain(gt, lights)
    sc, _ = normal_scores(r.normals, gt["normals"].astype(float), domain, r.valid)
    al = albedo_scores(np.pi * r.albedo, grey(gt["albedo"]), domain & r.valid)
    return sc["normal_mean_deg"], al["albedo_rel_err"]


def main(argv=None) -> None:
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.tasks.base import Job
    from pbrbench.tasks.photometric_stereo import PhotometricStereoTask

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("families", nargs="+", help="scene families (every albedo of a swept one)")
    ap.add_argument("--cache", required=True, help="render cache folder")
    ap.add_argument("--scenes", default=None, help="scene library folder (default: pbrbench's own)")
    ap.add_argument("--quality", default="standard")
    ap.add_argument("--conditions", default="global,local")
    ap.add_argument("--algorithms", default="woodham1980,nayar1991")
    ap.add_argument("--floor", action="store_true",
                    help="also score the local solve on the global images minus the true interreflection "
                         "(global - direct) smoothed by a Gaussian of 2 px: what a method that models the "
                         "interreflection as a smooth field can reach on these renders (their sampling "
                         "noise stays)")
    args = ap.parse_args(argv)

    task = PhotometricStereoTask()
    quality = get_quality(args.quality)
    wanted = args.algorithms.split(",")
    algs = [a for a in task.builtin_algorithms() if a.name in wanted]
    library = SceneLibrary(args.scenes) if args.scenes else SceneLibrary()
    src = GroundTruthSource(quality, cache=RenderCache(args.cache), library=library)
    family = library.family
    print(f"{'scene':28s} {'condition':10s} " + " ".join(f"{a.name + ' (deg, alb %, s)':>34s}" for a in algs))
    for fam in args.families:
        for spec in family(fam):
            gt = src.load(src.specs([spec.name])[spec.name])
            for cond in args.conditions.split(","):
                job = Job(task.name, spec.name, cond, task._params(spec))
                res = task.run_job(job, {spec.name: gt}, seed=0, algorithms=algs, quality=quality)
                cells = []
                for a in algs:
                    sc = {s.metric: s for s in res.scores if s.algorithm == a.name}
                    if "failed" in sc and sc["failed"].value:
                        cells.append(f"{'failed':>34s}")
                        continue
                    deg, alb = sc["normal_mean_deg"].value, sc["albedo_rel_err"].value
                    cells.append(f"{deg:14.2f} {100 * alb:9.2f} {sc['normal_mean_deg'].seconds:9.2f}")
                if args.floor and cond == "global":
                    deg, alb = _floor(task, gt, np.asarray(job.param("lights"), float))
                    cells.append(f"  floor {deg:.2f} deg {100 * alb:.2f} %")
                print(f"{spec.name:28s} {cond:10s} " + " ".join(cells), flush=True)


if __name__ == "__main__":
    main()
