"""Tests of the chapter's path integration (``pbrbench.infer.integration.path``)."""

import numpy as np

from pbrbench.infer.integration import integrate_lsq, integrate_normals, integrate_path
from pbrbench.shading.surfaces import on_grid
from tests.infer.integration._fields import HW, H, N, rel_rmse


def test_path_integration_follows_the_chapter():
    # top-left is the anchor; a tilted plane integrates exactly along any path
    pl = on_grid("plane", 10, 1.0, fx=0.3, fy=-0.7)
    z = integrate_normals(pl.normals, method="path", pixel_size=0.2)
    truth = pl.z - pl.z.mean()
    np.testing.assert_allclose(z, truth, atol=1e-12)


def test_path_error_accumulates_with_noise():
    # failure mode: noise in the gradients is summed along the path (a random walk whose spread
    # grows as the square root of the path length), while least squares averages it away
    s = on_grid("bumps", N, HW)
    rng = np.random.default_rng(0)
    p = s.fx + 0.2 * rng.standard_normal(s.fx.shape)
    q = s.fy + 0.2 * rng.standard_normal(s.fy.shape)
    full = np.ones((N, N), bool)
    path = rel_rmse(integrate_path(gradients=(p, q), pixel_size=H), s.z, full)
    lsq = rel_rmse(integrate_lsq(gradients=(p, q), pixel_size=H), s.z, full)
    assert path > 3 * lsq
