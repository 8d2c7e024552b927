"""Lightness from one image: reflectance and shading of a flat, matte "Mondrian" world.

Model: a frontal, matte, flat scene seen by a linear camera, ``C(x) = k I(x) rho(x)``, so
``log C = log k + log I + log rho``.  Albedo ``rho`` is piecewise constant (a "Mondrian" of
papers), illumination ``I`` varies slowly; hence large log-gradients are albedo edges and small
ones are illumination.  Differentiate ``log C``, drop the small gradients, integrate, and fix the
missing constant of integration by a rule (the brightest patch is white, or the mean lightness
is given).  The known failure is a sharp illumination edge (a cast shadow), which passes the
threshold and is taken for paint.

Image methods share the signature ``fn(image, *, <own options>) -> (reflectance, shading)``;
:data:`METHODS` maps a name to each and :func:`estimate_lightness` dispatches by name:

- ``"blake1985"``: :func:`lightness_blake1985` (:mod:`~pbrbench.infer.lightness.blake1985`), the
  chapter's Algorithm 1.1: thresholded log-gradients, least-squares (Poisson) reconstruction,
  anchor rule; options ``threshold``, ``anchor``, ``mean_lightness``, ``mask``, ``edge_rule``,
  ``edge_illumination``, ``min_value``, ``brightest_percentile``, ``solver``.

- ``"grosse2009"``: :func:`lightness_grosse2009` (:mod:`~pbrbench.infer.lightness.grosse2009`),
  colour retinex: a log-gradient is paint when its luminance part exceeds ``threshold`` or its
  chromaticity part exceeds ``chromaticity_threshold`` (Grosse et al. 2009, after Funt et al.
  1992); :func:`select_thresholds_hold_one_out` chooses both on a data set by hold-one-out.

Profiles (1-D signals, not images; not in :data:`METHODS`): :func:`lightness_1d_horn1974`
(:mod:`~pbrbench.infer.lightness.horn1974`), the chapter's Fig. 1.11.

Names: ``retinex`` (= :func:`lightness_blake1985`) and ``retinex_1d`` (=
:func:`lightness_1d_horn1974`) stay importable.  Why these papers (all four are cited by the
methods): Blake (1985) thresholds the gradient and reconstructs by least squares with Neumann
boundary conditions, which is exactly the 2-D algorithm; Horn (1974) thresholds the Laplacian in
2-D (not what is done here) but his 1-D scheme (difference, threshold, sum) is exactly the profile
method; Land & McCann (1971) contribute the white-patch anchor and Grosse et al. (2009) the
per-component edge rule, both options rather than methods.

References
----------
- E. H. Land and J. J. McCann, "Lightness and retinex theory", JOSA 61(1), 1971.
- B. K. P. Horn, "Determining lightness from an image", Computer Graphics and Image
  Processing 3(4), 1974.
- A. Blake, "Boundary conditions for lightness computation in Mondrian world", Computer
  Vision, Graphics, and Image Processing 32(3), 1985.
- R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset and
  baseline evaluations for intrinsic image algorithms", ICCV 2009.
- B. V. Funt, M. S. Drew and M. Brockington, "Recovering shading from color images", ECCV 1992.
"""

from __future__ import annotations

from pbrbench.checks import call_method
from pbrbench.infer.lightness._common import ANCHORS
from pbrbench.infer.lightness.blake1985 import EDGE_ILLUMINATION, EDGE_RULES, lightness_blake1985
from pbrbench.infer.lightness.grosse2009 import lightness_grosse2009, select_thresholds_hold_one_out
from pbrbench.infer.lightness.horn1974 import lightness_1d_horn1974

__all__ = [
    "ANCHORS",
    "EDGE_ILLUMINATION",
    "EDGE_RULES",
    "METHODS",
    "estimate_lightness",
    "lightness_1d_horn1974",
    "lightness_blake1985",
    "lightness_grosse2009",
    "retinex",
    "retinex_1d",
    "select_thresholds_hold_one_out",
]

METHODS = {
    "blake1985": lightness_blake1985,
    "grosse2009": lightness_grosse2009,
}

retinex = lightness_blake1985
retinex_1d = lightness_1d_horn1974


def estimate_lightness(image, *, method: str = "blake1985", **options):
    r"""Separate a linear image into reflectance and shading with the method ``method``.

    .. math:: \log C = \log k + \log I + \log \rho

    with the large log-gradients taken for albedo edges (module docstring).

    Parameters
    ----------
    image : (H, W) or (H, W, C) array
        Linear image, > 0 on the valid pixels.
    method : str
        A key of :data:`METHODS`.
    **options
        Options of that method (for ``"blake1985"``: ``threshold``, ``anchor``,
        ``mean_lightness``, ``mask``, ``edge_rule``, ``edge_illumination``, ``min_value``,
        ``brightest_percentile``, ``solver``); an option it does not accept raises
        ``ValueError`` listing those it accepts.

    Returns
    -------
    reflectance, shading : arrays of the image's shape, ``reflectance * shading == image`` on
    the valid pixels.

    References
    ----------
    A. Blake, "Boundary conditions for lightness computation in Mondrian world", CVGIP 1985
    (the default method).
    """
    return call_method(METHODS, method, "estimate_lightness", image, **options)
