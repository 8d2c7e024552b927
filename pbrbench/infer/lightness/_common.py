"""Shared pieces of the lightness methods: option checks, the log-gradients of the image, the
reconstruction and the constant of integration."""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_finite, check_mask, check_number, check_positive
from pbrbench.infer.poisson import solve_gradient_field

__all__ = ["ANCHORS", "DOCS", "anchor_reflectance", "check_percentile", "check_threshold", "log_gradients", "reconstruct",
           "valid_pixels"]

ANCHORS = ("brightest", "mean")


# numpydoc fragments shared by the methods' docstrings (pbrbench.infer._docstring)
DOCS = {
    "returns": """\
Returns
-------
reflectance, shading : arrays of the image's shape, float64; 0 outside the valid pixels.""",
}

def check_threshold(threshold) -> float:
    """``threshold`` as a finite float >= 0 (log units per pixel)."""
    return check_number(threshold, "threshold", lo=0.0)


def check_percentile(p) -> float:
    """``brightest_percentile`` as a float in (0, 100]."""
    return check_number(p, "brightest_percentile", lo=0.0, lo_open=True, hi=100.0)


def anchor_reflectance(log_refl: np.ndarray, sel: np.ndarray, anchor: str, mean_lightness: float,
                       percentile: float) -> np.ndarray:
    """Reflectance from the log-albedo (..., C) with the constant fixed per channel over ``sel``.

    ``"brightest"``: the ``percentile`` percentile of the log-albedo (100: the maximum) is white
    (Land's white-patch normalisation, Land & McCann 1971); ``"mean"``: the mean reflectance is
    ``mean_lightness``.
    """
    vals = log_refl[sel]  # (n, C)
    if anchor == "brightest":
        top = vals.max(axis=0) if percentile == 100.0 else np.percentile(vals, percentile, axis=0)
        return np.exp(log_refl - top)
    refl = np.exp(log_refl - vals.mean(axis=0))
    return refl * (mean_lightness / refl[sel].mean(axis=0))


def valid_pixels(img: np.ndarray, m: np.ndarray, min_value, name: str) -> np.ndarray:
    """Mask of pixels whose log is defined; ValueError for NaN/inf or non-positive values."""
    check_finite(img, name, where=m)
    chan_min = img if img.ndim == 2 else img.min(axis=-1)
    if min_value is None:
        bad = m & ~(chan_min > 0)
        if bad.any():
            raise ValueError(
                f"{name}: {int(bad.sum())} pixel(s) inside the mask are <= 0, where the log is "
                "undefined; exclude them with mask= or pass min_value= (e.g. 1e-6) to drop "
                "pixels below it from the domain")
        return m
    floor = check_positive(min_value, "min_value")
    m = m & (chan_min >= floor)
    if not m.any():
        raise ValueError(f"{name}: no pixel inside the mask is >= min_value={floor:g}; "
                         "lower min_value or check the image scale")
    return m


def log_gradients(img: np.ndarray, mask, min_value):
    """The forward differences of ``log C`` on the valid domain: ``(x, m, gx, gy)``.

    ``x`` (H, W, C) the image (a channel axis added for grey), ``m`` the domain
    (:func:`valid_pixels` of ``mask``), ``gx[i, j] = log C[i, j+1] - log C[i, j]`` and
    ``gy[i, j] = log C[i+1, j] - log C[i, j]``, 0 for a difference that leaves the domain (not
    an equation) and on the last column / row.
    """
    x = img[..., None] if img.ndim == 2 else img
    h, w, nc = x.shape
    m = check_mask(mask, (h, w))
    m = valid_pixels(img, m, min_value, "image")
    full = bool(m.all())

    logc = np.log(x) if full else np.where(m[..., None], np.log(np.where(m[..., None], x, 1.0)), 0.0)
    gx = np.zeros_like(logc)
    gy = np.zeros_like(logc)
    gx[:, :-1] = logc[:, 1:] - logc[:, :-1]
    gy[:-1, :] = logc[1:, :] - logc[:-1, :]
    if not full:  # differences that leave the domain are not equations
        gx[:, :-1] *= (m[:, :-1] & m[:, 1:])[..., None]
        gy[:-1, :] *= (m[:-1, :] & m[1:, :])[..., None]
    return x, m, gx, gy


def reconstruct(x, m, gx, gy, anchor: str, mean_lightness: float, percentile: float, solver: str, *, grey: bool):
    r"""Reflectance and shading from the kept log-gradients (a Neumann Poisson solve per channel).

    .. math:: \min_{\log \rho} \sum (\nabla \log \rho - (g_x, g_y))^2, \qquad
              S = C / \rho

    on the domain ``m`` (:func:`pbrbench.infer.poisson.solve_gradient_field`), the constant
    fixed by :func:`anchor_reflectance`; both 0 outside ``m``, channel axis dropped for ``grey``.
    """
    full = bool(m.all())
    sol_mask = None if full else m
    log_refl = np.stack([solve_gradient_field(gx[..., c], gy[..., c], mask=sol_mask, method=solver)
                         for c in range(x.shape[-1])], axis=-1)
    refl = anchor_reflectance(log_refl, m, anchor, mean_lightness, percentile)
    if full:
        shading = x / refl
    else:
        refl = np.where(m[..., None], refl, 0.0)
        shading = np.where(m[..., None], x / np.where(m[..., None], refl, 1.0), 0.0)
    if grey:
        return refl[..., 0], shading[..., 0]
    return refl, shading
