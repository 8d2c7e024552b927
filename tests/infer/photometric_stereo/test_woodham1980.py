"""Least-squares photometric stereo (Woodham 1980) on analytic Lambertian images
(pbrbench.infer.photometric_stereo.woodham1980)."""

import numpy as np
import pytest

from pbrbench.infer.photometric_stereo import (
    PhotometricStereoResult,
    photometric_stereo_woodham1980,
)
from pbrbench.shading.lambert import lambertian_images, ring_lights
from pbrbench.shading.surfaces import on_grid
from tests.infer.photometric_stereo._data import CHAPTER_LIGHTS, ang


@pytest.fixture(scope="module")
def sphere():
    s = on_grid("sphere", 128, half_width=1.05)
    lit = (s.normals @ CHAPTER_LIGHTS.T > 0).sum(-1)
    return s, lit


def test_noise_free_sphere_chapter_lights_and_naive_fit_fails(sphere):
    s, lit = sphere
    n, m = s.normals, s.mask
    imgs = lambertian_images(n, 0.7, CHAPTER_LIGHTS, mask=m)
    sel = m & (lit >= 3)
    assert (m & (lit < 5)).sum() > 0.2 * m.sum()  # shadows are present
    r = photometric_stereo_woodham1980(imgs, CHAPTER_LIGHTS, mask=m)
    assert isinstance(r, PhotometricStereoResult)
    assert r.valid[sel].all()
    assert ang(r.normals, n)[sel].mean() < 0.01
    np.testing.assert_allclose(r.albedo[sel], 0.7, rtol=1e-9)
    assert np.all(r.n_used[sel] <= lit[sel])  # the default threshold also drops near-grazing lights
    r0 = photometric_stereo_woodham1980(imgs, CHAPTER_LIGHTS, mask=m, shadow_threshold=0.0)
    assert np.all(r0.n_used[sel] == lit[sel]) and ang(r0.normals, n)[sel].mean() < 0.01
    # the residual is formed from the normal equations (sum J^2 - rho N.b): its floor is
    # sqrt(machine eps) ~ 1e-8 of the brightness, far below any noise
    assert r.residual[sel].max() < 1e-7
    # the naive fit keeps the clamped zeros of shadowed lights in the equations: ~1 degree off
    g = np.linalg.lstsq(CHAPTER_LIGHTS, imgs[:, sel], rcond=None)[0].T
    naive = ang(g / np.linalg.norm(g, axis=1, keepdims=True), n[sel]).mean()
    assert naive > 0.5 and naive > 100 * 0.01


def test_eight_bit_quantised_sphere(sphere):
    s, lit = sphere
    imgs = lambertian_images(s.normals, 0.7, CHAPTER_LIGHTS, mask=s.mask)
    q = np.round(imgs / imgs.max() * 255.0)
    r = photometric_stereo_woodham1980(q, CHAPTER_LIGHTS, mask=s.mask, saturation=255.5)
    sel = s.mask & (lit >= 3) & r.valid
    assert sel.sum() > 0.99 * (s.mask & (lit >= 3)).sum()
    assert ang(r.normals, s.normals)[sel].mean() < 0.2


def test_pixels_lit_by_fewer_than_three_lights_are_invalid_not_wrong():
    s = on_grid("sphere", 96, half_width=1.05)
    lights = ring_lights(4, elevations=(30, 30))  # four grazing sources: the rim sees only two
    lit = (s.normals @ lights.T > 0).sum(-1)
    assert (s.mask & (lit < 3)).any()
    r = photometric_stereo_woodham1980(lambertian_images(s.normals, 1.0, lights, mask=s.mask), lights, mask=s.mask)
    few = s.mask & (lit < 3)
    assert not r.valid[few].any()
    assert np.all(r.normals[few] == 0) and np.all(r.albedo[few] == 0)
    ok = r.valid
    assert ang(r.normals, s.normals)[ok].max() < 1e-4


