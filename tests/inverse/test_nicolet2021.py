"""Inverse rendering: input validation, the NumPy helpers, and one small render."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.inverse import METHODS, inverse_rendering_nicolet2021
from pbrbench.inverse import nicolet2021 as N
from pbrbench.scene.geometry import light_vectors
from pbrbench.scene.load import SceneLibrary


@pytest.fixture(scope="module")
def groove():
    return SceneLibrary().spec("ps_groove[albedo=0.9]")


def _inputs(spec, n=16):
    lights = light_vectors(spec)
    imgs = np.full((len(lights), n, n), 0.3)
    return imgs, lights, np.ones((n, n), bool)


def test_methods_table():
    assert METHODS == {"nicolet2021": inverse_rendering_nicolet2021}


@pytest.mark.parametrize("change, match", [
    (dict(mask=None), "mask: required"),
    (dict(mask=np.zeros((16, 16), bool)), "mask: no pixel"),
    (dict(mask=np.ones((8, 8), bool)), "mask"),
    (dict(lights=np.ones((5, 3))), r"lights: shape \(5, 3\), expected \(6, 3\)"),
    (dict(scene=None), "scene: required"),
    (dict(max_depth=1), "max_depth: 1"),
    (dict(adjoint="reparam"), "adjoint"),
    (dict(light_model="point"), "light_model"),
    (dict(levels=(3, 1), iterations=(2, 2)), "does not divide"),
    (dict(levels=(2, 2), iterations=(2, 2)), "last level must be 1"),
    (dict(levels=(2, 1), iterations=(2,)), "one iteration count per level"),
    (dict(levels=(1,), iterations=(0,)), "budget is 0"),
    (dict(spp=0), "spp"),
    (dict(smoothness=-1.0), "smoothness"),
    (dict(refine_lit=1.5), "refine_lit"),
    (dict(start=(np.zeros((3, 3)), np.zeros((16, 16)))), "start"),
])
def test_bad_inputs_raise_with_a_fix(groove, change, match):
    imgs, lights, mask = _inputs(groove)
    kw = dict(images=imgs, lights=lights, mask=mask, scene=groove)
    kw.update(change)
    with pytest.raises(ValueError, match=match):
        inverse_rendering_nicolet2021(kw.pop("images"), kw.pop("lights"), **kw)


def test_nan_in_the_images_is_refused(groove):
    imgs, lights, mask = _inputs(groove)
    imgs[0, 3, 3] = np.nan
    with pytest.raises(ValueError, match="images"):
        inverse_rendering_nicolet2021(imgs, lights, mask=mask, scene=groove)


def test_perspective_camera_is_refused():
    room = SceneLibrary().family("room_white")[0]
    lights = np.tile([0.0, 0.0, 1.0], (3, 1))
    with pytest.raises(ValueError, match="orthographic"):
        inverse_rendering_nicolet2021(np.ones((3, 16, 16)), lights, mask=np.ones((16, 16), bool), scene=room)


def test_relief_modes_are_orthogonal_and_scaled():
    x = np.linspace(-1, 1, 50)
    z = np.abs(x) + 0.1
    m = N.relief_modes(z, 3)
    assert m.shape == (3, 50)
    assert np.allclose(m.mean(axis=1), 0.0, atol=1e-12)
    gram = m @ m.T
    assert np.allclose(gram - np.diag(np.diag(gram)), 0.0, atol=1e-9)
    assert np.allclose(np.sqrt((m * m).mean(axis=1)), z.std())
    assert np.allclose(m[0], z - z.mean())                     # the first mode is the relief itself
    assert N.relief_modes(np.full(10, 2.0), 3).shape == (0, 10)  # a flat field has no relief


def test_robust_loss_is_least_squares_near_zero_and_bounded_far_out():
    data = np.ones((4, 4), bool)
    wts = np.full((4, 4), 1.0)
    r = np.zeros((2, 4, 4))
    r[0] = 0.01
    r[1, 0, 0] = 10.0                         # one outlier
    loss_ls, g_ls, _ = N._robust(r, data, wts, 0.0)
    assert loss_ls == pytest.approx(float((r * r).sum()))
    assert np.allclose(g_ls, 2 * r)
    loss_c, g_c, irls = N._robust(r, data, wts, 3.0)
    assert irls[1, 0, 0] < 1e-3 and irls[0, 0, 0] > 0.9       # the outlier is down-weighted
    assert abs(g_c[1, 0, 0]) < abs(g_ls[1, 0, 0]) * 1e-2
    assert loss_c < loss_ls


def test_albedo_scale_recovers_a_per_pixel_factor():
    rng = np.random.default_rng(0)
    R = rng.uniform(0.1, 1.0, (5, 3, 3))
    f = rng.uniform(0.5, 1.5, (3, 3))
    assert np.allclose(N._albedo_scale(R, R * f), f)


def _groove_targets(groove, n: int, seed: int):
    """Direct-light renders (n x n, 64 spp) of the true V groove ``z = |x|`` with albedo 0.9:
    ``(targets, lights, height field, true corner heights)``."""
    from pbrbench.inverse.heightfield import HeightField
    from pbrbench.inverse.render import HeightFieldScene, ad_mitsuba
    from pbrbench.inverse.scene import frame_extension, light_dicts

    mi = ad_mitsuba()
    lights = light_vectors(groove)
    hf = HeightField(np.ones((n, n), bool), groove.camera.half_width, extend=frame_extension(groove, n, n))
    x, _ = hf.corner_xy()
    z_true = np.abs(x)
    sc = HeightFieldScene(groove, hf, hf.params_from_corners(z_true), np.full((n, n), 0.9),
                          light_dicts(mi, groove, lights, "scene"), max_depth=2, spp=64)
    targets = sc.renders(seed=seed)
    del sc
    return targets, lights, hf, z_true


@pytest.mark.render
def test_small_render_recovers_a_groove_from_a_shallow_start(groove):
    """Targets rendered (direct light, 16 x 16) from the true V groove ``z = |x|`` with albedo
    0.9; from a groove half as deep with albedo 0.6 the loss falls and the normal and albedo
    errors drop."""
    from pbrbench.inverse.heightfield import pixel_normals, pixel_sets

    n = 16
    targets, lights, hf, z_true = _groove_targets(groove, n, seed=123)
    mask = np.ones((n, n), bool)
    res = inverse_rendering_nicolet2021(
        targets, lights, mask=mask, scene=groove, max_depth=2, levels=(1,), iterations=(12,), spp=8,
        spp_grad=4, relief_every=4, relief_spp=4, start=(0.5 * z_true, np.full((n, n), 0.6)), seed=1,
        lr_height=0.01)   # a far start: the large step of a coarse-to-fine schedule (the default refines)
    truth = pixel_normals(z_true, hf.h)
    data, _ = pixel_sets(mask, targets)

    def ang(nn):
        return float(np.degrees(np.arccos(np.clip((nn * truth).sum(-1), -1, 1)))[data].mean())

    assert res.loss.shape == (12,) and np.isfinite(res.loss).all()
    assert res.loss[-3:].mean() < 0.5 * res.loss[:2].mean()
    assert ang(res.normals) < 0.5 * ang(res.initial_normals)
    alb = np.pi * res.albedo[data]
    assert np.abs(alb / 0.9 - 1).mean() < 0.5 * abs(0.6 / 0.9 - 1)
    assert res.paths > 0 and res.options["variant"].endswith("_ad_rgb")
    vs = res.options["versus_start"]
    assert vs["kept_fit"] and vs["improvement"] > 2 * vs["se"]      # far better than the start: kept
    assert res.options["refined"] > 0.9                              # direct light: the pixels refitted


@pytest.mark.render
def test_a_fit_worse_than_its_start_gives_the_start_back(groove):
    """Direct-light targets of the true groove, the true surface as the start, and a height step
    far too large for it: the iterates walk away from the optimum, their data term is worse than
    the start's beyond the renders' noise, and the start is returned (with ``keep_start=0`` the
    walked-away fit is)."""
    from pbrbench.inverse.heightfield import pixel_normals

    n = 16
    targets, lights, hf, z_true = _groove_targets(groove, n, seed=5)
    mask = np.ones((n, n), bool)
    truth = pixel_normals(z_true, hf.h)

    def ang(nn):
        return float(np.degrees(np.arccos(np.clip((nn * truth).sum(-1), -1, 1))).mean())

    kw = dict(mask=mask, scene=groove, max_depth=2, iterations=(6,), spp=8, spp_grad=4, lr_height=0.05, seed=2,
              start=(z_true, np.full((n, n), 0.9)), refine_lit=0)   # the height field's own normals
    kept = inverse_rendering_nicolet2021(targets, lights, **kw)
    walked = inverse_rendering_nicolet2021(targets, lights, keep_start=0, **kw)
    vs = kept.options["versus_start"]
    assert not vs["kept_fit"] and vs["improvement"] < -2 * vs["se"]
    assert walked.options["versus_start"] is None
    assert ang(walked.normals) > 1.0, ang(walked.normals)   # the large step did walk away
    np.testing.assert_allclose(kept.normals, kept.initial_normals)   # a given start: its own normals
    assert ang(kept.normals) < 1e-6
    np.testing.assert_allclose(np.pi * kept.albedo, 0.9)


def test_direct_light_refinement_refits_each_pixel_on_the_measurements_the_shape_lights():
    """The cup's Lambertian images under 8 sources with a planted cast shadow (zero) and a
    planted half shadow (half the light) on some measurements; the shape handed to the refinement
    has normals 3 degrees off and its render holds the same shadows.  Every pixel with 3 fully
    lit measurements gets the true normal and albedo exactly; Woodham's least squares, which keeps
    the half-shadowed measurements, does not.  Half-shadowed measurements count as lit below
    ``refine_lit = 0.5``, and then the refit is biased like Woodham's."""
    from pbrbench.infer.photometric_stereo import METHODS as PS
    from pbrbench.shading.lambert import lambertian_images, ring_lights
    from pbrbench.shading.surfaces import on_grid

    s = on_grid("cup", 32, half_width=1.0)
    lights = ring_lights(8)
    true_n, alb = np.where(s.mask[..., None], s.normals, 0.0), 0.9 / np.pi
    rng = np.random.default_rng(4)
    vis = np.ones((8, 32, 32))
    vis[rng.random(vis.shape) < 0.15] = 0.0
    vis[rng.random(vis.shape) < 0.15] = 0.5
    imgs = lambertian_images(true_n, alb, lights, mask=s.mask) * vis
    tilt = np.deg2rad(3.0)
    shape_n = true_n @ np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    rho = np.full((32, 32), 0.8)          # the shape's albedo (rho, not divided by pi): also off
    rendered = (rho / np.pi)[None] * np.maximum(0.0, np.einsum("hwc,kc->khw", shape_n, lights)) * vis
    n, a, ok = N._refine_direct(imgs, lights, s.mask, shape_n, rho, rendered, 0.9)

    def ang(nn, where):
        return np.degrees(np.arccos(np.clip((nn * true_n).sum(-1), -1, 1)))[where]

    assert ok.sum() > 0.9 * s.mask.sum() and not (ok & ~s.mask).any()
    np.testing.assert_allclose(n[ok], true_n[ok], atol=1e-12)
    np.testing.assert_allclose(a[ok], alb, rtol=1e-9)
    np.testing.assert_array_equal(n[s.mask & ~ok], shape_n[s.mask & ~ok])   # not refitted: the shape's
    wood = PS["woodham1980"](imgs, lights, mask=s.mask)
    assert ang(wood.normals, ok).mean() > 1.0
    n_half, _, _ = N._refine_direct(imgs, lights, s.mask, shape_n, rho, rendered, 0.4)
    assert ang(n_half, ok).mean() > 1.0


