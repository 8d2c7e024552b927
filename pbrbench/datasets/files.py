"""File helpers of the data-set loaders (public: the infer command reads masks with them):
case-insensitive look-ups, numeric text tables, masks of any bit depth, integer -> float scaling."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".exr", ".npy", ".jpg", ".jpeg", ".bmp", ".ppm", ".pgm")


def find(folder: Path, *names: str) -> Path | None:
    """The first of ``names`` present in ``folder``, matched case-insensitively."""
    try:
        entries = {p.name.lower(): p for p in Path(folder).iterdir() if p.is_file()}
    except OSError:
        return None
    for n in names:
        p = entries.get(n.lower())
        if p is not None:
            return p
    return None


def find_stem(folder: Path, stem: str, suffixes=IMAGE_SUFFIXES) -> Path | None:
    """``<stem><suffix>`` for the first suffix present (case-insensitive)."""
    return find(folder, *(stem + s for s in suffixes))


def read_table(path: Path, columns: int | None = None) -> np.ndarray:
    """A whitespace- or comma-separated numeric table (blank lines and ``#`` comments skipped;
    CRLF line ends and a UTF-8 BOM are fine); ``ValueError`` naming the file and line."""
    rows = []
    text = Path(path).read_text(encoding="utf-8-sig", errors="replace")
    for i, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p for p in re.split(r"[\s,;]+", line) if p]
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise ValueError(f"{path}, line {i}: {line[:60]!r} is not a row of numbers") from None
        if columns is not None and len(vals) != columns:
            raise ValueError(f"{path}, line {i}: {len(vals)} values, expected {columns}")
        rows.append(vals)
    if not rows:
        raise ValueError(f"{path}: no numbers in the file")
    if len({len(r) for r in rows}) != 1:
        raise ValueError(f"{path}: rows of different lengths")
    return np.asarray(rows, np.float64)


def read_lines(path: Path) -> list[str]:
    text = Path(path).read_text(encoding="utf-8-sig", errors="replace")
    return [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("#")]


def read_mask(path: Path, shape=None) -> np.ndarray:
    """A mask image (any bit depth, grey or colour): non-zero in any channel = inside."""
    from pbrbench.io import read_image

    a = np.asarray(read_image(path))
    if a.ndim == 3:   # grey + alpha: the grey channel; RGB(A): any colour channel
        a = a[..., 0] > 0 if a.shape[2] == 2 else (a[..., :3] > 0).any(axis=-1)
    else:
        a = a > 0
    if shape is not None and a.shape != tuple(shape):
        raise ValueError(f"{path}: mask shape {a.shape}, the images are {tuple(shape)}")
    return a


def to_float(a: np.ndarray, path) -> np.ndarray:
    """Integer pixel values scaled to [0, 1] by their type's range (16-bit / 65535, 8-bit / 255);
    float arrays unchanged.  No gamma: the data sets read here are linear."""
    a = np.asarray(a)
    if a.dtype == np.uint16:
        return a.astype(np.float64) / 65535.0
    if a.dtype == np.uint8:
        return a.astype(np.float64) / 255.0
    if a.dtype.kind == "f":
        return a.astype(np.float64)
    raise ValueError(f"{path}: pixel type {a.dtype}; expected 8- or 16-bit or float images")
