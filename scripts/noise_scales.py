"""Measure the noise scales of the inverse-rendering scores over independent render seeds.

    python scripts/noise_scales.py --seeds 8 [--quality standard] [--quality draft] [--cache DIR]
                                   [--out pbrbench/bench/noise_scales.json]

For every job of each ``--quality`` (default: standard) on which a scene-interface algorithm (inverse rendering) runs, the
job's scene is rendered with each render seed ``1 .. --seeds`` (every scene file's
``render.seed`` offset by it, as ``pbrbench run --render-seed``), the algorithm is scored on it
as the benchmark scores it (``run_job``, algorithm seed 0), and the sample standard deviation of
each metric over the seeds is written with its degrees of freedom (seeds - 1), the algorithm's
version, the scene's content hash at render seed 0, its noise hash (the content hash without the
render seed: the key, so the scale holds at any render seed of the same scene), the ground-truth
format it was measured on (an entry of another format is ignored) and the quality.  ``pbrbench run`` then takes
those scores' standard errors from this table instead of re-running the algorithm on the four
delete-one-group replicates (:mod:`pbrbench.bench.uncertainty`, ``docs/uncertainty.md``).  The
table is valid only for the algorithm version and scene content it names; anything else falls
back to the replicates.  The entries of qualities not measured are kept from ``--out``.  A draft
entry whose standard twin is in the table also gets its Monte Carlo bias, the difference of the
two means (``bias``, with ``bias_se``), which the run reports as the score's bias.  Nothing is
fetched; renders missing from the cache are made.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8, help="independent render seeds 1 .. N (>= 3)")
    ap.add_argument("--cache", default=None, help="render cache (default: pbrbench's)")
    ap.add_argument("--out", default="pbrbench/bench/noise_scales.json")
    ap.add_argument("--quality", action="append", choices=["draft", "standard"],
                    help="quality to measure (repeatable; default standard)")
    a = ap.parse_args(argv)
    if a.seeds < 3:
        ap.error("--seeds: give at least 3 render seeds")
    from pbrbench.bench.plan import load_tasks
    from pbrbench.quality import get_quality
    from pbrbench.registry import builtin_registry
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.settings import Settings

    qualities = list(dict.fromkeys(a.quality or ["standard"]))
    lib = SceneLibrary()
    tasks = {n: t.bind(lib) for n, t in load_tasks(["photometric_stereo"]).items()}
    task = tasks["photometric_stereo"]
    algs = [x for x in builtin_registry(tasks).for_task("photometric_stereo") if x.interface == "scene"]
    cache = RenderCache(a.cache or Settings.from_env().cache)
    entries = []
    try:
        with open(a.out) as f:
            entries = [e for e in json.load(f)["entries"] if e.get("quality") not in qualities]
    except FileNotFoundError:
        pass
    n_jobs = 0
    for qname in qualities:
        n_jobs += _measure(get_quality(qname), a.seeds, lib, task, tasks, algs, cache, entries)
    _draft_bias(entries)
    with open(a.out, "w") as f:
        json.dump({"about": "standard errors over independent render seeds (scripts/noise_scales.py)",
                   "entries": entries}, f, indent=1)
        f.write("\n")
    print(f"{len(entries)} scales ({', '.join(qualities)}: {n_jobs} job(s) measured) written to {a.out}")
    return 0


def _draft_bias(entries) -> None:
    """Give each draft entry whose standard twin (same task, scene, condition, algorithm, version
    and metric) is in the table its Monte Carlo bias: the difference of the two means over the
    render seeds, ``bias`` (standard's own bias neglected), with its standard error ``bias_se``."""
    std = {(e["task"], e["scene"], e["condition"], e["algorithm"], e["algorithm_version"], e["metric"]): e
           for e in entries if e["quality"] == "standard"}
    for e in entries:
        if e["quality"] != "draft":
            continue
        e.pop("bias", None)
        e.pop("bias_se", None)
        s = std.get((e["task"], e["scene"], e["condition"], e["algorithm"], e["algorithm_version"], e["metric"]))
        if s is not None:
            e["bias"] = e["mean"] - s["mean"]
            e["bias_se"] = math.sqrt(e["sd"] ** 2 / (e["dof"] + 1) + s["sd"] ** 2 / (s["dof"] + 1))


def _measure(q, seeds, lib, task, tasks, algs, cache, entries) -> int:
    """Append the entries of quality ``q`` to ``entries``; returns the number of jobs measured."""
    import numpy as np

    from pbrbench.bench.plan import plan
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.render.groundtruth import GT_FORMAT

    jobs = [j for j in plan(tasks, q) if not j.extra_scenes and j.param("plot") is None   # scored jobs, not figures
            and any(x.applies(j.condition) and task._inverse_applies(j, q) and x.applies_to_job(j, q) for x in algs)]
    src0 = GroundTruthSource(q, cache=cache, library=lib)
    for job in jobs:
        spec0 = src0.specs([job.scene])[job.scene]
        hash0 = str(src0.load(spec0).meta["scene_hash"])
        noise_hash = spec0.noise_hash()     # the key: the scale holds at any render seed of this content
        values: dict = {}
        for s in range(1, seeds + 1):
            src = GroundTruthSource(q, cache=cache, library=lib, render_seed=s)
            gt = src.load(src.specs([job.scene])[job.scene])
            t0 = time.perf_counter()
            res = task.run_job(job, {job.scene: gt}, seed=0, algorithms=algs, quality=q)
            for sc in res.scores:
                values.setdefault((sc.algorithm, sc.algorithm_version, sc.metric), []).append(sc.value)
            print(f"{job.scene} {job.condition} render seed {s}: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
        for (alg, version, metric), v in sorted(values.items()):
            if len(v) != seeds or not all(math.isfinite(x) for x in v):
                continue
            entries.append({"task": job.task, "scene": job.scene, "condition": job.condition, "scene_hash": hash0,
                            "noise_hash": noise_hash, "gt_format": GT_FORMAT, "algorithm": alg, "algorithm_version": version, "metric": metric,
                            "quality": q.name, "sd": float(np.std(v, ddof=1)), "dof": seeds - 1,
                            "mean": float(np.mean(v)), "render_seeds": list(range(1, seeds + 1))})
    return len(jobs)


if __name__ == "__main__":
    sys.exit(main())
