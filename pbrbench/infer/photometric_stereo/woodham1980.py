"""Photometric stereo by least squares over the lit, unsaturated lights (Woodham 1980).

Reference: R. J. Woodham, "Photometric method for determining surface orientation from multiple
images", Optical Engineering 19(1), 1980; D. A. Forsyth and J. Ponce, *Computer Vision: A Modern
Approach*, Algorithm 1.2.
"""

from __future__ import annotations

from pbrbench.infer.photometric_stereo._common import (
    PhotometricStereoResult,
    accumulate,
    check_sums,
    finish,
    prepare,
    sym_solve,
)

__all__ = ["photometric_stereo_woodham1980"]


def photometric_stereo_woodham1980(images, lights, *, mask=None, intensities=None, shadow_threshold: float = 0.01,
                                   saturation: float | None = None, min_lights: int = 3) -> PhotometricStereoResult:
    r"""Normals and albedo of a Lambertian surface by per-pixel least squares (Woodham 1980).

    Per pixel, with the used lights ``U`` (lit and unsaturated),

    .. math:: g = \arg\min_g \sum_{k \in U} (V_k \cdot g - I_k)^2, \quad
              \rho = |g|, \quad N = g / |g|,

    where ``V_k`` is row k of ``lights`` (times ``intensities[k]`` if given); vectorised as
    batched 3x3 normal equations solved by cofactors.

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear images, one per light.
    lights : (K, 3) array
        Source vectors in the camera frame (x right, y up, z toward the camera), pointing from
        the surface toward the source; the length scales the intensity.
    mask : (H, W) bool, optional
        Pixels to solve (default all).
    intensities : (K,) or (K, C) array, optional
        Source intensities multiplying ``lights`` (per channel for coloured sources), all > 0.
    shadow_threshold : float
        A measurement is treated as shadowed and dropped when its intensity-normalised value is
        <= ``shadow_threshold`` times the pixel's brightest normalised measurement (0 drops only
        exact zeros and negatives). Shadowed measurements are clamped, not linear: leaving them in
        biases the normal.
    saturation : float, optional
        Measurements >= this value (in any channel) are dropped. Default: none.
    min_lights : int
        Minimum number of used lights for a valid pixel (>= 3).

    Returns
    -------
    PhotometricStereoResult
        ``normals`` (H, W, 3), ``albedo`` (H, W) or (H, W, C), ``residual`` (H, W), ``n_used``
        (H, W), ``valid`` (H, W). Colour: one normal shared by the channels (from the sum of the
        intensity-normalised channels), albedo per channel (least squares given the normal).

    Raises
    ------
    ValueError
        On bad shapes, non-finite input inside the mask, non-positive intensities,
        ``min_lights < 3``, or a degenerate light matrix (fewer than 3 lights, or all directions
        coplanar / collinear).

    References
    ----------
    R. J. Woodham, "Photometric method for determining surface orientation from multiple
    images", Optical Engineering 19(1), 1980.
    """
    p = prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights)
    amat, bmat, bsum, q, _, _ = accumulate(p)
    check_sums(p, bsum, q)
    g, ok = sym_solve(amat[:6], bsum)
    return finish(p, g, ok, amat, bmat, q)
