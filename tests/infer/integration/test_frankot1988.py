"""Tests of Frankot & Chellappa (1988) Fourier integration (``pbrbench.infer.integration.frankot1988``)."""

import numpy as np

from pbrbench.infer.integration import integrate_frankot1988, integrate_normals
from pbrbench.shading.surfaces import pixel_grid
from tests.infer.integration._fields import HW, H, N, periodic_field, rel_rmse


def test_frankot1988_fails_on_non_periodic_surface():
    # known failure mode: FC assumes a periodic field; a paraboloid's slopes jump at the border
    x, y = pixel_grid(N, N, HW)
    z = 0.3 * x**2 - 0.2 * x * y + 0.1 * y**2
    p, q = 0.6 * x - 0.2 * y, -0.2 * x + 0.2 * y
    full = np.ones_like(z, bool)
    fc = rel_rmse(integrate_normals(gradients=(p, q), method="frankot1988", pixel_size=H), z, full)
    for method in ("lsq", "simchony1990", "path"):
        est = integrate_normals(gradients=(p, q), method=method, pixel_size=H)
        assert rel_rmse(est, z, full) < 1e-3
    assert fc > 0.05


def test_spectrally_exact_on_a_periodic_surface():
    z, p, q = periodic_field()
    est = integrate_frankot1988(gradients=(p, q), pixel_size=H)
    assert rel_rmse(est, z, np.ones_like(z, bool)) < 1e-10
    assert abs(est.mean()) < 1e-12
