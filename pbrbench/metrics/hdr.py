"""Scores for HDR recovery: log-radiance error after the free global scale, response-curve error.

All errors are in stops (log2 units).  A merged radiance is defined up to one global scale
(calibration fixes ``f^{-1}`` only up to a factor), so :func:`log_radiance_rmse` first removes the
best single factor for all channels together (the least-squares offset of ``log2(est / truth)``):
a colour-balance drift between channels is therefore *not* forgiven.  A response curve is defined
up to a factor per channel; :func:`response_rmse` removes it per channel by default (the shape
error), or one factor for all channels with ``align="global"``.
"""

from __future__ import annotations

import numpy as np

from pbrbench.metrics.table import table

__all__ = [
    "hdr_scores",
    "invalid_fraction",
    "log_radiance_rmse",
    "log_radiance_rmse_extremes",
    "response_rmse",
]


def _pair(estimate, truth):
    est = np.asarray(estimate, dtype=np.float64)
    tru = np.asarray(truth, dtype=np.float64)
    if est.shape != tru.shape:
        raise ValueError(f"estimate: shape {est.shape} does not match truth {tru.shape}; pass arrays of one shape")
    if est.size == 0:
        raise ValueError("estimate: empty array")
    return est, tru


def _valid(est, tru, mask):
    ok = np.isfinite(est) & (est > 0) & np.isfinite(tru) & (tru > 0)
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if m.shape == est.shape[:2] and est.ndim == 3:
            m = np.broadcast_to(m[..., None], est.shape)
        if m.shape != est.shape:
            raise ValueError(f"mask: shape {m.shape} matches neither {est.shape} nor {est.shape[:2]}")
        ok &= m
    return ok


def invalid_fraction(estimate, *, mask=None) -> float:
    """Fraction of (pixel, channel) values that are NaN, infinite, zero or negative."""
    est = np.asarray(estimate, dtype=np.float64)
    bad = ~(np.isfinite(est) & (est > 0))
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if est.ndim == 3 and m.shape == est.shape[:2]:
            m = np.broadcast_to(m[..., None], est.shape)
        return float(bad[m].mean()) if m.any() else 0.0
    return float(bad.mean())


def _log_residual(estimate, truth, mask):
    est, tru = _pair(estimate, truth)
    ok = _valid(est, tru, mask)
    if not ok.any():
        raise ValueError("estimate: no pixel where both estimate and truth are finite and > 0")
    d = np.where(ok, np.log2(np.where(ok, est, 1.0)) - np.log2(np.where(ok, tru, 1.0)), 0.0)
    offset = d[ok].mean()  # best global log-scale (least squares)
    return d - offset, ok


def log_radiance_rmse(estimate, truth, *, mask=None, per_channel: bool = False):
    """RMSE of ``log2(estimate) - log2(truth)`` (stops) after the best single global scale.

    Only pixels where both are finite and > 0 (and inside ``mask``, (H, W) or (H, W, C)) count;
    report :func:`invalid_fraction` alongside.  ``per_channel=True`` returns one value per
    channel (same global scale), as an array.
    """
    r, ok = _log_residual(estimate, truth, mask)
    if per_channel:
        if r.ndim != 3:
            raise ValueError("per_channel: needs (H, W, C) images")
        return np.array([np.sqrt(np.mean(r[..., c][ok[..., c]] ** 2)) for c in range(r.shape[2])])
    return float(np.sqrt(np.mean(r[ok] ** 2)))


def log_radiance_rmse_extremes(estimate, truth, *, fraction: float = 0.01, mask=None) -> dict[str, float]:
    """Log2 RMSE (stops, global scale fitted on all valid pixels) on the brightest and darkest
    ``fraction`` of pixels, ranked by true luminance (channel mean)."""
    if not 0 < fraction <= 0.5:
        raise ValueError(f"fraction: must be in (0, 0.5], got {fraction!r}")
    r, ok = _log_residual(estimate, truth, mask)
    tru = np.asarray(truth, dtype=np.float64)
    lum = tru.mean(axis=2) if tru.ndim == 3 else tru
    okp = ok.all(axis=2) if ok.ndim == 3 else ok
    vals = lum[okp]
    lo, hi = np.quantile(vals, [fraction, 1 - fraction])
    out = {}
    for name, sel in (("bright", okp & (lum >= hi)), ("dark", okp & (lum <= lo))):
        rr = r[sel]
        out[name] = float(np.sqrt(np.mean(rr**2)))
    return out


