"""Scores for photometric stereo and surface integration: normals, albedo, height.

Angular error follows the DiLiGenT protocol (Shi, Wu, Tan, Matsushita, Zickler & Ikeuchi,
"A benchmark dataset and evaluation for non-Lambertian and uncalibrated photometric stereo",
CVPR 2016 / TPAMI 2019): per pixel the angle ``arccos(clip(n_est . n_true, -1, 1))`` between unit
normals, in degrees, averaged over the object mask.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_mask
from pbrbench.metrics.table import table

__all__ = [
    "angular_error_map",
    "angular_error_stats",
    "albedo_relative_error",
    "height_rmse",
    "height_rmse_scaled",
    "normal_scores",
    "albedo_scores",
    "height_scores",
    "largest_component",
    "METRICS",
]


def _unit(n, name):
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0), norm[..., 0] > 0


def angular_error_map(n_est, n_true, mask=None) -> np.ndarray:
    """Per-pixel angle (degrees) between estimated and true normals.

    ``err = degrees(arccos(clip(n_est/|n_est| . n_true/|n_true|, -1, 1)))``. Both fields are
    normalised first. A pixel inside ``mask`` whose estimated normal is zero (an invalid
    estimate) scores 90 degrees (``arccos(0)``), so leaving pixels out is never rewarded; pass a
    smaller mask to score only valid pixels. Outside ``mask`` the map is NaN.

    Parameters
    ----------
    n_est, n_true : (H, W, 3) arrays
    mask : (H, W) bool, optional (default: pixels where ``n_true`` is non-zero)

    Raises
    ------
    ValueError
        On shape mismatch, non-finite values in the mask, or a zero true normal in the mask.
    """
    a = as_float_array(n_est, "n_est", ndim=(3,))
    b = as_float_array(n_true, "n_true", ndim=(3,))
    if a.shape != b.shape or a.shape[-1] != 3:
        raise ValueError(f"n_est: shape {a.shape} must equal n_true's {b.shape} and be (H, W, 3)")
    if mask is None:
        m = np.linalg.norm(np.nan_to_num(b), axis=-1) > 0
        if not m.any():
            raise ValueError("n_true: every normal is zero; pass true normals or a mask")
    else:
        m = check_mask(mask, a.shape[:2])
    check_finite(a, "n_est", where=m)
    check_finite(b, "n_true", where=m)
    ua, _ = _unit(np.where(m[..., None], a, 0.0), "n_est")
    ub, okb = _unit(np.where(m[..., None], b, 0.0), "n_true")
    if np.any(m & ~okb):
        raise ValueError("n_true: zero normal(s) inside the mask; exclude them with the mask")
    dot = np.clip(np.einsum("hwc,hwc->hw", ua, ub), -1.0, 1.0)
    err = np.degrees(np.arccos(dot))
    return np.where(m, err, np.nan)


def angular_error_stats(n_est, n_true, mask=None) -> dict:
    """Mean, median and the fractions under 5 and 10 degrees of :func:`angular_error_map`.

    Returns ``{"mean", "median", "frac_under_5", "frac_under_10", "n_pixels"}`` (degrees,
    fractions in [0, 1]) over ``mask``.
    """
    err = angular_error_map(n_est, n_true, mask)
    e = err[np.isfinite(err)]
    return {
        "mean": float(e.mean()),
        "median": float(np.median(e)),
        "frac_under_5": float(np.mean(e < 5.0)),
        "frac_under_10": float(np.mean(e < 10.0)),
        "n_pixels": int(e.size),
    }


def _pair(est, true, mask, name_est, name_true):
    a = as_float_array(est, name_est)
    b = as_float_array(true, name_true)
    if a.shape != b.shape:
        raise ValueError(f"{name_est}: shape {a.shape} differs from {name_true} shape {b.shape}; pass arrays of one shape")
    if a.ndim not in (2, 3):
        raise ValueError(f"{name_est}: expected (H, W) or (H, W, C), got shape {a.shape}")
    m = check_mask(mask, a.shape[:2])
    check_finite(a, name_est, where=m)
    check_finite(b, name_true, where=m)
    return a[m], b[m]


def albedo_relative_error(est, true, mask=None) -> float:
    """Relative albedo error after one global least-squares scale.

    ``s = sum(est * true) / sum(est^2)`` over the mask (all channels), then
    ``mean(|s est - true|) / mean(|true|)``. Photometric stereo recovers albedo only up to the
    unknown source intensity, hence the free scale.

    Raises
    ------
    ValueError
        On shape mismatch, non-finite values in the mask, or an all-zero estimate.
    """
    a, b = _pair(est, true, mask, "est", "true")
    den = float(np.sum(a * a))
    if den <= 0:
        raise ValueError("est: the estimated albedo is zero everywhere in the mask; nothing to scale")
    tn = float(np.mean(np.abs(b)))
    if tn <= 0:
        raise ValueError("true: the true albedo is zero everywhere in the mask; the relative error is undefined")
    s = float(np.sum(a * b)) / den
    return float(np.mean(np.abs(s * a - b)) / tn)


def height_rmse(est, true, mask=None) -> float:
    """Height RMSE after removing the free offset: ``sqrt(mean((d - mean(d))^2))``, ``d = est - true``.

    Integration recovers height only up to a constant. Same units as the inputs.
    """
    a, b = _pair(est, true, mask, "est", "true")
    d = a - b
    return float(np.sqrt(np.mean((d - d.mean()) ** 2)))


def height_rmse_scaled(est, true, mask=None) -> float:
    """Height RMSE after the best offset and scale: ``min_{s,c} rms(s est + c - true)``.

    For reconstructions whose depth scale is unknown (e.g. uncalibrated intensities or an
    unknown pixel size).
    """
    a, b = _pair(est, true, mask, "est", "true")
    x = np.stack([a, np.ones_like(a)], axis=1)
    coef = np.linalg.lstsq(x, b, rcond=None)[0]
    r = b - x @ coef
    return float(np.sqrt(np.mean(r * r)))


# ----------------------------------------------------------------------------- task scores
def normal_scores(est, true, domain, valid) -> tuple[dict, np.ndarray]:
    """DiLiGenT angular-error scores over ``domain`` (an invalid estimate scores 90 degrees:
    :func:`angular_error_map`) plus ``coverage``, the valid fraction of the domain; returns
    (scores, error map).  An empty domain gives no scores."""
    domain = np.asarray(domain, bool)
    valid = np.asarray(valid, bool)
    if not domain.any():
        return {}, np.full(domain.shape, np.nan)
    n = np.where(valid[..., None], est, 0.0)
    emap = angular_error_map(n, true, domain)
    st = angular_error_stats(n, true, domain)
    return {"normal_mean_deg": st["mean"], "normal_median_deg": st["median"],
            "normal_frac_under_5deg": st["frac_under_5"], "normal_frac_under_10deg": st["frac_under_10"],
            "coverage": float((domain & valid).sum() / domain.sum())}, emap


def albedo_scores(est, true, sel) -> dict:
    """``albedo_rel_err``: mean ``|est / true - 1|`` with the nominal intensities (no rescaling:
    shows the inflation by interreflection); ``albedo_rel_err_scaled``:
    :func:`albedo_relative_error` (one global least-squares scale).  Empty when ``sel`` selects
    nothing or the estimate is zero there."""
    sel = np.asarray(sel, bool)
    if not sel.any() or not np.any(est[sel] > 0):
        return {}
    r = est[sel] / np.maximum(true[sel], 1e-6)
    return {"albedo_rel_err": float(np.mean(np.abs(r - 1))),
            "albedo_rel_err_scaled": albedo_relative_error(est, true, sel)}


def largest_component(mask: np.ndarray) -> np.ndarray:
    """The largest 4-connected component of ``mask``."""
    from scipy import ndimage

    lab, n = ndimage.label(mask)
    if n <= 1:
        return np.asarray(mask, bool).copy()
    sizes = ndimage.sum(mask, lab, index=np.arange(1, n + 1))
    return lab == (1 + int(np.argmax(sizes)))


def height_scores(normals, z_true, domain, pixel_size, integrate=None) -> tuple[dict, np.ndarray]:
    """Integrate ``normals`` on the largest component of ``domain`` (pixels with ``N_z > 1e-3``)
    with ``integrate`` (a surface-integration method of :mod:`pbrbench.infer.integration`, called
    as ``integrate(normals, mask=..., pixel_size=...)``; default its ``lsq``); height RMSE vs
    ``z_true`` after removing the free offset (:func:`height_rmse`, world units) and relative to
    the true height range.  Returns (scores, height map with its mean removed, NaN outside)."""
    if integrate is None:
        from pbrbench.infer.integration import METHODS

        integrate = METHODS["lsq"]
    dom = largest_component(np.asarray(domain, bool) & (normals[..., 2] > 1e-3))
    if dom.sum() < 4:
        return {}, np.full(z_true.shape, np.nan)
    z = integrate(normals, mask=dom, pixel_size=pixel_size)
    rmse = height_rmse(z, z_true, dom)
    rng = float(np.ptp(z_true[dom]))
    return {"height_rmse": rmse, "height_rmse_rel": rmse / rng if rng > 0 else float("nan")}, \
        np.where(dom, z - z[dom].mean(), np.nan)


METRICS = table("""
normal_mean_deg         | lower  | deg         | normal_scores | mean angle between estimated and true normals over the domain (DiLiGenT)
normal_median_deg       | lower  | deg         | normal_scores | median angle between estimated and true normals
normal_frac_under_5deg  | higher | fraction    | normal_scores | fraction of the domain with an angular error below 5 degrees
normal_frac_under_10deg | higher | fraction    | normal_scores | fraction of the domain with an angular error below 10 degrees
coverage                | higher | fraction    | normal_scores | fraction of the domain where the method returned a valid normal
albedo_rel_err          | lower  | fraction    | albedo_scores | mean |albedo_est / albedo - 1| with the nominal source intensities
albedo_rel_err_scaled   | lower  | fraction    | albedo_scores | relative albedo error after one global least-squares scale
height_rmse             | lower  | world units | height_scores | height RMSE after removing the free offset
height_rmse_rel         | lower  | fraction    | height_scores | height RMSE relative to the true height range
""")
