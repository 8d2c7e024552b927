"""Shared grid, masks and error measure of the surface-integration tests."""

import numpy as np

from pbrbench.shading.surfaces import pixel_grid

N = 96
HW = 1.0
H = 2 * HW / N  # world size of one pixel


def irregular_mask(surface):
    """A blob with a notch inside the surface's mask: non-convex, non-rectangular."""
    x, y = pixel_grid(N, N, HW)
    blob = ((x / 0.9) ** 2 + (y / 0.7) ** 2 < 1) | ((x - 0.3) ** 2 + (y + 0.5) ** 2 < 0.2)
    return surface.mask & blob & ~((x > 0.2) & (np.abs(y) < 0.15))  # a notch: non-convex


def rel_rmse(z, truth, m):
    """RMS height error after the free offset, relative to the true height range."""
    d = z[m] - truth[m]
    d -= d.mean()
    return np.sqrt(np.mean(d**2)) / np.ptp(truth[m])


def periodic_field():
    """A surface periodic on the film (period 2 = the film's width) and its exact slopes."""
    x, y = pixel_grid(N, N, HW)
    z = 0.1 * np.sin(np.pi * x) * np.cos(np.pi * y) + 0.05 * np.sin(2 * np.pi * y)
    p = 0.1 * np.pi * np.cos(np.pi * x) * np.cos(np.pi * y)
    q = -0.1 * np.pi * np.sin(np.pi * x) * np.sin(np.pi * y) + 0.1 * np.pi * np.cos(2 * np.pi * y)
    return z, p, q


def paraboloid_field():
    """A non-periodic quadratic surface and its exact slopes."""
    x, y = pixel_grid(N, N, HW)
    z = 0.3 * x**2 - 0.2 * x * y + 0.1 * y**2
    p, q = 0.6 * x - 0.2 * y, -0.2 * x + 0.2 * y
    return z, p, q