def test_frame_convention_on_tilted_plane():
    # plane rising toward the top of the image (f_y > 0): normal leans to -y, so a source
    # from below (-y) lights it more than one from above (+y)
    pl = on_grid("plane", 16, 1.0, fy=0.4)
    lights = np.array([[0, 0.5, 1], [0, -0.5, 1], [0.5, 0, 1], [0, 0, 1.0]])
    imgs = lambertian_images(pl.normals, 0.5, lights)
    assert imgs[1].mean() > imgs[0].mean()
    r = photometric_stereo_woodham1980(imgs, lights)
    np.testing.assert_allclose(r.normals, pl.normals, atol=1e-12)
    assert np.all(r.normals[..., 1] < 0)
    # lights given with their length as intensity: albedo = |g| is the true albedo
    np.testing.assert_allclose(r.albedo, 0.5, rtol=1e-12)


def test_colour_shared_normal_per_channel_albedo_and_coloured_sources():
    s = on_grid("bumps", 64, 1.0)
    lights = ring_lights(8)
    rng = np.random.default_rng(4)
    albedo = np.stack([np.full((64, 64), a) for a in (0.2, 0.5, 0.9)], axis=-1)
    albedo *= rng.uniform(0.8, 1.2, size=(64, 64, 1))
    e = rng.uniform(0.5, 2.0, size=(8, 3))  # coloured sources
    imgs = lambertian_images(s.normals, albedo, lights, intensities=e, mask=s.mask)
    r = photometric_stereo_woodham1980(imgs, lights, mask=s.mask, intensities=e)
    assert r.albedo.shape == (64, 64, 3)
    v = r.valid
    assert v[s.mask].mean() > 0.99
    assert ang(r.normals, s.normals)[v].max() < 1e-5
    np.testing.assert_allclose(r.albedo[v], albedo[v], rtol=1e-8)
    # without the intensities the albedo absorbs them and the normals are wrong
    r2 = photometric_stereo_woodham1980(imgs, lights, mask=s.mask)
    assert ang(r2.normals, s.normals)[r2.valid].mean() > 1.0


def test_scalar_intensities_equal_light_lengths():
    s = on_grid("random_smooth", 48, 1.0)
    lights = ring_lights(6)
    e = np.array([1.0, 2.0, 0.5, 1.5, 3.0, 0.8])
    imgs = lambertian_images(s.normals, 0.6, lights * e[:, None])
    a = photometric_stereo_woodham1980(imgs, lights, intensities=e)
    b = photometric_stereo_woodham1980(imgs, lights * e[:, None])
    np.testing.assert_allclose(a.normals, b.normals, atol=1e-12)
    np.testing.assert_allclose(a.albedo, 0.6, rtol=1e-9)


def test_saturated_measurements_are_excluded():
    s = on_grid("sphere", 64, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 1.0, lights, mask=s.mask)
    clipped = np.minimum(imgs, 0.8)
    bad = photometric_stereo_woodham1980(clipped, lights, mask=s.mask)
    good = photometric_stereo_woodham1980(clipped, lights, mask=s.mask, saturation=0.8)
    sel = good.valid & (imgs >= 0.8).any(0)
    assert sel.sum() > 50
    assert ang(bad.normals, s.normals)[sel].mean() > 0.5
    assert ang(good.normals, s.normals)[sel].max() < 1e-9


def test_noise_gives_growing_error_and_residual():
    s = on_grid("sphere", 64, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.8, lights, mask=s.mask)
    rng = np.random.default_rng(0)
    errs, res = [], []
    for sigma in (0.0, 0.005, 0.02):
        r = photometric_stereo_woodham1980(imgs + rng.normal(scale=sigma, size=imgs.shape), lights, mask=s.mask)
        errs.append(ang(r.normals, s.normals)[r.valid].mean())
        res.append(np.median(r.residual[r.valid]))
    assert errs[0] < 1e-5 < errs[1] < errs[2]
    assert res[0] < 1e-7 and 0.3 * 0.02 < res[2] < 2 * 0.02