@pytest.mark.render
def test_without_the_start_comparison_the_refit_renders_the_fit_itself(groove):
    """``keep_start=0`` (no comparison, so no render of it to reuse): the direct-light refit
    renders the fit on its own.  The height step walks the fit away from the true groove (11 degrees
    mean without the refit), yet the fit still tells which sources reach each pixel, so the refit
    recovers the true normals and albedo."""
    from pbrbench.inverse.heightfield import pixel_normals

    n = 16
    targets, lights, hf, z_true = _groove_targets(groove, n, seed=5)
    truth = pixel_normals(z_true, hf.h)
    kw = dict(mask=np.ones((n, n), bool), scene=groove, max_depth=2, iterations=(6,), spp=8, spp_grad=4,
              lr_height=0.05, seed=2, start=(z_true, np.full((n, n), 0.9)), keep_start=0)
    walked = inverse_rendering_nicolet2021(targets, lights, refine_lit=0, **kw)
    refit = inverse_rendering_nicolet2021(targets, lights, **kw)

    def ang(nn):
        return float(np.degrees(np.arccos(np.clip((nn * truth).sum(-1), -1, 1))).mean())

    assert refit.options["versus_start"] is None and walked.options["refined"] is None
    assert refit.options["refined"] > 0.9
    assert ang(walked.normals) > 1.0, ang(walked.normals)
    assert ang(refit.normals) < 0.01, ang(refit.normals)
    np.testing.assert_allclose(np.pi * refit.albedo, 0.9, rtol=1e-3)


