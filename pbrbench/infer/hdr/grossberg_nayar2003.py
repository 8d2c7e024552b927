r"""Radiometric calibration without registration: Grossberg & Nayar (2003).

Two exposures of the same scene, ``t_k < t_l``, have (nearly) the same histogram of
irradiance ``E`` even when they are not registered (shifted, jittered, a moving camera), so
the pixel levels ``Z_k = f(E t_k)`` and ``Z_l = f(E t_l)`` are related through their
*cumulative histograms* ``H_k``, ``H_l`` alone: the brightness transfer function

.. math::
    T_{kl}(z) = H_l^{-1}\big(H_k(z)\big), \qquad
    f^{-1}\big(T_{kl}(z)\big) = \frac{t_l}{t_k}\, f^{-1}(z),

found by histogram specification, needs no pixel correspondence.  With the exposure ratios
known, the transfer functions determine ``f^{-1}`` (Grossberg & Nayar 2003, Theorem 2: only the
ratios' exponential ambiguity ``f^{-1} -> (f^{-1})^\gamma`` remains when they are unknown).

References
----------
M. D. Grossberg and S. K. Nayar, "Determining the camera response from images: what is
knowable?", IEEE Transactions on Pattern Analysis and Machine Intelligence 25(11):1455-1467,
2003.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pbrbench.checks import check_number
from pbrbench.infer.hdr._common import (
    as_stack,
    check_informative,
    check_times,
    finalise,
    level_weights,
)
from pbrbench.infer.hdr.debevec1997 import _smoothness_operator
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["calibrate_grossberg_nayar2003", "brightness_transfer"]

_MAX_KNOTS = 1024


def brightness_transfer(za: np.ndarray, zb: np.ndarray, levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The brightness transfer function from exposure ``za`` to exposure ``zb`` by histogram
    specification: ``T(z) = H_b^{-1}(H_a(z))``.

    Each level ``z`` present in ``za`` is represented by the mid-rank of its pixels,
    ``u = (H_a(z - 1) + H_a(z)) / 2``, mapped through the continuous inverse of ``H_b``
    (linear interpolation between the mid-ranks of ``zb``'s unclipped levels ``1 .. levels-2``).
    Only ``z`` in ``1 .. levels-2`` whose rank falls inside ``zb``'s unclipped mid-ranks are
    returned.  The images need not be registered, nor even of the same size.

    Parameters
    ----------
    za, zb : arrays of unsigned integer levels (any shape)
    levels : int

    Returns
    -------
    z : (n,) int
        Source levels.
    T : (n,) float
        Their (fractional) levels in ``zb``.
    frac : (n,) float
        Fraction of ``za``'s pixels at each source level (the weight of that sample).
    """
    top = levels - 1
    ca = np.bincount(np.ravel(za), minlength=levels)[:levels].astype(np.float64)
    cb = np.bincount(np.ravel(zb), minlength=levels)[:levels].astype(np.float64)
    na, nb = ca.sum(), cb.sum()
    Ha, Hb = np.cumsum(ca) / na, np.cumsum(cb) / nb
    mid_a = Ha - 0.5 * ca / na
    mid_b = Hb - 0.5 * cb / nb
    lv = np.arange(levels)
    okb = (cb > 0) & (lv > 0) & (lv < top)
    if okb.sum() < 2:
        return np.zeros(0, int), np.zeros(0), np.zeros(0)
    mb, yb = mid_b[okb], lv[okb].astype(np.float64)
    oka = (ca > 0) & (lv > 0) & (lv < top) & (mid_a >= mb[0]) & (mid_a <= mb[-1])
    z = lv[oka]
    T = np.interp(mid_a[oka], mb, yb)
    return z, T, ca[oka] / na


