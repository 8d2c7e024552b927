r"""Colour photometric stereo: one normal shared by the channels, one albedo per channel.

Woodham's Lambertian model (Woodham 1980) written per colour channel ``c`` of a coloured surface,

.. math:: I_{kc} = \rho_c E_{kc} \max(0, N \cdot S_k),

has four unknowns per pixel (two for ``N``, one albedo per channel for RGB) and ``3 K``
measurements.  The joint least-squares fit over channels and lights has a closed form: the normal
is the top generalised eigenvector of a 3x3 pencil, so the bright channels weigh more than the
dark ones (a per-channel Woodham fit followed by averaging of the normals, or a fit to the
channel sum, does not weigh them so).  A descriptive extension of Woodham's method (the module
name says so); colour photometric stereo with a shared normal is also treated by Barsky & Petrou
(2003), who use the colour images to find highlights and shadows.

References
----------
- R. J. Woodham, "Photometric method for determining surface orientation from multiple images",
  Optical Engineering 19(1), 1980.
- S. Barsky and M. Petrou, "The 4-source photometric stereo technique for three-dimensional
  surfaces in the presence of highlights and shadows", IEEE TPAMI 25(10):1239-1252, 2003.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer.photometric_stereo._common import (
    PhotometricStereoResult,
    accumulate,
    check_sums,
    finish,
    prepare,
    sym_solve,
)

__all__ = ["photometric_stereo_woodham1980_colour"]

_CHUNK = 8192  # pixels per batched 3x3 eigen-decomposition


def _unpack(a6):
    """(6, N) packed symmetric matrices (xx, yy, zz, xy, xz, yz) -> (N, 3, 3)."""
    xx, yy, zz, xy, xz, yz = a6
    return np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1),
                     np.stack([xz, yz, zz], -1)], -2)


def shared_normal(a6, b, bsum, ok):
    r"""Per-pixel normal maximising :math:`N^T M N / N^T A N`, :math:`M = \sum_c b_c b_c^T`.

    ``a6`` (6, N) packed :math:`A = \sum_k w_k S_k S_k^T`; ``b`` (C, 3, N) the per-channel
    :math:`b_c = \sum_k w_k J_{kc} S_k`; ``bsum`` (3, N) their sum (fixes the sign so that the
    albedos sum to a positive number); ``ok`` (N,) well-conditioned pixels.  Returns (3, N) unit
    normals (0 where not ``ok``).  With :math:`A = V \Lambda V^T`, the normal is
    :math:`A^{-1/2} u` for the top eigenvector ``u`` of :math:`A^{-1/2} M A^{-1/2}`.
    """
    nc, _, n = b.shape
    out = np.zeros((3, n))
    idx = np.flatnonzero(ok)
    for start in range(0, idx.size, _CHUNK):
        sel = idx[start:start + _CHUNK]
        am = _unpack(a6[:, sel])
        # scale each pixel's pencil to O(1): eigh is exact up to rounding relative to the largest entry
        sa = np.trace(am, axis1=1, axis2=2)[:, None, None]
        lam, vec = np.linalg.eigh(am / sa)
        ih = (vec / np.sqrt(np.maximum(lam, 1e-300))[:, None, :]) @ np.swapaxes(vec, 1, 2)       # A^{-1/2} (times sqrt(sa))
        bc = np.moveaxis(b[:, :, sel], 2, 0)                                  # (n, C, 3)
        y = bc @ ih                                                           # rows b_c^T A^{-1/2}
        mm = np.swapaxes(y, 1, 2) @ y                                         # A^{-1/2} M A^{-1/2}
        mm /= np.maximum(np.trace(mm, axis1=1, axis2=2), np.finfo(float).tiny)[:, None, None]
        _, u = np.linalg.eigh(mm)
        nrm = ih @ u[:, :, -1:]                                               # (n, 3, 1)
        nrm = nrm[:, :, 0]
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        sign = np.where(np.einsum("ni,in->n", nrm, bsum[:, sel]) < 0, -1.0, 1.0)
        out[:, sel] = (nrm * sign[:, None]).T
    return out


def photometric_stereo_woodham1980_colour(images, lights, *, mask=None, intensities=None,
                                          shadow_threshold: float = 0.01, saturation: float | None = None,
                                          min_lights: int = 3) -> PhotometricStereoResult:
    r"""Shared normal and per-channel albedo of a coloured Lambertian surface by joint least squares.

    Per pixel, over the used lights ``U`` (lit and unsaturated; shared by the channels) and the
    channels ``c``, with ``J_kc = I_kc / E_kc`` the intensity-normalised measurements,

    .. math:: (N, \rho) = \arg\min_{|N| = 1, \rho} \sum_c \sum_{k \in U}
              (\rho_c N \cdot S_k - J_{kc})^2 .

    For fixed ``N`` the albedo is :math:`\rho_c = N \cdot b_c / N^T A N` with
    :math:`A = \sum_{k \in U} S_k S_k^T` and :math:`b_c = \sum_{k \in U} J_{kc} S_k`; substituting
    it leaves :math:`\sum_c q_c - N^T M N / N^T A N`, :math:`M = \sum_c b_c b_c^T`, so ``N`` is the
    top generalised eigenvector of :math:`M N = \lambda A N` (computed as :math:`A^{-1/2} u`, ``u``
    the top eigenvector of :math:`A^{-1/2} M A^{-1/2}`).  Noise free, every per-channel Woodham
    solution :math:`g_c = A^{-1} b_c = \rho_c N` is parallel and ``M`` has rank 1.  With one channel,
    or a grey albedo, the normal is Woodham's :math:`A^{-1} b`.

    Parameters
    ----------
    images : (K, H, W, C) or (K, H, W) array
        Linear images, one per light, ``C`` channels (RGB: 3).  One channel gives Woodham's fit.
    lights : (K, 3) array
        Source vectors in the camera frame (x right, y up, z toward the camera), pointing from
        the surface toward the source; the length scales the intensity.
    mask : (H, W) bool, optional
        Pixels to solve (default all).
    intensities : (K,) or (K, C) array, optional
        Source intensities multiplying ``lights`` (per channel for coloured sources), all > 0.
    shadow_threshold : float
        A light is dropped at a pixel (in every channel) when its intensity-normalised channel sum
        is <= ``shadow_threshold`` times the pixel's brightest one.
    saturation : float, optional
        A light is dropped at a pixel when any channel is >= this value. Default: none.
    min_lights : int
        Minimum number of used lights for a valid pixel (>= 3).

    Returns
    -------
    PhotometricStereoResult
        ``normals`` (H, W, 3), ``albedo`` (H, W, C) (or (H, W) for 3-D input), ``residual``
        (RMS over the used lights and the channels of the shared-normal fit), ``n_used``,
        ``valid``.

    Raises
    ------
    ValueError
        On bad shapes (``intensities`` whose channel count is neither 1 nor ``C``), non-finite
        input inside the mask, non-positive intensities, ``min_lights < 3``, or a degenerate
        light matrix (fewer than 3 lights, or all directions coplanar / collinear).

    References
    ----------
    R. J. Woodham, "Photometric method for determining surface orientation from multiple
    images", Optical Engineering 19(1), 1980; S. Barsky and M. Petrou, IEEE TPAMI 25(10), 2003.
    """
    p = prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights)
    amat, bmat, bsum, q, _, _ = accumulate(p)
    check_sums(p, bsum, q)
    g, ok = sym_solve(amat[:6], bsum)   # conditioning flag (and Woodham's solution, unused)
    if p.nc == 1:
        return finish(p, g, ok, amat, bmat, q)
    nrm = shared_normal(amat[:6], bmat, bsum, ok)
    return finish(p, nrm, ok, amat, bmat, q)
