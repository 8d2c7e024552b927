"""Image I/O: float32 multichannel OpenEXR (lossless, bit-exact), lossless PNG of any bit depth,
PNG previews, any image file by suffix, and the public loader of renders (:func:`load_render`).

The OpenEXR Python API changed within 3.x; this module is the only place that touches it.
Channels are stored one by one under their full names (``radiance.R``, ``normals.X``,
``depth.Z``): arrays (H, W, 3) map to the suffixes of :data:`SUFFIXES`, arrays (H, W) to ``.Y``.

Every writer here is atomic: the data goes to a temporary file beside the target, which is
renamed over it only once complete, so a full disk or a kill mid-write never leaves a partial
file under the final name (:func:`atomic_path`).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from pathlib import Path

import numpy as np

SUFFIXES = {
    "normals": ("X", "Y", "Z"),
    "position": ("X", "Y", "Z"),
}
RGB = ("R", "G", "B")


def _suffixes(name: str, nch: int) -> tuple[str, ...]:
    base = name.rsplit(".", 1)[-1] if "." in name else name
    if nch == 3:
        return SUFFIXES.get(base, RGB)
    return tuple(f"C{i}" for i in range(nch))


def flatten_channels(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """{name: (H, W[, C]) array} -> {channel name: (H, W) float32 array}."""
    out = {}
    for name, a in arrays.items():
        a = np.asarray(a)
        if a.dtype == bool:
            a = a.astype(np.float32)
        if a.dtype != np.float32:
            a = a.astype(np.float32)
        if a.ndim == 2:
            out[f"{name}.Y"] = np.ascontiguousarray(a)
        elif a.ndim == 3:
            for c, sfx in enumerate(_suffixes(name, a.shape[2])):
                out[f"{name}.{sfx}"] = np.ascontiguousarray(a[..., c])
        else:
            raise ValueError(f"array {name!r} has shape {a.shape}; expected (H, W) or (H, W, C)")
    return out


def group_channels(channels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Inverse of :func:`flatten_channels`."""
    groups: dict[str, dict[str, np.ndarray]] = {}
    for full, a in channels.items():
        name, sfx = full.rsplit(".", 1)
        groups.setdefault(name, {})[sfx] = a
    out = {}
    for name, chans in groups.items():
        if set(chans) == {"Y"}:
            out[name] = chans["Y"]
            continue
        for order in (RGB, ("X", "Y", "Z")):
            if set(chans) == set(order):
                out[name] = np.stack([chans[s] for s in order], axis=-1)
                break
        else:
            keys = sorted(chans, key=lambda s: int(s[1:]) if s[1:].isdigit() else s)
            out[name] = np.stack([chans[k] for k in keys], axis=-1)
    return out


# ----------------------------------------------------------------------------- atomic writes
@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path`` (same suffix); on success it replaces ``path`` in one
    rename, on any error it is removed.  Errors (OSError) propagate unchanged."""
    p = Path(path)
    tmp = p.with_name(f".tmp-{os.getpid()}-{secrets.token_hex(3)}-{p.name}")
    try:
        yield tmp
        if not tmp.exists():
            raise OSError(f"{tmp}: the writer produced no file")
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)


def copy_file(src: str | os.PathLike, dst: str | os.PathLike) -> Path:
    """Copy ``src`` to ``dst`` atomically (``dst`` is whole or untouched)."""
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)
        if os.path.getsize(tmp) != os.path.getsize(src):
            raise OSError(f"{dst}: copy is incomplete")
    return Path(dst)


def write_exr(path: str | os.PathLike, arrays: dict[str, np.ndarray], header: dict | None = None) -> None:
    """Write named float32 arrays to a ZIP-compressed (lossless) scanline EXR (atomically)."""
    import OpenEXR

    chans = flatten_channels(arrays)
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if header:
        hdr.update(header)
    with atomic_path(path) as tmp:
        try:
            with OpenEXR.File(hdr, chans) as f:
                f.write(str(tmp))
        except OSError:
            raise
        except Exception as exc:  # the OpenEXR bindings raise RuntimeError for I/O failures
            raise OSError(f"cannot write the EXR file ({exc})") from exc


def write_exr_image(path: str | os.PathLike, image: np.ndarray) -> None:
    """One float32 image as a plain EXR any program reads: channel ``Y`` for (H, W), ``R G B``
    (and ``A``) for (H, W, 3) / (H, W, 4), ZIP-compressed (lossless)."""
    import OpenEXR

    a = np.asarray(image, np.float32)
    if a.ndim == 2:
        chans = {"Y": np.ascontiguousarray(a)}
    elif a.ndim == 3 and a.shape[2] in (3, 4):
        chans = {c: np.ascontiguousarray(a[..., i]) for i, c in enumerate("RGBA"[:a.shape[2]])}
    else:
        raise ValueError(f"write_exr_image: shape {a.shape}; give (H, W), (H, W, 3) or (H, W, 4)")
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, chans) as f:
        f.write(str(path))


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read an EXR written by :func:`write_exr` back into named float32 arrays."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        chans = {name: np.array(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
    return group_channels(chans)


# ----------------------------------------------------------------------------- previews
def srgb_encode(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> sRGB-encoded [0, 1] (IEC 61966-2-1, colour-science's inverse EOTF)."""
    import colour

    return np.asarray(colour.cctf_encoding(np.clip(x, 0.0, 1.0), function="sRGB"), dtype=np.float64)


