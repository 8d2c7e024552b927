"""Closed-form interreflections inside a concave spherical cap, and what they do to photometric stereo.

On a sphere of radius ``R`` the interreflection kernel is constant: for two points ``x, x'`` of
the sphere, ``cos(theta) = cos(theta') = r / (2R)``, so

.. math::  K(x, x') = \\frac{\\cos\\theta\\cos\\theta'}{\\pi r^2} = \\frac{1}{4\\pi R^2},

and no point of the concave side hides another (the chord lies inside the ball).  For a cap of
half-angle ``alpha`` (the bowl of :func:`pbrbench.shading.surfaces.spherical_cap`, area
``A = 2 pi R^2 (1 - cos alpha)``, axis ``a`` toward the opening and the viewer) the radiosity
equation ``B = E + rho K int B`` integrates to a uniform interreflected term:

.. math::  B(x) = E(x) + \\frac{\\rho f \\bar E}{1 - \\rho f}, \\qquad
           f = \\frac{A}{4\\pi R^2} = \\frac{1 - \\cos\\alpha}{2},

with ``E`` the direct radiosity and ``E-bar`` its mean over the cap (``f`` is the form factor
from any point of the sphere to the cap).  Under a distant source ``S`` (irradiance ``E0``) with
no shadow, ``E = rho E0 N . S`` and the mean normal of the cap is ``a (1 + cos alpha) / 2``, so

.. math::  B(x) = \\rho E_0 \\, (N + \\beta a) \\cdot S, \\qquad
           \\beta = \\frac{\\rho \\sin^2\\alpha}{4 \\, (1 - \\rho (1 - \\cos\\alpha) / 2)}:

Lambertian photometric stereo with such sources recovers ``g = rho E0 (N + beta a)``, i.e. the
normal ``(N + beta a) / |N + beta a|`` (tilted toward the axis, the cap looks shallower) and the
albedo ``rho |N + beta a|`` (inflated), whatever the sources.

Shadows: a point ``x`` (unit vector ``u`` from the centre) is lit iff ``N . S > 0`` and the
reflection ``u - 2 (u . S) S`` of ``u`` (where the ray toward the source meets the sphere again)
is outside the cap.  No point is shadowed (attached or cast) iff the source's angle from the
axis is at most ``90 deg - alpha``; otherwise the closed form above still holds with ``E-bar``
the mean of the shadowed direct term (:func:`cap_mean_direct` integrates it numerically).

References
----------
D. A. Forsyth and A. Zisserman, "Reflections on shading", IEEE PAMI 13(7), 1991 (the constant
kernel inside a sphere; interreflections bias shape from shading); J. J. Koenderink and
A. J. van Doorn, "Geometrical modes as a general method to treat diffuse interreflections in
radiometry", JOSA 73(6), 1983; S. K. Nayar, K. Ikeuchi and T. Kanade, "Shape from
interreflections", IJCV 6(3), 1991.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_int, check_number, check_positive
from pbrbench.radiosity.patches import Patches, make_patches

__all__ = [
    "spherical_cap_patches",
    "cap_form_factor",
    "cap_photometric_stereo_bias",
    "cap_shadow_free",
    "cap_lit",
    "cap_mean_direct",
    "cap_radiosity",
    "cap_recovered_normals",
    "cap_photometric_stereo",
]


def _alpha(half_angle_deg) -> float:
    return np.radians(check_number(half_angle_deg, "half_angle_deg", lo=0.0, hi=90.0, lo_open=True))


def _rho(rho) -> float:
    return check_number(rho, "rho", lo=0.0, hi=1.0, hi_open=True)


def _unit(direction) -> np.ndarray:
    s = as_float_array(direction, "direction")
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.linalg.norm(s) < 1e-12:
        raise ValueError(f"direction: expected a finite non-zero 3-vector (toward the source), got {direction!r}")
    return s / np.linalg.norm(s)


def _centre(radius, half_angle_deg, center) -> np.ndarray:
    return np.array([center[0], center[1], radius * np.cos(_alpha(half_angle_deg))], float)


def cap_form_factor(half_angle_deg) -> float:
    """Form factor from any point of the sphere to the cap: ``f = (1 - cos alpha) / 2``."""
    return float((1.0 - np.cos(_alpha(half_angle_deg))) / 2.0)


def cap_photometric_stereo_bias(rho, half_angle_deg) -> float:
    """``beta = rho sin^2(alpha) / (4 (1 - rho (1 - cos alpha) / 2))``: photometric stereo on the
    cap recovers ``n-hat ∝ N + beta a`` (``a`` the cap's axis toward the viewer)."""
    r, a = _rho(rho), _alpha(half_angle_deg)
    return float(r * np.sin(a) ** 2 / (4.0 * (1.0 - r * (1.0 - np.cos(a)) / 2.0)))


def cap_shadow_free(direction, half_angle_deg) -> bool:
    """True when a distant source in ``direction`` lights the whole cap (angle from the axis <= 90 - alpha)."""
    s = _unit(direction)
    return bool(np.degrees(np.arccos(np.clip(s[2], -1, 1))) <= 90.0 - np.degrees(_alpha(half_angle_deg)) + 1e-9)


def cap_lit(points, direction, *, radius: float = 1.0, half_angle_deg: float = 60.0, center=(0.0, 0.0)) -> np.ndarray:
    """Which points of the cap (..., 3) a distant source in ``direction`` lights (attached and cast shadows)."""
    R = check_positive(radius, "radius")
    s = _unit(direction)
    c = _centre(R, half_angle_deg, center)
    u = (as_float_array(points, "points") - c) / R
    us = u @ s
    u2 = u - 2 * us[..., None] * s
    return (-us > 0) & (-u2[..., 2] < np.cos(_alpha(half_angle_deg)) - 1e-12)


def cap_mean_direct(rho, half_angle_deg, direction, irradiance: float = 1.0, *, n: int = 600) -> float:
    """Mean over the cap of the direct radiosity ``rho E0 max(0, N.S) lit(x)``.

    Closed form ``rho E0 (a . S) (1 + cos alpha) / 2`` when the source lights the whole cap;
    otherwise a product Gauss-Legendre (polar angle, ``n`` nodes) x midpoint (azimuth, ``2n``)
    rule over the cap with the exact lit indicator (error about ``1/n`` from the shadow edge).
    """
    r, a = _rho(rho), _alpha(half_angle_deg)
    s = _unit(direction)
    e0 = check_number(irradiance, "irradiance", lo=0.0)
    if cap_shadow_free(s, half_angle_deg):
        return float(r * e0 * s[2] * (1.0 + np.cos(a)) / 2.0)
    n = check_int(n, "n", 8, 20000)
    g, w = np.polynomial.legendre.leggauss(n)
    th = 0.5 * a * (g + 1)
    wt = 0.5 * a * w * np.sin(th)
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    T, P = np.meshgrid(th, ph, indexing="ij")
    u = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), -np.cos(T)], -1)
    lit = cap_lit(u + np.array([0, 0, np.cos(a)]), s, radius=1.0, half_angle_deg=half_angle_deg)
    e = r * e0 * np.maximum(-(u @ s), 0.0) * lit
    tot = np.sum(e * wt[:, None]) * (np.pi / n)
    return float(tot / (2 * np.pi * (1 - np.cos(a))))


