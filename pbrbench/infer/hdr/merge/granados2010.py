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
    fill_unexposed,
    response_table,
)
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["estimate_noise_levels", "merge_granados2010"]


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
    acc = np.zeros((C, H, W), np.complex64)
    for c in range(C):
        if nm is None:
            a, b = estimate_noise_levels(Z, t, inv, q[:, c], c)
        else:
            a, b = nm[0] ** 2, (0.0 if np.isinf(nm[1]) else 1.0 / nm[1])
        x = inv[:, c]
        var = a + b * x + q[:, c]
        ok = usable & (var > 0)
        ivar = np.where(ok, 1.0 / np.where(ok, var, 1.0), 0.0)
        out = acc[c]
        for k in range(K):
            lut = (t[k] * x * ivar + 1j * (t[k] ** 2 * ivar)).astype(np.complex64).view(np.float64)
            out += np.take(lut, Zt[k, c]).view(np.complex64)
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
    saturated = np.zeros((C, H, W), bool)
    if empty.any():
        lnE = np.zeros((C, H, W))
        saturated = fill_unexposed(lnE, empty, Zt, np.log(inv), np.log(t), top)
        ci, yi, xi = np.nonzero(empty)
        rad[yi, xi, ci] = np.exp(lnE[ci, yi, xi])
    if return_mask:
        return rad, np.ascontiguousarray(np.moveaxis(saturated, 0, 2))
    return rad


