"""Small display images, error maps and profile plots a task hands the report.

Pure functions of their arguments (no renderer, no plotting library): the report draws them.
"""

from __future__ import annotations

import math

import numpy as np

from pbrbench.tasks.common.inputs import block_mean


def display(a, max_size: int = 128) -> np.ndarray:
    """A small float32 copy of an image or map for the report (block-averaged to <= max_size)."""
    a = np.nan_to_num(np.asarray(a, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    factor = max(1, math.ceil(max(a.shape[:2]) / max_size))
    return block_mean(a, factor).astype(np.float32)


def display_map(a, mask=None, max_size: int = 128) -> np.ndarray:
    """Like :func:`display` for an error map: NaN outside ``mask`` is kept NaN (blank in the
    report) by averaging the valid values only."""
    a = np.asarray(a, np.float64)
    m = np.isfinite(a) if mask is None else (np.asarray(mask, bool) & np.isfinite(a))
    factor = max(1, math.ceil(max(a.shape[:2]) / max_size))
    num = block_mean(np.where(m, a, 0.0), factor)
    den = block_mean(m.astype(float), factor)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan).astype(np.float32)


def normals_display(n, mask=None, max_size: int = 128) -> np.ndarray:
    """Normals as display RGB ``(n + 1) / 2`` in [0, 1]; black outside ``mask``."""
    rgb = np.clip((np.asarray(n, np.float64) + 1.0) / 2.0, 0.0, 1.0)
    if mask is not None:
        rgb = np.where(np.asarray(mask, bool)[..., None], rgb, 0.0)
    return display(rgb, max_size)


def profile_plot(x, series: dict, xlabel: str, ylabel: str, **extra) -> dict:
    """Plot data in the :class:`JobResult` format, as plain lists of floats (NaN -> None)."""

    def clean(v):
        return [None if not np.isfinite(f) else float(f) for f in np.asarray(v, float).ravel()]

    out = {"x": clean(x), "series": {k: clean(v) for k, v in series.items()},
           "xlabel": xlabel, "ylabel": ylabel}
    out.update(extra)
    return out
