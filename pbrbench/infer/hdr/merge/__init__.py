"""HDR merging: an exposure bracket and a calibrated response to linear radiance.

Every merge method is a function

    ``fn(images, exposure_times, response, *, return_mask=False, <own options>)``

returning the (H, W, C) float32 radiance, > 0 everywhere and defined up to one global scale
(plus, with ``return_mask``, the (H, W, C) boolean mask of pixels saturated in every exposure).
:data:`MERGE_METHODS` maps a method's name to it and :func:`merge_hdr` dispatches by name.

Adding a merge method is one new module in this package (named after its paper, built on the
shared checks and helpers of :mod:`pbrbench.infer.hdr._common`: ``as_stack``, ``check_times``,
``check_response``, ``response_table``, ``check_noise_model``, ``estimate_noise``,
``fill_unexposed`` / ``unexposed_bounds``, ``merge_output``) plus one line in :data:`MERGE_METHODS`.

Methods
-------
- ``"granados2010"`` (the default): :func:`~pbrbench.infer.hdr.merge.granados2010.merge_granados2010`,
  the linear-domain inverse-variance estimator of Granados et al. (2010) with the camera noise
  model (read + shot + quantisation; estimated from the bracket when not given).  Chosen as the
  default by measurement (``pbrbench perf hdr``): as accurate as ``"debevec1997"`` without
  noise, and within a few per cent of the best linear merge under read and shot noise, where
  the log-domain average is biased on the dark pixels.
- ``"debevec1997"``: :func:`~pbrbench.infer.hdr.merge.debevec1997.merge_debevec1997`, the
  weighted log-domain average of Debevec & Malik (1997, eq. 6); its default ``"variance"``
  weights are the inverse variance of each exposure's log estimate.
"""

from __future__ import annotations

from pbrbench.checks import call_method
from pbrbench.infer._docstring import docstring
from pbrbench.infer.hdr._common import DOCS
from pbrbench.infer.hdr.merge.debevec1997 import MERGE_WEIGHTINGS, merge_debevec1997
from pbrbench.infer.hdr.merge.granados2010 import merge_granados2010

__all__ = ["DEFAULT_MERGE", "MERGE_METHODS", "MERGE_WEIGHTINGS", "merge_debevec1997", "merge_granados2010",
           "merge_hdr"]

DEFAULT_MERGE = "granados2010"   # merge_hdr's default, and the command line's

MERGE_METHODS = {
    "debevec1997": merge_debevec1997,
    "granados2010": merge_granados2010,
}


@docstring(DOCS)
def merge_hdr(images, exposure_times, response, *, method: str = DEFAULT_MERGE, **options):
    """Merge an exposure bracket into linear radiance with the merge method ``method``.

    Parameters
    ----------
    %(merge_bracket)s
    response : CameraResponse
        From :func:`pbrbench.infer.hdr.calibrate_response` (or built by hand).
    method : str
        A key of :data:`MERGE_METHODS`; the default is ``"granados2010"``; ``"debevec1997"``
        (with its default ``weighting="variance"``) is the merge every earlier version used.
    **options
        Options of that method (``noise_model``, ``iterations``, ``return_mask`` for
        ``"granados2010"``; ``weighting``, ``noise_model``, ``return_mask`` for ``"debevec1997"``); an option it does not accept raises ``ValueError`` listing those it
        accepts.

    Returns
    -------
    radiance : ndarray (H, W, C) float32, > 0
    saturated : ndarray (H, W, C) bool, only with ``return_mask=True``

    References
    ----------
    M. Granados, B. Ajdin, M. Wand, C. Theobalt, H.-P. Seidel and H. P. A. Lensch, "Optimal HDR
    reconstruction with linear digital cameras", CVPR 2010 (the default method); P. E. Debevec
    and J. Malik, "Recovering High Dynamic Range Radiance Maps from Photographs", SIGGRAPH 1997.
    """
    return call_method(MERGE_METHODS, method, "merge_hdr", images, exposure_times, response, **options)
