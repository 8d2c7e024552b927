"""Radiometric calibration by Debevec & Malik (1997): least squares for ``g = ln f^{-1}``.

Reference: P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from
Photographs", SIGGRAPH 1997.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pbrbench.checks import check_int, check_method, check_number
from pbrbench.infer._docstring import docstring
from pbrbench.infer.hdr._common import (
    CALIBRATION_WEIGHTINGS,
    DOCS,
    finalise,
    level_weights,
    prepare_bracket,
    sample_pixels,
)
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["calibrate_debevec1997"]

_MAX_KNOTS = 1024
CURVATURES = ("auto", "log", "level")
LEVEL_CURVATURE_STOPS = 2.5   # "auto": curvature per pixel level when exposures are this many stops apart or more
SMOOTHNESS = {"log": 1e-7, "level": 3e-8}   # the default smoothness of each curvature


def _smoothness_operator(pos: np.ndarray, w: np.ndarray, curvature: str = "log") -> np.ndarray:
    """Mean weighted squared curvature ``sum_j w_j^2 h_j g''(u_j)^2 / sum_j w_j^2 h_j`` as a matrix.

    ``curvature="log"``: ``u = ln(z + 1/2)`` is log pixel level, ``pos`` the knot levels, ``h_j``
    the local spacing in ``u``.  Curvature is measured per unit ``u`` and averaged over ``u``, so
    the penalty does not depend on the number of levels or knots (bit depth): the same
    ``smoothness`` smooths over the same fraction of the log-level range at 8 and at 16 bits.  A
    power-law response (``g = gamma ln z``) has zero curvature in ``u`` and is not biased by the
    penalty.  ``curvature="level"``: ``u = z / (levels - 1)``, the pixel level itself (Debevec &
    Malik's ``g''(z)``), on the same unit range whatever the bit depth.
    """
    n = pos.size
    u = np.log(pos + 0.5) if curvature == "log" else pos / pos[-1]
    du = np.diff(u)
    h = 0.5 * (du[1:] + du[:-1])
    j = np.arange(n - 2)
    rows = np.repeat(j, 3)
    cols = np.stack([j, j + 1, j + 2], axis=1).ravel()
    vals = np.stack([1 / du[:-1], -(1 / du[:-1] + 1 / du[1:]), 1 / du[1:]], axis=1) / h[:, None]
    D = sp.csr_matrix((vals.ravel(), (rows, cols)), shape=(n - 2, n))
    ww = np.maximum(w, 0.05)[1:-1] ** 2 * h
    return (D.T @ sp.diags(ww / ww.sum()) @ D).toarray()


@docstring(DOCS)
def calibrate_debevec1997(images, exposure_times, *, smoothness: float | None = None, samples: int = 4096,
                          weighting: str = "hat", seed: int = 0, bit_depth: int | None = None,
                          curvature: str = "auto") -> CameraResponse:
    r"""Recover the inverse response with the method of Debevec & Malik (1997).

    Minimises, per channel, over ``g = ln f^{-1}`` (at every level) and ``ln E_i`` (at sampled pixels)

    .. math::

        \sum_{i,k} \left[w(Z_{ik})\,(g(Z_{ik}) - \ln E_i - \ln \Delta t_k)\right]^2
        + \lambda' \sum_z \left[w(z)\, g''(z)\right]^2 .

    The ``ln E_i`` are eliminated in closed form (Schur complement), leaving a
    ``levels x levels`` system; above 1024 levels ``g`` is piecewise linear on 1024 knots.
    The gauge is ``g(levels - 1) = 0`` for every channel (see :mod:`pbrbench.infer.hdr`).

    Parameters
    ----------
    %(bracket)s
    smoothness : float or None
        ``lambda``.  The penalty actually added is ``lambda * A * s^2 * mean_u[w^2 g_uu^2]``:
        ``A`` the total data weight (so ``lambda`` does not depend on the sample count), the
        curvature ``g_uu`` taken in the coordinate ``u`` of ``curvature`` and averaged over ``u``
        (so it does not depend on bit depth), ``s = max(1, log2 r)`` for the widest exposure
        ratio ``r`` (the periodic ambiguity grows with the spacing).  None: ``1e-7`` for the log
        curvature, ``3e-8`` for the level curvature (chosen on 8- to 12-bit brackets 1 to 4 stops
        apart).
    curvature : {"auto", "log", "level"}
        Where the curvature is measured.  ``"log"``: per unit of ``u = ln(z + 1/2)``, which
        leaves a power law (``g = gamma ln z``) unbiased.  ``"level"``: per unit of the pixel
        level ``z`` (the paper's ``g''(z)``).  Equally spaced exposures leave ``g`` undetermined
        up to a ripple periodic in ``ln E`` with period ``ln r``, which only the penalty
        decides; the farther apart the exposures, the more of ``g`` it must decide, and the log
        curvature then prefers a ripple to a film response's shoulder (on a film-like bracket of
        3 exposures 3 stops apart, read and shot noise, 512 x 512: 7.6x the true-response
        floor, against 1.4x with the level curvature).  ``"auto"``: ``"level"`` when the widest
        ratio is :data:`LEVEL_CURVATURE_STOPS` stops or more, else ``"log"`` (docs/peers.md
        lists the brackets it was chosen on).
    samples : int
        Random pixels used; pixels are added so that every level present is sampled.
    weighting : {"hat", "uniform", "gaussian"}
        ``w(z)``; all are zero at the clipped ends.
    seed : int
        Seeds the pixel sampling (the result is deterministic given it).
    bit_depth : int or None
        Number of bits; inferred from the dtype / largest level when None.

    Returns
    -------
    %(calibrated)s

    References
    ----------
    P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from Photographs",
    SIGGRAPH 1997.
    """
    Z, levels, t = prepare_bracket(images, exposure_times, bit_depth)
    check_method(curvature, CURVATURES, "curvature")
    widest = float(np.max(np.diff(np.log2(t)))) if t.size > 1 else 0.0
    if curvature == "auto":
        curvature = "level" if widest >= LEVEL_CURVATURE_STOPS - 1e-9 else "log"
    lam = SMOOTHNESS[curvature] if smoothness is None else check_number(smoothness, "smoothness", lo=0.0, hi=1e6)
    n_samp = check_int(samples, "samples", 1)
    check_method(weighting, CALIBRATION_WEIGHTINGS, "weighting")
    K, H, W, C = Z.shape
    # centred log times: g does not depend on the unit of time, and scaling every time by a
    # constant leaves the linear system (not only its solution) unchanged; rounding to 1e-12
    # (far below any shutter's precision) removes the last-bit differences of the logs, which
    # the ill-conditioned low-level rows (cond ~ 1e10) would amplify to ~1e-5
    lnt = np.round(np.log(t) - np.log(t).mean(), 12)
    wl = level_weights(weighting, levels)
    n_knots = min(levels, _MAX_KNOTS)
    scale = (n_knots - 1) / (levels - 1)
    knot_pos = np.arange(n_knots) / scale
    idx_c = sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    # smoothness operator on the knots (second differences), weighted by w at the knots + floor
    DtWD = _smoothness_operator(knot_pos, np.interp(knot_pos, np.arange(levels), wl), curvature)
    # Equal exposure ratios r leave g undetermined up to a ripple periodic in ln E with period
    # ln r (Grossberg & Nayar 2003); only the smoothness term fixes it, and the wider the
    # spacing the more of g it must decide.  The penalty is scaled by (log2 r)^2 (empirical, with
    # the log curvature: on the benchmark bracket, 3 exposures 3 stops apart, ^4 over-smooths the
    # true curvature and ^0 leaves the ripple; see pbrbench/perf/hdr.py.  With the level
    # curvature, ^2 with smoothness 3e-8 and ^4 with 3e-9 (equal at 3 stops) gave errors within
    # about 10 % of each other on most wide brackets of docs/peers.md, neither lower throughout).
    stretch = max(1.0, widest) ** 2
    logx = np.empty((levels, C))
    counts = np.zeros((levels, C))
    mid_knot = n_knots // 2
    for c in range(C):
        z = flat[:, idx_c[c], c].T.astype(np.int64)  # (n, K)
        n = z.shape[0]
        a = wl[z] ** 2
        A = a.sum(axis=1)
        keep = A > 0
        z, a, A = z[keep], a[keep], A[keep]
        n = z.shape[0]
        if n == 0:
            raise ValueError(f"images: channel {c} has no pixel with a usable (unclipped) level; use other exposures")
        u = z * scale
        j0 = np.minimum(np.floor(u).astype(np.int64), n_knots - 2)
        al = u - j0
        rows = np.repeat(np.arange(n), K)
        # S: (n, n_knots) rows s_i = sum_k a_ik b_ik ; B^T diag(a) B via coo (sums duplicates)
        cols = np.concatenate([j0.ravel(), j0.ravel() + 1])
        vals_s = np.concatenate([(a * (1 - al)).ravel(), (a * al).ravel()])
        S = sp.csr_matrix((vals_s, (np.concatenate([rows, rows]), cols)), shape=(n, n_knots))
        b0, b1 = (1 - al).ravel(), al.ravel()
        av = a.ravel()
        jj = j0.ravel()
        M1 = sp.coo_matrix((np.concatenate([av * b0 * b0, av * b0 * b1, av * b0 * b1, av * b1 * b1]),
                            (np.concatenate([jj, jj, jj + 1, jj + 1]), np.concatenate([jj, jj + 1, jj, jj + 1]))),
                           shape=(n_knots, n_knots)).toarray()
        Sinv = sp.diags(1.0 / A) @ S
        M = M1 - (S.T @ Sinv).toarray()
        alt = (a * lnt).sum(axis=1)  # sum_k a_ik ln t_k
        rhs = np.bincount(cols, weights=np.concatenate([(a * lnt * (1 - al)).ravel(), (a * lnt * al).ravel()]),
                          minlength=n_knots) - S.T @ (alt / A)
        lam_eff = lam * stretch * a.sum()
        M += lam_eff * DtWD
        M[mid_knot, mid_knot] += a.sum() / n_knots
        g = np.linalg.solve(M, rhs)
        logx[:, c] = np.interp(np.arange(levels), knot_pos, g)
        counts[:, c] = np.bincount(z.ravel(), minlength=levels)[:levels]
    logx[-1] = np.nan  # the clipped top level carries no data: extrapolate it like the other methods
    inverse = finalise(logx, counts + 1.0)
    return CameraResponse(inverse, levels, "debevec1997")
