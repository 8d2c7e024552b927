"""Tests of the gradient helpers of surface integration (``pbrbench.infer.integration.gradients``)."""

import numpy as np
import pytest

from pbrbench.infer.integration import (
    gradients_from_height,
    integrability_residual,
    integrate_normals,
    normals_from_gradients,
    normals_to_gradients,
)
from pbrbench.shading.surfaces import on_grid, pixel_grid
from tests.infer.integration._fields import HW, H, N


def test_normals_to_gradients_frame_and_signs():
    s = on_grid("bumps", N, HW)
    p, q, valid = normals_to_gradients(s.normals, s.mask)
    np.testing.assert_allclose(p[valid], s.fx[valid], atol=1e-12)
    np.testing.assert_allclose(q[valid], s.fy[valid], atol=1e-12)
    assert valid.sum() == s.mask.sum()
    # y up: a plane rising toward the top of the image has q > 0 and grows with decreasing row
    pl = on_grid("plane", 8, 1.0, fy=0.5)
    _, q, _ = normals_to_gradients(pl.normals)
    assert np.all(q > 0)
    z = integrate_normals(pl.normals, method="lsq", pixel_size=0.25)
    assert np.all(np.diff(z[:, 3]) < 0)  # rows go down, height goes down


def test_integrability_residual_small_for_surface_large_for_corrupted_field():
    s = on_grid("bumps", N, HW)
    good = integrability_residual(s.normals, s.mask, pixel_size=H)
    inner = s.mask.copy()
    inner[:2] = inner[-2:] = False
    inner[:, :2] = inner[:, -2:] = False
    # central differences of exact gradients: O(h^2) mismatch of the mixed partials
    assert np.abs(good[inner]).max() < 0.05
    # a rotational (non-integrable) perturbation of the gradients
    x, y = pixel_grid(N, N, HW)
    p, q = s.fx - 0.5 * y, s.fy + 0.5 * x  # adds curl d(-0.5y)/dy - d(0.5x)/dx = -1
    bad = integrability_residual(gradients=(p, q), mask=s.mask, pixel_size=H)
    np.testing.assert_allclose(bad[inner], good[inner] - 1.0, atol=1e-9)


def test_grazing_normals_are_dropped_not_integrated():
    s = on_grid("sphere", N, 1.05)
    n = s.normals.copy()
    n[N // 2, N // 2] = [1.0, 0.0, 0.0]  # grazing normal: infinite gradient
    p, q, valid = normals_to_gradients(n, s.mask)
    assert not valid[N // 2, N // 2] and np.isfinite(p).all()
    z = integrate_normals(n, mask=s.mask, pixel_size=2 * 1.05 / N)
    assert np.isfinite(z).all() and z[N // 2, N // 2] == 0.0


def test_helper_errors():
    with pytest.raises(ValueError, match="normals"):
        normals_to_gradients(np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="min_nz"):
        normals_to_gradients(np.zeros((4, 4, 3)) + [0, 0, 1], min_nz=0)
    with pytest.raises(ValueError, match="pixel_size"):
        integrability_residual(np.zeros((4, 4, 3)) + [0, 0, 1], pixel_size=-1)


def test_normals_from_gradients_inverts_normals_to_gradients():
    s = on_grid("sphere", N, 1.05)
    p, q, valid = normals_to_gradients(s.normals, s.mask)
    n = normals_from_gradients(p, q, valid)
    np.testing.assert_allclose(n[valid], s.normals[valid], atol=1e-12)
    assert np.all(n[~valid] == 0)
    np.testing.assert_allclose(np.linalg.norm(n[valid], axis=-1), 1.0, atol=1e-15)
    # the frame: a slope up to the right (p > 0) tilts the normal to the left (N_x < 0)
    assert normals_from_gradients(np.full((2, 2), 1.0), np.zeros((2, 2)))[0, 0, 0] == pytest.approx(-np.sqrt(0.5))


def test_gradients_from_height_exact_for_a_quadratic_and_one_sided_at_the_edge():
    # central differences are exact for a quadratic; at the mask's edge the one-sided
    # difference of z = a x^2 misses the slope by a h (the second-order term)
    x, y = pixel_grid(N, N, HW)
    a = 0.3
    z = a * x**2 - 0.2 * x * y + 0.1 * y**2
    m = x**2 + y**2 < 0.8
    p, q = gradients_from_height(z, m, pixel_size=H)
    inner = m & np.roll(m, 1, 0) & np.roll(m, -1, 0) & np.roll(m, 1, 1) & np.roll(m, -1, 1)
    np.testing.assert_allclose(p[inner], (2 * a * x - 0.2 * y)[inner], atol=1e-12)
    np.testing.assert_allclose(q[inner], (-0.2 * x + 0.2 * y)[inner], atol=1e-12)
    i, j = N // 2, int(np.flatnonzero(m[N // 2])[0])  # leftmost pixel of the middle row
    assert p[i, j] == pytest.approx(2 * a * x[i, j] - 0.2 * y[i, j] + a * H, abs=1e-12)  # forward difference
    assert np.all(p[~m] == 0) and np.all(q[~m] == 0)
    # pixel_size only rescales
    p1, q1 = gradients_from_height(z / H, m)
    np.testing.assert_array_equal(p1, p)
    np.testing.assert_array_equal(q1, q)


def test_gradients_and_normals_helpers_errors():
    with pytest.raises(ValueError, match="q"):
        normals_from_gradients(np.zeros((4, 4)), np.zeros((4, 5)))
    with pytest.raises(ValueError, match="p"):
        normals_from_gradients(np.full((4, 4), np.nan), np.zeros((4, 4)))
    with pytest.raises(ValueError, match="z"):
        gradients_from_height(np.zeros(4))
    with pytest.raises(ValueError, match="mask"):
        gradients_from_height(np.zeros((4, 4)), np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="pixel_size"):
        gradients_from_height(np.zeros((4, 4)), pixel_size=0.0)
