"""Lightness of a 1-D profile: forward differences of the log, threshold, summation (Horn 1974).

Why "horn1974": the method is Horn's one-dimensional scheme literally (his forward-differencing,
threshold and summing operators on the log intensity); Land & McCann's (1971) ratio-threshold-
product along a path is the same computation in ratio form, plus the reset that makes the
brightest sample white (here ``anchor="brightest"``).  It is the chapter's Fig. 1.11
(D. A. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, "Light and shading").

References
----------
- B. K. P. Horn, "Determining lightness from an image", Computer Graphics and Image
  Processing 3(4), 1974.
- E. H. Land and J. J. McCann, "Lightness and retinex theory", JOSA 61(1), 1971.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_method, check_number
from pbrbench.infer.lightness._common import (
    ANCHORS,
    anchor_reflectance,
    check_percentile,
    check_threshold,
)

__all__ = ["lightness_1d_horn1974"]


def lightness_1d_horn1974(profile, *, threshold: float = 0.05, anchor: str = "brightest",
                          mean_lightness: float = 0.5, brightest_percentile: float = 100.0):
    r"""Retinex on a 1-D profile (Horn 1974; the chapter's Fig. 1.11).

    ``d_k = log C_{k+1} - log C_k`` is zeroed where ``|d_k| <= threshold`` and integrated
    exactly, ``l_k = sum_{i<k} d_i`` (in 1-D the least-squares problem has this exact
    solution); the constant is fixed by ``anchor`` as in
    :func:`~pbrbench.infer.lightness.blake1985.lightness_blake1985`.  For a (N, C) profile the
    decision uses the RMS over channels, shared by all channels.

    Parameters
    ----------
    profile : (N,) or (N, C) array, > 0
    threshold, anchor, mean_lightness, brightest_percentile
        As in :func:`~pbrbench.infer.lightness.blake1985.lightness_blake1985`.

    Returns
    -------
    reflectance, shading : arrays of the profile's shape with ``reflectance * shading == profile``.

    References
    ----------
    B. K. P. Horn, "Determining lightness from an image", Computer Graphics and Image
    Processing 3(4), 1974; E. H. Land and J. J. McCann, "Lightness and retinex theory", JOSA
    61(1), 1971.
    """
    prof = as_float_array(profile, "profile", ndim=(1, 2))
    check_method(anchor, ANCHORS, "anchor")
    t = check_threshold(threshold)
    mean_lightness = check_number(mean_lightness, "mean_lightness", lo=0.0, lo_open=True, hi=1.0)
    pct = check_percentile(brightest_percentile)
    if prof.shape[0] < 1:
        raise ValueError("profile: is empty; pass at least one sample")
    one = prof.ndim == 1
    x = prof[:, None] if one else prof
    check_finite(x, "profile")
    if np.any(x <= 0):
        raise ValueError(f"profile: {int(np.sum(np.any(x <= 0, axis=-1)))} sample(s) are <= 0, "
                         "where the log is undefined; crop or clip the profile to positive values")
    d = np.diff(np.log(x), axis=0)
    keep = np.sqrt(np.mean(d * d, axis=-1)) > t
    d = d * keep[:, None]
    log_refl = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(d, axis=0)], axis=0)
    refl = anchor_reflectance(log_refl, np.ones(x.shape[0], dtype=bool), anchor, mean_lightness, pct)
    shading = x / refl
    if one:
        return refl[:, 0], shading[:, 0]
    return refl, shading
