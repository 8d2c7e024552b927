"""Lightness by thresholded log-gradients and least-squares reconstruction (Blake 1985).

This is the chapter's Algorithm 1.1 (D. A. Forsyth and J. Ponce, *Computer Vision: A Modern
Approach*, chapter "Light and shading", Algorithm 1.1): differentiate ``log C``, zero the gradients
below a threshold, reconstruct the log-albedo ``l`` minimising ``|M_x l - p|^2 + |M_y l - q|^2``
(a Poisson problem with Neumann boundary conditions, solved by
:func:`pbrbench.infer.poisson.solve_gradient_field`), fix the missing constant by a rule, and
exponentiate.

Why "blake1985": thresholding the *gradient* (first derivatives) and reconstructing by least
squares with the natural (Neumann) boundary conditions is Blake's formulation.  Horn (1974)
thresholds the Laplacian instead and inverts it; Land & McCann (1971) multiply thresholded ratios
along paths; Grosse et al. (2009) contribute only the per-component rule
(``edge_rule="component"``).

References
----------
- A. Blake, "Boundary conditions for lightness computation in Mondrian world", Computer
  Vision, Graphics, and Image Processing 32(3), 1985.
- B. K. P. Horn, "Determining lightness from an image", Computer Graphics and Image
  Processing 3(4), 1974.
- E. H. Land and J. J. McCann, "Lightness and retinex theory", JOSA 61(1), 1971.
- R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset and
  baseline evaluations for intrinsic image algorithms", ICCV 2009.
- H. Knutsson and C.-F. Westin, "Normalized and differential convolution", CVPR 1993
  (``edge_illumination="subtract"``).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from pbrbench.checks import (
    as_float_array,
    check_method,
    check_number,
)
from pbrbench.infer._docstring import docstring
from pbrbench.infer.lightness._common import (
    ANCHORS,
    DOCS,
    check_percentile,
    check_threshold,
    log_gradients,
    reconstruct,
)

__all__ = ["EDGE_ILLUMINATION", "EDGE_RULES", "lightness_blake1985"]

EDGE_RULES = ("magnitude", "component")
EDGE_ILLUMINATION = ("keep", "subtract")
_SMOOTH_RADIUS = 3  # half-size of the normalised-convolution window of edge_illumination="subtract"


def _smooth_part(g: np.ndarray, keep: np.ndarray, m: np.ndarray, axis_valid) -> np.ndarray:
    """Illumination part of the differences ``g`` (H, W, C) at every pixel: the mean of the
    discarded (non-edge) differences in a (2r+1)^2 window -- normalised convolution
    (Knutsson & Westin, CVPR 1993) with a box kernel."""
    h, w = keep.shape
    valid = m.copy()
    if axis_valid == (1, 0):  # x-differences exist for column < W-1 with both pixels inside
        valid[:, -1] = False
        valid[:, :-1] &= m[:, 1:]
    else:
        valid[-1, :] = False
        valid[:-1, :] &= m[1:, :]
    wgt = (valid & ~keep).astype(float)
    size = 2 * _SMOOTH_RADIUS + 1
    den = ndimage.uniform_filter(wgt, size, mode="constant")
    out = np.empty_like(g)
    for c in range(g.shape[-1]):
        num = ndimage.uniform_filter(g[..., c] * wgt, size, mode="constant")
        out[..., c] = np.where(den > 1e-9, num / np.where(den > 1e-9, den, 1.0), 0.0)
    return out


@docstring(DOCS)
def lightness_blake1985(image, *, threshold: float = 0.05, anchor: str = "brightest",
                        mean_lightness: float = 0.5, mask=None, edge_rule: str = "magnitude",
                        edge_illumination: str = "keep", min_value: float | None = None,
                        brightest_percentile: float = 100.0, solver: str = "auto"):
    r"""Separate a linear image into reflectance and shading (retinex, Algorithm 1.1).

    With ``L = log C`` and forward differences ``p = L[i, j+1] - L[i, j]``,
    ``q = L[i+1, j] - L[i, j]`` (array-index coordinates, rows going down), the thresholded
    field is ``(p, q) * [e > threshold]`` and the log-albedo solves

    .. math:: \min_l \; |M_x l - p_t|^2 + |M_y l - q_t|^2

    on the (masked) pixel grid, with Neumann boundary conditions (Blake 1985).
    Reflectance is ``exp(l + c)``, shading is ``image / reflectance``, so that
    ``reflectance * shading == image`` exactly on the valid pixels.

    Edge decision (``edge_rule``):

    - ``"magnitude"`` (the chapter's wording, default): at each pixel the gradient vector
      ``(p, q)`` is kept whole when its magnitude ``e = sqrt(p^2 + q^2)`` exceeds ``threshold``
      and zeroed otherwise.
    - ``"component"`` (Grosse et al. 2009): each forward difference is kept when ``|p|``
      (resp. ``|q|``) exceeds ``threshold``.

    Colour, (H, W, C): the log-gradients are computed per channel, but the edge decision is
    shared: ``e`` is the root mean square over channels, ``sqrt(mean_c(p_c^2 + q_c^2))``
    (resp. ``sqrt(mean_c p_c^2)`` per component), and a kept edge is kept in every channel.
    An albedo edge that changes only the hue is therefore kept in all channels, and a grey
    image replicated into C channels gives the same decisions as the grey image; each channel
    is then reconstructed separately, so a colour Mondrian keeps its colours.

    Constant of integration (``anchor``), fixed per channel over the valid pixels:

    - ``"brightest"``: the brightest patch is white, ``max reflectance = 1`` (or the
      ``brightest_percentile`` percentile of the log-albedo; 100 = the maximum).  Per channel
      this is Land's white-patch normalisation: a white paper under a coloured light comes out
      white.  Exact when the brightest paper is white, wrong by its albedo otherwise.
    - ``"mean"``: the mean lightness is fixed, ``mean(reflectance) = mean_lightness``.

    When the valid domain has several 4-connected components, the reconstruction fixes each
    component's mean log-albedo to zero before the single global anchor is applied: their
    relative lightness is unknown (nothing links them).

    Parameters
    ----------
    image : (H, W) or (H, W, C) array
        Linear image (radiance or a linear camera), > 0 on the valid pixels.
    threshold : float
        Threshold on the log-gradient in log units per pixel (0.05 ~ a 5 % step).  It must lie
        above the illumination's per-pixel log gradient and noise, and below the smallest paper
        contrast.
    anchor : {"brightest", "mean"}
        Rule for the constant of integration (see above).
    mean_lightness : float
        Mean reflectance imposed by ``anchor="mean"``.
    mask : (H, W) bool, optional
        Valid pixels; outside, reflectance and shading are 0 and no gradient crosses the border.
    edge_rule : {"magnitude", "component"}
        How the threshold is applied (see above).
    edge_illumination : {"keep", "subtract"}
        ``"keep"`` (the chapter's algorithm): a kept difference is used as it is, so it also
        carries the light's change across that pixel pair; patch ratios then drift by about
        the light's per-pixel log gradient per edge crossed (1 % per edge at 0.01 / pixel).
        ``"subtract"``: from each kept difference the local illumination gradient is
        subtracted, estimated as the mean of the discarded (non-edge) differences of the same
        direction in a 7x7 window (normalised convolution; Knutsson & Westin, "Normalized and
        differential convolution", CVPR 1993); the leak drops to second order.
    min_value : float, optional
        If given, pixels with a channel below it are dropped from the domain (treated as
        outside the mask) instead of raising; use it for black background or deep shadow.
    brightest_percentile : float
        Percentile of the log-albedo taken as white by ``anchor="brightest"`` (robust to
        isolated bright outliers when < 100).
    solver : str
        Poisson solver, passed as ``method`` to :func:`~pbrbench.infer.poisson.solve_gradient_field`.

    %(returns)s

    Raises
    ------
    ValueError
        Wrong dimensions, NaN/inf or non-positive values inside the mask (unless
        ``min_value``), a bad mask, an unknown ``anchor``/``edge_rule``, or invalid numbers.

    References
    ----------
    A. Blake, "Boundary conditions for lightness computation in Mondrian world", CVGIP 32(3),
    1985; E. H. Land and J. J. McCann, "Lightness and retinex theory", JOSA 1971 (white-patch
    anchor); B. K. P. Horn, "Determining lightness from an image", CGIP 1974; R. Grosse et al.,
    ICCV 2009 (``edge_rule="component"``).
    """
    img = as_float_array(image, "image", ndim=(2, 3))
    check_method(anchor, ANCHORS, "anchor")
    check_method(edge_rule, EDGE_RULES, "edge_rule")
    check_method(edge_illumination, EDGE_ILLUMINATION, "edge_illumination")
    t = check_threshold(threshold)
    mean_lightness = check_number(mean_lightness, "mean_lightness", lo=0.0, lo_open=True, hi=1.0)
    pct = check_percentile(brightest_percentile)
    x, m, gx, gy = log_gradients(img, mask, min_value)

    if edge_rule == "magnitude":
        e = np.sqrt(np.mean(gx * gx + gy * gy, axis=-1))
        keep_x = keep_y = e > t
    else:
        keep_x = np.sqrt(np.mean(gx * gx, axis=-1)) > t
        keep_y = np.sqrt(np.mean(gy * gy, axis=-1)) > t
    if edge_illumination == "subtract":
        gx -= _smooth_part(gx, keep_x, m, (1, 0)) * keep_x[..., None]
        gy -= _smooth_part(gy, keep_y, m, (0, 1)) * keep_y[..., None]
    gx *= keep_x[..., None]
    gy *= keep_y[..., None]

    return reconstruct(x, m, gx, gy, anchor, mean_lightness, pct, solver, grey=img.ndim == 2)


