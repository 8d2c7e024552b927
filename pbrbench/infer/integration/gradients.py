r"""Gradient fields of surfaces: normals <-> slopes, slopes of a height map, integrability.

Frame (``docs/conventions.md``): x right, y up, z toward the camera; row 0 is the top, so ``y``
decreases with the row index.  A Monge patch ``z = f(x, y)`` has unit normal

.. math:: N = \frac{(-f_x, -f_y, 1)}{\sqrt{1 + f_x^2 + f_y^2}},

hence ``p = f_x = -N_x/N_z`` and ``q = f_y = -N_y/N_z``.  On the pixel grid (pixel size ``h``),
moving one column right changes the height by about ``h p`` and moving one row *down* by about
``-h q``.

Objects
-------
normals_to_gradients
    ``(p, q, valid)`` of a normal field.
normals_from_gradients
    Unit normals of slopes ``(p, q)``.
gradients_from_height
    Slopes of a height map by masked central differences.
integrability_residual
    ``dp/dy - dq/dx``, the chapter's integrability check.

The private helpers (``_prepare``, ``_edge_gradients``) are the input handling every integrator
of :mod:`pbrbench.infer.integration` shares.

References
----------
D. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, chapter "Light and Shading",
Algorithm 1.2 (photometric stereo with the integrability check).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_mask,
    check_number,
    check_pixel_size,
)
from pbrbench.infer._scale import robust_norm

__all__ = ["DOCS", "normals_to_gradients", "normals_from_gradients", "gradients_from_height", "integrability_residual"]

# numpydoc fragments shared by the integrators' docstrings (pbrbench.infer._docstring)
DOCS = {
    "inputs": """\
normals : (H, W, 3) array, optional
    Normals in the camera frame (x right, y up, z toward the camera).
gradients : pair of (H, W) arrays, optional
    ``(p, q)``, ``p = f_x``, ``q = f_y`` in the y-up frame, given instead of ``normals``.
mask : (H, W) bool, optional
    Domain.  Default: the pixels with a finite, non-zero normal (finite ``p``, ``q``).
    Pixels with ``N_z <= 1e-3`` are dropped from the domain.""",
    "pixel_size": """\
pixel_size : float
    World size of one pixel; the height is returned in the same world units.""",
    "rectangle": """\
Parameters
----------
normals : (H, W, 3) array, optional
    Normals in the camera frame (x right, y up, z toward the camera).
gradients : pair of (H, W) arrays, optional
    ``(p, q)``, ``p = f_x``, ``q = f_y`` in the y-up frame, given instead of ``normals``.
mask : (H, W) bool, optional
    Domain (default: finite, non-zero normals; ``N_z <= 1e-3`` dropped); the gradients
    outside it are set to 0 and the whole rectangle is integrated.
pixel_size : float
    World size of one pixel; the height is returned in the same world units.

Returns
-------
z : (H, W) float64
    Height with mean zero over the domain, 0 outside.

