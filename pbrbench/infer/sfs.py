r"""Shape from one shaded image (SCIENCE.md §7): classical shape-from-shading methods.

Model (all methods): a Monge patch ``z = f(x, y)`` seen orthographically along ``z`` in the
camera frame of SCIENCE.md §0 (x right, y up, z toward the camera; row 0 is the top), of uniform
Lambertian albedo ``rho``, lit by one distant source of unit direction ``S`` (toward the source).
With ``p = f_x``, ``q = f_y`` the image irradiance equation is

.. math::
    I(x, y) = \rho\, R(p, q), \qquad
    R(p, q) = \max\Big(0, \frac{S_z - S_x p - S_y q}{\sqrt{1 + p^2 + q^2}}\Big),

the normal being ``N = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``.  Every method works on the
normalised image ``E = I / rho`` (clipped to [0, 1]) in **pixel units** (slopes are unitless; the
height is computed in pixels and multiplied by ``pixel_size`` at the end).

Objects
-------
shape_from_shading
    Height and normals from one image: ``horn1989``, ``tsai_shah1994``, ``pentland1990``,
    ``fast_marching``.
light_from_shading
    Light direction (and albedo) from one image: ``contour`` (occluding-contour least squares)
    and ``lee_rosenfeld1985`` (image statistics).
SFSResult, LightEstimate
    Frozen result records.

References
----------
- B. K. P. Horn, "Height and gradient from shading", International Journal of Computer Vision
  5(1):37-75, 1990 (MIT AI Memo 1105, 1989).
- P.-S. Tsai and M. Shah, "Shape from shading using linear approximation", Image and Vision
  Computing 12(8):487-498, 1994.
- A. P. Pentland, "Linear shape from shading", International Journal of Computer Vision
  4(2):153-162, 1990.
- R. Kimmel and J. A. Sethian, "Optimal algorithm for shape from shading and path planning",
  Journal of Mathematical Imaging and Vision 14(3):237-244, 2001.
- C.-H. Lee and A. Rosenfeld, "Improved methods of estimating shape from shading using the light
  source coordinate system", Artificial Intelligence 26(2):125-143, 1985.
- A. P. Pentland, "Finding the illuminant direction", Journal of the Optical Society of America
  72(4):448-455, 1982.
- P. Nillius and J.-O. Eklundh, "Automatic estimation of the projected light source direction",
  CVPR 2001 (light from the occluding contour).
- R. Zhang, P.-S. Tsai, J. E. Cryer and M. Shah, "Shape from shading: a survey", IEEE TPAMI
  21(8):690-706, 1999.
"""

from __future__ import annotations

import heapq
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_mask,
    check_method,
    check_positive,
)

__all__ = [
    "METHODS",
    "LIGHT_METHODS",
    "SFSResult",
    "LightEstimate",
    "shape_from_shading",
    "light_from_shading",
    "integrate_gradients",
    "occluding_boundary",
]

METHODS = ("horn1989", "tsai_shah1994", "pentland1990", "fast_marching")
LIGHT_METHODS = ("contour", "lee_rosenfeld1985")
# boundary="auto": the mask's edge is taken as an occluding contour when at least this fraction
# of its pixels is consistent with one (sphere 0.96, vase 0.82, a cut random surface 0.13 under
# the oblique light of the tests)
AUTO_CONTOUR_FRACTION = 0.6


