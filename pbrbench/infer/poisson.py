"""Least-squares integration of a gradient field (the Poisson problem), shared by surface
integration, retinex and shape from shading.

The problem, in **array-index coordinates** (``gx``: forward difference along columns,
``gy``: forward difference along rows, i.e. downward)::

    min_u  sum_{i,j} wx[i,j] (u[i,j+1] - u[i,j] - gx[i,j])^2
         + sum_{i,j} wy[i,j] (u[i+1,j] - u[i,j] - gy[i,j])^2

An equation is used only when both of its pixels lie inside ``mask`` and its weight is > 0.
Its normal equations are the weighted graph-Laplacian (discrete Poisson) system
``L u = D^T W g`` with natural (Neumann) boundary conditions on the border of the domain.

Conversion from surface gradients ``p = f_x``, ``q = f_y`` (y up, docs/conventions.md) sampled with
pixel size ``h``: ``gx = h p`` (averaged to the edge between the two pixels) and ``gy = -h q``
(rows go down while y goes up).

Only NumPy and SciPy are imported at module level; pyamg is imported lazily by ``method="cg"``.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.fft
import scipy.sparse as sp
import scipy.sparse.linalg
from scipy.sparse.csgraph import connected_components

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_int,
    check_mask,
    check_method,
    check_tolerance,
)
from pbrbench.infer._scale import max_abs, pow2_exponent

__all__ = ["solve_gradient_field", "METHODS"]

METHODS = ("auto", "dct", "cg", "direct")


def _check_weight(w, shape, name):
    if w is None:
        return None
    arr = as_float_array(w, name, ndim=(2,))
    if arr.shape != tuple(shape):
        raise ValueError(f"{name}: shape {arr.shape} does not match gx/gy shape {tuple(shape)}; "
                         "pass an (H, W) array of weights")
    check_finite(arr, name)
    if np.any(arr < 0):
        raise ValueError(f"{name}: weights must be >= 0, got a minimum of {arr.min():g}; "
                         "clip negative weights to 0")
    return arr


def _solve_dct(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Exact Neumann solve on the full rectangle: DCT-II diagonalises the grid Laplacian."""
    h, w = gx.shape
    b = np.zeros((h, w))
    if w > 1:
        ex = gx[:, :-1]
        b[:, 1:] += ex
        b[:, :-1] -= ex
    if h > 1:
        ey = gy[:-1, :]
        b[1:, :] += ey
        b[:-1, :] -= ey
    bh = scipy.fft.dctn(b, type=2, norm="ortho", workers=-1)
    lam_x = 2.0 - 2.0 * np.cos(np.pi * np.arange(w) / w)
    lam_y = 2.0 - 2.0 * np.cos(np.pi * np.arange(h) / h)
    lam = lam_y[:, None] + lam_x[None, :]
    lam[0, 0] = 1.0
    uh = bh / lam
    uh[0, 0] = 0.0  # mean zero
    return scipy.fft.idctn(uh, type=2, norm="ortho", workers=-1)


def _build_system(gx, gy, mask, wx, wy):
    """Weighted 5-point Laplacian (CSR) on the pixels touched by at least one equation, and rhs.

    Returns ``(lap, rhs, unk)`` with ``unk`` the flat indices of the unknown pixels.
    """
    h, w = gx.shape
    n = h * w
    ex = np.zeros((h, w))
    ey = np.zeros((h, w))
    ex[:, :-1] = mask[:, :-1] & mask[:, 1:]
    ey[:-1, :] = mask[:-1, :] & mask[1:, :]
    if wx is not None:
        ex[:, :-1] *= wx[:, :-1]
    if wy is not None:
        ey[:-1, :] *= wy[:-1, :]
    exf = ex.ravel()
    eyf = ey.ravel()
    diag = exf + eyf
    diag[1:] += exf[:-1]
    diag[w:] += eyf[:-w]
    unk = np.flatnonzero(diag > 0)
    diagonals, offsets = [diag], [0]
    if w > 1:
        diagonals += [-exf[:-1], -exf[:-1]]
        offsets += [-1, 1]
    if h > 1:
        diagonals += [-eyf[:-w], -eyf[:-w]]
        offsets += [-w, w]
    lap = sp.diags(diagonals, offsets, shape=(n, n), format="csr")
    lap.eliminate_zeros()
    lap = lap[unk][:, unk].tocsr()
    bx = exf * gx.ravel()
    by = eyf * gy.ravel()
    rhs = -bx - by
    rhs[1:] += bx[:-1]
    rhs[w:] += by[:-w]
    return lap, rhs[unk], unk


