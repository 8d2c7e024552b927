"""Tests of what the shape-from-shading methods share (``pbrbench.infer.sfs._common``)."""

import numpy as np
import pytest

from pbrbench.infer.sfs import integrate_gradients, occluding_boundary, shape_from_shading
from pbrbench.infer.sfs._common import _reflectance
from pbrbench.metrics.sfs import normal_angle
from pbrbench.shading.surfaces import on_grid
from tests.infer.sfs._scenes import FRONTAL, HW, scene


def test_default_albedo_is_the_brightest_pixel():
    s, img, h = scene("sphere", 64, FRONTAL, albedo=0.5)
    r = shape_from_shading(img, FRONTAL, method="kimmel2001", mask=s.mask, pixel_size=h)
    assert r.albedo == pytest.approx(img[s.mask].max())
    assert normal_angle(r.normals, s.normals, s.mask) < 3.0


def test_reflectance_map_and_its_derivatives():
    s = np.array([0.3, -0.2, 0.9])
    s /= np.linalg.norm(s)
    p, q = np.array([0.4, -1.2]), np.array([0.1, 0.7])
    r, rp, rq = _reflectance(p, q, s)
    n = np.stack([-p, -q, np.ones(2)], 1) / np.sqrt(1 + p * p + q * q)[:, None]
    np.testing.assert_allclose(r, n @ s, atol=1e-15)  # R = N . S (unclipped)
    eps = 1e-6
    np.testing.assert_allclose(rp, (_reflectance(p + eps, q, s)[0] - _reflectance(p - eps, q, s)[0]) / (2 * eps),
                               atol=1e-8)
    np.testing.assert_allclose(rq, (_reflectance(p, q + eps, s)[0] - _reflectance(p, q - eps, s)[0]) / (2 * eps),
                               atol=1e-8)


def test_integrate_gradients_recovers_a_plane_in_world_units():
    pl = on_grid("plane", 16, 1.0, fx=0.3, fy=-0.5)
    z = integrate_gradients(pl.fx, pl.fy, pixel_size=2.0 / 16)
    np.testing.assert_allclose(z, pl.z - pl.z.mean(), atol=1e-9)


def test_occluding_boundary_excludes_the_frame():
    s = on_grid("sphere", 32, half_width=HW)
    b = occluding_boundary(s.mask)
    assert b.any() and not (b & ~s.mask).any()
    # the image frame is no contour: a full mask has none, and a mask cut by the frame keeps its
    # inner edge (column 3 here) minus, with exclude_border, the two pixels on the frame
    assert not occluding_boundary(np.ones((8, 8), bool), exclude_border=False).any()
    half = np.zeros((8, 8), bool)
    half[:, :4] = True
    assert occluding_boundary(half, exclude_border=False).sum() == 8
    assert occluding_boundary(half).sum() == 6 and occluding_boundary(half)[1:-1, 3].all()
