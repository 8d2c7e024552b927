"""Robust photometric stereo by sparse Bayesian learning (Ikehata et al. 2012, SBL variant).

Reference: S. Ikehata, D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo using
sparse regression", CVPR 2012; M. E. Tipping, "Sparse Bayesian learning and the relevance vector
machine", JMLR 1, 2001 (the evidence maximisation).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int, check_number
from pbrbench.infer._docstring import docstring
from pbrbench.infer.photometric_stereo._common import (
    _CHUNK,
    DOCS,
    PhotometricStereoResult,
    cofactors,
    least_squares,
    measurements,
    prepare,
    reject_outliers,
    sym_solve,
)

__all__ = ["photometric_stereo_ikehata2012_sbl"]

VERSION = "2"  # the final rejection never leaves inliers that determine no normal (three coplanar sources)


def _pairs6(s):
    """(K, 6) rows ``(sx^2, sy^2, sz^2, 2 sx sy, 2 sx sz, 2 sy sz)`` of the lights ``s`` (K, 3)."""
    return np.stack([s[:, 0] ** 2, s[:, 1] ** 2, s[:, 2] ** 2,
                     2 * s[:, 0] * s[:, 1], 2 * s[:, 0] * s[:, 2], 2 * s[:, 1] * s[:, 2]], axis=1)


def _quad_from_cofactors(q6, cof, inv_det):
    """``s_k^T A^{-1} s_k`` from the cofactors ``(c00, c01, c02, c11, c12, c22)`` of ``A`` and
    ``1 / det A`` (0 where singular): one (K, 6) x (6, N) product with ``q6 = _pairs6(s)``."""
    c00, c01, c02, c11, c12, c22 = cof
    return q6 @ (np.stack([c00, c11, c22, c01, c02, c12]) * inv_det)


def _sbl_em(jsum, used, g, scale, lam, s, s7, n_iter):
    """The EM iterations of the docstring on one block of pixels (pixels are independent);
    ``g`` (3, N) is the start.  Each iteration forms the weighted normal equations ``A = sum_k
    w_k S_k S_k^T`` and their cofactors once, for both the solve and ``h_k``."""
    usedf = used.astype(float)
    gamma = np.where(used, scale**2, 0.0)  # start: every measurement may be corrupted
    q6 = _pairs6(s)
    sT, s7T = s.T, s7.T
    zero = np.zeros_like(gamma)
    for _ in range(n_iter):
        # only used measurements carry a weight: at a pixel dark in every image, gamma and lam
        # underflow to 0 and a plain division would give 0 / 0 (a NaN and a RuntimeWarning)
        w = np.divide(usedf, gamma + lam, out=zero.copy(), where=used)
        a = s7T @ w
        *cof, det = cofs = cofactors(a[:6])
        g_new, ok = sym_solve(a[:6], sT @ (w * jsum), cofs)
        g = np.where(ok, g_new, g)
        r = jsum - s @ g
        inv_pos = np.divide(1.0, det, out=np.zeros_like(det), where=det > 0)
        h = _quad_from_cofactors(q6, cof, inv_pos)
        sigma_kk = gamma - gamma * gamma * (w - w * w * h)
        mu = gamma * w * r
        gamma = np.where(used, mu * mu + np.maximum(sigma_kk, 0.0), 0.0)
    return g


@docstring(DOCS)
def photometric_stereo_ikehata2012_sbl(images, lights, *, mask=None, intensities=None, shadow_threshold: float = 0.01,
                                       saturation: float | None = None, min_lights: int = 3, noise: float = 1e-3,
                                       max_iter: int = 100) -> PhotometricStereoResult:
    r"""Normals and albedo robust to highlights and cast shadows by sparse Bayesian learning.

    Per pixel, over the used lights (lit and unsaturated), the measurements are modelled as
    (Ikehata et al. 2012)

    .. math:: y = V g + e + \epsilon, \qquad e \sim \mathcal N(0, \Gamma),\ \Gamma =
              \mathrm{diag}(\gamma), \qquad \epsilon \sim \mathcal N(0, \lambda I),

    with a flat prior on ``g = \rho N`` and a sparse corruption ``e`` (highlights, cast
    shadows) whose variances ``\gamma`` are learned by maximising the evidence
    ``p(y \mid \gamma)`` (type-II maximum likelihood, Tipping 2001).  Marginalising ``e`` and
    ``\epsilon`` gives ``y \sim \mathcal N(V g, \Gamma + \lambda I)``, so for given
    ``\gamma`` the estimate of ``g`` is weighted least squares with weights
    ``w_k = 1 / (\gamma_k + \lambda)``, and the EM update of ``\gamma`` is

    .. math:: \gamma_k \leftarrow \mu_k^2 + \Sigma_{kk}, \quad \mu_k = \gamma_k w_k r_k, \quad
              \Sigma_{kk} = \gamma_k - \gamma_k^2 (w_k - w_k^2 h_k),

    with ``r = y - V g`` and ``h_k = V_k^T (V^T W V)^{-1} V_k``.  Corrupted measurements get a
    large ``\gamma`` (weight near 0), clean ones ``\gamma \to 0``: unlike the convex
    :math:`\ell_1` fit, the implicit penalty is close to counting the outliers.  Vectorised over
    pixels with batched 3x3 solves.  Measurements whose final residual exceeds 5 robust
    standard deviations of the noise are then dropped and ``g`` is refitted by least squares on
    the rest (as for the :math:`\ell_1` method).  With 3 used lights there is nothing to
    reject and the result is the least-squares one.

    Parameters
    ----------
    %(inputs)s
    %(options)s
    noise : float
        ``\sqrt\lambda`` as a fraction of each pixel's brightest measurement (> 0).
    max_iter : int
        EM iterations (>= 1).

    Returns
    -------
    PhotometricStereoResult
        ``residual`` is the RMS over the inliers and ``n_used`` counts them.

    Raises
    ------
    ValueError
        As for the least-squares method, and for ``noise <= 0`` or ``max_iter < 1``.

    References
    ----------
    S. Ikehata, D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo using sparse
    regression", CVPR 2012; M. E. Tipping, "Sparse Bayesian learning and the relevance vector
    machine", JMLR 1, 2001.
    """
    p = prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights)
    sig = check_number(noise, "noise", lo=0.0, lo_open=True)
    n_iter = check_int(max_iter, "max_iter", 1)
    s, s7 = p.s, p.s7
    jsum, used, g = measurements(p)
    scale = np.maximum(jsum.max(axis=0), np.finfo(float).tiny)
    lam = (sig * scale) ** 2
    g = g.copy()
    for start in range(0, g.shape[1], _CHUNK):   # pixel blocks: the temporaries stay in cache
        sl = slice(start, start + _CHUNK)
        g[:, sl] = _sbl_em(jsum[:, sl], used[:, sl], g[:, sl], scale[sl], lam[sl], s, s7, n_iter)
    r = np.abs(jsum - s @ g)
    free = used & (r > 1e-9 * scale)
    used = reject_outliers(used, r, free, scale, p.min_lights, p.s7)
    return least_squares(p, used_in=used, fallback=g)
