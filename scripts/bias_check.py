"""Does the jackknife bias correction move a score toward the value at more samples?

    python scripts/bias_check.py [--factor 4] [--geometry same|own] [--seeds N] [--cache DIR] [--scene TASK=SCENE ...]

Renders the scenes at draft quality and at ``factor`` times draft's samples (same resolution),
scores every job of the tasks on them, and for every headline-metric cell (job, algorithm) whose
two values differ beyond float32 rounding counts whether the bias-corrected 1x value
``v - bias`` is closer to the ``factor``x value than the uncorrected one.  Prints the fraction
and the cells.

``--geometry same`` (default): the ``factor``x ground truth gets the 1x one's geometry (albedo,
normals, depth, coverage, pure mask, object ids), so the two differ in their light transport
only, which is what the jackknife bias estimates (its replicates share the geometry,
docs/science.md §8).  ``own``: each keeps its own; the difference then also holds the
geometry's footprint sampling at 1x against ``factor``x samples, a bias that no replicate sees.

``--seeds N`` (default 1) renders both at render seeds ``0..N-1`` and also compares the means over
the seeds: ``mean(v - bias)`` against ``mean(v)`` as estimates of the ``factor``x mean, which
separates the bias estimate's own noise from a single draw's, and counts separately the cells
whose mean 1x and ``factor``x values differ beyond 2 standard errors of the means (a bias the
seeds resolve).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--factor", type=float, default=4.0)
    ap.add_argument("--geometry", choices=["same", "own"], default="same",
                    help="the factor-x ground truth with the 1x geometry (same) or its own (own)")
    ap.add_argument("--seeds", type=int, default=1, help="render seeds 0..N-1 (default 1)")
    ap.add_argument("--cache", default=None)
    ap.add_argument("--scene", action="append", default=None, metavar="TASK=SCENE")
    a = ap.parse_args(argv)
    pairs = [s.split("=", 1) for s in (a.scene or ["photometric_stereo=ps_groove[albedo=0.9]",
                                                   "photometric_stereo=ps_cup[albedo=0.9]", "sfs=sfs_vase",
                                                   "sfs=sfs_sphere"])]
    from pbrbench import quality as Q
    from pbrbench.bench.plan import load_tasks
    from pbrbench.bench.run import execute_job
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.registry import builtin_registry
    from pbrbench.render.cache import RenderCache
    from pbrbench.settings import Settings

    draft = Q.PRESETS["draft"]

    @dataclasses.dataclass(frozen=True)
    class Times(Q.Quality):
        """``factor`` times the samples draft gives each pass (draft's floors, 2 per sample group,
        put most draft passes at 8 spp; scaling ``spp_scale`` instead gave them 12, 1.5x)."""
        factor: float = 1.0

        def spp(self, spp: int, groups: int | None = None) -> int:
            return int(round(self.factor * draft.spp(spp, groups)))

        def render_key(self) -> dict:
            return {**super().render_key(), "spp_factor_of_draft": self.factor}

    more = Times(**{**{f.name: getattr(draft, f.name) for f in dataclasses.fields(draft)},
                    "name": f"draft{a.factor:g}x", "factor": float(a.factor),
                    "description": f"draft resolution, {a.factor:g}x draft's samples (scripts/bias_check.py)"})
    Q.PRESETS[more.name] = more      # the render layer looks profiles up by name
    from pbrbench.render.groundtruth import AOV_REPLICATED, JK

    class SameGeometry(GroundTruthSource):
        """The ground truths of ``quality`` with the geometry of ``base``'s (same resolution)."""

        def __init__(self, quality, base, **kw):
            super().__init__(quality, **kw)
            self.base = base

        def load(self, spec):
            gt = super().load(spec)
            g1 = self.base.load(spec)
            for name in list(gt.arrays):
                if name.split(JK)[0] in AOV_REPLICATED or name == "object_id":
                    gt.arrays[name] = g1.arrays[name]
            return gt

    tasks = load_tasks(sorted({t for t, _ in pairs}))
    reg = builtin_registry(tasks)
    if a.seeds < 1:
        print("bias_check.py: --seeds must be at least 1", file=sys.stderr)
        return 1
    vals = {}          # (job key, algorithm) -> {profile name: score} at render seed 0
    by_seed = {}       # (job key, algorithm) -> {profile name: [score per render seed]}
    cache = RenderCache(a.cache or Settings.from_env().cache)
    for seed in range(a.seeds):
        base = GroundTruthSource(draft, cache=cache, render_seed=seed)
        for q in (draft, more):
            src = base if q is draft else (SameGeometry(q, base, cache=cache, render_seed=seed)
                                           if a.geometry == "same" else GroundTruthSource(q, cache=cache, render_seed=seed))
            for tname, scene in pairs:
                task = tasks[tname]
                for job in [j for j in task.jobs(draft) if j.scene.split(":")[0] == scene and j.param("plot") is None]:
                    res = execute_job(task, job, src.specs([job.scene, *job.extra_scenes]), src, 0, "j",
                                      reg.for_task(tname), q)
                    if res["error"]:
                        print(res["error"], file=sys.stderr)
                        return 1
                    for s in res["scores"]:
                        if s["metric"] == task.headline_metric:
                            key = (job.key, s["algorithm"])
                            if seed == 0:
                                vals.setdefault(key, {})[q.name] = s
                            by_seed.setdefault(key, {}).setdefault(q.name, []).append(s)
            print(f"render seed {seed}: {q.name} done", file=sys.stderr, flush=True)
    better, n, jobs = 0, 0, set()
    subsets = {"stable (replicates not bimodal)": [0, 0], "marked (|bias| > SE, stable)": [0, 0],
               "1x and 4x differ beyond 2 SE (stable)": [0, 0]}
    for (key, alg), d in sorted(vals.items()):
        if len(d) < 2:
            continue
        s1, s4 = d[draft.name], d[more.name]
        v1, b1, v4 = s1["value"], s1.get("bias"), s4["value"]
        if b1 is None or b1 != b1 or abs(v1 - v4) <= 1e-5 + 1e-4 * abs(v4):
            continue
        n += 1
        jobs.add(key)
        ok = abs(v1 - b1 - v4) < abs(v1 - v4)
        better += ok
        stable = not s1.get("unstable")
        se1 = s1.get("uncertainty") or float("inf")
        marked = stable and abs(b1) > se1
        differ = stable and abs(v1 - v4) > 2 * se1
        for name, inside in zip(subsets, (stable, marked, differ), strict=True):
            if inside:
                subsets[name][0] += ok
                subsets[name][1] += 1
        print(f"{'closer' if ok else 'farther'}  {alg:30s} 1x {v1:9.4g}  bias {b1:+9.3g}  corrected {v1 - b1:9.4g}  "
              f"{a.factor:g}x {v4:9.4g}   {key[:70]}")
    print(f"bias-corrected 1x closer to {a.factor:g}x in {better} of {n} cells ({100 * better / max(n, 1):.0f} %), "
          f"{len(jobs)} jobs")
    for name, (k, m) in subsets.items():
        print(f"  {name}: {k} of {m} ({100 * k / max(m, 1):.0f} %)")
    if a.seeds > 1:
        print(seed_means(by_seed, draft.name, more.name, a.factor))
    return 0