@dataclass(frozen=True)
class SFSResult:
    """Result of :func:`shape_from_shading`.

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
        Iterations used (0 for direct methods, marched pixels for ``fast_marching``).
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
    """Result of :func:`light_from_shading`: unit ``direction`` (3,), ``albedo``, ``method``."""

    direction: np.ndarray
    albedo: float
    method: str


# --------------------------------------------------------------------------------------------
# shared helpers
# --------------------------------------------------------------------------------------------

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


def _normals_from_pq(p, q, mask):
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[~mask] = 0.0
    return n


def _pq_from_height(z, mask):
    """Slopes ``p = f_x``, ``q = f_y`` (pixel units) of a height map by central differences,
    one-sided where a neighbour lies outside ``mask``; 0 where a pixel has no neighbour inside."""
    def deriv(axis):
        zf = np.where(mask, z, 0.0)
        plus = np.roll(zf, -1, axis)
        minus = np.roll(zf, 1, axis)
        mp = np.roll(mask, -1, axis)
        mm = np.roll(mask, 1, axis)
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
    return np.where(mask, p, 0.0), np.where(mask, q, 0.0)


def integrate_gradients(p, q, *, mask=None, pixel_size: float = 1.0) -> np.ndarray:
    """Least-squares height from slopes ``p = f_x``, ``q = f_y`` with the shared integrator.

    Uses :func:`pbrbench.infer.integration.integrate_normals` (``method="lsq"``) when that module
    is present, else :func:`pbrbench.infer.poisson.solve_gradient_field` directly with
    ``gx = h (p_j + p_{j+1}) / 2`` and ``gy = -h (q_i + q_{i+1}) / 2`` (rows go down, y up).
    The same function gives the SFS methods' heights and the metric's floor
    (:func:`pbrbench.metrics.sfs.floor_height`), so both share one integrator.

    Returns the height (H, W) in units of ``pixel_size``, mean zero on each connected component
    of ``mask``, 0 outside.
    """
    p = np.asarray(p, float)
    q = np.asarray(q, float)
    m = check_mask(mask, p.shape)
    h = check_positive(pixel_size, "pixel_size")
    p0 = np.where(m, p, 0.0)
    q0 = np.where(m, q, 0.0)
    try:
        from pbrbench.infer.integration import integrate_normals  # noqa: PLC0415
    except ImportError:
        integrate_normals = None
    if integrate_normals is not None:
        z = integrate_normals(gradients=(p0, q0), mask=m, method="lsq", pixel_size=h)
        z = np.asarray(getattr(z, "height", z), float)
    else:
        from pbrbench.infer.poisson import solve_gradient_field  # noqa: PLC0415
        gx = np.zeros_like(p0)
        gy = np.zeros_like(q0)
        gx[:, :-1] = 0.5 * h * (p0[:, :-1] + p0[:, 1:])
        gy[:-1, :] = -0.5 * h * (q0[:-1, :] + q0[1:, :])
        z = solve_gradient_field(gx, gy, mask=m)
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


def _contour_slants(E, s, mask):
    """Outward silhouette normals ``dx, dy`` and the two candidate contour slants per pixel.

    At a contour pixel the normal is ``(sin t d, cos t)`` with ``d`` the outward silhouette
    normal, so ``E = sin t (d . S_xy) + cos t S_z``; its roots are ``t = phi +- alpha`` with
    ``phi = atan2(d . S_xy, S_z)`` and ``alpha = acos(E / |(d . S_xy, S_z)|)``.  Returns
    ``dx, dy, cands`` with ``cands`` of shape (2, H, W).
    """
    dx, dy = _outward_directions(mask)
    a = dx * s[0] + dy * s[1]
    c = np.hypot(a, s[2])
    phi = np.arctan2(a, s[2])
    alpha = np.arccos(np.clip(E / np.maximum(c, 1e-12), -1.0, 1.0))
    return dx, dy, np.stack([phi + alpha, phi - alpha])


def _contour_pq(E, s, mask, boundary, theta_max):
    """Gradients at occluding-contour pixels: tilt from the silhouette, slant from brightness.

    Of the two roots of :func:`_contour_slants` the one nearest 90 degrees (and at most
    ``theta_max``) is kept.
    """
    dx, dy, cands = _contour_slants(E, s, mask)
    ok = (cands >= 0) & (cands <= theta_max)
    dist = np.where(ok, np.abs(cands - np.pi / 2), np.inf)
    pick = np.take_along_axis(cands, np.argmin(dist, axis=0)[None], 0)[0]
    t = np.where(ok.any(axis=0), pick, theta_max)
    slope = np.tan(t)
    # the surface falls away outward: grad f = -tan(t) d, so that N = (sin t d, cos t)
    p = np.where(boundary, -slope * dx, 0.0)
    q = np.where(boundary, -slope * dy, 0.0)
    return p, q


def _contour_consistent(E, s, mask, boundary, *, theta_max, theta_min_deg: float = 60.0):
    """The pixels of ``boundary`` whose brightness an occluding contour could produce.

    At a contour pixel with outward silhouette normal ``d`` the normal is ``(sin t d, cos t)``
    with ``t`` near 90 degrees, so ``E = sin t (d . S_xy) + cos t S_z`` must have a root ``t`` in
    ``[theta_min_deg, theta_max]``; dark pixels (``E < 0.02``, attached shadow) are kept.  A mask
    edge that is a cut through a surface (a frame, a vase's end) usually fails this.
    """
    _, _, cands = _contour_slants(E, s, mask)
    ok = ((cands >= math.radians(theta_min_deg)) & (cands <= theta_max)).any(axis=0)
    return boundary & (ok | (E < 0.02))


def _prepare(image, light, albedo, mask, pixel_size):
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
    ns = np.linalg.norm(s)
    if ns == 0:
        raise ValueError("light: zero vector; pass a direction toward the source, e.g. (0, 0, 1)")
    s = s / ns
    if s[2] <= 0:
        raise ValueError(f"light: z component {s[2]:.3g} <= 0 (light behind the surface); the "
                         "camera looks along -z, so pass a light with z > 0")
    h = check_positive(pixel_size, "pixel_size")
    if albedo is None:
        rho = float(img[m].max())
        if rho <= 0:
            raise ValueError("image: all zero inside the mask; shape from shading needs a lit surface")
    else:
        rho = check_positive(albedo, "albedo")
    e = np.clip(np.where(m, img / rho, 0.0), 0.0, 1.0)
    return e, s, m, rho, h


def _check_int(v, name):
    iv = int(v)
    if iv != v or iv < 1:
        raise ValueError(f"{name}: must be a positive integer, got {v!r}")
    return iv


# --------------------------------------------------------------------------------------------
# horn1989
# --------------------------------------------------------------------------------------------

def _nb_sum(a, ex, ey):
    """Sum of ``a`` over each pixel's 4-neighbours joined by an in-mask edge, and their count."""
    s = np.zeros_like(a)
    s[:, :-1] += ex * a[:, 1:]
    s[:, 1:] += ex * a[:, :-1]
    s[:-1, :] += ey * a[1:, :]
    s[1:, :] += ey * a[:-1, :]
    return s


def _horn(E, s, m, *, max_iter, tol, lam, lam_min, mu, boundary, theta_max, n_stages, init=None,
          stages=True, omega=1.7):
    """Horn's (1989) iterative scheme on one grid: red-black Gauss-Seidel on (p, q), then on z.

    Discrete energy (x-edges ``a -> b`` join horizontal neighbours, y-edges vertical ones, both
    pixels in the mask)::

        J = sum_pix (E - R+(p, q))^2
          + lam * sum_edges ((p_a - p_b)^2 + (q_a - q_b)^2)
          + mu  * (sum_x-edges (z_b - z_a - (p_a + p_b)/2)^2 + sum_y-edges (z_b - z_a + (q_a + q_b)/2)^2)

    (y up: moving one row down changes z by ``-q``).  One sweep minimises ``J`` over each pixel's
    ``(p, q)`` with the reflectance linearised at the current value (Horn's update, with the
    Gauss-Newton term ``R_p^2``, ``R_q^2`` kept in the denominator so the step never overshoots),
    red pixels then black ones, then over each pixel's ``z`` (a Gauss-Seidel sweep of the Poisson
    equation ``L z = div (p, q)``).  Occluding-contour pixels keep their gradient fixed
    (Dirichlet).  Attached-shadow pixels (``E = 0``) contribute only where ``R > 0``.
    Returns ``p, q, z, converged, sweeps, last RMS (p, q) update``.
    """
    fixed = boundary & m
    pb, qb = _contour_pq(E, s, m, fixed, theta_max)
    free = m & ~fixed
    ex = (m[:, :-1] & m[:, 1:]).astype(float)  # edge indicators as weights
    ey = (m[:-1, :] & m[1:, :]).astype(float)
    nx = np.zeros(E.shape)
    nx[:, :-1] += ex
    nx[:, 1:] += ex
    ny = np.zeros(E.shape)
    ny[:-1, :] += ey
    ny[1:, :] += ey
    nn = nx + ny
    shadow = E <= 0.0
    ii, jj = np.indices(E.shape)
    red = (ii + jj) % 2 == 0
    colours = (free & red, free & ~red)
    zcol = (m & red, m & ~red)
    nzk = np.maximum(nn, 1.0)
    if init is None:
        P = np.where(fixed, pb, 0.0)
        Q = np.where(fixed, qb, 0.0)
        Z = integrate_gradients(P, Q, mask=m)
    else:
        P = np.where(fixed, pb, np.where(m, init[0], 0.0))
        Q = np.where(fixed, qb, np.where(m, init[1], 0.0))
        Z = np.where(m, init[2], 0.0)
    lam_list = np.geomspace(lam, lam_min, n_stages) if (stages and n_stages > 1) else np.array([lam_min])
    lam_list = lam_list[-max_iter:]
    per_stage = max(1, max_iter // len(lam_list))
    nf = max(int(free.sum()), 1)
    sweeps = 0
    delta = np.inf
    converged = False
    for k, lam_k in enumerate(lam_list):
        last = k == len(lam_list) - 1
        budget = max_iter - sweeps if last else per_stage
        for _ in range(max(1, budget)):
            sweeps += 1
            dsum = 0.0
            for col in colours:
                r, rp, rq = _reflectance(P, Q, s)
                pos = r > 0
                res = np.where(pos, E - r, np.where(shadow, 0.0, E))
                rp *= pos
                rq *= pos
                # integrability targets seen from each pixel: c = z_b - z_a - p_b / 2 on its x-edges
                cx = np.zeros_like(E)
                cx[:, :-1] += ex * (Z[:, 1:] - Z[:, :-1] - 0.5 * P[:, 1:])
                cx[:, 1:] += ex * (Z[:, 1:] - Z[:, :-1] - 0.5 * P[:, :-1])
                # y-edges a (row i) -> b (row i+1): z_b - z_a + (q_a + q_b)/2; target for q_a is
                # -(z_b - z_a) - q_b / 2
                cy = np.zeros_like(E)
                cy[:-1, :] += ey * (Z[:-1, :] - Z[1:, :] - 0.5 * Q[1:, :])
                cy[1:, :] += ey * (Z[:-1, :] - Z[1:, :] - 0.5 * Q[:-1, :])
                # quadratic model per pixel in (dp, dq): [[a11, a12], [a12, a22]] d = [b1, b2]
                a11 = rp * rp + lam_k * nn + 0.25 * mu * nx
                a22 = rq * rq + lam_k * nn + 0.25 * mu * ny
                a12 = rp * rq
                b1 = (res * rp + lam_k * (_nb_sum(P, ex, ey) - nn * P) + 0.5 * mu * (cx - 0.5 * nx * P))
                b2 = (res * rq + lam_k * (_nb_sum(Q, ex, ey) - nn * Q) + 0.5 * mu * (cy - 0.5 * ny * Q))
                det = a11 * a22 - a12 * a12
                det = np.where(det > 1e-12, det, 1e-12)
                dp = (a22 * b1 - a12 * b2) / det
                dq = (a11 * b2 - a12 * b1) / det
                dp = np.where(col, omega * dp, 0.0)
                dq = np.where(col, omega * dq, 0.0)
                P += dp
                Q += dq
                dsum += float(np.sum(dp * dp + dq * dq))
            # z: Gauss-Seidel on the Poisson equation with targets gx = (p_a + p_b)/2, gy = -(q_a + q_b)/2
            gx = ex * 0.5 * (P[:, :-1] + P[:, 1:])
            gy = ey * -0.5 * (Q[:-1, :] + Q[1:, :])
            for col in zcol:
                acc = _nb_sum(Z, ex, ey)
                acc[:, :-1] -= gx
                acc[:, 1:] += gx
                acc[:-1, :] -= gy
                acc[1:, :] += gy
                Z = np.where(col, Z + omega * (acc / nzk - Z), Z)
            delta = math.sqrt(dsum / nf)
            if last and delta < tol:
                converged = True
                break
    return P, Q, Z, converged, sweeps, delta


def _horn_pyramid(E, s, m, *, levels, coarse_iter, **kw):
    """Coarse-to-fine driver: solve on 2x2-block-averaged images first, upsample (p, q, 2 z).

    The coarsest level runs the full lambda continuation with ``coarse_iter`` sweeps; finer
    levels start from the upsampled solution at the final lambda.  Returns ``(p, q, converged,
    sweeps on the finest grid, last update, total sweeps)``.
    """
    H, W = E.shape
    if levels > 1 and min(H, W) >= 32 and H % 2 == 0 and W % 2 == 0:
        mc = m.reshape(H // 2, 2, W // 2, 2).all(axis=(1, 3))
        if mc.sum() >= 16:
            Ec = (np.where(m, E, 0.0).reshape(H // 2, 2, W // 2, 2).sum(axis=(1, 3))
                  / np.maximum(m.reshape(H // 2, 2, W // 2, 2).sum(axis=(1, 3)), 1))
            kc = dict(kw)
            kc["boundary"] = occluding_boundary(mc) if kw["boundary"].any() else np.zeros_like(mc)
            pc, qc, zc, _, _, _, tot = _horn_pyramid(Ec, s, mc, levels=levels - 1, coarse_iter=coarse_iter, **kc)
            up = np.ones((2, 2))
            init = (np.kron(pc, up), np.kron(qc, up), 2.0 * np.kron(zc, up))
            # pixels of the fine mask outside the coarse one: nearest coarse value
            known = np.kron(mc, up).astype(bool)
            if (m & ~known).any():
                idx = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
                init = tuple(a[idx[0], idx[1]] for a in init)
            p, q, z, ok, it, d = _horn(E, s, m, init=init, stages=False, **kw)
            return p, q, z, ok, it, d, tot + it
    kw = dict(kw)
    kw["max_iter"] = max(kw["max_iter"], coarse_iter)
    p, q, z, ok, it, d = _horn(E, s, m, **kw)
    return p, q, z, ok, it, d, it


# --------------------------------------------------------------------------------------------
# tsai_shah1994
# --------------------------------------------------------------------------------------------

def _tsai_shah(E, s, m, *, max_iter, tol, damping, init, mu_schedule=(0.0, 0.1, 0.3, 1.0, 3.0, 10.0),
               n_halvings=8):
    """Damped Newton iteration on Tsai & Shah's discrete equations, all pixels at once.

    ``f_k(z) = E_k - R(z_k - z_left, z_k - z_below)`` (pixels outside the mask hold ``z = 0``);
    in the causal order (rows bottom to top, columns left to right) the Jacobian is lower
    triangular with diagonal ``-(R_p + R_q)`` and ``R_p``, ``R_q`` on the left/below neighbours,
    so the Newton step ``J d = -f`` is one forward substitution (Tsai & Shah's own update keeps
    only the diagonal: a Jacobi iteration whose spectral radius is ~1, so it oscillates).  Each
    step is damped: the diagonal is pushed away from zero by ``mu`` (0, then larger on failure,
    and at least ``damping`` in magnitude) and the step length halved until the brightness
    residual ``sum f^2`` decreases (backtracking line search from a step no pixel of which moves
    more than the image size).  Shadow pixels (``E = 0``)
    contribute ``-max(R, 0)``.  Returns ``z, converged, steps, info``; ``info["stalled"]`` is
    True when no damped step lowered the residual (a stationary point of the damped
    linearisation, not a solution).
    """
    from scipy.sparse import csr_matrix  # noqa: PLC0415
    from scipy.sparse.linalg import spsolve_triangular  # noqa: PLC0415

    H, W = E.shape
    n = H * W
    max_step = float(max(H, W))
    ef = E[::-1].ravel()
    mf = m[::-1].ravel()
    shadow = ef <= 0.0
    col = np.tile(np.arange(W), H)
    idx = np.arange(n)
    has_l = np.zeros(n, bool)
    has_l[1:] = mf[:-1] & (col[1:] > 0)
    has_b = np.zeros(n, bool)
    has_b[W:] = mf[:-W]
    has_l &= mf
    has_b &= mf
    z = np.zeros(n) if init is None else np.where(mf, np.asarray(init, float)[::-1].ravel(), 0.0)
    # sparsity pattern of the Jacobian: diagonal, left neighbour, neighbour below
    rows = np.concatenate([idx, idx[has_l], idx[has_b]])
    cols = np.concatenate([idx, idx[has_l] - 1, idx[has_b] - W])

    def residual(zv):
        zl = np.zeros(n)
        zl[1:] = zv[:-1]
        zb = np.zeros(n)
        zb[W:] = zv[:-W]
        p = zv - np.where(has_l, zl, 0.0)
        q = zv - np.where(has_b, zb, 0.0)
        r, rp, rq = _reflectance(p, q, s)
        f = np.where(shadow, -np.maximum(r, 0.0), ef - r)
        g = np.where(shadow & (r <= 0.0), 0.0, 1.0)
        return np.where(mf, f, 0.0), rp * g, rq * g

    f, rp, rq = residual(z)
    cost = float(f @ f)
    cost0 = cost
    nm = max(int(mf.sum()), 1)
    converged = False
    stalled = False
    delta = np.inf
    steps = 0
    for _ in range(max_iter):
        d0 = -(rp + rq)
        sgn = np.where(d0 < 0, -1.0, 1.0)
        accepted = False
        for mu in mu_schedule:
            dg = d0 + mu * sgn
            dg = np.where(np.abs(dg) < damping, damping * sgn, dg)
            dg = np.where(mf, dg, 1.0)
            vals = np.concatenate([dg, rp[has_l], rq[has_b]])
            J = csr_matrix((vals, (rows, cols)), shape=(n, n))
            d = np.where(mf, spsolve_triangular(J, -f, lower=True), 0.0)
            if not np.all(np.isfinite(d)):
                continue
            # trust region: no pixel moves by more than the image's size in one step (a near-zero
            # diagonal otherwise gives steps of 1e4 px that still lower the residual)
            dmax = float(np.abs(d).max())
            a = min(1.0, max_step / dmax) if dmax > 0 else 1.0
            for _ in range(n_halvings):
                zn = z + a * d
                fn, rpn, rqn = residual(zn)
                cn = float(fn @ fn)
                if np.isfinite(cn) and cn < cost * (1.0 - 1e-4 * a):
                    accepted = True
                    break
                a *= 0.5
            if accepted:
                break
        if not accepted:
            stalled = True
            break
        steps += 1
        delta = a * math.sqrt(float(np.sum(d * d)) / nm)
        z, f, rp, rq, cost = zn, fn, rpn, rqn, cn
        if delta < tol:
            converged = True
            break
    zimg = z.reshape(H, W)[::-1]
    info = {"final_update": float(delta), "stalled": stalled,
            "residual_rms": math.sqrt(cost / nm), "initial_residual_rms": math.sqrt(cost0 / nm)}
    return np.where(m, zimg, 0.0), converged, steps, info


# --------------------------------------------------------------------------------------------
# pentland1990
# --------------------------------------------------------------------------------------------

def _pentland(E, s, m, *, reg):
    H, W = E.shape
    ph, pw = 2 * H, 2 * W
    src = np.zeros((ph, pw))
    src[:H, :W] = np.where(m, E - s[2], 0.0)
    F = np.fft.fft2(src)
    kr = 2 * np.pi * np.fft.fftfreq(ph)[:, None]
    kc = 2 * np.pi * np.fft.fftfreq(pw)[None, :]
    # E - S_z ~ -S_x f_x - S_y f_y, with f_x = d/dcol and f_y = -d/drow
    hsym = 1j * (-s[0] * kc + s[1] * kr)
    a2 = np.abs(hsym) ** 2
    eps = reg * (2 * np.pi / max(ph, pw)) ** 2  # relative to the lowest frequency of the padded grid
    Z = F * np.conj(hsym) / (a2 + eps)
    Z[0, 0] = 0.0
    z = np.real(np.fft.ifft2(Z))[:H, :W]
    return np.where(m, z, 0.0)


# --------------------------------------------------------------------------------------------
# fast_marching
# --------------------------------------------------------------------------------------------

def _singular_seeds(E, m, delta):
    """Connected pixel sets where ``E >= 1 - delta`` (normal along the light): singular points."""
    cand = m & (E >= 1.0 - delta)
    return cand


def _fmm_eikonal(E, m, *, seeds, delta, e_min, order):
    import skfmm  # noqa: PLC0415

    g = np.sqrt(1.0 / np.maximum(E, e_min) ** 2 - 1.0)
    if seeds == "singular":
        phi = np.where(m, (1.0 - delta) - E, 1.0)
        sign = -1.0
    else:  # boundary: zero level at the silhouette, height grows inward (convex)
        phi = np.where(m, 1.0, -1.0)
        phi = np.pad(phi, 1, constant_values=-1.0)
        sign = 1.0
    speed = 1.0 / np.maximum(g, 1e-6)
    if seeds == "singular":
        pm = np.ma.MaskedArray(phi, mask=~m)
        t = skfmm.travel_time(pm, np.ma.MaskedArray(speed, mask=~m), order=order)
    else:
        sp = np.pad(speed, 1, constant_values=1.0)
        t = skfmm.travel_time(phi, sp, order=order)[1:-1, 1:-1]
    t = np.asarray(np.ma.filled(t, np.nan), float)
    t = np.where(m & np.isfinite(t), t, np.nan)
    if seeds == "singular":
        t = np.where(m & (phi < 0), 0.0, t)  # inside the seed level set
    return sign * t, g


def _fmm_oblique(E, s, m, *, e_min, seed_mask, seed_values=None, upward=False):
    """Ordered upwind marching of ``u = S . X`` (Kimmel & Sethian 2001, oblique light).

    With ``u = S_z z + S_x x + S_y y`` the irradiance equation becomes
    ``E^2 (S_z^2 + |grad u - S_xy|^2) = (1 - S_xy . grad u)^2``; ``u`` is largest at the
    singular points (normal = S) and decreases away from them.  We march ``T = u_max - u``
    outward from the seeds with one-sided (upwind) differences, solving the quadratic for ``T``
    at each accepted neighbour, as in the fast marching method.
    """
    H, W = E.shape
    sx, sy = s[0], s[1]
    sxy2 = sx * sx + sy * sy
    k = 1.0 if upward else -1.0  # u = k T + const: T grows downhill (from maxima) or uphill (from the contour)
    Ec = np.maximum(E, e_min)
    INF = np.inf
    T = np.full((H, W), INF)
    done = np.zeros((H, W), bool)
    heap = []
    for i, j in zip(*np.nonzero(seed_mask), strict=True):
        t0 = 0.0 if seed_values is None else float(seed_values[i, j])
        T[i, j] = t0
        heap.append((t0, int(i), int(j)))
    heapq.heapify(heap)
    mm = m.tolist()
    Tl = T.tolist()
    dn = done.tolist()
    El = Ec.tolist()

    def solve(i, j):
        # candidate one-sided differences. grad u = -grad T. For the x axis the upwind
        # neighbour is the accepted one with the smaller T; the derivative T_x = (T - Tn) * sgn.
        e2 = El[i][j] ** 2
        best = INF
        opts_x = []
        for jj, sg in ((j - 1, 1.0), (j + 1, -1.0)):
            if 0 <= jj < W and mm[i][jj] and dn[i][jj]:
                opts_x.append((Tl[i][jj], sg))
        opts_y = []
        for ii, sg in ((i + 1, 1.0), (i - 1, -1.0)):  # y up: row + 1 is y - 1
            if 0 <= ii < H and mm[ii][j] and dn[ii][j]:
                opts_y.append((Tl[ii][j], sg))
        combos = [(ox, None) for ox in opts_x] + [(None, oy) for oy in opts_y]
        combos += [(ox, oy) for ox in opts_x for oy in opts_y]
        for ox, oy in combos:
            # grad T = (a T + b): T_x = sgx (T - tx), T_y = sgy (T - ty); grad u = -grad T
            ax = ox[1] if ox else 0.0
            bx = -ox[1] * ox[0] if ox else 0.0
            ay = oy[1] if oy else 0.0
            by = -oy[1] * oy[0] if oy else 0.0
            # u_x = -(ax T + bx), u_y = -(ay T + by)
            # F(T) = e2 (sz^2 + (u_x - sx)^2 + (u_y - sy)^2) - (1 - sx u_x - sy u_y)^2 = 0
            # write u_x - sx = -ax T - (bx + sx), etc.; 1 - sx u_x - sy u_y = (sx ax + sy ay) T + (1 + sx bx + sy by)
            c1x, c0x = k * ax, k * bx - sx
            c1y, c0y = k * ay, k * by - sy
            l1 = -k * (sx * ax + sy * ay)
            l0 = 1.0 - k * (sx * bx + sy * by)
            A = e2 * (c1x * c1x + c1y * c1y) - l1 * l1
            B = 2 * e2 * (c1x * c0x + c1y * c0y) - 2 * l1 * l0
            C = e2 * (s[2] ** 2 + c0x * c0x + c0y * c0y) - l0 * l0
            tmin = max(ox[0] if ox else -INF, oy[0] if oy else -INF)
            roots = []
            if abs(A) > 1e-14:
                disc = B * B - 4 * A * C
                if disc >= 0:
                    sq = math.sqrt(disc)
                    roots = [(-B + sq) / (2 * A), (-B - sq) / (2 * A)]
            elif abs(B) > 1e-14:
                roots = [-C / B]
            for t in roots:
                if t >= tmin - 1e-12:
                    # upwind consistency: the used neighbours must be below t; and the shading
                    # must be lit (1 - S_xy . grad u > 0 means N . S > 0)
                    lit = l1 * t + l0
                    if lit > 0 and t < best:
                        best = t
        return best

    count = 0
    while heap:
        t, i, j = heapq.heappop(heap)
        if dn[i][j] or t > Tl[i][j]:
            continue
        dn[i][j] = True
        count += 1
        for ii, jj in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
            if 0 <= ii < H and 0 <= jj < W and mm[ii][jj] and not dn[ii][jj]:
                tn = solve(ii, jj)
                if tn < Tl[ii][jj]:
                    Tl[ii][jj] = tn
                    heapq.heappush(heap, (tn, ii, jj))
    T = np.array(Tl)
    # u = -T (plus a constant); z = (u - S_x x - S_y y) / S_z with x, y in pixels (y up)
    xs = np.arange(W)[None, :].astype(float)
    ys = -np.arange(H)[:, None].astype(float)
    z = (k * T - sx * xs - sy * ys) / s[2]
    z = np.where(np.isfinite(T) & m, z, np.nan)
    return z, count, sxy2


def _global_max_seed(E, s, m, sing, *, e_min, coarse=64, max_candidates=6):
    """Keep the one singular component at the global maximum of ``u = S . X``.

    Singular points (``N = S``) are the critical points of ``u`` on the surface: maxima, but also
    saddles (a vase's neck) and lower maxima, whose ``u`` differ; seeding them all at one value
    is wrong, and the image cannot tell a maximum from a saddle locally.  We march ``u`` from
    each component alone on a <= ``coarse``-pixel subsampled grid and keep the component whose
    solution puts the lit occluding contour (pixels whose brightness matches a contour normal,
    ``E ~ d . S_xy``) at the most uniform depth: this assumes the silhouette lies in one depth
    plane, true for solids of revolution about an axis in the image plane (sphere, vase).
    Lower maxima are then reached by the march as ridges (a local error only).
    """
    # group nearby singular pixels (noise scatters them) and test at most ``max_candidates``
    # components, the largest first
    grow = ndimage.binary_dilation(sing, iterations=max(1, min(E.shape) // 64)) & m
    lab, k = ndimage.label(grow)
    lab = np.where(sing, lab, 0)
    if k <= 1:
        return sing, k
    sizes = ndimage.sum(sing, lab, range(1, k + 1))
    order = [int(c) + 1 for c in np.argsort(-sizes)[:max_candidates]]
    f = max(1, min(E.shape) // coarse)
    Ec, mc = E[::f, ::f], m[::f, ::f]
    b = occluding_boundary(mc)
    dx, dy = _outward_directions(mc)
    pred = np.maximum(0.0, dx * s[0] + dy * s[1])
    cont = b & (Ec > 0.05) & (np.abs(Ec - pred) < 0.25)
    if cont.sum() < 4:
        cont = b
    best, best_c = np.inf, 1
    cents = ndimage.center_of_mass(sing, lab, order)
    for c, (ci, cj) in zip(order, cents, strict=True):
        seed = np.zeros_like(mc)
        i, j = min(int(round(ci / f)), mc.shape[0] - 1), min(int(round(cj / f)), mc.shape[1] - 1)
        if not mc[i, j]:
            continue
        seed[i, j] = True
        zc, _, _ = _fmm_oblique(Ec, s, mc, e_min=e_min, seed_mask=seed)
        v = zc[cont & np.isfinite(zc)]
        score = float(np.std(v)) if v.size >= 4 else np.inf
        if score < best:
            best, best_c = score, c
    return lab == best_c, k


def _fill_unreached(z, m):
    """Fill mask pixels the marching did not reach (NaN) by nearest reached value."""
    bad = m & ~np.isfinite(z)
    if not bad.any():
        return z, 0
    good = m & np.isfinite(z)
    if not good.any():
        return np.zeros_like(z), int(bad.sum())
    idx = ndimage.distance_transform_edt(~good, return_distances=False, return_indices=True)
    zf = z[idx[0], idx[1]]
    return np.where(m, np.where(good, z, zf), 0.0), int(bad.sum())


# --------------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------------

def shape_from_shading(image, light, *, method: str = "horn1989", albedo=None, mask=None,
                       pixel_size: float = 1.0, max_iter: int | None = None, tol: float | None = None,
                       boundary="auto", theta_max_deg: float = 88.0, smoothness: float = 1.0,
                       smoothness_min: float = 0.02, integrability: float = 1.0, n_stages: int = 4, levels: int = 5,
                       damping: float = 1e-2, regularization: float = 0.1,
                       seeds: str = "auto", singular_delta: float = 1e-3, e_min: float = 1e-2) -> SFSResult:
    r"""Height and normals of a Lambertian surface from one image under a known distant light.

    Solves the image irradiance equation ``E(x, y) = R(p, q)`` (module docstring) with
    ``E = image / albedo`` for ``z = f(x, y)``: orthographic view along ``-z``, uniform known
    albedo, one distant source of known direction, no interreflections, no cast shadows
    (attached shadows, ``E = 0``, are treated as "no constraint where ``R <= 0``").

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    light : (3,) array
        Direction toward the source in the camera frame (normalised here); needs ``z > 0``.
    method : {"horn1989", "tsai_shah1994", "pentland1990", "fast_marching"}
        ``"horn1989"``
            Horn, "Height and gradient from shading" (IJCV 1990 / AI Memo 1989).  Minimises
            ``sum (E - R(p,q))^2 + lambda sum |grad p|^2 + |grad q|^2 + mu sum (z_x - p)^2 +
            (z_y - q)^2`` (``lambda = smoothness``, ``mu = integrability``; z_x, z_y forward
            differences on edges inside the mask) jointly over ``(p, q, z)`` by Horn's own
            iterative scheme: each sweep updates every pixel's ``(p, q)`` from its neighbours'
            mean, the integrability target and the reflectance linearised at the current value
            (with the Gauss-Newton term ``R_p^2`` in the denominator, so it never overshoots),
            then ``z`` by a Gauss-Seidel step of the Poisson equation ``L z = div (p, q)``;
            red-black ordering, over-relaxed (``omega = 1.7``), coarse to fine over ``levels``
            pyramid levels (2x2 block means; the coarsest grid gets ``5 max_iter`` sweeps, each
            finer one ``max_iter`` from the upsampled solution); the final height integrates
            ``(p, q)`` exactly (:func:`integrate_gradients`).  On the coarsest grid
            ``lambda`` is decreased geometrically to ``smoothness_min`` over ``n_stages`` stages
            as Horn recommends.  Normals come from the final ``(p, q)``.  Boundary
            condition: on occluding-contour pixels the gradient is fixed (Dirichlet) with tilt
            from the silhouette's outward normal and slant from the brightness (the root
            nearest 90 degrees, at most ``theta_max_deg``); elsewhere natural boundary.
            Assumes the mask's edge (not the image frame) is an occluding contour when
            ``boundary="auto"``.
        ``"tsai_shah1994"``
            Tsai & Shah, "Shape from shading using linear approximation" (IVC 1994).  With
            backward differences ``p = z(x,y) - z(x-1,y)``, ``q = z(x,y) - z(x,y-1)`` (pixels
            outside the mask hold ``z = 0``) each pixel gives ``f(z) = E - R(p, q) = 0``,
            linearised in ``z``.  Tsai & Shah update each pixel alone (a Jacobi iteration on a
            triangular system: it oscillates and never converges); here the linearised system
            is solved for all pixels at once, which in causal order (from the lower left) is one
            forward substitution: a Newton step.  It is damped (the diagonal ``-(R_p + R_q)``
            pushed away from 0, at least ``damping``), no pixel may move more than the image size
            in one step, and the length is halved until the brightness residual ``sum f^2``
            decreases.  The image is mirrored so that the light comes from
            the lower left (the causal direction of the differences) and mirrored back.  From the
            flat start the first step is the linear (Pentland-like) solution; the iteration
            usually stalls after a few steps at a point where no damped step lowers the
            residual: it then stops with a ``RuntimeWarning`` (``info["stalled"]``) and
            ``converged=False``.  Under a frontal light the flat start is a stationary point;
            the iteration then starts from a small dome (distance to the mask edge x 1e-2) and
            does little better than flat.
        ``"pentland1990"``
            Pentland, "Linear shape from shading" (IJCV 1990).  Linearises ``R`` at ``p = q = 0``:
            ``E - S_z = -S_x f_x - S_y f_y`` and solves it in the Fourier domain,
            ``Z(w) = F[E - S_z] conj(H) / (|H|^2 + eps)``, ``H = -i (S_x w_x + S_y w_y)``
            (Wiener-regularised where ``H`` vanishes, ``eps = regularization * w_min^2`` with
            ``w_min = 2 pi / N`` the lowest frequency of the 2x zero-padded ``N``-pixel grid,
            so the damping is independent of the light's slant and of the image size: a light
            close to the view gives a nearly flat result instead of huge heights),
            with ``E - S_z`` set to 0 outside the mask.  Cannot see frequencies perpendicular
            to the light's tilt and fails for a frontal light (then returns the flat surface
            with a warning).  Direct: ``n_iter = 0``.
        ``"fast_marching"``
            Kimmel & Sethian, "Optimal algorithm for shape from shading and path planning"
            (JMIV 2001).  Frontal light: the eikonal equation ``|grad z| = sqrt(1/E^2 - 1)``
            solved by fast marching (scikit-fmm) from the singular points
            (``E >= 1 - singular_delta``; all taken as maxima of one height, the convex
            choice) or from the occluding boundary (``z = 0`` there, height growing inward).
            ``seeds="auto"`` uses singular points when present, else the boundary.  Oblique
            light: the same paper's transformation to ``u = S . X`` gives
            ``E^2 (S_z^2 + |grad u - S_xy|^2) = (1 - S_xy . grad u)^2``, marched here by an
            ordered upwind (Dijkstra-like) scheme from the singular points.  Singular points are
            critical points of ``u`` (maxima, but also saddles such as a vase's neck, each at its
            own ``u``), so only the component at the global maximum is seeded: the one whose
            single-seed march (on a <= 64 px subsampled grid) puts the lit occluding contour at
            the most uniform depth (assumes a silhouette in one depth plane; lower maxima then
            become ridges, a local error).  With no singular point under an oblique light
            (``seeds="auto"``) the brightest pixels (``E >= max E - singular_delta``) are
            seeded instead, with a ``RuntimeWarning``.  ``E`` is floored at
            ``e_min`` (shadows become grazing slopes); unreached pixels take their nearest
            reached value (reported in ``info["unreached"]`` with a warning).
    albedo : float, optional
        Uniform albedo (times source intensity).  Default: the brightest pixel in the mask,
        i.e. assume some visible point faces the light (Pentland 1982's assumption).
    mask : (H, W) bool, optional
        Pixels of the surface.  Default: the whole image (then there is no occluding contour).
    pixel_size : float
        Pixel pitch in world units; the height is returned in these units.
    max_iter : int, optional
        Iteration budget (defaults: horn1989 100 sweeps on each grid finer than the coarsest,
        tsai_shah1994 100 Newton steps).
    tol : float, optional
        Stop when the RMS (p, q) update per sweep on the finest grid (horn1989) or the RMS height
        update in pixels
        (tsai_shah1994) falls below it (default 1e-4 for both).
    boundary : "auto", "occluding", "free" or (H, W) bool
        Occluding-contour pixels for ``horn1989``.  ``"occluding"``: the mask's edge minus the
        image frame; ``"auto"`` (default): those of them whose brightness an occluding contour
        could produce (a slant of at least 60 degrees solves the irradiance equation there, or
        the pixel is dark), or none when fewer than ``AUTO_CONTOUR_FRACTION`` (60 %) of the edge
        passes, so a mask cut through a surface is not mistaken for a contour;
        ``"free"``: none; an array: exactly those pixels.
    seeds : {"auto", "singular", "boundary"}
        Start set of ``fast_marching`` (``"boundary"`` only for a frontal light).
    Other keywords tune one method each as described above.

    Returns
    -------
    SFSResult
        ``height`` (H, W) in ``pixel_size`` units with mean zero on the mask (the offset is
        free), ``normals`` (H, W, 3), ``converged``, ``n_iter``, ``method``, ``light``,
        ``albedo``, ``seconds``, ``info``.  A method that stops without meeting its tolerance
        issues a ``RuntimeWarning`` naming the method and the last update size.  The outputs
        never contain NaN.

    Raises
    ------
    ValueError
        On an unknown method or bad input (wrong shapes, NaN, negative pixels, light with
        ``z <= 0``, non-positive albedo / pixel size, bad option values).

    Notes
    -----
    Convex/concave ambiguity: under a frontal light ``f`` and ``-f`` give the same image; all
    methods here pick the convex solution (contour boundary conditions, dome start, maxima at
    the singular points).  Score with :func:`pbrbench.metrics.sfs.ambiguity_aware_scores`.
    """
    check_method(method, METHODS)
    E, s, m, rho, h = _prepare(image, light, albedo, mask, pixel_size)
    theta_max = math.radians(float(theta_max_deg))
    if not 0 < theta_max < math.pi / 2:
        raise ValueError(f"theta_max_deg: must lie in (0, 90), got {theta_max_deg!r}")
    if isinstance(boundary, str):
        check_method(boundary, ("auto", "occluding", "free"), "boundary")
        bnd = occluding_boundary(m) if boundary in ("auto", "occluding") else np.zeros_like(m)
        if boundary == "auto" and bnd.any():
            ok = _contour_consistent(E, s, m, bnd, theta_max=theta_max)
            # a few wrong Dirichlet slopes (tan 88 deg = 29) ruin the solve: trust the edge as a
            # contour only when most of it looks like one
            bnd = ok if ok.sum() >= AUTO_CONTOUR_FRACTION * bnd.sum() else np.zeros_like(m)
    else:
        bnd = check_mask(boundary, m.shape, "boundary") & m if np.asarray(boundary).any() else np.zeros_like(m)
    check_method(seeds, ("auto", "singular", "boundary"), "seeds")
    for name, v in (("smoothness", smoothness), ("smoothness_min", smoothness_min),
                    ("integrability", integrability), ("damping", damping),
                    ("regularization", regularization), ("singular_delta", singular_delta),
                    ("e_min", e_min)):
        check_positive(v, name)
    n_stages = _check_int(n_stages, "n_stages")
    levels = _check_int(levels, "levels")
    frontal = float(np.hypot(s[0], s[1])) < 1e-6
    t0 = time.perf_counter()
    info: dict = {}
    converged = True
    n_iter = 0
    p = q = None
    z = None
    if method == "horn1989":
        mi = _check_int(100 if max_iter is None else max_iter, "max_iter")
        tl = check_positive(1e-4 if tol is None else tol, "tol")
        init = None
        p, q, _, converged, n_iter, delta, total = _horn_pyramid(
            E, s, m, levels=levels, coarse_iter=5 * mi, max_iter=mi, tol=tl, lam=float(smoothness),
            lam_min=float(smoothness_min), mu=float(integrability), boundary=bnd, theta_max=theta_max,
            n_stages=n_stages)
        info = {"final_update": delta, "total_sweeps": total, "n_boundary": int((bnd & m).sum())}
        z = integrate_gradients(p, q, mask=m) * h
        if not converged:
            warnings.warn(f"horn1989: stopped after {n_iter} sweeps on the finest grid (max_iter={mi}) "
                          f"with RMS (p, q) update {delta:.3g} > tol={tl:g}; raise max_iter or tol",
                          RuntimeWarning, stacklevel=2)
    elif method == "tsai_shah1994":
        mi = _check_int(100 if max_iter is None else max_iter, "max_iter")
        tl = check_positive(1e-4 if tol is None else tol, "tol")
        init = None
        if frontal:
            init = 1e-2 * ndimage.distance_transform_edt(np.pad(m, 1))[1:-1, 1:-1]
        # the backward differences make the solve causal from the left and from below: mirror
        # the image so that the light comes from there (S_x, S_y >= 0), solve, mirror back
        fx, fy = s[0] < 0, s[1] < 0
        sm = np.array([abs(s[0]), abs(s[1]), s[2]])

        def mirror(a):
            if a is None:
                return None
            a = a[:, ::-1] if fx else a
            return a[::-1, :] if fy else a
        with np.errstate(all="ignore"):
            zp, converged, n_iter, info = _tsai_shah(mirror(E), sm, mirror(m), max_iter=mi, tol=tl,
                                                     damping=float(damping), init=mirror(init))
        zp = np.ascontiguousarray(mirror(zp))
        z = zp * h
        if info["stalled"]:
            warnings.warn(f"tsai_shah1994: stopped after {n_iter} Newton step(s): no damped step lowers "
                          f"the brightness residual (RMS {info['residual_rms']:.3g}, from "
                          f"{info['initial_residual_rms']:.3g}); the result is the last accepted iterate, "
                          "a stationary point of the linearisation, not an exact solution",
                          RuntimeWarning, stacklevel=2)
        elif not converged:
            warnings.warn(f"tsai_shah1994: stopped at max_iter={mi} with RMS height update "
                          f"{info['final_update']:.3g} px > tol={tl:g}; raise max_iter or tol",
                          RuntimeWarning, stacklevel=2)
    elif method == "pentland1990":
        if frontal:
            warnings.warn("pentland1990: the linear term vanishes for a light along the view "
                          "(S_x = S_y = 0); returning the flat surface", RuntimeWarning, stacklevel=2)
            z = np.zeros_like(E)
            converged = False
        else:
            z = _pentland(E, s, m, reg=float(regularization)) * h
    else:  # fast_marching
        sing = _singular_seeds(E, m, float(singular_delta))
        mode = seeds
        if mode == "auto":
            mode = "boundary" if (frontal and not sing.any()) else "singular"
            if not sing.any() and not frontal:
                # no pixel faces the light (albedo too high, or no such normal on the surface):
                # the brightest pixels are the nearest to singular; seed there
                emax = float(E[m].max())
                sing = m & (E >= emax - float(singular_delta))
                info["brightest_seed"] = emax
                warnings.warn(f"fast_marching: no singular point (max E = {emax:.3g} < 1 - "
                              f"singular_delta = {1 - singular_delta:g}); seeding at the brightest "
                              "pixel(s) as if they faced the light (an approximation: pass the "
                              "albedo so that the brightest point reads 1, if it does face the light)",
                              RuntimeWarning, stacklevel=2)
        if mode == "singular" and not sing.any():
            raise ValueError(f"seeds='singular': no pixel has E >= 1 - singular_delta "
                             f"({1 - singular_delta:g}); pass the albedo, raise singular_delta or "
                             "use seeds='boundary'")
        if frontal:
            zp, gmag = _fmm_eikonal(E, m, seeds=mode, delta=float(singular_delta), e_min=float(e_min), order=2)
            n_iter = int(np.isfinite(zp).sum())
            # the eikonal fixes |grad z| = g exactly; keep the marched tilt, take the slant from g
            zfill, _ = _fill_unreached(zp.copy(), m)
            p, q = _pq_from_height(zfill, m)
            gn = np.hypot(p, q)
            scale = np.where(gn > 1e-12, gmag / np.maximum(gn, 1e-12), 0.0)
            p, q = p * scale, q * scale
        else:
            if mode == "boundary":
                raise ValueError("seeds='boundary': fast_marching supports boundary seeds only for a "
                                 "light along the view; use seeds='singular' or 'auto'")
            sing, n_comp = _global_max_seed(E, s, m, sing, e_min=float(e_min))
            zp, n_iter, _ = _fmm_oblique(E, s, m, e_min=float(e_min), seed_mask=sing)
            info["singular_components"] = n_comp
        zp, unreached = _fill_unreached(zp, m)
        info = {**info, "seeds": mode, "n_seeds": int(sing.sum()) if mode == "singular" else int(occluding_boundary(m, exclude_border=False).sum()),
                "unreached": unreached}
        if unreached:
            converged = False
            warnings.warn(f"fast_marching: {unreached} mask pixel(s) were not reached from the seeds "
                          "(disconnected or unlit); they take their nearest reached height",
                          RuntimeWarning, stacklevel=2)
        z = zp * h
    z = np.where(m, np.nan_to_num(z), 0.0)
    z[m] -= z[m].mean()
    if p is None:
        p, q = _pq_from_height(z / h, m)
    normals = _normals_from_pq(np.nan_to_num(p), np.nan_to_num(q), m)
    return SFSResult(height=z, normals=normals, converged=bool(converged), n_iter=int(n_iter), method=method,
                     light=s, albedo=rho, seconds=time.perf_counter() - t0, info=info)


def _disc_moments(slant: float, n: int = 201):
    """Mean of ``max(0, N.S)`` and of its square over the image of a sphere (uniform on the disc)."""
    u = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(u, u)
    inside = x * x + y * y < 1
    nz = np.sqrt(np.clip(1 - x * x - y * y, 0, None))
    sh = np.maximum(0.0, x * math.sin(slant) + nz * math.cos(slant))[inside]
    return sh.mean(), (sh * sh).mean()


def _brightest(img, m, sigma: float = 1.0) -> float:
    """Brightest value of ``img`` in ``m`` after a normalised Gaussian blur inside the mask.

    Pentland's (1982) albedo is the brightest pixel; the blur (``sigma`` px) keeps pixel noise
    from biasing it upward (the maximum of n noisy pixels sits ~4 sd above the truth).
    """
    w = ndimage.gaussian_filter(m.astype(float), sigma)
    v = ndimage.gaussian_filter(np.where(m, img, 0.0), sigma)
    sm = np.where(m & (w > 1e-3), v / np.maximum(w, 1e-3), 0.0)
    return float(max(sm[m].max(), 0.0))


def _contour_light(img, m, *, seed: int = 0, n_trials: int = 300, inlier_frac: float = 0.05):
    """Robust occluding-contour light fit; returns ``(direction, albedo)``.

    Model at contour pixels: ``I = max(0, a d_x + b d_y + c)`` with ``(a, b) = rho S_xy`` and
    ``c`` absorbing ``rho S_z N_z`` (the pixels read slightly inside the contour).  Edges of the
    mask that are not occluding contours (a surface cut by a plane, a vase's ends) break the
    model; they are rejected as outliers: RANSAC over triples of bright contour pixels (consensus:
    ``|I - max(0, pred)| < inlier_frac * rho``, counted over all contour pixels, dark ones
    included), then least squares on the inliers that are predicted lit, re-selected until stable.
    """
    rho = _brightest(img, m)
    b = occluding_boundary(m)
    dx, dy = _outward_directions(m)
    bi = np.flatnonzero(b)
    inten = img.ravel()[bi]
    A = np.stack([dx.ravel()[bi], dy.ravel()[bi], np.ones(bi.size)], axis=1)
    bright = np.flatnonzero(inten > 0.1 * rho)
    if bright.size < 8:
        raise ValueError(f"mask: only {int(bright.size)} lit occluding-contour pixels (need >= 8); "
                         "pass a mask whose edge is the object's silhouette, or use "
                         "method='lee_rosenfeld1985'")
    tau = inlier_frac * rho

    def consensus(coef):
        return np.abs(inten - np.maximum(0.0, A @ coef)) < tau

    rng = np.random.default_rng(seed)
    best, best_n = None, -1
    for _ in range(n_trials):
        pick = rng.choice(bright, 3, replace=False)
        try:
            coef = np.linalg.solve(A[pick], inten[pick])
        except np.linalg.LinAlgError:
            continue
        n_in = int(consensus(coef).sum())
        if n_in > best_n:
            best, best_n = coef, n_in
    if best is None:
        best = np.linalg.lstsq(A[bright], inten[bright], rcond=None)[0]
    coef = best
    for _ in range(20):
        use = consensus(coef) & (A @ coef > 0.1 * rho) & (inten > 0.02 * rho)
        if use.sum() < 3:
            break
        new = np.linalg.lstsq(A[use], inten[use], rcond=None)[0]
        if np.allclose(new, coef, atol=1e-9):
            break
        coef = new
    sxy = coef[:2] / rho
    nxy = float(np.hypot(*sxy))
    if nxy > 1:
        sxy = sxy / nxy
        nxy = 1.0
    d = np.array([sxy[0], sxy[1], math.sqrt(max(0.0, 1 - nxy * nxy))])
    return d / np.linalg.norm(d), rho


def light_from_shading(image, mask=None, *, method: str = "contour", seed: int = 0) -> LightEstimate:
    r"""Estimate the distant light direction (and albedo) from one image of a Lambertian object.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    mask : (H, W) bool, optional
        The object's pixels; ``"contour"`` needs a mask whose edge is an occluding contour.
    method : {"contour", "lee_rosenfeld1985"}
        ``"contour"`` (default; Nillius & Eklundh, CVPR 2001, with the albedo of Pentland 1982):
        on an occluding contour the normal is the silhouette's outward normal ``(d, 0)``, so
        ``I = max(0, rho d . S_xy)`` at contour pixels: a linear fit for ``rho S_xy``.  The
        albedo is the brightest pixel (some point faces the light, Pentland 1982; taken after a
        1-pixel Gaussian blur so noise does not bias it up), and ``S_z = sqrt(1 - |S_xy|^2)``.
        Contour pixels read slightly inside the true contour, where ``I = rho N . S`` also
        carries ``S_z N_z``; the fit therefore includes a constant term that absorbs it.  Mask
        edges that are not occluding contours (a surface cut by a plane or by the frame) do not
        obey the model: the fit is robust (RANSAC over contour-pixel triples with consensus
        ``|I - max(0, pred)| < 0.05 rho``, then least squares on the inliers predicted lit), so
        they are rejected as long as most of the edge is a true contour.
        ``"lee_rosenfeld1985"`` (Lee & Rosenfeld, Artificial Intelligence 1985): the tilt is the
        direction of the mean image gradient over the object's interior; the slant is found by
        matching the ratio ``<I>^2 / <I^2>`` to its value for a sphere (normals uniform over the
        image disc, attached shadows included), the albedo from ``<I>``.
        Both assume one object of uniform albedo; ``lee_rosenfeld1985`` also assumes its normals
        are distributed like a sphere's.
    seed : int
        Seed of the RANSAC sampling of ``"contour"`` (the result is deterministic given it).

    Returns
    -------
    LightEstimate
        ``direction`` (3,) unit vector toward the source (``z >= 0``), ``albedo``, ``method``.

    Raises
    ------
    ValueError
        On an unknown method, bad image or mask, or too few lit contour pixels.
    """
    check_method(method, LIGHT_METHODS)
    img = as_float_array(image, "image", ndim=(2,))
    m = check_mask(mask, img.shape)
    check_finite(img, "image", where=m)
    if np.any(img[m] < 0):
        raise ValueError("image: has negative values inside the mask; pass a linear image (>= 0)")
    imax = float(img[m].max())
    if imax <= 0:
        raise ValueError("image: all zero inside the mask; the light cannot be estimated")
    if method == "contour":
        d, rho = _contour_light(img, m, seed=seed)
        return LightEstimate(direction=d, albedo=rho, method=method)
    # lee_rosenfeld1985
    inner = ndimage.binary_erosion(m, iterations=2, border_value=0)
    if inner.sum() < 16:
        inner = m
    gr, gc = np.gradient(img)
    mx, my = float(gc[inner].mean()), float(-gr[inner].mean())
    tilt = math.atan2(my, mx)
    m1 = float(img[m].mean())
    m2 = float((img[m] ** 2).mean())
    ratio = m1 * m1 / m2
    slants = np.linspace(0.0, math.radians(89.0), 90)
    table = np.array([_disc_moments(a) for a in slants])
    rt = table[:, 0] ** 2 / table[:, 1]
    # the ratio decreases with the slant; interpolate on the reversed (increasing) arrays
    slant = float(np.interp(ratio, rt[::-1], slants[::-1]))
    e1 = float(np.interp(slant, slants, table[:, 0]))
    rho = m1 / e1 if e1 > 0 else imax
    d = np.array([math.sin(slant) * math.cos(tilt), math.sin(slant) * math.sin(tilt), math.cos(slant)])
    return LightEstimate(direction=d, albedo=float(rho), method=method)
