"""Robust L1 photometric stereo (Ikehata et al. 2012) on analytic images with highlights
(pbrbench.infer.photometric_stereo.ikehata2012)."""

import numpy as np
import pytest

from pbrbench.infer.photometric_stereo import (
    photometric_stereo_ikehata2012_l1,
    photometric_stereo_woodham1980,
)
from pbrbench.shading.lambert import blinn_phong_highlights, lambertian_images, ring_lights
from pbrbench.shading.surfaces import on_grid
from tests.infer.photometric_stereo._data import ang


def _specular_sphere(n_px=64, shininess=300.0):
    s = on_grid("sphere", n_px, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.8, lights, mask=s.mask)
    spec = blinn_phong_highlights(s.normals, lights, shininess, mask=s.mask)
    return s, lights, imgs + spec, (spec > 1e-3).any(0) & s.mask


def test_robust_l1_removes_highlights_where_least_squares_fails():
    s, lights, imgs, hl = _specular_sphere()
    ls = photometric_stereo_woodham1980(imgs, lights, mask=s.mask)
    l1 = photometric_stereo_ikehata2012_l1(imgs, lights, mask=s.mask)
    e_ls = ang(ls.normals, s.normals)[hl & ls.valid].mean()
    e_l1 = ang(l1.normals, s.normals)[hl & l1.valid].mean()
    assert l1.valid[s.mask].mean() > 0.99
    assert e_ls > 1.0
    assert e_l1 < 0.05
    assert np.abs(l1.albedo[hl & l1.valid] - 0.8).mean() < 0.02 < np.abs(ls.albedo[hl] - 0.8).mean()
    # outliers are reported: highlight pixels use fewer lights than the lit count
    assert (l1.n_used[hl] < ls.n_used[hl]).mean() > 0.5


def test_robust_method_is_exact_on_clean_data():
    s = on_grid("sphere", 48, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.5, lights, mask=s.mask)
    r = photometric_stereo_ikehata2012_l1(imgs, lights, mask=s.mask)
    assert ang(r.normals, s.normals)[r.valid].max() < 1e-5
    assert r.valid[s.mask].mean() > 0.99
    np.testing.assert_allclose(r.albedo[r.valid], 0.5, rtol=1e-6)


def test_dense_corruption_is_not_sparse_and_defeats_l1():
    # failure mode: the L1 fit assumes the errors are sparse.  A constant ambient term added to
    # every measurement is a dense error: the fit cannot reject it and the normals tilt toward
    # the view (the same bias as least squares, not removed)
    s = on_grid("sphere", 48, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.5, lights, mask=s.mask) + 0.2 * s.mask
    r = photometric_stereo_ikehata2012_l1(imgs, lights, mask=s.mask, shadow_threshold=0.0)
    assert ang(r.normals, s.normals)[r.valid & s.mask].mean() > 5.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(max_iter=0), "max_iter"),
    (dict(min_lights=2), "min_lights"),
    (dict(lights=np.array([[1, 0, 1], [-1, 0, 1], [0, 0, 1.0]])), "coplanar"),
])
def test_argument_errors(kwargs, match):
    args = dict(images=np.ones((3, 4, 4)), lights=np.eye(3) + [0, 0, 1])
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        photometric_stereo_ikehata2012_l1(**args)
