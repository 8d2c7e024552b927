"""Do the standard errors hold per algorithm?  Render scenes with N independent render seeds and
compare each score's spread over the seeds with the standard error a single render predicts.

    python scripts/seed_calibration.py [--quality draft] [--seeds 8] [--cache DIR]
        [--scene photometric_stereo=ps_groove[albedo=0.9]] [--scene sfs=sfs_vase] ...

For every (task, scene, condition, algorithm, metric) scored at every seed: ``observed`` = the
standard deviation of the values over the seeds, ``predicted`` = the RMS of their jackknife
standard errors.  Prints, per task and algorithm, ``sqrt(mean(observed^2 / predicted^2))`` over
its scores (scale-free; noise-free scores, with predicted and observed below float32 rounding,
are left out), the median per-score ratio, and the same over every score; a well-calibrated SE
gives 1.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import defaultdict

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quality", default="draft")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--cache", default=None)
    ap.add_argument("--scene", action="append", default=None, metavar="TASK=SCENE")
    ap.add_argument("--worst", type=int, default=0, metavar="N", help="also list the N scores furthest from 1")
    a = ap.parse_args(argv)
    pairs = [s.split("=", 1) for s in (a.scene or ["photometric_stereo=ps_groove[albedo=0.9]", "sfs=sfs_vase"])]

    from pbrbench.bench.plan import load_tasks
    from pbrbench.bench.run import execute_job
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.quality import get_quality
    from pbrbench.registry import builtin_registry
    from pbrbench.render.cache import RenderCache
    from pbrbench.settings import Settings

    q = get_quality(a.quality)
    tasks = load_tasks(sorted({t for t, _ in pairs}))
    reg = builtin_registry(tasks)
    cache = RenderCache(a.cache or Settings.from_env().cache)
    per = defaultdict(list)        # (task, condition, algorithm, metric, scene) -> [(value, se)]
    for seed in range(a.seeds):
        src = GroundTruthSource(q, cache=cache, render_seed=seed)
        for tname, scene in pairs:
            task = tasks[tname]
            jobs = [j for j in task.jobs(q) if j.scene.split(":")[0] == scene and j.param("plot") is None]
            if not jobs:
                print(f"no job of {tname} on {scene} at {q.name}", file=sys.stderr)
                return 1
            algs = reg.for_task(tname)
            for job in jobs:
                specs = src.specs([job.scene, *job.extra_scenes])
                res = execute_job(task, job, specs, src, seed, "j", algs, q)
                if res["error"]:
                    print(res["error"], file=sys.stderr)
                    return 1
                for s in res["scores"]:
                    if s["metric"] in ("failed", "converged"):
                        continue
                    label = job.param("label")
                    per[(tname, job.condition, s["algorithm"], s["metric"],
                         job.scene + (f":{label}" if label else "") + ("" if len(jobs) == len({(j.condition, j.param("label")) for j in jobs}) else f" {job.key}"))].append(
                        (s["value"], s["uncertainty"]))
        print(f"seed {seed + 1}/{a.seeds} done", file=sys.stderr, flush=True)
    by_alg = defaultdict(lambda: [[], [], []])      # observed var, predicted var, per-score ratio
    listed = []
    for (tname, _cond, alg, _m, _sc), vs in per.items():
        if len(vs) < a.seeds:
            continue
        v = np.array([x for x, _ in vs])
        u = np.array([e for _, e in vs])
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(u))):
            continue
        obs, pred = float(np.var(v, ddof=1)), float(np.mean(u ** 2))
        floor = (1e-5 + 1e-4 * float(np.abs(v).mean())) ** 2
        if obs <= floor and pred <= floor:
            continue
        b = by_alg[(tname, alg)]
        b[0].append(obs)
        b[1].append(pred)
        b[2].append(math.sqrt(obs / pred) if pred > 0 else math.inf)
        listed.append((b[2][-1], (tname, _cond, alg, _m, _sc), [round(float(x), 5) for x in v], [round(float(x), 5) for x in u]))
    print(f"{'task':20s} {'algorithm':34s} {'scores':>6s} {'pooled':>7s} {'median':>7s}")
    allo, allp = [], []
    for (tname, alg), (o, p, r) in sorted(by_alg.items()):
        allo += o
        allp += p
        print(f"{tname:20s} {alg:34s} {len(o):6d} {math.sqrt(np.mean(np.square(r))):7.2f} {np.median(r):7.2f}")
    for r, key, v, u in sorted(listed, key=lambda x: -abs(math.log(x[0])) if 0 < x[0] < math.inf else -1e9)[:a.worst]:
        print(f"  ratio {r:.2f} {' / '.join(key)}: values {v} SEs {u}")
    if allo:
        rr = np.array(allo) / np.array(allp)
        print(f"pooled over {len(allo)} scores: observed / predicted SE = {math.sqrt(np.mean(rr)):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
