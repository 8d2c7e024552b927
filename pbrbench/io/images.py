"""Every image format but EXR, read and written without loss: PNG (Pillow), TIFF (tifffile),
JPEG / BMP / TGA / PPM / PGM (Pillow), PFM (a small reader here: no installed library reads it)
and ``.npy`` (:func:`read_npy`, the one reader of array files: no pickle, a size limit).

Every reader looks at the header first (Pillow's and tifffile's lazy open, the ``.npy`` and PFM
headers) and refuses a file whose decoded pixels would exceed
:data:`~pbrbench.io.files.MAX_IMAGE_BYTES` before anything is allocated, so a decompression bomb
(a small file declaring a huge image) costs nothing.  Pillow's own guard,
``PIL.Image.MAX_IMAGE_PIXELS``, is set to half that many pixels when this module first opens a
file: Pillow then refuses outright only what is too large even at one byte a pixel, and the exact
check here decides the rest.  Every failure is one ``ValueError`` line naming the file.

16-bit colour PNGs: Pillow decodes them (zlib, filters, CRCs, interlacing) but keeps only the
high byte of each sample; :func:`read_png` asks Pillow's decoder for the high and the low bytes
of the same data (its raw modes ``;16B`` and ``;16L``) and joins them, so every bit is kept.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from pbrbench.io.files import MAX_IMAGE_BYTES, TooLarge, atomic_path, check_size, fmt_bytes

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}   # PNG colour type -> samples per pixel
PILLOW_SUFFIXES = (".jpg", ".jpeg", ".bmp", ".tga", ".ppm", ".pgm")

# Pillow's raw mode of a PNG -> (channels of the array read_png returns, bytes per sample)
_PNG_RAW = {"1": (1, 1), "L;2": (1, 1), "L;4": (1, 1), "L": (1, 1), "I;16B": (1, 2),
            "RGB": (3, 1), "RGB;16B": (3, 2), "LA": (2, 1), "LA;16B": (2, 2),
            "RGBA": (4, 1), "RGBA;16B": (4, 2),
            "P;1": (4, 1), "P;2": (4, 1), "P;4": (4, 1), "P": (4, 1)}   # palette: RGB(A)


def _pillow():
    """``PIL.Image`` with its pixel limit set to match :data:`MAX_IMAGE_BYTES`."""
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = MAX_IMAGE_BYTES // 2
    return Image


def _one_line(path, e: BaseException, what: str = "image") -> ValueError:
    """A decoder's exception as one line naming the file (no fix: the callers add theirs)."""
    text = " ".join(str(e).replace(f"'{path}'", "").replace(str(path), "").split())[:200] or type(e).__name__
    if "truncated" in text.lower():
        return ValueError(f"{path}: truncated {what} file ({text})")
    return ValueError(f"{path}: not a readable {what} ({text})")


def _open(path):
    """Pillow's lazy (header-only) open; a file Pillow refuses is one ``ValueError``."""
    Image = _pillow()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)   # the exact check follows
            return Image.open(path)
    except Image.DecompressionBombError as e:
        import re

        n = re.search(r"\((\d+) pixels\)", str(e))
        raise TooLarge(f"{path}: its header announces {n.group(1) if n else 'too many'} pixels, above the "
                         f"{MAX_IMAGE_BYTES // 2**20} MiB pbrbench decodes from one image; check the file or crop / "
                         "downsample it") from None
    except (OSError, ValueError, SyntaxError) as e:   # UnidentifiedImageError is an OSError
        raise _one_line(path, e) from None


def _decode(im, path, rawmode: str | None = None) -> np.ndarray:
    """The pixels of the lazily opened ``im`` (decoded with ``rawmode`` when given)."""
    try:
        if rawmode is not None:
            im.tile = [t._replace(args=rawmode) for t in im.tile]
        im.load()
        return np.asarray(im)
    except MemoryError:
        raise
    except Exception as e:  # noqa: BLE001 - a damaged file raises anything from the decoder
        raise _one_line(path, e) from None