def tonemap(img: np.ndarray, *, percentile: float = 99.5, exposure: float | None = None) -> np.ndarray:
    """Linear radiance -> 8-bit sRGB preview; the ``percentile`` of the image maps to white."""
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
    """Tone-mapped sRGB PNG of a linear image."""
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


def ensure_dir(p: str | os.PathLike) -> Path:
    p = Path(p)
    p.mkdir(parents=True, exist_ok=True)
    return p


# ----------------------------------------------------------------------------- PNG, lossless
# A small PNG codec (ISO/IEC 15948): every colour type, bit depths 1-16, Adam7 interlacing,
# CRC-checked.  Pillow and imageio read 16-bit colour PNGs as 8 bits; this reader keeps every
# bit.  When OpenCV is installed it decodes the plain cases (8/16-bit grey, RGB, RGBA, not
# interlaced) faster; the result is the same array (tests/test_io.py compares the two).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def _png_chunks(path) -> tuple[dict, bytes, bytes | None, bytes | None]:
    import struct
    import zlib

    data = Path(path).read_bytes()
    if data[:8] != PNG_SIGNATURE:
        raise ValueError(f"{path}: not a PNG file (bad signature)")
    pos, hdr, idat, plte, trns = 8, None, [], None, None
    while pos + 8 <= len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + n]
        if len(body) < n or pos + 12 + n > len(data):
            raise ValueError(f"{path}: truncated PNG ({kind.decode('latin-1')} chunk cut short)")
        (crc,) = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError(f"{path}: corrupt PNG (CRC mismatch in the {kind.decode('latin-1')} chunk)")
        pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, ctype, comp, filt, inter = struct.unpack(">IIBBBBB", body)
            if ctype not in _PNG_CHANNELS or comp != 0 or filt != 0 or inter not in (0, 1):
                raise ValueError(f"{path}: unsupported PNG header (colour type {ctype}, compression {comp}, "
                                 f"filter {filt}, interlace {inter})")
            hdr = {"width": w, "height": h, "bit_depth": depth, "colour_type": ctype, "interlace": inter,
                   "channels": _PNG_CHANNELS[ctype]}
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"PLTE":
            plte = body
        elif kind == b"tRNS":
            trns = body
        elif kind == b"IEND":
            break
    if hdr is None or not idat:
        raise ValueError(f"{path}: not a complete PNG (no IHDR or IDAT chunk)")
    try:
        raw = zlib.decompress(b"".join(idat))
    except zlib.error as e:
        raise ValueError(f"{path}: corrupt PNG image data ({e})") from None
    return hdr, raw, plte, trns


def png_info(path) -> dict:
    """``{"width", "height", "bit_depth", "colour_type", "interlace", "channels"}`` of a PNG."""
    return _png_chunks(path)[0]


