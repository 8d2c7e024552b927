"""Filling specular blobs from their surroundings: harmonic and biharmonic interpolation.

Both fills share the signature ``fn(image, mask=None, *, dilate=3, detect_options=None)``: the
pixels of ``mask`` (default: :func:`~pbrbench.infer.specular.detect.detect_specularities` with
``detect_options``), dilated by ``dilate`` pixels to cover the highlight's faint halo, are
replaced by the solution of an interpolation problem with the other pixels as boundary values;
each channel independently.  Descriptive names (``"harmonic"``, ``"biharmonic"``): they name the
equation solved; the fills are classical, not one paper's method.

References
----------
- M. Bertalmio, G. Sapiro, V. Caselles and C. Ballester, "Image inpainting", SIGGRAPH 2000
  (filling from the surroundings).
- S. B. Damelin and N. S. Hoang, "On surface completion and image inpainting by biharmonic
  functions", Int. J. Math. Math. Sci. 2018 (biharmonic filling; it is
  :func:`skimage.restoration.inpaint_biharmonic`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.linalg import splu

from pbrbench.checks import as_array, as_float_array, check_finite, check_int
from pbrbench.infer.specular.detect import detect_specularities

__all__ = ["remove_specularities_biharmonic", "remove_specularities_harmonic"]


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


def _hole(image, mask, dilate, detect_options):
    """Checked ``(img, hole)``: the float image and the dilated mask of pixels to fill, or
    ``(img, None)`` when there is nothing to fill."""
    img = as_float_array(image, "image", ndim=(2, 3))
    check_finite(img, "image")
    d = check_int(dilate, "dilate", 0, max(img.shape[:2]))
    if mask is None:
        hole = detect_specularities(img, **(detect_options or {}))
    else:
        hole = as_array(mask, "mask")
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
        return img, None
    if hole.all():
        raise ValueError(f"mask: covers the whole image{f' once dilated by dilate={d}' if d else ''}, nothing to "
                         "interpolate from; pass a smaller mask (or a smaller dilate)")
    return img, hole


def remove_specularities_harmonic(image, mask=None, *, dilate: int = 3, detect_options: dict | None = None) -> np.ndarray:
    r"""Replace specular blobs by the harmonic interpolant of their surroundings.

    The unknowns ``u`` (the pixels of the dilated mask) solve Laplace's equation

    .. math:: \Delta u = 0 \quad\text{in the hole}, \qquad u = I \quad\text{on its border}

    (5-point stencil; natural boundary at the image border): the smoothest membrane, which
    flattens curved shading.  A direct sparse solve (SciPy's SuperLU).

    Parameters
    ----------
    image : (H, W) or (H, W, C) linear image.
    mask : (H, W) bool, optional
        The specular pixels; default :func:`~pbrbench.infer.specular.detect.detect_specularities`
        with ``detect_options``.
    dilate : int
        Dilation of the mask in pixels (3x3 structuring element) before filling; 0 = none.
    detect_options : dict, optional
        Keyword arguments of the detection when ``mask`` is None.

    Returns
    -------
    float64 array of the image's shape; pixels outside the (dilated) mask are unchanged.

    References
    ----------
    M. Bertalmio, G. Sapiro, V. Caselles and C. Ballester, "Image inpainting", SIGGRAPH 2000.
    """
    img, hole = _hole(image, mask, dilate, detect_options)
    if hole is None:
        return img.copy()
    img3 = img[..., None] if img.ndim == 2 else img
    out = _harmonic_fill(img3, hole)
    return out[..., 0] if img.ndim == 2 else out


def remove_specularities_biharmonic(image, mask=None, *, dilate: int = 3,
                                    detect_options: dict | None = None) -> np.ndarray:
    r"""Replace specular blobs by the biharmonic interpolant of their surroundings.

    The unknowns ``u`` (the pixels of the dilated mask) solve

    .. math:: \Delta^2 u = 0 \quad\text{in the hole}

    with the surrounding pixels as boundary data (:func:`skimage.restoration.inpaint_biharmonic`,
    Damelin & Hoang 2018), which also continues the surrounding slope.  Loads scikit-image
    when called.

    Parameters
    ----------
    image, mask, dilate, detect_options
        As for :func:`remove_specularities_harmonic`.

    Returns
    -------
    float64 array of the image's shape; pixels outside the (dilated) mask are unchanged.

    References
    ----------
    S. B. Damelin and N. S. Hoang, "On surface completion and image inpainting by biharmonic
    functions", Int. J. Math. Math. Sci. 2018.
    """
    img, hole = _hole(image, mask, dilate, detect_options)
    if hole is None:
        return img.copy()
    from skimage.restoration import inpaint_biharmonic  # lazy: keeps `import pbrbench.infer` light

    img3 = img[..., None] if img.ndim == 2 else img
    out = inpaint_biharmonic(img3, hole, channel_axis=-1)
    out = np.where(hole[..., None], out, img3)
    return out[..., 0] if img.ndim == 2 else out
