r"""Scores for shape from one shaded image (the model of :mod:`pbrbench.infer.sfs`).

Height errors are computed after removing the free offset (``offset``) and, reported
separately, after the best affine fit ``a z + b`` (``scale_offset``; least squares over the mask),
which forgives a wrong overall depth scale (e.g. from a wrong albedo or pixel size).  Every method
is reported beside two references:

- the **flat baseline**: height constant, normals ``(0, 0, 1)`` (what "no shape" scores);
- the **floor**: the true normals (gradients) integrated by the same least-squares integrator the
  methods use (:func:`pbrbench.infer.sfs.integrate_gradients`), with normals taken from that
  height the same way a method's height-based normals are.  It is the error the discretisation
  and integration alone would leave.

Objects
-------
height_errors, normal_angle, flat_baseline, floor_height, floor_scores, ambiguity_aware_scores,
sfs_scores.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_mask, check_positive
from pbrbench.metrics.table import table

__all__ = [
    "height_errors",
    "normal_angle",
    "flat_baseline",
    "floor_height",
    "floor_scores",
    "ambiguity_aware_scores",
    "sfs_scores",
]


def _pair(est, true, mask, name="height"):
    e = as_float_array(est, name, ndim=(2,))
    t = as_float_array(true, f"true_{name}", ndim=(2,))
    if e.shape != t.shape:
        raise ValueError(f"{name}: shape {e.shape} differs from the true {name} shape {t.shape}; pass arrays of one shape")
    m = check_mask(mask, e.shape)
    check_finite(e, name, where=m)
    check_finite(t, f"true_{name}", where=m)
    return e, t, m


def height_errors(height, true_height, mask=None) -> dict:
    """Height RMSE and MAE after removing the offset, and after the best scale + offset.

    ``offset``: ``d = (z - mean z) - (z* - mean z*)`` over the mask.
    ``scale_offset``: ``d = a z + b - z*`` with ``(a, b)`` the least-squares fit over the mask
    (``a`` is reported; a negative ``a`` means the estimate is inverted).

    Returns
    -------
    dict with keys ``rmse``, ``mae`` (offset removed), ``rmse_scaled``, ``mae_scaled``, ``scale``.
    """
    e, t, m = _pair(height, true_height, mask)
    ev, tv = e[m], t[m]
    d = (ev - ev.mean()) - (tv - tv.mean())
    ec = ev - ev.mean()
    var = float(ec @ ec)
    a = float(ec @ (tv - tv.mean())) / var if var > 0 else 0.0
    ds = a * ec - (tv - tv.mean())
    return {
        "rmse": float(np.sqrt(np.mean(d * d))),
        "mae": float(np.mean(np.abs(d))),
        "rmse_scaled": float(np.sqrt(np.mean(ds * ds))),
        "mae_scaled": float(np.mean(np.abs(ds))),
        "scale": a,
    }


def normal_angle(normals, true_normals, mask=None) -> float:
    """Mean angle (degrees) between estimated and true normals over the mask (normalised here)."""
    n = as_float_array(normals, "normals", ndim=(3,))
    t = as_float_array(true_normals, "true_normals", ndim=(3,))
    if n.shape != t.shape or n.shape[-1] != 3:
        raise ValueError(f"normals: shape {n.shape} must equal the true normals' shape {t.shape} and be (H, W, 3)")
    m = check_mask(mask, n.shape[:2])
    check_finite(n, "normals", where=m)
    check_finite(t, "true_normals", where=m)
    a, b = n[m], t[m]
    na = np.linalg.norm(a, axis=-1)
    nb = np.linalg.norm(b, axis=-1)
    if np.any(na == 0) or np.any(nb == 0):
        raise ValueError("normals: zero vector inside the mask; every masked pixel needs a normal")
    c = np.clip(np.sum(a * b, axis=-1) / (na * nb), -1.0, 1.0)
    return float(np.degrees(np.arccos(c)).mean())


_NAMES = {"rmse": "height_rmse", "mae": "height_mae", "rmse_scaled": "height_rmse_scaled",
          "mae_scaled": "height_mae_scaled", "normal_angle": "normal_mean_deg"}


def _named(scores: dict, height_range: float | None) -> dict:
    """Score names of the metrics table (``height_rmse`` ...), plus ``height_rmse_rel`` when the
    true height range is given."""
    out = {_NAMES[k]: float(v) for k, v in scores.items() if k in _NAMES}
    if height_range and "height_rmse" in out:
        out["height_rmse_rel"] = out["height_rmse"] / float(height_range)
    return out


def flat_baseline(true_height, true_normals, mask=None, *, height_range: float | None = None) -> dict:
    """Scores of the flat surface (height constant, normals (0, 0, 1)): the "no shape" baseline."""
    t = as_float_array(true_height, "true_height", ndim=(2,))
    flat_n = np.zeros(t.shape + (3,))
    flat_n[..., 2] = 1.0
    out = height_errors(np.zeros_like(t), t, mask)
    out["normal_angle"] = normal_angle(flat_n, true_normals, mask)
    return _named(out, height_range)


def floor_height(true_normals, mask=None, *, pixel_size: float = 1.0) -> np.ndarray:
    """The true normals integrated by the SFS methods' integrator (mean zero on the mask)."""
    from pbrbench.infer.sfs import integrate_gradients  # noqa: PLC0415

    n = as_float_array(true_normals, "true_normals", ndim=(3,))
    m = check_mask(mask, n.shape[:2])
    check_finite(n, "true_normals", where=m)
    nz = n[..., 2]
    if np.any(nz[m] <= 0):
        raise ValueError("true_normals: N_z <= 0 inside the mask; the normals must face the camera (z up)")
    nzs = np.where(m, nz, 1.0)
    p = np.where(m, -n[..., 0] / nzs, 0.0)
    q = np.where(m, -n[..., 1] / nzs, 0.0)
    return integrate_gradients(p, q, mask=m, pixel_size=check_positive(pixel_size, "pixel_size"))


