"""Photometric stereo that undoes interreflection (Nayar, Ikeuchi & Kanade 1991)
(pbrbench.infer.photometric_stereo.nayar1991 and its facet kernel, ._interreflection).

Known answers: the kernel of the inside of a sphere is the constant ``A_j / (4 pi R^2)``; images
made with interreflection by the facet model (``_interreflection.interreflect``) of a V groove
and of a concave spherical cap are inverted to machine precision; a convex surface has no
interreflection, so the method is Woodham's bit for bit.
"""

import numpy as np
import pytest

from pbrbench.infer.photometric_stereo import (
    METHODS,
    photometric_stereo_nayar1991,
    photometric_stereo_woodham1980,
    solve_photometric_stereo,
)
from pbrbench.infer.photometric_stereo import _interreflection as ir
from pbrbench.infer.photometric_stereo.nayar1991 import InterreflectionResult
from pbrbench.shading.lambert import lambertian_images, ring_lights
from pbrbench.shading.surfaces import on_grid
from tests.infer.photometric_stereo._data import CHAPTER_LIGHTS, ang

# six sources high enough that no point of the test surfaces is shadowed or grazing-lit; the
# irradiance pi makes the radiance images rho N.S
LIGHTS = ring_lights(6, elevations=(65.0, 75.0)) * np.pi


def _cap(size, radius=1.5, rim=0.45):
    """A concave spherical cap of radius ``radius`` seen whole: the mask is a disc of
    ``rim * size`` pixels (the cup surface cut off below its rim, nothing outside)."""
    s = on_grid("cup", size, half_width=1.05, radius=radius)
    x, y = np.meshgrid(np.arange(size), np.arange(size))
    m = s.mask & (np.hypot(x - size / 2 + 0.5, y - size / 2 + 0.5) < rim * size)
    return s.normals * m[..., None], m


def _groove(size, slope=0.6, extent=2.0):
    """A V groove ``z = slope |x|``; ``extent`` > 1.05: it fills the view (touches every border)."""
    s = on_grid("groove", size, half_width=1.05, slope=slope, extent=extent)
    return s.normals, s.mask


def _render(normals, mask, rho, block, pad, lights=LIGHTS):
    direct = lambertian_images(normals, rho, lights, mask=mask, radiance=True)
    rho_map = np.broadcast_to(np.asarray(rho, float), mask.shape + np.shape(rho)).copy()
    return direct, ir.interreflect(direct, normals, rho_map, mask, block=block, pad=pad)


def test_registered_and_dispatched():
    assert METHODS["nayar1991"] is photometric_stereo_nayar1991
    n, m = _groove(32)
    _, imgs = _render(n, m, 0.6, 4, 0.5)
    a = solve_photometric_stereo(imgs, LIGHTS, method="nayar1991", mask=m, block=4)
    b = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=4)
    assert isinstance(a, InterreflectionResult)
    np.testing.assert_array_equal(a.normals, b.normals)


def test_kernel_of_a_sphere_interior_is_constant():
    # two points on the inside of a sphere: cos(theta_i) = cos(theta_j) = r / (2R), so
    # cos cos / (pi r^2) = 1 / (4 pi R^2) for every pair (the facet model's point form factor)
    size, radius = 96, 1.5
    n, m = _cap(size, radius=radius, rim=0.45)
    f = ir.build_facets(n, m, 4, 0.0)
    k = ir.kernel(f)
    r_px = radius * size / 2.1
    expect = f.area[None, :] / (4 * np.pi * r_px ** 2)
    off = ~np.eye(f.n, dtype=bool)
    rel = k[off] / np.broadcast_to(expect, k.shape)[off]
    assert f.src_pos.shape[0] == f.n  # the disc touches no border: nothing is continued
    assert np.median(rel) == pytest.approx(1.0, abs=0.01)
    assert np.percentile(np.abs(rel - 1), 95) < 0.03
    # the facets lie on the sphere: the heights come from integrating the normals
    c = np.array([size / 2, -size / 2, f.pos[:, 2].max() + r_px])
    c[2] = np.mean(f.pos[:, 2] + np.sqrt(r_px ** 2 - ((f.pos[:, :2] - c[:2]) ** 2).sum(1)))
    dist = np.linalg.norm(f.pos - c, axis=1)
    assert np.abs(dist - r_px).max() < 0.02 * r_px