Raises
------
ValueError
    On bad input (as :func:`pbrbench.infer.integration.integrate_lsq`).""",
}


def _check_normals(normals, name="normals"):
    n = as_float_array(normals, name, ndim=(3,))
    if n.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (H, W, 3), got {n.shape}; pass one 3-vector per pixel")
    return n


def normals_to_gradients(normals, mask=None, *, min_nz: float = 1e-3):
    """Surface gradients ``p = f_x = -N_x/N_z`` and ``q = f_y = -N_y/N_z`` of a normal field.

    Parameters
    ----------
    normals : (H, W, 3) array
        Normals in the camera frame (x right, y up, z toward the camera); need not be unit.
    mask : (H, W) bool, optional
        Pixels to convert. Default: pixels whose normal is finite and non-zero.
    min_nz : float
        Pixels whose unit normal has ``N_z <= min_nz`` (grazing or facing away) have no finite
        gradient and are left out of ``valid``.

    Returns
    -------
    p, q : (H, W) float64
        The gradients, 0 outside ``valid``.
    valid : (H, W) bool
        ``mask`` minus the pixels with ``N_z <= min_nz``.

    Raises
    ------
    ValueError
        If ``normals`` is not (H, W, 3), the mask does not match, or a masked normal is not finite.
    """
    n = _check_normals(normals)
    shape = n.shape[:2]
    if mask is None:
        finite = np.all(np.isfinite(n), axis=-1)
        m = finite & (np.einsum("hwc,hwc->hw", np.where(finite[..., None], n, 0.0),
                                np.where(finite[..., None], n, 0.0)) > 0)
        if not m.any():
            raise ValueError("normals: every normal is zero or non-finite; pass a mask or valid normals")
    else:
        m = check_mask(mask, shape)
        check_finite(n, "normals", where=m)
    min_nz = check_number(min_nz, "min_nz", lo=0.0, lo_open=True, hi=1.0, hi_open=True)
    nn = np.where(m[..., None], n, 0.0)
    with np.errstate(over="ignore", under="ignore"):
        norm = np.linalg.norm(nn, axis=-1)
    off = m & ~((norm > 1e-150) & (norm < 1e150))   # need not be unit: norms that under/overflow
    if off.any():
        norm = np.where(off, robust_norm(nn), norm)
    nz = np.divide(nn[..., 2], norm, out=np.zeros(shape), where=norm > 0)
    valid = m & (nz > min_nz)
    safe = np.where(valid, nn[..., 2], 1.0)
    p = np.where(valid, -nn[..., 0] / safe, 0.0)
    q = np.where(valid, -nn[..., 1] / safe, 0.0)
    return p, q, valid


def _masked_derivative(f, mask, axis):
    """Central difference along ``axis`` (array index), one-sided where a neighbour is masked out."""
    fwd = np.zeros_like(f)
    bwd = np.zeros_like(f)
    has_f = np.zeros(f.shape, bool)
    has_b = np.zeros(f.shape, bool)
    sl = [slice(None)] * 2
    lo, hi = list(sl), list(sl)
    lo[axis] = slice(None, -1)
    hi[axis] = slice(1, None)
    lo, hi = tuple(lo), tuple(hi)
    d = f[hi] - f[lo]
    both = mask[hi] & mask[lo]
    fwd[lo] = np.where(both, d, 0.0)
    has_f[lo] = both
    bwd[hi] = np.where(both, d, 0.0)
    has_b[hi] = both
    cnt = has_f.astype(float) + has_b
    return np.divide(fwd + bwd, cnt, out=np.zeros_like(f), where=cnt > 0)


def _gradients_from_input(normals, gradients, mask):
    if (normals is None) == (gradients is None):
        raise ValueError("normals/gradients: pass exactly one of normals (H, W, 3) or gradients=(p, q)")
    if normals is not None:
        return normals_to_gradients(normals, mask)
    try:
        p, q = gradients
    except (TypeError, ValueError) as exc:
        raise ValueError("gradients: expected a pair (p, q) of (H, W) arrays with p = f_x, q = f_y") from exc
    p = as_float_array(p, "gradients[0] (p)", ndim=(2,))
    q = as_float_array(q, "gradients[1] (q)", ndim=(2,))
    if p.shape != q.shape:
        raise ValueError(f"gradients: p has shape {p.shape} but q has {q.shape}; pass two (H, W) arrays of one shape")
    if mask is None:
        m = np.isfinite(p) & np.isfinite(q)
        if not m.any():
            raise ValueError("gradients: no pixel has finite p and q; pass finite gradients")
    else:
        m = check_mask(mask, p.shape)
        check_finite(p, "gradients[0] (p)", where=m)
        check_finite(q, "gradients[1] (q)", where=m)
    return np.where(m, p, 0.0), np.where(m, q, 0.0), m


def integrability_residual(normals=None, mask=None, *, gradients=None, pixel_size: float = 1.0):
    r"""Integrability residual ``dp/dy - dq/dx`` of a normal field (the chapter's check).

    With ``p = f_x`` and ``q = f_y`` of a true surface the mixed partials agree, so the map is ~0;
    large values flag wrong normals (shadows, highlights, interreflections) or a discontinuity.
    Derivatives are central differences in world units (``pixel_size`` per pixel; ``y`` up, so
    ``d/dy = -d/drow``), one-sided where a neighbour falls outside the mask.

    Parameters
    ----------
    normals : (H, W, 3) array, optional
        Normal field (or pass ``gradients=(p, q)`` instead).
    mask : (H, W) bool, optional
        Domain (default: non-zero finite normals / finite gradients).
    gradients : pair of (H, W) arrays, optional
        ``(p, q)`` with ``p = f_x``, ``q = f_y``.
    pixel_size : float
        World size of one pixel.

    Returns
    -------
    (H, W) float64 map, 0 outside the domain.

    References
    ----------
    D. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, "Light and Shading",
    Algorithm 1.2 (photometric stereo, integrability check).
    """
    p, q, m = _gradients_from_input(normals, gradients, mask)
    h = check_pixel_size(pixel_size)
    dp_dy = -_masked_derivative(p, m, axis=0) / h
    dq_dx = _masked_derivative(q, m, axis=1) / h
    return np.where(m, dp_dy - dq_dx, 0.0)


def _prepare(normals, gradients, mask, pixel_size):
    """The common input step of every integrator: ``(p, q, domain, h)`` (gradients 0 outside)."""
    p, q, m = _gradients_from_input(normals, gradients, mask)
    if not m.any():
        raise ValueError("mask: no pixel has a usable normal (N_z > 1e-3); check the normals' frame (z toward the camera)")
    h = check_pixel_size(pixel_size)
    return p, q, m, h


def _edge_gradients(p, q, m, h):
    """Forward differences in index coordinates: trapezoid average of the two pixels' slopes.

    ``gx[i, j] = h (p[i, j] + p[i, j+1]) / 2`` (one column right) and
    ``gy[i, j] = -h (q[i, j] + q[i+1, j]) / 2`` (one row down is ``-y``), the right-hand side
    of :func:`pbrbench.infer.poisson.solve_gradient_field`.
    """
    gx = np.zeros_like(p)
    gy = np.zeros_like(p)
    gx[:, :-1] = 0.5 * h * (p[:, :-1] + p[:, 1:])
    gy[:-1, :] = -0.5 * h * (q[:-1, :] + q[1:, :])
    return gx, gy


def normals_from_gradients(p, q, mask=None) -> np.ndarray:
    r"""Unit normals ``N = (-p, -q, 1) / sqrt(1 + p^2 + q^2)`` of slopes ``p = f_x``, ``q = f_y``.

    Parameters
    ----------
    p, q : (H, W) arrays
        Slopes in the y-up frame (unitless: height and ``x``, ``y`` in the same units).
    mask : (H, W) bool, optional
        Pixels to fill (default: all); the normal is (0, 0, 0) outside.

    Returns
    -------
    (H, W, 3) float64
        Unit normals in the camera frame.

    Raises
    ------
    ValueError
        If ``p`` and ``q`` are not 2-D arrays of one shape, the mask does not match, or a slope
        inside the mask is not finite.
    """
    p = as_float_array(p, "p", ndim=(2,))
    q = as_float_array(q, "q", ndim=(2,))
    if p.shape != q.shape:
        raise ValueError(f"q: shape {q.shape} differs from p's {p.shape}; pass two (H, W) arrays of one shape")
    m = check_mask(mask, p.shape)
    check_finite(p, "p", where=m)
    check_finite(q, "q", where=m)
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[~m] = 0.0
    return n


def gradients_from_height(z, mask=None, *, pixel_size: float = 1.0):
    """Slopes ``p = f_x``, ``q = f_y`` of a height map by central differences inside ``mask``.

    One-sided (forward or backward) differences where a neighbour lies outside ``mask`` or the
    image, 0 where a pixel has no neighbour inside along that axis.  ``y`` is up, so
    ``f_y = -dz/drow``.

    Parameters
    ----------
    z : (H, W) array
        Height in world units (values outside ``mask`` are ignored).
    mask : (H, W) bool, optional
        Domain (default: the whole image).
    pixel_size : float
        World size of one pixel; the slopes are ``dz / (pixel_size * pixels)``.

    Returns
    -------
    p, q : (H, W) float64
        The slopes, 0 outside ``mask``.

    Raises
    ------
    ValueError
        On a non-2-D ``z``, a mismatched mask, a non-finite height inside the mask or a
        non-positive ``pixel_size``.
    """
    z = as_float_array(z, "z", ndim=(2,))
    m = check_mask(mask, z.shape)
    check_finite(z, "z", where=m)
    h = check_pixel_size(pixel_size)
    if h != 1.0:
        z = z / h

    def deriv(axis):
        zf = np.where(m, z, 0.0)
        plus = np.roll(zf, -1, axis)
        minus = np.roll(zf, 1, axis)
        mp = np.roll(m, -1, axis)
        mm = np.roll(m, 1, axis)
        n = z.shape[axis]
        idx = np.arange(n)
        edge_hi = (idx == n - 1)
        edge_lo = (idx == 0)
        shape = [1, 1]
        shape[axis] = n
        mp = mp & ~edge_hi.reshape(shape)
        mm = mm & ~edge_lo.reshape(shape)
        both = mp & mm
        d = np.zeros_like(z)
        d[both] = (plus[both] - minus[both]) / 2.0
        fwd = mp & ~mm
        d[fwd] = plus[fwd] - zf[fwd]
        bwd = mm & ~mp
        d[bwd] = zf[bwd] - minus[bwd]
        return d
    p = deriv(1)
    q = -deriv(0)  # y up: f_y = -d/d(row)
    return np.where(m, p, 0.0), np.where(m, q, 0.0)