def _unfilter(rows: list[np.ndarray], bpp: int) -> list[np.ndarray]:
    """Undo the PNG scanline filters of several images of one size at once.

    ``rows``: per image, a (h, 1 + rowbytes) uint8 array (filter byte + filtered bytes).  Rows
    whose filters are all None/Sub/Up are undone row by row (vectorised along the row); Average
    and Paeth depend on the reconstructed left neighbour, so they are undone along anti-diagonals
    of pixels (every pixel of a diagonal depends only on the previous two diagonals), for all
    images together.
    """
    h, rb1 = rows[0].shape
    rb = rb1 - 1
    g = rb // bpp
    k = len(rows)
    data = np.stack(rows, axis=1)                       # (h, K, 1 + rowbytes)
    ft = data[:, :, 0]
    if ft.max(initial=0) > 4:
        raise ValueError(f"unknown PNG filter type {int(ft.max())}")
    f = data[:, :, 1:].reshape(h, k, g, bpp)
    if ft.max(initial=0) <= 2:
        out = np.empty((h, k, g, bpp), np.uint8)
        prev = np.zeros((k, g, bpp), np.uint8)
        for r in range(h):
            cur = f[r].copy()
            sub, up = ft[r] == 1, ft[r] == 2
            if sub.any():
                cur[sub] = (np.cumsum(cur[sub], axis=1, dtype=np.uint32) & 0xFF).astype(np.uint8)
            if up.any():
                cur[up] = cur[up] + prev[up]
            out[r] = cur
            prev = out[r]
        return [out[:, i].reshape(h, rb) for i in range(k)]
    n_diag = h + g - 1
    rr = np.broadcast_to(np.arange(h)[:, None], (h, g))
    dd = rr + np.arange(g)[None, :]
    fs = np.zeros((n_diag, h, k, bpp), np.uint8)        # filtered bytes, diagonal-major
    fs[dd, rr] = f.transpose(0, 2, 1, 3)
    s = np.zeros((n_diag + 2, h + 1, k, bpp), np.int16)  # reconstructed; zero borders
    is1, is2, is3, is4 = ((ft == t)[:, :, None] for t in (1, 2, 3, 4))
    for d in range(n_diag):
        r0, r1 = max(0, d - g + 1), min(h - 1, d)
        sl = slice(r0, r1 + 1)
        a = s[d + 1, r0 + 1:r1 + 2]    # left
        b = s[d + 1, r0:r1 + 1]        # up
        c = s[d, r0:r1 + 1]            # up-left
        p = a + b - c
        pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
        pred = np.where(is4[sl], paeth, np.where(is3[sl], (a + b) >> 1,
                                                  np.where(is2[sl], b, np.where(is1[sl], a, 0))))
        s[d + 2, r0 + 1:r1 + 2] = (fs[d, sl] + pred) & 0xFF
    out = s[dd + 2, rr + 1].astype(np.uint8)            # (h, g, K, bpp)
    return [out[:, :, i].reshape(h, rb) for i in range(k)]


def _unpack(rows: np.ndarray, w: int, ch: int, depth: int) -> np.ndarray:
    h = rows.shape[0]
    if depth == 16:
        return rows.reshape(h, -1).view(">u2")[:, :w * ch].astype(np.uint16).reshape(h, w, ch)
    if depth == 8:
        return rows[:, :w * ch].reshape(h, w, ch)
    per = 8 // depth
    shifts = (8 - depth * (np.arange(per) + 1)).astype(np.uint8)
    vals = (rows[:, :, None] >> shifts) & ((1 << depth) - 1)
    return vals.reshape(h, -1)[:, :w * ch].reshape(h, w, ch).astype(np.uint8)


