"""Vectorised ray casting against a triangle soup: the visibility term of the radiosity model.

Triangles are grouped (one group per planar face of a shape, one per heightfield, one per area
light) and each group is cut into small clusters (at most ``cluster_size`` triangles, by
recursive median bisection).  A query is a set of *bundles*: rays from points of one convex set
``a`` (a receiving patch) to points of another ``b`` (an emitting patch, a light).  A bundle is
tested against a group or a cluster only if

* its bounding sphere comes within reach of the segment between the bundle's centres (every
  segment from ``a`` to ``b`` lies within ``max(r_a, r_b)`` of it), and
* for a planar group or cluster, ``a`` and ``b`` have points strictly on opposite sides of its
  plane (a segment crosses a plane only then), and
* it has a point strictly in front of ``a``'s plane (rays leave ``a`` to its front side).

The side flags of ``a`` and ``b`` (:func:`side_flags`) can be computed once per patch and reused
for every pair.  The surviving (ray, triangle) pairs go through the Möller-Trumbore test in
chunks that keep the temporaries to a few hundred MB.  Hits with ``t`` in
``(t_min, 1 - t_min)`` of the segment count: the end points lie on surfaces and never block.

Reference: T. Möller and B. Trumbore, "Fast, minimum storage ray-triangle intersection",
Journal of Graphics Tools 2(1), 1997; E. A. Haines and J. R. Wallace, "Shaft culling for
efficient ray-cast radiosity", Eurographics Workshop on Rendering, 1991 (the culling idea).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Occluders", "build_occluders", "side_flags", "front_flags", "bundles_maybe_blocked", "segments_blocked",
           "ray_triangle_hits"]

_EPS = 1e-9


@dataclass(frozen=True)
class Occluders:
    """Triangles sorted by cluster, with bounding spheres and planes of clusters and groups."""

    triangles: np.ndarray  # (K, 3, 3), sorted by cluster
    cluster_start: np.ndarray  # (C + 1,) CSR offsets into triangles
    cluster_centre: np.ndarray  # (C, 3)
    cluster_radius: np.ndarray  # (C,)
    cluster_plane: np.ndarray  # (C, 4): unit normal and offset (n . x = d); NaN when not planar
    group_centre: np.ndarray  # (G, 3)
    group_radius: np.ndarray  # (G,)
    group_plane: np.ndarray  # (G, 4)
    group_clusters: np.ndarray  # (G + 1,) CSR offsets into the clusters
    tri_normal: np.ndarray = None  # (K, 3) e1 x e2 (unnormalised)
    tri_offset: np.ndarray = None  # (K,) normal . v0
    tri_dual: np.ndarray = None  # (K, 2, 3): (e2 x n, n x e1) / |n|^2 (barycentric coordinates)

    def __post_init__(self):
        t = self.triangles
        e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        n = np.cross(e1, e2)
        n2 = np.sum(n * n, axis=1)
        good = n2 > 1e-30 * np.maximum(np.sum(e1 * e1, 1) * np.sum(e2 * e2, 1), 1e-300)
        inv = np.where(good, 1.0 / np.where(good, n2, 1.0), 0.0)
        dual = np.stack([np.cross(e2, n), np.cross(n, e1)], axis=1) * inv[:, None, None]
        object.__setattr__(self, "tri_normal", np.where(good[:, None], n, 0.0))
        object.__setattr__(self, "tri_offset", np.sum(n * t[:, 0], axis=1) * good)
        object.__setattr__(self, "tri_dual", dual)

    @property
    def n_groups(self) -> int:
        return len(self.group_radius)

    @property
    def n_clusters(self) -> int:
        return len(self.cluster_radius)


def _sphere(pts: np.ndarray) -> tuple[np.ndarray, float]:
    c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return c, float(np.max(np.linalg.norm(pts - c, axis=1)))


def _plane(tris: np.ndarray) -> np.ndarray:
    """(n, d) of the common plane of triangles, NaN if they are not coplanar."""
    pts = tris.reshape(-1, 3)
    nrm = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]).sum(axis=0)
    ln = np.linalg.norm(nrm)
    scale = max(float(np.ptp(pts, axis=0).max()), 1e-300)
    if ln < 1e-300:
        return np.full(4, np.nan)
    nrm = nrm / ln
    d = float(np.mean(pts @ nrm))
    if np.max(np.abs(pts @ nrm - d)) > 1e-9 * scale:
        return np.full(4, np.nan)
    return np.array([*nrm, d])


def _bisect(idx: np.ndarray, cent: np.ndarray, size: int) -> list[np.ndarray]:
    if len(idx) <= size:
        return [idx]
    p = cent[idx]
    ax = int(np.argmax(np.ptp(p, axis=0)))
    order = idx[np.argsort(p[:, ax], kind="stable")]
    h = len(order) // 2
    return _bisect(order[:h], cent, size) + _bisect(order[h:], cent, size)


def build_occluders(triangles, groups, *, cluster_size: int = 16) -> Occluders:
    """Group and cluster triangles (K, 3, 3); ``groups`` (K,) labels the faces/objects."""
    tris = np.asarray(triangles, float).reshape(-1, 3, 3)
    groups = np.asarray(groups).reshape(-1)
    if len(groups) != len(tris):
        raise ValueError(f"groups: expected one label per triangle ({len(tris)}), got {len(groups)}")
    cent = tris.mean(axis=1)
    order, c_start, c_cent, c_rad, c_plane, offsets = [], [0], [], [], [], [0]
    g_cent, g_rad, g_plane = [], [], []
    for g in np.unique(groups):
        members = np.flatnonzero(groups == g)
        gc, gr = _sphere(tris[members].reshape(-1, 3))
        g_cent.append(gc)
        g_rad.append(gr)
        g_plane.append(_plane(tris[members]))
        for leaf in _bisect(members, cent, cluster_size):
            order.append(leaf)
            c_start.append(c_start[-1] + len(leaf))
            cc, cr = _sphere(tris[leaf].reshape(-1, 3))
            c_cent.append(cc)
            c_rad.append(cr)
            c_plane.append(_plane(tris[leaf]))
        offsets.append(len(c_cent))
    e3, e, e4 = np.zeros((0, 3)), np.zeros(0), np.zeros((0, 4))
    if not c_cent:
        return Occluders(tris, np.zeros(1, int), e3, e, e4, e3, e, e4, np.zeros(1, int))
    return Occluders(tris[np.concatenate(order)], np.array(c_start), np.array(c_cent), np.array(c_rad),
                     np.array(c_plane), np.array(g_cent), np.array(g_rad), np.array(g_plane), np.array(offsets))


def _sides(pts: np.ndarray, plane: np.ndarray, tol: np.ndarray):
    planar = ~np.isnan(plane[:, 0])
    P, X = len(pts), len(plane)
    pos = np.ones((P, X), bool)
    neg = np.ones((P, X), bool)
    if planar.any():
        h = np.einsum("pvk,xk->pxv", pts, plane[planar, :3]) - plane[planar, 3][None, :, None]
        pos[:, planar] = (h > tol[:, None, None]).any(-1)
        neg[:, planar] = (h < -tol[:, None, None]).any(-1)
    return pos, neg


def side_flags(occ: Occluders, pts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which point sets ``pts`` (P, V, 3) have points strictly above / below each plane.

    Returns ``(group_pos, group_neg, cluster_pos, cluster_neg)``, (P, G) and (P, C) bools; a
    non-planar group or cluster counts as both (it is never culled by its plane).
    """
    pts = np.asarray(pts, float)
    scale = np.max(np.abs(pts), axis=(1, 2)) + 1.0
    tol = _EPS * scale
    gp, gn = _sides(pts, occ.group_plane, tol)
    cp, cn = _sides(pts, occ.cluster_plane, tol)
    return gp, gn, cp, cn


