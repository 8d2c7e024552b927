"""The local shading model: Lambertian images from normals, albedo and distant sources.

``I_k(x) = rho(x) * E_k * max(0, N(x) . S_k) / pi`` (SCIENCE.md §0), or without the 1/pi when
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