def test_convex_surface_has_no_interreflection_and_is_woodhams_result():
    s = on_grid("sphere", 96, half_width=1.05)
    imgs = lambertian_images(s.normals, 0.7, CHAPTER_LIGHTS, mask=s.mask)
    w = photometric_stereo_woodham1980(imgs, CHAPTER_LIGHTS, mask=s.mask)
    r = photometric_stereo_nayar1991(imgs, CHAPTER_LIGHTS, mask=s.mask)
    assert r.iterations == 1 and np.all(r.interreflection == 0.0)
    for name in ("normals", "albedo", "residual", "n_used", "valid"):
        np.testing.assert_array_equal(getattr(r, name), getattr(w, name))


@pytest.mark.parametrize("shape, block, pad", [("groove", 2, 0.5), ("groove", 4, 0.0), ("cap", 2, 0.5)])
def test_inverts_its_own_forward_model_exactly(shape, block, pad):
    n, m = _groove(40) if shape == "groove" else _cap(40)
    rho = 0.8
    direct, imgs = _render(n, m, rho, block, pad)
    share = (imgs - direct)[:, m].sum() / imgs[:, m].sum()
    assert share > 0.08  # a strong interreflection: 9-11 % of the light
    w = photometric_stereo_woodham1980(imgs, LIGHTS, mask=m)
    assert ang(w.normals, n)[m].mean() > 1.5  # the local solve is biased (the pseudo shape)
    assert np.abs(np.pi * w.albedo[m] / rho - 1).mean() > 0.05
    r = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=block, pad=pad, max_iter=60, tol=1e-9)
    assert r.valid[m].all() and r.changes[-1] < 1e-9 and r.iterations < 60
    assert ang(r.normals, n)[m].max() < 1e-8
    np.testing.assert_allclose(np.pi * r.albedo[m], rho, rtol=1e-10)
    np.testing.assert_allclose(r.interreflection[:, m], (imgs - direct)[:, m], atol=1e-10)
    # the plain iteration (no Anderson mixing) reaches the same fixed point, in more steps
    r0 = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=block, pad=pad, max_iter=200, tol=1e-9, history=0)
    assert ang(r0.normals, n)[m].max() < 1e-7 and r0.iterations > r.iterations


def test_colour_albedo_per_channel():
    n, m = _cap(32)
    rho = np.broadcast_to(np.array([0.8, 0.5, 0.2]), m.shape + (3,)).copy()
    direct = lambertian_images(n, rho, LIGHTS, mask=m, radiance=True)
    imgs = ir.interreflect(direct, n, rho, m, block=2, pad=0.5)
    r = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=2, max_iter=60, tol=1e-9)
    assert r.albedo.shape == m.shape + (3,) and r.interreflection.shape == imgs.shape
    assert ang(r.normals, n)[m].max() < 1e-7
    np.testing.assert_allclose(np.pi * r.albedo[m], rho[m], rtol=1e-8)


def test_continuation_across_the_borders_a_groove_crosses():
    # the groove z = |x| fills the view: its crease crosses the top and bottom borders unchanged
    # and is continued there; its faces climb across the left and right borders and end there
    n, m = _groove(64, slope=1.0)
    f = ir.build_facets(n, m, 4, 0.5)
    extra = f.src_pos[f.n:]
    assert extra.shape[0] == 2 * 16 * 8  # 16 columns x 8 facets above and below
    assert np.all((extra[:, 1] > 0) | (extra[:, 1] < -64)) and np.all((extra[:, 0] > 0) & (extra[:, 0] < 64))
    # with it the border rows receive nearly as much as the middle row (the groove is
    # translation invariant in y); without it about a fifth less
    for pad, lo in ((0.5, 0.93), (0.0, 0.6)):
        g = ir.kernel(ir.build_facets(n, m, 4, pad)).sum(axis=1).reshape(16, 16)
        edge, middle = g[0].mean(), g[8].mean()
        assert lo < edge / middle < (1.0 if pad else 0.85)
    # a bumpy surface is not continued (its normals change across the border)
    b = on_grid("bumps", 64, half_width=1.05, extent=1.1)
    fb = ir.build_facets(b.normals, b.mask, 4, 0.5)
    assert fb.src_pos.shape[0] < fb.n + 0.6 * 4 * 16 * 8