def _pin(lap, rhs, labels, ncomp):
    """Drop the first node of each component: the rest is symmetric positive definite.

    Returns ``(sub, sub_rhs, keep, first)``.
    """
    n = lap.shape[0]
    first = np.full(ncomp, -1, dtype=np.int64)
    order = np.arange(n)[::-1]
    first[labels[order]] = order  # last write wins: the smallest index of each component
    keep = np.ones(n, dtype=bool)
    keep[first] = False
    return lap[keep][:, keep].tocsr(), rhs[keep], keep, first


_DCT_PCG_MAXITER = 40


def _dct_pcg(lap, rhs, unk, shape, tol):
    """Conjugate gradients preconditioned by the exact Neumann Poisson solve (DCT) on a
    rectangle holding the domain (its bounding box, padded to fast FFT sizes). Few iterations on compact domains; returns ``(x, converged)``."""
    w_full = shape[1]
    ii, jj = np.divmod(unk, w_full)
    r0, c0 = ii.min(), jj.min()
    # any rectangle holding the domain will do: pad to sizes the FFT handles fast
    bh = scipy.fft.next_fast_len(int(ii.max() - r0 + 1), real=True)
    bw = scipy.fft.next_fast_len(int(jj.max() - c0 + 1), real=True)
    loc = (ii - r0) * bw + (jj - c0)
    lam = ((2.0 - 2.0 * np.cos(np.pi * np.arange(bh) / bh))[:, None]
           + (2.0 - 2.0 * np.cos(np.pi * np.arange(bw) / bw))[None, :])
    lam[0, 0] = 1.0
    inv_lam = 1.0 / lam
    inv_lam[0, 0] = 0.0
    buf = np.zeros(bh * bw)

    def prec(r):
        buf[loc] = r
        f = scipy.fft.dctn(buf.reshape(bh, bw), type=2, norm="ortho")
        f *= inv_lam
        v = scipy.fft.idctn(f, type=2, norm="ortho").ravel()[loc]
        return v - v.mean()

    m_op = scipy.sparse.linalg.LinearOperator(lap.shape, prec, dtype=float)
    x, info = scipy.sparse.linalg.cg(lap, rhs, rtol=tol, atol=0.0, maxiter=_DCT_PCG_MAXITER, M=m_op)
    return x, info == 0


def _solve_cg(lap, rhs, tol, maxiter, x0=None):
    import pyamg  # lazy: keeps `import pbrbench.infer` light

    # Classical (Ruge-Stuben) AMG with the second coarsening pass: on the 5-point Laplacian it
    # needs ~8 CG iterations for 1e-8 and has the cheapest setup of pyamg's solvers.
    ml = pyamg.ruge_stuben_solver(lap, CF=("RS", {"second_pass": True}), max_coarse=50)
    x = ml.solve(rhs, x0=x0, tol=tol, maxiter=maxiter if maxiter is not None else 200, accel="cg")
    bnorm = np.linalg.norm(rhs)
    final = np.linalg.norm(rhs - lap @ x)
    if bnorm > 0 and final > 10 * tol * bnorm:
        warnings.warn(f"solve_gradient_field: conjugate gradients stopped at relative residual "
                      f"{final / bnorm:.2e} > tol={tol:g}; raise maxiter", RuntimeWarning, stacklevel=3)
    return x


