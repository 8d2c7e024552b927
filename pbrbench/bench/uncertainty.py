"""The standard error of every score: replicate scores from the two half-sample renders and,
where the inputs depend on the seed, from a second seed.

Every rendered pass of a ground truth is the mean of two independent half-sample renders ``a``
and ``b`` (:meth:`pbrbench.render.groundtruth.GroundTruth.replicate` rebuilds them).  Scoring a
job on each half, with the same seed, gives two replicate values ``v_a`` and ``v_b`` of each
metric.  Each half has twice the variance of the full-sample ground truth, so for a metric that is
smooth in the images (to first order)

    var(v_a - v_b) = 2 var_half = 4 var_full,   hence   SE_mc = |v_a - v_b| / 2

is an unbiased (one-degree-of-freedom) estimate of the Monte Carlo standard error of the score
``v`` computed on the full ground truth.  The difference of two halves rendered with one seed
each cancels any bias the noise gives the metric (both halves have the same), which a comparison
of ``v`` with one half would not.

Where the job's inputs also depend on the seed (injected camera noise, random pixel sampling:
:meth:`pbrbench.tasks.base.Task.seed_dependent`), the job is scored once more on the full ground
truth with another seed, ``v_n``, and ``SE_noise = |v - v_n| / sqrt(2)``.  The two parts are
independent: ``SE = sqrt(SE_mc^2 + SE_noise^2)``.

The replicate values are stored with the score (``rep_a``, ``rep_b``, ``rep_noise``), so a
difference between two conditions rendered from the same ground truth (``global - local`` of one
scene) gets its own paired standard error, which accounts for their correlation
(:func:`pbrbench.uncertainty.paired_se`).  ``tests/bench/test_uncertainty.py`` checks the estimator against the
spread of the metric over independently rendered seeds.
"""

from __future__ import annotations

from pbrbench.uncertainty import standard_error

NOISE_SEED_OFFSET = 1_000_003     # the second seed of seed-dependent jobs


def score_key(s: dict) -> tuple:
    return (s["scene"], s["algorithm"], s["metric"])


def _values(scores) -> dict:
    out = {}
    for s in scores:
        d = s.as_dict() if hasattr(s, "as_dict") else s
        out[score_key(d)] = float(d["value"])
    return out


def replicate_scores(task, job, gts: dict, *, seed: int, algorithms, quality) -> dict[str, dict]:
    """``{"rep_a": {key: value}, "rep_b": ..., "rep_noise": ...}`` for the job's scores (keys
    ``(scene, algorithm, metric)``); parts that cannot be computed (a ground truth without its
    half-sample deltas, a job whose inputs do not depend on the seed) are absent."""
    out: dict[str, dict] = {}
    if all(getattr(g, "has_replicates", False) for g in gts.values()):
        for half, name in ((0, "rep_a"), (1, "rep_b")):
            halves = {n: g.replicate(half) for n, g in gts.items()}
            res = task.run_job(job, halves, seed=seed, algorithms=algorithms, quality=quality)
            out[name] = _values(res.scores)
    if task.seed_dependent(job):
        res = task.run_job(job, gts, seed=seed + NOISE_SEED_OFFSET, algorithms=algorithms, quality=quality)
        out["rep_noise"] = _values(res.scores)
    return out


def attach(scores: list[dict], reps: dict[str, dict]) -> list[dict]:
    """The score dicts with ``rep_a``, ``rep_b``, ``rep_noise`` and ``uncertainty`` filled in."""
    for s in scores:
        k = score_key(s)
        for name in ("rep_a", "rep_b", "rep_noise"):
            s[name] = reps.get(name, {}).get(k)
        s["uncertainty"] = standard_error(s["value"], s["rep_a"], s["rep_b"], s["rep_noise"])
    return scores
