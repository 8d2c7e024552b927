"""Radiometric calibration and HDR merging from an exposure bracket.

Model: a pixel level ``Z = f(E * t)`` for irradiance ``E`` and exposure time ``t`` (reciprocity),
``f`` monotone and unknown.  A calibration returns a :class:`CameraResponse` whose
``inverse[z, c]`` is ``f_c^{-1}(z)`` up to the free scale, which is fixed the same way for every
method and channel: ``inverse[levels - 1, c] == 1``, i.e. exposure is measured relative to the
clipping point.  All channels of a sensor clip at the same exposure, so this gauge keeps the
colour balance (the classical ``g(Z_mid) = 0`` gauge per channel does not).

Images are ``(K, H, W[, C])`` unsigned integers of any bit depth up to 16 (or a sequence of
``(H, W[, C])`` arrays), sorted by strictly increasing exposure time (seconds).  The lowest and the
highest level are treated as clipped: they get weight zero everywhere.

Calibration methods share the signature ``fn(images, exposure_times, *, <own options>) ->
CameraResponse``; :data:`CALIBRATION_METHODS` maps a name to each and :func:`calibrate_response`
dispatches by name:

- ``"debevec1997"``: :func:`calibrate_debevec1997`, least squares for ``g = ln f^{-1}``;
- ``"robertson2003"``: :func:`calibrate_robertson2003`, the ML alternation of Robertson et al.;
- ``"mitsunaga1999"``: :func:`calibrate_mitsunaga1999`, polynomial ``f^{-1}`` and re-estimated
  exposure ratios;
- ``"grossberg_nayar2003"``: :func:`calibrate_grossberg_nayar2003`, from the exposures'
  histograms only (brightness transfer functions): needs no registration.

Merge methods (:mod:`pbrbench.infer.hdr.merge`): :data:`MERGE_METHODS` and the dispatcher
:func:`merge_hdr`; ``"granados2010"`` (:func:`merge_granados2010`, the linear-domain
inverse-variance estimator with the camera noise model) is the default, ``"debevec1997"``
(:func:`merge_debevec1997`, the log-domain average) the one every version before it used.

Adding a calibration is one new module in this package (named after its paper, built on
:mod:`pbrbench.infer.hdr._common`) plus one line in :data:`CALIBRATION_METHODS`.

References
----------
- P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from Photographs",
  SIGGRAPH 1997.
- M. A. Robertson, S. Borman and R. L. Stevenson, "Dynamic range improvement through multiple
  exposures", ICIP 1999; "Estimation-theoretic approach to dynamic range enhancement using
  multiple exposures", Journal of Electronic Imaging 12(2), 2003.
- T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999.
- M. D. Grossberg and S. K. Nayar, "Determining the camera response from images: what is
  knowable?", IEEE TPAMI 25(11):1455-1467, 2003.
- M. Granados, B. Ajdin, M. Wand, C. Theobalt, H.-P. Seidel and H. P. A. Lensch, "Optimal HDR
  reconstruction with linear digital cameras", CVPR 2010 (inverse-variance weights).
"""

from __future__ import annotations

from pbrbench.checks import call_method
from pbrbench.infer.hdr._common import CALIBRATION_WEIGHTINGS
from pbrbench.infer.hdr.debevec1997 import calibrate_debevec1997
from pbrbench.infer.hdr.grossberg_nayar2003 import calibrate_grossberg_nayar2003
from pbrbench.infer.hdr.merge import (
    MERGE_METHODS,
    MERGE_WEIGHTINGS,
    merge_debevec1997,
    merge_granados2010,
    merge_hdr,
)
from pbrbench.infer.hdr.mitsunaga1999 import calibrate_mitsunaga1999
from pbrbench.infer.hdr.response import CameraResponse
from pbrbench.infer.hdr.robertson2003 import calibrate_robertson2003

__all__ = [
    "CALIBRATION_METHODS",
    "CALIBRATION_WEIGHTINGS",
    "MERGE_METHODS",
    "MERGE_WEIGHTINGS",
    "CameraResponse",
    "calibrate_debevec1997",
    "calibrate_grossberg_nayar2003",
    "calibrate_mitsunaga1999",
    "calibrate_response",
    "calibrate_robertson2003",
    "merge_debevec1997",
    "merge_granados2010",
    "merge_hdr",
]

CALIBRATION_METHODS = {
    "debevec1997": calibrate_debevec1997,
    "robertson2003": calibrate_robertson2003,
    "mitsunaga1999": calibrate_mitsunaga1999,
    "grossberg_nayar2003": calibrate_grossberg_nayar2003,
}


def calibrate_response(images, exposure_times, *, method: str = "debevec1997", **options) -> CameraResponse:
    """Recover the inverse camera response from an exposure bracket with the method ``method``.

    Parameters
    ----------
    images : array (K, H, W[, C]) or sequence, unsigned integers
    exposure_times : sequence of K floats, strictly increasing, seconds
    method : str
        A key of :data:`CALIBRATION_METHODS`.
    **options
        Options of that method (e.g. ``smoothness`` for ``"debevec1997"``, ``degree`` for
        ``"mitsunaga1999"``); an option it does not accept raises ``ValueError`` listing those
        it accepts.

    Returns
    -------
    CameraResponse

    References
    ----------
    See :data:`CALIBRATION_METHODS`: Debevec & Malik, SIGGRAPH 1997; Robertson, Borman &
    Stevenson, J. Electronic Imaging 2003; Mitsunaga & Nayar, CVPR 1999.
    """
    return call_method(CALIBRATION_METHODS, method, "calibrate_response", images, exposure_times, **options)
