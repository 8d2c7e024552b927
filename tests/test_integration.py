"""Tests of surface integration (``pbrbench.infer.integration``) on analytic surfaces."""

import numpy as np
import pytest

from pbrbench.infer.integration import (
    integrability_residual,
    integrate_normals,
    normals_to_gradients,
)
from pbrbench.shading.surfaces import on_grid, pixel_grid

N = 96
HW = 1.0
H = 2 * HW / N  # world size of one pixel


def _irregular_mask(surface):
    x, y = pixel_grid(N, N, HW)
    blob = ((x / 0.9) ** 2 + (y / 0.7) ** 2 < 1) | ((x - 0.3) ** 2 + (y + 0.5) ** 2 < 0.2)
    return surface.mask & blob & ~((x > 0.2) & (np.abs(y) < 0.15))  # a notch: non-convex


def _rel_rmse(z, truth, m):
    d = z[m] - truth[m]
    d -= d.mean()
    return np.sqrt(np.mean(d**2)) / np.ptp(truth[m])


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


@pytest.mark.parametrize("name", ["bumps", "random_smooth"])
def test_lsq_exact_on_masked_analytic_surface(name):
    s = on_grid(name, N, HW)
    m = _irregular_mask(s)
    z = integrate_normals(s.normals, mask=m, pixel_size=H)
    assert _rel_rmse(z, s.z, m) < 0.01  # the target: < 1 % of the height range
    assert abs(z[m].mean()) < 1e-12 and np.all(z[~m] == 0)


def test_rectangle_methods_are_far_worse_on_a_mask():
    s = on_grid("bumps", N, HW)
    m = _irregular_mask(s)
    errs = {meth: _rel_rmse(integrate_normals(s.normals, mask=m, method=meth, pixel_size=H), s.z, m)
            for meth in ("lsq", "path", "frankot_chellappa", "dct")}
    for meth in ("path", "frankot_chellappa", "dct"):
        assert errs[meth] > 10 * errs["lsq"], errs


@pytest.mark.parametrize("method", ["lsq", "path", "frankot_chellappa", "dct"])
def test_all_methods_accurate_on_periodic_surface_over_full_rectangle(method):
    x, y = pixel_grid(N, N, HW)  # the film spans 2 world units: period 2 is periodic on it
    z = 0.1 * np.sin(np.pi * x) * np.cos(np.pi * y) + 0.05 * np.sin(2 * np.pi * y)
    p = 0.1 * np.pi * np.cos(np.pi * x) * np.cos(np.pi * y)
    q = -0.1 * np.pi * np.sin(np.pi * x) * np.sin(np.pi * y) + 0.1 * np.pi * np.cos(2 * np.pi * y)
    est = integrate_normals(gradients=(p, q), method=method, pixel_size=H)
    # FC is spectrally exact here; the others carry the O(h^2) trapezoid error
    bound = 1e-10 if method == "frankot_chellappa" else 2e-3
    assert _rel_rmse(est, z, np.ones_like(z, bool)) < bound


def test_frankot_chellappa_fails_on_non_periodic_surface():
    # known failure mode: FC assumes a periodic field; a paraboloid's slopes jump at the border
    x, y = pixel_grid(N, N, HW)
    z = 0.3 * x**2 - 0.2 * x * y + 0.1 * y**2
    p, q = 0.6 * x - 0.2 * y, -0.2 * x + 0.2 * y
    full = np.ones_like(z, bool)
    fc = _rel_rmse(integrate_normals(gradients=(p, q), method="frankot_chellappa", pixel_size=H), z, full)
    for method in ("lsq", "dct", "path"):
        est = integrate_normals(gradients=(p, q), method=method, pixel_size=H)
        assert _rel_rmse(est, z, full) < 1e-3
    assert fc > 0.05


def test_path_integration_follows_the_chapter():
    # top-left is the anchor; a tilted plane integrates exactly along any path
    pl = on_grid("plane", 10, 1.0, fx=0.3, fy=-0.7)
    z = integrate_normals(pl.normals, method="path", pixel_size=0.2)
    truth = pl.z - pl.z.mean()
    np.testing.assert_allclose(z, truth, atol=1e-12)


def test_gradients_input_matches_normals_input():
    s = on_grid("bumps", N, HW)
    a = integrate_normals(s.normals, mask=s.mask, pixel_size=H)
    b = integrate_normals(gradients=(s.fx, s.fy), mask=s.mask, pixel_size=H)
    np.testing.assert_allclose(a, b, atol=1e-10)


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


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(), "normals/gradients"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], gradients=(np.zeros((4, 4)),) * 2), "normals/gradients"),
        (dict(normals=np.zeros((4, 4, 2))), "normals"),
        (dict(gradients=np.zeros((4, 4))), "gradients"),
        (dict(gradients=(np.zeros((4, 4)), np.zeros((4, 5)))), "gradients"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], method="poisson"), "method"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], pixel_size=0.0), "pixel_size"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], mask=np.ones((3, 3), bool)), "mask"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, -1]), "mask"),
        (dict(gradients=(np.full((4, 4), np.nan), np.zeros((4, 4))), mask=np.ones((4, 4), bool)), "gradients"),
    ],
)
def test_integrate_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        integrate_normals(**kwargs)


def test_helper_errors():
    with pytest.raises(ValueError, match="normals"):
        normals_to_gradients(np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="min_nz"):
        normals_to_gradients(np.zeros((4, 4, 3)) + [0, 0, 1], min_nz=0)
    with pytest.raises(ValueError, match="pixel_size"):
        integrability_residual(np.zeros((4, 4, 3)) + [0, 0, 1], pixel_size=-1)
