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

Checks (a malformed folder raises :class:`~pbrbench.errors.UserError` with one line naming the
file and the fix; data that may still be valid gives a
:class:`~pbrbench.datasets.files.DataWarning` and is kept):

* refused: a missing, empty, damaged, pickled or oversized file; non-numeric text; NaN or
  infinite light directions, intensities, pixels or mask values; a zero light direction;
  intensities that are not positive, or with other than 1 or 3 columns; counts of images,
  directions and intensities that differ; images of different sizes or channel counts, more
  than 4 channels; a mask with no pixel inside; images black everywhere inside the mask
  (an empty stack); more than half of the measurements inside the mask saturated (the top
  level of 8- or 16-bit images: the fit would be meaningless); ground-truth normals zero or
  non-finite everywhere inside the mask; ``indices`` out of range;
* warned: light directions not of unit length (they are normalised: DiLiGenT's are unit,
  the intensities live in ``light_intensities.txt``) or pointing away from the camera
  (z < 0); an image black everywhere inside the mask (a light that did not fire) or
  saturated at more than half of it; more than 5 % of the measurements saturated; negative
  float pixels; ground-truth normals non-finite or zero at some mask pixels (not scored).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrbench.datasets.files import (
    MAX_STACK_BYTES,
    MAX_VALUES,
    find,
    find_stem,
    load_image,
    read_lines,
    read_mask,
    table,
    to_float,
    warn,
)
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


def read_normals(path: Path, shape, choose=None, mask=None) -> np.ndarray:
    """Ground-truth normals from a ``.mat`` / ``.npy`` / ``.exr`` / ``.txt`` file, (H, W, 3).

    A ``.txt`` of H*W rows is read in row-major pixel order (row 0 first), unless ``choose``
    (a function of the two candidate fields returning 0 or 1) prefers the column-major order
    (MATLAB's ``N(:)``); :func:`load_diligent` chooses by how well each explains the images.
    Non-finite or zero normals become 0 (no normal), with a ``DataWarning`` when some lie inside
    ``mask``; ``UserError`` naming the file when it is unreadable or when no pixel of ``mask``
    (default: all) has a normal."""
    path = Path(path)
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
        if not np.issubdtype(arrays[key].dtype, np.number) or np.iscomplexobj(arrays[key]):
            raise UserError(f"{path}: variable {key} holds {arrays[key].dtype} values; save real numbers")
        n = np.asarray(arrays[key], np.float64)
    elif suffix == ".txt":
        t = table(path, what="normals (nx ny nz)")
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
        n = _normals_array(path)
    if n.shape != (h, w, 3):
        raise UserError(f"{path}: normals of shape {n.shape}, the images are {h} x {w}; give {h} x {w} x 3 normals")
    m = np.ones((h, w), bool) if mask is None else np.asarray(mask, bool)
    finite = np.isfinite(n).all(axis=-1)
    out = _unit(n)
    has = finite & (np.linalg.norm(out, axis=-1) > 0)
    if not (m & has).any():
        raise UserError(f"{path}: no finite, non-zero normal inside the mask; write the normals (nx ny nz) again")
    if (m & ~finite).any():
        warn(f"{path}: {int((m & ~finite).sum())} NaN or infinite normal(s) inside the mask; those pixels are not scored")
    return np.where(finite[..., None], out, 0.0)


def _normals_array(path: Path) -> np.ndarray:
    """Normals from an image / array file (float values; NaN kept for the caller)."""
    from pbrbench.io import read_image

    try:
        if path.stat().st_size == 0:
            raise UserError(f"{path}: an empty file (0 bytes); write the normals again")
    except OSError as e:
        raise UserError(f"{path}: cannot read ({e.strerror or e})") from None
    if path.suffix.lower() in (".npy", ".png", ".tif", ".tiff"):
        return np.asarray(load_image(path, "normals"), np.float64) if path.suffix.lower() != ".npy" \
            else _npy_normals(path)
    try:
        a = np.asarray(read_image(path))
    except MemoryError:
        raise UserError(f"{path}: too large to load; check the file") from None
    except Exception as e:  # noqa: BLE001 - decoders raise anything on damaged data
        raise UserError(f"{' '.join(str(e).split())[:200]}; not readable normals ({path}): write them again") from None
    if a.dtype.kind not in "uif":
        raise UserError(f"{path}: {a.dtype} values; save the normals as float numbers")
    return a.astype(np.float64)


