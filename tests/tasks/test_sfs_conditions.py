"""The SFS task's ambient, wrong-albedo and near-source conditions and the albedo-estimating method."""

from __future__ import annotations

import numpy as np

from pbrbench.quality import get_quality
from pbrbench.registry import Algorithm
from pbrbench.tasks.base import Job
from tests.fakes import run_task, scores_of, sfs_gt


def _with(job, condition, **params):
    p = tuple((k, params.pop(k)) if k in params else (k, v) for k, v in job.params) + tuple(params.items())
    return Job(job.task, job.scene, condition, p)


def test_new_sfs_conditions_have_jobs_at_draft_and_standard():
    from pbrbench.tasks.sfs import NEAR_DISTANCES, TASK, near_condition

    for q in ("draft", "standard"):
        jobs = TASK.jobs(get_quality(q))
        conds = {j.condition for j in jobs}
        assert {"local+ambient0.1", "local+wrong_albedo0.7"} <= conds
        near = [j for j in jobs if j.condition.startswith("near+d")]
        assert {j.param("label") for j in near} == {"view", "oblique"}
        assert all(j.scene.startswith("sfs_near[") and j.param("match") == "sfs_sphere" for j in near)
        assert conds <= set(TASK.conditions)
    draft = TASK.jobs(get_quality("draft"))
    # draft: the middle distance only, and the new conditions on sfs_sphere only
    assert {j.condition for j in draft if j.condition.startswith("near+d")} == {near_condition(4)}
    assert {j.scene for j in draft if j.condition.startswith("local+")} >= {"sfs_sphere"}
    assert all(j.scene == "sfs_sphere" for j in draft if "ambient" in j.condition or "wrong_albedo" in j.condition)
    std = TASK.jobs(get_quality("standard"))
    assert {j.condition for j in std if j.condition.startswith("near+d")} == {near_condition(d) for d in NEAR_DISTANCES}


def test_near_scenes_are_sfs_sphere_with_a_point_source_at_the_stated_distance():
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.tasks.sfs import NEAR_DISTANCES

    lib = SceneLibrary()
    (ref,) = lib.family("sfs_sphere")
    near = lib.family("sfs_near")
    assert len(near) == 2 * len(NEAR_DISTANCES)
    for s in near:
        assert s.camera == ref.camera and s.shapes == ref.shapes and s.render.resolution == ref.render.resolution
        (li,) = s.lights
        assert li.type == "point"
    dist = sorted(round(float(np.linalg.norm(s.lights[0].position)), 3) for s in near)
    assert dist == sorted(2 * [float(d) for d in NEAR_DISTANCES])


def test_zheng_chellappa_is_scored_and_has_no_estimated_light_variant():
    from pbrbench.tasks.sfs import TASK

    names = {a.name for a in TASK.builtin_algorithms()}
    assert "zheng_chellappa1991" in names and "light_from_shading:zheng_chellappa1991" in names
    assert "zheng_chellappa1991+estimated_light" not in names and "horn1989+estimated_light" in names
    gt, job = sfs_gt()
    sc = scores_of(run_task(TASK, job, {"sfs_sphere": gt}))
    assert sc[("zheng_chellappa1991", "failed")] == 0
    assert sc[("zheng_chellappa1991", "normal_mean_deg")] < 0.5 * sc[("baseline:flat", "normal_mean_deg")]
    assert sc[("light_from_shading:zheng_chellappa1991", "light_error_deg")] < 15


def _spy(record):
    def spy(image, light, *, albedo=None, mask=None, pixel_size=1.0):
        record.append((np.array(image), float(albedo)))
        n = np.zeros(image.shape + (3,))
        n[..., 2] = 1.0
        return {"height": np.zeros(image.shape), "normals": n}
    return spy


def _spied(job, gt):
    from pbrbench.tasks.sfs import TASK

    rec = []
    TASK.run_job(job, {job.scene: gt}, algorithms=[Algorithm("spy", "sfs", _spy(rec))], quality=get_quality("draft"))
    (got,) = rec
    return got


def test_wrong_albedo_hands_every_method_0_7_times_the_albedo_and_ambient_adds_rho_a():
    gt, job = sfs_gt(albedo=0.8)
    img0, a0 = _spied(job, gt)
    img1, a1 = _spied(_with(job, "local+wrong_albedo0.7"), gt)
    assert np.isclose(a0, 0.8) and np.isclose(a1, 0.7 * a0)
    np.testing.assert_array_equal(img0, img1)
    img2, a2 = _spied(_with(job, "local+ambient0.1"), gt)
    assert a2 == a0
    mask = gt.mask
    np.testing.assert_allclose((img2 - img0)[mask], 0.1 * 0.8, rtol=1e-6)   # rho A = 0.1 rho E / pi, E = pi
    assert np.all((img2 - img0)[~mask] == 0)


def test_albedo_estimating_sfs_against_sfs_given_a_wrong_albedo():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    loc = scores_of(run_task(TASK, job, {"sfs_sphere": gt}))
    wrong = scores_of(run_task(TASK, _with(job, "local+wrong_albedo0.7"), {"sfs_sphere": gt}))
    # zheng_chellappa1991 ignores the given albedo: the same score; horn1989 (its shape solver)
    # given 0.7x the albedo does worse than with the true one, and worse than zheng_chellappa1991
    assert wrong[("zheng_chellappa1991", "normal_mean_deg")] == loc[("zheng_chellappa1991", "normal_mean_deg")]
    assert wrong[("horn1989", "normal_mean_deg")] > loc[("horn1989", "normal_mean_deg")] + 2
    assert wrong[("horn1989", "normal_mean_deg")] > wrong[("zheng_chellappa1991", "normal_mean_deg")]
    assert not any("+estimated_light" in a for a, _ in wrong)


def test_ambient_and_near_jobs_are_scored_and_near_is_labelled_as_its_sfs_sphere_case():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    loc = scores_of(run_task(TASK, job, {"sfs_sphere": gt}))
    amb = scores_of(run_task(TASK, _with(job, "local+ambient0.1"), {"sfs_sphere": gt}))
    assert amb[("kimmel2001", "normal_mean_deg")] != loc[("kimmel2001", "normal_mean_deg")]
    assert all(amb[(m, "failed")] == 0 for m in ("horn1989", "pentland1990", "zheng_chellappa1991"))
    # a near job: a single-light scene (direct), scored under the sfs_sphere case it twins
    arr = {k: v for k, v in gt.arrays.items() if not k.startswith("light00")}
    near_gt = type(gt)(arr, {"scene_hash": "synthetic-near"})
    name = "sfs_near[position=1.41421_0_1.41421]"
    params = tuple((k, -1 if k == "light_index" else v) for k, v in job.params) + (("match", "sfs_sphere"),)
    res = run_task(TASK, Job("sfs", name, "near+d2", params), {name: near_gt})
    assert {s.scene for s in res.scores} == {"sfs_sphere:oblique"}
    assert {s.scene_hash for s in res.scores} == {"synthetic-near"}
    assert scores_of(res)[("zheng_chellappa1991", "failed")] == 0
