"""Baselines for photometric stereo: deliberately naive estimates that the methods must beat.

They share the methods' signature, ``fn(images, lights, *, mask=None) -> PhotometricStereoResult``,
but are not methods of the problem (not in :data:`pbrbench.infer.photometric_stereo.METHODS`);
:data:`BASELINES` maps their names (as the benchmark reports them, after ``baseline:``) to them.
Descriptive names: no paper proposes these.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_mask
from pbrbench.infer._scale import max_abs, pow2_exponent, robust_norm
from pbrbench.infer.photometric_stereo._common import PhotometricStereoResult, check_lights

__all__ = ["BASELINES", "photometric_stereo_naive_lstsq"]


def photometric_stereo_naive_lstsq(images, lights, *, mask=None) -> PhotometricStereoResult:
    r"""The naive fit: ``g = pinv(V) I`` with every light, shadowed (clamped) ones included.

    .. math:: g = \arg\min_g \sum_{k=1}^{K} (V_k \cdot g - I_k)^2 = V^{+} I, \quad
              \rho = |g|, \quad N = g / |g|,

    over all K lights at every pixel: the clamped zeros of shadowed lights stay in the
    equations and bias the normal (the failure the lit-light selection of
    :func:`~pbrbench.infer.photometric_stereo.woodham1980.photometric_stereo_woodham1980`
    avoids; Woodham 1980 discusses it).

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear images, one per light.  Colour: the normal comes from the channel sum, the
        albedo per channel is the least-squares fit given the normal over all lights.
    lights : (K, 3) array
        Source vectors in the camera frame, pointing toward the sources (length = intensity).
    mask : (H, W) bool, optional
        Pixels to report (default all); 0 outside.

    Returns
    -------
    PhotometricStereoResult
        ``n_used`` is K inside the mask; ``residual`` the RMS of ``rho_c V N - I_c`` over all K
        lights and the channels (0 where not valid); ``valid``: inside the mask with ``|g| > 0``.

    Raises
    ------
    ValueError
        On bad shapes, a degenerate light matrix, a bad mask or non-finite values inside it.

    References
    ----------
    R. J. Woodham, "Photometric method for determining surface orientation from multiple
    images", Optical Engineering 19(1), 1980 (the least-squares solve).
    """
    img = as_float_array(images, "images", ndim=(3, 4))
    colour = img.ndim == 4
    k, h, w = img.shape[:3]
    s = check_lights(lights, k)
    m = check_mask(mask, (h, w))
    check_finite(img, "images", where=np.broadcast_to(m.reshape((1, h, w) + (1,) * colour), img.shape))
    ei = pow2_exponent(max_abs(img, np.broadcast_to(m.reshape((1, h, w) + (1,) * colour), img.shape)))
    es = pow2_exponent(float(robust_norm(s, axis=1).max()))
    if ei or es:   # 1e+-300 magnitudes: solve exactly rescaled, scale the albedo and residual back
        r = photometric_stereo_naive_lstsq(np.ldexp(img, -ei), np.ldexp(s, -es), mask=m)
        alb, res = np.ldexp(r.albedo, ei - es), np.ldexp(r.residual, ei)
        if not (np.isfinite(alb).all() and np.isfinite(res).all()):
            raise ValueError("images/lights: the albedo (image / light length) overflows float64; divide the images "
                             "by a constant or give lights of ordinary length (the normals do not change)")
        return PhotometricStereoResult(normals=r.normals, albedo=alb, residual=res, n_used=r.n_used, valid=r.valid)
    pinv = np.linalg.pinv(s)
    img3 = img if colour else img[..., None]
    if colour:
        g = (pinv @ img3.sum(axis=-1).reshape(k, -1)).T.reshape(h, w, 3)
    else:
        g = pinv @ img.reshape(k, -1)  # (3, H*W)
        g = g.T.reshape(h, w, 3)
    a = np.linalg.norm(g, axis=-1)
    valid = m & (a > 0)
    n = np.divide(g, a[..., None], out=np.zeros_like(g), where=valid[..., None])
    shade = np.einsum("kc,hwc->khw", s, n)  # V_k . N, (K, H, W)
    if colour:
        den = np.einsum("khw,khw->hw", shade, shade)
        num = np.einsum("khw,khwc->hwc", shade, img3)
        albedo = np.divide(num, den[..., None], out=np.zeros_like(num), where=(valid & (den > 0))[..., None])
        model = shade[..., None] * albedo[None]
    else:
        albedo = np.where(valid, a, 0.0)
        model = (shade * albedo[None])[..., None]
    res = np.sqrt(np.mean((model - img3) ** 2, axis=(0, 3)))
    return PhotometricStereoResult(
        normals=n, albedo=albedo, residual=np.where(valid, res, 0.0),
        n_used=np.where(m, k, 0).astype(np.int64), valid=valid)


BASELINES = {
    "naive_lstsq_all_lights": photometric_stereo_naive_lstsq,
}