def test_fewer_than_three_lights():
    n, m = _groove(16)
    imgs = lambertian_images(n, 0.5, LIGHTS[:2], mask=m, radiance=True)
    with pytest.raises(ValueError, match="at least 3 lights"):
        photometric_stereo_nayar1991(imgs, LIGHTS[:2], mask=m)


def test_nan_inside_the_mask():
    n, m = _groove(16)
    imgs = lambertian_images(n, 0.5, LIGHTS, mask=m, radiance=True)
    imgs[2, 5, 5] = np.nan
    with pytest.raises(ValueError, match="images: 1 non-finite"):
        photometric_stereo_nayar1991(imgs, LIGHTS, mask=m)
    ok = m.copy()
    ok[5, 5] = False  # outside the mask it is ignored
    photometric_stereo_nayar1991(imgs, LIGHTS, mask=ok, block=2)


def test_mask_of_too_few_facets():
    n, m = _groove(32)
    imgs = lambertian_images(n, 0.5, LIGHTS, mask=m, radiance=True)
    small = np.zeros_like(m)
    small[4:8, 4:12] = True  # two facets of 4 x 4
    with pytest.raises(ValueError, match="covers 2 facet"):
        photometric_stereo_nayar1991(imgs, LIGHTS, mask=small, block=4)
    r = photometric_stereo_nayar1991(imgs, LIGHTS, mask=small, block=1)  # 32 facets of one pixel
    assert r.n_facets == 32


def test_pseudo_albedo_above_one_is_clipped_in_the_kernel():
    # images 3x too bright: the pseudo reflectance pi * albedo ~ 3 > 1; the kernel uses
    # max_reflectance instead, so the removed light scales with it exactly
    n, m = _cap(32)
    _, imgs = _render(n, m, 0.8, 2, 0.5)
    imgs = 3.0 * imgs
    a = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=2, max_iter=1)
    b = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=2, max_iter=1, max_reflectance=0.5)
    np.testing.assert_allclose(b.interreflection, a.interreflection * 0.5 / 0.99, rtol=1e-12)
    full = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, block=2)
    assert np.isfinite(full.normals).all() and np.isfinite(full.albedo).all()
    assert full.valid[m].all() and np.pi * full.albedo[m].min() > 1.0  # returned unclipped


@pytest.mark.parametrize("opt, val, msg", [("block", 0, "block"), ("pad", 1.5, "pad"), ("max_iter", -1, "max_iter"),
                                           ("tol", 0.0, "tol"), ("history", 1.5, "history"),
                                           ("ir_shadow_threshold", 1.0, "ir_shadow_threshold"),
                                           ("albedo_scale", -1.0, "albedo_scale"),
                                           ("max_reflectance", 1.2, "max_reflectance")])
def test_bad_options(opt, val, msg):
    n, m = _groove(16)
    imgs = lambertian_images(n, 0.5, LIGHTS, mask=m, radiance=True)
    with pytest.raises(ValueError, match=msg):
        photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, **{opt: val})


def test_no_correction_is_the_local_solve():
    n, m = _groove(32)
    _, imgs = _render(n, m, 0.6, 4, 0.5)
    r = photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, max_iter=0)
    w = photometric_stereo_woodham1980(imgs, LIGHTS, mask=m)
    assert r.iterations == 0 and r.n_facets == 0
    np.testing.assert_array_equal(r.normals, w.normals)
    np.testing.assert_array_equal(r.albedo, w.albedo)


# -------------------------------------------------------------------------- the premise test
A60 = np.tan(np.radians(60.0))   # a deep V groove: faces 60 degrees from the image plane
# two sources across the groove at 45 degrees elevation (each shadows the far face and part of the
# near one), two along it (no shadow) and two across it at 70 degrees (above the faces: no shadow)
SHADOW_LIGHTS = np.pi * np.array([[np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]
                                  for a, e in np.radians([(0, 45), (180, 45), (90, 45), (270, 45), (0, 70), (180, 70)])])