def _cup_start(max_depth, start=None, n=32):
    """``N._start`` on the local (direct-light) images of a concave cup: Lambertian shading of the
    true normals, no interreflection."""
    from pbrbench.inverse import heightfield as HF
    from pbrbench.shading.lambert import lambertian_images, ring_lights
    from pbrbench.shading.surfaces import on_grid

    s = on_grid("cup", n, half_width=1.0)
    lights = ring_lights(8)
    imgs = lambertian_images(s.normals, 0.9 / np.pi, lights, mask=s.mask)
    data, surf = HF.pixel_sets(s.mask, imgs)
    hf = HF.HeightField(surf, 1.0)
    zc, rho, name, _ = N._start(imgs, lights, data, surf, hf, start, max_depth)
    got = HF.pixel_normals(zc, hf.h)
    err = np.degrees(np.arccos(np.clip((got * s.normals).sum(-1), -1, 1)))[data]
    return float(err.mean()), name, rho[data]


def test_the_start_follows_the_transport_of_the_images():
    # direct-light images: Woodham's start, whose integrated normals are the cup's (the height
    # field's own discretisation error only); Nayar's correction on the same images removes
    # interreflection that is not there and deepens the cup
    e_local, name_local, rho = _cup_start(max_depth=2)
    e_nayar, name_nayar, _ = _cup_start(max_depth=-1)
    assert name_local == "woodham1980" and name_nayar == "nayar1991"
    assert e_local < 2.0 and e_nayar > 2.0 * e_local
    np.testing.assert_allclose(np.median(rho), 0.9, rtol=1e-6)
    # a name chooses the method whatever the transport
    assert _cup_start(max_depth=-1, start="woodham1980")[:2] == (e_local, "woodham1980")


