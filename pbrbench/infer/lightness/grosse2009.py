"""Colour retinex: a log-gradient is paint if its luminance or its chromaticity changes
(Grosse et al. 2009, after Funt, Drew & Brockington 1992).

References
----------
- R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset and
  baseline evaluations for intrinsic image algorithms", ICCV 2009 (colour retinex and the
  hold-one-out protocol).
- B. V. Funt, M. S. Drew and M. Brockington, "Recovering shading from color images", ECCV 1992
  (a change of chromaticity is a change of material).
- A. Blake, "Boundary conditions for lightness computation in Mondrian world", CVGIP 32(3),
  1985 (least-squares reconstruction with Neumann boundary conditions).
"""

from __future__ import annotations

import itertools

import numpy as np

from pbrbench.checks import as_float_array, check_method, check_positive
from pbrbench.infer._docstring import docstring
from pbrbench.infer.lightness._common import (
    ANCHORS,
    DOCS,
    check_percentile,
    check_threshold,
    log_gradients,
    reconstruct,
)

__all__ = ["lightness_grosse2009", "select_thresholds_hold_one_out"]


@docstring(DOCS)
def lightness_grosse2009(image, *, threshold: float = 0.05, chromaticity_threshold: float = 0.05,
                         anchor: str = "brightest", mean_lightness: float = 0.5, mask=None,
                         min_value: float | None = None, brightest_percentile: float = 100.0,
                         solver: str = "auto"):
    r"""Separate a linear colour image into reflectance and shading by colour retinex.

    With ``L_c = log C_c`` and forward differences per channel ``p_c`` (along x) and ``q_c``
    (along y), split each difference into its luminance part (the mean over channels, the
    log-gradient of the geometric-mean luminance) and its chromaticity part (the rest):

    .. math::

        \bar p = \frac{1}{C} \sum_c p_c, \qquad
        \|p^{chr}\| = \Big(\sum_c (p_c - \bar p)^2\Big)^{1/2},

    and keep the difference (in every channel) as paint when

    .. math:: |\bar p| > T_L \quad \text{or} \quad \|p^{chr}\| > T_C

    (the same for ``q``), zero it otherwise, and reconstruct each channel's log-reflectance
    by least squares, ``\min_l |M_x l - p_t|^2 + |M_y l - q_t|^2`` with Neumann boundary
    conditions (Blake 1985; :func:`pbrbench.infer.poisson.solve_gradient_field`).  This is the
    colour retinex of Grosse et al. (2009): shading (even from a coloured light, as long as
    its colour varies slowly) changes the luminance and leaves the chromaticity nearly alone,
    so a chromaticity step is paint even when it is iso-luminant (Funt et al. 1992), which a
    threshold on the luminance (or on the RMS of the RGB log-gradients) misses.  A grey
    image, (H, W) or (H, W, 1), has no chromaticity and reduces to grey retinex with the
    per-component rule.

    Reflectance is ``exp(l + c)`` per channel, the constant ``c`` fixed by ``anchor`` (as in
    :func:`~pbrbench.infer.lightness.blake1985.lightness_blake1985`), and
    ``shading = image / reflectance``.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array
        Linear image (radiance or a linear camera; for an 8-bit photo, linearise it first), > 0
        on the valid pixels.  Its scale does not matter.
    threshold : float
        ``T_L``, on the luminance log-gradient (log units per pixel).
    chromaticity_threshold : float
        ``T_C``, on the norm of the chromaticity log-gradient (log units per pixel); ``np.inf``
        turns the chromaticity test off (grey retinex on the luminance).  Choose both on data
        like yours with :func:`select_thresholds_hold_one_out`.
    anchor, mean_lightness, mask, min_value, brightest_percentile, solver
        As in :func:`~pbrbench.infer.lightness.blake1985.lightness_blake1985`.

    %(returns)s

    Raises
    ------
    ValueError
        Wrong dimensions, NaN/inf or non-positive values inside the mask (unless
        ``min_value``), a bad mask, negative thresholds or an unknown ``anchor``.

    References
    ----------
    R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset and
    baseline evaluations for intrinsic image algorithms", ICCV 2009; B. V. Funt, M. S. Drew and
    M. Brockington, "Recovering shading from color images", ECCV 1992; A. Blake, "Boundary
    conditions for lightness computation in Mondrian world", CVGIP 32(3), 1985.
    """
    img = as_float_array(image, "image", ndim=(2, 3))
    check_method(anchor, ANCHORS, "anchor")
    t_lum = check_threshold(threshold)
    t_chr = float(chromaticity_threshold)
    if np.isnan(t_chr) or t_chr < 0:
        raise ValueError(f"chromaticity_threshold: must be a number >= 0 (log units per pixel) or np.inf, "
                         f"got {chromaticity_threshold!r}")
    mean_lightness = check_positive(mean_lightness, "mean_lightness")
    pct = check_percentile(brightest_percentile)
    x, m, gx, gy = log_gradients(img, mask, min_value)
    keep = []
    for g in (gx, gy):
        lum = g.mean(axis=-1)
        chrom = np.sqrt(np.sum((g - lum[..., None]) ** 2, axis=-1))
        keep.append((np.abs(lum) > t_lum) | (chrom > t_chr))
    gx *= keep[0][..., None]
    gy *= keep[1][..., None]

    return reconstruct(x, m, gx, gy, anchor, mean_lightness, pct, solver, grey=img.ndim == 2)