def _npy_normals(path: Path) -> np.ndarray:
    from pbrbench.datasets.files import _header_values

    _header_values(path)   # refuses pickled arrays and damaged headers
    try:
        a = np.load(path, allow_pickle=False)
    except MemoryError:
        raise UserError(f"{path}: too large to load; check the file") from None
    except Exception as e:  # noqa: BLE001
        raise UserError(f"{path}: not a readable .npy file ({' '.join(str(e).split())[:160]}); save it with "
                        "numpy.save") from None
    if a.dtype.kind not in "uif":
        raise UserError(f"{path}: {a.dtype} values; save the normals as float numbers")
    return a.astype(np.float64)


def load_diligent(folder, *, indices=None, normals: bool = True, log=None) -> DiLiGenTObject:
    """Load one DiLiGenT object folder (see the module docstring).  ``indices`` selects lights
    (e.g. ``range(20, 96)``); a malformed folder raises ``UserError`` with one line."""

    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such folder")
    ld = find(folder, "light_directions.txt")
    if ld is None:
        raise UserError(f"{folder}: not a DiLiGenT object folder (no light_directions.txt)")
    dirs = table(ld, 3, "light directions (x y z)")
    li = find(folder, "light_intensities.txt")
    ints = table(li, what="light intensities (r g b)") if li is not None else np.ones_like(dirs)
    if ints.shape[1] not in (1, 3):
        raise UserError(f"{li}: {ints.shape[1]} columns; give one row per light of 3 intensities (r g b) or of 1")
    if ints.shape[1] == 1:
        ints = np.repeat(ints, 3, axis=1)
    bad = np.flatnonzero((ints <= 0).any(axis=1))
    if bad.size:
        raise UserError(f"{li}, row {bad[0] + 1}: intensities must be positive; drop the image of a light that is off")
    norms = np.linalg.norm(dirs, axis=1)
    bad = np.flatnonzero(norms < 1e-9)
    if bad.size:
        raise UserError(f"{ld}, row {bad[0] + 1}: a zero light direction; give a unit vector toward the light")
    files = _image_files(folder, len(dirs))
    if not (len(files) == len(dirs) == len(ints)):
        raise UserError(f"{folder}: {len(files)} images, {len(dirs)} light directions and {len(ints)} intensities; "
                        "they must match one to one")
    sel = list(range(len(files))) if indices is None else _indices(indices, len(files))
    files, dirs, ints, norms = [files[i] for i in sel], dirs[sel], ints[sel], norms[sel]
    off = np.flatnonzero(np.abs(norms - 1.0) > 0.01)
    if off.size:
        warn(f"{ld}: {off.size} light direction(s) not of unit length (row {sel[off[0]] + 1}: {norms[off[0]]:.3g}); "
             "normalised (intensities belong in light_intensities.txt)")
    dirs = dirs / norms[:, None]
    sv = np.linalg.svd(dirs, compute_uv=False) if len(dirs) >= 3 else np.zeros(3)
    if len(dirs) >= 3 and sv[2] < 1e-6 * sv[0]:
        raise UserError(f"{ld}: the light directions are {'collinear' if sv[1] < 1e-6 * sv[0] else 'coplanar'}; "
                        "photometric stereo needs lights in 3 independent directions")
    away = np.flatnonzero(dirs[:, 2] < 0)
    if away.size:
        warn(f"{ld}: {away.size} light direction(s) point away from the camera (z < 0, row {sel[away[0]] + 1}); "
             "check the frame: x right, y up, z toward the camera")
    if log:
        log(f"{folder.name}: reading {len(files)} images")
    raw = _read_images(files)
    imgs = _stack(raw, files, folder)
    tops = [np.iinfo(r.dtype).max if r.dtype.kind in "ui" else None for r in raw]
    del raw
    h, w = imgs.shape[1:3]
    mf = find_stem(folder, "mask")
    try:
        mask = read_mask(mf, (h, w)) if mf is not None else np.ones((h, w), bool)
    except ValueError as e:
        raise UserError(str(e)) from None
    _check_stack(imgs, tops, files, mask, folder)
    imgs = imgs / ints[:, None, None, :]
    n = None
    if normals:
        nf = find(folder, *NORMAL_FILES)
        if nf is not None:
            def choose(*fields):          # the order whose Lambertian shading fits the images best
                fits = [_fit(imgs.mean(-1), dirs, _unit(f), mask) for f in fields]
                return int(np.argmax(fits))

            n = read_normals(nf, (h, w), choose, mask=mask)
            n = np.where(mask[..., None], n, 0.0)
            if np.any(mask & (np.linalg.norm(n, axis=-1) == 0)):
                mask = mask & (np.linalg.norm(n, axis=-1) > 0)   # no normal: not scored
    return DiLiGenTObject(folder.name, folder, imgs, dirs, ints, mask, n, files)