def _groove60_direct(size, rho):
    """Direct images of ``z = tan(60 deg) |x|`` filling the view under :data:`SHADOW_LIGHTS`, cast
    shadows from the closed form: a source across the groove (ground track along +x or -x, height
    per unit of x travel ``t``) shadows the near face's points within ``X (a - t) / (a + t)`` of the
    crease (the ray meets the far face at ``x* = |x0| (a + t) / (a - t)``, which must lie inside the
    view, ``x* <= X`` at the last pixel centre)."""
    n, m = _groove(size, slope=A60)
    direct = lambertian_images(n, rho, SHADOW_LIGHTS, mask=m, radiance=True)
    x = np.arange(size) + 0.5 - size / 2                     # pixel centres, crease at 0 (pixel units)
    X = size / 2 - 0.5
    cast = np.zeros((len(SHADOW_LIGHTS), size, size), bool)
    for k, s in enumerate(SHADOW_LIGHTS / np.pi):
        if abs(s[0]) < 1e-9:
            continue
        t = s[2] / abs(s[0])
        if t < A60:
            near = (x < 0) if s[0] > 0 else (x > 0)
            cast[k] = (near & (np.abs(x) <= X * (A60 - t) / (A60 + t)))[None, :]
    return n, m, np.where(cast, 0.0, direct), cast


def test_shadowed_matches_the_closed_form_of_a_deep_groove():
    size = 64
    n, m, _, cast = _groove60_direct(size, 0.5)
    sh = ir.shadowed(n, m, SHADOW_LIGHTS / np.pi)
    attached = np.einsum("hwc,kc->khw", n, SHADOW_LIGHTS) <= 0
    assert attached[0].sum() == size * size // 2 and attached[2].sum() == 0   # the far face; none along the groove
    for k in range(len(SHADOW_LIGHTS)):
        assert np.all(sh[k][attached[k]])                                     # attached shadows are in
        got, want = (sh[k] & ~attached[k]).sum(axis=1), cast[k].sum(axis=1)  # cast pixels per row
        assert np.all(np.abs(got - want) <= 1), (k, got[:3], want[:3])
    assert cast[0].sum() > 5 * size                   # the test has cast shadows to find (7 columns)
    assert not sh[2:].any() and not sh[4:].any()      # sources along the groove or above the faces: none


def _marched_everywhere(normals, used, lights, margin=0.25):
    """shadowed()'s cast shadows, every ray marched over its whole length at every pixel."""
    from scipy import ndimage

    from pbrbench.infer.integration import integrate_lsq

    h, w = used.shape
    s = lights / np.linalg.norm(lights, axis=1, keepdims=True)
    ok = used & (normals[..., 2] > 0)
    nz = np.maximum(normals[..., 2], ir.MIN_NZ)
    z = integrate_lsq(gradients=(np.where(ok, -normals[..., 0] / nz, 0.0), np.where(ok, -normals[..., 1] / nz, 0.0)),
                      mask=ok)
    part, _ = ndimage.label(ok)
    rr, cc = np.mgrid[0:h, 0:w]
    relief = float(z[ok].max() - z[ok].min())
    out = (np.einsum("hwc,kc->khw", normals, s) <= 0.0) & used[None]
    for k in range(len(s)):
        hor = float(np.hypot(s[k, 0], s[k, 1]))
        if hor < 1e-9:
            continue
        dx, dy, tan = s[k, 0] / hor, s[k, 1] / hor, s[k, 2] / hor
        for t in np.arange(1.0, min(1.5 * max(h, w), relief / max(tan, 1e-9) + 1.0) + 1.0, 1.0):
            r, c = np.rint(rr - t * dy).astype(int), np.rint(cc + t * dx).astype(int)
            ins = (r >= 0) & (r < h) & (c >= 0) & (c < w)
            r, c = np.where(ins, r, 0), np.where(ins, c, 0)
            out[k] |= ins & (part[r, c] == part) & ok & (z[r, c] > z + t * tan + margin)
    return out


