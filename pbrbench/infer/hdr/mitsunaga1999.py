"""Radiometric self-calibration by Mitsunaga & Nayar (1999): polynomial ``f^{-1}`` and
re-estimated exposure ratios.

Reference: T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int, check_number, check_tolerance
from pbrbench.infer.hdr._common import (
    finalise,
    prepare_bracket,
    sample_pixels,
)
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["calibrate_mitsunaga1999"]

VERSION = "6"  # a ratio is re-estimated only from a pair of >= RATIO_ROWS_PER_COEFFICIENT (N + 1) rows per channel
RATIO_ROWS_PER_COEFFICIENT = 4   # fewer: on hdr_scene's 64 x 64 3-exposure bracket (4-5 rows) ln R moved 0.4, 0.14 -> 0.24 stops


_GRID = 65  # points on which the monotonicity of the fitted polynomial is enforced


def _moments(ma, mb, kk, n_pairs: int, nmax: int, powers=None):
    """Per pair ``k``: the monomial moment matrices ``sum Ma^i Ma^j``, ``sum Ma^i Mb^j`` and
    ``sum Mb^i Mb^j`` (i, j <= nmax) of its rows, shape (n_pairs, 3, nmax + 1, nmax + 1).

    ``powers``: optional ``(Va, Vb)``, the rows' monomials ``M^n`` (n <= nmax) when the caller
    has them already.  Rows sorted by ``kk`` are summed as contiguous blocks."""
    out = np.zeros((n_pairs, 3, nmax + 1, nmax + 1))
    if powers is None:
        Va = ma[:, None] ** np.arange(nmax + 1)
        Vb = mb[:, None] ** np.arange(nmax + 1)
    else:
        Va, Vb = powers
    bounds = np.searchsorted(kk, np.arange(n_pairs + 1)) if np.all(np.diff(kk) >= 0) else None
    for k in range(n_pairs):
        s = slice(bounds[k], bounds[k + 1]) if bounds is not None else (kk == k)
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
            u = _convex_qp(Gs, hs, Ds, d0)
    return T @ (u / sc) + e


def _convex_qp(G, h, A, b):
    r"""The exact minimiser of ``v' G v - 2 h' v`` subject to ``A v + b >= 0`` (``G`` symmetric
    positive semi-definite; directions with eigenvalues below ``1e-14`` of the largest are left
    out, as the unconstrained ``lstsq`` leaves them), as a least-distance programme solved by
    non-negative least squares (Lawson & Hanson 1974, *Solving Least Squares Problems*, ch. 23).

    With ``G = V W V'`` and ``x = W^{1/2} V' (v - v_0)``, ``v_0 = G^+ h`` the unconstrained
    minimiser, the objective is ``|x|^2`` plus a constant and the constraints are ``E x >= f``,
    ``E = A V W^{-1/2}``, ``f = -b - A v_0``.  With ``u >= 0`` minimising
    ``|[E'; f'] u - e_{n+1}|`` and ``r`` its residual, ``x = -r_{1..n} / r_{n+1}``.

    Replaces SLSQP (5-15 ms and 50-150 iterations a fit, stopping above the optimum: its
    objective was higher than this one's on every fit of ``pbrbench perf hdr``; this takes
    about 0.1 ms).  An infeasible set (``r = 0``; the constraints here are never infeasible:
    ``p(M) = M^N`` satisfies them) returns the unconstrained minimiser."""
    from scipy.optimize import nnls

    w, V = np.linalg.eigh(G)
    keep = w > 1e-14 * max(float(w[-1]), 1e-300)
    s, Vk = np.sqrt(w[keep]), V[:, keep]
    v0 = Vk @ ((Vk.T @ h) / w[keep])
    f = -b - A @ v0
    if not np.any(f > 1e-12):
        return v0
    M = np.vstack([(A @ Vk / s).T, f[None, :]])
    d = np.zeros(M.shape[0])
    d[-1] = 1.0
    u, _ = nnls(M, d, maxiter=50 * M.shape[1])
    r = M @ u - d
    if abs(r[-1]) <= 1e-300:
        return v0
    return v0 + Vk @ ((-r[:-1] / r[-1]) / s)


def _mn_fit_free(mom, R, degree, black: bool):
    """The unconstrained :func:`_mn_fit` of every channel at once, ``mom`` (C, pairs, 3, n, n)
    the channels' moments; (C, degree + 1) coefficients.  Sums over pairs vectorised and a
    batched solve (singular values below 1e-14 of the largest dropped, as ``lstsq``): rounded
    differently, for screening only."""
    N = degree
    M = mom[..., : N + 1, : N + 1]
    M1 = M[:, :, 1]
    Q = M[:, :, 0].sum(axis=1) - np.einsum("k,ckij->cij", R, M1 + M1.transpose(0, 1, 3, 2)) \
        + np.einsum("k,ckij->cij", R * R, M[:, :, 2])
    n = np.arange(1 if black else 0, N)  # free coefficients; c_N = 1 - sum(free)
    c = np.zeros((Q.shape[0], N + 1))
    c[:, N] = 1.0
    if n.size:
        qnN, qNN = Q[:, n, N], Q[:, N, N][:, None]
        G = Q[:, n[:, None], n[None, :]] - qnN[:, :, None] - Q[:, N, n][:, None, :] + qNN[:, :, None]
        sc = np.sqrt(np.maximum(np.diagonal(G, axis1=1, axis2=2), 1e-300))
        U, sv, Vt = np.linalg.svd(G / (sc[:, :, None] * sc[:, None, :]))
        keep = sv > 1e-14 * sv[:, :1]
        w = np.where(keep, np.einsum("cji,cj->ci", U, (qNN - qnN) / sc) / np.where(keep, sv, 1.0), 0.0)
        u = np.einsum("cji,cj->ci", Vt, w) / sc
        c[:, n] = u
        c[:, N] -= u.sum(axis=1)
    return c


def calibrate_mitsunaga1999(images, exposure_times, *, degree: int | None = None, max_degree: int = 10,
                            max_iter: int = 20, tol: float = 1e-6, estimate_ratios: bool | str = "auto",
                            ratio_gain: float = 0.5, samples: int = 20000, seed: int = 0,
                            bit_depth: int | None = None) -> CameraResponse:
    r"""Polynomial inverse response and exposure ratios by Mitsunaga & Nayar (1999).

    With ``M = z / (levels - 1)`` and ``f^{-1}(M) = \sum_{n=0}^{N} c_n M^n``, ``f^{-1}(1) = 1``,
    minimise over pairs of adjacent exposures ``k, k+1`` (Mitsunaga & Nayar, eq. 7)

    .. math::

        \varepsilon = \sum_{i,k} \left[ f^{-1}(M_{i,k}) - R_k\, f^{-1}(M_{i,k+1}) \right]^2,
        \qquad R_k = \Delta t_k / \Delta t_{k+1},

    alternating the linear solve for ``c`` with the ratio update that minimises the same
    ``\varepsilon`` for fixed ``c``, ``R_k = \sum_i f^{-1}(M_{i,k}) f^{-1}(M_{i,k+1}) / \sum_i
    f^{-1}(M_{i,k+1})^2`` (their eq. 9 averages the per-pixel ratios instead, which the dark
    pixels, where ``f^{-1}`` is least determined, dominate: on a 14-exposure bracket of a 32x32
    render it let the ratios drift from 2 to between 1.6 and 2.1 and cost 25x in log2 RMSE).  Response and
    ratios are ambiguous up to ``f^{-1} -> (f^{-1})^\gamma, R -> R^\gamma`` (Grossberg & Nayar);
    the stated span ``\sum_k \ln R_k = \ln(\Delta t_0 / \Delta t_{K-1})`` is kept fixed, which
    removes that ambiguity while the individual ratios are re-estimated.  Ratios are shared by
    all channels.

    Ratios kept or re-estimated: the ratio freedom also absorbs the polynomial's misfit, so
    re-estimated ratios always lower ``\varepsilon`` a little and then drift: on the HDR task's
    15-exposure draft brackets with exact times they lowered it by 5-15 % and moved single ratios
    by up to 0.6 in ``ln R`` (log2 RMSE 0.013-0.111 stops against 0.004 with the stated ratios,
    the floor 0.0024).  Under stated times with a 7 % error (``rough_times0.07``) they lowered it
    10-100 fold.  So by default the stated ratios are kept unless re-estimating halves
    ``\varepsilon`` (``ratio_gain = 0.5``) without raising the relative pair error below (a
    timing error shows in bright and dark pairs alike; on a 3-exposure bracket 3 stops apart a
    re-estimated ratio 7x off fitted the few overlapping rows 6x better in ``\varepsilon`` and
    17x worse in relative terms).  Only pairs of ``4 (N + 1)`` rows per channel or more re-estimate
    theirs (a polynomial fits fewer at any ratio; with the span fixed, one such pair alone none).

    Order: the paper's rule, the order ``N`` in ``1 .. max_degree`` with the smallest
    ``\varepsilon`` among the monotonic solutions.  Here every fit is constrained to be
    monotonic (a quadratic programme when the least-squares solution is not), so every order
    competes (an order whose unconstrained least squares already has a larger ``\varepsilon``
    than a monotonic solution of another order cannot win; it is recognised by a cheap screen
    and not solved further, which leaves the result that of solving every order).  The dark
    end, where the absolute error ``\varepsilon`` has no leverage, is constrained in one of two
    ways, and the one whose pair equations hold better in relative terms, ``\sum
    [(f^{-1}(M_{ik}) - R_k f^{-1}(M_{i,k+1})) / (f^{-1}(M_{ik}) + R_k f^{-1}(M_{i,k+1}))]^2``,
    is kept: black at zero (``c_0 = 0``, increasing on ``[0, 1]``:
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
    estimate_ratios : bool or "auto"
        True: re-estimate the exposure ratios (the paper); False: trust the stated times;
        ``"auto"`` (default): fit both ways and keep the re-estimated ratios only where their pair
        error ``\varepsilon`` is below ``ratio_gain`` times the stated times' and their relative
        pair error is not above it (see below).
    ratio_gain : float
        In ``(0, 1]``; the factor by which re-estimated ratios must lower ``\varepsilon`` to be
        kept under ``"auto"``.
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
    Z, levels, t = prepare_bracket(images, exposure_times, bit_depth)
    degree = None if degree is None else check_int(degree, "degree", 1, 20)
    max_degree = check_int(max_degree, "max_degree", 1, 20)
    max_iter = check_int(max_iter, "max_iter", 1)
    tol = check_tolerance(tol)
    n_samp = check_int(samples, "samples", 1)
    if not (estimate_ratios is True or estimate_ratios is False or estimate_ratios == "auto"):
        raise ValueError(f"estimate_ratios: expected True, False or 'auto', got {estimate_ratios!r}")
    ratio_gain = check_number(ratio_gain, "ratio_gain", lo=0.0, hi=1.0, lo_open=True)
    (K, H, W, C), top = Z.shape, levels - 1
    m_first = 1.0 / top
    idx_c = sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    lnR_nom = np.log(t[:-1] / t[1:])
    span = lnR_nom.sum()
    # per channel: stacked pair rows (Ma, Mb, pair index k), rows of pair k contiguous; a row's
    # levels as indices into the channel's distinct levels, so that a polynomial is evaluated
    # once per level (not per row) and looked up
    rows = []  # per channel (distinct levels / top, ia, ib, kk): the row order of the sums
    sums = []  # per channel (distinct levels / top, [ia | ib], [kk | kk + K - 1]), interleaved
    distinct = []  # per channel (distinct levels / top, ia, ib, kk, multiplicity), distinct rows
    for c in range(C):
        z = flat[:, idx_c[c], c]
        ia, ib, kk = [], [], []
        for k in range(K - 1):
            za, zb = z[k], z[k + 1]
            ok = (za > 0) & (za < top) & (zb > 0) & (zb < top)
            ia.append(za[ok])
            ib.append(zb[ok])
            kk.append(np.full(int(ok.sum()), k))
        ia, ib, kk = np.concatenate(ia), np.concatenate(ib), np.concatenate(kk)
        if ia.size < 4:
            raise ValueError(f"images: channel {c} has too few pixels unclipped in two adjacent exposures; "
                             "use exposures closer together or that cover the scene")
        # the distinct levels (np.unique by counting) and each row's index into them
        present = np.zeros(levels, bool)
        present[ia] = present[ib] = True
        lv = np.flatnonzero(present)
        pos = np.cumsum(present) - 1
        ia, ib = np.take(pos, ia), np.take(pos, ib)
        ml = lv.astype(np.float64) / top
        rows.append((ml, ia, ib, kk))
        # the ratio update's per-pair sums run over the rows of a pair in their order, one pair
        # after the other; interleaving the pairs keeps each pair's order (the same sums) and
        # lets the additions of different pairs overlap
        cnt = np.bincount(kk, minlength=K - 1)
        rank = np.arange(kk.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        order = np.argsort(rank.astype(np.uint16) if kk.size < 1 << 16 else rank, kind="stable")
        sums.append((ml, np.concatenate([ia[order], ib[order]]), np.concatenate([kk[order], kk[order] + K - 1])))
        # the distinct rows and their multiplicities (for the screen of :func:`run`)
        nl = lv.size
        code = (kk * nl + ia) * nl + ib
        if (K - 1) * nl * nl <= 1 << 22:
            mult = np.bincount(code, minlength=(K - 1) * nl * nl)
            code = np.flatnonzero(mult)
            mult = mult[code]
        else:
            code, mult = np.unique(code, return_counts=True)
        distinct.append((ml, code // nl % nl, code % nl, code // (nl * nl), mult.astype(np.float64)))

    support = np.min([np.bincount(r[3], minlength=K - 1) for r in rows], axis=0)   # rows per pair, fewest channel

    def residuals(coefs, lnR):
        """Per channel ``p(Ma)``, ``R_k p(Mb)`` and ``k`` of every row."""
        for (ml, ia, ib, kk), cf in zip(rows, coefs, strict=True):
            pl = np.polynomial.polynomial.polyval(ml, cf)
            yield np.take(pl, ia), np.take(np.exp(lnR), kk) * np.take(pl, ib), kk

    nmax = degree if degree is not None else max_degree
    moms = []
    for ml, ia, ib, kk in rows:
        vl = ml[:, None] ** np.arange(nmax + 1)
        moms.append(_moments(None, None, kk, K - 1, nmax, powers=(np.take(vl, ia, axis=0), np.take(vl, ib, axis=0))))

    mom_all = np.stack(moms)

    def pair_error_distinct(coefs, lnR):
        """The pair error over the distinct rows (rounded differently: for screening only)."""
        eps = 0.0
        for (ml, ia, ib, kk, mult), cf in zip(distinct, coefs, strict=True):
            pl = np.polynomial.polynomial.polyval(ml, cf)
            eps += float(mult @ (np.take(pl, ia) - np.take(np.exp(lnR), kk) * np.take(pl, ib)) ** 2)
        return eps

    def ratio_sums(coefs):
        """``sum_i p(Ma) p(Mb)`` and ``sum_i p(Mb)^2`` per pair over the rows, in row order."""
        num = np.zeros(K - 1)
        den = np.zeros(K - 1)
        for (ml, iab, kk2), cf in zip(sums, coefs, strict=True):
            p = np.take(np.polynomial.polynomial.polyval(ml, cf), iab)
            nr = p.size // 2
            w = np.empty_like(p)
            np.multiply(p[:nr], p[nr:], out=w[:nr])  # p(Ma) p(Mb)
            np.multiply(p[nr:], p[nr:], out=w[nr:])  # p(Mb)^2
            both = np.bincount(kk2, weights=w, minlength=2 * (K - 1))
            num += both[:K - 1]
            den += both[K - 1:]
        return num, den

    def ratio_sums_moments(coefs):
        """:func:`ratio_sums` from the moments, ``c^T (sum Va Vb^T) c`` and ``c^T (sum Vb Vb^T) c``
        (cheap, but rounded differently: for screening only)."""
        M = mom_all[:, :, 1:, : coefs.shape[1], : coefs.shape[1]]
        both = np.einsum("ci,ckmij,cj->mk", coefs, M, coefs)
        return both[0], both[1]

    def alternate(deg, black, sums_of, start=None, estimate=True):
        """The ratios after alternating the least-squares fit and the ratio update (from the
        stated ratios, or from ``start``); the stated ones without ``estimate``."""
        lnR = (lnR_nom if start is None else start).copy()
        free = support >= RATIO_ROWS_PER_COEFFICIENT * (deg + 1)
        for _ in range(max_iter if estimate and int(free.sum()) >= 2 else 0):
            # plain (absolute-error) least squares, as in the paper; the ratios converge on the
            # unconstrained fits, the final fit is constrained to be monotonic
            if sums_of is ratio_sums:
                coefs = [_mn_fit(m, np.exp(lnR), deg, black, m_first, False) for m in moms]
            else:
                coefs = _mn_fit_free(mom_all, np.exp(lnR), deg, black)
            num, den = sums_of(coefs)
            good = (num > 0) & (den > 0) & free
            new = np.where(good, np.log(np.where(good, num, 1.0) / np.where(good, den, 1.0)), lnR)
            new[free] += (span - new.sum()) / int(free.sum())
            change = np.max(np.abs(new - lnR))
            lnR = new
            if change < tol:
                break
        return lnR

    def run(deg, black, bound=None, start=None, estimate=True):
        """Alternate fits and ratio updates, then the monotone fit; ``(coefs, lnR, eps, rel)``.

        With ``bound``, first a screen: the same alternation with the sums from the moments
        and the distinct rows (from the ratios ``start``: the same fixed point), and None when
        the unconstrained fit at its ratios has a pair error above ``bound`` by more than the
        different rounding and stopping point can explain (the monotone fit, a constrained
        version of the same least squares, cannot have less)."""
        if bound is not None:
            lnR = alternate(deg, black, ratio_sums_moments, start, estimate)
            free = _mn_fit_free(mom_all, np.exp(lnR), deg, black)
            if pair_error_distinct(free, lnR) > bound * (1 + 1e-4):
                return None
        lnR = alternate(deg, black, ratio_sums, None, estimate)
        coefs = [_mn_fit(m, np.exp(lnR), deg, black, m_first, True) for m in moms]
        eps = rel = 0.0
        for pa, rpb, _ in residuals(coefs, lnR):
            eps += float(np.sum((pa - rpb) ** 2))
            with np.errstate(divide="ignore", invalid="ignore"):
                rel += float(np.nansum(((pa - rpb) / (np.abs(pa) + np.abs(rpb))) ** 2))
        return coefs, lnR, eps, rel

    # per dark-end mode the order with the smallest pair error (the lowest among equals), then
    # the mode with the smallest relative error.  The orders are run from the highest down, and
    # an order whose screen (:func:`run`) shows it cannot beat a monotone fit already run is
    # skipped; the ascending scan below over the orders run then picks what a scan over all
    # would (a skipped order has a finite error above the smallest)
    orders = [degree] if degree is not None else list(range(1, max_degree + 1))

    def search(estimate):
        """The order and dark-end mode of the rule above: ``(coefs, lnR, eps, rel)``."""
        best = None
        for black in (True, False):
            results = {}
            least = None
            for deg in reversed(orders):
                out = run(deg, black, least, results[min(results)][1] if results else None, estimate)
                if out is not None:
                    results[deg] = out
                    if np.isfinite(out[2]) and (least is None or out[2] < least):
                        least = out[2]
            mode = None
            for deg in orders:
                if deg in results and (mode is None or results[deg][2] < mode[2]):
                    mode = results[deg]
            if best is None or mode[3] < best[3]:
                best = mode
        return best

    best = search(estimate_ratios is True)
    if estimate_ratios == "auto" and K >= 3:    # with 2 exposures there is no ratio to re-estimate
        free = search(True)
        if free[2] < ratio_gain * best[2] and free[3] <= best[3]:
            best = free
    coefs, lnR = best[0], best[1]
    M = np.arange(levels) / top
    logx = np.full((levels, C), np.nan)
    for c in range(C):
        p = np.maximum.accumulate(np.polynomial.polynomial.polyval(M, coefs[c]))
        good = p > 1e-9 * p[-1]
        logx[good, c] = np.log(p[good])
    inverse = finalise(logx, None)
    lnt = np.concatenate([[0.0], np.cumsum(-lnR)])
    lnt += np.log(t).mean() - lnt.mean()
    return CameraResponse(inverse, levels, "mitsunaga1999", exposure_times=np.exp(lnt),
                          coefficients=np.stack(coefs, axis=1))
