"""The psmImages photometric-stereo layout (the public TGA data of "Shape and spatially-varying
BRDFs from photometric stereo", Goldman et al., ICCV 2005, used by many course exercises).

One object folder (``psmImages/buddha``, ``cat``, ``owl``, ...) holds:

* ``buddha.0.tga`` .. ``buddha.11.tga``: 8-bit images, one per light, in the order of the
  light file (sorted by the number before the suffix; PNG, TIFF or EXR images work too);
* ``buddha.mask.tga`` (or ``mask.tga`` / ``mask.png``): the object mask, non-zero inside;
* ``lights.txt``, in the folder or the one above it (the data set keeps one for all objects):
  an optional first line with the number of lights, then one light per line -- ``x y z`` (a
  direction toward the light, camera frame x right, y up, z toward the camera), ``x y z s`` (a
  direction and its intensity) or ``x y z r g b`` (an intensity per channel).  Directions
  that are not unit length are normalised; their length is not read as an intensity.

No ground-truth normals come with the data set: ``normals`` is None.  Images are taken as
linear (8-bit / 255) and each channel is divided by its light's intensity, as
:func:`pbrbench.datasets.diligent.load_diligent` does.

Checks are DiLiGenT's (:mod:`pbrbench.datasets.diligent`): a malformed folder raises
:class:`~pbrbench.errors.UserError` with one line naming the file and the fix.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from pbrbench.datasets.diligent import DiLiGenTObject, _check_stack, _read_images, _stack
from pbrbench.datasets.files import find, read_mask, warn
from pbrbench.errors import UserError

__all__ = ["is_psm", "load_psm", "psm_lights"]

PSM_SUFFIXES = (".tga", ".png", ".tif", ".tiff", ".exr")
_NUMBERED = re.compile(r"^(?:.*?[._-])?(\d+)$")


def _lights_file(folder: Path) -> Path | None:
    return find(folder, "lights.txt") or find(folder.parent, "lights.txt")


def _images(folder: Path) -> tuple[list[Path], Path | None]:
    """The numbered images in order, and the mask file (a name with ``mask`` in its stem)."""
    imgs, mask = [], None
    for p in sorted(folder.iterdir()):
        if not p.is_file() or p.suffix.lower() not in PSM_SUFFIXES:
            continue
        if "mask" in p.stem.lower():
            mask = mask or p
            continue
        m = _NUMBERED.match(p.stem)
        if m:
            imgs.append((int(m.group(1)), p))
    return [p for _, p in sorted(imgs)], mask


def is_psm(folder) -> bool:
    """Whether ``folder`` looks like a psmImages object: a ``lights.txt`` here or one level up,
    numbered TGA images and no DiLiGenT ``light_directions.txt``."""
    folder = Path(folder)
    if not folder.is_dir() or find(folder, "light_directions.txt") is not None or _lights_file(folder) is None:
        return False
    files, _ = _images(folder)
    return any(p.suffix.lower() == ".tga" for p in files)


def psm_lights(path: Path, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The unit directions (K, 3) and intensities (K, 3) of a psmImages ``lights.txt``.

    Parameters
    ----------
    path : pathlib.Path
        The light file.
    k : int, optional
        The number of images, to check the count against.

    Returns
    -------
    tuple of numpy.ndarray
        Directions (unit rows) and per-channel intensities (1 where the file gives none).

    Raises
    ------
    UserError
        One line naming the file: not numbers, rows of other than 3, 4 or 6 values, a zero
        direction, an intensity that is not positive, or a count that is not ``k``.
    """
    from pbrbench.datasets.files import read_lines

    lines = read_lines(path)
    if len(lines) > 1 and re.fullmatch(r"\d+", lines[0]):   # the count line of the data set's own file
        if int(lines[0]) != len(lines) - 1:
            raise UserError(f"{path}: the first line announces {int(lines[0])} lights, the file lists "
                            f"{len(lines) - 1}; write one line per light (and the count first, or no count)")
        lines = lines[1:]
    rows = []
    for i, line in enumerate(lines, 1):
        try:
            rows.append([float(v) for v in re.split(r"[\s,;]+", line) if v])
        except ValueError:
            raise UserError(f"{path}, light {i}: {line[:60]!r} is not a row of numbers; write x y z per line") from None
    if not rows or len({len(r) for r in rows}) != 1:
        raise UserError(f"{path}: {'no lights' if not rows else 'rows of different lengths'}; write one x y z per line")
    t = np.asarray(rows, np.float64)
    if not np.isfinite(t).all():
        raise UserError(f"{path}: a NaN or infinite value; give finite light directions")
    if t.shape[1] not in (3, 4, 6):
        raise UserError(f"{path}: {t.shape[1]} values per line; write x y z, x y z intensity or x y z r g b")
    dirs = t[:, :3]
    norms = np.linalg.norm(dirs, axis=1)
    if not (norms > 0).all():
        row = int(np.flatnonzero(norms == 0)[0])
        raise UserError(f"{path}: light {row + 1} has a zero direction; give the direction toward the light")
    ints = np.ones((len(t), 3)) if t.shape[1] == 3 else np.repeat(t[:, 3:4], 3, 1) if t.shape[1] == 4 else t[:, 3:]
    if not (ints > 0).all():
        row = int(np.flatnonzero(~(ints > 0).all(axis=1))[0])
        raise UserError(f"{path}: light {row + 1} has an intensity that is not positive; give positive intensities")
    if k is not None and len(t) != k:
        raise UserError(f"{path}: {len(t)} lights for {k} images; give one line per image")
    off = np.flatnonzero(np.abs(norms - 1) > 1e-3)
    if off.size:
        warn(f"{path}: {off.size} light direction(s) not of unit length (light {off[0] + 1}: {norms[off[0]]:.3g}); "
             "normalised")
    return dirs / norms[:, None], ints


def load_psm(folder, *, indices=None, log=None) -> DiLiGenTObject:
    """Load one psmImages object folder.

    Parameters
    ----------
    folder : str or os.PathLike
        The object folder (``psmImages/buddha``).
    indices : sequence of int, optional
        The lights to keep (all by default).
    log : callable, optional
        Receives one progress line.

    Returns
    -------
    DiLiGenTObject
        ``images`` (K, H, W, 3) float64 divided by the intensities, ``lights`` unit (K, 3),
        ``mask``, ``normals`` None.

    Raises
    ------
    UserError
        One line naming the file and the fix for a malformed folder.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such folder")
    lf = _lights_file(folder)
    files, mf = _images(folder)
    if lf is None or not files:
        raise UserError(f"{folder}: not a psmImages object folder (lights.txt here or above, numbered images "
                        "name.0.tga, name.1.tga, ...)")
    dirs, ints = psm_lights(lf, len(files))
    if indices is not None:
        from pbrbench.datasets.diligent import _indices

        sel = _indices(indices, len(files))
        files, dirs, ints = [files[i] for i in sel], dirs[sel], ints[sel]
    if log is not None:
        log(f"psmImages {folder.name}: {len(files)} images, lights from {lf}")
    raw = _read_images(files)
    imgs = _stack(raw, files, folder)
    tops = [np.iinfo(r.dtype).max if r.dtype.kind in "ui" else None for r in raw]
    del raw
    h, w = imgs.shape[1:3]
    try:
        mask = read_mask(mf, (h, w)) if mf is not None else np.ones((h, w), bool)
    except ValueError as e:
        raise UserError(str(e)) from None
    _check_stack(imgs, tops, files, mask, folder)
    return DiLiGenTObject(folder.name, folder, imgs / ints[:, None, None, :], dirs, ints, mask, None, files)