def _decode(hdr, raw: bytes) -> np.ndarray:
    w, h, depth, ch = hdr["width"], hdr["height"], hdr["bit_depth"], hdr["channels"]
    bpp = max(1, ch * depth // 8)
    buf = np.frombuffer(raw, np.uint8)
    dtype = np.uint16 if depth == 16 else np.uint8
    if not hdr["interlace"]:
        rb = (w * ch * depth + 7) // 8
        if buf.size < h * (rb + 1):
            raise ValueError("truncated PNG image data")
        rows = _unfilter([buf[:h * (rb + 1)].reshape(h, rb + 1)], bpp)[0]
        return _unpack(rows, w, ch, depth)
    out = np.zeros((h, w, ch), dtype)
    pos = 0
    for xs, ys, dx, dy in _ADAM7:
        pw, ph = (w - xs + dx - 1) // dx, (h - ys + dy - 1) // dy
        if pw <= 0 or ph <= 0:
            continue
        rb = (pw * ch * depth + 7) // 8
        n = ph * (rb + 1)
        if buf.size < pos + n:
            raise ValueError("truncated PNG image data")
        rows = _unfilter([buf[pos:pos + n].reshape(ph, rb + 1)], bpp)[0]
        out[ys::dy, xs::dx] = _unpack(rows, pw, ch, depth)
        pos += n
    return out


def _expand(hdr, a: np.ndarray, plte, trns, path) -> np.ndarray:
    if hdr["colour_type"] == 3:
        if plte is None:
            raise ValueError(f"{path}: palette PNG without a PLTE chunk")
        pal = np.frombuffer(plte, np.uint8).reshape(-1, 3)
        idx = a[..., 0].astype(np.intp)
        if idx.max(initial=0) >= len(pal):
            raise ValueError(f"{path}: palette index {int(idx.max())} beyond the {len(pal)} palette entries")
        rgb = pal[idx]
        if trns is not None:
            alpha = np.full(len(pal), 255, np.uint8)
            t = np.frombuffer(trns, np.uint8)[:len(pal)]
            alpha[:len(t)] = t
            rgb = np.concatenate([rgb, alpha[idx][..., None]], axis=-1)
        return rgb
    return a[..., 0] if a.shape[-1] == 1 else a


def _cv2_read(path, hdr):
    """OpenCV's decoding of a plain PNG (8/16-bit grey, RGB, RGBA, no interlace, no tRNS), or
    None when OpenCV is absent or the file is not plain."""
    if hdr["interlace"] or hdr["bit_depth"] not in (8, 16) or hdr["colour_type"] not in (0, 2, 6):
        return None
    try:
        import cv2
    except ImportError:
        return None
    a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    want = (hdr["height"], hdr["width"]) + ((hdr["channels"],) if hdr["channels"] > 1 else ())
    dtype = np.uint16 if hdr["bit_depth"] == 16 else np.uint8
    if a is None or a.shape != want or a.dtype != dtype:
        return None
    if a.ndim == 3:
        a = a[..., [2, 1, 0, 3][:a.shape[2]]]
    return np.ascontiguousarray(a)


def read_png(path: str | os.PathLike, *, accelerate: bool = True) -> np.ndarray:
    """Read a PNG without loss: (H, W) grey, (H, W, 2) grey + alpha, (H, W, 3) RGB or (H, W, 4)
    RGBA, uint16 for 16-bit files and uint8 otherwise (1/2/4-bit samples keep their values
    ``0 .. 2**depth - 1``; palette images are expanded to RGB(A)).  No gamma or colour
    conversion is applied.  ``accelerate``: let OpenCV decode plain files when it is installed
    (identical result).  A damaged file raises ``ValueError`` naming it."""
    hdr, raw, plte, trns = _png_chunks(path)
    if accelerate and trns is None:
        a = _cv2_read(path, hdr)
        if a is not None:
            return a
    try:
        a = _decode(hdr, raw)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None
    return _expand(hdr, a, plte, trns, path)


def read_pngs(paths, *, accelerate: bool = True) -> list[np.ndarray]:
    """:func:`read_png` of several files; non-interlaced files of one size and format are
    unfiltered together (several times faster than one by one without OpenCV)."""
    paths = [Path(p) for p in paths]
    out: dict[int, np.ndarray] = {}
    groups: dict[tuple, list] = {}
    for i, p in enumerate(paths):
        hdr, raw, plte, trns = _png_chunks(p)
        if accelerate and trns is None:
            a = _cv2_read(p, hdr)
            if a is not None:
                out[i] = a
                continue
        if hdr["interlace"] or hdr["colour_type"] == 3 or trns is not None:
            out[i] = read_png(p, accelerate=False)
            continue
        key = (hdr["width"], hdr["height"], hdr["bit_depth"], hdr["channels"])
        groups.setdefault(key, []).append((i, p, hdr, raw))
    for (w, h, depth, ch), items in groups.items():
        rb = (w * ch * depth + 7) // 8
        bpp = max(1, ch * depth // 8)
        for start in range(0, len(items), 8):     # 8 at a time bounds the memory
            part = items[start:start + 8]
            rows = []
            for _, p, _, raw in part:
                buf = np.frombuffer(raw, np.uint8)
                if buf.size < h * (rb + 1):
                    raise ValueError(f"{p}: truncated PNG image data")
                rows.append(buf[:h * (rb + 1)].reshape(h, rb + 1))
            for (i, _p, _h, _), r in zip(part, _unfilter(rows, bpp), strict=True):
                a = _unpack(r, w, ch, depth)
                out[i] = a[..., 0] if ch == 1 else a
    return [out[i] for i in range(len(paths))]


def write_png_exact(path: str | os.PathLike, a: np.ndarray, *, filters=(4,)) -> None:
    """Write a uint8 or uint16 (H, W), (H, W, 2), (H, W, 3) or (H, W, 4) array as a PNG without
    loss (bool arrays as 0 / 255 grey).  ``filters``: the scanline filter of each row, cycled
    (0 None, 1 Sub, 2 Up, 3 Average, 4 Paeth)."""
    import struct
    import zlib

    a = np.asarray(a)
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    if a.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"write_png_exact: dtype {a.dtype}; give uint8 or uint16 (scale and round first)")
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise ValueError(f"write_png_exact: shape {a.shape}; give (H, W) or (H, W, 1-4)")
    h, w, ch = a.shape
    depth = 16 if a.dtype == np.uint16 else 8
    ctype = {1: 0, 2: 4, 3: 2, 4: 6}[ch]
    rows = (a.astype(">u2") if depth == 16 else a).reshape(h, -1).view(np.uint8).reshape(h, -1).astype(np.int16)
    bpp = ch * depth // 8
    zero = np.zeros((1, rows.shape[1]), np.int16)
    up = np.concatenate([zero, rows[:-1]])
    left = np.concatenate([np.zeros((h, bpp), np.int16), rows[:, :-bpp]], axis=1)
    upleft = np.concatenate([np.zeros((h, bpp), np.int16), up[:, :-bpp]], axis=1)
    p = left + up - upleft
    pa, pb, pc = np.abs(p - left), np.abs(p - up), np.abs(p - upleft)
    paeth = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, up, upleft))
    preds = {0: 0, 1: left, 2: up, 3: (left + up) >> 1, 4: paeth}
    ft = np.resize(np.asarray(filters, np.uint8), h)
    body = np.empty((h, rows.shape[1] + 1), np.uint8)
    body[:, 0] = ft
    for t in np.unique(ft):
        sel = ft == t
        pred = preds[int(t)]
        body[sel, 1:] = ((rows[sel] - (pred[sel] if not np.isscalar(pred) else 0)) & 0xFF).astype(np.uint8)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, depth, ctype, 0, 0, 0)
    Path(path).write_bytes(PNG_SIGNATURE + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(body.tobytes(), 6))
                           + chunk(b"IEND", b""))


