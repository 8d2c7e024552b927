"""An exposure bracket on disk: a folder of images of one scene at several exposure times.

Exposure times, in this order of preference:

* a times file in the folder: ``times.txt`` / ``exposure_times.txt`` / ``exposures.txt``, one
  time in seconds per line (``0.004`` or ``1/250``), either alone (then in the order of the
  sorted file names) or after the file name (``img_01.jpg 1/250``);
* OpenCV's sample layout ``list.txt``: ``name value`` lines where value is the *inverse* of the
  time (the samples load it as ``1 / value``);
* HDRShop / Debevec's ``*.hdr_image_list.txt``: an optional image count, then ``name 1/shutter
  f-stop gain ND`` lines (time = 1 / the second column); a listed ``.ppm`` may be present as
  ``.png`` with the same stem;
* else the EXIF ``ExposureTime`` of each image (JPEG, TIFF, PNG with an eXIf chunk).

Images are integer pixel values (8 or 16 bits: what the camera wrote, before any linearisation),
returned sorted by increasing exposure time as :func:`pbrbench.infer.hdr.calibrate_response`
wants them.  Differing f-stops, gains or ND filters in an HDRShop list are folded into an
equivalent exposure and said
so in ``notes`` (relative to the first line: ``t (f0 / f)^2 10^((gain - gain0) / 10)``, 3 dB of
gain doubling the exposure).

Checks (a malformed folder raises :class:`~pbrbench.errors.UserError` with one line naming the
file and the fix; data that may still be valid gives a
:class:`~pbrbench.datasets.files.DataWarning`, also listed in ``notes``):

* refused: a missing, empty (0 bytes), damaged or oversized image; float pixels or integers
  other than 8 and 16 bits; **mixed bit depths** (an 8-bit and a 16-bit file: their levels
  mean different things, so the bracket cannot be calibrated as one camera); images of
  different sizes or channel counts, or more than 4 channels; a time that is not a positive
  finite number; two images sharing a time; fewer than 2 exposures with information (the
  others entirely saturated or black); **exposure times out of order with the
  images' brightness**: a longer exposure darker than a shorter one at most of the pixels
  well exposed in both (10 points more pixels darker than brighter), which is what a
  reversed or shuffled times file gives;
* warned: an image saturated or black everywhere (it adds nothing); more than 5 % of
  the pixels saturated even in the shortest exposure (their radiance is only a lower bound)
  or black even in the longest; a longer exposure darker at more pixels than it is brighter,
  but by less than the refusal margin (the scene may have changed); 16-bit files whose
  values never exceed 255 (read as 8-bit levels).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from pbrbench.datasets.files import (
    IMAGE_SUFFIXES,
    MAX_STACK_BYTES,
    find,
    load_image,
    read_lines,
    warn,
)
from pbrbench.errors import UserError

__all__ = ["Bracket", "load_bracket", "parse_time"]

TIMES_FILES = ("times.txt", "exposure_times.txt", "exposures.txt", "exposure.txt")
EXIF_EXPOSURE_TIME = 0x829A
EXIF_IFD = 0x8769


@dataclass
class Bracket:
    """``images`` (K, H, W[, C]) unsigned integers, ``exposure_times`` (K,) seconds, strictly
    increasing, ``files`` in the same order, ``source`` (where the times came from)."""

    images: np.ndarray
    exposure_times: np.ndarray
    files: list[Path]
    source: str
    notes: list[str] = field(default_factory=list)


def parse_time(text: str, where: str) -> float:
    """``"0.004"``, ``"1/250"``, ``"4e-3"`` -> seconds (> 0); ``UserError`` naming ``where``."""
    t = text.strip().rstrip("s")
    try:
        v = float(Fraction(t)) if "/" in t else float(t)
    except (ValueError, ZeroDivisionError):
        raise UserError(f"{where}: {text!r} is not an exposure time (write 0.004 or 1/250)") from None
    if not v > 0 or not np.isfinite(v):
        raise UserError(f"{where}: exposure time {text!r} must be positive and finite (in seconds)")
    return v


def _images(folder: Path) -> list[Path]:
    return sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
                   and p.suffix.lower() not in (".exr", ".npy") and not p.name.startswith(".")),
                  key=lambda p: [int(x) if x.isdigit() else x.lower() for x in re.split(r"(\d+)", p.name)])


def _resolve(folder: Path, name: str, where: str) -> Path:
    p = folder / name
    if p.is_file():
        return p
    alt = find(folder, Path(name).name)
    if alt is None:
        stem = Path(name).stem.lower()
        alt = next((q for q in _images(folder) if q.stem.lower() == stem), None)
    if alt is None:
        raise UserError(f"{where}: lists {name!r}, which is not in {folder}")
    return alt


def _from_times_file(folder: Path, f: Path, images: list[Path]):
    lines = read_lines(f)
    pairs = []
    for i, ln in enumerate(lines, 1):
        parts = ln.split()
        where = f"{f}, line {i}"
        if len(parts) == 1:
            pairs.append((None, parse_time(parts[0], where)))
        else:
            pairs.append((_resolve(folder, parts[0], where), parse_time(parts[1], where)))
    if all(p is None for p, _ in pairs):
        if len(pairs) != len(images):
            raise UserError(f"{f}: {len(pairs)} times for {len(images)} images; give one time per image "
                            "(in the order of the sorted file names) or 'name time' lines")
        return list(images), [t for _, t in pairs], []
    if any(p is None for p, _ in pairs):
        raise UserError(f"{f}: mix of 'time' and 'name time' lines; use one form")
    files = [p for p, _ in pairs]
    seen = {}
    for i, p in enumerate(files, 1):
        if p.resolve() in seen:
            raise UserError(f"{f}, line {i}: lists {p.name} again (first on line {seen[p.resolve()]}); list each "
                            "image once")
        seen[p.resolve()] = i
    return files, [t for _, t in pairs], []


def _from_inverse_list(folder: Path, f: Path, hdrshop: bool):
    files, times, notes = [], [], []
    lines = read_lines(f)
    if hdrshop and lines and re.fullmatch(r"\d+", lines[0]):
        lines = lines[1:]
    ref = None
    for i, ln in enumerate(lines, 1):
        parts = ln.split()
        where = f"{f}, line {i}"
        if len(parts) < 2:
            raise UserError(f"{where}: expected 'name value' (value = 1 / exposure time)")
        inv = parse_time(parts[1], where)
        t = 1.0 / inv
        if hdrshop and len(parts) >= 4:
            try:
                stop, gain = float(parts[2]), float(parts[3])
            except ValueError:
                raise UserError(f"{where}: f-stop and gain must be numbers") from None
            ref = (stop, gain) if ref is None else ref
            if (stop, gain) != ref:   # relative to the first line: f-stop squared, 3 dB of gain = x2
                notes.append(f"{parts[0]}: f/{stop:g}, gain {gain:g} dB folded into the exposure")
                t *= (ref[0] / stop) ** 2 * 10 ** ((gain - ref[1]) / 10.0)
        files.append(_resolve(folder, parts[0], where))
        times.append(t)
    return files, times, notes


def _exif_time(path: Path) -> float | None:
    from PIL import Image

    try:
        with Image.open(path) as im:
            exif = im.getexif()
            v = exif.get(EXIF_EXPOSURE_TIME)
            if v is None:
                v = exif.get_ifd(EXIF_IFD).get(EXIF_EXPOSURE_TIME)
    except (OSError, ValueError):
        return None
    if v is None:
        return None
    try:
        v = float(v)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return v if v > 0 and np.isfinite(v) else None


def load_bracket(folder) -> Bracket:
    """Load an exposure bracket (see the module docstring); ``UserError`` with one line when the
    folder is malformed (no images, no times, mismatched sizes, duplicate times, float images,
    mixed bit depths, times out of order with the brightness, no informative exposure)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such folder")
    images = _images(folder)
    tf = find(folder, *TIMES_FILES)
    ol = find(folder, "list.txt")
    hs = next((p for p in sorted(folder.iterdir()) if p.name.lower().endswith("hdr_image_list.txt")), None)
    if tf is not None:
        files, times, notes = _from_times_file(folder, tf, images)
        source = str(tf)
    elif hs is not None:
        files, times, notes = _from_inverse_list(folder, hs, hdrshop=True)
        source = f"{hs} (HDRShop list: time = 1 / second column)"
    elif ol is not None:
        files, times, notes = _from_inverse_list(folder, ol, hdrshop=False)
        source = f"{ol} (OpenCV list: time = 1 / value)"
    else:
        if not images:
            raise UserError(f"{folder}: no images (.png, .jpg, .tif, ...)")
        times = [_exif_time(p) for p in images]
        missing = [p.name for p, t in zip(images, times, strict=True) if t is None]
        if missing:
            raise UserError(f"{folder}: no times.txt and no EXIF exposure time in {missing[0]}"
                            f"{f' (and {len(missing) - 1} more)' if len(missing) > 1 else ''}; write times.txt "
                            "with one exposure time in seconds per image")
        files, notes, source = list(images), [], "EXIF ExposureTime"
    if len(files) < 2:
        raise UserError(f"{folder}: {len(files)} image(s); a bracket needs at least 2 exposures")
    order = np.argsort(times, kind="stable")
    files = [files[i] for i in order]
    times = np.asarray(times, float)[order]
    if np.any(np.diff(times) <= 0):
        dup = times[np.flatnonzero(np.diff(times) <= 0)[0]]
        where = tf or hs or ol or folder
        raise UserError(f"{where}: two images share the exposure time {dup:g} s; give each exposure its own time "
                        "(or drop the repeated image)")
    arrays = []
    for f in files:
        a = load_image(f, "bracket image")
        if a.dtype not in (np.uint8, np.uint16):
            raise UserError(f"{f}: {a.dtype} pixels; a bracket needs the camera's unsigned integer values (8 or "
                            "16 bits): save the exposures as 8- or 16-bit PNG / TIFF / JPEG")
        if arrays and a.dtype != arrays[0].dtype:
            raise UserError(f"{f}: {8 * a.dtype.itemsize}-bit, {files[0].name} is {8 * arrays[0].dtype.itemsize}-bit; "
                            "the exposures of one bracket must share one bit depth: save them all alike")
        if arrays and a.shape != arrays[0].shape:
            raise UserError(f"{f}: shape {a.shape}, {files[0].name} is {arrays[0].shape}; the images must align "
                            "(same size and channels)")
        if a.ndim == 3 and a.shape[2] > 4:
            raise UserError(f"{f}: {a.shape[2]} channels; give grey, RGB or RGBA images")
        arrays.append(a)
        if len(arrays) * a.size * 8 > MAX_STACK_BYTES:
            raise UserError(f"{folder}: the images are too large to merge ({len(files)} x {a.shape}); downsample them")
    stack = np.stack(arrays)
    if stack.ndim == 4 and stack.shape[-1] == 4:
        notes.append("alpha channel dropped")
        stack = stack[..., :3]
    elif stack.ndim == 4 and stack.shape[-1] == 2:
        notes.append("alpha channel dropped")
        stack = stack[..., 0]
    elif stack.ndim == 4 and stack.shape[-1] == 1:
        stack = stack[..., 0]
    if stack.dtype == np.uint16 and stack.max() <= 255:
        _note(notes, f"{files[0].parent}: 16-bit files whose values never exceed 255; read as 8-bit levels")
        stack = stack.astype(np.uint8)
    _check_content(stack, times, files, source, notes)
    return Bracket(stack, times, files, source, notes)


