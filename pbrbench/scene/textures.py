"""Albedo textures as NumPy arrays, in image orientation (row 0 = top, i.e. +v / +y).

The Mitsuba builder flips them vertically (a bitmap's row 0 lands at v = 0, the bottom), so the
albedo AOV of a front-facing rectangle equals these arrays exactly.
"""

from __future__ import annotations

import os

import numpy as np

from pbrbench.scene import spec as S


def mondrian(t: S.MondrianTexture) -> np.ndarray:
    """(R, R, 3) float32: a ``patches`` x ``patches`` grid of random papers (seeded)."""
    rng = np.random.default_rng(t.seed)
    n = t.patches
    if t.colour:
        vals = rng.uniform(t.low, t.high, (n, n, 3))
    else:
        vals = np.repeat(rng.uniform(t.low, t.high, (n, n, 1)), 3, axis=2)
    if t.white:
        i, j = rng.integers(0, n, 2)
        vals[i, j] = t.high
    # patch edges fall on texel boundaries
    edges = np.linspace(0, t.resolution, n + 1).round().astype(int)
    idx = np.searchsorted(edges, np.arange(t.resolution), side="right") - 1
    return vals[idx][:, idx].astype(np.float32)


def image(t: S.ImageTexture, base_dir: str) -> np.ndarray:
    """The albedo image of ``t`` (read safely and checked: :mod:`pbrbench.scene.data`)."""
    from pbrbench.scene.data import load_data

    return load_data(base_dir, t.path, "texture", where=f"texture {os.path.join(base_dir, t.path)}")


def texture_array(t, base_dir: str) -> np.ndarray:
    if isinstance(t, S.MondrianTexture):
        return mondrian(t)
    if isinstance(t, S.ImageTexture):
        return image(t, base_dir)
    raise TypeError(t)
