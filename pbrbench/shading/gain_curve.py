"""The gain of interreflection: how much of a sinusoidal radiosity pattern jumps a gap (chapter Fig 1.19).

A small patch at unit height above an infinite plane ``z = 0`` whose radiosity is
``sin(omega x)``, its normal slanted by ``sigma`` toward +x from the plane's normal
(``n = (sin sigma, 0, -cos sigma)``, facing the plane).  Its irradiance (per unit radiosity
amplitude) is the kernel integral

.. math::  H(\\omega, \\sigma) = \\int\\!\\!\\int K \\, e^{i\\omega x} \\, dx\\,dy, \\qquad
           K = \\frac{\\max(0, \\cos\\theta)\\cos\\theta'}{\\pi r^2}
             = \\frac{\\max(0,\\, x\\sin\\sigma + \\cos\\sigma)}{\\pi (1 + x^2 + y^2)^2},

and as the patch slides along x its irradiance is ``|H| sin(omega x0 + arg H)``: the *gain* is
``G = |H|``.  The y integral is closed-form, ``int dy / (a^2 + y^2)^2 = pi / (2 a^3)`` with
``a^2 = 1 + x^2``, leaving

.. math::  H = \\int_{x_0}^{\\infty} k_\\sigma(x) e^{i\\omega x} dx, \\qquad
           k_\\sigma(x) = \\frac{x\\sin\\sigma + \\cos\\sigma}{2 (1 + x^2)^{3/2}}, \\quad
           x_0 = -\\cot\\sigma,

a one-dimensional Fourier integral done with QUADPACK's oscillatory rules (``scipy.integrate.quad``
with ``weight='cos'/'sin'``; QAWF for the infinite tail).  Checks: at ``omega = 0`` the gain is
the form factor of the visible half-space of the plane, ``(1 + cos sigma) / 2``; for
``sigma = 0``, ``G = omega K_1(omega)`` (modified Bessel function), which falls off as
``sqrt(pi omega / 2) e^{-omega}``: high spatial frequencies do not cross the gap.  By scale
invariance a patch at height ``h`` reads the curve at ``omega h``; a patch on a surface slanted
by ``sigma`` sees the pattern at frequency ``omega cos(sigma)`` along that surface.

References
----------
J. J. Koenderink and A. J. van Doorn, "Geometrical modes as a general method to treat diffuse
interreflections in radiometry", JOSA 73(6), 1983; J. Haddon and D. A. Forsyth, "Shading
primitives: finding folds and shallow grooves", ICCV 1998 (the figure); D. A. Forsyth and
A. Zisserman, "Reflections on shading", IEEE PAMI 13(7), 1991.
"""

from __future__ import annotations

import math

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_number, check_positive

__all__ = [
    "gain_kernel",
    "gain_response",
    "gain_curve",
    "gain_measurement_spec",
]


def _slant(slant) -> float:
    return check_number(slant, "slant", lo=0.0, hi=np.pi / 2)


def gain_kernel(x, slant, *, half_size: float | None = None) -> np.ndarray:
    """The kernel integrated along y, ``k(x) = max(0, x sin s + cos s) / (2 (1 + x^2)^{3/2})``.

    With ``half_size = Y`` the plane is the square ``|x|, |y| <= Y`` and the y integral is
    ``(1/pi) [Y / (a^2 (a^2 + Y^2)) + arctan(Y / a) / a^3]`` instead of ``1 / (2 a^3)`` (and
    ``k = 0`` for ``|x| > Y``).
    """
    s = _slant(slant)
    x = as_float_array(x, "x")
    a2 = 1.0 + x * x
    vis = np.maximum(x * np.sin(s) + np.cos(s), 0.0)
    if half_size is None:
        return vis / (2.0 * a2 ** 1.5)
    Y = check_positive(half_size, "half_size")
    a = np.sqrt(a2)
    yint = (Y / (a2 * (a2 + Y * Y)) + np.arctan(Y / a) / a ** 3) / np.pi
    return np.where(np.abs(x) <= Y, vis * yint, 0.0)


