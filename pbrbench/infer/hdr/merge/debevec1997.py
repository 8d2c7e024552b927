"""HDR merging by the weighted log-domain average of Debevec & Malik (1997, eq. 6).

Reference: P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from
Photographs", SIGGRAPH 1997.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_method
from pbrbench.infer._docstring import docstring
from pbrbench.infer.hdr._common import (
    DOCS,
    as_stack,
    check_noise_model,
    check_response,
    check_times,
    estimate_noise,
    fill_unexposed,
    level_weights,
    merge_output,
    response_table,
)
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["MERGE_WEIGHTINGS", "merge_debevec1997"]

MERGE_WEIGHTINGS = ("variance", "hat", "uniform", "gaussian")


@docstring(DOCS)
def merge_debevec1997(images, exposure_times, response: CameraResponse, *, weighting: str = "variance",
                      noise_model: tuple[float, float] | None = None, return_mask: bool = False):
    r"""Merge an exposure bracket into linear radiance (up to one global scale), in the log domain.

    Per pixel and channel (Debevec & Malik 1997, eq. 6),

    .. math::

        \ln E = \frac{\sum_k w_k(Z_k)\,(g(Z_k) - \ln \Delta t_k)}{\sum_k w_k(Z_k)}, \qquad
        g = \ln f^{-1},

    with ``w = 0`` at the clipped levels ``0`` and ``levels - 1``.  The default ``"variance"``
    weights are the inverse variance of each exposure's ``ln E_k`` (first-order propagation of
    the noise model): ``w = x^2 / var(x)`` with ``x = f^{-1}(Z)`` (proportional to
    ``\Delta t_k^2 / var`` for a given pixel: exposure-aware, as the weights of Granados et al.
    2010) and ``var(x) = \sigma_r^2 + x / N_{fw} + q(Z)``, ``q`` the quantisation variance
    ``(dx/dz)^2 / 12``.  ``(\sigma_r, N_{fw})`` come from ``noise_model`` or are estimated from
    the differences between adjacent exposures.  The estimator stays the log-domain average of
    eq. 6 whatever the weights (Granados et al. average in the linear domain: a different
    estimator).  ``"hat"`` is the paper's own ``w(z) = min(z, top - z)``.  A pixel with no
    usable exposure gets the best bound: ``f^{-1}(top) / \Delta t_{min}`` (a lower bound) when it
    is clipped high, the upper bound ``f^{-1}(1) / \Delta t_{max}`` when it is black in every
    exposure, and the geometric mean of both bounds if both apply; never 0 or NaN.

    Parameters
    ----------
    %(merge_bracket)s
    response : CameraResponse
        One channel is broadcast to all image channels.
    weighting : {"variance", "hat", "uniform", "gaussian"}
    noise_model : (read_noise, full_well) or None
        Read noise standard deviation as a fraction of full scale and the full-well capacity in
        electrons (``np.inf`` for no shot noise); None estimates them (``"variance"`` only).
    return_mask : bool
        Also return the (H, W, C) boolean mask of pixels saturated in every exposure (their
        value is the lower bound above).

    Returns
    -------
    radiance : ndarray (H, W, C) float32, > 0
    saturated : ndarray (H, W, C) bool, only if ``return_mask``

    References
    ----------
    P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from Photographs",
    SIGGRAPH 1997 (merge equation, eq. 6); M. Granados, B. Ajdin, M. Wand, C. Theobalt,
    H.-P. Seidel and H. P. A. Lensch, "Optimal HDR reconstruction with linear digital cameras",
    CVPR 2010 (inverse-variance weights).
    """
    check_response(response)
    Z, _ = as_stack(images, None)
    K, H, W, C = Z.shape
    t = check_times(exposure_times, K)
    check_method(weighting, MERGE_WEIGHTINGS, "weighting")
    inv = response_table(response, Z)
    nm = check_noise_model(noise_model)
    levels = response.levels
    lnt = np.log(t)
    logx = np.log(inv)
    Zt = np.ascontiguousarray(np.moveaxis(Z, 3, 1))  # (K, C, H, W)
    if Zt.dtype != np.uint8 and levels <= 256:
        Zt = Zt.astype(np.uint8)
    wlut = np.empty((levels, C))
    if weighting == "variance":
        dx = np.gradient(inv, axis=0)
        q = dx**2 / 12.0
        for c in range(C):
            if nm is None:
                a, b = estimate_noise(Zt, t, inv, q[:, c], c)
            else:
                rn, fw = nm
                a, b = rn**2, (0.0 if np.isinf(fw) else 1.0 / fw)
            wlut[:, c] = inv[:, c] ** 2 / (a + b * inv[:, c] + q[:, c])
    else:
        wlut[:] = level_weights(weighting, levels)[:, None]
    wlut[0] = wlut[-1] = 0.0
    wlut /= wlut.max(axis=0, keepdims=True)
    wg = (wlut * logx).astype(np.float32)
    wf = wlut.astype(np.float32)
    num = np.zeros((C, H, W), np.float32)
    den = np.zeros((C, H, W), np.float32)
    for k in range(K):
        for c in range(C):
            z = Zt[k, c]
            lut_n = wg[:, c] - np.float32(lnt[k]) * wf[:, c]
            num[c] += np.take(lut_n, z)
            den[c] += np.take(wf[:, c], z)
    empty = den <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        lnE = num / den
    saturated = fill_unexposed(lnE, empty, Zt, logx, lnt, levels - 1)
    return merge_output(lnE, saturated, return_mask)