def calibrate_grossberg_nayar2003(images, exposure_times, *, smoothness: float = 1e-6,
                                  bit_depth: int | None = None) -> CameraResponse:
    r"""Inverse response from the exposures' histograms only (Grossberg & Nayar 2003).

    For every pair of exposures ``k < l`` (both directions) and channel the brightness transfer
    function ``T_{kl}`` is found by histogram specification (:func:`brightness_transfer`); no
    pixel of one exposure is compared with "the same" pixel of another, so the bracket need not be
    registered, only show the same scene (equal irradiance histograms).  Then ``g = ln f^{-1}``,
    tabulated on the levels (piecewise linear between them, on at most 1024 knots), solves the
    weighted least squares

    .. math::
        \sum_{k \ne l} \sum_z w_{kl}(z) \Big[ g\big(T_{kl}(z)\big) - g(z)
        - \ln\frac{t_l}{t_k} \Big]^2 + \lambda' \sum_z \big[w(z)\, g''(z)\big]^2,

    ``w_{kl}(z)`` the fraction of pixels at ``z`` times the hat weights of ``z`` and
    ``T_{kl}(z)``; the curvature penalty is that of
    :func:`~pbrbench.infer.hdr.debevec1997.calibrate_debevec1997` (in ``u = ln(z + 1/2)``, so a
    power law is not biased), which fixes the ripple equal ratios leave (Grossberg & Nayar's
    fractal ambiguity).  The response model is free (a smoothed table, no polynomial or EMoR
    basis); it is made monotone and gauged ``inverse[levels - 1] == 1`` like every calibration
    of :mod:`pbrbench.infer.hdr`.

    Parameters
    ----------
    images : array (K, H, W[, C]) or sequence, unsigned integers
        The bracket, sorted by exposure time; the exposures may be shifted against each other.
    exposure_times : sequence of K floats, strictly increasing, seconds
        Their ratios are trusted (the method cannot re-estimate them: with unknown ratios the
        response is only knowable up to ``f^{-1} -> (f^{-1})^\gamma``).
    smoothness : float
        ``lambda`` (>= 0, at most 1e6); scaled by the total data weight and ``max(1, log2 r)^2``
        for the widest ratio ``r``, as in ``debevec1997``.
    bit_depth : int or None
        Number of bits; inferred from the dtype / largest level when None.

    Returns
    -------
    CameraResponse
        With ``method == "grossberg_nayar2003"``.

    Raises
    ------
    ValueError
        On a bad bracket (fewer than 2 exposures, non-integer levels, times not strictly
        increasing, e.g. equal times) or one that says nothing about the response (constant or
        clipped exposures: no transfer function has two unclipped levels).

    References
    ----------
    M. D. Grossberg and S. K. Nayar, "Determining the camera response from images: what is
    knowable?", IEEE Transactions on Pattern Analysis and Machine Intelligence 25(11):1455-1467,
    2003.
    """
    Z, levels = as_stack(images, bit_depth)
    t = check_times(exposure_times, Z.shape[0])
    check_informative(Z, levels)
    lam = check_number(smoothness, "smoothness", lo=0.0, hi=1e6)
    K, H, W, C = Z.shape
    top = levels - 1
    lnt = np.log(t) - np.log(t).mean()
    wl = level_weights("hat", levels)
    lv = np.arange(levels, dtype=np.float64)
    n_knots = min(levels, _MAX_KNOTS)
    scale = (n_knots - 1) / (levels - 1)
    knot_pos = np.arange(n_knots) / scale
    DtWD = _smoothness_operator(knot_pos, np.interp(knot_pos, lv, wl))
    stretch = max(1.0, float(np.max(np.diff(np.log2(t))))) ** 2
    mid_knot = n_knots // 2
    logx = np.full((levels, C), np.nan)
    counts = np.zeros((levels, C))
    for c in range(C):
        src, dst, rhs_r, wts = [], [], [], []
        for k in range(K):
            for m in range(K):
                if m == k:
                    continue
                z, T, frac = brightness_transfer(Z[k, ..., c], Z[m, ..., c], levels)
                if z.size == 0:
                    continue
                w = frac * wl[z] * np.interp(T, lv, wl)
                keep = w > 0
                src.append(z[keep].astype(np.float64))
                dst.append(T[keep])
                rhs_r.append(np.full(int(keep.sum()), lnt[m] - lnt[k]))
                wts.append(w[keep])
        if not src or sum(s.size for s in src) < 2:
            raise ValueError(f"images: channel {c} has no brightness transfer between two exposures (the "
                             "exposures' unclipped ranges do not overlap); use exposures closer together")
        zs, Ts, b, w = (np.concatenate(a) for a in (src, dst, rhs_r, wts))
        n = zs.size

        def basis(x):
            u = x * scale
            j0 = np.minimum(np.floor(u).astype(np.int64), n_knots - 2)
            al = u - j0
            return j0, al

        j0, a0 = basis(zs)
        j1, a1 = basis(Ts)
        rows = np.repeat(np.arange(n), 4)
        cols = np.stack([j1, j1 + 1, j0, j0 + 1], axis=1).ravel()
        vals = np.stack([1 - a1, a1, -(1 - a0), -a0], axis=1).ravel()
        A = sp.csr_matrix((vals, (rows, cols)), shape=(n, n_knots))
        Aw = sp.diags(w) @ A
        M = (A.T @ Aw).toarray()
        rhs = Aw.T @ b
        wsum = float(w.sum())
        M += lam * stretch * wsum * DtWD
        M[mid_knot, mid_knot] += wsum / n_knots   # the free offset (the gauge is set by finalise)
        g = np.linalg.solve(M, rhs)
        logx[:, c] = np.interp(lv, knot_pos, g)
        # the levels the transfer functions reach: outside them g is extrapolated by finalise
        cover = np.zeros(levels)
        np.add.at(cover, zs.astype(np.int64), w)
        np.add.at(cover, np.clip(np.rint(Ts).astype(np.int64), 0, top), w)
        seen = np.flatnonzero(cover > 0)
        lo, hi = seen.min(), seen.max()
        logx[:lo, c] = np.nan
        logx[hi + 1:, c] = np.nan
        counts[:, c] = cover / max(cover.max(), 1e-300) * n + 1.0
    logx[-1] = np.nan   # the clipped top level carries no data
    inverse = finalise(logx, counts)
    return CameraResponse(inverse, levels, "grossberg_nayar2003")