def solve_gradient_field(gx, gy, *, mask=None, wx=None, wy=None, tol: float = 1e-8,
                         maxiter: int | None = None, method: str = "auto") -> np.ndarray:
    r"""Least-squares function whose forward differences best match a gradient field.

    Solves

    .. math::
        \min_u \sum w^x_{ij}(u_{i,j+1}-u_{ij}-g^x_{ij})^2 + \sum w^y_{ij}(u_{i+1,j}-u_{ij}-g^y_{ij})^2

    through its normal equations, the discrete Poisson equation ``L u = D^T W g`` with natural
    (Neumann) boundary conditions on the border of the (possibly non-rectangular) domain
    (Simchony, Chellappa & Shao, "Direct analytical methods for solving Poisson equations in
    computer vision problems", IEEE TPAMI 1990; Agrawal, Raskar & Chellappa, "What is the range
    of surface reconstructions from a gradient field?", ECCV 2006). The iterative solver is
    conjugate gradients preconditioned by classical algebraic multigrid (Ruge & Stuben,
    "Algebraic multigrid", in Multigrid Methods, SIAM Frontiers in Applied Math. 1987).

    Parameters
    ----------
    gx, gy : (H, W) array
        Target forward differences in array-index coordinates: ``gx[i, j]`` ~ ``u[i, j+1] -
        u[i, j]`` (last column ignored), ``gy[i, j]`` ~ ``u[i+1, j] - u[i, j]`` (last row
        ignored, rows go down).
    mask : (H, W) bool, optional
        Domain. An equation is used only when both its pixels are inside. Default: all pixels.
    wx, wy : (H, W) array, optional
        Non-negative weights of the x / y equations (default 1); weight 0 drops an equation.
    tol : float
        Relative residual tolerance of the iterative solver (``"cg"``).
    maxiter : int, optional
        Iteration cap of the iterative solver (default 200 preconditioned iterations).
    method : {"auto", "dct", "cg", "direct"}
        ``"dct"``: exact DCT-II Poisson solve, only for the full rectangle with unit weights.
        ``"cg"``: preconditioned conjugate gradients. With unit weights it first tries the exact
        DCT Poisson solve on the domain's bounding box as preconditioner (converges in ~10-20
        iterations on compact domains; capped at 40); weighted problems, and domains where that
        stalls (thin, elongated), use classical (Ruge-Stuben) algebraic multigrid (pyamg) on the masked / weighted graph Laplacian. ``"direct"``: SciPy sparse direct solve
        (reference, slow at large sizes). ``"auto"``: ``"dct"`` when applicable, else ``"cg"``.

    Returns
    -------
    u : (H, W) float64
        The solution, with mean zero over each connected component of the graph of used
        equations (the mask's 4-connected components when all weights are positive); 0 outside
        the mask and at pixels that no equation touches.

    Raises
    ------
    ValueError
        On mismatched shapes, non-finite values inside the mask, negative weights, an unknown
        method, or ``method="dct"`` with a mask or non-unit weights.
    """
    check_method(method, METHODS)
    gx = as_float_array(gx, "gx", ndim=(2,))
    gy = as_float_array(gy, "gy", ndim=(2,))
    if gx.shape != gy.shape:
        raise ValueError(f"gy: shape {gy.shape} differs from gx shape {gx.shape}; pass two (H, W) arrays of one shape")
    shape = gx.shape
    m = check_mask(mask, shape)
    check_finite(gx, "gx", where=m)
    check_finite(gy, "gy", where=m)
    wx = _check_weight(wx, shape, "wx")
    wy = _check_weight(wy, shape, "wy")
    tol = check_tolerance(tol)
    if maxiter is not None:
        maxiter = check_int(maxiter, "maxiter", 1)

    e = pow2_exponent(max(max_abs(gx, m), max_abs(gy, m)))
    if e:   # extreme magnitudes: solve the exactly rescaled field (the solution is linear in g)
        z = np.ldexp(solve_gradient_field(np.ldexp(gx, -e), np.ldexp(gy, -e), mask=m, wx=wx, wy=wy, tol=tol,
                                          maxiter=maxiter, method=method), e)
        if not np.isfinite(z).all():
            raise ValueError("gx/gy: the height overflows float64 at this gradient scale; divide gx and gy by a "
                             "constant (the solution scales with them)")
        return z
    full = bool(m.all())
    unit = all(w is None or np.all(w == 1.0) for w in (wx, wy))
    if method == "dct" and not (full and unit):
        raise ValueError("method='dct' solves only the full rectangle with unit weights; "
                         "drop mask/wx/wy or use method='cg' (or 'auto')")
    if method == "auto":
        method = "dct" if (full and unit) else "cg"
    if method == "dct":
        gx0 = np.where(m, gx, 0.0)
        gy0 = np.where(m, gy, 0.0)
        return _solve_dct(gx0, gy0)

    gx0 = np.where(m, gx, 0.0)
    gy0 = np.where(m, gy, 0.0)
    lap, rhs, unk = _build_system(gx0, gy0, m, wx, wy)
    out = np.zeros(shape[0] * shape[1])
    if unk.size == 0:
        return out.reshape(shape)
    ncomp, labels = connected_components(lap, directed=False)
    x = None
    if method == "cg" and unit:
        # compact domains: DCT-preconditioned CG converges in ~10-20 iterations
        xd, converged = _dct_pcg(lap, rhs, unk, shape, tol)
        if converged:
            x = xd
    if x is None:
        sub, srhs, keep, first = _pin(lap, rhs, labels, ncomp)
        x = np.zeros(unk.size)
        if sub.shape[0] > 0:
            if method == "cg":
                # thin or weighted domains: AMG-preconditioned CG (warm start from the DCT phase)
                x0 = None if not unit else (xd - xd[first][labels])[keep]
                x[keep] = _solve_cg(sub, srhs, tol, maxiter, x0)
            else:
                x[keep] = scipy.sparse.linalg.spsolve(sub.tocsc(), srhs)
    counts = np.bincount(labels, minlength=ncomp)
    x -= (np.bincount(labels, x, minlength=ncomp) / counts)[labels]
    out[unk] = x
    return out.reshape(shape)
