"""Tests of masked least-squares integration (``pbrbench.infer.integration.lsq``)."""

import numpy as np
import pytest

from pbrbench.infer.integration import integrate_lsq, integrate_normals, integrate_path
from pbrbench.shading.surfaces import on_grid, pixel_grid
from tests.infer.integration._fields import HW, H, N, irregular_mask, rel_rmse


@pytest.mark.parametrize("name", ["bumps", "random_smooth"])
def test_lsq_exact_on_masked_analytic_surface(name):
    s = on_grid(name, N, HW)
    m = irregular_mask(s)
    z = integrate_normals(s.normals, mask=m, pixel_size=H)
    assert rel_rmse(z, s.z, m) < 0.01  # the target: < 1 % of the height range
    assert abs(z[m].mean()) < 1e-12 and np.all(z[~m] == 0)


def test_gradients_input_matches_normals_input():
    s = on_grid("bumps", N, HW)
    a = integrate_normals(s.normals, mask=s.mask, pixel_size=H)
    b = integrate_normals(gradients=(s.fx, s.fy), mask=s.mask, pixel_size=H)
    np.testing.assert_allclose(a, b, atol=1e-10)


def test_a_pure_rotation_has_a_flat_least_squares_surface():
    # failure mode of every integrator: the curl part of a field is lost.  (p, q) = (-y, x) has
    # zero divergence and zero flux through a circle, so its least-squares surface is flat (the
    # disc's staircase edge leaves a little); the path integral makes up a large surface
    x, y = pixel_grid(N, N, HW)
    disc = x**2 + y**2 < 0.8
    z = integrate_lsq(gradients=(-y, x), mask=disc, pixel_size=H)
    zp = integrate_path(gradients=(-y, x), mask=disc, pixel_size=H)
    assert np.ptp(z[disc]) < 0.1 * np.ptp(zp[disc])


def test_tolerance_is_the_solver_tolerance():
    s = on_grid("bumps", N, HW)
    m = irregular_mask(s)
    loose = integrate_lsq(s.normals, mask=m, pixel_size=H, tol=1e-2)
    tight = integrate_lsq(s.normals, mask=m, pixel_size=H)
    # a loose relative residual stops the conjugate gradients early: close to, not at, the solution
    assert 0 < np.abs(loose - tight)[m].max() < 0.05 * np.ptp(tight[m])
    with pytest.raises(ValueError, match="pixel_size"):
        integrate_lsq(s.normals, mask=m, pixel_size=-1.0)
