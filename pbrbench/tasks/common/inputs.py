"""How a task makes an algorithm's inputs from a ground truth: grey levels, camera noise with a
per-job generator, block means, erosion, and the hashable job parameters.

Pure functions of their arguments (no renderer).
"""

from __future__ import annotations

import zlib

import numpy as np

from pbrbench.tasks.base import Job


def as_param(a) -> tuple:
    """A float array as a nested tuple of rounded floats (hashable, for :class:`Job` params)."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        return round(float(a), 9)
    return tuple(as_param(x) for x in a)


def pixel_size(half_width: float, width: int) -> float:
    """World size of one pixel of an orthographic film ``[-half_width, half_width]`` wide."""
    return 2.0 * float(half_width) / int(width)


def grey(img) -> np.ndarray:
    """Channel mean of an (..., 3) image (the grey level used by every task); 2-D passes through."""
    a = np.asarray(img, np.float64)
    return a.mean(axis=-1) if a.ndim >= 3 and a.shape[-1] in (3, 4) else a


def job_rng(job: Job, seed: int) -> np.random.Generator:
    """A generator determined by ``seed`` and the job's key (stable across processes)."""
    return np.random.default_rng([int(seed), zlib.crc32(job.key.encode())])


def add_noise(images, level: float, rng: np.random.Generator, *, peak: float | None = None) -> np.ndarray:
    """Images plus Gaussian noise of standard deviation ``level`` x ``peak`` (default: the
    stack's maximum), clipped at 0 -- a linear camera with read noise ``level`` of full scale."""
    a = np.asarray(images, np.float64)
    if level <= 0:
        return a.copy()
    peak = float(a.max()) if peak is None else float(peak)
    return np.maximum(a + rng.normal(0.0, level * peak, a.shape), 0.0)


def block_mean(a: np.ndarray, factor: int) -> np.ndarray:
    """Average ``factor`` x ``factor`` blocks of an (H, W[, C]) array (edges cropped)."""
    if factor <= 1:
        return a
    h, w = a.shape[0] // factor * factor, a.shape[1] // factor * factor
    a = a[:h, :w]
    shp = (h // factor, factor, w // factor, factor) + a.shape[2:]
    return a.reshape(shp).mean(axis=(1, 3))


def erode(mask, iterations: int = 1) -> np.ndarray:
    from scipy import ndimage

    m = np.asarray(mask, bool)
    if iterations <= 0:
        return m.copy()
    return ndimage.binary_erosion(m, iterations=iterations, border_value=0)


def visible_surface(gt) -> np.ndarray:
    """The evaluation domain: pixels wholly covered by one object (coverage 1, the same object id
    as their eight neighbours, not an emitter or the background).

    The eight neighbours, not four: with the box reconstruction filter a pixel's samples cover
    its own square, and an object whose corner cuts that square shows its id at a diagonal
    neighbour only.  In the rooms at draft a ceiling pixel diagonal to the emitter had its corner
    in the source: one sample in 15 saw the emitter's radiance, 7.5 against 0.75 for the brightest
    surface pixel, and the black room's scores moved far beyond their standard errors between
    render seeds.  The ground truth's ``mask`` adds that the footprint-averaged shape index
    equal the point-sampled one, which leaves out whole objects of some scenes (in the rooms the
    back wall and the boxes); the radiance of a pixel inside one object's outline is a clean
    comparison whatever that test says."""
    obj = np.asarray(gt["object_id"]).astype(int) if "object_id" in gt else None
    if obj is None or "coverage" not in gt:
        return gt.mask
    H, W = obj.shape
    pad = np.pad(obj, 1, mode="edge")
    same = np.ones(obj.shape, bool)
    for di in range(3):
        for dj in range(3):
            same &= pad[di:di + H, dj:dj + W] == obj
    return (np.asarray(gt["coverage"]) > 0.999) & same & (obj > 0)
