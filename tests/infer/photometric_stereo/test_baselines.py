"""The naive photometric-stereo baseline (pbrbench.infer.photometric_stereo.baselines)."""

import numpy as np
import pytest

from pbrbench.infer.photometric_stereo import (
    BASELINES,
    METHODS,
    PhotometricStereoResult,
    photometric_stereo_naive_lstsq,
)
from pbrbench.shading.lambert import lambertian_images, ring_lights
from pbrbench.shading.surfaces import on_grid
from tests.infer.photometric_stereo._data import CHAPTER_LIGHTS, ang


def test_table_and_not_a_method():
    assert BASELINES == {"naive_lstsq_all_lights": photometric_stereo_naive_lstsq}
    assert not set(BASELINES) & set(METHODS)


def test_exact_without_shadows():
    # known answer: a plane lit by every light has no clamped measurement, so pinv(V) I is exact
    pl = on_grid("plane", 16, 1.0, fx=0.2, fy=-0.3)
    lights = ring_lights(6, elevations=(60, 70))
    imgs = lambertian_images(pl.normals, 0.4, lights)
    assert np.all(imgs > 0)
    r = photometric_stereo_naive_lstsq(imgs, lights)
    assert isinstance(r, PhotometricStereoResult)
    assert r.valid.all() and np.all(r.n_used == 6)
    np.testing.assert_allclose(r.normals, pl.normals, atol=1e-12)
    np.testing.assert_allclose(r.albedo, 0.4, rtol=1e-12)
    assert r.residual.max() < 1e-12
    # colour: the same normal, albedo per channel
    alb = np.stack([np.full((16, 16), a) for a in (0.2, 0.4, 0.8)], axis=-1)
    rc = photometric_stereo_naive_lstsq(lambertian_images(pl.normals, alb, lights), lights)
    np.testing.assert_allclose(rc.normals, pl.normals, atol=1e-12)
    np.testing.assert_allclose(rc.albedo, alb, rtol=1e-10)


def test_shadows_bias_the_naive_fit():
    # failure mode: the clamped zeros of shadowed lights stay in the equations (~1 degree off on
    # the sphere under the chapter's lights), and the residual shows it
    s = on_grid("sphere", 96, half_width=1.05)
    lit = (s.normals @ CHAPTER_LIGHTS.T > 0).sum(-1)
    imgs = lambertian_images(s.normals, 0.7, CHAPTER_LIGHTS, mask=s.mask)
    r = photometric_stereo_naive_lstsq(imgs, CHAPTER_LIGHTS, mask=s.mask)
    sel = s.mask & (lit >= 3)
    shadowed = sel & (lit < 5)
    assert ang(r.normals, s.normals)[sel].mean() > 0.5
    assert r.residual[shadowed].mean() > 1e-3 > r.residual[sel & (lit == 5)].max()
    assert not r.valid[~s.mask].any() and np.all(r.normals[~s.mask] == 0) and np.all(r.n_used[~s.mask] == 0)


def test_argument_errors():
    with pytest.raises(ValueError, match="coplanar"):
        photometric_stereo_naive_lstsq(np.ones((3, 4, 4)), np.array([[1, 0, 1], [-1, 0, 1], [0, 0, 1.0]]))
    with pytest.raises(ValueError, match="mask"):
        photometric_stereo_naive_lstsq(np.ones((3, 4, 4)), np.eye(3) + [0, 0, 1], mask=np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="non-finite"):
        photometric_stereo_naive_lstsq(np.full((3, 4, 4), np.nan), np.eye(3) + [0, 0, 1])
