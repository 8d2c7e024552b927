"""nayar1991's iteration traced: the mean normal change of every correction and the normal error
after it, on the photometric-stereo task's own inputs.

Each argument is ``SCENE|CONDITION`` or ``SCENE|CONDITION|data``; ``data`` solves on the pixel set
inverse:nicolet2021 hands the method as its start (:func:`pbrbench.inverse.heightfield.pixel_sets`),
not the task's pure mask.  Prints, per correction, the change (degrees), the mean normal error
over the task's evaluation domain (degrees) and the distance of the normals from those of the
most settled correction so far (the one with the smallest change), with woodham1980's error.
The figures of ``docs/nayar1991.md`` ("Tried: a test on the iteration's steps") come from:

    python scripts/nayar1991_iterations.py --history 0 --max-iter 20 \\
        "ps_groove[albedo=0.9]|global|data" "ps_groove[albedo=0.5]|local" \\
        "ps_groove[albedo=0.7]|local+ambient0.1" "ps_cup[albedo=0.9]|local+ambient0.1" "ps_cup[albedo=0.9]|global"

A scene not in the render cache is rendered first (about a minute each at standard quality).
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> None:
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.infer.photometric_stereo import nayar1991 as ny
    from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980
    from pbrbench.inverse.heightfield import pixel_sets
    from pbrbench.metrics.normals import normal_scores
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.settings import Settings
    from pbrbench.tasks.base import Job
    from pbrbench.tasks.photometric_stereo import PhotometricStereoTask

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("items", nargs="+", help="SCENE|CONDITION[|data]")
    ap.add_argument("--history", type=int, default=3, help="Anderson steps (0: the plain iteration; default 3)")
    ap.add_argument("--max-iter", type=int, default=10)
    ap.add_argument("--quality", default="standard")
    ap.add_argument("--cache", default=None, help="render cache folder (default: pbrbench's)")
    args = ap.parse_args(argv)

    task = PhotometricStereoTask()
    quality = get_quality(args.quality)
    library = SceneLibrary()
    src = GroundTruthSource(quality, cache=RenderCache(args.cache or Settings.from_env().cache), library=library)
    states = []
    change = ny._mean_change

    def record(n0, n1, m):                   # every correction's normals, as the iteration forms them
        states.append((n1.copy(), m.copy()))
        return change(n0, n1, m)

    ny._mean_change = record
    for item in args.items:
        name, cond, *rest = item.split("|")
        spec = src.specs([name])[name]
        gt = src.load(spec)
        job = Job(task.name, name, cond, task._params(spec))
        images = task._inputs(job, gt, 0)
        lights = np.asarray(job.param("lights"), float)
        mask = pixel_sets(gt.mask, images)[0] if rest == ["data"] else gt.mask
        domain = task._domain(gt, lights) & mask
        truth = gt["normals"].astype(float)
        states.clear()
        r = ny.photometric_stereo_nayar1991(images, lights, mask=mask, history=args.history, max_iter=args.max_iter)
        w = photometric_stereo_woodham1980(images, lights, mask=mask)
        errs = [normal_scores(n, truth, domain, v)[0]["normal_mean_deg"] for n, v in states]
        dist, best = [], 0
        for t, c in enumerate(r.changes):
            best = t if c <= r.changes[best] else best
            dist.append(change(states[t][0], states[best][0], states[t][1] & states[best][1]))
        we = normal_scores(w.normals, truth, domain, w.valid)[0]["normal_mean_deg"]
        print(f"{item}: woodham1980 {we:.2f} deg, refuted {r.refuted}")
        for label, row in (("change", r.changes), ("error", errs), ("from settled", dist)):
            print(f"  {label:12s} " + " ".join(f"{v:5.2f}" for v in row), flush=True)


if __name__ == "__main__":
    main()
