"""Find and remove specularities: small, very bright blobs (SCIENCE.md §1).

The chapter's Lambertian+specular model removes specularities before applying Lambert's law:
"find small bright spots, and replace them by smoothing the local pixel values" (§1.1.3).
Here "small" and "bright" are made precise with grey-scale morphology: the *opening* of the
brightness by a disc (here an octagon) of radius ``r`` removes every bright structure narrower
than it while keeping smooth shading nearly unchanged, so the ratio of the brightness to its
opening (the multiplicative white top-hat) is large exactly on small bright blobs.  The blobs
are replaced by the solution of Laplace's equation (harmonic interpolation) or of the
biharmonic equation with the surrounding pixels as boundary values.

Objects
-------
- :func:`detect_specularities` -- boolean mask of small, very bright blobs.
- :func:`remove_specularities` -- the image with those blobs filled in from their surroundings.
- ``FILL_METHODS`` -- the valid ``method`` values of :func:`remove_specularities`.

References
----------
- J. Serra, *Image Analysis and Mathematical Morphology*, Academic Press, 1982 (opening);
  F. Meyer, "Iterative image transformations for an automatic screening of cervical smears",
  J. Histochem. Cytochem. 27, 1979 (the top-hat transform).
- J. Canny, "A computational approach to edge detection", IEEE TPAMI 8(6), 1986 (hysteresis).
- M. Bertalmio, G. Sapiro, V. Caselles and C. Ballester, "Image inpainting", SIGGRAPH 2000, and
  S. B. Damelin and N. S. Hoang, "On surface completion and image inpainting by biharmonic
  functions", Int. J. Math. Math. Sci. 2018 (harmonic / biharmonic filling; the latter is
  :func:`skimage.restoration.inpaint_biharmonic`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.linalg import splu

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_mask,
    check_method,
    check_positive,
)

__all__ = ["detect_specularities", "remove_specularities", "FILL_METHODS"]

FILL_METHODS = ("harmonic", "biharmonic")


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
    r = max(3, min(img.shape[:2]) // 10) if radius is None else int(radius)
    if r < 1:
        raise ValueError(f"radius: must be an integer >= 1, got {radius!r}")
    ratio = check_positive(ratio, "ratio")
    low_ratio = check_positive(low_ratio, "low_ratio")
    if not (1.0 < low_ratio <= ratio):
        raise ValueError(f"low_ratio/ratio: need 1 < low_ratio <= ratio, got low_ratio={low_ratio}, "
                         f"ratio={ratio}")
    min_excess = float(min_excess)
    if not (np.isfinite(min_excess) and min_excess >= 0):
        raise ValueError(f"min_excess: must be a finite number >= 0, got {min_excess!r}")
    size = 2 * r + 1
    max_area = size * size if max_area is None else int(max_area)
    if max_area < 1:
        raise ValueError(f"max_area: must be a positive integer, got {max_area!r}")

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


def _harmonic_fill(img3: np.ndarray, hole: np.ndarray) -> np.ndarray:
    """Solve Laplace's equation in ``hole`` with the other pixels as Dirichlet data."""
    h, w, nc = img3.shape
    idx = np.full((h, w), -1, dtype=np.int64)
    ii, jj = np.nonzero(hole)
    n = ii.size
    idx[ii, jj] = np.arange(n)
    rows, cols, vals = [], [], []
    diag = np.zeros(n)
    rhs = np.zeros((n, nc))
    for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        ni, nj = ii + di, jj + dj
        inside = (ni >= 0) & (ni < h) & (nj >= 0) & (nj < w)  # image border: natural (Neumann)
        diag += inside
        k = np.flatnonzero(inside)
        nb = idx[ni[k], nj[k]]
        unknown = nb >= 0
        rows.append(k[unknown])
        cols.append(nb[unknown])
        vals.append(-np.ones(int(unknown.sum())))
        known = k[~unknown]
        rhs[known] += img3[ni[known], nj[known]]
    rows.append(np.arange(n))
    cols.append(np.arange(n))
    vals.append(diag)
    a = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    out = img3.copy()
    out[ii, jj] = splu(a).solve(rhs)
    return out


def remove_specularities(image, mask=None, *, method: str = "harmonic", dilate: int = 3,
                         detect_options: dict | None = None) -> np.ndarray:
    r"""Replace specular blobs by values interpolated from their surroundings.

    The pixels of ``mask`` (default: :func:`detect_specularities` with ``detect_options``),
    dilated by ``dilate`` pixels to cover the highlight's faint halo, are unknowns ``u`` solving

    - ``"harmonic"``: Laplace's equation ``Delta u = 0`` (5-point stencil) with the pixels
      around the hole as Dirichlet values (the smoothest membrane; flattens curved shading);
    - ``"biharmonic"``: ``Delta^2 u = 0`` (:func:`skimage.restoration.inpaint_biharmonic`,
      Damelin & Hoang 2018), which also continues the surrounding slope.

    Each channel is filled independently; pixels outside the (dilated) mask are unchanged.

    Parameters
    ----------
    image : (H, W) or (H, W, C) linear image.
    mask : (H, W) bool, optional; the specular pixels.
    method : {"harmonic", "biharmonic"}
    dilate : int
        Dilation of the mask in pixels (3x3 structuring element) before filling; 0 = none.
    detect_options : dict, optional
        Keyword arguments of :func:`detect_specularities` when ``mask`` is None.

    Returns
    -------
    float64 array of the image's shape.
    """
    img = as_float_array(image, "image", ndim=(2, 3))
    check_method(method, FILL_METHODS)
    check_finite(img, "image")
    d = int(dilate)
    if d < 0:
        raise ValueError(f"dilate: must be an integer >= 0, got {dilate!r}")
    if mask is None:
        hole = detect_specularities(img, **(detect_options or {}))
    else:
        hole = np.asarray(mask)
        if hole.shape != img.shape[:2]:
            raise ValueError(f"mask: shape {hole.shape} does not match the image shape {img.shape[:2]}; "
                             "pass an (H, W) boolean mask")
        if hole.dtype != bool:
            if not np.isin(hole, (0, 1)).all():
                raise ValueError("mask: must be boolean (or 0/1); got values outside {0, 1}")
            hole = hole.astype(bool)
    if d > 0 and hole.any():
        hole = ndimage.binary_dilation(hole, iterations=d)
    if not hole.any():
        return img.copy()
    if hole.all():
        raise ValueError("mask: covers the whole image, nothing to interpolate from; pass a smaller mask")
    img3 = img[..., None] if img.ndim == 2 else img
    if method == "harmonic":
        out = _harmonic_fill(img3, hole)
    else:
        from skimage.restoration import inpaint_biharmonic

        out = inpaint_biharmonic(img3, hole, channel_axis=-1)
        out = np.where(hole[..., None], out, img3)
    return out[..., 0] if img.ndim == 2 else out
