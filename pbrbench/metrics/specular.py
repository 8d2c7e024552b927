"""Scores for specularity detection and removal (docs/science.md §1).

The ground truth comes from a *diffuse-only twin*: the same scene rendered with the glossy
lobe switched off.  ``radiance - diffuse_only`` is the specular component.

Objects
-------
- :func:`specular_mask_from_twin` -- ground-truth specular mask from the twin.
- :func:`mask_iou` -- intersection over union of two masks.
- :func:`removal_errors` -- error of a specular-free estimate vs the twin, inside the mask and
  in a ring around it.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from pbrbench.checks import as_float_array, check_finite, check_mask, check_method
from pbrbench.metrics.table import table

__all__ = ["specular_scores", "METRICS", "specular_mask_from_twin", "mask_iou", "removal_errors", "REFERENCES"]

REFERENCES = ("peak", "local", "absolute")


def _brightness(a):
    return a if a.ndim == 2 else a.mean(axis=-1)


def specular_mask_from_twin(radiance, diffuse_only, *, threshold: float = 0.1,
                            reference: str = "peak", mask=None, window: int = 1) -> np.ndarray:
    r"""Pixels where the specular component ``s = radiance - diffuse_only`` is significant.

    With ``s`` and the diffuse ``d`` averaged over channels (and, with ``window > 1``, ``s``
    averaged over the ``window x window`` neighbourhood's pixels inside ``mask``), a pixel is
    specular when

    - ``reference="peak"`` (default): ``s > threshold * max_mask(d)`` (a fraction of the
      brightest diffuse radiance; insensitive to dark pixels and Monte Carlo noise there);
    - ``reference="local"``: ``s > threshold * d`` (a fraction of the pixel's own diffuse);
    - ``reference="absolute"``: ``s > threshold`` in radiance units.

    ``window``: an odd box size.  Both renders are Monte Carlo estimates, and where a broad
    glossy lobe's tail lies near the level (rough plastic), the noise of single pixels decides
    which cross it: on the standard render of ``specular_shapes`` the pixelwise mask was 406 and
    362 pixels at two render seeds, in 222 components, and the two masks shared 193 pixels.  The
    lobe is smooth and the noise is not, so a 3 x 3 mean (the specular task's choice) gives 193
    pixels at both seeds, 22 of them different.

    Returns
    -------
    (H, W) bool.
    """
    win = int(window) if isinstance(window, (int, np.integer)) and not isinstance(window, bool) else -1
    if win < 1 or win % 2 == 0:
        raise ValueError(f"window: must be an odd integer >= 1 (1 = no averaging), got {window!r}")
    rad = as_float_array(radiance, "radiance", ndim=(2, 3))
    dif = as_float_array(diffuse_only, "diffuse_only", ndim=(2, 3))
    if rad.shape != dif.shape:
        raise ValueError(f"diffuse_only: shape {dif.shape} differs from radiance shape {rad.shape}; "
                         "pass the twin render of the same scene")
    check_method(reference, REFERENCES, "reference")
    t = float(threshold)
    if not (np.isfinite(t) and t >= 0):
        raise ValueError(f"threshold: must be a finite number >= 0, got {threshold!r}")
    m = check_mask(mask, rad.shape[:2])
    check_finite(rad, "radiance", where=m)
    check_finite(dif, "diffuse_only", where=m)
    s = _brightness(rad) - _brightness(dif)
    d = _brightness(dif)
    if win > 1:
        from scipy.ndimage import uniform_filter

        w = uniform_filter(m.astype(np.float64), win, mode="constant")
        s = uniform_filter(np.where(m, s, 0.0), win, mode="constant") / np.where(w > 0, w, 1.0)
    if reference == "peak":
        level = t * float(d[m].max())
    elif reference == "local":
        level = t * d
    else:
        level = t
    return m & (s > level)


def mask_iou(pred, true) -> float:
    """``|pred & true| / |pred | true|``; 1.0 when both masks are empty (perfect agreement)."""
    p = np.asarray(pred)
    t = np.asarray(true)
    if p.shape != t.shape:
        raise ValueError(f"pred: shape {p.shape} differs from true shape {t.shape}; pass masks of one shape")
    p, t = p.astype(bool), t.astype(bool)
    union = int(np.sum(p | t))
    return 1.0 if union == 0 else float(np.sum(p & t) / union)


def removal_errors(removed, diffuse_only, mask, *, ring: int = 3, valid=None) -> dict[str, float]:
    """Error of a specular-free estimate vs the diffuse-only twin, inside and around ``mask``.

    ``inside`` is ``mask``; ``ring`` is ``dilate(mask, ring) & ~mask`` (pixels within ``ring``
    steps of a 3x3 dilation), both restricted to ``valid``.  Returns the RMS error over the
    region's pixels and channels (``*_rmse``) and the same divided by the twin's RMS value in
    the region (``*_rel``); NaN for an empty region.
    """
    est = as_float_array(removed, "removed", ndim=(2, 3))
    tru = as_float_array(diffuse_only, "diffuse_only", ndim=(2, 3))
    if est.shape != tru.shape:
        raise ValueError(f"removed: shape {est.shape} differs from diffuse_only shape {tru.shape}")
    m = np.asarray(mask)
    if m.shape != est.shape[:2]:
        raise ValueError(f"mask: shape {m.shape} does not match the image shape {est.shape[:2]}")
    m = m.astype(bool)
    v = check_mask(valid, est.shape[:2], "valid")
    k = int(ring)
    if k < 1:
        raise ValueError(f"ring: must be an integer >= 1, got {ring!r}")
    check_finite(est, "removed", where=v)
    check_finite(tru, "diffuse_only", where=v)
    around = (ndimage.binary_dilation(m, iterations=k) if m.any() else m) & ~m
    out = {}
    for name, region in (("inside", m & v), ("ring", around & v)):
        if not region.any():
            out[f"{name}_rmse"] = out[f"{name}_rel"] = float("nan")
            continue
        diff = est[region] - tru[region]
        rmse = float(np.sqrt(np.mean(diff * diff)))
        ref = float(np.sqrt(np.mean(tru[region] ** 2)))
        out[f"{name}_rmse"] = rmse
        out[f"{name}_rel"] = rmse / ref if ref > 0 else float("nan")
    return out


def specular_scores(removed, diffuse_only, true_mask, valid, *, detected=None) -> dict[str, float]:
    """The specular task's scores of one estimate: ``inside_rel`` and ``ring_rel`` of
    :func:`removal_errors` (when defined), ``image_rel_rmse`` (relative RMS error vs the twin over
    ``valid``) and, when the detected mask is given, ``mask_iou``."""
    sc = removal_errors(removed, diffuse_only, true_mask, valid=valid)
    out = {k: v for k, v in sc.items() if k in ("inside_rel", "ring_rel") and np.isfinite(v)}
    if detected is not None:
        out["mask_iou"] = mask_iou(detected, true_mask)
    obj = np.asarray(valid, bool)
    twin = np.asarray(diffuse_only, np.float64)
    d = (np.asarray(removed, np.float64) - twin)[obj]
    ref = float(np.sqrt(np.mean(twin[obj] ** 2))) if obj.any() else 0.0
    if ref > 0:
        out["image_rel_rmse"] = float(np.sqrt(np.mean(d * d))) / ref
    return out


METRICS = table("""
mask_iou       | higher | fraction | specular_scores | intersection over union of the detected and the true specular mask
inside_rel     | lower  | fraction | specular_scores | relative RMS error vs the diffuse-only twin inside the true specular mask
ring_rel       | lower  | fraction | specular_scores | relative RMS error vs the twin in a 3-pixel ring around the true mask
image_rel_rmse | lower  | fraction | specular_scores | relative RMS error vs the twin over the whole object
""")
