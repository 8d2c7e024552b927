"""The standard errors of the scores: the delete-one-group jackknife on synthetic data with a
known answer (SE per cell, its degrees of freedom, the Monte Carlo bias), its plumbing through a
run, and a check against the spread over independent renders."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from pbrbench.bench.uncertainty import NOISE_SEEDS, attach, replicate_scores
from pbrbench.quality import get_quality
from pbrbench.registry import Algorithm, builtin_registry
from pbrbench.render.groundtruth import JK, GroundTruth, jackknife_sd, loo_deviations
from pbrbench.tasks.base import Job, JobResult, Task
from pbrbench.tasks.common.scoring import ScoreBook
from pbrbench.uncertainty import estimate, jackknife, paired, standard_error, unstable
from tests.fakes import ps_gt, ps_job

G = 4


def noisy_gt(truth, sigma, rng, groups=G):
    """A ground truth whose 'radiance' is the mean of ``groups`` sample groups whose mean has noise
    ``sigma`` ('albedo' holds the exact image, which replicates leave alone)."""
    gs = [truth + sigma * math.sqrt(groups) * rng.standard_normal(truth.shape) for _ in range(groups)]
    m, jk = loo_deviations(gs)
    arr = {"radiance": m.astype(np.float32), "direct": m.astype(np.float32), "albedo": truth.astype(np.float32)}
    for i in range(groups):
        arr[f"radiance{JK}{i}"] = arr[f"direct{JK}{i}"] = jk[i].astype(np.float32)
    return GroundTruth(arr, {"scene_hash": "x"})


class ErrorTask(Task):
    """Scores how far the rendered image is from a model of it that is ``offset`` off (a
    systematic error, as every real algorithm has): RMS, mean absolute and mean squared error,
    all biased upward by the noise.  ``offset = 0`` scores the noise alone."""

    offset = 0.1

    name = "err"
    conditions = ("global",)
    headline_metric = "height_rmse"

    def builtin_algorithms(self):
        return [Algorithm("identity", self.name, lambda img: img)]

    def jobs(self, quality):
        return [Job(self.name, "s", "global")]

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        gt = gts[job.scene]
        book = ScoreBook(job, "x", algorithms)
        for alg in algorithms:
            d = alg(gt["radiance"].astype(float)) - (1 + self.offset) * gt["albedo"]
            book.add(alg.name, {"height_rmse": float(np.sqrt(np.mean(d * d))), "height_mae": float(np.mean(np.abs(d))),
                                "height_rmse_rel": float(np.mean(d * d))}, 0.0)
        return JobResult(job, scores=book.scores)


def test_replicates_are_the_delete_one_group_means():
    rng = np.random.default_rng(0)
    truth = rng.uniform(0.2, 1.0, (8, 9, 3))
    groups = [truth + 0.01 * rng.standard_normal(truth.shape) for _ in range(G)]
    m, jk = loo_deviations(groups)
    arr = {"radiance": m.astype(np.float32), "direct": m.astype(np.float32), "indirect": np.zeros_like(m, np.float32)}
    for i in range(G):
        arr[f"radiance{JK}{i}"] = arr[f"direct{JK}{i}"] = jk[i].astype(np.float32)
    gt = GroundTruth(arr, {})
    assert gt.has_replicates and gt.groups == G
    # the jackknife sd of a mean is the groups' sample sd over sqrt(G)
    assert np.allclose(gt["radiance_sd"], np.std(groups, axis=0, ddof=1) / math.sqrt(G), atol=1e-6)
    assert np.allclose(jackknife_sd(jk), gt["radiance_sd"], atol=1e-6)
    for i in range(G):
        others = np.mean([g for j, g in enumerate(groups) if j != i], axis=0)
        assert np.allclose(gt.replicate(i)["radiance"], others, atol=1e-6)
        assert np.allclose(gt.replicate(i)["indirect"], 0, atol=1e-6)
    with pytest.raises(ValueError, match="group"):
        gt.replicate(G)


def test_two_groups_reduce_to_the_half_sample_estimate():
    # G = 2: the replicate deleting half a is half b, and SE = |a - b| / 2 on one degree of freedom
    se, bias, dof = jackknife(1.0, [0.8, 1.2])
    assert se == pytest.approx(0.2) and dof == 1 and bias == pytest.approx(0.0)


@pytest.mark.parametrize("offset", [0.1, 0.0])
def test_jackknife_standard_error_holds_per_cell_over_independent_renders(offset):
    """K = 400 independent 'renders': the predicted standard error (RMS over the renders) matches
    the observed SD of each metric, and the 95 % Student-t interval on G - 1 degrees of freedom
    covers the mean over renders 95 % of the time (a per-cell check, not only pooled).  A metric
    of the noise alone (offset 0: no linear term) is the jackknife's known conservative case
    (Efron & Stein 1981): its SE is too large, never too small."""
    rng = np.random.default_rng(1)
    truth = rng.uniform(0.2, 1.0, (16, 16, 3))
    task = ErrorTask()
    task.offset = offset
    algs = builtin_registry({task.name: task}).for_task(task.name)
    job = task.jobs(None)[0]
    vals, ses, dofs = {}, {}, {}
    for _ in range(400):
        gts = {"s": noisy_gt(truth, 0.05, rng)}
        res = task.run_job(job, gts, algorithms=algs)
        reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"))
        assert set(reps) == {"replicates"}
        for sc in attach([s.as_dict() for s in res.scores], reps):
            vals.setdefault(sc["metric"], []).append(sc["value"])
            ses.setdefault(sc["metric"], []).append(sc["uncertainty"])
            dofs.setdefault(sc["metric"], []).append(sc["dof"])
    for m in vals:
        v, u = np.array(vals[m]), np.array(ses[m])
        ratio = np.std(v, ddof=1) / math.sqrt(np.mean(u ** 2))
        assert set(dofs[m]) == {G - 1}
        t = stats.t.ppf(0.975, G - 1)
        cover = np.mean(np.abs(v - v.mean()) <= t * u)
        if offset:
            assert 0.85 < ratio < 1.15, (m, ratio)
            assert 0.91 <= cover <= 0.985, (m, cover)
        else:
            assert 0.6 < ratio < 1.05, (m, ratio)
            assert cover >= 0.93, (m, cover)


def test_jackknife_bias_correction_removes_the_noise_bias():
    """The mean squared error of a noisy image is biased by the noise variance; the jackknife's
    bias-corrected value is unbiased (its mean over renders is ~0, the uncorrected one ~sigma^2)."""
    rng = np.random.default_rng(2)
    truth = rng.uniform(0.2, 1.0, (16, 16, 3))
    task = ErrorTask()
    algs = builtin_registry({task.name: task}).for_task(task.name)
    job = task.jobs(None)[0]
    raw, corrected = [], []
    for _ in range(100):
        gts = {"s": noisy_gt(truth, 0.05, rng)}
        res = task.run_job(job, gts, algorithms=algs)
        reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"))
        (sc,) = [x for x in attach([s.as_dict() for s in res.scores], reps) if x["metric"] == "height_rmse_rel"]
        raw.append(sc["value"])
        corrected.append(sc["value"] - sc["bias"])
    exact = float(np.mean((0.1 * truth) ** 2))      # the score of a noise-free render
    assert np.mean(raw) - exact == pytest.approx(0.05 ** 2, rel=0.1)   # biased by the noise variance
    assert abs(np.mean(corrected) - exact) < 0.05 * (np.mean(raw) - exact)


def test_seed_dependent_jobs_add_the_noise_seed_part():
    assert standard_error(1.0, None, 1.0 + math.sqrt(2) * 0.3) == pytest.approx(0.3)   # one other seed (old rows)
    # K other seeds: the sample variance of the K + 1 values, on K degrees of freedom
    e = estimate(1.0, None, [1.2, 0.8, 1.4])
    assert e["uncertainty"] == pytest.approx(float(np.std([1.0, 1.2, 0.8, 1.4], ddof=1))) and e["dof"] == 3
    assert estimate(1.0, None, "[1.2, 0.8, 1.4]")["uncertainty"] == e["uncertainty"]   # as stored (JSON)
    assert estimate(1.0, None, [1.2, float("nan"), 0.8])["dof"] == 2                    # a failed seed is left out
    e = estimate(1.0, [1.1, 0.9, 1.0, 1.0], 1.0 + math.sqrt(2) * 0.3)
    assert 1 <= e["dof"] <= 4 and e["uncertainty"] > 0.3
    from pbrbench.tasks.photometric_stereo import TASK

    assert TASK.seed_dependent(ps_job("local+noise0.01")) and not TASK.seed_dependent(ps_job("local"))
    gt, vec = ps_gt()
    algs = builtin_registry({TASK.name: TASK}).for_task(TASK.name)
    job = ps_job("local+noise0.01", lights=vec)
    reps = replicate_scores(TASK, job, {"s": gt}, seed=0, algorithms=algs, quality=get_quality("draft"))
    assert set(reps) == {"rep_noise"}  # a synthetic ground truth has no sample groups; the noise seed part is there
    res = TASK.run_job(job, {"s": gt}, seed=0, algorithms=algs, quality=get_quality("draft"))
    own = {(s.algorithm, s.metric): s.value for s in res.scores}
    sc = {(s["algorithm"], s["metric"]): s for s in attach([s.as_dict() for s in res.scores], reps)}
    w = sc[("woodham1980", "normal_mean_deg")]
    draws = [own[("woodham1980", "normal_mean_deg")], *w["rep_noise"]]
    assert len(w["rep_noise"]) == NOISE_SEEDS and len(set(draws)) == NOISE_SEEDS + 1
    # the score is the mean over the seeds, its seed part the standard error of that mean
    assert w["noise_mean"] and w["value"] == pytest.approx(np.mean(draws))
    assert w["uncertainty"] == pytest.approx(np.std(draws, ddof=1) / math.sqrt(NOISE_SEEDS + 1))
    assert 0 < w["uncertainty"] < 0.2 * w["value"] and w["dof"] == NOISE_SEEDS


def test_a_seed_dependent_score_is_the_mean_over_its_seeds():
    from pbrbench.uncertainty import mean_over_seeds, noise_part

    draws = [1.0, 1.2, 0.8, 1.4]                     # the own seed's draw first
    m, reps = mean_over_seeds(draws[0], [0.9, 1.1, 1.05, 0.95], draws[1:])
    assert m == pytest.approx(1.1) and reps == pytest.approx([1.0, 1.2, 1.15, 1.05])
    var, dof = noise_part(m, draws[1:], mean=True)   # the own draw is recovered from the mean
    assert var == pytest.approx(np.var(draws, ddof=1) / 4) and dof == 3
    e1 = estimate(draws[0], [0.9, 1.1, 1.05, 0.95], draws[1:])
    e2 = estimate(m, reps, draws[1:], mean=True)
    assert e2["bias"] == pytest.approx(e1["bias"])   # the replicates moved with the value: the same bias
    assert e2["uncertainty"] < e1["uncertainty"]
    # the seed's part of a difference of two means, paired: a common shift of the draws cancels
    x = {"value": 2.05, "replicates": [1.0] * 4, "rep_noise": [2.5, 1.5, 2.2], "scene_hash": "h", "noise_mean": True}
    ref = {"value": 1.05, "replicates": [1.0] * 4, "rep_noise": [1.5, 0.5, 1.2], "scene_hash": "h", "noise_mean": True}
    assert paired(x, ref)[0] == pytest.approx(0.0, abs=1e-12)
    # without other seeds nothing changes
    assert mean_over_seeds(1.0, [1.0, 1.1], None) == (1.0, [1.0, 1.1])
    # the status metrics stay the own seed's draw
    key = ("s", "a", "failed")
    (f,) = attach([{"scene": "s", "algorithm": "a", "metric": "failed", "value": 1.0}], {"rep_noise": {key: [0.0, 0.0, 0.0]}})
    assert f["value"] == 1.0 and not f["noise_mean"]


def test_the_noise_seed_part_of_a_difference_is_paired():
    """Two seed-dependent scores of one ground truth scored with the same seeds: the seed's part of
    their difference comes from the paired differences, so a common seed effect cancels; a score
    whose other side does not depend on the seed keeps its own part."""
    reps = [1.0, 1.0, 1.0, 1.0]
    x = {"value": 2.0, "replicates": reps, "rep_noise": [2.5, 1.5, 2.2], "scene_hash": "h"}
    ref = {"value": 1.0, "replicates": reps, "rep_noise": [1.5, 0.5, 1.2], "scene_hash": "h"}   # the same shifts
    se, dof = paired(x, ref)
    assert se == pytest.approx(0.0, abs=1e-12)
    plain = {"value": 1.0, "replicates": reps, "rep_noise": None, "scene_hash": "h"}
    se, dof = paired(x, plain)
    assert se == pytest.approx(float(np.std([2.0, 2.5, 1.5, 2.2], ddof=1))) and dof == 3


def test_a_flipped_discrete_choice_is_detected_and_smooth_scores_are_not():
    assert unstable([5.78, 3.10, 3.12, 3.11]) is True     # one group flips the pipeline's choice
    assert unstable([0.354, 0.2912, 0.2908, 0.3538]) is True   # two groups against two
    assert unstable([1.0, 1.01, 1.02, 1.03]) is False
    assert unstable([0.9974, 0.9974, 0.9961, 0.9974]) is False  # one pixel of a counting metric
    assert unstable([1.0, 2.0]) is None                    # two replicates: no test
    # eight groups (render.min_groups): one replicate alone beyond the gap is one heavy-tailed
    # group (the image-as-reflectance baseline on a penumbra), two against six is a flip
    firefly = [0.02459, 0.02451, 0.02469, 0.02453, 0.02458, 0.02290, 0.02452, 0.02464]
    assert unstable(firefly) is False
    assert unstable([1.877e-5, 1.875e-5, 1.869e-5, 1.652e-5, 1.878e-5, 1.870e-5, 1.864e-5, 1.642e-5]) is True
    # Gaussian replicates are called bimodal about once in 1000
    rng = np.random.default_rng(5)
    flags = [unstable(list(10 + rng.standard_normal(G))) for _ in range(20000)]
    assert np.mean(flags) < 0.003


def test_the_gap_criticals_are_the_99_9th_percentiles_of_gaussian_replicates():
    """GAP_CRITICAL[G] re-measured: of 200,000 draws of G Gaussian replicates, the largest gap
    between the sorted values over their range exceeds it in 0.1 % of the draws (200 expected;
    a binomial SD of 14, so 130-270 holds at 5 SD; the 99th percentile would give 2,000)."""
    from pbrbench.uncertainty import GAP_CRITICAL

    rng = np.random.default_rng(2024)
    n = 200_000
    for G, crit in GAP_CRITICAL.items():
        v = np.sort(rng.standard_normal((n, G)), axis=1)
        stat = np.diff(v, axis=1).max(axis=1) / (v[:, -1] - v[:, 0])
        above = int(np.sum(stat > crit))
        assert 130 <= above <= 270, f"G = {G}: {above} of {n} above {crit} (expected 200)"


@pytest.mark.render
@pytest.mark.slow
@pytest.mark.longest   # scheduled first (tests/conftest.py)
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
    ratios, keys = [], []
    for key, vs in per.items():
        v = np.array([x for x, _ in vs])
        u = np.array([e for _, e in vs])
        assert np.all(np.isfinite(u))
        # scores at the float32 precision of the images (the exact local solve: 1e-6 degrees) vary
        # by rounding, not Monte Carlo noise: the comparison floor (1e-6 absolute) covers them
        if abs(v.mean()) > 1e-4:
            ratios.append(np.var(v, ddof=1) / np.mean(u ** 2))
            keys.append(key)
    pooled = math.sqrt(float(np.mean(ratios)))
    print(f"observed / predicted standard error, pooled over {len(ratios)} scores: {pooled:.2f}")
    worst = sorted(zip(ratios, keys, strict=True), reverse=True)[:5]
    assert 0.5 < pooled < 2.0, (pooled, [(round(math.sqrt(r), 2), k) for r, k in worst])


def test_a_replicate_that_changes_nothing_the_job_read_is_not_scored_again():
    """A job that reads only arrays without Monte Carlo noise (here the exact 'albedo') gets its
    replicates from the full score without rescoring; one that reads a noisy pass is rescored."""
    rng = np.random.default_rng(4)
    truth = rng.uniform(0.2, 1.0, (8, 8, 3))
    calls = []

    class Reads(ErrorTask):
        array = "albedo"

        def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
            calls.append(gts["s"].meta.get("replicate"))
            book = ScoreBook(job, "x", algorithms)
            for alg in algorithms:
                book.add(alg.name, {"height_rmse": float(np.mean(gts["s"][self.array]))}, 0.0)
            return JobResult(job, scores=book.scores)

    for array, rescored in (("albedo", False), ("radiance", True)):
        task = Reads()
        task.array = array
        algs = builtin_registry({task.name: task}).for_task(task.name)
        gts = {"s": noisy_gt(truth, 0.05, rng)}
        job = task.jobs(None)[0]
        calls.clear()
        gts["s"].reads.clear()
        res = task.run_job(job, gts, algorithms=algs)
        reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"), full=res.scores)
        (v,) = reps["replicates"].values()
        assert calls == ([None, 0, 1, 2, 3] if rescored else [None])
        assert (len(set(v)) > 1) == rescored and (rescored or v == [res.scores[0].value] * G)


def test_a_flip_marks_every_metric_of_the_algorithm_on_the_job():
    scores = [{"scene": "s", "algorithm": "a", "metric": "x", "value": 5.78},
              {"scene": "s", "algorithm": "a", "metric": "y", "value": 1.0},
              {"scene": "s", "algorithm": "b", "metric": "x", "value": 1.0}]
    reps = {"replicates": {("s", "a", "x"): [3.10, 3.12, 3.11, 5.78], ("s", "a", "y"): [1.0, 1.01, 1.02, 1.0],
                           ("s", "b", "x"): [1.0, 1.01, 1.02, 1.0]}}
    out = {(d["algorithm"], d["metric"]): d["unstable"] for d in attach(scores, reps)}
    assert out == {("a", "x"): True, ("a", "y"): True, ("b", "x"): False}


class StoppedTask(ErrorTask):
    """Two algorithms on one noisy image: ``smooth`` (its mean, converged) and ``stopped`` (the
    same plus a jump that the last bits of its input decide, of a size proportional to the noise
    it sees, and ``converged = 0``: an iteration stopped before its fixed point)."""

    def builtin_algorithms(self):
        return [Algorithm("smooth", self.name, lambda img: img), Algorithm("stopped", self.name, lambda img: img)]

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        import hashlib

        gt = gts[job.scene]
        img, calls = gt["radiance"], self.calls
        book = ScoreBook(job, "x", algorithms)
        for alg in algorithms:
            calls.append((alg.name, gt.meta.get("replicate"), "perturbed" in gt.meta))
            v = float(np.mean(img))
            if alg.name == "stopped":
                h = int.from_bytes(hashlib.blake2b(img.tobytes(), digest_size=8).digest(), "little")
                v += 3 * float(np.std(img - gt["albedo"])) / math.sqrt(img.size) * np.random.default_rng(h).standard_normal()
            book.add(alg.name, {"height_rmse": v, "converged": float(alg.name == "smooth")}, 0.0)
        return JobResult(job, scores=book.scores)


def test_a_score_chaotic_in_its_input_gets_its_standard_error_from_independent_draws():
    """A score that jumps with the last bits of its input makes the replicates independent draws:
    the jackknife then states too large an error (by about sqrt(G - 1)).  The rescoring on the
    perturbed ground truth detects it, only for the algorithm that did not converge, and the SE
    from the draws holds over 400 independent renders; the smooth algorithm keeps its jackknife."""
    from pbrbench.uncertainty import bias_of

    rng = np.random.default_rng(7)
    truth = rng.uniform(0.2, 1.0, (12, 12, 3))
    task = StoppedTask()
    task.calls = []
    algs = builtin_registry({task.name: task}).for_task(task.name)
    job = task.jobs(None)[0]
    vals, ses, jks, flags = {}, {}, {}, {}
    for trial in range(400):
        gts = {"s": noisy_gt(truth, 0.05, rng)}
        task.calls.clear()
        res = task.run_job(job, gts, algorithms=algs)
        reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"), full=res.scores)
        if trial == 0:   # one call on the perturbed ground truth, of the unconverged algorithm only
            assert [c for c in task.calls if c[2]] == [("stopped", None, True)]
            assert set(reps["perturbed"]) == {("s", "stopped", "height_rmse"), ("s", "stopped", "converged")}
        for sc in attach([s.as_dict() for s in res.scores], reps):
            if sc["metric"] != "height_rmse":
                continue
            a = sc["algorithm"]
            vals.setdefault(a, []).append(sc["value"])
            ses.setdefault(a, []).append(sc["uncertainty"])
            jks.setdefault(a, []).append(jackknife(sc["value"], sc["replicates"])[0])
            flags.setdefault(a, []).append(sc["chaotic"])
            if sc["chaotic"]:
                assert sc["dof"] == G and math.isnan(sc["bias"]) and math.isnan(bias_of(sc))
    ratio = {a: np.std(vals[a], ddof=1) / math.sqrt(np.mean(np.square(ses[a]))) for a in vals}
    ratio_jk = {a: np.std(vals[a], ddof=1) / math.sqrt(np.mean(np.square(jks[a]))) for a in vals}
    assert np.mean([f is True for f in flags["stopped"]]) > 0.95
    assert all(f is None for f in flags["smooth"]) and ses["smooth"] == jks["smooth"]
    assert 0.85 < ratio["stopped"] < 1.15 and 0.85 < ratio["smooth"] < 1.15, ratio
    assert ratio_jk["stopped"] < 0.7, ratio_jk      # what the jackknife alone would state


def test_a_smooth_score_is_not_chaotic_under_the_perturbation():
    """The chaos test on a smooth, nonlinear score: the perturbed value moves by eps (v_(0) - v)
    to first order, so the estimate is the jackknife's, bias included; a jump makes it chaotic."""
    from pbrbench.uncertainty import PERTURBATION, chaotic

    v, reps = 2.0, [2.10, 1.95, 2.02, 1.97]
    smooth = v + PERTURBATION * (reps[0] - v) + 1e-7
    assert chaotic(v, reps, smooth) is False
    assert estimate(v, reps, perturbed=smooth) == {**estimate(v, reps), "chaotic": False}
    assert chaotic(v, reps, v + 0.05) is True and chaotic(v, reps, None) is None and chaotic(v, None, 2.5) is None
    e = estimate(v, reps, perturbed=v + 0.05)
    se, dof = math.sqrt((0.05 ** 2 / 2 + 0.75 * sum((r - np.mean(reps)) ** 2 for r in reps)) / 4), 4
    assert e["uncertainty"] == pytest.approx(se) and e["dof"] == dof and math.isnan(e["bias"])
    # a difference involving a chaotic score is not paired: its replicates are no jackknife series
    x = {"value": v, "replicates": reps, "scene_hash": "h", "uncertainty": e["uncertainty"], "dof": 4.0, "chaotic": True}
    ref = {"value": 1.0, "replicates": [1.01, 0.99, 1.0, 1.0], "scene_hash": "h", "uncertainty": 0.01, "dof": 3.0}
    assert paired(x, ref)[0] == pytest.approx(math.hypot(e["uncertainty"], 0.01))
