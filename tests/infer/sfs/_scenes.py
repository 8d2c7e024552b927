"""Analytic Lambertian scenes shared by the shape-from-shading tests (exact shapes known)."""

import numpy as np

from pbrbench.metrics.sfs import normal_angle
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid

HW = 1.1
OBLIQUE = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
FRONTAL = np.array([0.0, 0.0, 1.0])


def scene(name, n, light, albedo=0.8):
    """Surface, its Lambertian image under ``light`` and the pixel size."""
    s = on_grid(name, n, half_width=HW)
    img = lambertian_images(s.normals, albedo, light[None])[0]
    return s, img, 2 * HW / n


def flat_angle(s):
    """Mean normal angle of the flat answer (normals along the view): the score to beat."""
    flat = np.zeros(s.normals.shape)
    flat[..., 2] = 1.0
    return normal_angle(flat, s.normals, s.mask)