def gain_response(omega, slant, *, half_size: float | None = None) -> complex:
    """``H(omega, slant) = int k(x) e^{i omega x} dx`` (the patch's complex response; gain = |H|).

    ``half_size`` restricts the plane to ``|x|, |y| <= half_size`` (the finite plane of a
    measurement).  Accuracy about 1e-10 absolute (QUADPACK tolerances).
    """
    from scipy.integrate import quad

    w = check_number(omega, "omega", lo=0.0)
    s = _slant(slant)
    x0 = -np.inf if s == 0 else -np.cos(s) / np.sin(s)
    X = np.inf if half_size is None else check_positive(half_size, "half_size")
    lo = max(x0, -X)

    ss, cs = math.sin(s), math.cos(s)
    Y = None if half_size is None else float(half_size)

    def k(x):  # gain_kernel for one point, without the argument checks (QUADPACK calls it thousands of times)
        a2 = 1.0 + x * x
        vis = max(x * ss + cs, 0.0)
        if Y is None:
            return vis / (2.0 * a2 ** 1.5)
        if abs(x) > Y:
            return 0.0
        a = math.sqrt(a2)
        return vis * (Y / (a2 * (a2 + Y * Y)) + math.atan(Y / a) / a ** 3) / math.pi

    opts = dict(limit=400, epsabs=1e-12, epsrel=1e-10)
    re = im = 0.0
    if w == 0:
        if np.isinf(lo):
            re = 2 * quad(k, 0, X, **opts)[0]
        else:
            re = quad(k, lo, 0, **opts)[0] + quad(k, 0, X, **opts)[0]
        return complex(re, 0.0)
    if np.isinf(X):  # tail [0, inf) by QAWF
        re += quad(k, 0, np.inf, weight="cos", wvar=w, limlst=200)[0]
        im += quad(k, 0, np.inf, weight="sin", wvar=w, limlst=200)[0]
    else:
        re += quad(k, 0, X, weight="cos", wvar=w, **opts)[0]
        im += quad(k, 0, X, weight="sin", wvar=w, **opts)[0]
    if np.isinf(lo):  # sigma = 0: the kernel is even
        re *= 2
        im = 0.0
    else:
        re += quad(k, lo, 0, weight="cos", wvar=w, **opts)[0]
        im += quad(k, lo, 0, weight="sin", wvar=w, **opts)[0]
    return complex(re, im)


def gain_curve(omegas, slants=None) -> np.ndarray:
    """Gains ``|H(omega, slant)|`` (len(slants), len(omegas)); default slants: 10 from 0 to pi/2."""
    om = as_float_array(omegas, "omegas", ndim=(0, 1)).ravel()
    check_finite(om, "omegas")
    if np.any(om < 0):
        raise ValueError("omegas: spatial frequencies must be >= 0")
    sl = np.linspace(0.0, np.pi / 2, 10) if slants is None else as_float_array(slants, "slants", ndim=(0, 1)).ravel()
    return np.array([[abs(gain_response(w, s)) for w in om] for s in sl])


# ------------------------------------------------------------------ a measurement to render
# (rendered by pbrbench.render.proofs.gain.measure_gain_mitsuba: shading never imports Mitsuba)
def gain_measurement_spec(omega: float, slant: float, *, phase: float = 0.0, plane_half_size: float = 30.0,
                          radiance: float = 1.0, modulation: float = 0.5, patch_half_size: float = 0.01,
                          texels: int = 8192) -> dict:
    """One point of the gain curve as a renderable description (a plain dict of NumPy values).

    An emitting square ``|x|, |y| <= plane_half_size`` in ``z = 0`` (facing +z) of radiance
    ``L(x) = radiance (1 + modulation sin(omega x + phase))``, tabulated at ``texels`` texel
    centres along x (bilinear filtering), and a small square patch (half side
    ``patch_half_size``) centred at ``(0, 0, 1)`` with normal ``(sin slant, 0, -cos slant)``
    measuring irradiance (Mitsuba's ``irradiancemeter``).  Expected irradiance:
    ``pi radiance (F + modulation Im(e^{i phase} H))`` with ``F = H(0)`` and ``H`` of the finite
    plane (:func:`gain_response` with ``half_size``).
    """
    w = check_number(omega, "omega", lo=0.0)
    s = _slant(slant)
    X = check_positive(plane_half_size, "plane_half_size")
    m = check_number(modulation, "modulation", lo=0.0, hi=1.0)
    L0 = check_positive(radiance, "radiance")
    xs = X * (2 * (np.arange(int(texels)) + 0.5) / int(texels) - 1)
    tex = L0 * (1 + m * np.sin(w * xs + phase))
    H, F = gain_response(w, s, half_size=X), gain_response(0.0, s, half_size=X).real
    expected = np.pi * L0 * (F + m * (np.exp(1j * phase) * H).imag)
    return {"plane": {"half_size": X, "texture_x": xs, "radiance": tex},
            "patch": {"center": np.array([0.0, 0.0, 1.0]), "normal": np.array([np.sin(s), 0.0, -np.cos(s)]),
                      "half_size": float(patch_half_size)},
            "omega": w, "slant": s, "phase": float(phase), "modulation": m, "mean_radiance": L0,
            "expected_irradiance": float(expected), "H": H}