def _indices(indices, k: int) -> list[int]:
    try:
        sel = [int(i) for i in indices]
    except (TypeError, ValueError):
        raise UserError(f"indices: {indices!r} is not a list of light numbers; pass e.g. range(20, {k})") from None
    bad = [i for i in sel if not -k <= i < k]
    if bad or not sel:
        raise UserError(f"indices: {bad[0] if bad else 'none'} is not a light of the {k}; pass numbers in 0..{k - 1}")
    return sel


def _read_images(files: list[Path]) -> list[np.ndarray]:
    """The images, PNGs decoded together (fast); any failure names its file."""
    from pbrbench.datasets.files import _header_values
    from pbrbench.io import read_pngs

    pngs = [f for f in files if f.suffix.lower() == ".png"]
    decoded = {}
    if pngs:
        for f in pngs:   # cheap checks first: missing, empty, oversized headers
            try:
                ok = f.is_file() and f.stat().st_size > 0 and (_header_values(f) or 0) <= MAX_VALUES
            except (OSError, UserError, ValueError):
                ok = False
            if not ok:
                load_image(f, "image")   # raises the precise message
        try:
            decoded = dict(zip(pngs, read_pngs(pngs), strict=True))
        except Exception:  # noqa: BLE001 - find the file one by one for the message
            decoded = {f: load_image(f, "image") for f in pngs}
    return [decoded[f] if f in decoded else load_image(f, "image") for f in files]


def _stack(raw: list, files: list[Path], folder: Path) -> np.ndarray:
    """(K, H, W, 3) float64 images; refuses mismatched shapes and unusable channel counts."""
    s0 = np.shape(raw[0])
    for r, f in zip(raw, files, strict=True):
        if np.shape(r) != s0:
            raise UserError(f"{f}: shape {np.shape(r)}, {files[0].name} is {s0}; the images must have one size and "
                            "channel count")
    if len(s0) == 3 and s0[2] > 4:
        raise UserError(f"{files[0]}: {s0[2]} channels; give grey, RGB or RGBA images")
    if len(raw) * s0[0] * s0[1] * 3 * 8 > MAX_STACK_BYTES:
        raise UserError(f"{folder}: {len(raw)} images of {s0[1]} x {s0[0]} are too large to load; pass indices to "
                        "select lights or downsample the images")
    try:
        imgs = np.empty((len(raw), s0[0], s0[1], 3))
    except MemoryError:
        raise UserError(f"{folder}: not enough memory for {len(raw)} images of {s0[1]} x {s0[0]}; pass indices to "
                        "select lights") from None
    for k, (r, f) in enumerate(zip(raw, files, strict=True)):
        try:
            a = to_float(r, f)
        except ValueError as e:
            raise UserError(str(e)) from None
        if a.ndim == 3:
            a = a[..., 0] if a.shape[2] in (1, 2) else a[..., :3]    # grey (+ alpha) or RGB (+ alpha)
        imgs[k] = a[..., None] if a.ndim == 2 else a
    return imgs


def _check_stack(imgs: np.ndarray, tops: list, files: list[Path], mask: np.ndarray, folder: Path) -> None:
    """Refuse an empty or mostly saturated stack; warn about images that add nothing."""
    inside = imgs[:, mask]                           # (K, P, 3)
    if not inside.any():
        raise UserError(f"{folder}: every image is 0 (black) inside the mask; check the exposure and the mask")
    neg = np.flatnonzero((inside < 0).any(axis=(1, 2)))
    if neg.size:
        warn(f"{files[neg[0]]}: negative pixel values (in {neg.size} image(s)); clip them to 0 if they are noise")
    sat = np.zeros(inside.shape[:2], bool)
    for k, top in enumerate(tops):
        if top is not None:
            sat[k] = (inside[k] >= 1.0).any(axis=-1)   # the top level scales to exactly 1
    frac = float(sat.mean())
    if frac > 0.5:
        raise UserError(f"{folder}: {frac:.0%} of the measurements inside the mask are saturated (the top level of "
                        f"{files[0].name}); photometric stereo needs unsaturated images: shorten the exposure")
    for k, f in enumerate(files):
        if not inside[k].any():
            warn(f"{f}: black (0) everywhere inside the mask; did the light fire? drop the image if not")
        elif sat[k].mean() > 0.5:
            warn(f"{f}: saturated at {sat[k].mean():.0%} of the mask; drop the image or shorten its exposure")
    if frac > 0.05:
        warn(f"{folder}: {frac:.0%} of the measurements inside the mask are saturated; they bias the normals")


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
