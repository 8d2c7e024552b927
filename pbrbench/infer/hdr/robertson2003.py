"""Radiometric calibration by the ML alternation of Robertson, Borman & Stevenson (1999, 2003).

References: M. A. Robertson, S. Borman and R. L. Stevenson, "Dynamic range improvement through
multiple exposures", ICIP 1999; "Estimation-theoretic approach to dynamic range enhancement using
multiple exposures", Journal of Electronic Imaging 12(2), 2003.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int, check_tolerance
from pbrbench.infer._docstring import docstring
from pbrbench.infer.hdr._common import (
    DOCS,
    finalise,
    level_weights,
    prepare_bracket,
    sample_pixels,
)
from pbrbench.infer.hdr.debevec1997 import calibrate_debevec1997
from pbrbench.infer.hdr.response import CameraResponse

__all__ = ["calibrate_robertson2003"]


@docstring(DOCS)
def calibrate_robertson2003(images, exposure_times, *, max_iter: int = 30, tol: float = 1e-4,
                            samples: int = 50000, seed: int = 0, bit_depth: int | None = None) -> CameraResponse:
    r"""Recover the inverse response with the ML alternation of Robertson et al. (1999, 2003).

    With ``x = f^{-1}`` and Gaussian-shaped weights ``w`` (zero at the clipped ends), alternate

    .. math::

        E_i = \frac{\sum_k w(Z_{ik})\, \Delta t_k\, x(Z_{ik})}{\sum_k w(Z_{ik})\, \Delta t_k^2},
        \qquad x(m) = \frac{1}{|\Omega_m|} \sum_{(i,k) \in \Omega_m} E_i\, \Delta t_k ,

    where ``Omega_m`` is the set of observations at level ``m``, until the largest change of
    ``ln x`` is below ``tol``.  The result is made monotone (isotonic regression), extrapolated
    to the clipped ends in the log domain and normalised to ``x(levels - 1) = 1``.  The
    iteration starts from :func:`~pbrbench.infer.hdr.debevec1997.calibrate_debevec1997` (from a
    linear start the fixed point is reached slowly).

    Parameters
    ----------
    images, exposure_times
        As for :func:`~pbrbench.infer.hdr.debevec1997.calibrate_debevec1997`.
    max_iter : int
        Maximum number of alternations.
    tol : float
        Convergence threshold on ``max |Delta ln x|``.
    samples : int
        Random pixels used (plus pixels covering every level), seeded by ``seed``.
    bit_depth : int or None
        Inferred when None.

    Returns
    -------
    %(calibrated)s

    References
    ----------
    M. A. Robertson, S. Borman and R. L. Stevenson, "Dynamic range improvement through multiple
    exposures", ICIP 1999; "Estimation-theoretic approach to dynamic range enhancement using
    multiple exposures", Journal of Electronic Imaging 12(2), 2003.
    """
    Z, levels, t = prepare_bracket(images, exposure_times, bit_depth)
    max_iter = check_int(max_iter, "max_iter", 1)
    tol = check_tolerance(tol)
    n_samp = check_int(samples, "samples", 1)
    K, H, W, C = Z.shape
    wl = level_weights("gaussian", levels)
    idx_c = sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    logx = np.full((levels, C), np.nan)
    counts = np.zeros((levels, C))
    top = levels - 1
    # the fixed-point iteration converges slowly from a linear start: start from Debevec-Malik
    init = calibrate_debevec1997(Z, t, samples=min(n_samp, 4096), seed=seed, bit_depth=int(np.log2(levels))).inverse
    for c in range(C):
        z = flat[:, idx_c[c], c].astype(np.int64)  # (K, n)
        w = wl[z]
        tt = t[:, None]
        valid = (z > 0) & (z < top)
        cnt = np.bincount(z[valid], minlength=levels).astype(float)
        x = init[:, c].copy()
        denom = (w * tt**2).sum(axis=0)
        use = denom > 0
        z, w, valid, denom = z[:, use], w[:, use], valid[:, use], denom[use]
        zv = z[valid]
        tv = np.broadcast_to(tt, z.shape)[valid]
        pop = cnt > 0
        for _ in range(max_iter):
            E = (w * tt * x[z]).sum(axis=0) / denom
            Ev = np.broadcast_to(E, z.shape)[valid]
            new = np.bincount(zv, weights=Ev * tv, minlength=levels)
            new = np.where(pop, new / np.maximum(cnt, 1), x)
            new /= new[levels // 2] if pop[levels // 2] else new[pop].max()
            change = np.max(np.abs(np.log(new[pop]) - np.log(np.maximum(x[pop], 1e-300))))
            x = new
            if change < tol:
                break
        v = np.full(levels, np.nan)
        v[pop] = np.log(x[pop])
        logx[:, c] = v
        counts[:, c] = cnt
    inverse = finalise(logx, counts)
    return CameraResponse(inverse, levels, "robertson2003")