def test_shadowed_marches_only_undecided_rays_with_the_same_result():
    # shadowed() drops a ray once it leaves the image, rises above its part's top or is occluded;
    # on a random relief of two parts under low and high sources the shadows are those of
    # marching every ray to its end
    rng = np.random.default_rng(5)
    size = 48
    y, x = np.mgrid[0:size, 0:size] / size
    z = sum(rng.uniform(0.05, 0.2) * np.sin(2 * np.pi * (rng.uniform(1, 3) * x + rng.uniform(1, 3) * y + rng.uniform(0, 6)))
            for _ in range(4))
    gy, gx = np.gradient(z * size)
    n = np.stack([-gx, gy, np.ones_like(z)], -1)          # rows grow downward: y up is -row
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    used = np.ones((size, size), bool)
    used[:, 22:26] = False                                  # two parts
    lights = np.array([[1.0, 0.2, 0.3], [-0.4, 1.0, 0.5], [0.3, -0.2, 2.0], [-1.0, -1.0, 0.15], [0.0, 0.0, 1.0]])
    got = ir.shadowed(n, used, lights)
    want = _marched_everywhere(n, used, lights)
    assert np.array_equal(got, want)
    cast = got & ~(np.einsum("hwc,kc->khw", n, lights / np.linalg.norm(lights, axis=1, keepdims=True)) <= 0)
    assert cast[0].sum() > 20 and cast[3].sum() > 20      # the relief casts shadows under the low sources


def test_premise_refuted_on_direct_images_returns_the_local_solve():
    # direct light only: the deep groove's shadows are black, where the kernel of the local
    # estimate predicts interreflected light; without the test the method removes light that is not
    # there and bends the normals
    n, m, direct, _ = _groove60_direct(64, 0.8)
    w = photometric_stereo_woodham1980(direct, SHADOW_LIGHTS, mask=m)
    r = photometric_stereo_nayar1991(direct, SHADOW_LIGHTS, mask=m)
    old = photometric_stereo_nayar1991(direct, SHADOW_LIGHTS, mask=m, shadow_light_min=0)
    assert r.refuted and r.shadow_light < 0.05 and r.iterations == 0 and not r.interreflection.any()
    for name in ("normals", "albedo", "residual", "n_used", "valid"):
        np.testing.assert_array_equal(getattr(r, name), getattr(w, name))
    v = w.valid
    assert ang(w.normals, n)[v].mean() < 1e-6
    assert ang(old.normals, n)[v].mean() > 5.0        # what the test prevents
    assert np.isnan(old.shadow_light) and not old.refuted


def test_premise_holds_on_images_with_interreflection():
    # the same groove with its interreflection (the facet model): the local estimate's shadows hold
    # more light than its kernel predicts (the pseudo shape is shallower than the surface), the
    # method runs as without the test and recovers the groove
    rho = 0.3
    n, m, direct, _ = _groove60_direct(64, rho)
    imgs = ir.interreflect(direct, n, np.full(m.shape, rho), m, block=2, pad=0.5)
    r = photometric_stereo_nayar1991(imgs, SHADOW_LIGHTS, mask=m)
    old = photometric_stereo_nayar1991(imgs, SHADOW_LIGHTS, mask=m, shadow_light_min=0)
    assert not r.refuted and r.iterations > 0 and r.shadow_light > 1.0
    np.testing.assert_array_equal(r.normals, old.normals)
    w = photometric_stereo_woodham1980(imgs, SHADOW_LIGHTS, mask=m)
    assert ang(w.normals, n)[w.valid].mean() > 10.0
    assert ang(r.normals, n)[r.valid].mean() < 0.01


@pytest.mark.parametrize("opt, val", [("shadow_light_min", -0.1), ("shadow_support", 0.0), ("shadow_support", 1.5)])
def test_bad_premise_options(opt, val):
    n, m = _groove(16)
    imgs = lambertian_images(n, 0.5, LIGHTS, mask=m, radiance=True)
    with pytest.raises(ValueError, match=opt):
        photometric_stereo_nayar1991(imgs, LIGHTS, mask=m, **{opt: val})
