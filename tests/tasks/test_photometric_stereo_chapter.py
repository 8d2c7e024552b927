"""The photometric-stereo task's chapter additions: the near and ambient conditions, colour and
near-light methods, and the chapter's self-checks as scores (synthetic ground truths + one render)."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.quality import get_quality
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.shading.surfaces import on_grid, pixel_grid
from pbrbench.tasks.base import Job
from pbrbench.tasks.common.inputs import as_param
from tests.fakes import FIVE, HW, ps_gt, ps_job, run_task, scores_of

CHECKS = {"ps_integrability", "ps_lsq_residual", "ps_albedo_over1_frac"}


def near_gt(size=40, albedo=0.6, dist=2.0, intensity=4 * np.pi, camera=5.0):
    """A unit sphere under point sources at ``dist`` along FIVE (camera frame, target at the
    centre): radiance ``rho I N.(P - X) / (pi |P - X|^3)``."""
    s = on_grid("sphere", size, HW)
    x, y = pixel_grid(size, size, HW)
    X = np.stack([x, y, s.z], -1)
    pos = FIVE * dist
    arr = {}
    for k, p in enumerate(pos):
        d = p - X
        r = np.linalg.norm(d, axis=-1)
        im = np.where(s.mask, albedo * intensity * np.maximum(np.einsum("hwc,hwc->hw", s.normals, d), 0) / r ** 3
                      / np.pi, 0.0)
        arr[f"light{k:02d}.direct"] = arr[f"light{k:02d}.radiance"] = np.repeat(im[..., None], 3, -1).astype(np.float32)
    arr["normals"] = s.normals.astype(np.float32)
    arr["albedo"] = np.repeat(np.where(s.mask, albedo, 0.0)[..., None], 3, -1).astype(np.float32)
    arr["depth"] = np.where(s.mask, camera - s.z, 0.0).astype(np.float32)
    arr["mask"] = s.mask.astype(np.float32)
    gt = GroundTruth(arr, {"scene_hash": "synthetic-near", "n_light_set": len(pos)})
    nominal = FIVE * intensity / dist ** 2
    params = (("lights", as_param(nominal)), ("half_width", HW), ("positions", as_param(pos)),
              ("intensities", as_param([intensity] * len(pos))), ("camera_distance", camera))
    return gt, params


def test_near_and_ambient_jobs_at_draft_and_standard():
    from pbrbench.tasks.photometric_stereo import TASK

    for q, n_near in (("draft", 1), ("standard", 4)):
        jobs = [j for j in TASK.jobs(get_quality(q)) if j.param("plot") is None]
        near = [j for j in jobs if j.condition == "near"]
        assert len(near) == n_near and all(j.scene.startswith("ps_near[") for j in near)
        assert all(len(j.param("positions")) == len(j.param("lights")) == 5 for j in near)
        # each near scene's distant twin runs under local, scored under the near scene's name (matched)
        twins = {j.param("label"): j.scene for j in jobs if j.param("label")}
        assert set(twins) == {j.scene for j in near}
        assert all(t.startswith("ps_near_distant[") and t.split("[")[1] == n.split("[")[1] for n, t in twins.items())
        amb = [j for j in jobs if j.condition == "local+ambient0.1"]
        noise = [j for j in jobs if j.condition == "local+noise0.01"]
        assert amb and {j.scene for j in amb} == {j.scene for j in noise}
    draft = TASK.jobs(get_quality("draft"))
    assert {j.scene for j in draft if j.condition == "near"} == {"ps_near[radius=1]"}   # the nearest only
    assert any(j.param("plot") == "checks" for j in draft)
    assert any(j.param("plot") == "near_sweep" for j in TASK.jobs(get_quality("standard")))
    assert "near" in TASK.conditions and "local+ambient0.1" in TASK.conditions


def test_new_methods_registered_with_their_interfaces():
    from pbrbench.infer.photometric_stereo import METHODS
    from pbrbench.tasks.photometric_stereo import TASK

    assert {"woodham1980_colour", "iwahori1990"} <= set(METHODS)
    algs = {a.name: a for a in TASK.builtin_algorithms()}
    assert algs["iwahori1990"].interface == "near" and algs["iwahori1990"].applies("near")
    assert not algs["iwahori1990"].applies("local") and not algs["iwahori1990"].applies("global")
    assert algs["woodham1980_colour"].interface == "colour" and algs["woodham1980_colour"].applies("local")


def test_check_scores_in_every_scored_job_zero_on_exact_images():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt()
    res = run_task(TASK, ps_job(lights=vec), {"s": gt})
    sc = scores_of(res)
    methods = {s.algorithm for s in res.scores if not s.algorithm.startswith("integrate:")}
    for alg in methods:
        assert CHECKS <= {m for (a, m) in sc if a == alg}, alg
    assert sc[("woodham1980", "ps_lsq_residual")] < 1e-5       # float32 Lambertian images
    assert sc[("woodham1980", "ps_albedo_over1_frac")] == 0.0
    assert sc[("woodham1980", "ps_integrability")] < 0.5
    # the naive solve (shadows in the fit) leaves a residual the exact fit does not
    assert sc[("baseline:naive_lstsq_all_lights", "ps_lsq_residual")] > 10 * sc[("woodham1980", "ps_lsq_residual")]


def test_ambient_condition_is_the_local_model_term_and_costs_something():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt()
    loc = scores_of(run_task(TASK, ps_job(lights=vec), {"s": gt}))
    job = ps_job("local+ambient0.1", lights=vec)
    a = scores_of(run_task(TASK, job, {"s": gt}, seed=1))
    assert a == scores_of(run_task(TASK, job, {"s": gt}, seed=2))   # no noise: seed independent
    assert not TASK.seed_dependent(job)
    assert a[("woodham1980", "normal_mean_deg")] > loc[("woodham1980", "normal_mean_deg")] + 0.5
    assert a[("woodham1980", "ps_lsq_residual")] > 100 * loc[("woodham1980", "ps_lsq_residual")]
    # the term: rho A / pi with A = 0.1 x mean |V_k| (= 0.1 pi here), shadows no longer black
    images = TASK._inputs(job, gt, 0)
    base = TASK._inputs(ps_job(lights=vec), gt, 0)
    m = gt.mask
    assert np.allclose((images - base)[:, m], 0.6 * 0.1 * np.pi / np.pi, atol=1e-6)
    assert np.all((images - base)[:, ~m] == 0)


def test_near_condition_iwahori_beats_woodham_given_nominal_directions():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, params = near_gt()
    job = Job("photometric_stereo", "ps_near[radius=1]", "near", params)
    res = run_task(TASK, job, {job.scene: gt})
    sc = scores_of(res)
    assert sc[("woodham1980", "normal_mean_deg")] > 3.0          # distant model, sources at 2 radii
    assert sc[("iwahori1990", "normal_mean_deg")] < 0.3 * sc[("woodham1980", "normal_mean_deg")]
    assert not res.failures
    # the twin's local scores carry the near scene's name (the headline matches them)
    far, vec = ps_gt()
    twin = Job("photometric_stereo", "ps_near_distant[radius=1]", "local",
               (("lights", as_param(vec)), ("half_width", HW), ("label", "ps_near[radius=1]")))
    tres = run_task(TASK, twin, {twin.scene: far})
    assert {s.scene for s in tres.scores} == {"ps_near[radius=1]"}
    assert "iwahori1990" not in {s.algorithm for s in tres.scores}


def test_colour_method_gets_the_colour_stack():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt()
    rgb = np.array([0.9, 0.5, 0.2])
    arr = dict(gt.arrays)
    for k in range(len(vec)):
        arr[f"light{k:02d}.direct"] = (arr[f"light{k:02d}.direct"] / 0.6 * rgb).astype(np.float32)
    arr["albedo"] = (arr["albedo"] / 0.6 * rgb).astype(np.float32)
    cgt = GroundTruth(arr, dict(gt.meta))
    sc = scores_of(run_task(TASK, ps_job(lights=vec), {"s": cgt}))
    assert sc[("woodham1980_colour", "normal_mean_deg")] < 0.01
    assert sc[("woodham1980_colour", "albedo_rel_err")] < 1e-5    # channel mean of its per-channel albedo


def test_checks_plot_job_correlates_each_check_with_the_error():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt(gi_gain=1.2)
    job = Job("photometric_stereo", "s", "local", (("plot", "checks"), ("lights", as_param(vec)), ("half_width", HW)))
    res = run_task(TASK, job, {"s": gt})
    assert res.scores == []
    (plot,) = res.plots.values()
    assert plot["x"] == [0.0, 1.0, 2.0]
    assert {"Spearman, local+ambient0.1", "Pearson, local+noise0.01", "Spearman, global"} <= set(plot["series"])
    amb = plot["series"]["Spearman, local+ambient0.1"]
    assert amb[1] is not None and amb[1] > 0.3     # under ambient the residual marks the bad pixels


@pytest.mark.render
@pytest.mark.slow
def test_iwahori_beats_woodham_on_a_draft_near_render():
    from pbrbench.quality import DRAFT
    from pbrbench.render.groundtruth import render_ground_truth
    from pbrbench.tasks.photometric_stereo import TASK

    spec = TASK.scenes.spec("ps_near[radius=1]")
    gt = render_ground_truth(spec, DRAFT)
    job = next(j for j in TASK.jobs(DRAFT) if j.condition == "near" and j.param("plot") is None)
    sc = scores_of(run_task(TASK, job, {spec.name: gt}))
    assert sc[("iwahori1990", "normal_mean_deg")] < 0.6 * sc[("woodham1980", "normal_mean_deg")]
