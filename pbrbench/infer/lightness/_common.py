"""Shared pieces of the lightness methods: option checks and the constant of integration."""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_number

__all__ = ["ANCHORS", "anchor_reflectance", "check_percentile", "check_threshold"]

ANCHORS = ("brightest", "mean")


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
