"""Robust photometric stereo by L1 residual minimisation (Ikehata et al. 2012, convex L1 variant).

Reference: S. Ikehata, D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo using
sparse regression", CVPR 2012.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int
from pbrbench.infer._docstring import docstring
from pbrbench.infer.photometric_stereo._common import (
    DOCS,
    PhotometricStereoResult,
    least_squares,
    measurements,
    prepare,
    reject_outliers,
    weighted_fit,
)

__all__ = ["photometric_stereo_ikehata2012_l1"]

VERSION = "3"  # outlier rejection never leaves fewer than min_lights inliers, nor inliers that determine no normal


@docstring(DOCS)
def photometric_stereo_ikehata2012_l1(images, lights, *, mask=None, intensities=None, shadow_threshold: float = 0.01,
                                      saturation: float | None = None, min_lights: int = 3,
                                      max_iter: int = 50) -> PhotometricStereoResult:
    r"""Normals and albedo robust to highlights and residual shadows (Ikehata et al. 2012, L1).

    Per pixel, over the used lights ``U`` (lit and unsaturated, as for
    :func:`~pbrbench.infer.photometric_stereo.woodham1980.photometric_stereo_woodham1980`),

    .. math:: g = \arg\min_g \sum_{k \in U} |V_k \cdot g - I_k|, \quad
              \rho = |g|, \quad N = g / |g|,

    the convex :math:`\ell_1` variant of Ikehata et al., which treats highlights and residual
    shadows as sparse errors.  It is solved by iteratively reweighted least squares, vectorised
    over pixels, starting from the least-squares solution.  Measurements whose L1 residual
    exceeds 5 robust standard deviations of the noise (1.4826 times the median absolute
    residual over the image, from the residuals the fit did not interpolate exactly) are then
    dropped as outliers (they do not count in ``n_used``; a pixel that would keep fewer than
    ``min_lights`` keeps all its used lights) and ``g`` is refitted by least squares on the
    inliers.

    Parameters
    ----------
    %(inputs)s
    %(options)s
    max_iter : int
        Iterations of the reweighted solver (>= 1).

    Returns
    -------
    PhotometricStereoResult
        As for the least-squares method; ``residual`` is the RMS over the inliers and
        ``n_used`` counts the inliers.

    Raises
    ------
    ValueError
        As for the least-squares method, and for ``max_iter < 1``.

    References
    ----------
    S. Ikehata, D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo using sparse
    regression", CVPR 2012.
    """
    p = prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights)
    max_iter = check_int(max_iter, "max_iter", 1)
    s, s7 = p.s, p.s7
    jsum, used, g = measurements(p)

    scale = np.maximum(jsum.max(axis=0), np.finfo(float).tiny)
    delta = 1e-9 * scale
    wsum = used.astype(float)
    for _ in range(int(max_iter)):
        r = np.abs(jsum - s @ g)
        wl1 = wsum / np.maximum(r, delta)
        g_new, ok_new, _, _ = weighted_fit(wl1, jsum, s, s7)
        g_new = np.where(ok_new, g_new, g)
        step = np.max(np.abs(g_new - g) / scale) if g.size else 0.0
        g = g_new
        if step < 1e-10:
            break
    r = np.abs(jsum - s @ g)
    # Outliers: residual > 5 robust standard deviations of the image noise, estimated over
    # all pixels from the residuals the L1 fit did not interpolate exactly (an L1 fit passes
    # through >= 3 measurements, whose zero residuals say nothing about the noise).
    free = used & (r > 1e3 * delta)
    used = reject_outliers(used, r, free, scale, p.min_lights, p.s7)
    del r, wl1, wsum, free
    # least-squares polish on the inliers (Gaussian-efficient, exact when inliers are exact)
    return least_squares(p, used_in=used, fallback=g)
