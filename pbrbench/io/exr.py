"""OpenEXR files: float32 multichannel, lossless (ZIP) and bit-exact.

The OpenEXR Python API changed within 3.x; this module is the only place that touches it.
Channels are stored one by one under their full names (``radiance.R``, ``normals.X``,
``depth.Z``): arrays (H, W, 3) map to the suffixes of :data:`SUFFIXES`, arrays (H, W) to ``.Y``.

Readers check the header (data window x channels) against
:data:`~pbrbench.io.files.MAX_IMAGE_BYTES` before any pixel is decoded, and turn OpenEXR's own
exceptions and its messages on descriptors 1 and 2 into one ``ValueError`` line naming the file.
"""

from __future__ import annotations

import os

import numpy as np

from pbrbench.io.files import MAX_IMAGE_BYTES, atomic_path, check_size, quiet_output

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
    """{name: (H, W[, C]) array} -> {channel name: (H, W) float32 array}.

    Parameters
    ----------
    arrays : dict of str to numpy.ndarray
        Named (H, W) or (H, W, C) arrays (bool and any real dtype; stored as float32).

    Returns
    -------
    dict of str to numpy.ndarray
        One contiguous float32 (H, W) array per channel, named ``name.suffix``.
    """
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
    """Inverse of :func:`flatten_channels`: {``name.suffix``: (H, W)} -> {name: (H, W[, C])}."""
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


def write_exr(path: str | os.PathLike, arrays: dict[str, np.ndarray], header: dict | None = None) -> None:
    """Write named float32 arrays to a ZIP-compressed (lossless) scanline EXR, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    arrays : dict of str to numpy.ndarray
        Named (H, W) or (H, W, C) arrays (see :func:`flatten_channels`).
    header : dict, optional
        Extra header attributes.

    Raises
    ------
    OSError
        The file cannot be written (the OpenEXR bindings' errors included).
    """
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


def exr_shape(path: str | os.PathLike) -> tuple[int, int, int]:
    """(height, width, channels) from an EXR's header alone (no pixel is read).

    Raises
    ------
    ValueError
        One line naming the file when the header cannot be read.
    """
    import OpenEXR

    held: list[str] = []
    try:
        with quiet_output() as held, OpenEXR.File(str(path), header_only=True) as f:
            h = f.header()
            (x0, y0), (x1, y1) = (tuple(int(v) for v in c) for c in h["dataWindow"])
            channels = len(h.get("channels") or ())
    except Exception as e:  # noqa: BLE001 - OpenEXR raises plain exceptions
        raise ValueError(f"{path}: not a readable EXR file ({_why(e, held)}); write it again") from None
    return (y1 - y0 + 1, x1 - x0 + 1, max(channels, 1))


def _why(e: BaseException, held: list[str]) -> str:
    return " ".join((held[0] if held else str(e) or type(e).__name__).replace(" for read", "").split())[:200]


def _read_channels(path, *, limit: int) -> dict[str, np.ndarray]:
    """Every channel of an EXR as float32, the header checked first (each channel at most
    ``limit`` bytes as float32); OpenEXR's output held back, its failure one ``ValueError``."""
    import OpenEXR

    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such file")
    h, w, _ = exr_shape(path)
    check_size(path, (h, w), 4, limit)
    held: list[str] = []
    try:
        with quiet_output() as held, OpenEXR.File(str(path), separate_channels=True) as f:
            return {n: np.array(c.pixels, dtype=np.float32) for n, c in f.channels().items()}
    except MemoryError:
        raise
    except Exception as e:  # noqa: BLE001 - OpenEXR raises plain exceptions
        raise ValueError(f"{path}: not a readable EXR file ({_why(e, held)}); write it again") from None


def read_exr(path: str | os.PathLike, *, limit: int = MAX_IMAGE_BYTES) -> dict[str, np.ndarray]:
    """Read an EXR written by :func:`write_exr` back into named float32 arrays.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    limit : int
        The largest channel, in bytes as float32 (the header is checked before reading).

    Returns
    -------
    dict of str to numpy.ndarray
        The arrays by name (see :func:`group_channels`).

    Raises
    ------
    ValueError
        One line naming the file: missing, damaged or truncated, or a header above ``limit``.
    """
    return group_channels(_read_channels(path, limit=limit))


def read_exr_image(path: str | os.PathLike) -> np.ndarray:
    """One image from an EXR written by any program.

    (H, W) for a single channel, (H, W, 3) for R, G, B (or X, Y, Z), (H, W, 4) with alpha; half
    and uint channels become float32.  Channel names may carry one layer prefix (``normals.X``).

    Raises
    ------
    ValueError
        One line naming the file: unreadable, above :data:`MAX_IMAGE_BYTES` in all, or with
        several layers (a pbrbench ground truth: read it with :func:`read_exr`).
    """
    h, w, c = exr_shape(path)
    check_size(path, (h, w, c), 4, MAX_IMAGE_BYTES)
    chans = _read_channels(path, limit=MAX_IMAGE_BYTES)
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