# ----------------------------------------------------------------------------- PNG
def png_info(path: str | os.PathLike) -> dict:
    """The header of a PNG, read without decoding.

    Returns
    -------
    dict
        ``{"width", "height", "bit_depth", "colour_type", "interlace", "channels"}``.

    Raises
    ------
    ValueError
        One line naming the file when it is not a PNG.
    """
    import struct

    with open(path, "rb") as f:
        head = f.read(33)
    if head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR" or len(head) < 29:
        raise ValueError(f"{path}: not a PNG file (bad signature or no IHDR chunk); re-export it as PNG")
    w, h, depth, ctype, _, _, inter = struct.unpack(">IIBBBBB", head[16:29])
    return {"width": w, "height": h, "bit_depth": depth, "colour_type": ctype, "interlace": inter,
            "channels": _PNG_CHANNELS.get(ctype, 4)}


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG without loss (Pillow's decoder, every bit of 16-bit samples kept).

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    numpy.ndarray
        (H, W) grey, (H, W, 2) grey + alpha, (H, W, 3) RGB or (H, W, 4) RGBA; uint16 for 16-bit
        files and uint8 otherwise.  1/2/4-bit grey samples keep their values ``0 .. 2**depth - 1``;
        palette images are expanded to RGB, or RGBA when the file has a ``tRNS`` chunk.  No gamma or
        colour conversion is applied.

    Raises
    ------
    ValueError
        One line naming the file: not a PNG, damaged (CRC, truncated data), a palette index beyond
        the palette, or a header announcing more than :data:`MAX_IMAGE_BYTES` of pixels.
    """
    info = png_info(path)
    shape = (info["height"], info["width"], 4 if info["colour_type"] == 3 else info["channels"])
    nbytes = 2 if info["bit_depth"] == 16 else 1
    try:
        with _open(path) as im:
            im.verify()            # every chunk's CRC, the image data's included; nothing is decompressed
    except TooLarge:
        check_size(path, shape, nbytes)   # the exact message
        raise
    except ValueError:
        raise
    except Exception as e:  # noqa: BLE001 - Pillow raises SyntaxError, OSError, struct.error
        raise _one_line(path, e, "PNG") from None
    check_size(path, shape, nbytes)
    with _open(path) as im:
        if im.format != "PNG" or len(im.tile) != 1 or im.tile[0].args not in _PNG_RAW:
            raise ValueError(f"{path}: unsupported PNG ({im.format} {im.mode}); re-export it as 8- or 16-bit PNG")
        raw = im.tile[0].args
        if raw == "LA;16B":            # Pillow gives L, L, L, A; the 8-bit decoding of the same bytes holds them all
            b = _decode(im, path, "RGBA")
            return np.ascontiguousarray(b).view(">u2").astype(np.uint16)
        if raw in ("RGB;16B", "RGBA;16B"):
            hi = _decode(im, path)
            with _open(path) as again:
                lo = _decode(again, path, raw[:-1] + "L")   # the low byte of each big-endian sample
            return (hi.astype(np.uint16) << 8) | lo
        a = _decode(im, path)
        if raw == "I;16B":
            return a.astype(np.uint16)
        if raw in ("L;2", "L;4"):      # Pillow scales 2/4-bit grey to 0..255; the file holds 0..2**depth - 1
            return (a // (85 if raw == "L;2" else 17)).astype(np.uint8)
        if raw == "1":
            return a.astype(np.uint8)
        if raw.startswith("P"):
            return _palette(im, a, path)
        return np.ascontiguousarray(a, np.uint8)


def _palette(im, idx: np.ndarray, path) -> np.ndarray:
    pal = np.asarray(im.getpalette("RGB") or [], np.uint8).reshape(-1, 3)
    n = len(im.palette.palette) // 3 if im.palette is not None else len(pal)
    pal = pal[:max(n, 1)]
    if idx.max(initial=0) >= len(pal):
        raise ValueError(f"{path}: palette index {int(idx.max())} beyond the {len(pal)} palette entries")
    rgb = pal[idx]
    t = im.info.get("transparency")
    if t is None:
        return rgb
    alpha = np.full(len(pal), 255, np.uint8)
    if isinstance(t, bytes):
        t = np.frombuffer(t, np.uint8)[:len(pal)]
        alpha[:len(t)] = t
    else:
        alpha[int(t)] = 0
    return np.concatenate([rgb, alpha[idx][..., None]], axis=-1)


def read_pngs(paths) -> list[np.ndarray]:
    """:func:`read_png` of several files, in order."""
    return [read_png(p) for p in paths]


def write_png_exact(path: str | os.PathLike, a: np.ndarray, *, filters=(4,)) -> None:
    """Write a uint8 or uint16 array as a PNG without loss (bool arrays as 0 / 255 grey).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    a : numpy.ndarray
        (H, W), (H, W, 1), (H, W, 2), (H, W, 3) or (H, W, 4); uint8, uint16 or bool.
    filters : sequence of int
        The scanline filter of each row, cycled (0 None, 1 Sub, 2 Up, 3 Average, 4 Paeth), for the
        16-bit colour files; the others are written by Pillow, which chooses its filters itself.

    Notes
    -----
    Pillow writes 8-bit grey / grey + alpha / RGB / RGBA and 16-bit grey; it has no 16-bit colour
    mode, so 16-bit grey + alpha, RGB and RGBA are encoded here (zlib and the PNG filters, a
    few lines; :func:`read_png` reads them back through Pillow).
    """
    a = np.asarray(a)
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    if a.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"write_png_exact: dtype {a.dtype}; give uint8 or uint16 (scale and round first)")
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise ValueError(f"write_png_exact: shape {a.shape}; give (H, W) or (H, W, 1-4)")
    if a.dtype == np.uint8 or a.shape[2] == 1:
        Image = _pillow()
        img = np.ascontiguousarray(a[..., 0] if a.shape[2] == 1 else a)
        mode = "I;16" if a.dtype == np.uint16 else {1: "L", 2: "LA", 3: "RGB", 4: "RGBA"}[a.shape[2]]
        im = Image.frombuffer(mode, (img.shape[1], img.shape[0]), img.astype("<u2") if mode == "I;16" else img,
                              "raw", mode, 0, 1)
        im.save(path, format="PNG")
        return
    Path(path).write_bytes(_encode_png16(a, filters))


def _encode_png16(a: np.ndarray, filters) -> bytes:
    """A 16-bit grey + alpha, RGB or RGBA PNG (no library here writes them)."""
    import struct
    import zlib

    h, w, ch = a.shape
    rows = a.astype(">u2").reshape(h, -1).view(np.uint8).reshape(h, -1).astype(np.int16)
    bpp = ch * 2
    up = np.concatenate([np.zeros((1, rows.shape[1]), np.int16), rows[:-1]])
    left = np.concatenate([np.zeros((h, bpp), np.int16), rows[:, :-bpp]], axis=1)
    upleft = np.concatenate([np.zeros((h, bpp), np.int16), up[:, :-bpp]], axis=1)
    p = left + up - upleft
    pa, pb, pc = np.abs(p - left), np.abs(p - up), np.abs(p - upleft)
    preds = {0: np.zeros_like(rows), 1: left, 2: up, 3: (left + up) >> 1,
             4: np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, up, upleft))}
    ft = np.resize(np.asarray(filters, np.uint8), h)
    body = np.empty((h, rows.shape[1] + 1), np.uint8)
    body[:, 0] = ft
    for t in np.unique(ft):
        sel = ft == t
        body[sel, 1:] = ((rows[sel] - preds[int(t)][sel]) & 0xFF).astype(np.uint8)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 16, {2: 4, 3: 2, 4: 6}[ch], 0, 0, 0)
    return (PNG_SIGNATURE + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(body.tobytes(), 6))
            + chunk(b"IEND", b""))


def write_mask_png(path: str | os.PathLike, mask) -> None:
    """A boolean (H, W) mask as an 8-bit grey PNG: 255 inside, 0 outside."""
    write_png_exact(path, np.asarray(mask, bool))


def write_image(path: str | os.PathLike, a: np.ndarray) -> None:
    """Write an array without loss by the suffix of ``path``, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        ``.png`` (uint8 / uint16, :func:`write_png_exact`), ``.tif`` / ``.tiff`` (any dtype,
        tifffile), ``.npy`` (numpy) or ``.tga`` / ``.bmp`` (uint8, Pillow).
    a : numpy.ndarray
        (H, W) or (H, W, C).
    """
    suffix = Path(path).suffix.lower()
    a = np.asarray(a)
    with atomic_path(path) as tmp:
        if suffix == ".png":
            write_png_exact(tmp, a)
        elif suffix in (".tif", ".tiff"):
            import tifffile

            tifffile.imwrite(str(tmp), a, photometric="rgb" if a.ndim == 3 and a.shape[2] in (3, 4) else None)
        elif suffix == ".npy":
            with open(tmp, "wb") as f:
                np.save(f, a, allow_pickle=False)
        elif suffix in (".tga", ".bmp"):
            if a.dtype != np.uint8:
                raise ValueError(f"{path}: dtype {a.dtype}; {suffix} holds 8-bit images (write .png or .tif)")
            _pillow().fromarray(a).save(tmp, format={".tga": "TGA", ".bmp": "BMP"}[suffix])
        else:
            raise ValueError(f"{path}: cannot write {suffix!r} without loss; use .png, .tif, .npy, .tga or .exr")


# ----------------------------------------------------------------------------- any image
def read_npy(path: str | os.PathLike, *, where: str, limit: int = MAX_IMAGE_BYTES,
             what: str = "an array file") -> np.ndarray:
    """A real-valued array from the ``.npy`` file at ``path``, read without unpickling and with
    its header checked against the file size and ``limit`` bytes before anything is allocated;
    ``ValueError`` (prefixed with ``where``; ``what`` names the kind of file in the size message)
    otherwise.  The one ``.npy`` reader: scene data files, prediction files and images use it."""
    fmt = np.lib.format
    try:
        with open(path, "rb") as f:
            try:
                version = fmt.read_magic(f)
            except ValueError:
                f.seek(0)
                head = f.read(8)
                raise ValueError(f"{where}: not a NumPy .npy file (it starts with {head!r}); save the array with "
                                 "numpy.save") from None
            try:
                if version == (1, 0):
                    shape, fortran, dtype = fmt.read_array_header_1_0(f)
                else:
                    shape, fortran, dtype = fmt.read_array_header_2_0(f)
            except (ValueError, SyntaxError, TypeError) as exc:
                raise ValueError(f"{where}: damaged .npy header ({exc}); save the array again with numpy.save") from None
            if dtype.hasobject:
                raise ValueError(f"{where}: holds Python objects (dtype object, stored as a pickle); pbrbench never "
                                 "unpickles data files: save a numeric array, e.g. numpy.save(path, np.asarray(a, float))")
            if dtype.names is not None or dtype.subdtype is not None:
                raise ValueError(f"{where}: has the structured dtype {dtype}; save a plain numeric array")
            if dtype.kind == "c":
                raise ValueError(f"{where}: holds complex values (dtype {dtype}); save real values "
                                 "(np.real(a) or np.abs(a))")
            if dtype.kind not in "biuf":
                raise ValueError(f"{where}: dtype {dtype} is not a number type; save a float array")
            count = 1
            for n in shape:
                count *= int(n)
            nbytes = count * dtype.itemsize
            if nbytes > limit:
                raise ValueError(f"{where}: its header asks for {fmt_bytes(nbytes)} (shape {tuple(shape)}, {dtype}), above "
                                 f"the {fmt_bytes(limit)} limit for {what}; save a smaller array")
            left = os.fstat(f.fileno()).st_size - f.tell()
            if left < nbytes:
                raise ValueError(f"{where}: truncated: the header announces {nbytes} bytes of data (shape {tuple(shape)}, "
                                 f"{dtype}) but the file holds {left}; save the array again with numpy.save")
            try:
                f.seek(0)
                a = fmt.read_array(f, allow_pickle=False) if count else np.zeros(shape, dtype)
            except (ValueError, OSError) as exc:
                raise ValueError(f"{where}: cannot be read ({exc}); save the array again with numpy.save") from None
    except OSError as exc:
        raise ValueError(f"{where}: cannot be read ({exc.strerror or exc}); check the file's permissions") from None
    return np.asarray(a)


def _read_tiff(p: Path) -> np.ndarray:
    import tifffile

    try:
        with tifffile.TiffFile(str(p)) as tf:
            if not tf.series:
                raise ValueError("no image in the file")
            s = tf.series[0]
            check_size(p, s.shape, np.dtype(s.dtype).itemsize)
            return np.asarray(s.asarray())
    except ValueError as e:
        if str(p) in str(e):
            raise
        raise _one_line(p, e) from None
    except MemoryError:
        raise
    except Exception as e:  # noqa: BLE001 - tifffile raises its own errors on damaged files
        raise _one_line(p, e) from None


def _read_pillow(p: Path) -> np.ndarray:
    """JPEG, BMP, TGA, PPM, PGM through Pillow: grey, grey + alpha, RGB and RGBA as stored (uint8;
    16-bit grey as uint16), palette images expanded, other modes (CMYK, YCbCr, 1-bit) as RGB / grey."""
    with _open(p) as im:
        bands = len(im.getbands())
        mode = im.mode
        nbytes = 2 if mode.startswith("I;16") else 4 if mode in ("I", "F") else 1
        check_size(p, (im.size[1], im.size[0], 4 if mode == "P" else bands), nbytes)
        try:
            if mode == "P":
                im = im.convert("RGBA" if "transparency" in im.info else "RGB")
            elif mode == "1":
                im = im.convert("L")
            elif mode not in ("L", "LA", "RGB", "RGBA", "I;16", "I", "F"):
                im = im.convert("RGB")
        except MemoryError:
            raise
        except Exception as e:  # noqa: BLE001 - a damaged file raises anything from the decoder
            raise _one_line(p, e) from None
        a = _decode(im, p)
    return a.astype(np.uint16) if mode.startswith("I;16") else a


def _read_pfm(p: Path) -> np.ndarray:
    """A PFM file (``PF`` colour, ``Pf`` grey; float32, row 0 at the top), header checked."""
    with open(p, "rb") as f:
        kind = f.readline(16).strip()
        dims = f.readline(64).split()
        scale_line = f.readline(64)
        if kind not in (b"PF", b"Pf"):
            raise ValueError(f"{p}: not a PFM file (it starts with {kind[:8]!r}); write 'PF' or 'Pf' first")
        try:
            w, h = (int(x) for x in dims)
            scale = float(scale_line)
        except ValueError:
            raise ValueError(f"{p}: damaged PFM header (width, height and scale expected); write the file again") from None
        if w <= 0 or h <= 0 or scale == 0 or not np.isfinite(scale):
            raise ValueError(f"{p}: PFM header {w} x {h}, scale {scale}; write the file again")
        ch = 3 if kind == b"PF" else 1
        check_size(p, (h, w, ch), 4)
        n = w * h * ch
        left = os.fstat(f.fileno()).st_size - f.tell()
        if left < 4 * n:
            raise ValueError(f"{p}: truncated: the header announces {4 * n} bytes of data, the file holds {left}; "
                             "write the file again")
        a = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4", count=n)
    a = a.reshape(h, w, ch)[::-1].astype(np.float32)   # PFM stores the bottom row first
    return a[..., 0] if ch == 1 else a


def read_image(path: str | os.PathLike) -> np.ndarray:
    """An image or array file by its suffix, without loss.

    Parameters
    ----------
    path : str or os.PathLike
        ``.exr`` (float32, :func:`pbrbench.io.exr.read_exr_image`), ``.npy`` (as stored; no
        pickle), ``.png`` (uint8/uint16, :func:`read_png`), ``.tif``/``.tiff`` (as stored),
        ``.jpg``/``.jpeg``/``.bmp``/``.tga``/``.ppm``/``.pgm`` (uint8, 16-bit PGM uint16),
        ``.pfm`` (float32, row 0 at the top).

    Returns
    -------
    numpy.ndarray
        (H, W) or (H, W, C).

    Raises
    ------
    ValueError
        One line naming the file when it is missing, unreadable, of an unknown format or its
        header announces more than :data:`MAX_IMAGE_BYTES` of pixels.
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: no such file")
    suffix = p.suffix.lower()
    if suffix == ".exr":
        from pbrbench.io.exr import read_exr_image

        return read_exr_image(p)
    if suffix == ".npy":
        return read_npy(p, where=str(p), what="an image file")
    if suffix == ".png":
        return read_png(p)
    if suffix == ".pfm":
        return _read_pfm(p)
    if suffix in (".tif", ".tiff"):
        return _read_tiff(p)
    if suffix in PILLOW_SUFFIXES:
        return _read_pillow(p)
    raise ValueError(f"{p}: unknown image format {suffix!r}; use .exr, .npy, .png, .tif, .pfm, .jpg or .tga")
