"""The inverse-rendering methods in the photometric-stereo task: where they run, how they are
called (the scene interface), their figures, and a failure (no rendering: fakes)."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.infer.photometric_stereo import METHODS
from pbrbench.quality import get_quality
from pbrbench.registry import Algorithm, Registry
from pbrbench.tasks.base import Job
from pbrbench.tasks.photometric_stereo import TASK, PhotometricStereoTask
from tests.fakes import ps_gt, ps_job, run_task, scores_of


def test_registered_as_inverse_with_the_scene_interface():
    algs = {a.name: a for a in TASK.builtin_algorithms()}
    a = algs["inverse:nicolet2021"]
    assert a.interface == "scene" and a.kind == "method"
    assert a.applies("global") and a.applies("local") and not a.applies("area")


@pytest.mark.parametrize("scene, cond, quality, runs", [
    ("ps_groove[albedo=0.9]", "global", "standard", True),
    ("ps_groove[albedo=0.9]", "local", "standard", True),    # local too: its noise scales are measured
    ("ps_groove[albedo=0.9]", "local+noise0.01", "standard", False),
    ("ps_cup[albedo=0.9]", "global", "standard", True),
    ("ps_cap[albedo=0.9]", "global", "standard", True),
    ("ps_groove[albedo=0.5]", "global", "standard", False),   # the highest albedo only
    ("sphere_5lights", "local", "standard", False),           # convex families: not run
    ("ps_groove[albedo=0.9]", "global", "draft", True),       # draft: one scene, one condition
    ("ps_groove[albedo=0.9]", "local", "draft", False),
    ("ps_cup[albedo=0.9]", "global", "draft", False),
])
def test_where_the_inverse_methods_run(scene, cond, quality, runs):
    job = Job("photometric_stereo", scene, cond, ())
    assert PhotometricStereoTask()._inverse_applies(job, get_quality(quality)) is runs


def _fake_registry(fn):
    return Registry([Algorithm("woodham1980", "photometric_stereo", METHODS["woodham1980"]),
                     Algorithm("inverse:fake", "photometric_stereo", fn, interface="scene", conditions=("global", "local"))])


def test_scene_interface_call_scores_and_figures():
    gt, vec = ps_gt()
    seen = {}

    def fake(images, lights, *, mask, scene, max_depth, seed):
        seen.update(scene=scene.name, max_depth=max_depth, k=len(images), seed=seed)
        n = np.zeros(mask.shape + (3,))
        n[..., 2] = 1.0
        # the truth from the ground truth's normals: the fake is perfect
        n = np.where(mask[..., None], gt["normals"], n)
        return {"normals": n, "albedo": np.where(mask, 0.6 / np.pi, 0.0), "loss": np.array([3.0, 2.0, 1.0]),
                "level": np.array([2, 1, 1]), "initial_normals": np.where(mask[..., None], [0.0, 0.0, 1.0], 0.0),
                "options": {"start": "nayar1991"}}

    job = ps_job("global", lights=vec, scene="ps_groove[albedo=0.9]")
    res = run_task(TASK, job, {"ps_groove[albedo=0.9]": gt}, seed=5, quality="standard",
                   registry=_fake_registry(fake))
    assert seen == {"scene": "ps_groove[albedo=0.9]", "max_depth": -1, "k": len(vec), "seed": 5}
    sc = scores_of(res)
    assert sc[("inverse:fake", "normal_mean_deg")] < 0.01
    assert sc[("inverse:fake", "albedo_rel_err")] < 1e-5
    assert sc[("woodham1980", "normal_mean_deg")] < 0.01
    plot = res.plots["inverse:fake: loss per iteration"]
    assert plot["series"]["objective E"] == [3.0, 2.0, 1.0]
    before = res.error_maps["angular error (deg): inverse:fake, its start (nayar1991)"]   # named by the method
    after = res.error_maps["angular error (deg): inverse:fake"]
    assert np.nanmean(before) > 1.0 > np.nanmean(after)

    # local (run at standard): the transport of the images is direct light (max_depth 2)
    run_task(TASK, ps_job("local", lights=vec, scene="ps_groove[albedo=0.9]"), {"ps_groove[albedo=0.9]": gt},
             quality="standard", registry=_fake_registry(fake))
    assert seen["max_depth"] == 2


def test_a_failing_inverse_method_is_scored_failed_and_the_job_goes_on():
    gt, vec = ps_gt()

    def broken(images, lights, *, mask, scene, max_depth, seed):
        raise ValueError("inverse rendering needs a differentiable Mitsuba variant")

    res = run_task(TASK, ps_job("global", lights=vec, scene="ps_groove[albedo=0.9]"), {"ps_groove[albedo=0.9]": gt},
                   quality="standard", registry=_fake_registry(broken))
    sc = scores_of(res)
    assert sc[("inverse:fake", "failed")] == 1.0
    assert "differentiable" in res.failures["inverse:fake"]
    assert ("woodham1980", "normal_mean_deg") in sc


def test_not_called_outside_its_scenes():
    gt, vec = ps_gt()

    def never(*a, **k):  # pragma: no cover - must not run
        raise AssertionError("called")

    res = run_task(TASK, ps_job("global", lights=vec, scene="s"), {"s": gt}, quality="standard",
                   registry=_fake_registry(never))
    assert not any(s.algorithm == "inverse:fake" for s in res.scores)