def cap_radiosity(points, *, rho, half_angle_deg, direction, irradiance: float = 1.0, radius: float = 1.0,
                  center=(0.0, 0.0)) -> np.ndarray:
    """Exact radiosity at points (..., 3) of the cap under a distant source (see the module docstring).

    .. math::  B(x) = \\rho E_0 \\max(0, N \\cdot S)\\,\\mathrm{lit}(x) + \\frac{\\rho f \\bar E}{1 - \\rho f}
    """
    r = _rho(rho)
    s = _unit(direction)
    R = check_positive(radius, "radius")
    c = _centre(R, half_angle_deg, center)
    p = as_float_array(points, "points")
    N = (c - p) / R
    lit = cap_lit(p, s, radius=R, half_angle_deg=half_angle_deg, center=center)
    f = cap_form_factor(half_angle_deg)
    ebar = cap_mean_direct(r, half_angle_deg, s, irradiance)
    return r * irradiance * np.maximum(N @ s, 0.0) * lit + r * f * ebar / (1.0 - r * f)


def cap_recovered_normals(normals, rho, half_angle_deg) -> tuple[np.ndarray, np.ndarray]:
    """Photometric stereo's answer on the cap: unit normals ``(N + beta a)/|N + beta a|`` and the
    albedo inflation factor ``|N + beta a|`` (recovered albedo / true albedo), ``a = (0, 0, 1)``."""
    N = as_float_array(normals, "normals")
    beta = cap_photometric_stereo_bias(rho, half_angle_deg)
    g = N + beta * np.array([0.0, 0.0, 1.0])
    k = np.linalg.norm(g, axis=-1)
    return g / k[..., None], k


