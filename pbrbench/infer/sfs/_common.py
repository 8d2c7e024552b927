r"""What every shape-from-shading method shares: result records, input preparation, the
reflectance map, silhouette helpers and the least-squares integrator.

The model they share (the image irradiance equation, the frame, the pixel units) is stated once,
in the docstring of :mod:`pbrbench.infer.sfs`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_mask,
    check_pixel_size,
    check_positive,
)
from pbrbench.infer._scale import robust_norm
from pbrbench.infer.integration import gradients_from_height, integrate_lsq, normals_from_gradients

__all__ = ["SFSResult", "LightEstimate", "integrate_gradients", "occluding_boundary"]



# numpydoc fragments shared by the methods' docstrings (pbrbench.infer._docstring)
DOCS = {
    "raises": """\
Raises
------
ValueError
    On bad input (see :func:`pbrbench.infer.sfs.shape_from_shading`) or a bad option value.""",
    "light_result": """\
Returns
-------
LightEstimate
    ``direction`` (3,) unit vector toward the source (``z >= 0``), ``albedo``, and ``method``
    (the method's name in :data:`pbrbench.infer.sfs.LIGHT_METHODS`).

Raises
------
ValueError
    On a bad image or mask, or (for the contour method) too few lit contour pixels.""",
}

@dataclass(frozen=True)
class SFSResult:
    """Result of :func:`pbrbench.infer.sfs.shape_from_shading` (and of every method function).

    Attributes
    ----------
    height : (H, W) float64
        Height ``z`` in the units of ``pixel_size``, mean zero over the mask (the free offset),
        0 outside the mask.  Larger is closer to the camera.
    normals : (H, W, 3) float64
        Unit normals in the camera frame; (0, 0, 0) outside the mask.
    converged : bool
        True when the method met its tolerance (or is direct, as ``pentland1990``).
    n_iter : int
        Iterations used (0 for direct methods, marched pixels for ``kimmel2001``).
    method : str
    light : (3,) float64
        The unit light direction used.
    albedo : float
        The albedo used to normalise the image.
    seconds : float
        Wall-clock time of the solve.
    info : dict
        Method-specific diagnostics (final update size, seeds, ...).
    """

    height: np.ndarray
    normals: np.ndarray
    converged: bool
    n_iter: int
    method: str
    light: np.ndarray
    albedo: float
    seconds: float
    info: dict = field(default_factory=dict)


@dataclass(frozen=True)
class LightEstimate:
    """Result of :func:`pbrbench.infer.sfs.light_from_shading`: unit ``direction`` (3,), ``albedo``, ``method``."""

    direction: np.ndarray
    albedo: float
    method: str


def _reflectance(p, q, s):
    """``R(p, q)`` (unclipped), ``dR/dp``, ``dR/dq`` for unit light ``s``."""
    d2 = 1.0 + p * p + q * q
    d = np.sqrt(d2)
    num = s[2] - s[0] * p - s[1] * q
    r = num / d
    d3 = d2 * d
    rp = (-s[0] * d2 - num * p) / d3
    rq = (-s[1] * d2 - num * q) / d3
    return r, rp, rq


def integrate_gradients(p, q, *, mask=None, pixel_size: float = 1.0) -> np.ndarray:
    r"""Least-squares height from slopes ``p = f_x``, ``q = f_y`` with the shared integrator.

    .. math:: \min_z \sum_{\text{edges}} (\Delta z - g)^2, \quad
        g_x = h \frac{p_j + p_{j+1}}{2}, \; g_y = -h \frac{q_i + q_{i+1}}{2}

    (rows go down, y up): :func:`pbrbench.infer.integration.integrate_lsq` on the mask.  The same
    function gives the SFS methods' heights and the metric's floor
    (:func:`pbrbench.metrics.sfs.floor_height`), so both share one integrator.

    Returns the height (H, W) in units of ``pixel_size``, mean zero on each connected component
    of ``mask``, 0 outside.
    """
    p = np.asarray(p, float)
    q = np.asarray(q, float)
    m = check_mask(mask, p.shape)
    h = check_pixel_size(pixel_size)
    p0 = np.where(m, p, 0.0)
    q0 = np.where(m, q, 0.0)
    z = integrate_lsq(gradients=(p0, q0), mask=m, pixel_size=h)
    z = np.where(m, z, 0.0)
    z[m] -= z[m].mean()
    return z


def occluding_boundary(mask, *, exclude_border: bool = True) -> np.ndarray:
    """Pixels of ``mask`` with a 4-neighbour outside it: candidate occluding-contour pixels.

    With ``exclude_border`` pixels on the image frame are not counted (a mask cut by the frame is
    not an occluding contour there).
    """
    m = np.asarray(mask, bool)
    inner = ndimage.binary_erosion(m, structure=ndimage.generate_binary_structure(2, 1), border_value=1)
    b = m & ~inner
    if exclude_border:
        b[0, :] = b[-1, :] = False
        b[:, 0] = b[:, -1] = False
    return b


def _outward_directions(mask, sigma: float = 1.5):
    """Unit outward 2-D normals (dx, dy) of the silhouette, in the xy frame (y up)."""
    sm = ndimage.gaussian_filter(mask.astype(float), sigma)
    gr, gc = np.gradient(sm)
    dx, dy = -gc, gr  # outward = -grad(mask); y up flips the row component
    nrm = np.hypot(dx, dy)
    nrm[nrm == 0] = 1.0
    return dx / nrm, dy / nrm


def _prepare(image, light, albedo, mask, pixel_size):
    """The common input step of every method: ``(E, S, mask, albedo, pixel_size)``.

    ``E = clip(image / albedo, 0, 1)`` inside the mask (0 outside), ``S`` the unit light; the
    albedo defaults to the brightest pixel in the mask.  Raises ``ValueError`` on a bad image,
    mask, light (not a 3-vector, zero, or ``S_z <= 0``), albedo or pixel size.
    """
    img = as_float_array(image, "image", ndim=(2,))
    m = check_mask(mask, img.shape)
    check_finite(img, "image", where=m)
    if np.any(img[m] < 0):
        raise ValueError("image: has negative values inside the mask; pass a linear image (>= 0), "
                         "e.g. np.clip(image, 0, None)")
    s = as_float_array(light, "light", ndim=(1,))
    if s.shape != (3,):
        raise ValueError(f"light: expected a 3-vector (x, y, z) toward the source, got shape {s.shape}")
    check_finite(s, "light")
    ns = float(robust_norm(s))   # a direction: 1e300 or 1e-300 long is still one
    if ns == 0:
        raise ValueError("light: zero vector; pass a direction toward the source, e.g. (0, 0, 1)")
    s = s / ns
    if s[2] <= 0:
        raise ValueError(f"light: z component {s[2]:.3g} <= 0 (light behind the surface); the "
                         "camera looks along -z, so pass a light with z > 0")
    h = check_pixel_size(pixel_size)
    if albedo is None:
        rho = float(img[m].max())
        if rho <= 0:
            raise ValueError("image: all zero inside the mask; shape from shading needs a lit surface")
    else:
        rho = check_positive(albedo, "albedo")
    e = np.clip(np.where(m, img / rho, 0.0), 0.0, 1.0)
    return e, s, m, rho, h


def _is_frontal(s) -> bool:
    """True for a light along the view (``S_x = S_y = 0`` to 1e-6)."""
    return float(np.hypot(s[0], s[1])) < 1e-6


def _finish(z, p, q, m, h, *, method, converged, n_iter, s, rho, t0, info, image=None, hint: str = "") -> SFSResult:
    """The common end of every method: height ``z`` (world units) to mean zero on the mask, NaN
    to 0, normals from ``(p, q)`` (or, when ``p`` is None, from the height's slopes).

    A flat result from an ``image`` that varies inside the mask is a failure, never a success: the
    method returned its start (a fixed point of its iteration).  ``converged`` is then False,
    ``info["failure"]`` says why (with ``hint``, the method's way out), and a ``RuntimeWarning``
    is raised."""
    z = np.where(m, np.nan_to_num(z), 0.0)
    z[m] -= z[m].mean()
    if image is not None and m.any():
        e = np.asarray(image, float)[m]
        flat = float(np.ptp(z[m])) <= 1e-9 * max(1.0, float(h) * max(m.shape))
        flat &= p is None or (float(np.nanmax(np.abs(np.asarray(p)[m]), initial=0.0)) <= 1e-12
                              and float(np.nanmax(np.abs(np.asarray(q)[m]), initial=0.0)) <= 1e-12)
        if flat and float(np.ptp(e)) > 1e-6 * max(float(np.abs(e).max()), 1e-300):
            msg = (f"{method}: returned a flat surface although the image varies inside the mask: its start is a "
                   "fixed point of the iteration" + (f"; {hint}" if hint else ""))
            info = {**info, "failure": msg}
            converged = False
            import warnings

            warnings.warn(msg, RuntimeWarning, stacklevel=3)
    if p is None:
        p, q = gradients_from_height(z, m, pixel_size=h)
    normals = normals_from_gradients(np.nan_to_num(p), np.nan_to_num(q), m)
    return SFSResult(height=z, normals=normals, converged=bool(converged), n_iter=int(n_iter), method=method,
                     light=s, albedo=rho, seconds=time.perf_counter() - t0, info=info)


def _prepare_light_image(image, mask):
    """Checked image and mask of a light estimator; raises on negative or all-zero input."""
    img = as_float_array(image, "image", ndim=(2,))
    m = check_mask(mask, img.shape)
    check_finite(img, "image", where=m)
    if np.any(img[m] < 0):
        raise ValueError("image: has negative values inside the mask; pass a linear image (>= 0)")
    imax = float(img[m].max())
    if imax <= 0:
        raise ValueError("image: all zero inside the mask; the light cannot be estimated")
    return img, m, imax
