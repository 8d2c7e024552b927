"""The lightness task on synthetic Mondrians."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.tasks.base import Job
from tests.fakes import (
    mondrian_gt,
    run_task,
    scores_of,
)


def test_lightness_retinex_beats_baselines_and_anchor_rules_differ():
    from pbrbench.tasks.lightness import TASK

    res = run_task(TASK, Job("lightness", "m", "local", (("paper_ids", (1,)),)), {"m": mondrian_gt()})
    sc = scores_of(res)
    for alg in ("blake1985", "blake1985:mean"):
        assert sc[(alg, "lmse")] < 0.1 * sc[("baseline:image_is_reflectance", "lmse")]
        assert sc[(alg, "lmse")] < 0.1 * sc[("baseline:uniform_reflectance", "lmse")]
    # same decomposition up to scale, different constants of integration
    assert sc[("blake1985:mean", "lmse")] == pytest.approx(sc[("blake1985", "lmse")], rel=1e-6)
    assert sc[("blake1985:mean", "albedo_abs_err")] != pytest.approx(sc[("blake1985", "albedo_abs_err")], rel=0.1)
    assert sc[("blake1985:subtract", "ratio_err_max")] < 0.02
    # a uniform reflectance gets every ratio between papers wrong
    assert sc[("baseline:uniform_reflectance", "ratio_err_max")] > 10 * sc[("blake1985:subtract", "ratio_err_max")]
    (plot,) = res.plots.values()
    assert plot["note"] == "middle row" and len(plot["x"]) == 64


def test_lightness_cast_shadow_is_the_failure_and_is_profiled():
    from pbrbench.tasks.lightness import TASK

    job = Job("lightness", "m", "local", (("paper_ids", (1,)),))
    clean = scores_of(run_task(TASK, job, {"m": mondrian_gt()}))
    res = run_task(TASK, job, {"m": mondrian_gt(shadow=True)})
    shadow = scores_of(res)
    assert shadow[("blake1985", "lmse")] > 10 * clean[("blake1985", "lmse")]
    (plot,) = res.plots.values()
    frac = np.array(plot["series"]["unoccluded fraction"], float)
    assert plot["note"] == "row crossing the cast shadow" and frac.min() < 0.5 < frac.max()


def test_lightness_colour_keeps_channels():
    from pbrbench.tasks.lightness import TASK

    res = run_task(TASK, Job("lightness", "m", "global", (("paper_ids", (1,)),)), {"m": mondrian_gt(colour=True)})
    assert res.images["reflectance: truth"].shape[-1] == 3
    assert scores_of(res)[("blake1985:subtract", "lmse")] < 1e-3


def test_lightness_scores_only_the_paper():
    from pbrbench.tasks.lightness import TASK

    job = Job("lightness", "m", "local", (("paper_ids", (1,)),))
    ref = scores_of(run_task(TASK, job, {"m": mondrian_gt()}))
    gt = mondrian_gt()
    gt.arrays["object_id"][:6, :6] = 2  # another object (an occluder seen by the camera)
    gt.arrays["direct"][:6, :6] = 50.0
    gt.arrays["albedo"][:6, :6] = 0.02
    sc = scores_of(run_task(TASK, job, {"m": gt}))
    assert sc[("blake1985", "lmse")] < 3 * ref[("blake1985", "lmse")]
    wrong = scores_of(run_task(TASK, Job("lightness", "m", "local", (("paper_ids", (1, 2)),)), {"m": gt}))
    assert wrong[("blake1985", "albedo_abs_err")] > 2 * sc[("blake1985", "albedo_abs_err")]


def test_lightness_labels():
    from pbrbench.tasks.lightness import patch_labels

    a = np.array([[0.1, 0.1, 0.5], [0.9, 0.5, 0.5]])
    lab = patch_labels(a, np.array([[True, True, True], [True, True, False]]))
    assert lab[0, 0] == lab[0, 1] != lab[0, 2] and lab[1, 1] == lab[0, 2] and lab[1, 2] == -1



def test_lightness_ambient_jobs_at_draft_and_standard():
    from pbrbench.quality import get_quality
    from pbrbench.tasks.lightness import AMBIENT, TASK

    cond = f"local+ambient{AMBIENT:g}"
    assert cond == "local+ambient0.1" and cond in TASK.conditions
    for q in ("draft", "standard"):
        jobs = TASK.jobs(get_quality(q))
        local = {(j.scene, j.params) for j in jobs if j.condition == "local" and j.param("plot") is None}
        ambient = {(j.scene, j.params) for j in jobs if j.condition == cond}
        assert ambient == local and any(s == "mondrian_shadow" for s, _ in ambient), q


def _recorder(seen):
    from pbrbench.registry import Algorithm, Registry

    def record(image, *, mask):
        seen["image"], seen["mask"] = image.copy(), mask.copy()
        return np.ones_like(image), image

    return Registry([Algorithm("record", "lightness", record, kind="plugin")])


def test_lightness_ambient_input_is_direct_plus_albedo_times_a():
    """Closed form: the input is ``direct + rho A`` with ``A`` = 0.1 x the median direct shading
    of the lit paper, and the black umbra of the cast shadow enters the domain as ``rho A``."""
    from pbrbench.tasks.lightness import TASK

    gt = mondrian_gt(shadow=True)
    umbra = gt["unoccluded_fraction"] < 1
    gt.arrays["direct"][umbra] = 0.0           # a point source's umbra is black under the local model
    direct, alb = np.asarray(gt["direct"], float)[..., 0], np.asarray(gt["albedo"], float)[..., 0]
    a = 0.1 * np.median((direct / alb)[~umbra])
    seen_local, seen_amb = {}, {}
    run_task(TASK, Job("lightness", "m", "local", (("paper_ids", (1,)),)), {"m": gt}, registry=_recorder(seen_local))
    res = run_task(TASK, Job("lightness", "m", "local+ambient0.1", (("paper_ids", (1,)),)), {"m": gt},
                   registry=_recorder(seen_amb))
    assert not seen_local["mask"][umbra].any() and seen_local["mask"][~umbra].all()
    assert seen_amb["mask"].all()               # shadows are not black: the umbra is part of the input
    assert np.allclose(seen_amb["image"], direct + alb * a, rtol=1e-6)
    assert np.allclose(seen_amb["image"][umbra], alb[umbra] * a, rtol=1e-6) and a > 0
    # scored against the condition's own shading S + A: the recorder's reflectance 1 is off by the albedo
    assert scores_of(res)[("record", "lmse")] > 0


def test_lightness_ambient_puts_the_black_shadow_into_the_input_and_the_retinex_reads_it_as_paint():
    from pbrbench.tasks.lightness import TASK

    def black_umbra():
        gt = mondrian_gt(shadow=True)
        gt.arrays["direct"][gt["unoccluded_fraction"] < 1] = 0.0
        return gt

    job = {c: Job("lightness", "m", c, (("paper_ids", (1,)),)) for c in ("local", "local+ambient0.1")}
    flat = {c: scores_of(run_task(TASK, j, {"m": mondrian_gt()})) for c, j in job.items()}
    shadow = {c: scores_of(run_task(TASK, j, {"m": black_umbra()})) for c, j in job.items()}
    # a flat Mondrian: rho (S + A) keeps every ratio across a paint edge; only the smooth shading flattens
    assert flat["local+ambient0.1"][("blake1985", "lmse")] == pytest.approx(flat["local"][("blake1985", "lmse")],
                                                                             rel=0.3)
    # the umbra, outside the domain while black, enters it with a step (S + A) / A = 11 taken for paint
    for alg in ("blake1985", "grosse2009"):
        assert shadow["local+ambient0.1"][(alg, "lmse")] > 2 * shadow["local"][(alg, "lmse")], alg


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
def test_a_draft_run_of_lightness_scores_the_ambient_condition_with_an_uncertainty(tmp_path):
    from pbrbench.bench.run import RunConfig, run_benchmark
    from pbrbench.report.html import headline_tables
    from pbrbench.tasks.lightness import TASK
    from tests.fakes import FakeSource, settings_for, with_groups

    class MondrianSource(FakeSource):
        def load(self, spec):
            gt = with_groups(mondrian_gt(shadow="shadow" in spec.name), 0.01, seed=len(spec.name))
            gt.meta["scene_hash"] = spec.content_hash()
            return gt

    o = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path), tasks={"lightness": TASK},
                      source=MondrianSource(tmp_path / "cache"), log=lambda m: None)
    assert not o.errors
    amb = [s for s in o.scores if s["condition"] == "local+ambient0.1" and s["metric"] == "lmse"]
    assert {s["scene"] for s in amb} == {"mondrian_grey", "mondrian_shadow", "mondrian_folded"}
    (h,) = headline_tables(o.scores, o.task_info)
    col = h["conditions"].index("local+ambient0.1 − local")
    cell = next(r for r in h["rows"] if r["algorithm"] == "blake1985")["cells"][col]
    assert cell["n"] == 3 and np.isfinite(cell["value"]) and np.isfinite(cell["se"]) and " ± " in cell["text"]


def test_fig_1_11_integrates_the_thresholded_log_derivative():
    """Fig 1.11 on a row of two papers under a smooth gradient: the thresholded derivative keeps
    the paint step only, and its integral is the log reflectance (the brighter paper at 0)."""
    from pbrbench.tasks.lightness import lightness_1d_figure

    x = np.arange(40)
    refl = np.where(x < 20, 0.8, 0.2)
    shading = 1.0 + 0.005 * x
    f = lightness_1d_figure(refl * shading, 3, 0.1)
    s = f["series"]
    thr = np.array(s["thresholded (|d| > 0.1)"][:-1], float)
    assert np.count_nonzero(thr) == 1 and np.isclose(thr[19], np.log(0.2 / 0.8) + np.log(shading[20] / shading[19]))
    integral = np.array(s["integral: log reflectance (brightest = 0)"], float)
    assert np.allclose(integral[:20], 0.0) and np.allclose(integral[20:], thr[19])
    assert f["x"][0] == 3 and len(f["x"]) == 40


@pytest.mark.render
def test_fig_1_22_the_texture_changes_the_radiance_not_the_shading(cache_dir):
    """The retexture scene at draft: along the middle row the two copies' shading agrees to the
    render noise (the median difference well under a tenth of their radiance's; the pixels that
    straddle a paper edge mix two albedos, and there radiance / albedo is not the shading), and
    the plot job has no score."""
    import numpy as np

    from pbrbench.quality import DRAFT
    from pbrbench.render.cache import RenderCache, ground_truth
    from pbrbench.tasks.lightness import TASK

    (job,) = [j for j in TASK.jobs(DRAFT) if j.param("plot") == "retexture"]
    gt, _ = ground_truth(TASK.scenes.spec(job.scene), DRAFT, cache=RenderCache(cache_dir))
    res = TASK.run_job(job, {job.scene: gt}, quality=DRAFT)
    assert not res.scores and sum(n.startswith("linear:Fig 1.22") for n in res.images) == 2
    (plot,) = [p for n, p in res.plots.items() if n.startswith("Fig 1.22")]
    s = plot["series"]

    def on(name, x):
        return np.interp(x, s[name]["x"], s[name]["y"])

    x = np.linspace(-0.4, 0.4, 41)
    d_shading = np.median(np.abs(on("shading, plain copy", x) - on("shading, textured copy", x)))
    d_radiance = np.median(np.abs(on("radiance, plain copy", x) - on("radiance, textured copy", x)))
    assert d_shading < 0.1 * d_radiance
