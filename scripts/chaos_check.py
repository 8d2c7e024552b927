"""Is a score chaotic in its input?  Score every job of one scene on N render seeds, on the full
ground truth, on its G delete-one-group replicates and once more on the full ground truth moved
by 1e-3 of one group's deviation (a perturbation a thousand times below the render noise), and
compare each algorithm's spread over the seeds with two standard errors:

    python scripts/chaos_check.py [--task sfs] [--scene sfs_vase] [--seeds 8] [--threshold 0.05]

``jk``: the delete-one-group jackknife of one render (what the runs report).  ``draws``: where the
perturbed score moved by more than ``threshold`` jackknife SEs beyond its first-order change
``eps (v_(0) - v)`` (an output that depends on the last bit of its input: the replicates are then
independent draws, not a jackknife series), the variance pooled from ``(v_eps - v)^2 / 2`` and the
replicates' sample variance scaled to the full sample count by ``(G - 1) / G``; else the jackknife.
``draws|conv0``: the same, only for algorithms whose own run reports ``converged = 0``.  Each
column is ``sqrt(mean(observed^2 / predicted^2))`` over the algorithm's scores (1 is exact).  Jobs
with injected camera noise are left out (their seed part is not modelled here).  A measurement
script for the estimator's threshold and gate: the runs apply the gated rule themselves
(:func:`pbrbench.uncertainty.chaotic`, :func:`pbrbench.uncertainty.draws`), and
``scripts/seed_calibration.py`` measures the standard errors they report.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from collections import defaultdict

import numpy as np

from pbrbench.uncertainty import PERTURBATION as EPS  # the runs' perturbation (1e-3)
from pbrbench.uncertainty import chaotic, draws, jackknife


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="sfs")
    ap.add_argument("--scene", default="sfs_vase")
    ap.add_argument("--quality", default="draft")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--threshold", type=float, default=0.05)
    ap.add_argument("--cache", default=None)
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")

    from pbrbench.bench.plan import load_tasks
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.quality import get_quality
    from pbrbench.registry import builtin_registry
    from pbrbench.render.cache import RenderCache
    from pbrbench.settings import Settings

    q = get_quality(a.quality)
    tasks = load_tasks([a.task])
    task = tasks[a.task]
    algs = list(builtin_registry(tasks).for_task(a.task))
    cache = RenderCache(a.cache or Settings.from_env().cache)

    def values(gts, job, seed):
        out = task.run_job(job, gts, seed=seed, algorithms=algs, quality=q).scores
        return {(d["algorithm"], d["metric"]): d["value"] for d in (s.as_dict() if hasattr(s, "as_dict") else s for s in out)}

    per = defaultdict(list)
    G = 0
    for seed in range(a.seeds):
        src = GroundTruthSource(q, cache=cache, render_seed=seed)
        jobs = [j for j in task.jobs(q) if j.scene.split(":")[0] == a.scene and j.param("plot") is None
                and "noise" not in j.condition]
        if not jobs:
            print(f"no job of {a.task} on {a.scene} at {q.name} without injected noise", file=sys.stderr)
            return 1
        for job in jobs:
            specs = src.specs([job.scene, *job.extra_scenes])
            gts = {n: src.load(specs[n]) for n in (job.scene, *job.extra_scenes)}
            G = min(g.groups for g in gts.values())
            full = values(gts, job, seed)
            reps = [values({n: g.replicate(i) for n, g in gts.items()}, job, seed) for i in range(G)]
            pert = values({n: g.perturbed(EPS) for n, g in gts.items()}, job, seed)
            for (alg, metric), v in full.items():
                if metric in ("failed", "converged"):
                    continue
                per[(job.key, alg, metric)].append(
                    (v, np.array([r.get((alg, metric), np.nan) for r in reps]), pert.get((alg, metric), np.nan),
                     full.get((alg, "converged"))))
        print(f"seed {seed + 1}/{a.seeds} done", file=sys.stderr, flush=True)

    cols = ("jk", "draws", "draws|conv0")
    ratios = defaultdict(lambda: defaultdict(list))
    for (_job, alg, _m), rows in per.items():
        v = np.array([x[0] for x in rows])
        if len(rows) < a.seeds or not np.all(np.isfinite(v)):
            continue
        pred = defaultdict(list)
        n_chaotic = 0
        for v0, r, p, conv in rows:
            se2 = jackknife(v0, list(r))[0] ** 2
            flag = bool(chaotic(v0, list(r), p, threshold=a.threshold))
            var = draws(v0, list(r), p)[0] ** 2 if flag else se2
            n_chaotic += flag
            pred["jk"].append(se2)
            pred["draws"].append(var)
            pred["draws|conv0"].append(var if conv == 0.0 else se2)
        obs = float(np.var(v, ddof=1))
        floor = (1e-5 + 1e-4 * float(np.abs(v).mean())) ** 2
        if obs <= floor and np.mean(pred["jk"]) <= floor:
            continue
        for c in cols:
            ratios[alg][c].append(obs / np.mean(pred[c]) if np.mean(pred[c]) > 0 else math.inf)
        ratios[alg]["chaotic"].append(n_chaotic)
    print(f"{'algorithm':38s} {'scores':>6s} " + " ".join(f"{c:>11s}" for c in cols) + "  chaotic renders")
    for alg, d in sorted(ratios.items()):
        print(f"{alg:38s} {len(d['jk']):6d} " + " ".join(f"{math.sqrt(np.mean(d[c])):11.2f}" for c in cols)
              + f"  {np.mean(d['chaotic']):.1f} of {a.seeds}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