def _note(notes: list, msg: str) -> None:
    notes.append(msg)
    warn(msg)


def _check_content(stack: np.ndarray, times, files, source: str, notes: list) -> None:
    """Refuse a bracket without information or with times out of order with the brightness;
    warn about exposures that add nothing (see the module docstring)."""
    top = 255 if stack.dtype == np.uint8 else 65535
    k = len(stack)
    flat = stack.reshape(k, -1, stack.shape[-1] if stack.ndim == 4 else 1)
    step = max(1, flat.shape[1] // 200_000)       # a sample of the pixels bounds the time
    z = flat[:, ::step].astype(np.float64)
    zmax, zmin = z.max(axis=-1), z.min(axis=-1)    # (K, N): the brightest / darkest channel
    informative = []
    for i, f in enumerate(files):
        if zmin[i].min() >= top:
            _note(notes, f"{f}: every pixel is saturated ({top}); this exposure adds nothing: drop it")
        elif zmax[i].max() <= 0:
            _note(notes, f"{f}: every pixel is 0 (black); this exposure adds nothing: drop it")
        else:
            informative.append(i)
    if len(informative) < 2:
        raise UserError(f"{files[0].parent}: {len(informative)} exposure(s) with information (the others are "
                        "saturated or black everywhere); a bracket needs at least 2: shoot shorter and "
                        "longer exposures")
    sat_all = float((zmax >= top).all(axis=0).mean())
    dark_all = float((zmax <= 0).all(axis=0).mean())
    if sat_all > 0.05:
        _note(notes, f"{files[0]} (the shortest exposure): {sat_all:.0%} of the pixels are saturated in every "
                     "exposure; their radiance is only a lower bound: add a shorter exposure")
    if dark_all > 0.05:
        _note(notes, f"{files[-1]} (the longest exposure): {dark_all:.0%} of the pixels are 0 in every exposure; "
                     "add a longer exposure")
    # brightness must grow with the exposure time at pixels well exposed in both images
    good = (zmax < top) & (zmin > 0)
    for a, b in zip(informative[:-1], informative[1:], strict=True):
        both = good[a] & good[b]
        if both.sum() < 16:
            continue
        za, zb = z[a][both].mean(-1), z[b][both].mean(-1)
        darker, brighter = float((zb < za).mean()), float((zb > za).mean())
        if darker <= brighter:
            continue
        msg = (f"{source}: {files[b].name} ({times[b]:g} s) is darker than {files[a].name} ({times[a]:g} s) at "
               f"{darker:.0%} of the pixels (brighter at {brighter:.0%}): the exposure times are out of order with "
               "the images' brightness")
        if darker > brighter + 0.10:
            raise UserError(msg + "; check that each time belongs to its image (a bare list of times follows the "
                                  "sorted file names)")
        _note(notes, msg + " (a little: the scene may have changed)")