def write_mask_png(path: str | os.PathLike, mask) -> None:
    """A boolean (H, W) mask as an 8-bit grey PNG: 255 inside, 0 outside."""
    write_png_exact(path, np.asarray(mask, bool))


# ----------------------------------------------------------------------------- any image
def read_exr_image(path: str | os.PathLike) -> np.ndarray:
    """One image from an EXR written by any program: (H, W) for a single channel, (H, W, 3)
    for R, G, B (or X, Y, Z), (H, W, 4) with alpha; half and uint channels become float32.
    Channel names may carry one layer prefix (``normals.X``); a file with several layers
    (a pbrbench ground truth) raises ``ValueError`` (read it with :func:`read_exr`)."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            chans = {n: np.array(c.pixels, dtype=np.float32) for n, c in f.channels().items()}
    except Exception as e:  # noqa: BLE001 - OpenEXR raises plain exceptions
        raise ValueError(f"{path}: not a readable EXR file ({' '.join(str(e).split())})") from None
    layers = {n.rsplit(".", 1)[0] if "." in n else "" for n in chans}
    if len(layers) > 1:
        raise ValueError(f"{path}: {len(layers)} layers ({', '.join(sorted(layers))}); write one image per file")
    by = {n.rsplit(".", 1)[-1]: a for n, a in chans.items()}
    for order in (("R", "G", "B", "A"), ("R", "G", "B"), ("X", "Y", "Z"), ("B", "G", "R")):
        if set(by) == set(order):
            order = ("R", "G", "B") if order == ("B", "G", "R") else order
            return np.stack([by[c] for c in order], axis=-1)
    if len(by) == 1:
        return next(iter(by.values()))
    keys = sorted(by)
    return np.stack([by[k] for k in keys], axis=-1)


def read_image(path: str | os.PathLike) -> np.ndarray:
    """An image or array file by its suffix, without loss: ``.exr`` (float32,
    :func:`read_exr_image`), ``.npy`` (as stored), ``.png`` (uint8/uint16, :func:`read_png`),
    ``.tif``/``.tiff`` (as stored), ``.jpg``/``.jpeg``/``.bmp`` (uint8), ``.pfm`` (float32,
    row 0 at the top).  ``ValueError`` naming the file when it is missing or unreadable."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: no such file")
    suffix = p.suffix.lower()
    if suffix == ".exr":
        return read_exr_image(p)
    if suffix == ".npy":
        try:
            return np.load(p, allow_pickle=False)
        except (ValueError, OSError) as e:
            raise ValueError(f"{p}: not a readable .npy file ({e})") from None
    if suffix == ".png":
        return read_png(p)
    if suffix == ".pfm":
        return _read_pfm(p)
    if suffix in (".tif", ".tiff"):
        import tifffile

        return np.asarray(tifffile.imread(str(p)))
    if suffix in (".jpg", ".jpeg", ".bmp"):
        from PIL import Image

        with Image.open(p) as im:
            return np.asarray(im.convert("RGB") if im.mode not in ("L", "RGB") else im)
    raise ValueError(f"{p}: unknown image format {suffix!r}; use .exr, .npy, .png, .tif, .pfm or .jpg")