def seed_means(by_seed: dict, one: str, more: str, factor: float) -> str:
    """Per-draw and seed-mean fractions of cells whose bias-corrected 1x value is closer to the
    ``factor``x one, and the same among the cells whose seed means differ beyond 2 SEM."""
    import numpy as np

    draws = [0, 0]
    means = [0, 0]
    resolved = [0, 0]
    for d in by_seed.values():
        s1, s4 = d.get(one, []), d.get(more, [])
        if len(s1) != len(s4) or len(s1) < 2 or any(s.get("bias") is None or s["bias"] != s["bias"] for s in s1):
            continue
        v1 = np.array([s["value"] for s in s1])
        b1 = np.array([s["bias"] for s in s1])
        v4 = np.array([s["value"] for s in s4])
        if np.ptp(np.r_[v1, v4]) <= 1e-5 + 1e-4 * abs(v4).max():
            continue
        for x, b, y in zip(v1, b1, v4, strict=True):
            draws[0] += abs(x - b - y) < abs(x - y)
            draws[1] += 1
        ok = abs(v1.mean() - b1.mean() - v4.mean()) < abs(v1.mean() - v4.mean())
        means[0] += ok
        means[1] += 1
        sem = np.sqrt(v1.var(ddof=1) / len(v1) + v4.var(ddof=1) / len(v4))
        if abs(v1.mean() - v4.mean()) > 2 * sem:
            resolved[0] += ok
            resolved[1] += 1
    pct = lambda k, m: f"{k} of {m} ({100 * k / max(m, 1):.0f} %)"  # noqa: E731
    return (f"over {len(next(iter(by_seed.values()))[one])} render seeds: single draws {pct(*draws)} closer to "
            f"{factor:g}x; seed means {pct(*means)}; cells whose seed means differ beyond 2 SEM {pct(*resolved)}")


if __name__ == "__main__":
    sys.exit(main())
