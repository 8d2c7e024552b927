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

VERSION = "2"  # order by the paper's rule, monotone fits, dark end constrained


_GRID = 65  # points on which the monotonicity of the fitted polynomial is enforced


def _moments(ma, mb, kk, n_pairs: int, nmax: int):
    """Per pair ``k``: the monomial moment matrices ``sum Ma^i Ma^j``, ``sum Ma^i Mb^j`` and
    ``sum Mb^i Mb^j`` (i, j <= nmax) of its rows, shape (n_pairs, 3, nmax + 1, nmax + 1)."""
    out = np.zeros((n_pairs, 3, nmax + 1, nmax + 1))
    Va = ma[:, None] ** np.arange(nmax + 1)
    Vb = mb[:, None] ** np.arange(nmax + 1)
    for k in range(n_pairs):
        s = kk == k
        a, b = Va[s], Vb[s]
        out[k] = a.T @ a, a.T @ b, b.T @ b
    return out


def _mn_fit(mom, R, degree, black: bool, m_first: float, monotone: bool):
    """Least squares for the coefficients of ``p(M) = sum_n c_n M^n`` with ``p(1) = 1`` on the
    pair equations ``p(Ma) = R_k p(Mb)``, from the moments ``mom`` (:func:`_moments`);
    ``black``: ``c_0 = 0``.  With ``monotone``, ``p`` is constrained increasing on ``[m0, 1]``
    (``m0 = 0`` with ``black``, else the first level ``m_first``) and, without ``black``,
    ``p(m_first) >= 0``: a small quadratic programme when the least-squares solution violates
    the constraints."""
    N = degree
    sl = slice(0, N + 1)
    Q = sum(m[0][sl, sl] - r * (m[1][sl, sl] + m[1][sl, sl].T) + r * r * m[2][sl, sl] for m, r in zip(mom, R, strict=True))
    n = np.arange(1 if black else 0, N)  # free coefficients; c_N = 1 - sum(free)
    T = np.zeros((N + 1, n.size))
    T[n, np.arange(n.size)] = 1.0
    T[N] = -1.0
    e = np.zeros(N + 1)
    e[N] = 1.0
    G = T.T @ Q @ T
    h = -T.T @ Q @ e
    sc = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs, hs = G / np.outer(sc, sc), h / sc
    u = np.linalg.lstsq(Gs, hs, rcond=1e-14)[0] if n.size else np.zeros(0)
    if monotone and n.size:
        m0 = 0.0 if black else m_first
        g = np.linspace(m0, 1.0, _GRID)
        # derivative rows: d/dM [M^n - M^N] = n M^(n-1) - N M^(N-1)
        D = n * g[:, None] ** np.maximum(n - 1, 0) * (n > 0) - N * (g ** (N - 1))[:, None]
        d0 = N * g ** (N - 1)
        if not black:
            D = np.vstack([D, m_first**n - m_first**N])
            d0 = np.concatenate([d0, [m_first**N]])
        Ds = D / sc
        if np.any(Ds @ u + d0 < -1e-12):
            from scipy.optimize import minimize

            res = minimize(lambda v: v @ Gs @ v - 2 * hs @ v, u, jac=lambda v: 2 * (Gs @ v - hs),
                           constraints=[{"type": "ineq", "fun": lambda v: Ds @ v + d0, "jac": lambda v: Ds}],
                           method="SLSQP", options={"maxiter": 300, "ftol": 1e-16})
            u = res.x
    return T @ (u / sc) + e


