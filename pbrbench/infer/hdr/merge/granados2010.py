"""HDR merging by the linear-domain inverse-variance estimator of Granados et al. (2010).

Reference: M. Granados, B. Ajdin, M. Wand, C. Theobalt, H.-P. Seidel and H. P. A. Lensch,
"Optimal HDR reconstruction with linear digital cameras", CVPR 2010.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int
from pbrbench.infer.hdr._common import (
    as_stack,
    check_noise_model,
    check_response,
    check_times,
    response_table,
    unexposed_bounds,
)
from pbrbench.infer.hdr.merge._granados_noise import (  # noqa: F401 - the estimator's helpers, for the tests
    _bin_index,
    _bin_table,
    _group_median_mad,
    _noise_levels,
    estimate_noise_levels,
)
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["estimate_noise_levels", "merge_granados2010"]

# 2: the noise estimate samples at most max_pixels = 8192 pixels per pair (the grid step was
# rounded down: 28900 at 512 x 512 for 16384), groups by f^-1 at the mean neighbour level and
# reweights its fit with the fitted variances (no bias from the sample size)
# 3: max_pixels = 4096 (grid step 8 at 512 x 512): on the 512 x 512 brackets of
# ``pbrbench perf hdr`` the merged log2 RMSE is the same to six digits over five noise seeds,
# and the noise estimate takes 45 % less time; the HDR task's renders (32 x 32 at draft,
# 128 x 128 at standard) sample the same pixels as before (steps 1 and 2)
VERSION = "4"  # the noise fit reweights a first fit of a = b = 0 as any other (no jump between b = 0 and the reweighted b)


def merge_granados2010(images, exposure_times, response: CameraResponse, *,
                       noise_model: tuple[float, float] | None = None, iterations: int = 0,
                       return_mask: bool = False):
    r"""Merge an exposure bracket into linear radiance with inverse-variance weights (linear domain).

    With ``x_k = f^{-1}(Z_k)`` the linearised level of exposure ``k`` (time ``\Delta t_k``),
    each usable exposure gives an unbiased estimate ``x_k / \Delta t_k`` of the radiance ``E``
    (up to the response's scale) with variance ``\sigma_k^2 / \Delta t_k^2``.  The minimum-
    variance unbiased combination (Granados et al. 2010, eq. 5-7) is

    .. math::

        \hat E = \frac{\sum_k w_k\, x_k / \Delta t_k}{\sum_k w_k}, \qquad
        w_k = \frac{\Delta t_k^2}{\sigma_k^2}, \qquad
        \sigma_k^2 = \sigma_r^2 + \frac{\hat x_k}{N_{fw}} + \frac{1}{12}
        \left(\frac{d f^{-1}}{dz}\right)^2_{Z_k},

    the camera noise model of read noise ``\sigma_r`` (fraction of full scale), shot noise of a
    full well of ``N_{fw}`` electrons and quantisation.  The first pass evaluates the shot term
    at the measurement (``\hat x_k = x_k``); each of ``iterations`` further passes evaluates it
    at the prediction ``\hat x_k = \hat E \Delta t_k`` of the previous estimate (Granados et
    al. iterate the same way: weights computed from the noisy measurement itself favour the
    exposures whose noise happened to be negative).  Averaging in the linear domain keeps the
    estimator unbiased for dark, noisy pixels, where a log-domain average (Debevec & Malik
    1997, eq. 6) is biased and heavy-tailed.

    Excluded measurements: level 0 (black: the signal is below the first level, censored) and
    the top level (clipped).  Every pixel gets a finite, positive value.  A pixel that no
    exposure measures gets the best bound the bracket gives: clipped high in some exposure,
    the lower bound ``f^{-1}(top) / \Delta t_{min}`` of its shortest clipped exposure; black in
    every exposure, the upper bound ``f^{-1}(1) / \Delta t_{max}`` of its longest black one;
    both (black in the long and clipped in the short ones, a bracket with a gap), the geometric
    mean of the two bounds.  ``return_mask`` flags the pixels clipped in every exposure.

    Noise model: ``noise_model = (read_noise, full_well)`` when the camera is known (``np.inf``
    for no shot noise); otherwise ``(\sigma_r^2, 1 / N_{fw})`` are estimated from the bracket
    by :func:`estimate_noise_levels` (the spread of the
    differences ``x_{k+1} - r_k x_k`` of adjacent exposures at each level, with its mean
    removed so that calibration and exposure-time errors do not count as noise).

    Parameters
    ----------
    images : array (K, H, W[, C]) or sequence, unsigned integers (8 to 16 bits)
    exposure_times : sequence of K floats, strictly increasing, seconds (for a
        ``"mitsunaga1999"`` response, pass ``response.exposure_times``)
    response : CameraResponse
        One channel is broadcast to all image channels.  Its gauge (``inverse[-1] == 1`` at
        clipping) is the unit of ``read_noise``.
    noise_model : (read_noise, full_well) or None
        Read-noise standard deviation as a fraction of full scale and full-well capacity in
        electrons; None estimates both from the bracket.
    iterations : int
        Re-weighting passes with the shot noise at the predicted exposure (>= 0; skipped when
        there is no shot noise, where the weights do not depend on the signal).
    return_mask : bool
        Also return the (H, W, C) boolean mask of pixels clipped in every exposure.

    Returns
    -------
    radiance : ndarray (H, W, C) float32, finite and > 0
    saturated : ndarray (H, W, C) bool, only if ``return_mask``

    Raises
    ------
    ValueError
        On images that are not unsigned integer levels, times that are not strictly increasing
        or do not match the images, a response that is not a :class:`CameraResponse` or whose
        levels/channels do not fit the images, a bad ``noise_model`` or ``iterations < 0``.

    References
    ----------
    M. Granados, B. Ajdin, M. Wand, C. Theobalt, H.-P. Seidel and H. P. A. Lensch, "Optimal HDR
    reconstruction with linear digital cameras", CVPR 2010; P. E. Debevec and J. Malik,
    "Recovering High Dynamic Range Radiance Maps from Photographs", SIGGRAPH 1997 (the bounds
    for unmeasured pixels are those of :func:`~pbrbench.infer.hdr.merge.debevec1997.merge_debevec1997`).
    """
    check_response(response)
    Z, _ = as_stack(images, None)
    K, H, W, C = Z.shape
    t = check_times(exposure_times, K)
    inv = response_table(response, Z)
    nm = check_noise_model(noise_model)
    n_iter = check_int(iterations, "iterations", 0)
    levels = response.levels
    top = levels - 1
    q = np.gradient(inv, axis=0) ** 2 / 12.0
    usable = np.ones(levels, bool)
    usable[0] = usable[top] = False
    # one complex LUT per exposure and channel: real part t_k x / var, imaginary part t_k^2 / var
    # (numerator and denominator in one lookup; looked up through a float64 view, which NumPy's
    # take handles several times faster than complex64)
    Zt = np.moveaxis(Z, 3, 1)  # (K, C, H, W) view: strided lookups beat a transposed copy
    acc = np.empty((C, H, W), np.complex64)
    buf = np.empty((H, W), np.float64)  # one exposure's lookup, as float64 pairs of complex64
    if nm is None:
        noise = _noise_levels(Z, t, inv, [(c, q[:, c]) for c in range(C)])
    else:
        noise = [(nm[0] ** 2, 0.0 if np.isinf(nm[1]) else 1.0 / nm[1])] * C
    for c in range(C):
        a, b = noise[c]
        x = inv[:, c]
        var = a + b * x + q[:, c]
        ok = usable & (var > 0)
        ivar = np.where(ok, 1.0 / np.where(ok, var, 1.0), 0.0)
        out = acc[c]
        for k in range(K):
            lut = (t[k] * x * ivar + 1j * (t[k] ** 2 * ivar)).astype(np.complex64).view(np.float64)
            # mode="clip" writes straight into `out=` (response_table checked the levels)
            if k == 0:
                np.take(lut, Zt[k, c], out=out.view(np.float64), mode="clip")
            else:
                np.take(lut, Zt[k, c], out=buf, mode="clip")
                out += buf.view(np.complex64)
        if b > 0 and n_iter > 0:
            # re-weight with the shot noise at the predicted exposure E t_k (Granados et al.)
            base = np.where(ok, a + q[:, c], np.inf).astype(np.float32)
            xl = x.astype(np.float32)
            for _ in range(n_iter):
                dc = out.imag
                e = np.where(dc > 0, out.real / np.where(dc > 0, dc, 1.0), 0.0).astype(np.float32)
                n2 = np.zeros((H, W), np.float32)
                d2 = np.zeros((H, W), np.float32)
                for k in range(K):
                    z = Zt[k, c]
                    xp = np.minimum(e * np.float32(t[k]), np.float32(1.0))
                    wk = np.float32(t[k]) / (np.take(base, z) + np.float32(b) * xp)
                    n2 += wk * np.take(xl, z)
                    d2 += wk * np.float32(t[k])
                out.real = n2
                out.imag = d2
    den = acc.imag
    empty = den <= 0
    rad = np.empty((H, W, C), np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        for c in range(C):
            np.divide(acc[c].real, den[c], out=rad[..., c])
    ci = yi = xi = None
    if empty.any():
        ci, yi, xi = np.unravel_index(np.flatnonzero(empty), empty.shape)  # np.nonzero, faster
        lnE, sat = unexposed_bounds(Zt, ci, yi, xi, np.log(inv), np.log(t), top)
        rad[yi, xi, ci] = np.exp(lnE)
    if return_mask:
        saturated = np.zeros((H, W, C), bool)
        if ci is not None:
            saturated[yi, xi, ci] = sat
        return rad, saturated
    return rad
