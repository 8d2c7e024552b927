"""Robust photometric stereo by low-rank matrix completion and recovery (Wu et al. 2010).

Reference: L. Wu, A. Ganesh, B. Shi, Y. Matsushita, Y. Wang and Y. Ma, "Robust photometric
stereo via low-rank matrix completion and recovery", ACCV 2010; Z. Lin, M. Chen and Y. Ma, "The
augmented Lagrange multiplier method for exact recovery of corrupted low-rank matrices",
arXiv:1009.5055, 2010 (the inexact ALM solver).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int, check_number
from pbrbench.infer._docstring import docstring
from pbrbench.infer.photometric_stereo._common import (
    DOCS,
    PhotometricStereoResult,
    accumulate,
    least_squares,
    measurements,
    prepare,
    reject_outliers,
    sym_solve,
)

__all__ = ["photometric_stereo_wu2010"]

VERSION = "4"  # the low-rank recovery on the raw measurements proposes the errors, the Lambertian fit confirms them; a rejection never leaves inliers that determine no normal
REFITS = 5      # rounds of fit and outlier check at most


def _svt(X, tau):
    """Singular value thresholding of a wide (K, N) matrix through its K x K Gram matrix."""
    ev, U = np.linalg.eigh(X @ X.T)
    sv = np.sqrt(np.maximum(ev, 0.0))
    keep = sv > tau
    if not keep.any():
        return np.zeros_like(X), 0
    U = U[:, keep]
    f = (sv[keep] - tau) / sv[keep]
    return (U * f) @ (U.T @ X), int(keep.sum())


def inexact_alm(D, observed, lam: float, n_iter: int, tol: float):
    r"""``(A, E, rank)``: ``min ||A||_* + lam ||E||_1`` s.t. ``P_observed(D) = P_observed(A + E)``
    by the inexact augmented Lagrange multiplier method (Lin, Chen & Ma 2010), ``D`` (K, N) not
    all zero; ``E`` is soft-thresholded on the observed entries and free (the completion)
    elsewhere; stops after ``n_iter`` iterations or when ``||D - A - E||_F / ||D||_F < tol``."""
    norm_d = np.linalg.norm(D)
    two = np.sqrt(np.linalg.eigvalsh(D @ D.T)[-1])
    mu = 1.25 / two
    mu_max = mu * 1e7
    rho = 1.5
    Y = D / max(two, np.abs(D).max() / lam)
    E = np.zeros_like(D)
    A, rank = np.zeros_like(D), 0
    for _ in range(n_iter):
        A, rank = _svt(D - E + Y / mu, 1.0 / mu)
        T = D - A + Y / mu
        E = np.where(observed, np.sign(T) * np.maximum(np.abs(T) - lam / mu, 0.0), T)
        Z = D - A - E
        Y += mu * Z
        mu = min(mu * rho, mu_max)
        if np.linalg.norm(Z) / norm_d < tol:
            break
    return A, E, rank


@docstring(DOCS)
def photometric_stereo_wu2010(images, lights, *, mask=None, intensities=None, shadow_threshold: float = 0.01,
                              saturation: float | None = None, min_lights: int = 3, sparsity: float | None = None,
                              max_iter: int = 500, tol: float = 1e-7) -> PhotometricStereoResult:
    r"""Normals and albedo from the low-rank part of the observation matrix (Wu et al. 2010).

    Stack the (intensity-normalised) measurements into ``D`` (K lights x N pixels), as they
    are (no per-pixel normalisation, as in Wu et al.: on the robust stacks of ``pbrbench perf
    photometric_stereo`` a per-pixel normalisation to one albedo cost up to 35 %); shadowed
    and saturated entries are missing (the complement of the observed set ``\Omega``).  A
    Lambertian surface without shadows gives a matrix of rank 3 (``D = V G``); highlights and
    cast shadows are sparse errors ``E``.  Solve (Wu et al. 2010, eq. 5)

    .. math:: \min_{A, E} \|A\|_* + \lambda \|E\|_1 \quad \text{s.t.} \quad
              P_\Omega(D) = P_\Omega(A + E)

    by the inexact augmented Lagrange multiplier method (Lin, Chen & Ma 2010): singular value
    thresholding for ``A``, soft thresholding for ``E`` on ``\Omega`` (free, i.e. filled in,
    outside it).  Measurements flagged as errors (``|E|`` above 5 robust standard deviations of
    the entries of ``E``, and above ``10^{-3}`` of the pixel's brightest) are left out (unless
    fewer than 3 would remain) of a first least-squares fit of each pixel's ``g = \rho N`` with
    the known lights.  The flags are proposals: with few images (``K`` not much larger than the
    rank 3) the nuclear norm can prefer a different low-rank matrix and a dense ``E`` (on a
    rendered sphere under 12 distant lights it flagged 30 % of the clean measurements and left
    20 % of the pixels without a solvable set).  So, as for the sparse-regression methods, a
    measurement is finally dropped only where it is an outlier of that fit, its residual above 5
    robust standard deviations of the trusted measurements' residuals (over the pixels with more
    than 3 of them; ``reject_outliers``), and ``g`` is the
    least-squares fit on the rest, as for
    :func:`~pbrbench.infer.photometric_stereo.woodham1980.photometric_stereo_woodham1980` (the
    low-rank matrix decides which measurements to suspect; the known lights and the data decide
    which are errors and give the normal).

    Parameters
    ----------
    %(inputs)s
    %(options)s
    sparsity : float or None
        ``\lambda``; default ``1 / \sqrt{N}`` (Wu et al.; the usual RPCA choice
        ``1 / \sqrt{\max(K, N)}``).
    max_iter, tol
        ALM iterations and the stopping threshold on ``\|P_\Omega(D - A - E)\|_F / \|D\|_F``.

    Returns
    -------
    PhotometricStereoResult

    Raises
    ------
    ValueError
        As for the least-squares method, and for ``sparsity <= 0``, ``max_iter < 1`` or
        ``tol <= 0``.

    References
    ----------
    L. Wu, A. Ganesh, B. Shi, Y. Matsushita, Y. Wang and Y. Ma, "Robust photometric stereo via
    low-rank matrix completion and recovery", ACCV 2010; Z. Lin, M. Chen and Y. Ma, "The
    augmented Lagrange multiplier method for exact recovery of corrupted low-rank matrices",
    arXiv:1009.5055, 2010.
    """
    p = prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights)
    n_iter = check_int(max_iter, "max_iter", 1)
    tol = check_number(tol, "tol", lo=0.0, lo_open=True)
    jsum, used, g_all = measurements(p)
    K, N = jsum.shape
    lam = 1.0 / np.sqrt(max(K, N)) if sparsity is None else check_number(sparsity, "sparsity", lo=0.0, lo_open=True)
    scale = np.maximum(jsum.max(axis=0), np.finfo(float).tiny)
    D = np.where(used, jsum, 0.0)  # the measurements as they are (Wu et al.; a per-pixel
    # normalisation to one albedo gave dark pixels the weight of bright ones: version 2)
    if np.linalg.norm(D) > 0:
        _, E, _ = inexact_alm(D, used, lam, n_iter, tol)
        # errors: |E| (relative to the pixel's brightest) beyond 5 robust standard deviations of
        # the small entries (the noise the soft threshold left in E), at least 1e-3
        E = E / scale
        ae = np.abs(E[used])
        sig = 1.4826 * float(np.median(ae)) if ae.size else 0.0
        trusted = used & (np.abs(E) <= max(5.0 * sig, 1e-3))
        # a pixel left with 3 trusted measurements (interpolated exactly: nothing to check the
        # others against) or fewer starts from all its used ones
        few = trusted.sum(axis=0) <= 3
        trusted = np.where(few[None, :], used, trusted)
        # the fit on the trusted measurements (all used ones where it is ill-conditioned), then
        # the outliers of that fit among every used measurement; refitted on the inliers until
        # the set settles (a fit on a few trusted lights extrapolates the others with more error)
        for _ in range(REFITS):
            amat, _, bsum, _, _, _ = accumulate(p, used_in=trusted)
            g_t, ok_t = sym_solve(amat[:6], bsum)
            g = np.where(ok_t, g_t, g_all)
            r = np.abs(jsum - p.s @ g)
            # the noise from the inliers of the pixels the fit over-determines (three are
            # interpolated exactly), so that the errors the recovery found do not inflate it
            over = trusted & (trusted.sum(axis=0) > 3)[None, :]
            new = reject_outliers(used, r, over, scale, p.min_lights, p.s7)
            if np.array_equal(new, trusted):
                break
            trusted = new
        used = trusted
    return least_squares(p, used_in=used)
