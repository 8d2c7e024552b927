"""The shape-from-shading task on a synthetic sphere."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.tasks.base import Job
from tests.fakes import (
    run_task,
    scores_of,
    sfs_gt,
)


def test_sfs_methods_references_labels_and_conditions():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    res = run_task(TASK, job, {"sfs_sphere": gt})
    sc = scores_of(res)
    flat = sc[("baseline:flat", "normal_mean_deg")]
    assert flat > 30
    assert sc[("kimmel2001", "normal_mean_deg")] < 0.5 * flat
    assert sc[("floor:integrate_true_normals", "height_rmse")] < sc[("kimmel2001", "height_rmse")]
    assert sc[("floor:integrate_true_normals", "height_rmse")] < 0.2 * sc[("baseline:flat", "height_rmse")]
    assert ("kimmel2001+estimated_light", "height_rmse") in sc
    assert sc[("light_from_shading:contour", "light_error_deg")] < 10
    assert {s.scene for s in res.scores} == {"sfs_sphere:oblique"}
    assert next(s for s in res.scores if s.metric == "converged").better == "higher"
    assert all(np.isfinite(s.value) for s in res.scores)
    assert all(sc[(m, "failed")] == 0 for m in ("horn1989", "tsai_shah1994", "pentland1990", "kimmel2001"))
    (plot,) = [v for k, v in res.plots.items() if k.startswith("height profile")]
    assert {"truth", "baseline:flat", "floor:integrate_true_normals", "horn1989"} <= set(plot["series"])
    (law,) = [v for k, v in res.plots.items() if k.startswith("Fig 1.3")]      # the oblique sphere: Lambert's law
    pts = law["series"]["rendered pixels (direct light)"]
    np.testing.assert_allclose(pts["y"], np.maximum(pts["x"], 0.0), atol=0.05)
    # 'global' reads light00.radiance (x1.1 here: the known albedo is violated) and skips the
    # estimated-light variants
    glob = scores_of(run_task(TASK, Job(job.task, job.scene, "global", job.params), {"sfs_sphere": gt}))
    assert not any("+estimated_light" in a for a, _ in glob)
    assert glob[("kimmel2001", "normal_mean_deg")] > sc[("kimmel2001", "normal_mean_deg")]


def test_sfs_a_refused_input_is_scored_as_a_failure():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    # a nominal light behind the surface (z < 0): every method refuses it (ValueError) and is
    # scored failed = 1 with no other score; the two references are still scored
    params = tuple((k, (0.7, 0.0, -0.1) if k == "light" else v) for k, v in job.params)
    sc = scores_of(run_task(TASK, Job(job.task, job.scene, "local+noise0", params), {"sfs_sphere": gt}))
    for m in ("horn1989", "tsai_shah1994", "pentland1990", "kimmel2001"):
        assert sc[(m, "failed")] == 1.0 and (m, "height_rmse") not in sc
    assert ("baseline:flat", "normal_mean_deg") in sc and ("floor:integrate_true_normals", "height_rmse") in sc


def test_sfs_kimmel2001_without_singular_point_is_scored():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    # a nominal irradiance 30 % too high: the normalised image never reaches 1; fast marching
    # seeds the brightest pixels (it used to refuse the input) and beats the flat surface
    params = tuple((k, np.pi * 1.3 if k == "irradiance" else v) for k, v in job.params)
    sc = scores_of(run_task(TASK, Job(job.task, job.scene, "local+noise0", params), {"sfs_sphere": gt}))
    assert sc[("kimmel2001", "failed")] == 0.0
    assert sc[("kimmel2001", "normal_mean_deg")] < sc[("baseline:flat", "normal_mean_deg")]



def test_fig_1_3_the_cosine_law_plot_of_an_exact_lambertian_sphere_lies_on_the_law():
    import numpy as np

    from pbrbench.render.groundtruth import GroundTruth
    from pbrbench.shading.surfaces import on_grid
    from pbrbench.tasks.sfs import cosine_law_plot

    s = on_grid("sphere", 48, 1.1)
    S = np.array([0.6, 0.0, 0.8])
    rho, E = 0.7, 2.0
    img = np.where(s.mask, rho * E / np.pi * np.clip(s.normals @ S, 0, None), 0.0)
    gt = GroundTruth({"normals": s.normals.astype(np.float32), "mask": s.mask.astype(np.float32),
                      "albedo": np.full((48, 48, 3), rho, np.float32)}, {"scene_hash": "t"})
    p = cosine_law_plot(gt, img, 3.0 * S, E)          # any length of the source vector
    pts = p["series"]["rendered pixels (direct light)"]
    x, y = np.array(pts["x"]), np.array(pts["y"])
    assert x.min() < 0 < x.max() and len(x) == int(s.mask.sum())
    np.testing.assert_allclose(y, np.maximum(x, 0.0), atol=1e-5)     # float32 normals


@pytest.mark.render
def test_fig_1_23_a_grazing_source_picks_out_the_craters_and_a_high_one_hides_them(cache_dir):
    import numpy as np

    from pbrbench.quality import DRAFT
    from pbrbench.render.cache import RenderCache, ground_truth
    from pbrbench.tasks.sfs import TASK

    (job,) = [j for j in TASK.jobs(DRAFT) if j.param("plot") == "relief"]
    gt, _ = ground_truth(TASK.scenes.spec(job.scene), DRAFT, cache=RenderCache(cache_dir))
    res = TASK.run_job(job, {job.scene: gt}, quality=DRAFT)
    assert not res.scores
    names = sorted(res.images)
    assert [n.split(" deg")[0].split()[-1] for n in names] == ["15", "70"]
    contrast = [float(np.std(res.images[n]) / np.mean(res.images[n])) for n in names]
    assert contrast[0] > 3 * contrast[1]
