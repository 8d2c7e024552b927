r"""Light direction and albedo from the occluding contour (``"contour"``, a descriptive name).

The method has no single paper: it combines the occluding-contour constraint used by Nillius &
Eklundh (2001) with Pentland's (1982) brightest-point albedo and a robust (RANSAC) fit.  On an
occluding contour the normal is the silhouette's outward normal ``(d, 0)``, so

.. math:: I = \max(0,\; \rho\, d \cdot S_{xy} + c)

at contour pixels (``c`` absorbs ``rho S_z N_z`` of pixels read slightly inside the contour): a
linear fit for ``rho S_xy``, with ``S_z = sqrt(1 - |S_xy|^2)``.

References
----------
- P. Nillius and J.-O. Eklundh, "Automatic estimation of the projected light source direction",
  CVPR 2001.
- A. P. Pentland, "Finding the illuminant direction", Journal of the Optical Society of America
  72(4):448-455, 1982.
- M. A. Fischler and R. C. Bolles, "Random sample consensus", Communications of the ACM
  24(6):381-395, 1981.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from pbrbench.checks import check_int
from pbrbench.infer._docstring import docstring
from pbrbench.infer.sfs._common import (
    DOCS,
    LightEstimate,
    _outward_directions,
    _prepare_light_image,
    occluding_boundary,
)

__all__ = ["light_from_shading_contour"]


def _brightest(img, m, sigma: float = 1.0) -> float:
    """Brightest value of ``img`` in ``m`` after a normalised Gaussian blur inside the mask.

    Pentland's (1982) albedo is the brightest pixel; the blur (``sigma`` px) keeps pixel noise
    from biasing it upward (the maximum of n noisy pixels sits ~4 sd above the truth).
    """
    w = ndimage.gaussian_filter(m.astype(float), sigma)
    v = ndimage.gaussian_filter(np.where(m, img, 0.0), sigma)
    sm = np.where(m & (w > 1e-3), v / np.maximum(w, 1e-3), 0.0)
    return float(max(sm[m].max(), 0.0))


HOLE_FRACTION = 0.01   # holes of the mask below this fraction of its area are not silhouettes


def _fill_small_holes(m: np.ndarray) -> np.ndarray:
    """``m`` with its holes (components of the complement that do not touch the frame) smaller
    than :data:`HOLE_FRACTION` of its area filled: pixels a mask leaves out inside a surface (a
    rendered heightfield's pixels that fail a per-pixel test, a photo's specks) are not where
    the surface turns away from the view, and their number is noise (on sfs_random 4 lit ones at
    one render seed, 8 or more at another, which made the light estimate succeed or fail)."""
    holes = ~m
    lab, n = ndimage.label(holes)
    if n == 0:
        return m
    frame = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
    sizes = np.bincount(lab.ravel(), minlength=n + 1)
    small = sizes < HOLE_FRACTION * max(int(m.sum()), 1)
    small[0] = False
    small[frame] = False
    return m | small[lab]


def _contour_light(img, m, *, seed: int = 0, n_trials: int = 300, inlier_frac: float = 0.05):
    """Robust occluding-contour light fit; returns ``(direction, albedo)``.

    Model at contour pixels: ``I = max(0, a d_x + b d_y + c)`` with ``(a, b) = rho S_xy`` and
    ``c`` absorbing ``rho S_z N_z`` (the pixels read slightly inside the contour).  Edges of the
    mask that are not occluding contours (a surface cut by a plane, a vase's ends) break the
    model; they are rejected as outliers: RANSAC over triples of bright contour pixels (consensus:
    ``|I - max(0, pred)| < inlier_frac * rho``, counted over all contour pixels, dark ones
    included), then least squares on the inliers that are predicted lit, re-selected until stable.
    """
    rho = _brightest(img, m)
    b = occluding_boundary(_fill_small_holes(m)) & m
    dx, dy = _outward_directions(m)
    bi = np.flatnonzero(b)
    inten = img.ravel()[bi]
    A = np.stack([dx.ravel()[bi], dy.ravel()[bi], np.ones(bi.size)], axis=1)
    bright = np.flatnonzero(inten > 0.1 * rho)
    if bright.size < 8:
        raise ValueError(f"mask: only {int(bright.size)} lit occluding-contour pixels (need >= 8); "
                         "pass a mask whose edge is the object's silhouette, or use "
                         "method='lee_rosenfeld1985'")
    tau = inlier_frac * rho

    def consensus(coef):
        return np.abs(inten - np.maximum(0.0, A @ coef)) < tau

    rng = np.random.default_rng(seed)
    best, best_n = None, -1
    for _ in range(n_trials):
        pick = rng.choice(bright, 3, replace=False)
        try:
            coef = np.linalg.solve(A[pick], inten[pick])
        except np.linalg.LinAlgError:
            continue
        n_in = int(consensus(coef).sum())
        if n_in > best_n:
            best, best_n = coef, n_in
    if best is None:
        best = np.linalg.lstsq(A[bright], inten[bright], rcond=None)[0]
    coef = best
    for _ in range(20):
        use = consensus(coef) & (A @ coef > 0.1 * rho) & (inten > 0.02 * rho)
        if use.sum() < 3:
            break
        new = np.linalg.lstsq(A[use], inten[use], rcond=None)[0]
        if np.allclose(new, coef, atol=1e-9):
            break
        coef = new
    sxy = coef[:2] / rho
    nxy = float(np.hypot(*sxy))
    if nxy > 1:
        sxy = sxy / nxy
        nxy = 1.0
    d = np.array([sxy[0], sxy[1], math.sqrt(max(0.0, 1 - nxy * nxy))])
    return d / np.linalg.norm(d), rho


@docstring(DOCS)
def light_from_shading_contour(image, mask=None, *, seed: int = 0) -> LightEstimate:
    r"""Distant light direction and albedo from the brightness along the occluding contour.

    .. math:: I = \max(0, \rho\, d \cdot S_{xy} + c), \qquad S_z = \sqrt{1 - |S_{xy}|^2}

    A descriptive name (no single paper; Nillius & Eklundh, CVPR 2001, with the albedo of
    Pentland 1982): on an occluding contour the normal is the silhouette's outward normal
    ``(d, 0)``, so ``I = max(0, rho d . S_xy)`` at contour pixels, a linear fit for
    ``rho S_xy``.  The albedo is the brightest pixel (some point faces the light, Pentland 1982;
    taken after a 1-pixel Gaussian blur so noise does not bias it up).  Contour pixels read
    slightly inside the true contour, where ``I = rho N . S`` also carries ``S_z N_z``; the fit
    therefore includes a constant term ``c`` that absorbs it.  Mask edges that are not occluding
    contours (a surface cut by a plane or by the frame) do not obey the model: the fit is robust
    (RANSAC over contour-pixel triples with consensus ``|I - max(0, pred)| < 0.05 rho``, then
    least squares on the inliers predicted lit), so they are rejected as long as most of the
    edge is a true contour.  Holes of the mask smaller than 1 % of its area are filled first
    (they are not silhouettes).  Assumes one object of uniform albedo.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    mask : (H, W) bool, optional
        The object's pixels; its edge must be an occluding contour (at least 8 lit pixels).
    seed : int
        Seed of the RANSAC sampling (the result is deterministic given it).

    %(light_result)s

    References
    ----------
    P. Nillius and J.-O. Eklundh, "Automatic estimation of the projected light source
    direction", CVPR 2001; A. P. Pentland, "Finding the illuminant direction", JOSA
    72(4):448-455, 1982.
    """
    img, m, _ = _prepare_light_image(image, mask)
    seed = check_int(seed, "seed", lo=0)
    d, rho = _contour_light(img, m, seed=seed)
    return LightEstimate(direction=d, albedo=rho, method="contour")
