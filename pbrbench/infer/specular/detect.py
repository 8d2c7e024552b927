"""Detection of specularities: small, very bright blobs, by a grey-scale morphological top-hat.

The opening of the brightness by a disc (here an octagon) of radius ``r`` removes every bright
structure narrower than it while keeping smooth shading nearly unchanged, so the ratio of the
brightness to its opening (the multiplicative white top-hat) is large exactly on small bright
blobs; they are grown by hysteresis.  A descriptive name (``detect``): the method combines the
opening (Serra 1982), the top-hat (Meyer 1979) and hysteresis (Canny 1986); no single paper
proposes it.

References
----------
- J. Serra, *Image Analysis and Mathematical Morphology*, Academic Press, 1982 (opening).
- F. Meyer, "Iterative image transformations for an automatic screening of cervical smears",
  J. Histochem. Cytochem. 27, 1979 (the top-hat transform).
- J. Canny, "A computational approach to edge detection", IEEE TPAMI 8(6), 1986 (hysteresis).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_int,
    check_mask,
    check_number,
    check_positive,
)

__all__ = ["detect_specularities"]


def _brightness(img: np.ndarray) -> np.ndarray:
    return img if img.ndim == 2 else img.mean(axis=-1)


_SQUARE = np.ones((3, 3), dtype=bool)
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)


def _octagon_opening(b: np.ndarray, r: int, domain: np.ndarray) -> np.ndarray:
    """Grey opening of ``b`` restricted to ``domain`` by an octagon of radius ``r`` (a disc
    approximation): ``r`` erosions by alternating 3x3 square and cross, then the same
    dilations (Minkowski sums of small elements, Serra 1982).  Pixels outside ``domain`` take
    no part (+inf for the erosion, -inf for the dilation), so a bright object's rim next to a
    dark background is compared with the object only, not taken for a blob."""
    big = np.inf
    out = np.where(domain, b, big)
    for k in range(r):
        out = ndimage.grey_erosion(out, footprint=_SQUARE if k % 2 == 0 else _CROSS, mode="nearest")
        out[~domain] = big
    out[~domain] = -big
    for k in range(r):
        out = ndimage.grey_dilation(out, footprint=_SQUARE if k % 2 == 0 else _CROSS, mode="nearest")
        out[~domain] = -big
    return np.where(domain, out, 0.0)


def detect_specularities(image, *, radius: int | None = None, ratio: float = 1.5, low_ratio: float = 1.1,
                         min_excess: float = 0.05, max_area: int | None = None, mask=None) -> np.ndarray:
    r"""Mask of small, very bright blobs (specularities).

    With ``b`` the brightness (the mean over channels of a colour image) and ``B = (b o K)``
    its grey-scale opening by an octagon ``K`` of radius ``radius`` (Serra 1982), a pixel is
    a *seed* when

    .. math:: b > \text{ratio} \cdot B \quad\text{and}\quad b - B > \text{min\_excess} \cdot \max B

    (brighter than its local background by a factor and by an absolute margin relative to
    the brightest background, which ignores dark noise).  The blob is grown by hysteresis
    (Canny 1986) into the connected pixels with ``b > low_ratio * B`` and
    ``b - B > min_excess * max B / 2``; connected components larger than ``max_area`` pixels
    (default ``(2 radius + 1)^2``) are rejected as not small.

    Parameters
    ----------
    image : (H, W) or (H, W, C) linear image, >= 0.
    radius : int, optional
        Radius of the opening octagon (a disc approximation); blobs narrower than about
        ``2 radius + 1`` pixels are found.  Choose it larger than the highlights and smaller
        than the objects.  Default ``max(3, min(H, W) // 10)``.
    ratio, low_ratio : float
        Seed and hysteresis ratios to the local background, ``ratio >= low_ratio > 1``.
    min_excess : float
        Absolute margin as a fraction of the brightest background level.
    max_area : int, optional
        Largest accepted blob, in pixels.
    mask : (H, W) bool, optional
        Domain of the object(s): outside it and where ``b <= 0`` (black background) nothing is
        detected and the opening does not look (its rim is not a blob).

    Returns
    -------
    (H, W) bool mask.
    """
    img = as_float_array(image, "image", ndim=(2, 3))
    m = check_mask(mask, img.shape[:2])
    check_finite(img, "image")
    r = max(3, min(img.shape[:2]) // 10) if radius is None else check_int(radius, "radius", 1, max(img.shape[:2]))
    ratio = check_positive(ratio, "ratio")
    low_ratio = check_positive(low_ratio, "low_ratio")
    if not (1.0 < low_ratio <= ratio):
        raise ValueError(f"low_ratio/ratio: need 1 < low_ratio <= ratio, got low_ratio={low_ratio}, "
                         f"ratio={ratio}")
    min_excess = check_number(min_excess, "min_excess", lo=0.0)
    size = 2 * r + 1
    max_area = size * size if max_area is None else check_int(max_area, "max_area", 1)

    b = _brightness(img)
    bg = _octagon_opening(b, r, m & (b > 0))
    scale = float(bg[m].max()) if np.any(bg[m] > 0) else float(b[m].max())
    if scale <= 0:
        return np.zeros(b.shape, dtype=bool)
    excess = b - bg
    seed = m & (b > ratio * bg) & (excess > min_excess * scale)
    grow = m & (b > low_ratio * bg) & (excess > 0.5 * min_excess * scale)
    lab, n = ndimage.label(grow)
    if n == 0:
        return np.zeros(b.shape, dtype=bool)
    area = np.bincount(lab.ravel(), minlength=n + 1)
    has_seed = np.bincount(lab.ravel(), weights=seed.ravel(), minlength=n + 1) > 0
    ok = has_seed & (area <= max_area)
    ok[0] = False
    return ok[lab]