def _read_pfm(p: Path) -> np.ndarray:
    with open(p, "rb") as f:
        kind = f.readline().strip()
        if kind not in (b"PF", b"Pf"):
            raise ValueError(f"{p}: not a PFM file")
        w, h = (int(x) for x in f.readline().split())
        scale = float(f.readline())
        a = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
    ch = 3 if kind == b"PF" else 1
    a = a[:w * h * ch].reshape(h, w, ch)[::-1].astype(np.float32)   # PFM stores the bottom row first
    return a[..., 0] if ch == 1 else a


# ----------------------------------------------------------------------------- renders
class Render:
    """A render written by ``pbrbench render --out DIR``: the EXR's named arrays and the JSON's
    metadata (lights and camera in the camera frame, units, noise).

    ``render["radiance"]`` is an (H, W, 3) float32 array; ``light_vectors`` the (K, 3) source
    vectors of the light set (direction toward the source in the camera frame x irradiance, the
    ``lights`` argument of :func:`pbrbench.infer.photometric_stereo.photometric_stereo`) or None;
    ``light_stack(kind)`` the (K, H, W, 3) per-light images; ``mask`` the pure-pixel mask.
    """

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict, path: Path | None = None):
        self.arrays = arrays
        self.meta = meta
        self.path = path

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.arrays[name]
        except KeyError:
            raise KeyError(f"render has no {name!r}; it has {', '.join(sorted(self.arrays))}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.arrays

    def keys(self):
        return self.arrays.keys()

    @property
    def mask(self) -> np.ndarray:
        return self.arrays["mask"] > 0.5

    @property
    def lights(self) -> list[dict]:
        """The light set (one dict per ``lightNN`` image; see ``pbrbench render --help``)."""
        return list(self.meta.get("light_set") or [])

    @property
    def light_vectors(self) -> np.ndarray | None:
        v = self.meta.get("light_vectors")
        return None if v is None else np.asarray(v, np.float64)

    @property
    def camera(self) -> dict:
        return dict(self.meta.get("camera") or {})

    def light_stack(self, kind: str = "radiance") -> np.ndarray:
        """(K, H, W, 3) images of the light set, one light at a time (``kind``: radiance or direct)."""
        n = len(self.lights) or sum(1 for k in self.arrays if k.endswith(f".{kind}") and k.startswith("light"))
        return np.stack([self[f"light{k:02d}.{kind}"] for k in range(n)])

    def __repr__(self) -> str:
        return f"Render({self.meta.get('scene', '?')!r}, {len(self.arrays)} arrays)"


def load_render(path: str | os.PathLike) -> Render:
    """Load a render written by ``pbrbench render --out DIR``: ``path`` is the scene's folder, its
    ``gt.exr`` or its ``gt.json``.  Returns a :class:`Render` (arrays + metadata); a missing or
    unreadable file raises ``ValueError`` naming it."""
    import json

    p = Path(path)
    folder = p if p.is_dir() else p.parent
    exr, js = folder / "gt.exr", folder / "gt.json"
    for f in (exr, js):
        if not f.is_file():
            raise ValueError(f"{f}: missing; pass a folder written by `pbrbench render SCENE --out DIR`")
    try:
        meta = json.loads(js.read_text())
    except ValueError as e:
        raise ValueError(f"{js}: not valid JSON ({e})") from None
    return Render(read_exr(exr), meta, folder)