def response_rmse(inverse, true_inverse, *, align: str = "channel", levels=None) -> float:
    """RMSE (stops) of ``log2`` of an inverse response against the true one, over pixel levels.

    Compared levels: ``1 .. levels-2`` (the clipped ends carry no information) where the true
    inverse is > 0, or the boolean/integer selection ``levels``.  The free scale is removed by
    the least-squares offset of the log2 difference, per channel (``align="channel"``), for all
    channels at once (``"global"``), or not at all (``"none"``).
    """
    est = np.asarray(inverse, dtype=np.float64)
    tru = np.asarray(true_inverse, dtype=np.float64)
    if est.ndim == 1:
        est = est[:, None]
    if tru.ndim == 1:
        tru = tru[:, None]
    if est.shape[0] != tru.shape[0]:
        raise ValueError(f"inverse: {est.shape[0]} levels vs {tru.shape[0]} in true_inverse; use the same bit depth")
    if est.shape[1] != tru.shape[1]:
        if est.shape[1] == 1:
            est = np.repeat(est, tru.shape[1], axis=1)
        else:
            raise ValueError(f"inverse: {est.shape[1]} channels vs {tru.shape[1]} in true_inverse")
    if align not in ("channel", "global", "none"):
        raise ValueError(f"align={align!r} is not known; choose one of 'channel', 'global', 'none'")
    n = est.shape[0]
    sel = np.zeros(n, bool)
    if levels is None:
        sel[1:-1] = True
    else:
        lv = np.asarray(levels)
        if lv.dtype == bool:
            if lv.shape != (n,):
                raise ValueError(f"levels: boolean selection must have shape ({n},)")
            sel = lv.copy()
        else:
            sel[lv.astype(int)] = True
    ok = sel[:, None] & (tru > 0) & (est > 0) & np.isfinite(est)
    if not ok.any():
        raise ValueError("inverse: no level where both curves are > 0")
    d = np.where(ok, np.log2(np.where(ok, est, 1)) - np.log2(np.where(ok, tru, 1)), 0.0)
    if align == "channel":
        for c in range(d.shape[1]):
            if ok[:, c].any():
                d[:, c] -= d[ok[:, c], c].mean()
    elif align == "global":
        d -= d[ok].mean()
    return float(np.sqrt(np.mean(d[ok] ** 2)))


def hdr_scores(estimate, truth, *, mask=None) -> dict[str, float]:
    """All radiance scores in one dict: ``log2_rmse``, ``log2_rmse_c{i}``, ``bright1``,
    ``dark1`` and ``invalid_fraction``."""
    out = {"log2_rmse": log_radiance_rmse(estimate, truth, mask=mask)}
    est = np.asarray(estimate)
    if est.ndim == 3:
        for c, v in enumerate(log_radiance_rmse(estimate, truth, mask=mask, per_channel=True)):
            out[f"log2_rmse_c{c}"] = float(v)
    ext = log_radiance_rmse_extremes(estimate, truth, mask=mask)
    out["bright1"], out["dark1"] = ext["bright"], ext["dark"]
    out["invalid_fraction"] = invalid_fraction(estimate)
    return out


METRICS = table("""
log2_rmse        | lower  | stops    | hdr_scores    | log2 radiance RMSE after the one free global scale
log2_rmse_c0     | lower  | stops    | hdr_scores    | log2 radiance RMSE of the red channel
log2_rmse_c1     | lower  | stops    | hdr_scores    | log2 radiance RMSE of the green channel
log2_rmse_c2     | lower  | stops    | hdr_scores    | log2 radiance RMSE of the blue channel
bright1          | lower  | stops    | hdr_scores    | log2 radiance RMSE on the brightest 1 % of the pixels
dark1            | lower  | stops    | hdr_scores    | log2 radiance RMSE on the darkest 1 % of the pixels
invalid_fraction | lower  | fraction | hdr_scores    | fraction of pixels without a finite positive estimate
bracket_coverage | higher | fraction | -             | fraction of the pixels that at least one exposure measures (neither black nor saturated) in every channel
response_rmse    | lower  | stops    | response_rmse | RMSE of the recovered inverse response vs the true one (log2, per-channel scale removed)
""")
