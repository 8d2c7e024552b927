"""Previews: linear images tone-mapped to 8-bit sRGB PNGs (the IEC 61966-2-1 encoding, equal to
colour-science's to the last bit: a test checks it), normals as colours, scalar maps with a
colour bar (matplotlib).  Previews are for looking at, never read back for scoring; every
writer is atomic."""

from __future__ import annotations

import os

import numpy as np

from pbrbench.io.files import atomic_path


def srgb_encode(x: np.ndarray) -> np.ndarray:
    r"""Linear [0, 1] -> sRGB-encoded [0, 1], the inverse EOTF of IEC 61966-2-1:

    .. math:: V = 12.92\,L \ (L \le 0.0031308), \qquad V = 1.055\,L^{1/2.4} - 0.055 \ \text{otherwise}

    Written out rather than taken from colour-science (the same values, bit for bit, which a
    test checks): ``import colour`` imports its plotting package and matplotlib, 1.0-1.4 s in
    every process that writes a preview (each pool worker, each command-line run)."""
    a = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1.0 / 2.4) - 0.055)


def tonemap(img: np.ndarray, *, percentile: float = 99.5, exposure: float | None = None) -> np.ndarray:
    """Linear radiance -> 8-bit sRGB preview; the ``percentile`` of the image maps to white.

    Parameters
    ----------
    img : numpy.ndarray
        Linear values; NaN and infinities count as 0.
    percentile : float
        The percentile of the positive values that maps to white (when ``exposure`` is None).
    exposure : float, optional
        The factor applied before encoding.

    Returns
    -------
    numpy.ndarray
        uint8, the shape of ``img``.
    """
    a = np.nan_to_num(np.asarray(img, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    if exposure is None:
        pos = a[a > 0]
        white = np.percentile(pos, percentile) if pos.size else 1.0
        exposure = 1.0 / white if white > 0 else 1.0
    return (srgb_encode(a * exposure) * 255 + 0.5).astype(np.uint8)


def write_png(path: str | os.PathLike, rgb8: np.ndarray) -> None:
    """Write an 8-bit (H, W), (H, W, 3) or (H, W, 4) array as PNG (matplotlib's writer)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg

    a = np.asarray(rgb8)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    with atomic_path(path) as tmp:
        mpimg.imsave(str(tmp), a, format="png")


def write_preview(path: str | os.PathLike, img: np.ndarray, **kw) -> None:
    """Tone-mapped sRGB PNG of a linear image (``kw``: those of :func:`tonemap`)."""
    write_png(path, tonemap(img, **kw))


def write_normals_png(path: str | os.PathLike, normals: np.ndarray, mask: np.ndarray | None = None) -> None:
    """Normals as RGB: ``(n + 1) / 2`` (x right = red, y up = green, z toward camera = blue)."""
    rgb = (np.clip((np.asarray(normals) + 1) / 2, 0, 1) * 255 + 0.5).astype(np.uint8)
    if mask is not None:
        rgb[~np.asarray(mask, bool)] = 0
    write_png(path, rgb)


def write_colormap_png(path: str | os.PathLike, data: np.ndarray, *, label: str = "", cmap: str = "viridis",
                       mask: np.ndarray | None = None, vmin=None, vmax=None) -> None:
    """A scalar map (depth, error) with a colour bar, as a small matplotlib figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.asarray(data, np.float64).copy()
    if mask is not None:
        d[~np.asarray(mask, bool)] = np.nan
    h, w = d.shape
    fig, ax = plt.subplots(figsize=(4.2, 4.0 * h / w), dpi=100)
    im = ax.imshow(d, cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
    ax.set_axis_off()
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    if label:
        cb.set_label(label)
    fig.tight_layout()
    try:
        with atomic_path(path) as tmp:
            fig.savefig(str(tmp), format="png")
    finally:
        plt.close(fig)
