"""The standard errors of the scores: the half-sample estimator on synthetic data with a known
answer, its plumbing through a run, and a check against the spread over independent renders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pbrbench.bench.uncertainty import attach, replicate_scores
from pbrbench.registry import Algorithm, builtin_registry
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.render.quality import get_quality
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult, Task
from pbrbench.uncertainty import standard_error
from tests.fakes import ps_gt, ps_job


def noisy_gt(truth, sigma, rng):
    """A ground truth whose 'radiance' is the mean of two half renders with noise ``sigma`` each
    ('albedo' holds the exact image, which replicates leave alone)."""
    a = truth + sigma * rng.standard_normal(truth.shape)
    b = truth + sigma * rng.standard_normal(truth.shape)
    m = (0.5 * (a + b)).astype(np.float32)
    d = (0.5 * (a - b)).astype(np.float32)
    return GroundTruth({"radiance": m, "radiance_delta": d, "direct": m, "direct_delta": d,
                        "albedo": truth.astype(np.float32)}, {"scene_hash": "x"})


class ErrorTask(Task):
    """Scores how far the rendered image is from the exact one (RMS and mean absolute error)."""

    name = "err"
    conditions = ("global",)
    headline_metric = "height_rmse"

    def builtin_algorithms(self):
        return [Algorithm("identity", self.name, lambda img: img)]

    def jobs(self, quality):
        return [Job(self.name, "s", "global")]

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        gt = gts[job.scene]
        book = C.ScoreBook(job, "x", algorithms)
        for alg in algorithms:
            d = alg(gt["radiance"].astype(float)) - gt["albedo"]
            book.add(alg.name, {"height_rmse": float(np.sqrt(np.mean(d * d))), "height_mae": float(np.mean(np.abs(d)))}, 0.0)
        return JobResult(job, scores=book.scores)


def test_replicates_rebuild_the_halves_exactly():
    rng = np.random.default_rng(0)
    truth = rng.uniform(0.2, 1.0, (8, 9, 3))
    a = truth + 0.01 * rng.standard_normal(truth.shape)
    b = truth + 0.01 * rng.standard_normal(truth.shape)
    gt = GroundTruth({"radiance": ((a + b) / 2).astype(np.float32), "radiance_delta": ((a - b) / 2).astype(np.float32),
                      "direct": ((a + b) / 2).astype(np.float32), "direct_delta": ((a - b) / 2).astype(np.float32),
                      "indirect": np.zeros_like(a, np.float32)}, {})
    assert gt.has_replicates and np.allclose(gt["radiance_sd"], np.abs(a - b) / 2, atol=1e-6)
    assert np.allclose(gt.replicate(0)["radiance"], a, atol=1e-6) and np.allclose(gt.replicate(1)["radiance"], b, atol=1e-6)
    assert np.allclose(gt.replicate(0)["indirect"], 0, atol=1e-6)
    with pytest.raises(ValueError, match="half"):
        gt.replicate(2)


def test_half_sample_standard_error_matches_the_spread_over_independent_renders():
    """Two metrics of the render noise itself on K = 400 independent 'renders': the predicted
    standard error (RMS over the renders) matches the observed SD of the metric."""
    rng = np.random.default_rng(1)
    truth = rng.uniform(0.2, 1.0, (16, 16, 3))
    task = ErrorTask()
    algs = builtin_registry({task.name: task}).for_task(task.name)
    job = task.jobs(None)[0]
    vals, ses = {}, {}
    for _ in range(400):
        gts = {"s": noisy_gt(truth, 0.05, rng)}
        res = task.run_job(job, gts, algorithms=algs)
        reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"))
        assert set(reps) == {"rep_a", "rep_b"}
        for sc in attach([s.as_dict() for s in res.scores], reps):
            vals.setdefault(sc["metric"], []).append(sc["value"])
            ses.setdefault(sc["metric"], []).append(sc["uncertainty"])
    for m in vals:
        ratio = np.std(vals[m], ddof=1) / math.sqrt(np.mean(np.square(ses[m])))
        assert 0.85 < ratio < 1.15, (m, ratio)


def test_seed_dependent_jobs_add_the_noise_seed_part():
    assert standard_error(1.0, None, None, 1.0 + math.sqrt(2) * 0.3) == pytest.approx(0.3)
    from pbrbench.tasks.photometric_stereo import TASK

    assert TASK.seed_dependent(ps_job("local+noise0.01")) and not TASK.seed_dependent(ps_job("local"))
    gt, vec = ps_gt()
    algs = builtin_registry({TASK.name: TASK}).for_task(TASK.name)
    job = ps_job("local+noise0.01", lights=vec)
    reps = replicate_scores(TASK, job, {"s": gt}, seed=0, algorithms=algs, quality=get_quality("draft"))
    assert set(reps) == {"rep_noise"}  # a synthetic ground truth has no halves; the noise seed part is there
    res = TASK.run_job(job, {"s": gt}, seed=0, algorithms=algs, quality=get_quality("draft"))
    sc = {(s["algorithm"], s["metric"]): s for s in attach([s.as_dict() for s in res.scores], reps)}
    w = sc[("woodham1980", "normal_mean_deg")]
    assert 0 < w["uncertainty"] < 0.2 * w["value"]


@pytest.mark.render
@pytest.mark.slow
def test_predicted_standard_errors_match_the_spread_over_render_seeds(tmp_path):
    """ps_groove at albedo 0.9 rendered with 8 render seeds at draft quality: the standard errors a
    single render predicts for photometric stereo's scores agree with the scores' spread over the
    8 renders (pooled over metrics and the local / global conditions)."""
    from pbrbench.bench.run import execute_job
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import resolve
    from pbrbench.tasks.photometric_stereo import TASK

    (base,) = resolve(["ps_groove[albedo=0.9]"])
    q = get_quality("draft")
    algs = [a for a in builtin_registry({TASK.name: TASK}).for_task(TASK.name) if a.kind != "floor"]
    src = GroundTruthSource(q, cache=RenderCache(tmp_path / "cache"))
    per = {}
    for seed in range(8):
        spec = base.model_copy(update={"render": base.render.model_copy(update={"seed": seed})})
        for cond in ("local", "global"):
            from pbrbench.tasks.base import Job

            job = Job(TASK.name, spec.name, cond, TASK._params(spec))
            res = execute_job(TASK, job, {spec.name: spec}, src, 0, "j", algs, q)
            assert res["error"] is None, res["error"]
            for s in res["scores"]:
                if s["metric"] in ("normal_mean_deg", "albedo_rel_err", "height_rmse"):
                    per.setdefault((cond, s["algorithm"], s["metric"]), []).append((s["value"], s["uncertainty"]))
    ratios = []
    for vs in per.values():
        v = np.array([x for x, _ in vs])
        u = np.array([e for _, e in vs])
        assert np.all(np.isfinite(u))
        # scores at the float32 precision of the images (the exact local solve: 1e-6 degrees) vary
        # by rounding, not Monte Carlo noise: the comparison floor (1e-6 absolute) covers them
        if abs(v.mean()) > 1e-4:
            ratios.append(np.var(v, ddof=1) / np.mean(u ** 2))
    pooled = math.sqrt(float(np.mean(ratios)))
    print(f"observed / predicted standard error, pooled over {len(ratios)} scores: {pooled:.2f}")
    assert 0.5 < pooled < 2.0, pooled
