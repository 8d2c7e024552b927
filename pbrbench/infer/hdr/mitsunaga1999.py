"""Radiometric self-calibration by Mitsunaga & Nayar (1999): polynomial ``f^{-1}`` and
re-estimated exposure ratios.

Reference: T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int, check_tolerance
from pbrbench.infer.hdr._common import (
    as_stack,
    check_informative,
    check_times,
    finalise,
    sample_pixels,
)
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["calibrate_mitsunaga1999"]


def _mn_fit(Ma, Mb, R_pair, degree):
    """Least squares for polynomial coefficients with p(1) = 1; rows are pairs (a, b)."""
    N = degree
    n = np.arange(N)
    Pa = Ma[:, None] ** n - (Ma**N)[:, None]
    Pb = Mb[:, None] ** n - (Mb**N)[:, None]
    Aa = Pa - R_pair[:, None] * Pb
    y = -(Ma**N - R_pair * Mb**N)
    coef, *_ = np.linalg.lstsq(Aa, y, rcond=None)
    return np.concatenate([coef, [1.0 - coef.sum()]])


def calibrate_mitsunaga1999(images, exposure_times, *, degree: int | None = None, max_iter: int = 20,
                            tol: float = 1e-6, estimate_ratios: bool = True, samples: int = 4096,
                            seed: int = 0, bit_depth: int | None = None) -> CameraResponse:
    r"""Polynomial inverse response and exposure ratios by Mitsunaga & Nayar (1999).

    With ``M = z / (levels - 1)`` and ``f^{-1}(M) = \sum_{n=0}^{N} c_n M^n``, ``f^{-1}(1) = 1``,
    minimise over pairs of adjacent exposures ``k, k+1``

    .. math::

        \sum_{i,k} \left[ f^{-1}(M_{i,k}) - R_k\, f^{-1}(M_{i,k+1}) \right]^2,
        \qquad R_k = \Delta t_k / \Delta t_{k+1},

    alternating a linear solve for ``c`` with the ratio update
    ``R_k = \sum_i f^{-1}(M_{ik}) f^{-1}(M_{i,k+1}) / \sum_i f^{-1}(M_{i,k+1})^2``.  Response and
    ratios are ambiguous up to ``f^{-1} -> (f^{-1})^\gamma, R -> R^\gamma`` (Grossberg & Nayar);
    the stated span ``\sum_k \ln R_k = \ln(\Delta t_0 / \Delta t_{K-1})`` is kept fixed, which
    removes that ambiguity while the individual ratios are re-estimated.  Ratios are shared by
    all channels.

    Parameters
    ----------
    images, exposure_times
        As for :func:`~pbrbench.infer.hdr.debevec1997.calibrate_debevec1997`; the times are the initial guess.
    degree : int or None
        Polynomial degree ``N`` (>= 1); None picks 2..8 by error on held-out pixels.
    max_iter, tol
        Alternations and convergence threshold on ``max |Delta ln R_k|``.
    estimate_ratios : bool
        Re-estimate the exposure ratios (default) or trust the stated times.
    samples, seed, bit_depth
        As for :func:`~pbrbench.infer.hdr.debevec1997.calibrate_debevec1997`.

    Returns
    -------
    CameraResponse
        With ``exposure_times`` (re-estimated, geometric mean equal to the stated one) and
        ``coefficients`` (degree + 1, C).

    References
    ----------
    T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999.
    """
    Z, levels = as_stack(images, bit_depth)
    t = check_times(exposure_times, Z.shape[0])
    check_informative(Z, levels)
    if degree is not None:
        degree = check_int(degree, "degree", 1, 20)
    max_iter = check_int(max_iter, "max_iter", 1)
    tol = check_tolerance(tol)
    n_samp = check_int(samples, "samples", 1)
    K, H, W, C = Z.shape
    top = levels - 1
    idx_c = sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    # pairs (channel, pair index k, Ma, Mb)
    pairs = []
    for c in range(C):
        z = flat[:, idx_c[c], c].astype(np.float64)
        for k in range(K - 1):
            za, zb = z[k], z[k + 1]
            ok = (za > 0) & (za < top) & (zb > 0) & (zb < top)
            pairs.append((c, k, za[ok] / top, zb[ok] / top))
    lnR_nom = np.log(t[:-1] / t[1:])
    span = lnR_nom.sum()
    for c in range(C):
        if sum(p[2].size for p in pairs if p[0] == c) < 4:
            raise ValueError(f"images: channel {c} has too few pixels unclipped in two adjacent exposures; "
                             "use exposures closer together or that cover the scene")

    # per channel: stacked pair rows (Ma, Mb, pair index k)
    rows = []
    for c in range(C):
        sel = [p for p in pairs if p[0] == c]
        rows.append((np.concatenate([p[2] for p in sel]), np.concatenate([p[3] for p in sel]),
                     np.concatenate([np.full(p[2].size, p[1]) for p in sel])))

    def subset(part):
        """Rows of every channel: all (part None), even (0) or odd (1) positions."""
        if part is None:
            return rows
        return [(ma[part::2], mb[part::2], kk[part::2]) for ma, mb, kk in rows]

    def run(deg, data):
        lnR = lnR_nom.copy()
        coefs = [None] * C
        for _ in range(max_iter):
            # plain (absolute-error) least squares, as in the paper: rescaling rows by 1/f^{-1}
            # (relative error) rewards a curve that is small wherever there are data and rises
            # only near M = 1, the degenerate solution of the ratio equations
            coefs = [_mn_fit(ma, mb, np.exp(lnR[kk]), deg) for ma, mb, kk in data]
            if not estimate_ratios:
                break
            num = np.zeros(K - 1)
            den = np.zeros(K - 1)
            for (ma, mb, kk), cf in zip(data, coefs, strict=True):
                pa = np.polynomial.polynomial.polyval(ma, cf)
                pb = np.polynomial.polynomial.polyval(mb, cf)
                num += np.bincount(kk, weights=pa * pb, minlength=K - 1)
                den += np.bincount(kk, weights=pb * pb, minlength=K - 1)
            new = lnR.copy()
            good = (num > 0) & (den > 0)
            new[good] = np.log(num[good] / den[good])
            if np.all(new < 0):
                new *= span / new.sum()
            change = np.max(np.abs(new - lnR))
            lnR = new
            if change < tol:
                break
        return coefs, lnR

    def error(coefs, lnR, data):
        err = 0.0
        for (ma, mb, kk), cf in zip(data, coefs, strict=True):
            pa = np.polynomial.polynomial.polyval(ma, cf)
            pb = np.polynomial.polynomial.polyval(mb, cf)
            err += float(np.sum((pa - np.exp(lnR[kk]) * pb) ** 2))
        return err

    if degree is None:
        best = None
        train, test = subset(0), subset(1)
        for deg in range(2, 9):
            cf, lr = run(deg, train)
            e = error(cf, lr, test)
            if best is None or e < best[0] * (1 - 1e-3):
                best = (e, deg)
        degree = best[1]
    coefs, lnR = run(degree, subset(None))
    M = np.arange(levels) / top
    logx = np.full((levels, C), np.nan)
    for c in range(C):
        p = np.polynomial.polynomial.polyval(M, coefs[c])
        p = np.maximum.accumulate(p)
        good = p > 1e-6 * p[-1]
        logx[good, c] = np.log(p[good])
    inverse = finalise(logx, None)
    lnt = np.concatenate([[0.0], np.cumsum(-lnR)])
    lnt += np.log(t).mean() - lnt.mean()
    return CameraResponse(inverse, levels, "mitsunaga1999", exposure_times=np.exp(lnt),
                          coefficients=np.stack(coefs, axis=1))

