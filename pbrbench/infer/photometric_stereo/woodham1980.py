"""Photometric stereo by least squares over the lit, unsaturated lights (Woodham 1980).

Reference: R. J. Woodham, "Photometric method for determining surface orientation from multiple
images", Optical Engineering 19(1), 1980; D. A. Forsyth and J. Ponce, *Computer Vision: A Modern
Approach*, Algorithm 1.2.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer._docstring import docstring
from pbrbench.infer.photometric_stereo._common import (
    DOCS,
    PhotometricStereoResult,
    least_squares,
    prepare,
)

__all__ = ["photometric_stereo_woodham1980"]


@docstring(DOCS)
def photometric_stereo_woodham1980(images, lights, *, mask=None, intensities=None, shadow_threshold: float = 0.01,
                                   saturation: float | None = None, min_lights: int = 3,
                                   used=None) -> PhotometricStereoResult:
    r"""Normals and albedo of a Lambertian surface by per-pixel least squares (Woodham 1980).

    Per pixel, with the used lights ``U`` (lit and unsaturated),

    .. math:: g = \arg\min_g \sum_{k \in U} (V_k \cdot g - I_k)^2, \quad
              \rho = |g|, \quad N = g / |g|,

    where ``V_k`` is row k of ``lights`` (times ``intensities[k]`` if given); vectorised as
    batched 3x3 normal equations solved by cofactors.

    Parameters
    ----------
    %(inputs)s
    %(options)s
    used : (K, H, W) bool array, optional
        The measurements to use, in place of the classification by ``shadow_threshold`` and
        ``saturation`` (e.g. those a known shape lights fully); a pixel with fewer than
        ``min_lights`` of them, or whose used sources do not span 3-D, is not valid.

    Returns
    -------
    %(result)s

    Raises
    ------
    %(raises)s

    References
    ----------
    R. J. Woodham, "Photometric method for determining surface orientation from multiple
    images", Optical Engineering 19(1), 1980.
    """
    p = prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights)
    if used is None:
        return least_squares(p)
    u = np.asarray(used)
    if u.dtype != bool or u.shape != (p.k, p.h, p.w):
        raise ValueError(f"used: got a {u.dtype} array of shape {u.shape}; pass a ({p.k}, {p.h}, {p.w}) boolean array, "
                         "one flag per measurement")
    u = u.reshape(p.k, -1)
    return least_squares(p, used_in=u if p.sel is None else u[:, p.sel])