def cap_photometric_stereo(x, y, *, rho, half_angle_deg: float = 60.0, radius: float = 1.0, center=(0.0, 0.0)):
    """True normals, recovered normals, recovered albedo and mask of the cap at world points ``(x, y)``.

    Returns ``(N, N_hat, albedo_hat, mask)``; outside ``mask`` the arrays are 0.  The recovered
    albedo is ``rho |N + beta a|`` (for shadow-free sources, whatever they are).
    """
    from pbrbench.shading.surfaces import evaluate

    surf = evaluate("spherical_cap", x, y, radius=radius, half_angle_deg=half_angle_deg, center=center)
    N = surf.normals
    Nh, k = cap_recovered_normals(N, rho, half_angle_deg)
    Nh[~surf.mask] = 0.0
    return N, Nh, np.where(surf.mask, _rho(rho) * k, 0.0), surf.mask


def spherical_cap_patches(radius: float = 1.0, half_angle_deg: float = 60.0, *, n_rings: int = 8,
                          n_azimuth: int | None = None, center=(0.0, 0.0), albedo=0.5) -> Patches:
    """A polyhedral cap inscribed in the sphere: ``n_rings`` rings of planar trapezoids (triangles at the pole).

    Vertices lie on the sphere of :func:`pbrbench.shading.surfaces.spherical_cap` (rim at
    ``z = 0``) at polar angles ``theta_k = alpha k / n_rings`` from the bottom and azimuths
    ``2 pi m / n_azimuth``; the four corners of a ring cell are coplanar (an isosceles
    trapezoid), so the patches are exact planar polygons.  ``n_azimuth`` defaults to the
    number that makes the rim cells about square.  Normals face the sphere's centre.
    """
    R = check_positive(radius, "radius")
    a = _alpha(half_angle_deg)
    n_rings = check_int(n_rings, "n_rings", 1, 2000)
    if n_azimuth is None:
        n_azimuth = max(8, int(round(2 * np.pi * np.sin(a) / (a / n_rings))))
    n_az = check_int(n_azimuth, "n_azimuth", 3, 20000)
    c = _centre(R, half_angle_deg, center)
    th = np.linspace(0.0, a, n_rings + 1)
    ph = np.linspace(0.0, 2 * np.pi, n_az + 1)

    def pt(t, p):
        return c + R * np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), -np.cos(t) * np.ones_like(p)], -1)

    p0, p1 = ph[:-1], ph[1:]
    cells = []
    for k in range(n_rings):
        if k == 0:  # the pole: triangles (pole, (t1, p0), (t1, p1)), last vertex repeated
            b, d = pt(th[1], p0), pt(th[1], p1)
            cells.append(np.stack([pt(0.0, p0), b, d, d], axis=1))
        else:
            cells.append(np.stack([pt(th[k], p0), pt(th[k + 1], p0), pt(th[k + 1], p1), pt(th[k], p1)], axis=1))
    v = np.concatenate(cells)
    nrm = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    if np.any(np.sum(nrm * (c - v.mean(axis=1)), axis=1) <= 0):  # pragma: no cover - the order above faces c
        raise AssertionError("spherical_cap_patches: a cell faces away from the centre")
    return make_patches(v, albedo, face_id=np.zeros(len(v), int))