def test_mask_and_nan_outside_mask():
    s = on_grid("sphere", 32, half_width=1.05)
    lights = ring_lights(6)
    imgs = lambertian_images(s.normals, 1.0, lights, mask=s.mask)
    imgs[:, ~s.mask] = np.nan
    r = photometric_stereo_woodham1980(imgs, lights, mask=s.mask)
    assert not r.valid[~s.mask].any() and np.all(r.normals[~s.mask] == 0)
    assert r.normals.shape == (32, 32, 3) and r.n_used.dtype.kind == "i"


@pytest.mark.parametrize(
    "lights, match",
    [
        (np.array([[1, 0, 1], [-1, 0, 1], [0, 0, 1.0]]), "coplanar"),
        (np.array([[0, 0, 1], [0, 0, 2], [0, 0, 3.0]]), "collinear"),
        (np.array([[0, 0, 1], [1, 0, 1.0]]), "at least 3"),
        (np.array([[0, 0, 1], [1, 0, 1], [0, 0, 0.0]]), "zero"),
    ],
)
def test_degenerate_lights_raise(lights, match):
    # failure mode: fewer than 3 independent directions leave the normal undetermined
    imgs = np.ones((len(lights), 4, 4))
    with pytest.raises(ValueError, match=match):
        photometric_stereo_woodham1980(imgs, lights)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(images=np.ones((3, 4))), "images"),
        (dict(lights=np.eye(3)[:, :2]), "lights"),
        (dict(intensities=np.array([1.0, 0.0, 1.0])), "intensities"),
        (dict(intensities=np.ones((3, 2))), "intensities"),
        (dict(shadow_threshold=1.5), "shadow_threshold"),
        (dict(min_lights=2), "min_lights"),
        (dict(saturation=np.nan), "saturation"),
        (dict(mask=np.ones((3, 3), bool)), "mask"),
        (dict(images=np.full((3, 4, 4), np.nan)), "images"),
    ],
)
def test_argument_errors(kwargs, match):
    args = dict(images=np.ones((3, 4, 4)), lights=np.eye(3) + [0, 0, 1])
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        photometric_stereo_woodham1980(**args)


def test_given_measurements_replace_the_classification(sphere):
    """``used`` names the measurements to fit: a planted half shadow (a lit measurement at half its
    value, which the threshold keeps) biases the default fit and vanishes when it is left out."""
    s, lit = sphere
    n, m = s.normals, s.mask
    imgs = lambertian_images(n, 0.7, CHAPTER_LIGHTS, mask=m)
    on = (n @ CHAPTER_LIGHTS.T > 0).transpose(2, 0, 1) & m[None]
    half = np.zeros_like(on)
    half[0] = on[0] & (lit >= 4)                      # pixels that keep >= 3 lights without light 0
    bad = np.where(half, 0.5 * imgs, imgs)
    sel = half[0]
    assert ang(photometric_stereo_woodham1980(bad, CHAPTER_LIGHTS, mask=m).normals, n)[sel].mean() > 1.0
    r = photometric_stereo_woodham1980(bad, CHAPTER_LIGHTS, mask=m, used=on & ~half)
    assert r.valid[sel].all() and ang(r.normals, n)[sel].max() < 1e-6
    np.testing.assert_allclose(r.albedo[sel], 0.7, rtol=1e-9)
    assert np.array_equal(r.n_used[m], (on & ~half).sum(0)[m])
    none = photometric_stereo_woodham1980(bad, CHAPTER_LIGHTS, mask=m, used=np.zeros_like(on))
    assert not none.valid.any()                       # no measurement: no pixel, not a guess


@pytest.mark.parametrize("used", [np.ones((3, 4, 4), bool), np.ones((5, 128, 128), float)])
def test_given_measurements_of_the_wrong_shape_or_type_are_refused(sphere, used):
    s, _ = sphere
    imgs = lambertian_images(s.normals, 0.7, CHAPTER_LIGHTS, mask=s.mask)
    with pytest.raises(ValueError, match=r"used: .*pass a \(\d+, 128, 128\) boolean array"):
        photometric_stereo_woodham1980(imgs, CHAPTER_LIGHTS, mask=s.mask, used=used)
