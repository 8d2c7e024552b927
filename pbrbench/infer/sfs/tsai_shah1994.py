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

    Only the mask's pixels are unknowns (the others hold 0 and decouple).  The substitution runs
    over anti-diagonals of the image (a pixel's left and lower neighbours lie on the previous
    one), each a contiguous block of the unknowns, with the diagonal scaled out first and the
    lower neighbour's term subtracted before the left one's.  The iteration does not converge
    on most images (it stops at ``max_iter`` or stalls) and its path depends on the last bit of
    every step, so this order of operations, and the sums over the full image, are part of the
    method's definition: they give the same iterates as a general sparse triangular solver.
    """
    H, W = E.shape
    N = H * W
    max_step = float(max(H, W))
    mf = m[::-1].ravel()
    pix = np.flatnonzero(mf)                         # the unknowns' positions in the causal order
    wave = pix // W + pix % W                        # each one's anti-diagonal
    order = np.argsort(wave, kind="stable")
    pix, wave = pix[order], wave[order]              # grouped by anti-diagonal
    n = pix.size
    cuts = np.flatnonzero(np.diff(wave)) + 1
    blocks = list(zip(np.r_[0, cuts].tolist(), np.r_[cuts, n].tolist(), strict=True))
    where = np.full(N, n)                            # each pixel's unknown; n: outside the mask (z = 0)
    where[pix] = np.arange(n)
    left = np.where(pix % W > 0, where[np.maximum(pix - 1, 0)], n)
    below = np.where(pix >= W, where[np.maximum(pix - W, 0)], n)
    has_l, has_b = left < n, below < n
    ef = E[::-1].ravel()[pix]
    shadow = ef <= 0.0
    z = np.zeros(n) if init is None else np.asarray(init, float)[::-1].ravel()[pix]
    ext = np.zeros(n + 1)                            # an unknown's vector and the 0 outside the mask
    full = np.zeros(N)

    def total(v):
        # sum of squares over the whole image (0 outside the mask), summed in the image's order
        full[pix] = v
        return float(full @ full)

    def residual(zv):
        ext[:n] = zv
        p = zv - ext[left]
        q = zv - ext[below]
        r, rp, rq = _reflectance(p, q, s)
        f = np.where(shadow, -np.maximum(r, 0.0), ef - r)
        g = np.where(shadow & (r <= 0.0), 0.0, 1.0)
        return f, rp * g, rq * g

    def solve(dg, rp, rq, b):
        inv = 1.0 / dg
        ul = np.zeros(n)
        ub = np.zeros(n)
        ul[has_l] = rp[has_l] * inv[left[has_l]]
        ub[has_b] = rq[has_b] * inv[below[has_b]]
        y = np.zeros(n + 1)
        for a0, a1 in blocks:
            y[a0:a1] = (b[a0:a1] - ub[a0:a1] * y[below[a0:a1]]) - ul[a0:a1] * y[left[a0:a1]]
        return y[:n] * inv

    f, rp, rq = residual(z)
    cost = total(f)
    cost0 = cost
    nm = max(n, 1)
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
            d = solve(dg, rp, rq, -f)
            if not np.all(np.isfinite(d)):
                continue
            # trust region: no pixel moves by more than the image's size in one step (a near-zero
            # diagonal otherwise gives steps of 1e4 px that still lower the residual)
            dmax = float(np.abs(d).max()) if n else 0.0
            a = min(1.0, max_step / dmax) if dmax > 0 else 1.0
            for _ in range(n_halvings):
                zn = z + a * d
                fn, rpn, rqn = residual(zn)
                cn = total(fn)
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
        full[pix] = d
        delta = a * math.sqrt(float(np.sum(full * full)) / nm)
        z, f, rp, rq, cost = zn, fn, rpn, rqn, cn
        if delta < tol:
            converged = True
            break
    full[pix] = z                                    # (only the unknowns' places are ever written)
    zimg = full.reshape(H, W)[::-1]
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
