"""Named analytic surfaces ``z = f(x, y)`` with exact gradients.

Used twice: by scene files (a heightfield mesh built from a named surface) and by the analytic
tests of the inference package.  Frame of docs/conventions.md: x right, y up, z toward the camera;
row 0 of an image is the top (largest y).  The unit normal of the Monge patch is
``N = (-f_x, -f_y, 1) / sqrt(1 + f_x**2 + f_y**2)``.

Every surface function takes world coordinates ``x, y`` (arrays of one shape) and keyword
parameters, and returns ``(z, fx, fy, mask)``: height, its exact partial derivatives and the
domain where the surface is defined.  Outside the mask the values are 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Surface:
    """Height, exact gradient and domain of an analytic surface sampled on a grid."""

    z: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    mask: np.ndarray

    @property
    def normals(self) -> np.ndarray:
        """Unit normals (H, W, 3) in the camera frame; (0, 0, 0) outside the mask."""
        return normals_from_gradients(self.fx, self.fy, self.mask)


def pixel_grid(height: int, width: int | None = None, half_width: float = 1.0):
    """World coordinates of pixel centres of an orthographic film.

    The film covers ``x in [-half_width, half_width]`` and ``y in [-h, h]`` with
    ``h = half_width * height / width``, as Mitsuba's orthographic camera scaled by
    ``half_width`` does.  Returns ``(x, y)`` arrays of shape (height, width); row 0 is the top.
    """
    width = height if width is None else width
    j = np.arange(width) + 0.5
    i = np.arange(height) + 0.5
    x = half_width * (2.0 * j / width - 1.0)
    y = half_width * (1.0 - 2.0 * i / height) * (height / width)
    return np.meshgrid(x, y)


def normals_from_gradients(fx: np.ndarray, fy: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Unit normals ``(-fx, -fy, 1)/norm`` (H, W, 3); zero outside ``mask``."""
    n = np.stack([-fx, -fy, np.ones_like(fx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    if mask is not None:
        n[~mask] = 0.0
    return n


def sphere(x, y, *, radius: float = 1.0, center=(0.0, 0.0)):
    """Upper hemisphere ``z = sqrt(R^2 - r^2)`` (convex, facing the camera)."""
    dx, dy = x - center[0], y - center[1]
    r2 = dx * dx + dy * dy
    mask = r2 < radius * radius
    z = np.sqrt(np.where(mask, radius * radius - r2, 1.0))
    fx = np.where(mask, -dx / z, 0.0)
    fy = np.where(mask, -dy / z, 0.0)
    return np.where(mask, z, 0.0), fx, fy, mask


def cup(x, y, *, radius: float = 1.0, center=(0.0, 0.0)):
    """Inside of a hemispherical cup ``z = -sqrt(R^2 - r^2)`` (concave, opening to the camera)."""
    z, fx, fy, mask = sphere(x, y, radius=radius, center=center)
    return -z, -fx, -fy, mask


def spherical_cap(x, y, *, radius: float = 1.0, half_angle_deg: float = 60.0, center=(0.0, 0.0)):
    """Concave spherical cap (a bowl) of half-angle ``alpha``, opening toward the camera, rim at ``z = 0``.

    .. math::  z = R\\cos\\alpha - \\sqrt{R^2 - r^2}, \\qquad r < R \\sin\\alpha

    with ``r`` the distance from ``center``: the part of the sphere of radius ``R`` centred at
    ``(cx, cy, R cos(alpha))`` whose points make an angle below ``alpha`` with the downward axis
    from that centre.  The rim (``r = R sin(alpha)``) lies at ``z = 0``, the bottom at
    ``z = -R (1 - cos(alpha))``; the unit normal points toward the sphere's centre (the concave
    side, toward the camera).  ``half_angle_deg`` must lie in (0, 90]: beyond 90 degrees the bowl
    overhangs and is not a height field.  ``half_angle_deg = 90`` is :func:`cup`.
    """
    alpha = float(half_angle_deg)
    if not 0.0 < alpha <= 90.0:
        raise ValueError(f"half_angle_deg: must be in (0, 90] (a bowl that does not overhang), got {half_angle_deg!r}")
    if not float(radius) > 0:
        raise ValueError(f"radius: must be > 0, got {radius!r}")
    a = np.radians(alpha)
    dx, dy = x - center[0], y - center[1]
    r2 = dx * dx + dy * dy
    mask = r2 < (radius * np.sin(a)) ** 2
    root = np.sqrt(np.where(mask, radius * radius - r2, 1.0))
    z = np.where(mask, radius * np.cos(a) - root, 0.0)
    fx = np.where(mask, dx / root, 0.0)
    fy = np.where(mask, dy / root, 0.0)
    return z, fx, fy, mask


def vase(x, y, *, half_height: float = 0.9, r0: float = 0.45, a1: float = 0.2, a2: float = 0.08):
    """Surface of revolution about the y axis, ``z = sqrt(r(y)^2 - x^2)``.

    Profile ``r(y) = r0 + a1 cos(pi y / (2 h) * 1.5) + a2 sin(2 pi y / h)`` for ``|y| < h``.
    """
    h = half_height
    inside_y = np.abs(y) < h
    k1, k2 = 1.5 * np.pi / (2 * h), 2 * np.pi / h
    r = r0 + a1 * np.cos(k1 * y) + a2 * np.sin(k2 * y)
    dr = -a1 * k1 * np.sin(k1 * y) + a2 * k2 * np.cos(k2 * y)
    mask = inside_y & (x * x < r * r)
    z = np.sqrt(np.where(mask, r * r - x * x, 1.0))
    fx = np.where(mask, -x / z, 0.0)
    fy = np.where(mask, r * dr / z, 0.0)
    return np.where(mask, z, 0.0), fx, fy, mask


def bumps(x, y, *, centers=((-0.4, 0.3), (0.35, 0.25), (0.0, -0.4)), amplitudes=(0.35, 0.25, 0.3),
          sigmas=(0.25, 0.2, 0.3), extent: float = 1.0):
    """Sum of Gaussian bumps ``z = sum_i a_i exp(-|p - c_i|^2 / (2 s_i^2))`` on ``|x|,|y| < extent``."""
    z = np.zeros_like(x, dtype=float)
    fx = np.zeros_like(z)
    fy = np.zeros_like(z)
    for (cx, cy), a, s in zip(centers, amplitudes, sigmas, strict=True):
        g = a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
        z += g
        fx += -g * (x - cx) / (s * s)
        fy += -g * (y - cy) / (s * s)
    mask = (np.abs(x) < extent) & (np.abs(y) < extent)
    return z, fx, fy, mask


def groove(x, y, *, slope: float = 1.0, extent: float = 1.0):
    """Concave V groove ``z = slope * |x|`` along the y axis (slope 1: a right-angled groove)."""
    z = slope * np.abs(x)
    fx = slope * np.sign(x)
    fy = np.zeros_like(z)
    mask = (np.abs(x) < extent) & (np.abs(y) < extent)
    return z, fx, fy, mask


def random_smooth(x, y, *, seed: int = 0, n_waves: int = 12, amplitude: float = 0.08,
                  max_frequency: float = 3.0, extent: float = 1.0):
    """A smooth random surface: a seeded sum of plane waves ``sum_k a_k sin(w_k . p + phi_k)``.

    Frequencies (radians per world unit) are drawn uniformly in ``[0.5, max_frequency] * pi``;
    the amplitudes fall off as 1/|w| so the slopes stay moderate.
    """
    rng = np.random.default_rng(seed)
    theta = rng.uniform(0, 2 * np.pi, n_waves)
    freq = rng.uniform(0.5, max_frequency, n_waves) * np.pi
    phase = rng.uniform(0, 2 * np.pi, n_waves)
    amp = amplitude * rng.uniform(0.5, 1.0, n_waves) / (freq / np.pi)
    z = np.zeros_like(x, dtype=float)
    fx = np.zeros_like(z)
    fy = np.zeros_like(z)
    for t, f, ph, a in zip(theta, freq, phase, amp, strict=True):
        wx, wy = f * np.cos(t), f * np.sin(t)
        arg = wx * x + wy * y + ph
        z += a * np.sin(arg)
        c = a * np.cos(arg)
        fx += c * wx
        fy += c * wy
    mask = (np.abs(x) < extent) & (np.abs(y) < extent)
    return z, fx, fy, mask


def plane(x, y, *, fx: float = 0.0, fy: float = 0.0, extent: float = 1.0):
    """Tilted plane ``z = fx x + fy y``."""
    z = fx * x + fy * y
    mask = (np.abs(x) < extent) & (np.abs(y) < extent)
    return z, np.full_like(z, fx), np.full_like(z, fy), mask


def craters(x, y, *, seed: int = 0, count: int = 9, r_min: float = 0.1, r_max: float = 0.3,
            depth: float = 0.3, rim: float = 0.35, extent: float = 1.0):
    r"""A cratered relief (the chapter's Fig 1.23, the moon): ``count`` seeded craters of radius
    ``R`` in ``[r_min, r_max]`` on a plane, each a bowl and a raised rim,

    .. math:: h(r) = d R \left[ \rho\, e^{-((r - R) / w)^2} - e^{-(r / (0.6 R))^2} \right],
              \quad w = 0.25 R,

    (``d = depth``, ``rho = rim``: the rim's height over the bowl's depth), summed; gradients
    analytic.  Centres uniform over ``|x|, |y| < 0.8 extent``."""
    rng = np.random.default_rng(seed)
    cx = rng.uniform(-0.8, 0.8, count) * extent
    cy = rng.uniform(-0.8, 0.8, count) * extent
    radii = rng.uniform(r_min, r_max, count)
    z = np.zeros_like(x, dtype=float)
    fx = np.zeros_like(z)
    fy = np.zeros_like(z)
    for x0, y0, R in zip(cx, cy, radii, strict=True):
        dx, dy = x - x0, y - y0
        r = np.hypot(dx, dy)
        w, b = 0.25 * R, 0.6 * R
        ring = np.exp(-((r - R) / w) ** 2)
        bowl = np.exp(-(r / b) ** 2)
        z += depth * R * (rim * ring - bowl)
        # dh/dr / r, finite at r = 0 (the ring's term is ~exp(-16) there)
        g = depth * R * (rim * ring * (-2.0 * (r - R) / (w * w)) / np.maximum(r, 1e-12) + bowl * 2.0 / (b * b))
        fx += g * dx
        fy += g * dy
    mask = (np.abs(x) < extent) & (np.abs(y) < extent)
    return z, fx, fy, mask


SURFACES = {
    "sphere": sphere,
    "cup": cup,
    "spherical_cap": spherical_cap,
    "vase": vase,
    "bumps": bumps,
    "groove": groove,
    "random_smooth": random_smooth,
    "plane": plane,
    "craters": craters,
}


def evaluate(name: str, x, y, **params) -> Surface:
    """Evaluate the named surface at world coordinates ``(x, y)``.

    Raises ``ValueError`` listing the valid names when ``name`` is unknown.
    """
    if name not in SURFACES:
        raise ValueError(f"surface {name!r} is not known; choose one of {', '.join(sorted(SURFACES))}")
    z, fx, fy, mask = SURFACES[name](np.asarray(x, float), np.asarray(y, float), **params)
    return Surface(np.asarray(z, float), np.asarray(fx, float), np.asarray(fy, float), np.asarray(mask, bool))


def on_grid(name: str, size: int, half_width: float = 1.0, **params) -> Surface:
    """Evaluate the named surface at the pixel centres of a ``size`` x ``size`` orthographic film."""
    x, y = pixel_grid(size, size, half_width)
    return evaluate(name, x, y, **params)
