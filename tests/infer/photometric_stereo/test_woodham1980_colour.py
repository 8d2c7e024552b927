"""Colour photometric stereo with a shared normal (pbrbench.infer.photometric_stereo.woodham1980_colour)
on analytic coloured Lambertian spheres."""

import numpy as np
import pytest

from pbrbench.infer.photometric_stereo import (
    PhotometricStereoResult,
    photometric_stereo_woodham1980,
)
from pbrbench.infer.photometric_stereo.woodham1980_colour import (
    photometric_stereo_woodham1980_colour,
)
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid
from tests.infer.photometric_stereo._data import CHAPTER_LIGHTS, ang


@pytest.fixture(scope="module")
def sphere():
    s = on_grid("sphere", 96, half_width=1.05)
    lit = (s.normals @ CHAPTER_LIGHTS.T > 0).sum(-1)
    return s, lit


def test_exact_recovery_of_normal_and_per_channel_albedo(sphere):
    s, lit = sphere
    n, m = s.normals, s.mask
    alb = np.empty(m.shape + (3,))
    alb[..., 0] = 0.8
    alb[..., 1] = np.where(n[..., 0] > 0, 0.5, 0.3)   # a colour edge
    alb[..., 2] = 0.05 + 0.1 * (n[..., 1] > 0)
    e = np.array([[1.0, 0.9, 1.2], [0.7, 1.0, 1.0], [1.1, 1.3, 0.6], [1.0, 1.0, 1.0], [0.5, 0.8, 1.5]])
    imgs = lambertian_images(n, alb, CHAPTER_LIGHTS, intensities=e, mask=m)
    r = photometric_stereo_woodham1980_colour(imgs, CHAPTER_LIGHTS, mask=m, intensities=e)
    sel = m & (lit >= 3)
    assert isinstance(r, PhotometricStereoResult) and r.albedo.shape == m.shape + (3,)
    assert r.valid[sel].all() and not r.valid[~m].any()
    assert ang(r.normals, n)[sel].max() < 1e-8
    np.testing.assert_allclose(r.albedo[sel], alb[sel], rtol=1e-9, atol=1e-12)
    assert r.residual[sel].max() < 1e-7


def test_grey_albedo_equals_woodham_on_the_grey_image(sphere):
    s, _ = sphere
    rng = np.random.default_rng(3)
    grey = lambertian_images(s.normals, 0.6, CHAPTER_LIGHTS, mask=s.mask)
    grey = grey + 0.01 * rng.standard_normal(grey.shape)   # noisy: the equality is algebraic
    rgb = np.repeat(grey[..., None], 3, axis=-1)
    r = photometric_stereo_woodham1980_colour(rgb, CHAPTER_LIGHTS, mask=s.mask)
    w = photometric_stereo_woodham1980(grey, CHAPTER_LIGHTS, mask=s.mask)
    np.testing.assert_array_equal(r.valid, w.valid)
    v = w.valid
    assert ang(r.normals, w.normals)[v].max() < 1e-8
    np.testing.assert_allclose(r.albedo[v], np.repeat(w.albedo[v][:, None], 3, axis=1), rtol=1e-9)
    # one channel (3-D input) is Woodham exactly
    r1 = photometric_stereo_woodham1980_colour(grey, CHAPTER_LIGHTS, mask=s.mask)
    np.testing.assert_array_equal(r1.normals, w.normals)


@pytest.mark.parametrize("albedo", [(0.8, 0.2, 0.02), (1.0, 0.0, 0.0)])
def test_noise_joint_fit_beats_averaged_channel_normals_and_the_channel_sum(sphere, albedo):
    s, lit = sphere
    n, m = s.normals, s.mask
    alb = np.broadcast_to(np.asarray(albedo), m.shape + (3,))
    clean = lambertian_images(n, alb, CHAPTER_LIGHTS, mask=m)
    noisy = clean + 0.02 * np.random.default_rng(7).standard_normal(clean.shape)
    sel = m & (lit == 5)
    r = photometric_stereo_woodham1980_colour(noisy, CHAPTER_LIGHTS, mask=m, shadow_threshold=0.0)
    joint = ang(r.normals, n)[sel].mean()
    per = [photometric_stereo_woodham1980(noisy[..., c], CHAPTER_LIGHTS, mask=m, shadow_threshold=0.0).normals
           for c in range(3)]
    avg = sum(per)
    avg = avg / np.maximum(np.linalg.norm(avg, axis=-1, keepdims=True), 1e-300)
    averaged = ang(avg, n)[sel].mean()
    summed = ang(photometric_stereo_woodham1980(noisy, CHAPTER_LIGHTS, mask=m, shadow_threshold=0.0).normals,
                 n)[sel].mean()
    # the dark channels' normals are mostly noise: averaging them costs a factor > 5
    assert averaged > 5 * joint
    # the channel sum has signal sum(rho) over noise sqrt(C) sigma, the joint fit |rho| / sigma:
    # the error ratio is ~ sqrt(3) |rho| / sum(rho) (1.40 and 1.73 here)
    expect = np.sqrt(3) * np.linalg.norm(albedo) / np.sum(albedo)
    assert 0.8 * expect < summed / joint < 1.2 * expect


def test_failure_modes(sphere):
    s, _ = sphere
    imgs = lambertian_images(s.normals, np.full(s.mask.shape + (3,), 0.5), CHAPTER_LIGHTS, mask=s.mask)
    with pytest.raises(ValueError, match=r"intensities: expected shape \(5,\) or \(5, 3\)"):
        photometric_stereo_woodham1980_colour(imgs, CHAPTER_LIGHTS, intensities=np.ones((5, 2)))
    with pytest.raises(ValueError, match="lights: expected shape"):
        photometric_stereo_woodham1980_colour(imgs[:4], CHAPTER_LIGHTS)
    coplanar = CHAPTER_LIGHTS.copy()
    coplanar[:, 1] = 0.0
    with pytest.raises(ValueError, match="degenerate.*coplanar"):
        photometric_stereo_woodham1980_colour(imgs, coplanar)
    with pytest.raises(ValueError, match="images: expected 3 or 4 dimensions"):
        photometric_stereo_woodham1980_colour(imgs[..., None], CHAPTER_LIGHTS)
    bad = imgs.copy()
    bad[0, 48, 48, 1] = np.nan
    with pytest.raises(ValueError, match="images: 1 non-finite"):
        photometric_stereo_woodham1980_colour(bad, CHAPTER_LIGHTS, mask=s.mask)
    # a pixel whose used lights are degenerate (lit by 2) is invalid, not wrong
    two = imgs.copy()
    two[2:, 10, 48] = 0.0
    r = photometric_stereo_woodham1980_colour(two, CHAPTER_LIGHTS, mask=s.mask)
    assert not r.valid[10, 48] and np.all(r.normals[10, 48] == 0)
