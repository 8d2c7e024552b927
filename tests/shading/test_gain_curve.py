"""The gain curve of interreflection (a patch above a plane of sinusoidal radiosity)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import dblquad
from scipy.special import k1

from pbrbench.shading.gain_curve import (
    gain_curve,
    gain_kernel,
    gain_measurement_spec,
    gain_response,
)


def test_frontal_patch_gain_is_omega_k1():
    om = np.array([0.25, 0.5, 1.0, 2.0, 4.0, 8.0])
    np.testing.assert_allclose(gain_curve(om, [0.0])[0], om * k1(om), rtol=1e-8, atol=1e-9)  # QAWF: ~1e-10 absolute


def test_gain_at_zero_frequency_is_the_visible_form_factor():
    slants = np.linspace(0, np.pi / 2, 10)
    G = gain_curve([0.0], slants)[:, 0]
    np.testing.assert_allclose(G, (1 + np.cos(slants)) / 2, rtol=1e-9)  # 1 facing the plane, 1/2 edge-on


def test_gain_falls_off_fast():
    G = gain_curve(np.array([0.0, 1.0, 2.0, 4.0]))
    assert G.shape == (10, 4)
    assert np.all(np.diff(G, axis=1) < 0)
    assert np.all(G[:, 3] < 0.12 * G[:, 0])  # a factor of ten lost by omega = 4 at every slant


def test_y_integral_in_closed_form_against_a_2d_quadrature():
    s, w, Y = 0.7, 1.3, 3.0
    x0 = -np.cos(s) / np.sin(s)

    def kern(y, x, f):
        return max(0.0, x * np.sin(s) + np.cos(s)) / (np.pi * (1 + x * x + y * y) ** 2) * f(w * x)

    re = dblquad(kern, x0, Y, -Y, Y, args=(np.cos,), epsabs=1e-11)[0]
    im = dblquad(kern, x0, Y, -Y, Y, args=(np.sin,), epsabs=1e-11)[0]
    H = gain_response(w, s, half_size=Y)
    assert H.real == pytest.approx(re, abs=1e-8) and H.imag == pytest.approx(im, abs=1e-8)
    # the finite square tends to the infinite plane
    assert abs(gain_response(w, s, half_size=200.0) - gain_response(w, s)) < 1e-4
    x = np.linspace(-5, 5, 11)
    assert np.all(gain_kernel(x, s)[x < x0] == 0)


def test_measurement_spec_expected_irradiance():
    d = gain_measurement_spec(1.0, 0.3, phase=0.4, plane_half_size=10.0, modulation=0.5, radiance=2.0)
    H = gain_response(1.0, 0.3, half_size=10.0)
    F = gain_response(0.0, 0.3, half_size=10.0).real
    assert d["expected_irradiance"] == pytest.approx(np.pi * 2.0 * (F + 0.5 * (np.exp(0.4j) * H).imag))
    assert d["plane"]["radiance"].min() >= 0 and np.allclose(d["patch"]["normal"], [np.sin(0.3), 0, -np.cos(0.3)])
    with pytest.raises(ValueError, match="slant"):
        gain_response(1.0, 2.0)
    with pytest.raises(ValueError, match="omegas"):
        gain_curve([-1.0])
