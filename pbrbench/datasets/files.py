"""File helpers of the data-set loaders (public: the infer command reads masks with them):
case-insensitive look-ups, numeric text tables, masks of any bit depth, integer -> float scaling,
and the checked reading of one image file (:func:`load_image`).

Rules shared by the loaders: a file that cannot be used (missing, empty, unreadable, an image
header larger than :data:`MAX_VALUES`, pickled or non-numeric arrays, NaN or inf values where
numbers are measured) raises :class:`pbrbench.errors.UserError` with one line naming the file
and the fix; data that loads but may be wrong (a saturated or black image in a stack, light
directions that are not unit length) gives a :class:`DataWarning` of one line and is kept.
"""

from __future__ import annotations

import contextlib
import re
import struct
import warnings
from pathlib import Path

import numpy as np

from pbrbench.errors import UserError

MAX_VALUES = 200_000_000   # values (pixels x channels) of one image; larger headers are refused
MAX_STACK_BYTES = 16 * 2**30   # a stack of images as float64


class DataWarning(UserWarning):
    """Data that loads but may be wrong (one line naming the file; the loaders keep the data)."""


def warn(message: str) -> None:
    """Emit ``message`` as a :class:`DataWarning` (one line)."""
    warnings.warn(" ".join(str(message).split()), DataWarning, stacklevel=3)

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".exr", ".npy", ".jpg", ".jpeg", ".bmp", ".tga", ".ppm", ".pgm", ".pfm")


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
    """The non-blank, non-comment lines of a text file, stripped; ``UserError`` when unreadable."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig", errors="replace")
    except OSError as e:
        raise UserError(f"{path}: cannot read ({e.strerror or e}); check the file and its permissions") from None
    return [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("#")]


def read_mask(path: Path, shape=None) -> np.ndarray:
    """A mask image (any bit depth, grey or colour): non-zero in any channel = inside.

    ``UserError`` naming the file when it is unreadable, holds NaN / inf, or has no pixel
    inside; ``ValueError`` when its shape is not ``shape``."""
    a = load_image(path, "mask")
    if a.ndim == 3:   # grey + alpha: the grey channel; RGB(A): any colour channel
        a = a[..., 0] > 0 if a.shape[2] == 2 else (a[..., :3] > 0).any(axis=-1)
    else:
        a = a > 0
    if shape is not None and a.shape != tuple(shape):
        raise ValueError(f"{path}: mask shape {a.shape}, the images are {tuple(shape)}; give a mask of the images' size")
    if not a.any():
        raise UserError(f"{path}: no pixel inside the mask (all zero); mark the object non-zero")
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


def _header_values(path: Path) -> int | None:
    """The number of values (pixels x channels) an image file's header announces, when it is
    cheap to read (PNG, NumPy, TIFF, JPEG / BMP / PPM, PFM); None when unknown."""
    suffix = path.suffix.lower()
    if suffix == ".png":
        with open(path, "rb") as f:
            head = f.read(33)
        if len(head) >= 26 and head[12:16] == b"IHDR":
            w, h, _, ctype = struct.unpack(">IIBB", head[16:26])
            return w * h * {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(ctype, 4)
        return None
    if suffix == ".npy":
        with open(path, "rb") as f:
            try:
                version = np.lib.format.read_magic(f)
                shape, _, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                                   else np.lib.format.read_array_header_2_0(f))
            except Exception as e:  # noqa: BLE001 - any damage of the header
                raise UserError(f"{path}: not a readable .npy file ({_brief(e)}); save it with numpy.save") from None
        if dtype.hasobject:
            raise UserError(f"{path}: a pickled object array; save plain numbers with numpy.save(path, "
                            "numpy.asarray(a, float))")
        return int(np.prod(shape, dtype=np.float64))
    if suffix in (".tif", ".tiff"):
        import tifffile

        with tifffile.TiffFile(str(path)) as tf:
            return int(np.prod(tf.series[0].shape, dtype=np.float64)) if tf.series else None
    if suffix in (".jpg", ".jpeg", ".bmp", ".tga", ".ppm", ".pgm"):
        from PIL import Image

        with Image.open(path) as im:
            return im.size[0] * im.size[1] * max(1, len(im.getbands()))
    if suffix == ".pfm":
        with open(path, "rb") as f:
            kind = f.readline(16).strip()
            dims = f.readline(64).split()
        if len(dims) == 2:
            return int(dims[0]) * int(dims[1]) * (3 if kind == b"PF" else 1)
    return None


def _brief(e: BaseException) -> str:
    return " ".join(f"{type(e).__name__}: {e}".split())[:200]


@contextlib.contextmanager
def quiet_stderr():
    """What C libraries print on descriptors 1 and 2 held back (:func:`pbrbench.io.quiet_output`);
    yields a list that receives the first line held back."""
    from pbrbench.io import quiet_output

    with quiet_output() as held:
        yield held


def load_image(path, what: str = "image") -> np.ndarray:
    """One image or array file read with :func:`pbrbench.io.read_image`, every failure a
    one-line :class:`~pbrbench.errors.UserError` naming the file: missing, empty (0 bytes),
    unreadable or damaged, pickled, or a header announcing more than :data:`MAX_VALUES` values.
    Float pixels must be finite."""
    from pbrbench.io import TooLarge, read_image

    path = Path(path)
    try:
        if not path.is_file():
            raise UserError(f"{path}: no such file; check the {what} file name")
        if path.stat().st_size == 0:
            raise UserError(f"{path}: an empty file (0 bytes); copy the {what} again")
        n = _header_values(path)
        if n is not None and n > MAX_VALUES:
            raise UserError(f"{path}: the header announces {n:.3g} values, more than the {MAX_VALUES:.3g} pbrbench "
                            f"reads; check the file or crop / downsample the {what}")
        if path.suffix.lower() == ".exr":
            with quiet_stderr():
                a = np.asarray(read_image(path))
        else:
            a = np.asarray(read_image(path))
    except UserError:
        raise
    except TooLarge as e:
        raise UserError(str(e)) from None
    except MemoryError:
        raise UserError(f"{path}: too large to load into memory; crop or downsample the {what}") from None
    except PermissionError:
        raise UserError(f"{path}: permission denied; make the {what} readable") from None
    except Exception as e:  # noqa: BLE001 - decoders raise anything on damaged data
        msg = str(e) if isinstance(e, ValueError) and str(path) in str(e) else f"{path}: {_brief(e)}"
        raise UserError(f"{' '.join(msg.split())}; not a readable {what}: re-export it (PNG, TIFF, EXR, NPY)") from None
    if a.dtype.hasobject or a.dtype.kind not in "buif":
        raise UserError(f"{path}: {a.dtype} values; save the {what} as numbers (8/16-bit integers or float)")
    if a.ndim not in (2, 3) or a.size == 0:
        raise UserError(f"{path}: array of shape {a.shape}; an {what} is (H, W) or (H, W, C)")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        bad = int((~np.isfinite(a)).sum())
        raise UserError(f"{path}: {bad} NaN or infinite value(s); replace them (e.g. by 0) and mark the pixels "
                        "invalid in the mask")
    return a


def table(path, columns=None, what: str = "values") -> np.ndarray:
    """:func:`read_table` with every failure a one-line ``UserError``, and every number finite."""
    path = Path(path)
    try:
        t = read_table(path, columns)
    except ValueError as e:
        raise UserError(f"{e}; write {what} as numbers, one row per line") from None
    except OSError as e:
        raise UserError(f"{path}: cannot read ({_brief(e)})") from None
    bad = np.flatnonzero(~np.isfinite(t).all(axis=1))
    if bad.size:
        raise UserError(f"{path}, row {bad[0] + 1}: a NaN or infinite value; give finite {what}")
    return t
