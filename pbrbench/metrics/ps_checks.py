r"""The photometric-stereo chapter's self-checks, scored: what a method can see without the truth.

Photometric stereo recovers per pixel ``g = rho N`` from ``I_k = V_k . g`` (``V_k = E_k S_k``,
the source vectors).  The chapter lists three ways to notice that the answer is wrong without
knowing the true surface; each is computed here per pixel (a map) and as one score over the
pixels where the method returned a normal, inside the task's evaluation domain:

* **integrability** (``ps_integrability``): the gradients ``p = -N_x / N_z``, ``q = -N_y / N_z``
  of a surface ``z = f(x, y)`` have equal mixed second partials,

  .. math:: \frac{\partial p}{\partial y} - \frac{\partial q}{\partial x} = 0,

  so the score is the mean of :math:`|\partial p / \partial y - \partial q / \partial x|` (world
  units\ :sup:`-1`; :func:`pbrbench.infer.integration.gradients.integrability_residual`);
* **least-squares residual** (``ps_lsq_residual``): the RMS over the K lights of
  :math:`I_k - \max(0, V_k \cdot g)` (the Lambertian model with attached shadows, evaluated at
  the recovered ``g`` with the *nominal* source vectors the task gives), divided by the RMS of the
  images over the same pixels and lights; 0 for exact Lambertian images;
* **albedo above one** (``ps_albedo_over1_frac``): the fraction of the pixels with
  :math:`\pi |g| > 1`.  Radiance images carry :math:`\rho E \cos\theta / \pi`, so ``|g|`` is
  :math:`\rho / \pi` and the convention here is the **pi-scaled** albedo :math:`\pi |g|`: a
  physical surface has :math:`\pi |g| \le 1`, and a larger value flags a bad pixel or a wrong
  source (the chapter's ":math:`|g| > 1`").

:func:`check_error_correlation` says whether a check's map predicts the angular-error map: the
Pearson and Spearman (rank) correlations over the pixels where both are finite.

References
----------
- D. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, chapter "Light and Shading",
  §1.3.4 (photometric stereo; the integrability test of §1.3.4.4, the residual, ``|g| > 1``).
- R. J. Woodham, "Photometric method for determining surface orientation from multiple images",
  Optical Engineering 19(1), 1980.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_mask
from pbrbench.metrics.table import table

__all__ = ["METRICS", "albedo_over1_map", "check_error_correlation", "check_maps", "check_scores",
           "integrability_map", "lsq_residual_map"]

# below this N_z a normal has no finite gradient (it is left out of the integrability check)
MIN_NZ = 1e-3


def integrability_map(normals, domain, pixel_size: float = 1.0) -> np.ndarray:
    r"""Per-pixel :math:`|\partial p/\partial y - \partial q/\partial x|` of a normal field.

    Parameters
    ----------
    normals : (H, W, 3) array
        Unit normals (camera frame, z toward the camera).
    domain : (H, W) bool
        Pixels to use (normals with ``N_z <= 1e-3`` are dropped from it).
    pixel_size : float
        World size of one pixel (the derivatives are per world unit).

    Returns
    -------
    (H, W) float64 map, NaN outside the domain.
    """
    from pbrbench.infer.integration.gradients import integrability_residual

    n = as_float_array(normals, "normals", ndim=(3,))
    m = check_mask(domain, n.shape[:2]) & np.isfinite(n).all(axis=-1) & (n[..., 2] > MIN_NZ)
    out = np.full(n.shape[:2], np.nan)
    if not m.any():
        return out
    r = integrability_residual(np.where(m[..., None], n, 0.0), m, pixel_size=pixel_size)
    out[m] = np.abs(r[m])
    return out


def lsq_residual_map(images, lights, normals, albedo, domain) -> tuple[np.ndarray, float]:
    r"""Per-pixel RMS residual of the Lambertian fit and the images' RMS.

    .. math:: r(x) = \Big(\frac1K \sum_k \big(I_k(x) - \max(0, V_k \cdot g(x))\big)^2\Big)^{1/2},
              \qquad g = \text{albedo} \cdot N .

    Parameters
    ----------
    images : (K, H, W) array
        The images the method was given (grey).
    lights : (K, 3) array
        Source vectors ``V_k = E_k S_k``.
    normals : (H, W, 3) array
    albedo : (H, W) array
        The method's albedo in image units (``|g|``).
    domain : (H, W) bool

    Returns
    -------
    (map, rms) : the (H, W) map ``r`` (NaN outside the domain) and the RMS of the images over the
    domain and the lights (divide the map by it for the relative residual).
    """
    img = as_float_array(images, "images", ndim=(3,))
    v = as_float_array(lights, "lights", ndim=(2,))
    n = as_float_array(normals, "normals", ndim=(3,))
    a = as_float_array(albedo, "albedo", ndim=(2,))
    m = check_mask(domain, img.shape[1:3])
    out = np.full(img.shape[1:3], np.nan)
    if not m.any():
        return out, float("nan")
    g = n[m] * a[m][:, None]                       # (N, 3)
    pred = np.maximum(g @ v.T, 0.0).T              # (K, N)
    meas = img[:, m]
    out[m] = np.sqrt(np.mean((meas - pred) ** 2, axis=0))
    return out, float(np.sqrt(np.mean(meas ** 2)))


def albedo_over1_map(albedo, domain) -> np.ndarray:
    r"""The pi-scaled albedo :math:`\pi |g|` inside the domain (NaN outside): above 1 flags a pixel."""
    a = as_float_array(albedo, "albedo", ndim=(2,))
    m = check_mask(domain, a.shape)
    return np.where(m, np.pi * np.abs(a), np.nan)


def check_maps(images, lights, normals, albedo, domain, pixel_size: float = 1.0) -> dict[str, np.ndarray]:
    """The three check maps (name -> (H, W), NaN outside ``domain``): ``integrability``
    (:func:`integrability_map`), ``lsq residual`` (:func:`lsq_residual_map` over the image RMS)
    and ``pi |g|`` (:func:`albedo_over1_map`)."""
    r, rms = lsq_residual_map(images, lights, normals, albedo, domain)
    return {"integrability": integrability_map(normals, domain, pixel_size),
            "lsq residual": r / rms if rms > 0 else np.full_like(r, np.nan),
            "pi |g|": albedo_over1_map(albedo, domain)}


def check_scores(images, lights, normals, albedo, domain, pixel_size: float = 1.0) -> tuple[dict, dict]:
    """``({metric: value}, maps)``: the means of the check maps (:func:`check_maps`) over
    ``domain`` and the fraction of ``domain`` with pi |g| > 1; metrics without a pixel are left
    out."""
    maps = check_maps(images, lights, normals, albedo, domain, pixel_size)
    out = {}
    for name, key in (("ps_integrability", "integrability"), ("ps_lsq_residual", "lsq residual")):
        v = maps[key][np.isfinite(maps[key])]
        if v.size:
            out[name] = float(v.mean())
    g = maps["pi |g|"][np.isfinite(maps["pi |g|"])]
    if g.size:
        out["ps_albedo_over1_frac"] = float(np.mean(g > 1.0))
    return out, maps


def check_error_correlation(check, error) -> tuple[float, float]:
    r"""(Pearson, Spearman) correlation of a check map with an error map over the pixels where both
    are finite; NaN with fewer than 3 such pixels or a constant map.

    Spearman's coefficient is Pearson's of the ranks (ties: average ranks).
    """
    from scipy import stats

    c = np.asarray(check, float).ravel()
    e = np.asarray(error, float).ravel()
    ok = np.isfinite(c) & np.isfinite(e)
    c, e = c[ok], e[ok]
    if c.size < 3 or np.ptp(c) == 0 or np.ptp(e) == 0:
        return float("nan"), float("nan")
    return float(stats.pearsonr(c, e)[0]), float(stats.spearmanr(c, e)[0])


METRICS = table("""
ps_integrability     | lower | 1/world unit | check_scores | mean |dp/dy - dq/dx| of the recovered gradients over the domain (the chapter's integrability check)
ps_lsq_residual      | lower | fraction     | check_scores | RMS over the lights of I - max(0, V.g) at the recovered g, over the images' RMS (Lambertian least-squares residual)
ps_albedo_over1_frac | lower | fraction     | check_scores | fraction of the domain with pi |g| > 1 (recovered albedo above one: a bad pixel or a wrong source)
""")
