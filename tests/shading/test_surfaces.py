"""The named surfaces' analytic gradients against finite differences of their heights."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.shading.surfaces import SURFACES, craters, evaluate


@pytest.mark.parametrize("name", ["bumps", "random_smooth", "plane", "craters"])
def test_gradients_are_the_derivatives_of_the_height(name):
    h = 1e-5
    g = np.linspace(-0.9, 0.9, 61)
    x, y = np.meshgrid(g, g)
    s = evaluate(name, x, y)
    zx = (evaluate(name, x + h, y).z - evaluate(name, x - h, y).z) / (2 * h)
    zy = (evaluate(name, x, y + h).z - evaluate(name, x, y - h).z) / (2 * h)
    scale = max(1.0, float(np.abs(s.fx).max()))
    np.testing.assert_allclose(s.fx, zx, atol=1e-6 * scale)
    np.testing.assert_allclose(s.fy, zy, atol=1e-6 * scale)


def test_craters_are_bowls_with_raised_rims_and_follow_their_seed():
    """One crater at a known place (seeded): the centre is a bowl below the plane by about
    depth x R, the rim stands above it, and far away the plane is flat; another seed moves them."""
    rng = np.random.default_rng(0)
    x0, y0, R = rng.uniform(-0.8, 0.8), rng.uniform(-0.8, 0.8), rng.uniform(0.1, 0.3)
    centre = craters(np.array([x0]), np.array([y0]), seed=0, count=1)[0][0]
    rim = craters(np.array([x0 + R]), np.array([y0]), seed=0, count=1)[0][0]
    assert centre == pytest.approx(-0.3 * R, rel=0.01)
    assert rim == pytest.approx(0.3 * R * (0.35 - np.exp(-1 / 0.36)), rel=1e-6) and rim > 0
    far = craters(np.array([x0 + 5 * R if x0 < 0 else x0 - 5 * R]), np.array([y0]), seed=0, count=1)[0][0]
    assert abs(far) < 1e-6
    a = craters(np.linspace(-1, 1, 50), np.zeros(50), seed=1)[0]
    b = craters(np.linspace(-1, 1, 50), np.zeros(50), seed=2)[0]
    assert not np.allclose(a, b)
    assert "craters" in SURFACES
