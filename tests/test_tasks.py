"""Benchmark tasks: the shared helpers, and each task's jobs and run_job on synthetic ground truths
built in NumPy (no renderer), plus one draft-quality render through the photometric-stereo task."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.render.groundtruth import GroundTruth
from pbrbench.scene import spec as S
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.mondrian import cast_shadow, mondrian_scene
from pbrbench.shading.surfaces import on_grid
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult

HW = 1.05
FIVE = np.array([[0, 0, 1], [0.6, 0, 0.8], [-0.6, 0, 0.8], [0, 0.6, 0.8], [0, -0.6, 0.8]], float)


# ------------------------------------------------------------------------ synthetic ground truths
def ps_gt(surface="sphere", size=40, albedo=0.6, lights=FIVE, gi_gain=1.0):
    """Per-light Lambertian radiance images (E = pi) of an analytic surface; ``radiance`` passes are
    the direct ones times ``gi_gain`` (a stand-in for interreflection inflating brightness)."""
    s = on_grid(surface, size, HW)
    vec = np.asarray(lights, float) * np.pi
    imgs = lambertian_images(s.normals, albedo, vec, mask=s.mask, radiance=True)
    arr = {}
    for k in range(len(vec)):
        im = np.repeat(imgs[k][..., None], 3, -1).astype(np.float32)
        arr[f"light{k:02d}.direct"] = im
        arr[f"light{k:02d}.radiance"] = (im * gi_gain).astype(np.float32)
    arr["direct"] = sum(arr[f"light{k:02d}.direct"] for k in range(len(vec)))
    arr["radiance"] = arr["direct"] * gi_gain
    arr["normals"] = s.normals.astype(np.float32)
    arr["albedo"] = np.repeat(np.where(s.mask, albedo, 0.0)[..., None], 3, -1).astype(np.float32)
    arr["depth"] = np.where(s.mask, 5.0 - s.z, 0.0).astype(np.float32)
    arr["mask"] = s.mask.astype(np.float32)
    return GroundTruth(arr, {"scene_hash": f"synthetic-{surface}", "n_light_set": len(vec)}), vec


def ps_job(cond="local", lights=None, scene="s", **extra):
    lights = FIVE * np.pi if lights is None else lights
    return Job("photometric_stereo", scene, cond,
               (("lights", C.as_param(lights)), ("half_width", HW)) + tuple(extra.items()))


def mondrian_gt(size=64, colour=False, shadow=False):
    d = mondrian_scene(size, seed=0, colour=colour, shadow=shadow, n_patches=12)
    img, alb = d["image"], d["albedo"]
    if img.ndim == 2:
        img, alb = np.repeat(img[..., None], 3, -1), np.repeat(alb[..., None], 3, -1)
    arr = {"radiance": img.astype(np.float32), "direct": img.astype(np.float32),
           "albedo": alb.astype(np.float32), "mask": np.ones((size, size), np.float32),
           "object_id": np.ones((size, size), np.float32)}
    if shadow:
        arr["unoccluded_fraction"] = cast_shadow(size).astype(np.float32)
    return GroundTruth(arr, {"scene_hash": "synthetic-mondrian"})


def sfs_gt(size=32, light=(0.7071, 0.0, 0.7071), albedo=0.8):
    s = on_grid("sphere", size, HW)
    L = np.asarray(light, float) / np.linalg.norm(light)
    img = np.where(s.mask, np.clip(s.normals @ L, 0, None) * albedo, 0.0)  # rho E cos / pi, E = pi
    im3 = np.repeat(img[..., None], 3, -1).astype(np.float32)
    arr = {"light00.direct": im3, "light00.radiance": im3 * 1.1, "direct": im3, "radiance": im3,
           "normals": s.normals.astype(np.float32),
           "albedo": np.repeat(np.where(s.mask, albedo, 0.0)[..., None], 3, -1).astype(np.float32),
           "depth": np.where(s.mask, 5.0 - s.z, 0.0).astype(np.float32), "mask": s.mask.astype(np.float32)}
    job = Job("sfs", "sfs_sphere", "local",
              (("light", C.as_param(L)), ("irradiance", np.pi), ("light_index", 0), ("label", "oblique"),
               ("half_width", HW), ("draft", True)))
    return GroundTruth(arr, {"scene_hash": "synthetic-sfs", "n_light_set": 1}), job


def hdr_gt(size=24):
    rng = np.random.default_rng(0)
    ramp = 1e-3 * 10 ** (4 * np.linspace(0, 1, size))[None, :] * np.ones((size, 1))
    rad = (ramp[..., None] * rng.uniform(0.5, 1.0, (size, size, 3))).astype(np.float32)
    return GroundTruth({"radiance": rad, "direct": rad, "mask": np.ones((size, size), np.float32)},
                       {"scene_hash": "synthetic-hdr"})


def specular_gt(size=64):
    s = on_grid("sphere", size, 1.1)
    L = np.array([0.5, 0.5, 0.7071])
    L /= np.linalg.norm(L)
    H = (L + [0, 0, 1]) / np.linalg.norm(L + [0, 0, 1])
    diffuse = np.where(s.mask[..., None], np.clip(s.normals @ L, 0, None)[..., None] * [0.54, 0.3, 0.18], 0.0)
    spec = np.where(s.mask, 2.0 * np.clip(s.normals @ H, 0, None) ** 200, 0.0)
    arr = {"radiance": (diffuse + spec[..., None]).astype(np.float32), "diffuse_only": diffuse.astype(np.float32),
           "mask": s.mask.astype(np.float32)}
    return GroundTruth(arr, {"scene_hash": "synthetic-specular"})


def scores_of(res: JobResult) -> dict:
    return {(s.algorithm, s.metric): s.value for s in res.scores}


# ----------------------------------------------------------------------------------- helpers
def test_nominal_light_directional_area_point():
    cam = S.Camera()
    d, e = C.nominal_light(S.Directional(type="directional", direction=(0, 3, 4), irradiance=2.0), cam)
    assert np.allclose(d, [0, 0.6, 0.8]) and e == pytest.approx(2.0)
    area = S.AreaRect(type="area", center=(0, 0, 4), size=(1.0, 0.5), normal=(0, 0, -1), radiance=8.0)
    d, e = C.nominal_light(area, cam)
    assert np.allclose(d, [0, 0, 1]) and e == pytest.approx(8.0 * 0.5 / 16)
    tilted = S.AreaRect(type="area", center=(3, 0, 0), size=(1.0, 1.0), normal=(-1, 1, 0), radiance=1.0)
    d, e = C.nominal_light(tilted, cam)
    assert np.allclose(d, [1, 0, 0]) and e == pytest.approx(np.cos(np.pi / 4) / 9)
    d, e = C.nominal_light(S.Point(type="point", position=(0, 2, 0), intensity=4.0), cam)
    assert np.allclose(d, [0, 1, 0]) and e == pytest.approx(1.0)
    with pytest.raises(ValueError, match="no direction"):
        C.nominal_light(S.Ambient(type="ambient"), cam)


def test_light_vectors_in_a_rotated_camera_frame():
    # camera on +x looking at the origin: a source on +x is along the view (camera z)
    cam = S.Camera(origin=(5, 0, 0), up=(0, 1, 0))
    R = C.camera_rotation(cam)
    assert np.allclose(R @ R.T, np.eye(3))
    assert np.allclose(R @ [1, 0, 0], [0, 0, 1]) and np.allclose(R @ [0, 1, 0], [0, 1, 0])
    assert np.allclose(R @ [0, 0, -1], [1, 0, 0])  # world -z is to the camera's right
    spec = S.SceneSpec(name="t", description="t", camera=cam, shapes=({"type": "sphere"},),
                       light_set=({"type": "directional", "direction": (1, 0, 0), "irradiance": 3.0},
                                  {"type": "directional", "direction": (0, 1, 0), "irradiance": 1.0}))
    v = C.light_vectors(spec)
    assert np.allclose(v, [[0, 0, 3], [0, 1, 0]])


def test_parse_condition_sweep_value_subsample():
    assert C.parse_condition("local") == ("local", {})
    assert C.parse_condition("local+noise0.01") == ("local", {"noise": 0.01})
    assert C.parse_condition("global+readnoise0.002+3x3stops") == ("global", {"readnoise": 0.002, "3x3stops": 1.0})
    assert C.sweep_value("ps_cup[albedo=0.3]", "albedo") == 0.3
    assert C.sweep_value("ps_cup", "albedo") is None
    assert C.subsample([1, 2, 3, 4, 5], 2) == [1, 5]
    assert C.subsample([1, 2, 3, 4, 5], 3) == [1, 3, 5]
    assert C.subsample([1, 2], 5) == [1, 2]


def test_noise_is_deterministic_and_scaled():
    job = Job("t", "s", "local+noise0.01")
    img = np.full((200, 200), 0.5)
    img[0, 0] = 2.0
    a = C.add_noise(img, 0.01, C.job_rng(job, 0))
    b = C.add_noise(img, 0.01, C.job_rng(job, 0))
    c = C.add_noise(img, 0.01, C.job_rng(job, 1))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.std(a - img) == pytest.approx(0.02, rel=0.05)  # 1 % of the peak (2.0)
    assert np.array_equal(C.add_noise(img, 0.0, C.job_rng(job, 0)), img)


def test_display_helpers_shrink_and_keep_nan():
    a = np.arange(300 * 200, dtype=float).reshape(300, 200)
    assert C.display(a).shape == (100, 66) and C.display(a).dtype == np.float32
    m = np.zeros((4, 4), bool)
    m[:2, :2] = True
    d = C.display_map(np.ones((4, 4)), m, max_size=2)
    assert d[0, 0] == 1 and np.isnan(d[1, 1])
    n = C.normals_display(np.dstack([np.zeros((4, 4)), np.zeros((4, 4)), np.ones((4, 4))]), m)
    assert np.allclose(n[0, 0], [0.5, 0.5, 1.0]) and np.allclose(n[3, 3], 0)


# ------------------------------------------------------------------------- photometric stereo
def test_ps_local_exact_and_naive_baseline_biased():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt()
    res = TASK.run_job(ps_job(lights=vec), {"s": gt})
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
    a = scores_of(TASK.run_job(job, {"s": gt}, seed=3))
    b = scores_of(TASK.run_job(job, {"s": gt}, seed=3))
    c = scores_of(TASK.run_job(job, {"s": gt}, seed=4))
    assert a == b and a != c
    assert 0.1 < a[("woodham1980", "normal_mean_deg")] < 5
    assert ("integrate:lsq", "height_rmse") not in a  # the integration floor is scored once, under local


def test_ps_global_inflation_shows_in_absolute_albedo_only():
    from pbrbench.tasks.photometric_stereo import TASK

    gt, vec = ps_gt(gi_gain=1.25)
    sc = scores_of(TASK.run_job(ps_job("global", lights=vec), {"s": gt}))
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
    interior = C.erode(gt.mask, 1) & (lit.sum(0) >= 3) & ~coplanar
    assert np.all(dom[interior]) and np.all((cos > 0.049).sum(0)[dom] >= 3)
    sc = scores_of(TASK.run_job(ps_job(lights=four * np.pi), {"s": gt}))
    assert sc[("woodham1980", "normal_mean_deg")] < 0.01 and sc[("woodham1980", "coverage")] == 1.0
    assert not np.any(dom & (gt["mask"] < 0.5))


def test_ps_albedo_sweep_plot_job():
    from pbrbench.tasks.photometric_stereo import TASK

    gts = {}
    for a in (0.1, 0.9):
        gts[f"ps_cup[albedo={a:g}]"], vec = ps_gt("cup", albedo=a, gi_gain=1 + a / 2)
    job = Job("photometric_stereo", "ps_cup[albedo=0.9]", "global",
              (("plot", "albedo_sweep"), ("lights", C.as_param(vec)), ("half_width", HW)),
              extra_scenes=("ps_cup[albedo=0.1]",))
    res = TASK.run_job(job, gts)
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
    res = TASK.run_job(job, gts)
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
    monkeypatch.setenv("PBRBENCH_SCENES", str(tmp_path))
    task = PhotometricStereoTask()
    task.families = ("ps_cup", "missing_family")
    task.draft_families = ("ps_cup",)
    jobs = task.jobs("standard")
    conds = {(j.scene, j.condition) for j in jobs if j.param("plot") is None}
    assert ("ps_cup[albedo=0.5]", "local+noise0.01") in conds and ("ps_cup_area[albedo=0.5]", "area") in conds
    assert len(conds) == 3 * 4
    area_job = next(j for j in jobs if j.condition == "area")
    v = np.asarray(area_job.param("lights"))
    assert np.allclose(np.linalg.norm(v, axis=1), 16.0 / 16.0)  # L A / d^2, equal for all
    assert np.allclose(v / np.linalg.norm(v, axis=1, keepdims=True),
                       dirs / np.linalg.norm(dirs, axis=1, keepdims=True), atol=1e-5)
    sweep_jobs = [j for j in jobs if j.param("plot") == "albedo_sweep"]
    assert len(sweep_jobs) == 1 and len(sweep_jobs[0].extra_scenes) == 2
    draft = task.jobs("draft")
    assert {j.scene for j in draft if j.condition == "local"} == {"ps_cup[albedo=0.1]", "ps_cup[albedo=0.9]"}
    assert len({j.key for j in jobs}) == len(jobs)


# ----------------------------------------------------------------------------------- lightness
def test_lightness_retinex_beats_baselines_and_anchor_rules_differ():
    from pbrbench.tasks.lightness import TASK

    res = TASK.run_job(Job("lightness", "m", "local", (("paper_ids", (1,)),)), {"m": mondrian_gt()})
    sc = scores_of(res)
    for alg in ("retinex:brightest", "retinex:mean"):
        assert sc[(alg, "lmse")] < 0.1 * sc[("baseline:image_is_reflectance", "lmse")]
        assert sc[(alg, "lmse")] < 0.1 * sc[("baseline:uniform_reflectance", "lmse")]
    # same decomposition up to scale, different constants of integration
    assert sc[("retinex:mean", "lmse")] == pytest.approx(sc[("retinex:brightest", "lmse")], rel=1e-6)
    assert sc[("retinex:mean", "albedo_abs_err")] != pytest.approx(sc[("retinex:brightest", "albedo_abs_err")], rel=0.1)
    assert sc[("retinex:brightest,subtract", "ratio_err_max")] < 0.02
    assert ("baseline:uniform_reflectance", "ratio_err_max") not in sc
    (plot,) = res.plots.values()
    assert plot["note"] == "middle row" and len(plot["x"]) == 64


def test_lightness_cast_shadow_is_the_failure_and_is_profiled():
    from pbrbench.tasks.lightness import TASK

    job = Job("lightness", "m", "local", (("paper_ids", (1,)),))
    clean = scores_of(TASK.run_job(job, {"m": mondrian_gt()}))
    res = TASK.run_job(job, {"m": mondrian_gt(shadow=True)})
    shadow = scores_of(res)
    assert shadow[("retinex:brightest", "lmse")] > 10 * clean[("retinex:brightest", "lmse")]
    (plot,) = res.plots.values()
    frac = np.array(plot["series"]["unoccluded fraction"], float)
    assert plot["note"] == "row crossing the cast shadow" and frac.min() < 0.5 < frac.max()


def test_lightness_colour_keeps_channels():
    from pbrbench.tasks.lightness import TASK

    res = TASK.run_job(Job("lightness", "m", "global", (("paper_ids", (1,)),)), {"m": mondrian_gt(colour=True)})
    assert res.images["reflectance: truth"].shape[-1] == 3
    assert scores_of(res)[("retinex:brightest,subtract", "lmse")] < 1e-3


def test_lightness_scores_only_the_paper():
    from pbrbench.tasks.lightness import TASK

    job = Job("lightness", "m", "local", (("paper_ids", (1,)),))
    ref = scores_of(TASK.run_job(job, {"m": mondrian_gt()}))
    gt = mondrian_gt()
    gt.arrays["object_id"][:6, :6] = 2  # another object (an occluder seen by the camera)
    gt.arrays["direct"][:6, :6] = 50.0
    gt.arrays["albedo"][:6, :6] = 0.02
    sc = scores_of(TASK.run_job(job, {"m": gt}))
    assert sc[("retinex:brightest", "lmse")] < 3 * ref[("retinex:brightest", "lmse")]
    wrong = scores_of(TASK.run_job(Job("lightness", "m", "local", (("paper_ids", (1, 2)),)), {"m": gt}))
    assert wrong[("retinex:brightest", "albedo_abs_err")] > 2 * sc[("retinex:brightest", "albedo_abs_err")]


def test_lightness_labels():
    from pbrbench.tasks.lightness import patch_labels

    a = np.array([[0.1, 0.1, 0.5], [0.9, 0.5, 0.5]])
    lab = patch_labels(a, np.array([[True, True, True], [True, True, False]]))
    assert lab[0, 0] == lab[0, 1] != lab[0, 2] and lab[1, 1] == lab[0, 2] and lab[1, 2] == -1


# ------------------------------------------------------------------------------------------ sfs
def test_sfs_methods_references_labels_and_conditions():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    res = TASK.run_job(job, {"sfs_sphere": gt})
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
    (plot,) = res.plots.values()
    assert {"truth", "baseline:flat", "floor:integrate_true_normals", "horn1989"} <= set(plot["series"])
    # 'global' reads light00.radiance (x1.1 here: the known albedo is violated) and skips the
    # estimated-light variants
    glob = scores_of(TASK.run_job(Job(job.task, job.scene, "global", job.params), {"sfs_sphere": gt}))
    assert not any("+estimated_light" in a for a, _ in glob)
    assert glob[("kimmel2001", "normal_mean_deg")] > sc[("kimmel2001", "normal_mean_deg")]


def test_sfs_a_refused_input_is_scored_as_a_failure():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    # a nominal light behind the surface (z < 0): every method refuses it (ValueError) and is
    # scored failed = 1 with no other score; the two references are still scored
    params = tuple((k, (0.7, 0.0, -0.1) if k == "light" else v) for k, v in job.params)
    sc = scores_of(TASK.run_job(Job(job.task, job.scene, "local+noise0", params), {"sfs_sphere": gt}))
    for m in ("horn1989", "tsai_shah1994", "pentland1990", "kimmel2001"):
        assert sc[(m, "failed")] == 1.0 and (m, "height_rmse") not in sc
    assert ("baseline:flat", "normal_mean_deg") in sc and ("floor:integrate_true_normals", "height_rmse") in sc


def test_sfs_kimmel2001_without_singular_point_is_scored():
    from pbrbench.tasks.sfs import TASK

    gt, job = sfs_gt()
    # a nominal irradiance 30 % too high: the normalised image never reaches 1; fast marching
    # seeds the brightest pixels (it used to refuse the input) and beats the flat surface
    params = tuple((k, np.pi * 1.3 if k == "irradiance" else v) for k, v in job.params)
    sc = scores_of(TASK.run_job(Job(job.task, job.scene, "local+noise0", params), {"sfs_sphere": gt}))
    assert sc[("kimmel2001", "failed")] == 0.0
    assert sc[("kimmel2001", "normal_mean_deg")] < sc[("baseline:flat", "normal_mean_deg")]


# ------------------------------------------------------------------------------------------ hdr
def test_hdr_camera_conditions():
    from pbrbench.tasks.hdr import camera_setup

    rad = np.geomspace(1e-3, 10, 1000)
    cam, t = camera_setup("global+3x3stops", rad)
    assert len(t) == 3 and np.allclose(t[1:] / t[:-1], 8)
    cam, t = camera_setup("global+noise0", rad)
    assert np.allclose(t[1:] / t[:-1], 2) and cam.read_noise == 0 and cam.full_well is None
    cam, _ = camera_setup("global+readnoise0.002", rad)
    assert cam.read_noise == 0.002 and cam.full_well is not None


def test_hdr_true_response_floor_beats_ignoring_the_response():
    from pbrbench.tasks.hdr import TASK

    res = TASK.run_job(Job("hdr", "hdr_scene", "global+noise0"), {"hdr_scene": hdr_gt()})
    sc = scores_of(res)
    assert sc[("floor:true_response", "log2_rmse")] < 0.05
    assert sc[("baseline:ignore_response", "log2_rmse")] > 2 * sc[("floor:true_response", "log2_rmse")]
    for alg in ("debevec1997", "robertson2003", "mitsunaga1999"):
        assert sc[(alg, "invalid_fraction")] == 0 and np.isfinite(sc[(alg, "log2_rmse")])
        assert sc[(alg, "response_rmse")] < sc[("baseline:ignore_response", "response_rmse")]
    plot = res.plots["inverse response (green channel)"]
    assert len(plot["x"]) == 256 and {"true", "debevec1997", "baseline:ignore_response"} <= set(plot["series"])


# ------------------------------------------------------------------------------------- specular
def test_specular_removal_beats_no_removal():
    from pbrbench.tasks.specular import TASK

    res = TASK.run_job(Job("specular", "s", "global"), {"s": specular_gt()})
    sc = scores_of(res)
    assert sc[("harmonic", "mask_iou")] > 0.5 and sc[("baseline:no_removal", "mask_iou")] == 0
    for alg in ("harmonic", "biharmonic", "harmonic+true_mask"):
        assert sc[(alg, "inside_rel")] < 0.1 * sc[("baseline:no_removal", "inside_rel")]
    assert ("harmonic+true_mask", "mask_iou") not in sc


# ------------------------------------------------------------------------- jobs of every task
def test_every_task_lists_unique_jobs_of_its_conditions():
    from pbrbench.tasks import get_tasks

    for name, task in get_tasks().items():
        assert task.name == name and task.headline_metric and task.algorithms
        jobs = task.jobs("draft")
        assert len({j.key for j in jobs}) == len(jobs)
        for j in jobs:
            assert j.task == name and j.condition.split("+")[0] in ("local", "area", "global")
            assert all(isinstance(hash(v), int) for _, v in j.params)
        if name == "sfs" and jobs:
            assert {j.param("label") for j in jobs} == {"view", "oblique"}
        if jobs:
            assert {j.condition for j in jobs if j.param("plot") is None} <= set(task.conditions)


# ------------------------------------------------------------------------------- a real render
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
    gt = render_ground_truth(spec, "draft")  # 32 x 32, 4 spp
    job = Job("photometric_stereo", spec.name, "local", TASK._params(spec))
    sc = scores_of(TASK.run_job(job, {spec.name: gt}))
    assert sc[("woodham1980", "normal_mean_deg")] < 1.0
    assert sc[("woodham1980", "albedo_rel_err")] < 0.02
    assert sc[("baseline:naive_lstsq_all_lights", "normal_mean_deg")] > sc[("woodham1980", "normal_mean_deg")]
