"""Find and remove specularities: small, very bright blobs.

The chapter's Lambertian+specular model removes specularities before applying Lambert's law:
"find small bright spots, and replace them by smoothing the local pixel values" (D. A. Forsyth
and J. Ponce, *Computer Vision: A Modern Approach*, "Light and shading", §1.1.3).  Here "small"
and "bright" are made precise with grey-scale morphology (:mod:`~pbrbench.infer.specular.detect`),
and the blobs are replaced by the solution of Laplace's or the biharmonic equation with the
surrounding pixels as boundary values (:mod:`~pbrbench.infer.specular.fill`).

Objects
-------
- :func:`detect_specularities`: boolean mask of small, very bright blobs.
- :data:`FILL_METHODS`: fill methods by name, each ``fn(image, mask=None, *, dilate=3,
  detect_options=None)``; the names are descriptive (the equation solved), not papers:
  ``"harmonic"`` (:func:`remove_specularities_harmonic`) and ``"biharmonic"``
  (:func:`remove_specularities_biharmonic`, loads scikit-image when called).
- :func:`remove_specularities`: the dispatcher over :data:`FILL_METHODS`.

References
----------
- J. Serra, *Image Analysis and Mathematical Morphology*, Academic Press, 1982 (opening);
  F. Meyer, "Iterative image transformations for an automatic screening of cervical smears",
  J. Histochem. Cytochem. 27, 1979 (the top-hat transform).
- J. Canny, "A computational approach to edge detection", IEEE TPAMI 8(6), 1986 (hysteresis).
- M. Bertalmio, G. Sapiro, V. Caselles and C. Ballester, "Image inpainting", SIGGRAPH 2000, and
  S. B. Damelin and N. S. Hoang, "On surface completion and image inpainting by biharmonic
  functions", Int. J. Math. Math. Sci. 2018 (harmonic / biharmonic filling).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import call_method
from pbrbench.infer.specular.detect import detect_specularities
from pbrbench.infer.specular.fill import (
    remove_specularities_biharmonic,
    remove_specularities_harmonic,
)

__all__ = [
    "FILL_METHODS",
    "detect_specularities",
    "remove_specularities",
    "remove_specularities_biharmonic",
    "remove_specularities_harmonic",
]

FILL_METHODS = {
    "harmonic": remove_specularities_harmonic,
    "biharmonic": remove_specularities_biharmonic,
}


def remove_specularities(image, mask=None, *, method: str = "harmonic", **options) -> np.ndarray:
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
    method : str
        A key of :data:`FILL_METHODS`.
    **options
        Options of that method: ``dilate`` (int, dilation of the mask in pixels before
        filling, 0 = none; default 3) and ``detect_options`` (dict, keyword arguments of
        :func:`detect_specularities` when ``mask`` is None); an option it does not accept raises
        ``ValueError`` listing those it accepts.

    Returns
    -------
    float64 array of the image's shape.

    References
    ----------
    M. Bertalmio et al., "Image inpainting", SIGGRAPH 2000; S. B. Damelin and N. S. Hoang,
    Int. J. Math. Math. Sci. 2018.
    """
    return call_method(FILL_METHODS, method, "remove_specularities", image, mask, **options)