def calibrate_mitsunaga1999(images, exposure_times, *, degree: int | None = None, max_degree: int = 10,
                            max_iter: int = 20, tol: float = 1e-6, estimate_ratios: bool = True,
                            samples: int = 20000, seed: int = 0, bit_depth: int | None = None) -> CameraResponse:
    r"""Polynomial inverse response and exposure ratios by Mitsunaga & Nayar (1999).

    With ``M = z / (levels - 1)`` and ``f^{-1}(M) = \sum_{n=0}^{N} c_n M^n``, ``f^{-1}(1) = 1``,
    minimise over pairs of adjacent exposures ``k, k+1`` (Mitsunaga & Nayar, eq. 7)

    .. math::

        \varepsilon = \sum_{i,k} \left[ f^{-1}(M_{i,k}) - R_k\, f^{-1}(M_{i,k+1}) \right]^2,
        \qquad R_k = \Delta t_k / \Delta t_{k+1},

    alternating the linear solve for ``c`` with the ratio update (their eq. 9, in the log:
    ``\ln R_k`` = the mean of ``\ln(f^{-1}(M_{i,k}) / f^{-1}(M_{i,k+1}))``).  Response and
    ratios are ambiguous up to ``f^{-1} -> (f^{-1})^\gamma, R -> R^\gamma`` (Grossberg & Nayar);
    the stated span ``\sum_k \ln R_k = \ln(\Delta t_0 / \Delta t_{K-1})`` is kept fixed, which
    removes that ambiguity while the individual ratios are re-estimated.  Ratios are shared by
    all channels.

    Order: the paper's rule, the order ``N`` in ``1 .. max_degree`` with the smallest
    ``\varepsilon`` among the monotonic solutions.  Here every fit is constrained to be
    monotonic (a quadratic programme when the least-squares solution is not), so every order
    competes.  The dark end, where the absolute error ``\varepsilon`` has no leverage, is
    constrained in one of two ways, and the one whose pair equations hold better in relative
    terms, ``\sum [(f^{-1}(M_{ik}) - R_k f^{-1}(M_{i,k+1})) / (f^{-1}(M_{ik}) + R_k
    f^{-1}(M_{i,k+1}))]^2``, is kept: black at zero (``c_0 = 0``, increasing on ``[0, 1]``:
    power-law-like responses), or ``c_0`` free with ``f^{-1}`` positive and increasing from the
    first level on (responses with an infinite slope at black, such as film curves, which a
    polynomial through 0 cannot follow).

    Parameters
    ----------
    images, exposure_times
        As for :func:`~pbrbench.infer.hdr.debevec1997.calibrate_debevec1997`; the times are the initial guess.
    degree : int or None
        Polynomial degree ``N`` (>= 1); None chooses it by the rule above.
    max_degree : int
        Largest order tried when ``degree`` is None (the paper tries up to 10).
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
    T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999; M. D. Grossberg and
    S. K. Nayar, "Determining the camera response from images: what is knowable?", IEEE PAMI
    25(11), 2003 (the exponential ambiguity).
    """
    Z, levels = as_stack(images, bit_depth)
    t = check_times(exposure_times, Z.shape[0])
    check_informative(Z, levels)
    if degree is not None:
        degree = check_int(degree, "degree", 1, 20)
    max_degree = check_int(max_degree, "max_degree", 1, 20)
    max_iter = check_int(max_iter, "max_iter", 1)
    tol = check_tolerance(tol)
    n_samp = check_int(samples, "samples", 1)
    K, H, W, C = Z.shape
    top = levels - 1
    m_first = 1.0 / top
    idx_c = sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    lnR_nom = np.log(t[:-1] / t[1:])
    span = lnR_nom.sum()
    # per channel: stacked pair rows (Ma, Mb, pair index k)
    rows = []
    for c in range(C):
        z = flat[:, idx_c[c], c].astype(np.float64)
        ma, mb, kk = [], [], []
        for k in range(K - 1):
            za, zb = z[k], z[k + 1]
            ok = (za > 0) & (za < top) & (zb > 0) & (zb < top)
            ma.append(za[ok] / top)
            mb.append(zb[ok] / top)
            kk.append(np.full(int(ok.sum()), k))
        rows.append((np.concatenate(ma), np.concatenate(mb), np.concatenate(kk)))
        if rows[-1][0].size < 4:
            raise ValueError(f"images: channel {c} has too few pixels unclipped in two adjacent exposures; "
                             "use exposures closer together or that cover the scene")

    def residuals(coefs, lnR):
        for (ma, mb, kk), cf in zip(rows, coefs, strict=True):
            pa = np.polynomial.polynomial.polyval(ma, cf)
            pb = np.polynomial.polynomial.polyval(mb, cf)
            yield pa, np.exp(lnR[kk]) * pb, kk

    nmax = degree if degree is not None else max_degree
    moms = [_moments(ma, mb, kk, K - 1, nmax) for ma, mb, kk in rows]

    def run(deg, black):
        lnR = lnR_nom.copy()
        coefs = [None] * C
        for _ in range(max_iter if estimate_ratios and K >= 3 else 0):
            # plain (absolute-error) least squares, as in the paper; the ratios converge on the
            # unconstrained fits, the final fit below is constrained to be monotonic
            coefs = [_mn_fit(m, np.exp(lnR), deg, black, m_first, False) for m in moms]
            num = np.zeros(K - 1)
            cnt = np.zeros(K - 1)
            for pa, rpb, kk in residuals(coefs, np.zeros(K - 1)):
                ok = (pa > 0) & (rpb > 0)
                num += np.bincount(kk[ok], weights=np.log(pa[ok] / rpb[ok]), minlength=K - 1)
                cnt += np.bincount(kk[ok], minlength=K - 1)
            new = np.where(cnt > 0, num / np.maximum(cnt, 1.0), lnR)
            new += (span - new.sum()) / (K - 1)
            change = np.max(np.abs(new - lnR))
            lnR = new
            if change < tol:
                break
        coefs = [_mn_fit(m, np.exp(lnR), deg, black, m_first, True) for m in moms]
        eps = sum(float(np.sum((pa - rpb) ** 2)) for pa, rpb, _ in residuals(coefs, lnR))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = sum(float(np.nansum(((pa - rpb) / (np.abs(pa) + np.abs(rpb))) ** 2))
                      for pa, rpb, _ in residuals(coefs, lnR))
        return coefs, lnR, eps, rel

    best = None
    for black in (True, False):
        mode = None
        for deg in ([degree] if degree is not None else range(1, max_degree + 1)):
            out = run(deg, black)
            if mode is None or out[2] < mode[2]:
                mode = out
        if best is None or mode[3] < best[3]:
            best = mode
    coefs, lnR = best[0], best[1]
    M = np.arange(levels) / top
    logx = np.full((levels, C), np.nan)
    for c in range(C):
        p = np.polynomial.polynomial.polyval(M, coefs[c])
        p = np.maximum.accumulate(p)
        good = p > 1e-9 * p[-1]
        logx[good, c] = np.log(p[good])
    inverse = finalise(logx, None)
    lnt = np.concatenate([[0.0], np.cumsum(-lnR)])
    lnt += np.log(t).mean() - lnt.mean()
    return CameraResponse(inverse, levels, "mitsunaga1999", exposure_times=np.exp(lnt),
                          coefficients=np.stack(coefs, axis=1))
