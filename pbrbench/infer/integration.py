"""Surface integration: from a normal field (or surface gradients) to a height map.

Frame of SCIENCE.md §0: x right, y up, z toward the camera; row 0 is the top, so ``y``
decreases with the row index. A Monge patch ``z = f(x, y)`` has unit normal
``N = (-f_x, -f_y, 1)/|.|``, hence ``p = f_x = -N_x/N_z`` and ``q = f_y = -N_y/N_z``.
On the pixel grid (pixel size ``h``), moving one column right changes the height by about
``h p`` and moving one row *down* by about ``-h q``.

Methods of :func:`integrate_normals`:

- ``"path"``: the chapter's algorithm (Forsyth & Ponce, Algorithm 1.2): the top-left pixel is
  zero, integrate ``q`` down the left column, then ``p`` along every row.
- ``"frankot_chellappa"``: projection onto integrable Fourier functions (periodic rectangle).
- ``"dct"``: least squares on the full rectangle with Neumann boundary (DCT Poisson solve).
- ``"lsq"``: least squares on the masked, non-rectangular domain (default; AMG-preconditioned
  conjugate gradients from :mod:`pbrbench.infer.poisson`).

The three rectangle methods (``path``, ``frankot_chellappa``, ``dct``) set the gradients outside
the mask to 0 and integrate over the whole image; only ``lsq`` respects the domain.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_mask,
    check_method,
    check_positive,
)
from pbrbench.infer.poisson import solve_gradient_field

__all__ = ["normals_to_gradients", "integrability_residual", "integrate_normals", "METHODS"]

METHODS = ("lsq", "path", "frankot_chellappa", "dct")


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
    min_nz = check_positive(min_nz, "min_nz")
    nn = np.where(m[..., None], n, 0.0)
    norm = np.linalg.norm(nn, axis=-1)
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
    h = check_positive(pixel_size, "pixel_size")
    dp_dy = -_masked_derivative(p, m, axis=0) / h
    dq_dx = _masked_derivative(q, m, axis=1) / h
    return np.where(m, dp_dy - dq_dx, 0.0)


def _edge_gradients(p, q, m, h):
    """Forward differences in index coordinates: trapezoid average of the two pixels' slopes."""
    gx = np.zeros_like(p)
    gy = np.zeros_like(p)
    gx[:, :-1] = 0.5 * h * (p[:, :-1] + p[:, 1:])
    gy[:-1, :] = -0.5 * h * (q[:-1, :] + q[1:, :])
    return gx, gy


def _path(gx, gy):
    z = np.zeros_like(gx)
    z[1:, 0] = np.cumsum(gy[:-1, 0])
    z[:, 1:] = z[:, :1] + np.cumsum(gx[:, :-1], axis=1)
    return z


def _frankot_chellappa(p, q, h):
    rows, cols = p.shape
    gx = h * p        # derivative along columns (per pixel)
    gy = -h * q       # derivative along rows (rows go down)
    wx = 2 * np.pi * scipy.fft.fftfreq(cols)[None, :]
    wy = 2 * np.pi * scipy.fft.fftfreq(rows)[:, None]
    den = wx**2 + wy**2
    den[0, 0] = 1.0
    zf = (-1j * wx * scipy.fft.fft2(gx) - 1j * wy * scipy.fft.fft2(gy)) / den
    zf[0, 0] = 0.0
    return np.real(scipy.fft.ifft2(zf))


def integrate_normals(normals=None, *, gradients=None, mask=None, method: str = "lsq",
                      pixel_size: float = 1.0, tol: float = 1e-8) -> np.ndarray:
    r"""Height map ``z`` (up to a constant) whose gradients best match a normal field.

    The least-squares methods solve

    .. math:: \min_z \int_\Omega (z_x - p)^2 + (z_y - q)^2 \,dx\,dy,

    with ``p = -N_x/N_z``, ``q = -N_y/N_z``, whose Euler-Lagrange equation is the Poisson equation
    ``\nabla^2 z = p_x + q_y`` with natural boundary conditions on the border of ``\Omega``.

    Parameters
    ----------
    normals : (H, W, 3) array, optional
        Normals in the camera frame (x right, y up, z toward the camera).
    gradients : pair of (H, W) arrays, optional
        ``(p, q)``, ``p = f_x``, ``q = f_y`` in the y-up frame, given instead of ``normals``.
    mask : (H, W) bool, optional
        Domain. Default: the pixels with a finite, non-zero normal (finite ``p``, ``q``).
        Pixels with ``N_z <= 1e-3`` are dropped from the domain.
    method : {"lsq", "path", "frankot_chellappa", "dct"}
        ``"lsq"`` (default): least squares on the masked domain, AMG-preconditioned conjugate
        gradients (Agrawal, Raskar & Chellappa, "What is the range of surface reconstructions
        from a gradient field?", ECCV 2006). ``"path"``: the chapter's path integration
        (Forsyth & Ponce, "Light and Shading", Algorithm 1.2) with trapezoid steps.
        ``"frankot_chellappa"``: Frankot & Chellappa, "A method for enforcing integrability in
        shape from shading algorithms", IEEE TPAMI 10(4), 1988 (FFT, periodic rectangle).
        ``"dct"``: Neumann Poisson on the rectangle by DCT (Simchony, Chellappa & Shao, IEEE
        TPAMI 1990). The last three zero the gradients outside the mask and integrate over the
        whole rectangle, which biases the result on non-rectangular domains.
    pixel_size : float
        World size of one pixel; the height is returned in the same world units.
    tol : float
        Relative residual tolerance of the ``"lsq"`` iterative solver.

    Returns
    -------
    z : (H, W) float64
        Height with mean zero over the domain (per connected component for ``"lsq"``); 0 outside.

    Raises
    ------
    ValueError
        On an unknown method, both or neither of ``normals`` / ``gradients``, bad shapes, a
        mismatched mask, non-finite values in the mask, or a non-positive ``pixel_size``.
    """
    check_method(method, METHODS)
    p, q, m = _gradients_from_input(normals, gradients, mask)
    if not m.any():
        raise ValueError("mask: no pixel has a usable normal (N_z > 1e-3); check the normals' frame (z toward the camera)")
    h = check_positive(pixel_size, "pixel_size")
    if method == "lsq":
        gx, gy = _edge_gradients(p, q, m, h)
        return solve_gradient_field(gx, gy, mask=m, tol=tol, method="auto")
    if method == "path":
        gx, gy = _edge_gradients(p, q, m, h)
        z = _path(gx, gy)
    elif method == "dct":
        gx, gy = _edge_gradients(p, q, m, h)
        z = solve_gradient_field(gx, gy, method="dct")
    else:
        z = _frankot_chellappa(p, q, h)
    z = z - z[m].mean()
    return np.where(m, z, 0.0)
