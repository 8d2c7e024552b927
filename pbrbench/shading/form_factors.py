"""Form factors between planar polygons: exact point-to-polygon factors and their quadrature.

The form factor from a receiving patch :math:`P_i` (area :math:`A_i`) to an emitting patch
:math:`P_j` is

.. math::  F_{ij} = \\frac{1}{A_i} \\int_{P_i} \\int_{P_j}
           \\frac{\\cos\\theta \\cos\\theta'}{\\pi r^2} \\, \\mathrm{Vis}(x, x') \\, dA' \\, dA .

The inner integral without visibility is the point-to-polygon form factor, known in closed form
(Lambert's formula, the same one :func:`pbrbench.shading.irradiance.polygon_irradiance` uses:
``F(x -> P) = E(x) / (pi L)``):

.. math::  F(x \\to P) = \\frac{1}{2\\pi} \\Big| \\sum_i \\theta_i \\, n \\cdot \\gamma_i \\Big|

over the part of ``P`` above the tangent plane of ``x``.  :func:`point_polygon_form_factors`
evaluates it for many (point, polygon) pairs at once (the polygon is clipped to the hemisphere
of each point with a vectorised Sutherland-Hodgman step); the outer integral over ``P_i`` is a
Gauss-Legendre rule on the bilinear map of the patch (:func:`patch_quadrature`), refined for
pairs that are close (where ``1/r^2`` is steep).  Because the inner integral is exact, the only
quadrature error is that of a smooth outer integrand, and for a receiving point inside a closed
polyhedral enclosure the exact factors of all faces sum to one: row sums of the matrix measure
the outer quadrature error directly.

Also here: the closed forms used as known answers (parallel directly opposed rectangles,
perpendicular rectangles with a common edge; Howell's catalogue) and the exact 2-D factors
between strips of infinitely long faces (Hottel's crossed strings; kernel
``cos(phi) cos(phi') / (2 r)``).

References
----------
C. M. Goral, K. E. Torrance, D. P. Greenberg and B. Battaile, "Modeling the interaction of light
between diffuse surfaces", SIGGRAPH 1984 (the radiosity method; contour-integral form factors).
P. Schröder and P. Hanrahan, "On the form factor between two polygons", SIGGRAPH 1993 (the
point-to-polygon and polygon-to-polygon closed forms).
J. R. Howell, *A Catalog of Radiation Heat Transfer Configuration Factors* (configurations
C-11 and C-14); H. C. Hottel and A. F. Sarofim, *Radiative Transfer*, 1967 (crossed strings).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_int, check_positive
from pbrbench.memo import Memo

__all__ = [
    "patch_geometry",
    "patch_quadrature",
    "point_polygon_form_factors",
    "parallel_rectangles_form_factor",
    "perpendicular_rectangles_form_factor",
    "strip_form_factors_2d",
]

_CLIP = 1e-12  # the clipping offset of polygon_irradiance (points on the tangent plane are excluded)


# ------------------------------------------------------------------------------ geometry
def as_patch_vertices(vertices, name: str = "vertices") -> np.ndarray:
    """Vertices (N, 4, 3) of planar triangles or quads (a triangle repeats its last vertex).

    Accepts (N, 3, 3) triangles or (N, 4, 3) quads/padded triangles.
    """
    v = as_float_array(vertices, name, ndim=(3,))
    if v.shape[1] not in (3, 4) or v.shape[2] != 3:
        raise ValueError(f"{name}: expected (N, 3, 3) triangles or (N, 4, 3) quads, got shape {v.shape}")
    check_finite(v, name)
    if v.shape[1] == 3:
        v = np.concatenate([v, v[:, 2:3]], axis=1)
    return v


def patch_geometry(vertices) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Centroids (N, 3), unit normals (N, 3), areas (N,) and bounding radii (N,) of patches.

    The normal follows the right-hand rule of the vertex order (Newell's method); the centroid is
    the area centroid of the fan triangles; the bounding radius is the largest vertex distance
    from the centroid.  Raises ``ValueError`` for a degenerate (zero-area) patch.
    """
    v = as_patch_vertices(vertices)
    t1 = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    t2 = np.cross(v[:, 2] - v[:, 0], v[:, 3] - v[:, 0])
    a1 = 0.5 * np.linalg.norm(t1, axis=1)
    a2 = 0.5 * np.linalg.norm(t2, axis=1)
    area = a1 + a2
    scale = np.max(np.linalg.norm(v - v[:, :1], axis=2), axis=1)
    bad = ~(area > 1e-14 * np.maximum(scale, 1e-300) ** 2) | ~(area > 0)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"vertices: patch {k} is degenerate (zero area, {int(bad.sum())} such patch(es)); "
                         "give the corners of a planar triangle or quad")
    n = t1 + t2
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    c = (a1[:, None] * (v[:, 0] + v[:, 1] + v[:, 2]) + a2[:, None] * (v[:, 0] + v[:, 2] + v[:, 3])) / (3 * area[:, None])
    off = np.abs(np.einsum("nvk,nk->nv", v - c[:, None], n))
    if np.any(off > 1e-6 * np.maximum(scale, 1e-300)[:, None]):
        k = int(np.flatnonzero(np.any(off > 1e-6 * scale[:, None], axis=1))[0])
        raise ValueError(f"vertices: patch {k} is not planar (a vertex is {off[k].max():.3g} off its plane); "
                         "split non-planar quads into triangles")
    radius = np.max(np.linalg.norm(v - c[:, None], axis=2), axis=1)
    return c, n, area, radius