def estimate_noise_levels(Z: np.ndarray, t: np.ndarray, inv: np.ndarray, q: np.ndarray, c: int,
                          max_pixels: int = 16384, min_count: int = 8, n_bins: int = 48) -> tuple[float, float]:
    r"""Fit the camera noise model ``var(x) = a + b x`` (``a = sigma_r^2``, ``b = 1 / N_fw``,
    ``a, b >= 0``) of channel ``c`` from the spread of adjacent exposures.

    For each pair of adjacent exposures ``k, k+1`` (ratio ``r = t_{k+1} / t_k``) the
    differences ``d = x_{k+1} - r x_k`` of a pixel cancel its radiance and have

    .. math:: \mathrm{var}(d) = a (1 + r^2) + b (\bar x_{k+1} + r^2 \bar x_k)
              + \bar q_{k+1} + r^2 \bar q_k,

    with ``q`` the known quantisation variance.  Pixels are grouped by the mean of ``x_k`` over
    their 8 neighbours (independent of the pixel's own noise, so the grouping does not select
    the noise: grouping by the pixel's own level would), and only the spread about each group's
    mean counts, so a calibration error or a mis-stated exposure time (a systematic offset of
    ``d``) is not taken for noise.  Differences beyond 4 robust standard deviations of their
    group (edges, motion) are dropped first.  Pairs where either level is black or clipped are
    left out, and so are groups whose prediction ``r x_k`` is above 0.8 (their partner is
    censored by clipping).  ``(a, b)`` is the weighted least-squares fit of the group variances
    (weights ``n / var^2``: relative errors, ``var`` floored at its 10th percentile over the
    groups), with ``a`` or ``b`` clamped at 0 if the unconstrained fit is negative.

    ``Z``: (K, H, W, C) levels; ``t``: (K,) times; ``inv``: (levels, C) inverse response
    (gauge ``inv[-1] = 1``); ``q``: (levels,) quantisation variance of channel ``c``; at most
    about ``max_pixels`` pixels (a regular grid) are used per pair.  Returns ``(a, b)``;
    ``(0, 0)`` when no group has ``min_count`` pixels.
    """
    K, H, W = Z.shape[:3]
    levels = inv.shape[0]
    top = levels - 1
    x = inv[:, c]
    if H < 3 or W < 3:
        return 0.0, 0.0
    step = max(1, int(np.sqrt((H - 2) * (W - 2) / max_pixels)))
    ys, xs = slice(1, H - 1, step), slice(1, W - 1, step)
    offs = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]

    def around(k):  # mean of x over the 8 neighbours of the grid pixels
        acc = 0.0
        for dy, dx in offs:
            acc = acc + x[Z[k, 1 + dy:H - 1 + dy:step, 1 + dx:W - 1 + dx:step, c]]
        return (acc / 8.0).ravel()

    edges = np.linspace(0.0, 1.0, n_bins + 1) ** 2  # finer bins at the dark end
    groups = []
    for k in range(K - 1):
        r = t[k + 1] / t[k]
        za = Z[k, ys, xs, c].ravel().astype(np.intp)
        zb = Z[k + 1, ys, xs, c].ravel().astype(np.intp)
        prox = around(k)
        ok = (za > 0) & (za < top) & (zb > 0) & (zb < top) & (r * prox <= 0.8)
        if not ok.any():
            continue
        za, zb, prox = za[ok], zb[ok], prox[ok]
        gid = np.clip(np.searchsorted(edges, prox * r / 0.8, side="right") - 1, 0, n_bins - 1)
        groups.append((gid + k * n_bins, za, zb, np.full(za.size, r)))
    if not groups:
        return 0.0, 0.0
    g, za, zb, rr = (np.concatenate(a) for a in zip(*groups, strict=True))
    m = (K - 1) * n_bins
    d = x[zb] - rr * x[za]
    # robust rejection: median and MAD per group (by sorting within groups)
    order = np.lexsort((d, g))
    gs, ds = g[order], d[order]
    start = np.searchsorted(gs, np.arange(m), side="left")
    cnt = np.bincount(gs, minlength=m)
    med = np.where(cnt > 0, ds[np.minimum(start + cnt // 2, ds.size - 1)], 0.0)
    dev = np.abs(d - med[g])
    order2 = np.lexsort((dev, g))
    devs = dev[order2]
    mad = np.where(cnt > 0, devs[np.minimum(start + cnt // 2, devs.size - 1)], 0.0)
    keep = dev <= 4.0 * 1.4826 * mad[g] + 1e-12
    g, za, zb, rr, d = g[keep], za[keep], zb[keep], rr[keep], d[keep]
    n = np.bincount(g, minlength=m).astype(float)
    nn = np.maximum(n, 1.0)
    mean = np.bincount(g, weights=d, minlength=m) / nn
    var = np.bincount(g, weights=(d - mean[g]) ** 2, minlength=m) / np.maximum(nn - 1, 1)
    qs = np.bincount(g, weights=q[zb] + rr * rr * q[za], minlength=m) / nn
    u1 = np.bincount(g, weights=x[zb] + rr * rr * x[za], minlength=m) / nn
    u0 = np.bincount(g, weights=1 + rr * rr, minlength=m) / nn
    good = n >= min_count
    if not good.any():
        return 0.0, 0.0
    u0, u1, v, n = u0[good], u1[good], var[good], n[good]
    y = v - qs[good]
    # relative weights; the floor keeps a few groups of (nearly) constant differences (a black
    # or clipped plateau seen through a coarse level) from dominating the fit
    wgt = n / np.maximum(v, max(float(np.percentile(v, 10)), 1e-30)) ** 2
    G = np.array([[np.sum(wgt * u0 * u0), np.sum(wgt * u0 * u1)], [np.sum(wgt * u0 * u1), np.sum(wgt * u1 * u1)]])
    h = np.array([np.sum(wgt * u0 * y), np.sum(wgt * u1 * y)])
    det = G[0, 0] * G[1, 1] - G[0, 1] ** 2
    if det > 1e-12 * G[0, 0] * G[1, 1]:
        a = (G[1, 1] * h[0] - G[0, 1] * h[1]) / det
        b = (G[0, 0] * h[1] - G[0, 1] * h[0]) / det
        if a >= 0 and b >= 0:
            return float(a), float(b)
    fits = [(max(h[0] / G[0, 0], 0.0) if G[0, 0] > 0 else 0.0, 0.0),
            (0.0, max(h[1] / G[1, 1], 0.0) if G[1, 1] > 0 else 0.0)]
    sse = [float(np.sum(wgt * (y - f[0] * u0 - f[1] * u1) ** 2)) for f in fits]
    return fits[int(np.argmin(sse))]
