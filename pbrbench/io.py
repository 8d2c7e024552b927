"""Image I/O: float32 multichannel OpenEXR (lossless, bit-exact) and PNG previews.

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


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read an EXR written by :func:`write_exr` back into named float32 arrays."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        chans = {name: np.array(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
    return group_channels(chans)


# ----------------------------------------------------------------------------- previews
def srgb_encode(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> sRGB-encoded [0, 1] (IEC 61966-2-1)."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


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
