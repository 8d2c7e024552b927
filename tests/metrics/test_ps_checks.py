"""The chapter's photometric-stereo checks (pbrbench.metrics.ps_checks) in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.metrics import METRICS
from pbrbench.metrics.ps_checks import (
    check_error_correlation,
    check_scores,
    integrability_map,
    lsq_residual_map,
)
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid, pixel_grid

FIVE = np.array([[0, 0, 1], [0.6, 0, 0.8], [-0.6, 0, 0.8], [0, 0.6, 0.8], [0, -0.6, 0.8]], float)


def normals_of(p, q):
    n = np.stack([-p, -q, np.ones_like(p)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def test_integrability_zero_on_a_quadratic_surface_and_the_planted_curl():
    x, y = pixel_grid(32, 32, 1.0)
    px = 2.0 / 32
    dom = np.ones((32, 32), bool)
    # z = 0.3 x^2 - 0.2 y^2 + 0.5 x y: p, q linear, mixed partials both 0.5 (central differences exact)
    r = integrability_map(normals_of(0.6 * x + 0.5 * y, -0.4 * y + 0.5 * x), dom, px)
    assert np.nanmax(r) < 1e-9
    # p = k y, q = 0: dp/dy - dq/dx = k everywhere (no surface has these gradients)
    r = integrability_map(normals_of(0.7 * y, np.zeros_like(y)), dom, px)
    assert np.allclose(r, 0.7, atol=1e-9)
    # outside the domain: NaN
    part = dom.copy()
    part[:, :4] = False
    assert np.isnan(integrability_map(normals_of(0.7 * y, 0 * y), part, px)[:, :4]).all()


def test_lsq_residual_zero_for_exact_lambertian_images_and_grows_with_a_wrong_normal():
    s = on_grid("sphere", 40, 1.05)
    vec = FIVE * np.pi
    imgs = lambertian_images(s.normals, 0.6, vec, mask=s.mask, radiance=True)   # rho E cos / pi
    alb = np.full(s.mask.shape, 0.6 / np.pi)
    r, rms = lsq_residual_map(imgs, vec, s.normals, alb, s.mask)
    assert rms > 0 and np.nanmax(r) < 1e-12
    tilted = s.normals.copy()
    tilted[20, 20] = normals_of(np.array(0.5), np.array(0.0))
    r2, _ = lsq_residual_map(imgs, vec, tilted, alb, s.mask)
    assert r2[20, 20] > 1e-3 and np.nanmax(np.delete(r2.ravel(), 20 * 40 + 20)) < 1e-12


def test_albedo_over_one_fraction_counts_the_planted_pixel():
    s = on_grid("sphere", 40, 1.05)
    vec = FIVE * np.pi
    imgs = lambertian_images(s.normals, 0.6, vec, mask=s.mask, radiance=True)
    alb = np.full(s.mask.shape, 0.6 / np.pi)
    sc, maps = check_scores(imgs, vec, s.normals, alb, s.mask, 2.1 / 40)
    assert sc["ps_albedo_over1_frac"] == 0.0 and sc["ps_lsq_residual"] < 1e-12
    bad = alb.copy()
    bad[20, 20] = 1.5 / np.pi                 # pi |g| = 1.5 > 1: the pi-scaled convention
    sc, maps = check_scores(imgs, vec, s.normals, bad, s.mask, 2.1 / 40)
    assert sc["ps_albedo_over1_frac"] == pytest.approx(1 / s.mask.sum())
    assert maps["pi |g|"][20, 20] == pytest.approx(1.5)
    assert set(sc) <= set(METRICS) and all(METRICS[k].better == "lower" for k in sc)


def test_correlation_of_a_check_that_ranks_the_error():
    e = np.linspace(0, 1, 50).reshape(5, 10)
    pear, spear = check_error_correlation(e ** 3, e)   # monotone, not linear
    assert spear == pytest.approx(1.0) and 0.8 < pear < 1.0
    assert check_error_correlation(-e, e)[1] == pytest.approx(-1.0)
    assert np.isnan(check_error_correlation(np.ones_like(e), e)[0])   # a constant check predicts nothing