_GAUSS = Memo("Gauss-Legendre rules on [0, 1] by order", 64)


def gauss_legendre01(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights of order ``k`` on [0, 1] (the weights sum to 1; cached)."""
    if k not in _GAUSS:
        x, w = np.polynomial.legendre.leggauss(k)
        _GAUSS[k] = (0.5 * (x + 1.0), 0.5 * w)
    return _GAUSS[k]


def patch_quadrature(vertices, n_sub: int = 1, order: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature points (N, Q, 3) and weights (N, Q) (summing to 1) on planar patches.

    The patch is the bilinear image ``x(u, v) = (1-u)(1-v) v0 + u(1-v) v1 + u v v2 + (1-u) v v3``
    of the unit square (a triangle, whose last vertex is repeated, is the collapsed square of
    Duffy's transform); ``[0, 1]^2`` is cut into ``n_sub`` x ``n_sub`` cells, each with an
    ``order`` x ``order`` Gauss-Legendre rule, weighted by the Jacobian ``|x_u x x_v|`` and
    normalised by the patch area, so that ``sum_q w_q f(x_q)`` approximates the patch mean of
    ``f``.  ``n_sub = order = 1`` is the one-point rule at the area centroid (exact for linear
    ``f``).  A rule with ``Q = (n_sub * order)^2`` points integrates polynomials of degree
    ``2 order - 1`` exactly on each cell of a parallelogram.
    """
    v = as_patch_vertices(vertices)
    n_sub = check_int(n_sub, "n_sub", 1, 64)
    order = check_int(order, "order", 1, 16)
    if n_sub == 1 and order == 1:
        c, _, _, _ = patch_geometry(v)
        return c[:, None, :], np.ones((len(v), 1))
    g, w = gauss_legendre01(order)
    u1 = ((np.arange(n_sub)[:, None] + g[None, :]) / n_sub).ravel()
    w1 = np.tile(w / n_sub, n_sub)
    U, V = (a.ravel() for a in np.meshgrid(u1, u1, indexing="ij"))
    W = np.outer(w1, w1).ravel()
    v0, v1, v2, v3 = (v[:, k, None, :] for k in range(4))
    Uc, Vc = U[None, :, None], V[None, :, None]
    pts = (1 - Uc) * (1 - Vc) * v0 + Uc * (1 - Vc) * v1 + Uc * Vc * v2 + (1 - Uc) * Vc * v3
    xu = (1 - Vc) * (v1 - v0) + Vc * (v2 - v3)
    xv = (1 - Uc) * (v3 - v0) + Uc * (v2 - v1)
    J = np.linalg.norm(np.cross(xu, xv), axis=-1) * W[None, :]
    return pts, J / J.sum(axis=1, keepdims=True)


# ---------------------------------------------------------------- point-to-polygon factor
def point_polygon_form_factors(points, normals, polygons, polygon_normals=None) -> np.ndarray:
    """Exact unoccluded form factor from points (with normals) to one-sided polygons, pairwise.

    .. math::  F(x \\to P) = \\frac{1}{2\\pi} \\Big| \\sum_{i} \\theta_i \\, (n \\cdot \\gamma_i) \\Big|

    for the part of ``P`` above the tangent plane ``n . (y - x) > 0`` (the polygon is clipped to
    it), with ``theta_i`` the angle subtended at ``x`` by edge ``i`` and ``gamma_i`` the unit
    normal of the plane through ``x`` and that edge (Lambert's formula; equal to
    ``polygon_irradiance(x, n, P) / pi`` for ``L = 1``).  The polygon emits only toward its
    normal (right-hand rule of the vertex order): points behind it get 0.  Pair ``k`` is
    ``(points[k], normals[k], polygons[k])``.

    Parameters
    ----------
    points, normals : array_like (P, 3)
        Receiving points and unit normals.
    polygons : array_like (P, M, 3)
        Planar convex or non-convex polygons, vertices in order (repeated vertices allowed).
    polygon_normals : array_like (P, 3), optional
        Unit normals of the polygons (computed by Newell's method when omitted).

    Returns
    -------
    ndarray (P,)
        Form factors in [0, 1].

    References
    ----------
    Lambert (1760); Schröder and Hanrahan (1993), equation 1.
    """
    x = as_float_array(points, "points", ndim=(2,))
    n = as_float_array(normals, "normals", ndim=(2,))
    poly = as_float_array(polygons, "polygons", ndim=(3,))
    if x.shape[1] != 3 or n.shape != x.shape or poly.shape[0] != x.shape[0] or poly.shape[2] != 3:
        raise ValueError(f"points {x.shape}, normals {n.shape}, polygons {poly.shape}: expected (P, 3), (P, 3), (P, M, 3)")
    if polygon_normals is None:
        w = np.roll(poly, -1, axis=1)
        ns = np.stack([np.sum((poly[..., 1] - w[..., 1]) * (poly[..., 2] + w[..., 2]), 1),
                       np.sum((poly[..., 2] - w[..., 2]) * (poly[..., 0] + w[..., 0]), 1),
                       np.sum((poly[..., 0] - w[..., 0]) * (poly[..., 1] + w[..., 1]), 1)], -1)
        ns /= np.maximum(np.linalg.norm(ns, axis=1, keepdims=True), 1e-300)
    else:
        ns = as_float_array(polygon_normals, "polygon_normals", ndim=(2,))
    a = poly - x[:, None, :]
    h = np.einsum("pmk,pk->pm", a, n)
    front = np.einsum("pk,pk->p", x - poly[:, 0], ns) > 0
    inside = h >= _CLIP
    full = front & inside.all(axis=1)
    part = front & inside.any(axis=1) & ~full
    out = np.zeros(len(x))
    if full.any():
        out[full] = np.abs(_lambert_sum(a[full], n[full]))
    if part.any():
        out[part] = np.abs(_lambert_sum(_clip_to_halfspace(a[part], h[part] - _CLIP), n[part]))
    return out / (2.0 * np.pi)


def _lambert_sum(a: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``sum_i theta_i (n . gamma_i)`` for vertex vectors ``a`` (P, M, 3) seen from points with normals ``n`` (P, 3).

    The sum of :func:`pbrbench.shading.irradiance.polygon_irradiance` (its ``_lambert_sum``),
    written with scalar triple products for speed: ``n . gamma_i = n . (a_i x a_{i+1}) / |a_i x a_{i+1}|``
    for unit ``a_i``; zero-length edges contribute nothing.
    """
    an = a / np.sqrt(np.einsum("pmk,pmk->pm", a, a))[..., None]
    bn = np.roll(an, -1, axis=1)
    ax, ay, az = an[..., 0], an[..., 1], an[..., 2]
    bx, by, bz = bn[..., 0], bn[..., 1], bn[..., 2]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    s = np.sqrt(cx * cx + cy * cy + cz * cz)
    theta = np.arctan2(s, ax * bx + ay * by + az * bz)
    tn = cx * n[:, 0, None] + cy * n[:, 1, None] + cz * n[:, 2, None]
    good = s > 1e-15
    return np.sum(np.where(good, theta * tn / np.where(good, s, 1.0), 0.0), axis=1)


def _clip_to_halfspace(a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman clip of polygons a (P, M, 3) to d >= 0, vectorised.

    Returns (P, 2M, 3): each edge contributes its start vertex (if inside) and its crossing (if
    it crosses); unused slots repeat the previous used vertex (cyclically), which adds zero-length
    edges that contribute nothing to Lambert's sum.
    """
    P, M, _ = a.shape
    b = np.roll(a, -1, axis=1)
    db = np.roll(d, -1, axis=1)
    ins, insb = d >= 0, db >= 0
    cross = ins != insb
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cross, d / np.where(cross, d - db, 1.0), 0.0)
    inter = a + t[..., None] * (b - a)
    slots = np.empty((P, 2 * M, 3))
    slots[:, 0::2] = a
    slots[:, 1::2] = inter
    valid = np.empty((P, 2 * M), bool)
    valid[:, 0::2] = ins
    valid[:, 1::2] = cross
    idx = np.where(valid, np.arange(2 * M)[None, :], -1)
    idx = np.maximum.accumulate(idx, axis=1)
    last = idx[:, -1:]
    idx = np.where(idx < 0, last, idx)
    return np.take_along_axis(slots, idx[..., None], axis=1)


# ------------------------------------------------------------------- closed-form anchors
def parallel_rectangles_form_factor(a: float, b: float, c: float) -> float:
    """Form factor between two directly opposed parallel ``a`` x ``b`` rectangles a distance ``c`` apart.

    .. math::  F = \\frac{2}{\\pi X Y} \\Big[ \\ln\\sqrt{\\frac{(1+X^2)(1+Y^2)}{1+X^2+Y^2}}
        + X\\sqrt{1+Y^2}\\arctan\\frac{X}{\\sqrt{1+Y^2}} + Y\\sqrt{1+X^2}\\arctan\\frac{Y}{\\sqrt{1+X^2}}
        - X\\arctan X - Y\\arctan Y \\Big], \\quad X = a/c,\\ Y = b/c

    (Howell's catalogue, configuration C-11; 0.19982 for unit squares at unit distance).
    """
    X, Y = check_positive(a, "a") / check_positive(c, "c"), check_positive(b, "b") / c
    s1, s2 = np.sqrt(1 + X * X), np.sqrt(1 + Y * Y)
    t = (np.log(np.sqrt((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y)))
         + X * s2 * np.arctan(X / s2) + Y * s1 * np.arctan(Y / s1) - X * np.arctan(X) - Y * np.arctan(Y))
    return float(2.0 / (np.pi * X * Y) * t)


def perpendicular_rectangles_form_factor(length: float, width: float, height: float) -> float:
    """Form factor from an ``length`` x ``width`` rectangle to a perpendicular ``length`` x ``height``
    rectangle sharing the edge of length ``length``.

    .. math::  F_{12} = \\frac{1}{\\pi W}\\Big( W\\arctan\\frac1W + H\\arctan\\frac1H
        - \\sqrt{H^2+W^2}\\arctan\\frac{1}{\\sqrt{H^2+W^2}} + \\frac14 \\ln\\Big\\{
        \\frac{(1+W^2)(1+H^2)}{1+W^2+H^2}
        \\Big[\\frac{W^2(1+W^2+H^2)}{(1+W^2)(W^2+H^2)}\\Big]^{W^2}
        \\Big[\\frac{H^2(1+W^2+H^2)}{(1+H^2)(W^2+H^2)}\\Big]^{H^2} \\Big\\}\\Big)

    with ``H = height / length`` and ``W = width / length`` (Howell's catalogue, configuration
    C-14; 0.20004 for two unit squares).
    """
    L = check_positive(length, "length")
    W, H = check_positive(width, "width") / L, check_positive(height, "height") / L
    s = np.sqrt(H * H + W * W)
    lg = (np.log((1 + W * W) * (1 + H * H) / (1 + W * W + H * H))
          + W * W * np.log(W * W * (1 + W * W + H * H) / ((1 + W * W) * (W * W + H * H)))
          + H * H * np.log(H * H * (1 + H * H + W * W) / ((1 + H * H) * (H * H + W * W))))
    return float((W * np.arctan(1 / W) + H * np.arctan(1 / H) - s * np.arctan(1 / s) + 0.25 * lg) / (np.pi * W))


def strip_form_factors_2d(segments_from, segments_to) -> np.ndarray:
    """Exact 2-D form factors between segments (cross-sections of infinitely long strips).

    For translation-invariant geometry the 3-D kernel integrated along the common direction is

    .. math::  \\int_{-\\infty}^{\\infty} \\frac{\\cos\\theta\\cos\\theta'}{\\pi r^2}\\,dy'
               = \\frac{\\cos\\phi \\cos\\phi'}{2\\rho}

    (``rho`` and ``phi`` measured in the cross-section), and the strip-to-strip factor follows
    from Hottel's crossed strings: ``F_ij = (crossed - uncrossed) / (2 L_i)`` with the string
    lengths between the segments' end points.  Valid for segments that see each other fully
    (no occluder between them, each wholly in front of the other), as the faces of a V groove.

    Parameters
    ----------
    segments_from : array_like (N, 2, 2)
        End points of the receiving segments.
    segments_to : array_like (M, 2, 2)
        End points of the emitting segments.

    Returns
    -------
    ndarray (N, M)
    """
    a = as_float_array(segments_from, "segments_from", ndim=(3,))
    b = as_float_array(segments_to, "segments_to", ndim=(3,))
    if a.shape[1:] != (2, 2) or b.shape[1:] != (2, 2):
        raise ValueError(f"segments: expected (N, 2, 2) end points, got {a.shape} and {b.shape}")
    L = np.linalg.norm(a[:, 1] - a[:, 0], axis=1)
    if np.any(L <= 0):
        raise ValueError("segments_from: a segment has zero length")

    def d(p, q):
        return np.linalg.norm(p[:, None, :] - q[None, :, :], axis=-1)

    s1 = d(a[:, 0], b[:, 0]) + d(a[:, 1], b[:, 1])
    s2 = d(a[:, 0], b[:, 1]) + d(a[:, 1], b[:, 0])
    return np.abs(s1 - s2) / (2.0 * L[:, None])