def floor_scores(true_height, true_normals, mask=None, *, pixel_size: float = 1.0,
                 height_range: float | None = None) -> dict:
    """Scores of the floor: height errors of :func:`floor_height` and the mean angle of the
    normals recomputed from that height by central differences (as for height-based methods)."""
    from pbrbench.infer.integration import gradients_from_height, normals_from_gradients  # noqa: PLC0415

    h = check_positive(pixel_size, "pixel_size")
    m = check_mask(mask, np.shape(true_height))
    z = floor_height(true_normals, m, pixel_size=h)
    out = height_errors(z, true_height, m)
    p, q = gradients_from_height(z, m, pixel_size=h)
    out["normal_angle"] = normal_angle(normals_from_gradients(p, q, m), true_normals, m)
    return _named(out, height_range)


def ambiguity_aware_scores(height, normals, true_height, true_normals, mask=None) -> dict:
    """Scores that forgive the convex/concave ambiguity: the better of the estimate and its
    reflection ``z -> -z`` (normals ``(N_x, N_y, N_z) -> (-N_x, -N_y, N_z)``).

    Under a light along the view, ``z`` and ``-z`` produce the same image, so a method cannot
    tell a bump from a dent; under an oblique light the exact mirror is the reflection about the
    light's axis, but ``-z`` is what a person perceives as "inside out", is defined without the
    light, and equals the exact mirror for the frontal case, so we use it.  The minimum is taken
    separately for the height RMSE and the normal angle; ``flipped`` says which won for the angle.
    """
    e, t, m = _pair(height, true_height, mask)
    he = height_errors(e, t, m)
    hf = height_errors(-e, t, m)
    n = as_float_array(normals, "normals", ndim=(3,))
    nf = n * np.array([-1.0, -1.0, 1.0])
    a0 = normal_angle(n, true_normals, m)
    a1 = normal_angle(nf, true_normals, m)
    return {
        "rmse": min(he["rmse"], hf["rmse"]),
        "mae": min(he["mae"], hf["mae"]),
        "normal_angle": min(a0, a1),
        "flipped": bool(a1 < a0),
    }


def sfs_scores(height, normals, true_height, true_normals, mask=None, *, height_range: float | None = None) -> dict:
    """All scores of one estimate, named as in :data:`METRICS`: the :func:`height_errors` of the
    height (``height_rmse``, ``height_mae``, ``height_rmse_scaled``, ``height_mae_scaled``), the
    mean normal angle (``normal_mean_deg``), the ambiguity-aware ``height_rmse_flip`` /
    ``normal_mean_deg_flip`` and, given the true height range, ``height_rmse_rel``."""
    out = height_errors(height, true_height, mask)
    out["normal_angle"] = normal_angle(normals, true_normals, mask)
    out = _named(out, height_range)
    amb = ambiguity_aware_scores(height, normals, true_height, true_normals, mask)
    out["height_rmse_flip"] = float(amb["rmse"])
    out["normal_mean_deg_flip"] = float(amb["normal_angle"])
    return out


METRICS = table("""
height_rmse          | lower | world units | sfs_scores             | height RMSE after removing the free offset
height_mae           | lower | world units | sfs_scores             | mean absolute height error after removing the free offset
height_rmse_scaled   | lower | world units | sfs_scores             | height RMSE after the best scale and offset
height_mae_scaled    | lower | world units | sfs_scores             | mean absolute height error after the best scale and offset
height_rmse_rel      | lower | fraction    | sfs_scores             | height RMSE relative to the true height range
normal_mean_deg      | lower | deg         | sfs_scores             | mean angle between estimated and true normals
height_rmse_flip     | lower | world units | ambiguity_aware_scores | height RMSE of the better of z and -z (convex/concave ambiguity)
normal_mean_deg_flip | lower | deg         | ambiguity_aware_scores | mean normal angle of the better of z and -z
light_error_deg      | lower | deg         | -                      | angle between the estimated and the true light direction
""")
