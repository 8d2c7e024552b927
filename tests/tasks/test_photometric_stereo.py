"""The photometric-stereo task on synthetic ground truths built in NumPy, plus one draft render."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.quality import DRAFT, get_quality
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.scene import spec as S
from pbrbench.tasks.base import Job
from pbrbench.tasks.common.inputs import as_param, erode
from tests.fakes import (
    FIVE,
    HW,
    ps_gt,
    ps_job,
    run_task,
    scores_of,
)


def test_ps_local_exact_and_naive_baseline_biased():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt()
    res = run_task(TASK, ps_job(lights=vec), {"s": gt})
    sc = scores_of(res)
    assert sc[("woodham1980", "normal_mean_deg")] < 0.01
    assert sc[("woodham1980", "albedo_rel_err")] < 1e-6  # albedo x pi with the nominal E
    assert sc[("woodham1980", "coverage")] == 1.0
    # clamped (shadowed) measurements left in the fit bias the naive solve by about a degree
    assert sc[("baseline:naive_lstsq_all_lights", "normal_mean_deg")] > 0.5
    # integration floor on a non-rectangular mask: lsq beats the rectangle methods
    assert sc[("integrate:lsq", "height_rmse")] < 0.5 * sc[("integrate:path", "height_rmse")]
    assert sc[("integrate:lsq", "height_rmse_rel")] < 0.01
    assert all(s.task == "photometric_stereo" and s.condition == "local" and s.scene_hash for s in res.scores)
    assert {"normal_mean_deg", "coverage", "height_rmse"} <= {s.metric for s in res.scores}
    assert any(k.startswith("angular error") for k in res.error_maps)
    assert all(v.ndim in (2, 3) and max(v.shape[:2]) <= 128 for v in res.images.values())


def test_ps_noise_condition_deterministic_and_worse():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt()
    job = ps_job("local+noise0.01", lights=vec)
    a = scores_of(run_task(TASK, job, {"s": gt}, seed=3))
    b = scores_of(run_task(TASK, job, {"s": gt}, seed=3))
    c = scores_of(run_task(TASK, job, {"s": gt}, seed=4))
    assert a == b and a != c
    assert 0.1 < a[("woodham1980", "normal_mean_deg")] < 5
    assert ("integrate:lsq", "height_rmse") not in a  # the integration floor is scored once, under local


def test_ps_global_inflation_shows_in_absolute_albedo_only():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt(gi_gain=1.25)
    sc = scores_of(run_task(TASK, ps_job("global", lights=vec), {"s": gt}))
    assert sc[("woodham1980", "albedo_rel_err")] == pytest.approx(0.25, abs=1e-6)
    assert sc[("woodham1980", "albedo_rel_err_scaled")] < 1e-6
    assert sc[("woodham1980", "normal_mean_deg")] < 0.01  # a uniform gain does not move normals


def test_ps_domain_drops_pixels_lit_by_fewer_than_three_lights():
    from pbrbench.tasks.photometric_stereo import TASK

    four = FIVE[:4]  # without the source below, the bottom limb sees only the xz-plane sources
    gt, _ = ps_gt(lights=four)
    dom = TASK._domain(gt, four)
    cos = np.einsum("hwc,kc->khw", gt["normals"], four)
    lit = cos > 0.051
    # pixels lit only by the three lights of the xz plane have no unique normal
    coplanar = lit[0] & lit[1] & lit[2] & ~lit[3]
    assert coplanar.any() and not np.any(dom & coplanar)
    interior = erode(gt.mask, 1) & (lit.sum(0) >= 3) & ~coplanar
    assert np.all(dom[interior]) and np.all((cos > 0.049).sum(0)[dom] >= 3)
    sc = scores_of(run_task(TASK, ps_job(lights=four * np.pi), {"s": gt}))
    assert sc[("woodham1980", "normal_mean_deg")] < 0.01 and sc[("woodham1980", "coverage")] == 1.0
    assert not np.any(dom & (gt["mask"] < 0.5))


def test_ps_albedo_sweep_plot_job():
    from pbrbench.tasks.photometric_stereo import TASK

    gts = {}
    for a in (0.1, 0.9):
        gts[f"ps_cup[albedo={a:g}]"], vec = ps_gt("cup", albedo=a, gi_gain=1 + a / 2)
    job = Job("photometric_stereo", "ps_cup[albedo=0.9]", "global",
              (("plot", "albedo_sweep"), ("lights", as_param(vec)), ("half_width", HW)),
              extra_scenes=("ps_cup[albedo=0.1]",))
    res = run_task(TASK, job, gts)
    assert res.scores == []
    (name, plot), = [(k, v) for k, v in res.plots.items() if "albedo error" in k]
    assert plot["x"] == [0.1, 0.9]
    glob = plot["series"]["albedo rel. error, full GI (global)"]
    assert glob[0] == pytest.approx(0.05, abs=1e-3) and glob[1] == pytest.approx(0.45, abs=1e-3)
    assert max(plot["series"]["albedo rel. error, direct (local)"]) < 1e-6


def test_ps_reflex_plot_job():
    from pbrbench.tasks.photometric_stereo import TASK

    gts = {}
    for a in (0.0, 0.5):
        direct = np.zeros((8, 10, 3), np.float32)
        direct[:, 5:] = a  # one face lit (L = a E / pi with E = pi), the other in shadow
        glob = direct + a * a * np.linspace(1, 0, 10)[None, :, None].astype(np.float32)
        gts[f"groove_reflex_parallel[albedo={a:g}]"] = GroundTruth(
            {"radiance": glob, "direct": direct, "albedo": np.full((8, 10, 3), a, np.float32)}, {})
    job = Job("photometric_stereo", "groove_reflex_parallel[albedo=0.5]", "global", (("plot", "reflex"),),
              extra_scenes=("groove_reflex_parallel[albedo=0]",))
    res = run_task(TASK, job, gts)
    b = res.plots["groove_reflex_parallel: radiosity across the groove vs albedo"]["series"]
    assert set(b) == {"albedo 0", "albedo 0.5"} and max(b["albedo 0"]) == 0
    g = res.plots["groove_reflex_parallel: B / albedo (total irradiance) vs the local model"]["series"]
    assert np.allclose(g["local model (direct)"], [0] * 5 + [np.pi] * 5)
    assert np.allclose(np.subtract(g["albedo 0.5, global"], g["local model (direct)"]), np.pi * 0.5 * np.linspace(1, 0, 10))


def test_ps_jobs_pair_area_twins(tmp_path, monkeypatch):
    from pbrbench.tasks.photometric_stereo import PhotometricStereoTask

    def toml(v):
        return "[" + ", ".join(f"{float(x):.6f}" for x in v) + "]"

    dirs = FIVE[:3] + [0.1, 0, 0]
    lights = "".join(f'[[light_set]]\ntype = "directional"\ndirection = {toml(v)}\nirradiance = 3.0\n\n' for v in dirs)
    base = ('description = "t"\n[render]\nresolution = 32\n[materials.paint]\ntype = "diffuse"\nalbedo = 0.5\n'
            '[[shapes]]\ntype = "sphere"\nmaterial = "paint"\n')
    sweep = '[sweep]\n"materials.paint.albedo" = [0.1, 0.5, 0.9]\n'
    (tmp_path / "ps_cup.toml").write_text('name = "ps_cup"\n' + base + lights + sweep)
    area = "".join(f'[[light_set]]\ntype = "area"\ncenter = {toml(4 * v / np.linalg.norm(v))}\nsize = [1.0, 1.0]\n'
                   f'normal = {toml(-v / np.linalg.norm(v))}\nradiance = 16.0\n\n' for v in dirs)
    (tmp_path / "ps_cup_area.toml").write_text('name = "ps_cup_area"\n' + base + area + sweep)
    from pbrbench.scene.load import SceneLibrary

    task = PhotometricStereoTask().bind(SceneLibrary(tmp_path))
    task.families = ("ps_cup", "missing_family")
    task.short_families = ("ps_cup",)
    jobs = task.jobs(get_quality("standard"))
    conds = {(j.scene, j.condition) for j in jobs if j.param("plot") is None}
    assert ("ps_cup[albedo=0.5]", "local+noise0.01") in conds and ("ps_cup_area[albedo=0.5]", "area") in conds
    assert ("ps_cup[albedo=0.5]", "local+ambient0.1") in conds
    assert len(conds) == 3 * 5
    area_job = next(j for j in jobs if j.condition == "area")
    v = np.asarray(area_job.param("lights"))
    assert np.allclose(np.linalg.norm(v, axis=1), 16.0 / 16.0)  # L A / d^2, equal for all
    assert np.allclose(v / np.linalg.norm(v, axis=1, keepdims=True),
                       dirs / np.linalg.norm(dirs, axis=1, keepdims=True), atol=1e-5)
    sweep_jobs = [j for j in jobs if j.param("plot") == "albedo_sweep"]
    assert len(sweep_jobs) == 1 and len(sweep_jobs[0].extra_scenes) == 2
    draft = task.jobs(get_quality("draft"))
    assert {j.scene for j in draft if j.condition == "local"} == {"ps_cup[albedo=0.1]", "ps_cup[albedo=0.9]"}
    assert len({j.key for j in jobs}) == len(jobs)


@pytest.mark.render
@pytest.mark.slow
def test_ps_on_a_draft_render():
    from pbrbench.render.groundtruth import render_ground_truth
    from pbrbench.tasks.photometric_stereo import TASK

    spec = S.SceneSpec(
        name="ps_draft_sphere", description="draft test", camera=S.Camera(half_width=1.05),
        render=S.Render(resolution=64, spp=64, max_depth=-1),
        materials={"paint": {"type": "diffuse", "albedo": 0.7}},
        shapes=({"type": "sphere", "material": "paint"},),
        light_set=tuple({"type": "directional", "direction": tuple(v), "irradiance": np.pi} for v in FIVE[:4]))
    gt = render_ground_truth(spec, DRAFT)  # 32 x 32, 4 spp
    job = Job("photometric_stereo", spec.name, "local", TASK._params(spec))
    sc = scores_of(run_task(TASK, job, {spec.name: gt}))
    assert sc[("woodham1980", "normal_mean_deg")] < 1.0
    assert sc[("woodham1980", "albedo_rel_err")] < 0.02
    assert sc[("baseline:naive_lstsq_all_lights", "normal_mean_deg")] > sc[("woodham1980", "normal_mean_deg")]



def test_the_sphere_job_draws_the_chapter_figures_1_13_to_1_16():
    from pbrbench.tasks.photometric_stereo import TASK
    from tests.fakes import ps_gt, ps_job, run_task

    job = ps_job("local", scene="sphere_5lights")
    res = run_task(TASK, job, {"sphere_5lights": ps_gt()[0]})
    figs = {k.split(" ")[1]: v for k, v in res.images.items() if k.startswith("Fig 1.1")}
    assert set(figs) == {"1.13", "1.14", "1.15", "1.16"}
    assert all(0 <= np.nanmin(v) and np.nanmax(v) <= 1 for v in figs.values())
    shaded = figs["1.16"]
    h, w = shaded.shape
    assert shaded[h // 3, w // 3] > shaded[2 * h // 3, 2 * w // 3]  # the sphere lit from the upper left
    other = run_task(TASK, ps_job("local", scene="ps_bumps[albedo=0.5]"), {"ps_bumps[albedo=0.5]": ps_gt()[0]})
    assert not any(k.startswith("Fig") for k in other.images)  # only the chapter's sphere
