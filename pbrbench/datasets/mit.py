"""The MIT Intrinsic Images data set (Grosse, Johnson, Adelson & Freeman, ICCV 2009) as laid out on
disk, and its evaluation protocol.

One folder per object (``data/box``, ``data/cup1``, ...) with 16-bit PNGs, linear (captured
raw; the published code gamma-corrects only for display):

* ``diffuse.png`` (RGB): the image with the specular component removed -- the input;
* ``reflectance.png`` (RGB) and ``shading.png`` (grey): the ground truth;
* ``mask.png`` (grey): the object, non-zero inside (absent: every pixel);
* ``original.png``, ``specular.png`` and ``light01.png`` .. ``light10.png`` (ten lighting
  conditions), loaded when present.

Values are scaled to [0, 1] by 1/65535 (the published loader divides by 255; LMSE does not
depend on the scale, except its guard ``alpha = 0`` for windows whose estimate has energy below
1e-5).

Protocol (the published ``comparison.py`` / ``intrinsic.score_image``), grey: the input is the
channel mean of ``diffuse``, the true reflectance the channel mean of ``reflectance``, the true
shading ``shading``; the score is

    0.5 LMSE(shading) + 0.5 LMSE(reflectance),

each LMSE with 20 x 20 windows every 10 pixels (:func:`pbrbench.metrics.lightness.lmse`, which
is the published ``local_error``), over the mask.  The published table is the mean over the 16
objects of ``SET1 + SET2`` (:data:`EVALUATED`; apple, pear, phone and potato were left out).

Checks (a malformed folder raises :class:`~pbrbench.errors.UserError` with one line naming the
file and the fix; data that may still be valid gives a
:class:`~pbrbench.datasets.files.DataWarning` and is kept):

* refused: a missing, empty, damaged, pickled or oversized image; NaN or infinite pixels or
  mask values; images of different sizes; ``diffuse`` or ``reflectance`` without 3 channels;
  a mask with no pixel inside; ``diffuse``, ``reflectance`` or ``shading`` 0 everywhere inside
  the mask (nothing to decompose or to score against); ``diffuse`` saturated (the top level of
  an 8- or 16-bit file) at more than half of the mask;
* warned: ``diffuse`` saturated at more than 5 % of the mask; negative pixel values.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrbench.datasets.files import find_stem, load_image, read_mask, to_float, warn
from pbrbench.errors import UserError

__all__ = ["MITObject", "load_mit_object", "mit_objects", "is_mit", "mit_scores", "EVALUATED", "WINDOW", "STEP"]

EVALUATED = ("box", "cup1", "cup2", "dinosaur", "panther", "squirrel", "sun", "teabag2",
             "deer", "frog1", "frog2", "paper1", "paper2", "raccoon", "teabag1", "turtle")
WINDOW, STEP = 20, 10


@dataclass
class MITObject:
    """One object: ``image`` the grey input (channel mean of ``diffuse``), ``diffuse`` (H, W, 3),
    ``reflectance`` (H, W, 3), ``shading`` (H, W), ``mask`` (H, W) bool, and ``extra``: the other
    images present (``original``, ``specular``, ``lights`` (10, H, W, 3))."""

    name: str
    path: Path
    diffuse: np.ndarray
    reflectance: np.ndarray
    shading: np.ndarray
    mask: np.ndarray
    extra: dict = field(default_factory=dict)

    @property
    def image(self) -> np.ndarray:
        return self.diffuse.mean(axis=-1)

    @property
    def reflectance_grey(self) -> np.ndarray:
        return self.reflectance.mean(axis=-1) if self.reflectance.ndim == 3 else self.reflectance


def is_mit(folder) -> bool:
    f = Path(folder)
    return find_stem(f, "diffuse", (".png",)) is not None and find_stem(f, "reflectance", (".png",)) is not None


def mit_objects(root) -> list[Path]:
    """The object folders at or below ``root`` (an object, ``data`` or the data set's top)."""
    root = Path(root)
    if is_mit(root):
        return [root]
    return [d for d in sorted(p for p in root.rglob("*") if p.is_dir() and len(p.relative_to(root).parts) <= 3)
            if is_mit(d)]


def _read(folder: Path, stem: str, required: bool = True, top: list | None = None):
    f = find_stem(folder, stem, (".png", ".tif", ".tiff", ".exr", ".npy"))
    if f is None:
        if required:
            raise UserError(f"{folder}: no {stem}.png (an MIT Intrinsic Images object folder has diffuse.png, "
                            "reflectance.png, shading.png and mask.png)")
        return None, None
    raw = load_image(f, f"{stem} image")
    if top is not None:
        top.append(np.iinfo(raw.dtype).max if raw.dtype.kind in "ui" else None)
    try:
        a = to_float(raw, f)
    except ValueError as e:
        raise UserError(f"{e}: save it as an 8- or 16-bit PNG") from None
    if a.ndim == 3 and a.shape[2] > 4:
        raise UserError(f"{f}: {a.shape[2]} channels; give a grey or RGB image")
    if (a < 0).any():
        warn(f"{f}: negative pixel values; clip them to 0 if they are noise")
    return a, f


def load_mit_object(folder, *, lights: bool = False) -> MITObject:
    """Load one object folder (see the module docstring); ``lights``: also the ten
    ``lightNN.png`` images.  A malformed folder raises ``UserError`` with one line."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such folder")
    top: list = []
    diffuse, fd = _read(folder, "diffuse", top=top)
    refl, fr = _read(folder, "reflectance")
    shad, fs = _read(folder, "shading")
    for a, f in ((diffuse, fd), (refl, fr)):
        if a.ndim == 2:
            a = np.repeat(a[..., None], 3, -1)
        if a.ndim != 3 or a.shape[2] < 3:
            raise UserError(f"{f}: shape {a.shape}; expected an RGB image")
    diffuse = diffuse if diffuse.ndim == 3 else np.repeat(diffuse[..., None], 3, -1)
    refl = refl if refl.ndim == 3 else np.repeat(refl[..., None], 3, -1)
    diffuse, refl = diffuse[..., :3], refl[..., :3]
    shad = shad[..., :3].mean(axis=-1) if shad.ndim == 3 else shad
    h, w = diffuse.shape[:2]
    for a, f in ((refl, fr), (shad, fs)):
        if a.shape[:2] != (h, w):
            raise UserError(f"{f}: {a.shape[0]} x {a.shape[1]} pixels, diffuse.png is {h} x {w}")
    mf = find_stem(folder, "mask", (".png", ".tif", ".npy"))
    try:
        mask = read_mask(mf, (h, w)) if mf is not None else np.ones((h, w), bool)
    except ValueError as e:
        raise UserError(str(e)) from None
    for a, f in ((diffuse, fd), (refl, fr), (shad, fs)):
        if not (a[mask] != 0).any():
            raise UserError(f"{f}: 0 everywhere inside the mask; give the object's image (check the file and mask.png)")
    if top[0] is not None:
        sat = float((diffuse[mask] >= 1.0).any(axis=-1).mean())   # the top level scales to exactly 1
        if sat > 0.5:
            raise UserError(f"{fd}: saturated at {sat:.0%} of the mask; give an unsaturated (linear, raw) image")
        if sat > 0.05:
            warn(f"{fd}: saturated at {sat:.0%} of the mask; the decomposition there is unreliable")
    extra = {}
    for stem in ("original", "specular"):
        a, f = _read(folder, stem, required=False)
        if a is not None:
            _same_size(a, f, h, w)
            extra[stem] = a
    if lights:
        stack = []
        for k in range(1, 11):
            a, f = _read(folder, f"light{k:02d}", required=False)
            if a is not None:
                _same_size(a, f, h, w)
                if stack and a.shape != stack[0].shape:
                    raise UserError(f"{f}: shape {a.shape}, the first light image is {stack[0].shape}; give them alike")
                stack.append(a)
        if stack:
            extra["lights"] = np.stack(stack)
    return MITObject(folder.name, folder, diffuse, refl, shad, mask, extra)


def _same_size(a, f, h, w):
    if a.shape[:2] != (h, w):
        raise UserError(f"{f}: {a.shape[0]} x {a.shape[1]} pixels, diffuse.png is {h} x {w}; give images of one size")


def mit_scores(reflectance, shading, obj: MITObject) -> dict:
    """The protocol's scores of a grey (reflectance, shading) estimate: ``intrinsic_lmse``
    (0.5 shading + 0.5 reflectance LMSE), and the two terms ``lmse_reflectance`` and
    ``lmse_shading`` (window 20, step 10, over the mask)."""
    from pbrbench.metrics.lightness import lmse

    r = np.asarray(reflectance, float)
    s = np.asarray(shading, float)
    r = r.mean(axis=-1) if r.ndim == 3 else r
    s = s.mean(axis=-1) if s.ndim == 3 else s
    lr = lmse(r, obj.reflectance_grey, mask=obj.mask, window=WINDOW, step=STEP)
    ls = lmse(s, obj.shading, mask=obj.mask, window=WINDOW, step=STEP)
    return {"intrinsic_lmse": 0.5 * ls + 0.5 * lr, "lmse_reflectance": lr, "lmse_shading": ls}