def front_flags(occ: Occluders, planes) -> tuple[np.ndarray, np.ndarray]:
    """(P, G) and (P, C): groups/clusters whose bounding sphere reaches in front of each plane (n, d)."""
    planes = np.asarray(planes, float)
    tol = _EPS * (1.0 + np.abs(planes[:, 3:4]))
    fg = occ.group_centre @ planes[:, :3].T - planes[:, 3][None] + occ.group_radius[:, None]
    fc = occ.cluster_centre @ planes[:, :3].T - planes[:, 3][None] + occ.cluster_radius[:, None]
    return fg.T > tol, fc.T > tol


def _seg_dist(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points c (n, 3) to segments [a, b] (n, 3)."""
    ab = b - a
    ac = c - a
    t = np.clip(np.einsum("nk,nk->n", ac, ab) / np.maximum(np.einsum("nk,nk->n", ab, ab), 1e-300), 0.0, 1.0)
    d = ac - t[:, None] * ab
    return np.sqrt(np.einsum("nk,nk->n", d, d))


def ray_triangle_hits(orig, dirs, tris, t_min: float = 1e-7, t_max: float = 1.0 - 1e-7) -> np.ndarray:
    """Möller-Trumbore: does segment ``orig + t dirs`` (t in (t_min, t_max)) hit triangle ``tris``?

    Broadcasts ``orig``/``dirs`` (..., 3) against ``tris`` (..., 3, 3); returns a bool array.
    """
    v0, v1, v2 = tris[..., 0, :], tris[..., 1, :], tris[..., 2, :]
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(dirs, e2)
    det = np.sum(e1 * p, -1)
    scale = np.linalg.norm(dirs, axis=-1) * np.linalg.norm(e1, axis=-1) * np.linalg.norm(e2, axis=-1)
    good = np.abs(det) > 1e-12 * scale
    inv = np.where(good, 1.0 / np.where(good, det, 1.0), 0.0)
    s = orig - v0
    u = np.sum(s * p, -1) * inv
    q = np.cross(s, e1)
    v = np.sum(dirs * q, -1) * inv
    t = np.sum(e2 * q, -1) * inv
    return good & (u >= -1e-12) & (v >= -1e-12) & (u + v <= 1 + 1e-12) & (t > t_min) & (t < t_max)


def _segment_hits(occ: Occluders, o: np.ndarray, d: np.ndarray, tri: np.ndarray, t_min: float) -> np.ndarray:
    """Segments ``o + t d`` (n, R, 3), ``t`` in (t_min, 1 - t_min), against triangles ``tri`` (n,): (n, R) bool.

    Plane crossing first (``t = (c - n.o) / (n.d)``), then the barycentric coordinates of the
    crossing point from the precomputed dual basis (only for the crossings in range).
    """
    nn = occ.tri_normal[tri][:, None, :]
    nd = np.einsum("nrk,nrk->nr", d, np.broadcast_to(nn, d.shape))
    no = np.einsum("nrk,nrk->nr", o, np.broadcast_to(nn, o.shape))
    c = occ.tri_offset[tri][:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (c - no) / nd
    cand = (np.abs(nd) > 0) & (t > t_min) & (t < 1.0 - t_min)
    out = np.zeros(cand.shape, bool)
    k, r = np.nonzero(cand)
    if len(k):
        p = o[k, r] + t[k, r, None] * d[k, r] - occ.triangles[tri[k], 0]
        du = occ.tri_dual[tri[k]]
        u = np.einsum("mk,mk->m", p, du[:, 0])
        v = np.einsum("mk,mk->m", p, du[:, 1])
        out[k, r] = (u >= -1e-12) & (v >= -1e-12) & (u + v <= 1 + 1e-12)
    return out


def _expand(owner: np.ndarray, item: np.ndarray, start: np.ndarray):
    """(owner, item) pairs -> (owner, sub-item) pairs for the CSR ranges start[item]:start[item+1]."""
    counts = start[item + 1] - start[item]
    o = np.repeat(owner, counts)
    base = np.repeat(start[item], counts)
    within = np.arange(len(o)) - np.repeat(np.cumsum(counts) - counts, counts)
    return o, base + within


def _group_candidates(occ, sl, centres_a, centres_b, rmax, flags_a, idx_a, flags_b, idx_b, front):
    """(bundle, group) index pairs that pass the plane, front and sphere tests, for bundles ``sl``."""
    ia, ib = idx_a[sl], idx_b[sl]
    ok = (flags_a[0][ia] & flags_b[1][ib]) | (flags_a[1][ia] & flags_b[0][ib])
    if front is not None:
        ok &= front[0][ia]
    pg, gg = np.nonzero(ok)
    pg += sl.start
    reach = occ.group_radius[gg] + rmax[pg] * (1 + _EPS) + _EPS
    keep = _seg_dist(occ.group_centre[gg], centres_a[pg], centres_b[pg]) < reach
    return pg[keep], gg[keep]


def bundles_maybe_blocked(occ: Occluders, centres_a, centres_b, rmax, flags_a, idx_a, flags_b, idx_b,
                          front=None) -> np.ndarray:
    """(P,) bool: the bundles that some group may block (the group-level test of
    :func:`segments_blocked` alone; False means that no segment of the bundle is blocked)."""
    P = len(centres_a)
    out = np.zeros(P, bool)
    step = max(1, 4_000_000 // max(occ.n_groups, 1))
    for s in range(0, P if occ.n_groups else 0, step):
        pg, _ = _group_candidates(occ, slice(s, min(P, s + step)), centres_a, centres_b, rmax, flags_a, idx_a,
                                  flags_b, idx_b, front)
        out[pg] = True
    return out


def segments_blocked(occ: Occluders, origins, targets, centres_a, centres_b, rmax, flags_a, idx_a, flags_b, idx_b,
                     front=None, *, t_min: float = 1e-7, budget: int = 3_000_000) -> np.ndarray:
    """Which segments ``origins -> targets`` are blocked by the occluders.

    Parameters
    ----------
    occ : Occluders
    origins, targets : ndarray (P, R, 3), or callables
        ``R`` segments per bundle ``p``; a callable maps an index array (n,) of bundles to their
        (n, R, 3) points (built only for the bundles that need ray tests).
    centres_a, centres_b : ndarray (P, 3)
        Centres of spheres containing the origins and the targets, of radii at most ``rmax`` (P,).
    flags_a, flags_b : tuple
        :func:`side_flags` of point sets whose convex hulls contain the origins / the targets
        of bundle ``p``: rows ``idx_a[p]`` / ``idx_b[p]`` (P,) of these arrays.
    front : tuple, optional
        :func:`front_flags` of the origins' planes (rays leave them to their front), rows
        ``idx_a``.
    t_min : float
        Hits closer than ``t_min`` (a fraction of the segment) to either end are ignored.
    budget : int
        Ray-triangle tests per vectorised step (about 500 bytes each).

    Returns
    -------
    ndarray (P, R) of bool
    """
    P = len(centres_a)
    get_o = origins if callable(origins) else (lambda idx: origins[idx])
    get_t = targets if callable(targets) else (lambda idx: targets[idx])
    R = get_o(np.zeros(1, int)).shape[1] if P else 0
    blocked = np.zeros((P, R), bool)
    if occ.n_groups == 0 or P == 0:
        return blocked
    _, _, cp_a, cn_a = flags_a
    _, _, cp_b, cn_b = flags_b
    tol = _EPS * (1.0 + rmax)
    step = max(1, 4_000_000 // occ.n_groups)
    pc_all, cc_all = [], []
    for s in range(0, P, step):
        sl = slice(s, min(P, s + step))
        pg, gg = _group_candidates(occ, sl, centres_a, centres_b, rmax, flags_a, idx_a, flags_b, idx_b, front)
        if len(pg) == 0:
            continue
        pc, cc = _expand(pg, gg, occ.group_clusters)
        for k0 in range(0, len(pc), 500_000):
            p_, c_ = pc[k0:k0 + 500_000], cc[k0:k0 + 500_000]
            ia, ib = idx_a[p_], idx_b[p_]
            keep = (cp_a[ia, c_] & cn_b[ib, c_]) | (cn_a[ia, c_] & cp_b[ib, c_])
            if front is not None:
                keep &= front[1][ia, c_]
            keep &= _seg_dist(occ.cluster_centre[c_], centres_a[p_], centres_b[p_]) < occ.cluster_radius[c_] + rmax[p_] + tol[p_]
            pc_all.append(p_[keep])
            cc_all.append(c_[keep])
    if not pc_all:
        return blocked
    pt, tt = _expand(np.concatenate(pc_all), np.concatenate(cc_all), occ.cluster_start)
    chunk = max(1, budget // R)
    for k0 in range(0, len(pt), chunk):
        p_, t_ = pt[k0:k0 + chunk], tt[k0:k0 + chunk]
        o = get_o(p_)
        hit = _segment_hits(occ, o, get_t(p_) - o, t_, t_min)  # (n, R)
        rows = np.flatnonzero(hit.any(axis=1))
        if len(rows):
            np.logical_or.at(blocked, p_[rows], hit[rows])
    return blocked
