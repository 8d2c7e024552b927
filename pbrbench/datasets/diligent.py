"""DiLiGenT photometric-stereo data (Shi et al., CVPR 2016 / TPAMI 2019) as laid out on disk.

One object folder (``pmsData/ballPNG``, ``bearPNG``, ...) holds:

* ``001.png`` .. ``096.png``: 16-bit RGB images, one per light, linear (read without loss by
  :func:`pbrbench.io.read_pngs`; scaled to [0, 1] by 1/65535);
* ``filenames.txt``: the image files in light order (absent: the numbered PNGs in numeric order);
* ``light_directions.txt``: K rows ``x y z``, unit vectors from the object toward each light;
* ``light_intensities.txt``: K rows ``r g b``, the relative intensity of each light per channel
  (absent: 1); the loader divides each image channel by it, as the benchmark's evaluation does,
  so the lights become unit vectors;
* ``mask.png``: the object mask (non-zero inside; grey or RGB, any bit depth);
* ``Normal_gt.mat`` (MATLAB, variable ``Normal_gt``, H x W x 3), or ``Normal_gt.txt`` /
  ``normal.txt`` (H*W rows ``nx ny nz``, row-major pixel order, or column-major -- MATLAB's
  ``N(:)`` -- when that order explains the images better), or ``Normal_gt.npy``: the
  ground-truth normals (absent in the test objects without published normals).

Frames: DiLiGenT gives normals and light directions in the camera frame **x right, y up, z toward
the camera** (the viewer), image row 0 at the top -- exactly pbrbench's frame
(``docs/conventions.md``), so nothing is converted.  :func:`frame_check` tests that the normals
and the lights agree (a Lambertian fit with the ground-truth normals beats the fits with a
flipped axis); a loader that read a file in another convention would show up there.

Evaluation protocol (:func:`pbrbench.metrics.normals.angular_error_stats`): the per-pixel angle
between unit normals, ``degrees(arccos(clip(n_est . n_gt, -1, 1)))``, over the mask; mean (the
DiLiGenT table) and median.  Published code often drops the first 20 images of ``bearPNG``
(damaged); pass ``indices`` to do so.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrbench.datasets.files import find, find_stem, read_lines, read_mask, read_table, to_float
from pbrbench.errors import UserError

__all__ = ["DiLiGenTObject", "load_diligent", "diligent_objects", "is_diligent", "frame_check", "read_normals"]

NORMAL_FILES = ("Normal_gt.mat", "Normal_gt.npy", "Normal_gt.txt", "normal.txt", "normals.txt", "Normal_gt.exr")


@dataclass
class DiLiGenTObject:
    """One object: ``images`` (K, H, W, 3) float64 linear, each channel divided by its light's
    intensity; ``lights`` (K, 3) unit directions toward the lights (camera frame);
    ``intensities`` (K, 3); ``mask`` (H, W) bool; ``normals`` (H, W, 3) unit, zero outside the
    mask, or None; ``files`` the image files in light order."""

    name: str
    path: Path
    images: np.ndarray
    lights: np.ndarray
    intensities: np.ndarray
    mask: np.ndarray
    normals: np.ndarray | None
    files: list[Path] = field(default_factory=list)

    @property
    def grey(self) -> np.ndarray:
        """(K, H, W) channel means (the input of the benchmark's photometric-stereo methods)."""
        return self.images.mean(axis=-1)


def is_diligent(folder) -> bool:
    return find(Path(folder), "light_directions.txt") is not None


def diligent_objects(root) -> list[Path]:
    """The DiLiGenT object folders at or below ``root`` (an object folder, ``pmsData`` or the
    data set's top folder), sorted by name."""
    root = Path(root)
    if is_diligent(root):
        return [root]
    found = []
    for d in sorted(p for p in root.rglob("*") if p.is_dir() and len(p.relative_to(root).parts) <= 3):
        if is_diligent(d):
            found.append(d)
    return found


def _image_files(folder: Path, k: int | None) -> list[Path]:
    fn = find(folder, "filenames.txt")
    if fn is not None:
        files = []
        for name in read_lines(fn):
            p = folder / name
            if not p.is_file():
                alt = find(folder, Path(name).name) or find_stem(folder, Path(name).stem)
                if alt is None:
                    raise UserError(f"{fn}: lists {name!r}, which is not in {folder}")
                p = alt
            files.append(p)
        return files
    nums = sorted((p for p in folder.iterdir() if p.is_file() and re.fullmatch(r"\d+\.(png|tif|tiff|exr|npy)", p.name, re.I)),
                  key=lambda p: int(p.stem))
    if not nums:
        raise UserError(f"{folder}: no filenames.txt and no numbered images (001.png, ...)")
    return nums


def read_normals(path: Path, shape, choose=None) -> np.ndarray:
    """Ground-truth normals from a ``.mat`` / ``.npy`` / ``.exr`` / ``.txt`` file, (H, W, 3).

    A ``.txt`` of H*W rows is read in row-major pixel order (row 0 first), unless ``choose``
    (a function of the two candidate fields returning 0 or 1) prefers the column-major order
    (MATLAB's ``N(:)``); :func:`load_diligent` chooses by how well each explains the images."""
    h, w = shape
    suffix = path.suffix.lower()
    if suffix == ".mat":
        import scipy.io

        try:
            data = scipy.io.loadmat(str(path))
        except NotImplementedError:
            raise UserError(f"{path}: a MATLAB v7.3 (HDF5) file; save it with -v7 or give Normal_gt.txt") from None
        except (ValueError, OSError) as e:
            raise UserError(f"{path}: not a readable .mat file ({e})") from None
        arrays = {k: v for k, v in data.items() if not k.startswith("__") and isinstance(v, np.ndarray)
                  and v.ndim == 3 and v.shape[2] == 3}
        key = next((k for k in ("Normal_gt", "normal_gt", "N_gt", "Normal_est", "N") if k in arrays), None)
        if key is None:
            if len(arrays) != 1:
                raise UserError(f"{path}: no H x W x 3 variable Normal_gt (found {', '.join(sorted(arrays)) or 'none'})")
            key = next(iter(arrays))
        n = np.asarray(arrays[key], np.float64)
    elif suffix == ".txt":
        t = read_table(path)
        if t.shape == (h * w, 3):
            n = t.reshape(h, w, 3)            # one pixel per row, row-major (row 0 first)
            if choose is not None:
                col = t.reshape(w, h, 3).transpose(1, 0, 2)
                n = (n, col)[choose(n, col)]
        elif t.shape == (3, h * w):
            n = t.T.reshape(h, w, 3)
        elif t.shape == (h, 3 * w):
            n = t.reshape(h, w, 3)
        else:
            raise UserError(f"{path}: {t.shape[0]} x {t.shape[1]} numbers; expected {h * w} rows of nx ny nz "
                            f"for {h} x {w} images")
    else:
        from pbrbench.io import read_image

        n = np.asarray(read_image(path), np.float64)
    if n.shape != (h, w, 3):
        raise UserError(f"{path}: normals of shape {n.shape}, the images are {h} x {w}")
    return _unit(n)


def load_diligent(folder, *, indices=None, normals: bool = True, log=None) -> DiLiGenTObject:
    """Load one DiLiGenT object folder (see the module docstring).  ``indices`` selects lights
    (e.g. ``range(20, 96)``); a malformed folder raises ``UserError`` with one line."""
    from pbrbench.io import read_pngs

    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such folder")
    ld = find(folder, "light_directions.txt")
    if ld is None:
        raise UserError(f"{folder}: not a DiLiGenT object folder (no light_directions.txt)")
    try:
        dirs = read_table(ld, 3)
        li = find(folder, "light_intensities.txt")
        ints = read_table(li) if li is not None else np.ones_like(dirs)
    except ValueError as e:
        raise UserError(str(e)) from None
    if ints.shape[1] == 1:
        ints = np.repeat(ints, 3, axis=1)
    files = _image_files(folder, len(dirs))
    if not (len(files) == len(dirs) == len(ints)):
        raise UserError(f"{folder}: {len(files)} images, {len(dirs)} light directions and {len(ints)} intensities; "
                        "they must match one to one")
    sel = list(range(len(files))) if indices is None else list(indices)
    files, dirs, ints = [files[i] for i in sel], dirs[sel], ints[sel]
    if log:
        log(f"{folder.name}: reading {len(files)} images")
    try:
        pngs = [f for f in files if f.suffix.lower() == ".png"]
        decoded = dict(zip(pngs, read_pngs(pngs), strict=True)) if pngs else {}
        from pbrbench.io import read_image

        raw = [decoded[f] if f in decoded else read_image(f) for f in files]
    except ValueError as e:
        raise UserError(str(e)) from None
    shapes = {np.shape(r) for r in raw}
    if len(shapes) != 1:
        raise UserError(f"{folder}: the images have different shapes {sorted(shapes)}")
    imgs = np.stack([to_float(r, f) for r, f in zip(raw, files, strict=True)])
    if imgs.ndim == 3:
        imgs = np.repeat(imgs[..., None], 3, axis=-1)
    imgs = imgs[..., :3]
    if np.any(ints <= 0):
        raise UserError(f"{li}: intensities must be positive")
    imgs = imgs / ints[:, None, None, :]
    norms = np.linalg.norm(dirs, axis=1, keepdims=True)
    if np.any(norms < 1e-9):
        raise UserError(f"{ld}: a zero light direction")
    dirs = dirs / norms
    h, w = imgs.shape[1:3]
    mf = find_stem(folder, "mask")
    try:
        mask = read_mask(mf, (h, w)) if mf is not None else np.ones((h, w), bool)
    except ValueError as e:
        raise UserError(str(e)) from None
    n = None
    if normals:
        nf = find(folder, *NORMAL_FILES)
        if nf is not None:
            def choose(*fields):          # the order whose Lambertian shading fits the images best
                fits = [_fit(imgs.mean(-1), dirs, _unit(f), mask) for f in fields]
                return int(np.argmax(fits))

            n = read_normals(nf, (h, w), choose)
            n = np.where(mask[..., None], n, 0.0)
            if np.any(mask & (np.linalg.norm(n, axis=-1) == 0)):
                mask = mask & (np.linalg.norm(n, axis=-1) > 0)   # no normal: not scored
    return DiLiGenTObject(folder.name, folder, imgs, dirs, ints, mask, n, files)


def _unit(n):
    norm = np.linalg.norm(np.nan_to_num(n), axis=-1, keepdims=True)
    return np.where(norm > 0, np.nan_to_num(n) / np.where(norm > 0, norm, 1.0), 0.0)


def _fit(grey, lights, normals, mask, samples: int = 4000) -> float:
    """Mean per-pixel correlation over the lights between the images and ``max(0, n . l)``."""
    idx = np.flatnonzero((mask & (np.linalg.norm(normals, axis=-1) > 0)).ravel())
    if idx.size == 0:
        return -1.0
    idx = np.random.default_rng(0).choice(idx, size=min(samples, idx.size), replace=False)
    g = grey.reshape(len(lights), -1)[:, idx]
    s = np.maximum(lights @ normals.reshape(-1, 3)[idx].T, 0.0)
    gc, sc = g - g.mean(0), s - s.mean(0)
    den = np.sqrt((gc * gc).sum(0) * (sc * sc).sum(0))
    return float(np.where(den > 0, (gc * sc).sum(0) / np.where(den > 0, den, 1.0), 0.0).mean())


def frame_check(obj: DiLiGenTObject, *, samples: int = 4000) -> dict:
    """How well a Lambertian model with the ground-truth normals explains the images, with the
    normals as given and with one axis flipped: ``{"as_given": r, "flip_x": r, "flip_y": r,
    "flip_z": r}`` (mean per-pixel correlation over the lights).  The as-given frame should
    win; if a flip wins, the normals and the lights are in different frames."""
    if obj.normals is None:
        raise ValueError(f"{obj.name}: no ground-truth normals")
    if not obj.mask.any():
        raise ValueError(f"{obj.name}: empty mask")
    flips = {"as_given": (1, 1, 1), "flip_x": (-1, 1, 1), "flip_y": (1, -1, 1), "flip_z": (1, 1, -1)}
    return {label: _fit(obj.grey, obj.lights, obj.normals * np.asarray(f), obj.mask, samples)
            for label, f in flips.items()}
