"""The form-factor matrix of a patch mesh, with visibility by ray casting.

.. math::  F_{ij} = \\sum_q w_q \\, F(x_q \\to P_j) \\, V_j(x_q), \\qquad
           V_j(x) = \\frac{\\sum_s K(x, y_s)\\,\\mathrm{Vis}(x, y_s)}{\\sum_s K(x, y_s)}

with ``x_q, w_q`` a quadrature rule on the receiving patch ``P_i``
(:func:`~pbrbench.shading.form_factors.patch_quadrature`), ``F(x -> P_j)`` the exact
point-to-polygon factor (:func:`~pbrbench.shading.form_factors.point_polygon_form_factors`)
and ``V_j(x)`` the kernel-weighted fraction of sample points ``y_s`` of ``P_j`` that ``x`` sees
(``K = cos cos' / r^2``; rays cast by :func:`pbrbench.radiosity.raycast.segments_blocked`).  This is
the ray-cast visibility of Wallace, Elmquist and Haines (1989) on top of the exact unoccluded
factor; without occluders between the patches ``V = 1`` and the only error is the outer
quadrature.  Pairs closer than ``vis_near`` (distance ratio below) are sampled with rays between
``vis_order`` x ``vis_order`` Gauss points of both patches; farther pairs with the single ray
between the centroids (binary, and reciprocal: ``V_ij = V_ji``).  Only pairs that some occluder
may block cast rays at all (:mod:`pbrbench.radiosity.raycast` culls by bounding spheres and
separating planes).

The outer rule adapts to the separation: for the distance ratio
``t = |c_i - c_j| / max(D_i, D_j)`` (centroid distance over the larger patch diameter) the rule
of the first tier with ``t < t_max`` is used, by default

========  ==================================  ========  ====================
 t_max     rule (cells x Gauss order)          points    relative error
========  ==================================  ========  ====================
 1.2       4 x 4 cells, 2 x 2 Gauss each       64        < 4e-5 (touching)
 2.5       3 x 3 Gauss                         9         < 3e-4
 13        2 x 2 Gauss                         4         < 8e-4
 inf       centroid                            1         ~ 0.17 / t^2 < 1e-3
========  ==================================  ========  ====================

(errors of single factors measured against a converged rule for unit squares facing each other,
offset, and perpendicular; the centroid rule's error is the midpoint rule's
``h^2 Laplacian(f) / 24``).  Because the rule differs between the ``j`` of one row, row sums of
a closed enclosure are 1 only up to this quadrature error; a uniform rule
(``quadrature=(n_sub, order)``) makes them 1 to rounding.

References
----------
J. R. Wallace, K. A. Elmquist and E. A. Haines, "A ray tracing algorithm for progressive
radiosity", SIGGRAPH 1989; M. F. Cohen and D. P. Greenberg, "The hemi-cube: a radiosity solution
for complex environments", SIGGRAPH 1985 (the point-sampled, visibility-aware alternative);
P. Schröder and P. Hanrahan, "On the form factor between two polygons", SIGGRAPH 1993.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import check_int
from pbrbench.radiosity.raycast import front_flags, segments_blocked, side_flags
from pbrbench.shading.form_factors import (
    as_patch_vertices,
    patch_geometry,
    patch_quadrature,
    point_polygon_form_factors,
)

__all__ = ["form_factor_matrix", "DEFAULT_TIERS", "VisibilityContext", "visible_fraction"]

DEFAULT_TIERS = ((1.2, 4, 2), (2.5, 1, 3), (13.0, 1, 2), (np.inf, 1, 1))
_FACING = 1e-9


def _tiers(quadrature):
    if isinstance(quadrature, str):
        if quadrature != "adaptive":
            raise ValueError(f"quadrature={quadrature!r} is not known; use 'adaptive' or a pair (n_sub, order)")
        return DEFAULT_TIERS
    try:
        n_sub, order = quadrature
    except (TypeError, ValueError):
        raise ValueError(f"quadrature: expected 'adaptive' or a pair (n_sub, order), got {quadrature!r}") from None
    return ((np.inf, check_int(n_sub, "quadrature n_sub", 1, 64), check_int(order, "quadrature order", 1, 16)),)


class VisibilityContext:
    """Occluders of a patch mesh and the side flags of its patches and of a set of emitters."""

    def __init__(self, patches, emitter_vertices=None):
        self.patches = patches
        self.occ = patches.occluders()
        self.flags_r = side_flags(self.occ, patches.vertices)
        self.front_r = front_flags(self.occ, patches.planes)
        if emitter_vertices is None:
            self.flags_e = self.flags_r
            self.centres_e, self.radii_e = patches.centres, patches.radii
        else:
            self.flags_e = side_flags(self.occ, emitter_vertices)
            self.centres_e, _, _, self.radii_e = patch_geometry(emitter_vertices)


def visible_fraction(ctx: VisibilityContext, points, samples, sample_weights, i, j, b_normals):
    """Kernel-weighted fraction of the sample points of emitters ``j`` seen from points of patches ``i``.

    .. math::  V(x) = \\sum_s K(x, y_s) \\mathrm{Vis}(x, y_s) / \\sum_s K(x, y_s),
               \\quad K = w_s \\max(0, n \\cdot d) \\max(0, -n_s \\cdot d) / |d|^4

    ``points`` (P, Q, 3) lie on patches ``i`` (P,); ``samples`` (P, S, 3) with weights (P, S)
    on emitters ``j`` with normals ``b_normals`` (P, 3) (None: no cosine at the target).
    Returns (P, Q).
    """
    P, Q, _ = points.shape
    S = samples.shape[1]
    pt = ctx.patches
    vis = np.ones((P, Q))
    # spheres around the actual ray end points (a single ray: radius 0, the segment itself)
    ca, cb = points.mean(axis=1), samples.mean(axis=1)
    rmax = np.maximum(np.max(np.linalg.norm(points - ca[:, None], axis=-1), axis=1),
                      np.max(np.linalg.norm(samples - cb[:, None], axis=-1), axis=1))

    def orig(idx):
        return np.broadcast_to(points[idx][:, :, None, :], (len(idx), Q, S, 3)).reshape(len(idx), Q * S, 3)

    def targ(idx):
        return np.broadcast_to(samples[idx][:, None, :, :], (len(idx), Q, S, 3)).reshape(len(idx), Q * S, 3)

    blocked = segments_blocked(ctx.occ, orig, targ, ca, cb, rmax, ctx.flags_r, i, ctx.flags_e, j, ctx.front_r)
    m = np.flatnonzero(blocked.any(axis=1))
    if len(m) == 0:
        return vis
    blocked = blocked[m].reshape(len(m), Q, S)
    points, samples, sample_weights, i = points[m], samples[m], sample_weights[m], i[m]
    if not blocked.any():
        return vis
    d = samples[:, None, :, :] - points[:, :, None, :]
    r2 = np.maximum(np.sum(d * d, -1), 1e-300)
    k = np.maximum(np.einsum("pqsk,pk->pqs", d, pt.normals[i]), 0.0)
    if b_normals is not None:
        k = k * np.maximum(-np.einsum("pqsk,pk->pqs", d, b_normals[m]), 0.0)
    k = k / r2 ** 2 * sample_weights[:, None, :]
    tot = k.sum(-1)
    vis[m] = np.where(tot > 0, (k * ~blocked).sum(-1) / np.where(tot > 0, tot, 1.0), (~blocked).mean(-1))
    return vis


def _nearest_node(rule, coarse) -> np.ndarray:
    """For each node of a (n_sub, order) rule, the nearest node of the coarse rule, in (u, v)."""
    def nodes(ns, o):
        if ns == 1 and o == 1:
            return np.array([[0.5, 0.5]])
        from pbrbench.shading.form_factors import gauss_legendre01

        g, _ = gauss_legendre01(o)
        u1 = ((np.arange(ns)[:, None] + g[None, :]) / ns).ravel()
        U, V = np.meshgrid(u1, u1, indexing="ij")
        return np.stack([U.ravel(), V.ravel()], -1)

    a, b = nodes(*rule), nodes(*coarse)
    return np.argmin(np.linalg.norm(a[:, None] - b[None], axis=-1), axis=1)


def form_factor_matrix(patches, emitters=None, *, quadrature="adaptive", visibility: bool = True,
                       vis_order: int = 2, vis_near: float = 2.5, sparse: bool = False,
                       pair_budget: int = 300_000):
    """Form factors ``F[i, j]`` from every patch ``i`` to every emitter polygon ``j``.

    Parameters
    ----------
    patches : Patches
        Receivers (and occluders).
    emitters : array_like (M, 3 or 4, 3), optional
        One-sided emitting polygons (e.g. area lights); default: the patches themselves (then
        ``F[i, i] = 0`` and the result is the radiosity matrix).
    quadrature : 'adaptive' or (n_sub, order)
        Outer rule on the receiving patch (see the module docstring).
    visibility : bool
        Cast rays against every patch and extra occluder (False: assume every pair of mutually
        facing patches sees each other, exact for a convex enclosure or a V groove).
    vis_order : int
        For pairs closer than ``vis_near`` (distance ratio), visibility is sampled with rays
        between the ``vis_order`` x ``vis_order`` Gauss points of both patches (each quadrature
        point takes the value of its nearest visibility point); farther pairs use the one ray
        between the centroids (binary visibility, reciprocal).
    sparse : bool
        Return a ``scipy.sparse.csr_array`` instead of a dense array.
    pair_budget : int
        (point, polygon) evaluations per vectorised step (memory about 3 kB each).

    Returns
    -------
    ndarray (N, M) or csr_array
    """
    recv = patches
    same = emitters is None
    ev = recv.vertices if same else as_patch_vertices(emitters, "emitters")
    ec, en, _, er = (recv.centres, recv.normals, None, recv.radii) if same else patch_geometry(ev)
    vis_order = check_int(vis_order, "vis_order", 1, 8)
    tiers = _tiers(quadrature)
    N, M = len(recv), len(ev)
    # where visibility is sampled more finely than a tier's rule, integrate on the visibility points
    lo_t = (-np.inf,) + tuple(t for t, _, _ in tiers[:-1])
    tiers = tuple((t, 1, vis_order) if (visibility and lo < vis_near and ns * o < vis_order) else (t, ns, o)
                  for (t, ns, o), lo in zip(tiers, lo_t, strict=True))
    rules = [patch_quadrature(recv.vertices, ns, o) for _, ns, o in tiers]
    maps = [_nearest_node((ns, o), (1, vis_order)) for _, ns, o in tiers]
    vpts, _ = patch_quadrature(recv.vertices, 1, vis_order)
    samp, samp_w = patch_quadrature(ev, 1, vis_order)
    ctx = VisibilityContext(recv, None if same else ev) if visibility else None
    rows_out, cols_out, vals_out = [], [], []
    diam_r, diam_e = 2 * recv.radii, 2 * er
    step = max(1, 4_000_000 // (8 * max(M, 1)))
    for r0 in range(0, N, step):
        r1 = min(N, r0 + step)
        hj = np.einsum("mvk,nk->nmv", ev, recv.normals[r0:r1]) - np.sum(recv.normals[r0:r1] * recv.centres[r0:r1], 1)[:, None, None]
        hi = (np.einsum("nvk,mk->nmv", recv.vertices[r0:r1], en) - np.sum(en * ec, 1)[None, :, None])
        facing = (hj > _FACING).any(-1) & (hi > _FACING).any(-1)
        if same:
            facing[np.arange(r1 - r0), np.arange(r0, r1)] = False
        pi_, pj_ = np.nonzero(facing)
        pi_ = pi_ + r0
        ratio = np.linalg.norm(recv.centres[pi_] - ec[pj_], axis=1) / np.maximum(diam_r[pi_], diam_e[pj_])
        lo = -np.inf
        for (hi_t, _, _), (pts, w), nmap in zip(tiers, rules, maps, strict=True):
            sel = np.flatnonzero((ratio >= lo) & (ratio < hi_t))
            fine = lo < vis_near  # this tier holds pairs closer than vis_near
            lo = hi_t
            Q = pts.shape[1]
            chunk = max(1, pair_budget // Q)
            for k0 in range(0, len(sel), chunk):
                s = sel[k0:k0 + chunk]
                i, j = pi_[s], pj_[s]
                x = pts[i]
                ff = point_polygon_form_factors(
                    x.reshape(-1, 3), np.repeat(recv.normals[i], Q, axis=0),
                    np.repeat(ev[j], Q, axis=0), np.repeat(en[j], Q, axis=0)).reshape(len(s), Q)
                if ctx is not None:
                    live = np.flatnonzero(ff.any(axis=1))
                    if len(live):
                        il, jl = i[live], j[live]
                        if fine:
                            vis = visible_fraction(ctx, vpts[il], samp[jl], samp_w[jl], il, jl, en[jl])[:, nmap]
                        else:
                            vis = visible_fraction(ctx, recv.centres[il, None], ec[jl, None], np.ones((len(live), 1)),
                                                   il, jl, en[jl])
                        ff[live] *= vis
                val = np.sum(ff * w[i], axis=1)
                nz = val > 0
                rows_out.append(i[nz])
                cols_out.append(j[nz])
                vals_out.append(val[nz])
    rows = np.concatenate(rows_out) if rows_out else np.zeros(0, int)
    cols = np.concatenate(cols_out) if cols_out else np.zeros(0, int)
    vals = np.concatenate(vals_out) if vals_out else np.zeros(0)
    if sparse:
        from scipy.sparse import csr_array

        return csr_array((vals, (rows, cols)), shape=(N, M))
    F = np.zeros((N, M))
    F[rows, cols] = vals
    return F
