"""The standard error, degrees of freedom and Monte Carlo bias of every score: replicate scores
from the delete-one-group ground truths and, where the inputs depend on the seed, a second seed.

Every rendered pass of a ground truth is the mean of ``G`` independent sample groups
(:attr:`pbrbench.quality.Quality.groups`); :meth:`pbrbench.render.groundtruth.GroundTruth.replicate`
rebuilds the ground truth of every group but ``i``.  Scoring a job on each of those, with the same
seed, gives ``G`` replicate values ``v_(i)`` of each metric, and the delete-one-group jackknife
(:mod:`pbrbench.uncertainty`) gives the score's Monte Carlo standard error on ``G - 1`` degrees
of freedom and its render-noise bias from the same renders.

Where the job's inputs also depend on the seed (injected camera noise, random pixel sampling:
:meth:`pbrbench.tasks.base.Task.seed_dependent`), the job is scored :data:`NOISE_SEEDS` more times
on the full ground truth with other seeds, ``v_{n,k}``, and the score is the mean of the
:data:`NOISE_SEEDS` + 1 draws (the expected score under the injected noise, not one draw of it;
:func:`pbrbench.uncertainty.mean_over_seeds`; ``noise_mean`` True): the replicates move with it,
and the variance of that mean (the draws' sample variance over their number, :data:`NOISE_SEEDS`
degrees of freedom) is added.  The status metrics (``failed``, ``converged``) stay the own
seed's; the job's figures show the own seed's draw.

Noise scales measured over independent render seeds (:data:`SCALES_FILE`, written by
``scripts/noise_scales.py``) replace the replicates of the algorithms they cover: where every
score of an algorithm on a job has an entry for its task, scene, condition, noise hash (the scene's
content hash without its render seed, :meth:`pbrbench.scene.spec.SceneSpec.noise_hash`: a spread
over render seeds holds at any seed), algorithm version and quality (and the job's inputs do not
depend on the seed), that algorithm is not run
on the replicates, and each score's standard error is the entry's standard deviation over the
seeds, on its degrees of freedom (seeds - 1); its bias is the entry's ``bias`` where it has one
(a draft entry: its mean over the seeds minus the standard entry's), else not estimated (NaN).  Used for the
inverse-rendering methods, each call of which is a series of Mitsuba renders; anything the
table does not name exactly (another version, scene content or quality) falls back to the
replicates.

An algorithm whose own run reports ``converged = 0`` (and every plugin) is scored once more, on
the full ground truth moved by :data:`pbrbench.uncertainty.PERTURBATION` toward the replicate
without group 0 (:meth:`pbrbench.render.groundtruth.GroundTruth.perturbed`; ``perturbed``): a
score that moves far beyond the first-order change is chaotic in its input, its replicates are
independent draws, and its standard error comes from them as such, with no bias estimate
(:func:`pbrbench.uncertainty.chaotic`, :func:`pbrbench.uncertainty.draws`).

The replicate values are stored with the score (``replicates``, ``rep_noise``), so a difference
between two conditions rendered from the same ground truth (``global - local`` of one scene) gets
its own paired jackknife, which accounts for their correlation (:func:`pbrbench.uncertainty.paired`).
``tests/bench/test_uncertainty.py`` checks the estimator against the spread of the metric over
independently rendered seeds.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

from pbrbench.uncertainty import PERTURBATION, estimate, finite, mean_over_seeds, noise_values

SCALES_FILE = Path(__file__).with_name("noise_scales.json")

NOISE_SEED_OFFSET = 1_000_003     # other seed k (1, 2, ...) of a seed-dependent job: seed + k * NOISE_SEED_OFFSET
NOISE_SEEDS = 3                   # other seeds of a seed-dependent job: the seed's part of its SE on 3 dof


def noise_seeds(seed: int) -> list[int]:
    """The other seeds a seed-dependent job scored with ``seed`` is also scored with."""
    return [seed + k * NOISE_SEED_OFFSET for k in range(1, NOISE_SEEDS + 1)]


def score_key(s: dict) -> tuple:
    return (s["scene"], s["algorithm"], s["metric"])


def _values(scores) -> dict:
    out = {}
    for s in scores:
        if hasattr(s, "as_dict"):   # a Score: its fields read directly (as_dict copies every field, 3 % of a draft run's jobs)
            out[(s.scene, s.algorithm, s.metric)] = float(s.value)
        else:
            out[score_key(s)] = float(s["value"])
    return out


@functools.lru_cache(maxsize=4)
def noise_scales(path: str = str(SCALES_FILE)) -> dict:
    """``{(task, scene, condition, noise_hash, algorithm, algorithm_version, metric, quality): (sd,
    dof, bias)}`` from the scales file (empty when it is missing; ``bias`` NaN where the entry
    has none; an entry without a ``noise_hash`` names no scene, and one measured on another
    ground-truth format (another mask, other passes: ``gt_format``) is stale; both are left out)."""
    from pbrbench.render.groundtruth import GT_FORMAT

    try:
        with open(path) as f:
            entries = json.load(f).get("entries", [])
    except FileNotFoundError:
        return {}
    return {(e["task"], e["scene"], e["condition"], e["noise_hash"], e["algorithm"], e["algorithm_version"],
             e["metric"], e["quality"]): (float(e["sd"]), float(e["dof"]), float(e.get("bias", "nan")))
            for e in entries if e.get("noise_hash") and e.get("gt_format") == GT_FORMAT}


def _scale_key(d: dict, quality_name: str, noise_hashes: dict) -> tuple:
    h = noise_hashes.get(d["scene_hash"], d["scene_hash"])
    return (d["task"], d["scene"], d["condition"], h, d["algorithm"], d.get("algorithm_version", ""),
            d["metric"], quality_name)


def scaled_scores(full, quality, scales: dict | None = None, noise_hashes: dict | None = None) -> dict:
    """``{score key: (sd, dof[, bias])}`` of the scores in ``full`` whose algorithm has a noise scale for
    every one of its scores on the job (module docstring).  ``noise_hashes``: ``{scene hash: noise
    hash}`` of the job's scenes; a score whose scene hash it does not map is looked up by its
    scene hash."""
    noise_hashes = noise_hashes or {}
    scales = noise_scales() if scales is None else scales
    if not scales or full is None or isinstance(full, dict):
        return {}
    qn = getattr(quality, "name", str(quality))
    by_alg: dict = {}
    for s in full:
        d = s.as_dict() if hasattr(s, "as_dict") else s
        by_alg.setdefault(d["algorithm"], []).append((score_key(d), scales.get(_scale_key(d, qn, noise_hashes))))
    return {k: v for rows in by_alg.values() if all(v is not None for _, v in rows) for k, v in rows}


def replicate_scores(task, job, gts: dict, *, seed: int, algorithms, quality, full=None, scales=None,
                     noise_hashes: dict | None = None) -> dict[str, dict]:
    """``{"replicates": {key: [v_(0), ..., v_(G-1)]}, "perturbed": {key: v_eps}, "rep_noise": {key: [v_n1,
    ..., v_nK]}}`` for the job's scores (keys ``(scene, algorithm, metric)``); parts that cannot be
    computed (a ground truth without its sample groups, no algorithm to test for chaos, a job whose
    inputs do not depend on the seed) are absent.

    ``full``: the job's scores on the full ground truths, scored just before on ``gts`` (whose
    :attr:`~pbrbench.render.groundtruth.GroundTruth.reads` then name every array the job read): a
    replicate that changes none of those arrays is the same input, and its values are ``full``'s
    without scoring it again (a job on analytic or noise-free passes costs one scoring).
    ``noise_hashes``: as for :func:`scaled_scores`."""
    out: dict[str, dict] = {}
    algorithms = list(algorithms)
    seed_dependent = task.seed_dependent(job)
    scaled = {} if seed_dependent else scaled_scores(full, quality, scales, noise_hashes)
    if scaled:
        # the algorithms whose standard errors come from the scales are not run on the replicates
        done = {a for (_, a, _) in scaled}
        algorithms = [a for a in algorithms if a.name not in done]
        out["scales"] = scaled
    if full is not None and not isinstance(full, dict):
        full = _values(full)

    def _drop_failed(vals):
        # a plugin that failed (timed out, crashed, raised) is not called again for this job: its
        # failure has no standard error, and a hung plugin would cost its time limit again
        bad = {a for (_, a, m), v in vals.items() if m == "failed" and v == 1.0}
        algorithms[:] = [a for a in algorithms if not (a.kind == "plugin" and a.name in bad)]

    if full is not None:
        _drop_failed(full)
    groups = {getattr(g, "groups", 0) for g in gts.values()}
    if all(getattr(g, "has_replicates", False) for g in gts.values()) and len(groups) == 1:
        (G,) = groups
        reps: dict = {}
        for i in range(G):
            if full is not None and not any(g.varies(i) for g in gts.values()):
                vals = full          # the job read nothing this replicate changes: the same inputs, the same scores
            else:
                loo = {n: g.replicate(i) for n, g in gts.items()}
                vals = _values(task.run_job(job, loo, seed=seed, algorithms=algorithms, quality=quality).scores)
                _drop_failed(vals)
            for k, v in vals.items():
                reps.setdefault(k, [float("nan")] * G)[i] = v
        out["replicates"] = reps
    if seed_dependent:
        noise: dict = {}
        seeds = noise_seeds(seed)
        for k, sk in enumerate(seeds):
            vals = _values(task.run_job(job, gts, seed=sk, algorithms=algorithms, quality=quality).scores)
            _drop_failed(vals)
            for key, v in vals.items():
                noise.setdefault(key, [float("nan")] * len(seeds))[k] = v
        out["rep_noise"] = noise
    chaos = _chaos_candidates(task, job, full, algorithms) if "replicates" in out else []
    if chaos and any(g.varies(0) for g in gts.values()):
        # last: a plugin without predictions for this input set (an export's replicates/perturbed
        # left out) is then not dropped from the other seeds' scoring
        moved = {n: g.perturbed(PERTURBATION) for n, g in gts.items()}
        vals = _values(task.run_job(job, moved, seed=seed, algorithms=chaos, quality=quality).scores)
        names = {a.name for a in chaos}
        out["perturbed"] = {k: v for k, v in vals.items() if k[1] in names}
    return out


def _chaos_candidates(task, job, full, algorithms) -> list:
    """The algorithms of a job rescored on the perturbed ground truth (the chaos test,
    :func:`pbrbench.uncertainty.chaotic`): those whose own run reports ``converged = 0`` (an
    iteration stopped before its fixed point may jump with the last bits of its input; a converged
    one is smooth in it) and plugins (an outside program's convergence is not known), where the
    task scores that input set (an evaluated export made before it was written: not)."""
    if full is None or not getattr(task, "scores_perturbed", lambda job: True)(job):
        return []
    unconverged = {a for (_, a, m), v in full.items() if m == "converged" and v == 0.0}
    return [a for a in algorithms if a.name in unconverged or a.kind == "plugin"]


def attach(scores: list[dict], reps: dict[str, dict]) -> list[dict]:
    """The score dicts with ``replicates``, ``rep_noise``, ``perturbed``, ``uncertainty``, ``dof``,
    ``bias``, ``unstable`` and ``chaotic`` filled in (and ``noise_mean``: the value is the mean
    over the seeds)."""
    # the metrics package imports SciPy's image modules: not at the import of this module
    from pbrbench.metrics.table import STATUS

    for s in scores:
        k = score_key(s)
        scale = reps.get("scales", {}).get(k)
        if scale is not None:     # the standard error over independent render seeds (module docstring)
            s.update(replicates=None, rep_noise=None, uncertainty=scale[0], dof=scale[1],
                     bias=float(scale[2]) if len(scale) > 2 else float("nan"), unstable=None, perturbed=None,
                     chaotic=None)
            continue
        r = reps.get("replicates", {}).get(k)
        s["replicates"] = list(r) if r is not None else None
        n = reps.get("rep_noise", {}).get(k)
        s["rep_noise"] = list(n) if n is not None else None
        p = reps.get("perturbed", {}).get(k) if s["metric"] not in STATUS else None
        s["noise_mean"] = bool(noise_values(s["rep_noise"])) and s["metric"] not in STATUS and finite(s["value"])
        if s["noise_mean"]:   # a seed-dependent score: the mean over its seeds (module docstring)
            v0 = s["value"]
            s["value"], s["replicates"] = mean_over_seeds(s["value"], s["replicates"], s["rep_noise"])
            p = None if p is None else p + (s["value"] - v0)    # moved with the replicates
        s["perturbed"] = p if finite(p) else None
        s.update(estimate(s["value"], s["replicates"], s["rep_noise"], mean=s["noise_mean"], perturbed=s["perturbed"]))
    # a flipped discrete choice is the pipeline's, not one metric's: every metric of that
    # algorithm's output on the job is unstable when one of them is
    flipped = {(s["scene"], s["algorithm"]) for s in scores if s.get("unstable")}
    for s in scores:
        if (s["scene"], s["algorithm"]) in flipped:
            s["unstable"] = True
    return scores
