r"""Tsai & Shah (1994): shape from shading by linearising the reflectance in the height.

With backward differences ``p = z(x, y) - z(x-1, y)``, ``q = z(x, y) - z(x, y-1)`` (pixels outside
the mask hold ``z = 0``) every pixel gives one equation

.. math::
    f(z) = E - R\big(z_{x,y} - z_{x-1,y},\; z_{x,y} - z_{x,y-1}\big) = 0,

linearised in ``z`` (``R`` the reflectance map of :mod:`pbrbench.infer.sfs._common`).  Tsai & Shah
update each pixel alone (a Jacobi iteration on a triangular system, which oscillates); here the
linearised system is solved for all pixels at once: in causal order it is lower triangular, so a
Newton step is one forward substitution, damped and line-searched on the brightness residual.

References
----------
P.-S. Tsai and M. Shah, "Shape from shading using linear approximation", Image and Vision
Computing 12(8):487-498, 1994.
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
from scipy import ndimage

from pbrbench.checks import check_int, check_positive, check_tolerance
from pbrbench.infer._docstring import docstring
from pbrbench.infer.sfs._common import DOCS, SFSResult, _finish, _is_frontal, _prepare, _reflectance

__all__ = ["shape_from_shading_tsai_shah1994"]


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


@docstring(DOCS)
def shape_from_shading_tsai_shah1994(image, light, *, albedo=None, mask=None, pixel_size: float = 1.0,
                                     max_iter: int = 100, tol: float = 1e-4,
                                     damping: float = 1e-2) -> SFSResult:
    r"""Height and normals from one image by Tsai & Shah's (1994) linearisation, solved by Newton.

    .. math::
        f_k(z) = E_k - R(z_k - z_{\text{left}(k)},\; z_k - z_{\text{below}(k)}) = 0,
        \qquad J\, d = -f

    With backward differences each pixel gives ``f(z) = E - R(p, q) = 0``, linearised in ``z``.
    Tsai & Shah update each pixel alone (a Jacobi iteration on a triangular system: it
    oscillates and never converges); here the linearised system is solved for all pixels at
    once, which in causal order (from the lower left) is one forward substitution: a Newton
    step.  It is damped (the diagonal ``-(R_p + R_q)`` pushed away from 0, at least
    ``damping``), no pixel may move more than the image size in one step, and the length is
    halved until the brightness residual ``sum f^2`` decreases.  The image is mirrored so that
    the light comes from the lower left (the causal direction of the differences) and mirrored
    back.  From the flat start the first step is the linear (Pentland-like) solution; the
    iteration usually stalls after a few steps at a point where no damped step lowers the
    residual: it then stops with a ``RuntimeWarning`` (``info["stalled"]``) and
    ``converged=False``.  Under a frontal light the flat start is a stationary point; the
    iteration then starts from a small dome (distance to the mask edge x 1e-2) and does little
    better than flat.  Shadow pixels (``E = 0``) contribute ``-max(R, 0)``.

    Parameters
    ----------
    image, light, albedo, mask, pixel_size
        As for :func:`pbrbench.infer.sfs.shape_from_shading`.
    max_iter : int
        Newton steps.
    tol : float
        Stop when the RMS height update of a step (pixels) falls below it.
    damping : float
        Smallest magnitude of the Newton diagonal (> 0).

    Returns
    -------
    SFSResult
        ``method="tsai_shah1994"``; ``n_iter`` counts accepted Newton steps; ``info`` holds
        ``final_update``, ``stalled``, ``residual_rms`` and ``initial_residual_rms``.

    %(raises)s

    References
    ----------
    P.-S. Tsai and M. Shah, "Shape from shading using linear approximation", Image and Vision
    Computing 12(8):487-498, 1994.
    """
    E, s, m, rho, h = _prepare(image, light, albedo, mask, pixel_size)
    damping = check_positive(damping, "damping")
    mi = check_int(max_iter, "max_iter")
    tl = check_tolerance(tol)
    t0 = time.perf_counter()
    init = None
    if _is_frontal(s):
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
                                                 damping=damping, init=mirror(init))
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
    return _finish(z, None, None, m, h, method="tsai_shah1994", converged=converged, n_iter=n_iter, s=s,
                   rho=rho, t0=t0, info=info, image=E)
