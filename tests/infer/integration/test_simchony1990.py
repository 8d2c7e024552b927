"""Tests of Simchony, Chellappa & Shao (1990) DCT integration (``pbrbench.infer.integration.simchony1990``)."""

import numpy as np

from pbrbench.infer.integration import integrate_lsq, integrate_simchony1990
from pbrbench.shading.surfaces import on_grid
from tests.infer.integration._fields import HW, H, N, irregular_mask, paraboloid_field, rel_rmse


def test_accurate_on_a_non_periodic_surface_over_the_rectangle():
    # Neumann, not periodic: a paraboloid (where Fourier integration fails) comes back to the
    # trapezoid rule's O(h^2)
    z, p, q = paraboloid_field()
    est = integrate_simchony1990(gradients=(p, q), pixel_size=H)
    assert rel_rmse(est, z, np.ones_like(z, bool)) < 1e-3


def test_the_rectangle_biases_a_masked_domain():
    # failure mode: the gradients outside the mask are taken as 0 and integrated with the rest
    s = on_grid("bumps", N, HW)
    m = irregular_mask(s)
    err = rel_rmse(integrate_simchony1990(s.normals, mask=m, pixel_size=H), s.z, m)
    assert err > 10 * rel_rmse(integrate_lsq(s.normals, mask=m, pixel_size=H), s.z, m)