@pytest.mark.parametrize("bad, match", [("horn1989", "start: 'horn1989'; use one of woodham1980, nayar1991"),
                                        ((np.zeros((33, 33)),), "start: give a method name or a pair")])
def test_a_bad_start_is_refused_with_a_fix(bad, match):
    with pytest.raises(ValueError, match=match):
        _cup_start(max_depth=-1, start=bad)


def test_a_surface_too_small_for_nayars_kernel_starts_from_woodham_and_says_so():
    from pbrbench.inverse import heightfield as HF
    from pbrbench.shading.lambert import ring_lights

    lights = ring_lights(8)
    m = np.zeros((16, 16), bool)
    m[7:9, 7] = m[7, 8] = True            # three pixels: Nayar's kernel needs four facets
    imgs = np.where(m, 0.3, 0.0)[None] * lights[:, 2, None, None]
    data, surf = HF.pixel_sets(m, imgs)
    _, _, name, _ = N._start(imgs, lights, data, surf, HF.HeightField(surf, 1.0), None, -1)
    assert name.startswith("woodham1980 (nayar1991 refused: mask: the surface covers 3 facet(s)")
    with pytest.raises(ValueError, match="fewer than 4"):      # asked for by name, the refusal stands
        N._start(imgs, lights, data, surf, HF.HeightField(surf, 1.0), "nayar1991", -1)