def select_thresholds_hold_one_out(images, reflectances, shadings, masks=None, *, score=None, thresholds=None,
                                   chromaticity_thresholds=None, **options) -> dict:
    r"""Choose ``(threshold, chromaticity_threshold)`` for :func:`lightness_grosse2009` on a data
    set with ground truth, by the hold-one-out protocol of Grosse et al. (2009).

    For each image ``i`` the pair that minimises the mean ``score`` (the published protocol:
    the intrinsic LMSE, ``pbrbench.metrics.lightness.intrinsic_lmse``) over the *other*
    images is chosen and image ``i`` is scored with it, so the reported score is never tuned
    on the image it scores.

    .. math:: (T_L, T_C)_i = \arg\min_{(T_L, T_C)} \frac{1}{n - 1} \sum_{j \neq i}
              \mathrm{LMSE}_j(T_L, T_C)

    Parameters
    ----------
    images, reflectances, shadings : sequences of n >= 2 arrays (H, W[, C])
        Linear images and their true reflectance and shading (any scale).
    masks : sequence of n (H, W) bool arrays, optional
    score : callable
        ``score(refl_est, shad_est, refl_true, shad_true, mask) -> float``, lower is better, e.g.
        ``lambda r, s, R, S, m: intrinsic_lmse(r, s, R, S, mask=m, window=20)`` with
        ``from pbrbench.metrics.lightness import intrinsic_lmse`` (the inference package does
        not import the metrics itself).
    thresholds, chromaticity_thresholds : sequences of floats, optional
        The grid (default: Grosse et al.'s ``logspace(-1.5, 0, 5)`` for both, plus ``np.inf``
        for the chromaticity test off).
    **options
        Passed to :func:`lightness_grosse2009` (``anchor``, ``min_value``, ...).

    Returns
    -------
    dict with ``grid`` (list of pairs), ``scores`` ((n, len(grid)) LMSE of every image at every
    pair), ``chosen`` (the pair chosen for each image without it), ``held_out`` ((n,) the
    score of each image at its chosen pair), ``mean_held_out`` (their mean: the number to
    report) and ``best`` (the pair minimising the mean over all images: the one to use on new
    data).

    Raises
    ------
    ValueError
        Fewer than 2 images, sequences of different lengths, or no ``score``.

    References
    ----------
    R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset and
    baseline evaluations for intrinsic image algorithms", ICCV 2009.
    """
    if not callable(score):
        raise ValueError("score: pass the error to minimise, e.g. lambda r, s, R, S, m: "
                         "pbrbench.metrics.lightness.intrinsic_lmse(r, s, R, S, mask=m)")
    imgs, refls, shads = list(images), list(reflectances), list(shadings)
    n = len(imgs)
    ms = [None] * n if masks is None else list(masks)
    if n < 2 or not (len(refls) == len(shads) == len(ms) == n):
        raise ValueError(f"images, reflectances, shadings, masks: need n >= 2 of each and the same n; got "
                         f"{len(imgs)}, {len(refls)}, {len(shads)}, {len(ms)}")
    tl = list(np.logspace(-1.5, 0.0, 5)) if thresholds is None else [float(v) for v in thresholds]
    tc = list(np.logspace(-1.5, 0.0, 5)) + [np.inf] if chromaticity_thresholds is None else \
        [float(v) for v in chromaticity_thresholds]
    grid = list(itertools.product(tl, tc))
    scores = np.empty((n, len(grid)))
    for i in range(n):
        for j, (a, b) in enumerate(grid):
            r, s = lightness_grosse2009(imgs[i], threshold=a, chromaticity_threshold=b, mask=ms[i], **options)
            scores[i, j] = float(score(r, s, refls[i], shads[i], ms[i]))
    total = scores.sum(axis=0)
    chosen, held = [], np.empty(n)
    for i in range(n):
        j = int(np.argmin((total - scores[i]) / (n - 1)))
        chosen.append(grid[j])
        held[i] = scores[i, j]
    return {"grid": grid, "scores": scores, "chosen": chosen, "held_out": held,
            "mean_held_out": float(held.mean()), "best": grid[int(np.argmin(total))]}
