"""Noise scales over independent render seeds replace the replicates of the algorithms they cover
(``pbrbench.bench.uncertainty``: ``scaled_scores``, ``replicate_scores``, ``attach``)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pbrbench.bench.uncertainty import SCALES_FILE, attach, noise_scales, replicate_scores
from pbrbench.quality import get_quality
from pbrbench.registry import Algorithm, builtin_registry
from pbrbench.render.groundtruth import GT_FORMAT
from pbrbench.tasks.base import JobResult
from pbrbench.tasks.common.scoring import ScoreBook
from tests.bench.test_uncertainty import ErrorTask, noisy_gt

METRICS = ("height_rmse", "height_mae")


class TwoAlgorithms(ErrorTask):
    """Two algorithms on one noisy image; records which algorithms each call scored."""

    calls: list

    def builtin_algorithms(self):
        return [Algorithm("cheap", self.name, lambda img: img), Algorithm("costly", self.name, lambda img: 2 * img)]

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        self.calls.append(sorted(a.name for a in algorithms))
        gt = gts[job.scene]
        book = ScoreBook(job, "h", algorithms)
        for alg in algorithms:
            d = alg(gt["radiance"].astype(float)) - gt["albedo"]
            book.add(alg.name, {"height_rmse": float(np.sqrt(np.mean(d * d))), "height_mae": float(np.mean(np.abs(d)))},
                     0.0)
        return JobResult(job, scores=book.scores)


def _setup(seed_dependent=False):
    task = TwoAlgorithms()
    task.calls = []
    task.seed_dependent = lambda job: seed_dependent
    algs = builtin_registry({task.name: task}).for_task(task.name)
    gts = {"s": noisy_gt(np.random.default_rng(2).uniform(0.2, 1.0, (8, 8, 3)), 0.05, np.random.default_rng(3))}
    job = task.jobs(None)[0]
    res = task.run_job(job, gts, algorithms=algs)
    version = {a.name: a.full_version for a in algs}["costly"]
    return task, algs, gts, job, res, version


def _table(version, metrics=METRICS, scene_hash="h"):
    return {("err", "s", "global", scene_hash, "costly", version, m, "draft"): (0.25, 7.0) for m in metrics}


def test_a_covered_algorithm_is_not_rerun_and_takes_the_seed_scale():
    task, algs, gts, job, res, version = _setup()
    reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"), full=res.scores,
                            scales=_table(version))
    assert task.calls[1:] == [["cheap"]] * 4          # the four replicates score the other algorithm only
    scores = attach([s.as_dict() for s in res.scores], reps)
    for s in scores:
        if s["algorithm"] == "costly":
            assert (s["uncertainty"], s["dof"], s["replicates"]) == (0.25, 7.0, None) and math.isnan(s["bias"])
        else:
            assert s["dof"] == 3 and len(s["replicates"]) == 4 and 0 < s["uncertainty"] < 0.05


def test_a_partial_or_stale_table_falls_back_to_the_replicates():
    for table in (lambda v: _table(v, metrics=METRICS[:1]),     # one metric without a scale
                  lambda v: _table("other-version"),            # another version of the algorithm
                  lambda v: _table(v, scene_hash="changed")):   # another scene file
        task, algs, gts, job, res, version = _setup()
        reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"),
                                full=res.scores, scales=table(version))
        assert task.calls[1:] == [["cheap", "costly"]] * 4
        assert all(s["dof"] == 3 for s in attach([s.as_dict() for s in res.scores], reps))


def test_a_table_keyed_by_the_noise_hash_covers_every_render_seed_of_that_content():
    # the scores of a re-seeded render carry its own scene hash ("h"); the run maps it to the
    # scene's noise hash, which the table names, and the table's scale applies
    task, algs, gts, job, res, version = _setup()
    reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"), full=res.scores,
                            scales=_table(version, scene_hash="n"), noise_hashes={"h": "n"})
    assert task.calls[1:] == [["cheap"]] * 4
    # another content (another noise hash) falls back to the replicates
    task, algs, gts, job, res, version = _setup()
    reps = replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"), full=res.scores,
                            scales=_table(version, scene_hash="n"), noise_hashes={"h": "other"})
    assert task.calls[1:] == [["cheap", "costly"]] * 4
    assert all(s["dof"] == 3 for s in attach([s.as_dict() for s in res.scores], reps))


def test_the_noise_hash_ignores_the_render_seed_and_nothing_else():
    from pbrbench.bench.run import _noise_hashes
    from pbrbench.bench.source import reseeded
    from pbrbench.scene.load import SceneLibrary

    spec = SceneLibrary().all()["ps_groove[albedo=0.9]"]
    other = reseeded(spec, 3)
    assert other.render.seed == spec.render.seed + 3 and other.content_hash() != spec.content_hash()
    assert other.noise_hash() == spec.noise_hash()
    twin = SceneLibrary().all()["ps_groove[albedo=0.7]"]        # another albedo: another noise
    assert twin.noise_hash() != spec.noise_hash()
    # keyed by the scene hash each ground truth records (the one its scores carry)
    gts = {n: type("GT", (), {"meta": {"scene_hash": sp.content_hash()}})() for n, sp in (("a", other), ("b", twin))}
    assert _noise_hashes({"a": other, "b": twin}, gts) == {other.content_hash(): spec.noise_hash(),
                                                          twin.content_hash(): twin.noise_hash()}


def test_a_seed_dependent_job_ignores_the_table():
    # the seeds' spread was measured on noise-free inputs: camera noise is not in it
    task, algs, gts, job, res, version = _setup(seed_dependent=True)
    replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"), full=res.scores,
                     scales=_table(version))
    assert ["cheap", "costly"] in task.calls[1:5] and ["cheap"] not in task.calls


def test_the_committed_table_is_well_formed():
    entries = json.loads(SCALES_FILE.read_text())["entries"]
    assert entries and len(noise_scales()) == len(entries)          # one entry per key
    for e in entries:
        assert e["sd"] >= 0 and e["dof"] == len(e["render_seeds"]) - 1 >= 3 and 0 not in e["render_seeds"]
        assert e["quality"] in ("draft", "standard") and len(e["scene_hash"]) == 64 and len(e["noise_hash"]) == 64
        assert e["gt_format"] == GT_FORMAT      # measured on the ground truths the run reads
    # a draft entry with a standard twin carries the difference of the two means as its bias
    std = {(e["scene"], e["condition"], e["algorithm"], e["algorithm_version"], e["metric"]): e
           for e in entries if e["quality"] == "standard"}
    draft = [e for e in entries if e["quality"] == "draft"]
    for e in draft:
        twin = std.get((e["scene"], e["condition"], e["algorithm"], e["algorithm_version"], e["metric"]))
        if twin is None:
            assert "bias" not in e
        else:
            assert e["bias"] == pytest.approx(e["mean"] - twin["mean"], abs=1e-12) and e["bias_se"] >= 0


def test_the_committed_table_is_for_the_algorithms_as_they_are():
    """An entry whose algorithm version is not the code's is silently unused: the algorithm falls back to
    its replicates (for inverse rendering about five times its benchmark time).  A change to its module
    must be re-measured (scripts/noise_scales.py) or carried with evidence (the table's "about")."""
    from pbrbench.tasks import get_tasks

    entries = json.loads(SCALES_FILE.read_text())["entries"]
    reg = builtin_registry(get_tasks(sorted({e["task"] for e in entries})))
    current = {(a.task, a.name): a.full_version for a in reg}
    stale = sorted({(e["task"], e["algorithm"], e["algorithm_version"]) for e in entries
                    if current.get((e["task"], e["algorithm"])) != e["algorithm_version"]})
    assert not stale, f"noise scales of other versions than the code's: {stale}, code: " + str(
        {k: current.get(k[:2]) for k in stale})


def test_a_draft_scale_with_a_bias_reports_it():
    task, algs, gts, job, res, version = _setup()
    table = {k: (0.25, 7.0, 0.75) for k in _table(version)}
    scores = attach([s.as_dict() for s in res.scores],
                    replicate_scores(task, job, gts, seed=0, algorithms=algs, quality=get_quality("draft"),
                                     full=res.scores, scales=table))
    assert {(s["uncertainty"], s["bias"]) for s in scores if s["algorithm"] == "costly"} == {(0.25, 0.75)}


def test_an_entry_of_another_ground_truth_format_or_without_a_noise_hash_is_ignored(tmp_path):
    # a scale measured on other ground truths (another mask, other passes) is stale, even where
    # the scene files and the algorithm are the same
    entry = json.loads(SCALES_FILE.read_text())["entries"][0]
    for change, kept in (({}, 1), ({"gt_format": GT_FORMAT - 1}, 0), ({"noise_hash": None}, 0)):
        p = tmp_path / f"scales{len(change)}{kept}.json"
        p.write_text(json.dumps({"entries": [{**entry, **change}]}))
        assert len(noise_scales(str(p))) == kept
