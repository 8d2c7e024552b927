"""The local shading model: Lambertian images from normals, albedo and distant sources.

``I_k(x) = rho(x) * E_k * max(0, N(x) . S_k) / pi`` (docs/conventions.md), or without the 1/pi when
``radiance=False`` (the chapter's ``I = rho I0 cos(theta)`` with the 1/pi absorbed).
"""

from __future__ import annotations

import numpy as np


def lambertian_images(normals, albedo, lights, *, intensities=None, mask=None, radiance: bool = False):
    """Render K images of a Lambertian surface under distant sources.

    Parameters
    ----------
    normals : (H, W, 3) unit normals in the camera frame (x right, y up, z toward the camera).
    albedo : scalar, (H, W) or (H, W, C) albedo.
    lights : (K, 3) directions toward the sources; their length multiplies the intensity.
    intensities : optional (K,) or (K, C) source intensities (irradiance E_k).
    mask : optional (H, W) boolean; pixels outside are 0.
    radiance : if True divide by pi (outgoing radiance ``rho E cos / pi``).

    Returns
    -------
    (K, H, W) or (K, H, W, C) float64 images.
    """
    n = np.asarray(normals, float)
    s = np.atleast_2d(np.asarray(lights, float))
    shading = np.maximum(np.einsum("hwc,kc->khw", n, s), 0.0)  # (K, H, W)
    a = np.asarray(albedo, float)
    if intensities is not None:
        e = np.asarray(intensities, float)
        shading = shading[..., None] * e[:, None, None, :] if e.ndim == 2 else shading * e[:, None, None]
    if shading.ndim == 4 or a.ndim == 3:
        if shading.ndim == 3:
            shading = shading[..., None]
        img = shading * (a if a.ndim == 3 else a[..., None])
    else:
        img = shading * a
    if radiance:
        img = img / np.pi
    if mask is not None:
        img[:, ~np.asarray(mask, bool)] = 0.0
    return img


def ring_lights(k: int = 12, elevations=(35.0, 55.0)) -> np.ndarray:
    """``k`` unit light directions on a ring around the view axis, alternating two elevations (deg)."""
    i = np.arange(k)
    az = 2 * np.pi * i / k
    el = np.radians(np.where(i % 2 == 0, elevations[0], elevations[1]))
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)


def blinn_phong_highlights(normals, lights, shininess: float, *, mask=None) -> np.ndarray:
    """White specular lobes ``max(0, N . H_k)^n [N . S_k > 0]`` (Blinn, SIGGRAPH 1977), (K, H, W).

    ``H_k`` is the unit half-vector of the source direction ``S_k`` and the orthographic view
    ``V = (0, 0, 1)``; only the directions of ``lights`` matter.  Pixels outside ``mask`` are 0.
    """
    n = np.asarray(normals, float)
    s = np.atleast_2d(np.asarray(lights, float))
    s = s / np.linalg.norm(s, axis=1, keepdims=True)
    half = s + np.array([0.0, 0.0, 1.0])
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    lit = np.einsum("hwc,kc->khw", n, s) > 0
    spec = np.maximum(np.einsum("hwc,kc->khw", n, half), 0.0) ** shininess * lit
    if mask is not None:
        spec[:, ~np.asarray(mask, bool)] = 0.0
    return spec
