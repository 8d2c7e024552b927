"""Closed-form radiometry used to prove that the ground-truth renders are right.

Everything is NumPy, in the world frame of the scene files (docs/conventions.md: x right, y up, z toward
the default camera).  Light vectors point from the surface toward the source.

* :func:`polygon_irradiance` -- irradiance at points from a uniform Lambertian polygonal source
  (Lambert's formula for polygon lights);
* :func:`visible_polygon_irradiance` -- the same with convex polygonal occluders between the points
  and the source (the occluder is projected from each point onto the source plane and the hidden
  part subtracted exactly);
* :func:`polygon_irradiance_numeric` -- brute-force midpoint integration over a sub-grid of the
  source, with ray-occluder tests (the check on the closed forms);
* :func:`sphere_reference` -- box-filtered analytic images of a Lambertian sphere seen
  orthographically, under a directional or a point source, with exact pixel coverage;
* :func:`integrating_sphere_radiance` -- radiance inside a closed Lambertian sphere lit by a point
  source at its centre, direct and global (``direct / (1 - rho)``);
* :func:`shadow_regions` -- umbra and penumbra of a convex occluder under a convex source on
  parallel planes, by projecting the source through the occluder's edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pbrbench.checks import as_float_array, check_positive

__all__ = [
    "polygon_irradiance",
    "visible_polygon_irradiance",
    "polygon_irradiance_numeric",
    "rectangle_polygon",
    "sphere_reference",
    "SphereReference",
    "integrating_sphere_radiance",
    "shadow_regions",
    "ShadowRegions",
    "interval_on_line",
]


# ------------------------------------------------------------------------------- helpers
def _points_normals(points, normals):
    p = as_float_array(points, "points")
    n = as_float_array(normals, "normals")
    if p.shape[-1] != 3:
        raise ValueError(f"points: expected shape (..., 3), got {p.shape}; pass 3-D positions")
    if n.shape[-1] != 3:
        raise ValueError(f"normals: expected shape (..., 3), got {n.shape}; pass 3-D unit normals")
    p, n = np.broadcast_arrays(p, n)
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    if np.any(ln < 1e-12):
        raise ValueError("normals: contains a zero vector; every point needs a unit normal")
    return p, n / ln


def _polygon(polygon, name="polygon"):
    v = as_float_array(polygon, name)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
        raise ValueError(f"{name}: expected (M >= 3, 3) vertices, got shape {v.shape}")
    return v


def polygon_normal(polygon) -> np.ndarray:
    """Unit normal of a planar polygon by Newell's method (right-hand rule on the vertex order)."""
    v = _polygon(polygon)
    w = np.roll(v, -1, axis=0)
    n = np.array([np.sum((v[:, 1] - w[:, 1]) * (v[:, 2] + w[:, 2])),
                  np.sum((v[:, 2] - w[:, 2]) * (v[:, 0] + w[:, 0])),
                  np.sum((v[:, 0] - w[:, 0]) * (v[:, 1] + w[:, 1]))])
    ln = np.linalg.norm(n)
    if ln < 1e-15:
        raise ValueError("polygon: degenerate (zero area); give the vertices of a planar polygon")
    return n / ln


def rectangle_basis(normal, up=(0.0, 1.0, 0.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal ``(left, up, normal)`` of Mitsuba's ``look_at`` frame for a rectangle facing ``normal``.

    ``left = normalize(up x normal)``, ``up' = normal x left``; an ``up`` (nearly) parallel to
    ``normal`` is replaced by a fixed axis.  The scene builder uses the same basis, so the closed
    forms and the renders describe the same rectangle.
    """
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    u = np.asarray(up, float)
    if abs(np.dot(u / np.linalg.norm(u), n)) > 0.999:
        u = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    left = np.cross(u, n)
    left /= np.linalg.norm(left)
    return left, np.cross(n, left), n


def rectangle_polygon(center, size, normal=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """The four corners (4, 3) of a rectangle as the scene files define area lights and rectangles.

    ``size = (sx, sy)`` spans the local x axis (``normalize(up x normal)``... as Mitsuba's
    ``look_at`` frame: local z = ``normal``, local y = ``up`` made orthogonal, local x = y x z)
    and the local y axis.  Vertices are ordered counter-clockwise seen from the side ``normal``
    points to.
    """
    c = np.asarray(center, float)
    left, new_up, n = rectangle_basis(normal, up)
    hx, hy = 0.5 * size[0], 0.5 * size[1]
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    v = np.array([c + sx * hx * left + sy * hy * new_up for sx, sy in corners])
    if np.dot(polygon_normal(v), n) < 0:
        v = v[::-1]
    return v


def _clip_polygon(poly: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of ``poly`` (M, D) with ``normal . p >= offset``."""
    if len(poly) == 0:
        return poly
    d = poly @ normal - offset
    out = []
    m = len(poly)
    for i in range(m):
        j = (i + 1) % m
        pi, pj, di, dj = poly[i], poly[j], d[i], d[j]
        if di >= 0:
            out.append(pi)
        if (di >= 0) != (dj >= 0):
            t = di / (di - dj)
            out.append(pi + t * (pj - pi))
    return np.array(out).reshape(-1, poly.shape[1])


# --------------------------------------------------------------------- Lambert's formula
def _lambert_sum(a: np.ndarray, n: np.ndarray) -> np.ndarray:
    """sum_i theta_i (n . gamma_i) for vertex vectors a (..., M, 3) relative to the points."""
    b = np.roll(a, -1, axis=-2)
    an = a / np.linalg.norm(a, axis=-1, keepdims=True)
    bn = b / np.linalg.norm(b, axis=-1, keepdims=True)
    cr = np.cross(an, bn)
    s = np.linalg.norm(cr, axis=-1)
    c = np.sum(an * bn, axis=-1)
    theta = np.arctan2(s, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma = np.where(s[..., None] > 1e-15, cr / np.where(s > 1e-15, s, 1.0)[..., None], 0.0)
    return np.sum(theta * np.sum(gamma * n[..., None, :], axis=-1), axis=-1)


def polygon_irradiance(points, normals, polygon, radiance: float = 1.0, *, one_sided: bool = True) -> np.ndarray:
    """Irradiance at ``points`` from a uniform Lambertian polygonal source (Lambert's formula).

    .. math::  E(x) = \\frac{L}{2} \\Big|\\sum_{i=1}^{M} \\theta_i \\, (n \\cdot \\gamma_i)\\Big|

    with ``a_i = v_i - x`` the source's vertices seen from ``x``, ``theta_i`` the angle between
    ``a_i`` and ``a_{i+1}`` and ``gamma_i = (a_i x a_{i+1}) / |a_i x a_{i+1}|`` the unit normal of
    the plane through ``x`` and edge ``i``.  Sign convention: the sum is positive when the
    vertices run clockwise as seen from ``x`` (counter-clockwise seen from the side the source
    faces); the absolute value makes the result independent of the winding.  The formula holds
    for the part of the polygon above the tangent plane of ``x``; this function clips the polygon
    to that half-space first (per point).  With ``one_sided`` (Mitsuba's area lights), points
    behind the source (on the side opposite to its normal by the right-hand rule of the vertex
    order) get 0.

    Parameters
    ----------
    points, normals : array_like (..., 3)
        Receiver positions and unit normals (broadcast together).
    polygon : array_like (M, 3)
        Planar source polygon (convex or not), vertices in order.
    radiance : float
        Emitted radiance L of the source.
    one_sided : bool, keyword-only
        Emit only toward the polygon's normal side.

    Returns
    -------
    ndarray (...)
        Irradiance E (W m^-2 for L in W m^-2 sr^-1).

    References
    ----------
    J. H. Lambert, *Photometria*, 1760; J. Arvo, "Applications of irradiance tensors to the
    simulation of non-Lambertian phenomena", SIGGRAPH 1995 (the vector form used here).
    """
    p, n = _points_normals(points, normals)
    v = _polygon(polygon)
    _check_radiance(radiance)
    shape = p.shape[:-1]
    p2, n2 = p.reshape(-1, 3), n.reshape(-1, 3)
    a = v[None, :, :] - p2[:, None, :]  # (N, M, 3)
    heights = np.einsum("nmk,nk->nm", a, n2)
    above = np.all(heights > 0, axis=1)
    out = np.zeros(len(p2))
    if above.any():
        out[above] = np.abs(_lambert_sum(a[above], n2[above]))
    for k in np.flatnonzero(~above & np.any(heights > 0, axis=1)):
        clipped = _clip_polygon(a[k], n2[k], 1e-12)
        if len(clipped) >= 3:
            out[k] = abs(float(_lambert_sum(clipped[None], n2[k][None])[0]))
    if one_sided:
        ns = polygon_normal(v)
        facing = (p2 - v[0]) @ ns > 0
        out[~facing] = 0.0
    return (0.5 * float(radiance) * out).reshape(shape)


def _check_radiance(radiance) -> float:
    v = float(radiance)
    if not np.isfinite(v) or v < 0:
        raise ValueError(f"radiance: must be a finite number >= 0, got {radiance!r}")
    return v


def _project_to_plane(x: np.ndarray, pts: np.ndarray, plane_point: np.ndarray, plane_n: np.ndarray):
    """Central projection from ``x`` of points ``pts`` (K, 3) onto a plane; (K, 3) and ray params."""
    d = pts - x
    denom = d @ plane_n
    t = np.where(np.abs(denom) > 1e-15, ((plane_point - x) @ plane_n) / np.where(np.abs(denom) > 1e-15, denom, 1.0), np.inf)
    return x + t[:, None] * d, t


def _plane_basis(n: np.ndarray):
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _convex_intersection_2d(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Intersection of a polygon with a convex polygon (both (M, 2), any winding)."""
    c = clip
    area = 0.5 * np.sum(c[:, 0] * np.roll(c[:, 1], -1) - np.roll(c[:, 0], -1) * c[:, 1])
    if area < 0:
        c = c[::-1]
    out = subject
    for i in range(len(c)):
        e = c[(i + 1) % len(c)] - c[i]
        inward = np.array([-e[1], e[0]])
        out = _clip_polygon(out, inward, float(inward @ c[i]))
        if len(out) == 0:
            break
    return out


def visible_polygon_irradiance(points, normals, source, occluders=(), radiance: float = 1.0, *,
                               one_sided: bool = True) -> np.ndarray:
    """Irradiance from the part of a polygonal source not hidden by convex polygonal occluders.

    .. math::  E_{vis}(x) = E(S) - E(S \\cap P(O))

    where ``P(O)`` is the central projection from ``x`` of the occluder ``O`` onto the source's
    plane, and ``E`` is Lambert's formula (:func:`polygon_irradiance`).  Exact when the occluder
    is convex and lies entirely between ``x`` and the source plane (the source plane is reached at
    ``x + t (o - x)`` with ``t > 1`` for every occluder vertex ``o``), and, for several occluders, when their projections do not overlap
    (otherwise the overlap is subtracted twice; a ``ValueError`` says so).  Points where an
    occluder is not between the point and the source raise no error: that occluder is ignored
    (it cannot hide the source from there only if it is wholly behind the point or beyond the
    source -- both checked).

    Parameters
    ----------
    points, normals : array_like (..., 3)
    source : array_like (M, 3)
        Convex planar source polygon.
    occluders : sequence of array_like (K, 3)
        Convex planar occluder polygons (flat: a thin occluder such as a card).
    radiance : float
    one_sided : bool, keyword-only

    Returns
    -------
    ndarray (...)

    References
    ----------
    Lambert (1760); D. A. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, §2 (area
    sources, umbra and penumbra).
    """
    p, n = _points_normals(points, normals)
    s = _polygon(source, "source")
    occs = [_polygon(o, f"occluders[{i}]") for i, o in enumerate(occluders)]
    shape = p.shape[:-1]
    p2, n2 = p.reshape(-1, 3), n.reshape(-1, 3)
    full = polygon_irradiance(p2, n2, s, radiance, one_sided=one_sided)
    if not occs:
        return full.reshape(shape)
    ns = polygon_normal(s)
    e1, e2 = _plane_basis(ns)
    s2 = np.stack([(s - s[0]) @ e1, (s - s[0]) @ e2], -1)
    hidden = np.zeros(len(p2))
    for k in range(len(p2)):
        if full[k] == 0:
            continue
        pieces = []
        for o in occs:
            proj, t = _project_to_plane(p2[k], o, s[0], ns)
            # the plane is reached at x + t (o - x): t > 1 means the occluder is in front of it
            if np.all((t <= 0) | ~np.isfinite(t)) or np.all((t > 0) & (t <= 1)):
                continue  # wholly behind the point or beyond the source plane
            if not np.all(np.isfinite(t) & (t > 1)):
                raise ValueError("occluders: an occluder crosses the source plane or the receiver; "
                                 "the exact projection needs it wholly between them")
            o2 = np.stack([(proj - s[0]) @ e1, (proj - s[0]) @ e2], -1)
            inter = _convex_intersection_2d(o2, s2)
            if len(inter) >= 3:
                pieces.append(inter)
        if len(pieces) > 1:
            for i in range(len(pieces)):
                for j in range(i + 1, len(pieces)):
                    ov = _convex_intersection_2d(pieces[i], pieces[j])
                    if len(ov) >= 3 and abs(_area2d(ov)) > 1e-12:
                        raise ValueError("occluders: their shadows on the source overlap; "
                                         "give non-overlapping occluders or use polygon_irradiance_numeric")
        for piece in pieces:
            poly3 = s[0] + piece[:, :1] * e1 + piece[:, 1:] * e2
            hidden[k] += polygon_irradiance(p2[k], n2[k], poly3, radiance, one_sided=False)
    return np.maximum(full - hidden, 0.0).reshape(shape)


def _area2d(poly: np.ndarray) -> float:
    return 0.5 * float(np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1]))


def polygon_irradiance_numeric(points, normals, source, occluders=(), radiance: float = 1.0, *,
                               n: int = 64, one_sided: bool = True) -> np.ndarray:
    """Brute-force irradiance: midpoint rule on an ``n`` x ``n`` sub-grid of a convex source.

    .. math::  E(x) = L \\sum_j \\frac{\\cos\\theta_x \\cos\\theta_j}{r_j^2} V(x, y_j) \\Delta A

    over sub-cells ``y_j`` of the source (a parallelogram spanned by its first three vertices is
    assumed for the grid; cells outside a non-parallelogram source are dropped), with ``V`` the
    ray test against the (planar, convex) occluders.  Converges as O(1/n^2) away from shadow
    edges; used as the independent check of :func:`polygon_irradiance` and
    :func:`visible_polygon_irradiance`.
    """
    p, nn = _points_normals(points, normals)
    s = _polygon(source, "source")
    occs = [_polygon(o, f"occluders[{i}]") for i, o in enumerate(occluders)]
    if int(n) < 1:
        raise ValueError(f"n: must be a positive number of sub-cells per side, got {n}")
    n = int(n)
    e1, e2 = s[1] - s[0], s[3] - s[0] if len(s) >= 4 else s[2] - s[0]
    u = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(u, u, indexing="ij")
    ys = s[0] + uu.reshape(-1, 1) * e1 + vv.reshape(-1, 1) * e2
    ns = polygon_normal(s)
    dA = np.linalg.norm(np.cross(e1, e2)) / (n * n)
    if len(s) != 4 or not np.allclose(s[2], s[0] + e1 + e2):
        e1p, e2p = _plane_basis(ns)
        s2 = np.stack([(s - s[0]) @ e1p, (s - s[0]) @ e2p], -1)
        y2 = np.stack([(ys - s[0]) @ e1p, (ys - s[0]) @ e2p], -1)
        keep = _inside_convex(y2, s2)
        ys = ys[keep]
    shape = p.shape[:-1]
    p2, n2 = p.reshape(-1, 3), nn.reshape(-1, 3)
    out = np.empty(len(p2))
    for k in range(len(p2)):
        d = ys - p2[k]
        r2 = np.sum(d * d, axis=1)
        r = np.sqrt(r2)
        cx = np.clip(d @ n2[k] / r, 0, None)
        cy = -(d @ ns) / r
        cy = np.clip(cy, 0, None) if one_sided else np.abs(cy)
        vis = np.ones(len(ys), bool)
        for o in occs:
            vis &= ~_ray_hits_polygon(p2[k], d, o)
        out[k] = float(np.sum(cx * cy / r2 * vis)) * dA
    return (float(radiance) * out).reshape(shape)


def _inside_convex(pts2: np.ndarray, poly2: np.ndarray) -> np.ndarray:
    if _area2d(poly2) < 0:
        poly2 = poly2[::-1]
    inside = np.ones(len(pts2), bool)
    for i in range(len(poly2)):
        e = poly2[(i + 1) % len(poly2)] - poly2[i]
        inside &= (e[0] * (pts2[:, 1] - poly2[i, 1]) - e[1] * (pts2[:, 0] - poly2[i, 0])) >= 0
    return inside


def _ray_hits_polygon(x: np.ndarray, d: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Segments x -> x + d (d: (K, 3)) that cross the convex planar polygon."""
    npoly = polygon_normal(poly)
    denom = d @ npoly
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((poly[0] - x) @ npoly) / denom
    ok = (np.abs(denom) > 1e-15) & (t > 0) & (t < 1)
    hit = x + np.where(ok, t, 0)[:, None] * d
    e1, e2 = _plane_basis(npoly)
    p2 = np.stack([(poly - poly[0]) @ e1, (poly - poly[0]) @ e2], -1)
    h2 = np.stack([(hit - poly[0]) @ e1, (hit - poly[0]) @ e2], -1)
    return ok & _inside_convex(h2, p2)


# -------------------------------------------------------------------- sphere references
@dataclass(frozen=True)
class SphereReference:
    """Box-filtered analytic images of an orthographically viewed sphere (row 0 = top)."""

    radiance: np.ndarray  # (H, W): pixel-averaged radiance per unit albedo times albedo
    coverage: np.ndarray  # (H, W): exact fraction of the pixel covered by the disk
    normals: np.ndarray  # (H, W, 3): normalised average of the normals over the covered part
    centre_normals: np.ndarray  # (H, W, 3): normals at pixel centres (0 outside)


def _primitive_sqrt(x, R):
    """Antiderivative of sqrt(R^2 - x^2) on [-R, R]."""
    x = np.clip(x, -R, R)
    return 0.5 * (x * np.sqrt(np.maximum(R * R - x * x, 0.0)) + R * R * np.arcsin(x / R))


def disk_rectangle_area(R: float, x0: float, x1: float, y0: float, y1: float) -> float:
    """Exact area of the disk ``x^2 + y^2 <= R^2`` intersected with ``[x0, x1] x [y0, y1]``.

    ``int_{x0}^{x1} |[y0, y1] cap [-h(x), h(x)]| dx`` with ``h = sqrt(R^2 - x^2)``, split where
    the overlap changes form (h = |y0|, h = |y1|) so each piece is linear in ``h`` and integrates
    with the antiderivative of ``h``.
    """
    a, b = max(x0, -R), min(x1, R)
    if a >= b or y0 >= y1:
        return 0.0
    cuts = {a, b}
    for yy in (y0, y1):
        if abs(yy) < R:
            xc = np.sqrt(R * R - yy * yy)
            for c in (-xc, xc):
                if a < c < b:
                    cuts.add(float(c))
    cuts = sorted(cuts)
    total = 0.0
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=False):
        m = 0.5 * (lo + hi)
        h = np.sqrt(max(R * R - m * m, 0.0))
        top_h = h <= y1  # upper limit is h (else y1)
        bot_h = -h >= y0  # lower limit is -h (else y0)
        if min(y1, h) <= max(y0, -h):
            continue
        H = _primitive_sqrt(hi, R) - _primitive_sqrt(lo, R)
        w = hi - lo
        top = H if top_h else y1 * w
        bot = -H if bot_h else y0 * w
        total += top - bot
    return float(total)


def _rect_disk_distance(x0, x1, y0, y1) -> float:
    """Distance from the origin to the rectangle [x0, x1] x [y0, y1]."""
    dx = max(x0, 0.0, -x1)
    dy = max(y0, 0.0, -y1)
    return float(np.hypot(dx, dy))


def sphere_reference(resolution, half_width: float, *, albedo: float = 1.0, radius: float = 1.0,
                     center=(0.0, 0.0, 0.0), direction=None, irradiance: float = 1.0,
                     position=None, intensity: float = 1.0, sub: int = 32) -> SphereReference:
    """Box-filtered analytic images of a Lambertian sphere under one directional or point source.

    Orthographic camera on the +z axis looking at -z, film ``[-hw, hw] x [-hw H/W, hw H/W]``
    (Mitsuba's orthographic sensor scaled by ``half_width``; pixel ``(i, j)`` covers
    ``x in hw [2j/W - 1, 2(j+1)/W - 1]``, ``y`` decreasing with ``i``).  Visible point of the
    sphere above ``(x, y)``: ``z = c_z + sqrt(R^2 - r^2)``.  Radiance

    * directional (``direction`` toward the source, irradiance ``E``):
      ``L = rho E max(0, N.S) / pi``;
    * point (``position``, intensity ``I``): ``L = rho I max(0, N.(P - X)/r) / (pi r^2)``;

    averaged over each pixel with ``sub`` x ``sub`` midpoint sub-samples, background 0, and the
    coverage of silhouette pixels computed exactly (:func:`disk_rectangle_area`): pixel value =
    exact coverage x mean of the radiance over the covered sub-samples.  This is the box-filtered
    pixel a renderer with a box reconstruction filter converges to.

    References
    ----------
    Lambert's cosine law; docs/conventions.md; docs/rendering.md (box-filtered references).
    """
    if (direction is None) == (position is None):
        raise ValueError("give exactly one of direction= (a directional source) or position= (a point source)")
    if isinstance(resolution, (int, np.integer)):
        resolution = (int(resolution), int(resolution))
    W, H = (int(r) for r in resolution)
    if W < 1 or H < 1:
        raise ValueError(f"resolution: must be positive, got {resolution}")
    check_positive(half_width, "half_width")
    check_positive(radius, "radius")
    sub = int(sub)
    if sub < 1:
        raise ValueError(f"sub: must be >= 1 sub-samples per pixel side, got {sub}")
    hw, R = float(half_width), float(radius)
    c = np.asarray(center, float)
    hh = hw * H / W
    px = 2 * hw / W
    py = 2 * hh / H
    # sub-sample coordinates, (H, sub, W, sub)
    fx = -hw + (np.arange(W * sub) + 0.5) * px / sub
    fy = hh - (np.arange(H * sub) + 0.5) * py / sub
    X, Y = np.meshgrid(fx, fy)
    dx, dy = X - c[0], Y - c[1]
    r2 = dx * dx + dy * dy
    inside = r2 < R * R
    nz = np.sqrt(np.where(inside, R * R - r2, 0.0)) / R
    N = np.stack([dx / R, dy / R, nz], -1)
    N[~inside] = 0.0
    if direction is not None:
        s = np.asarray(direction, float)
        s = s / np.linalg.norm(s)
        L = float(albedo) * float(irradiance) * np.maximum(N @ s, 0.0) / np.pi
    else:
        P = np.asarray(position, float)
        Xs = np.stack([X, Y, c[2] + R * nz], -1)
        d = P - Xs
        r2p = np.sum(d * d, -1)
        cos = np.sum(N * d, -1) / np.sqrt(r2p)
        L = float(albedo) * float(intensity) * np.maximum(cos, 0.0) / (np.pi * r2p)
    L = np.where(inside, L, 0.0)

    def pool(a):
        return a.reshape(H, sub, W, sub, *a.shape[2:]).sum(axis=(1, 3))

    n_in = pool(inside.astype(float))
    sumL = pool(L)
    sumN = pool(N)
    cov = np.zeros((H, W))
    x_edges = -hw + np.arange(W + 1) * px
    y_edges = hh - np.arange(H + 1) * py
    # a pixel lies inside the (convex) disk exactly when its four corners do
    XE, YE = np.meshgrid(x_edges - c[0], y_edges - c[1])
    cin = XE * XE + YE * YE <= R * R
    full = cin[:-1, :-1] & cin[:-1, 1:] & cin[1:, :-1] & cin[1:, 1:]
    cov[full] = 1.0
    empty = n_in == 0
    for i, j in zip(*np.nonzero(~full), strict=True):
        if empty[i, j] and _rect_disk_distance(x_edges[j] - c[0], x_edges[j + 1] - c[0], y_edges[i + 1] - c[1], y_edges[i] - c[1]) >= R:
            continue
        a = disk_rectangle_area(R, x_edges[j] - c[0], x_edges[j + 1] - c[0], y_edges[i + 1] - c[1], y_edges[i] - c[1])
        cov[i, j] = min(1.0, a / (px * py))
    with np.errstate(invalid="ignore", divide="ignore"):
        meanL = np.where(n_in > 0, sumL / np.maximum(n_in, 1), 0.0)
        nrm = np.linalg.norm(sumN, axis=-1, keepdims=True)
        navg = np.where(nrm > 0, sumN / np.where(nrm > 0, nrm, 1.0), 0.0)
    # pixel-centre normals
    xc = -hw + (np.arange(W) + 0.5) * px
    yc = hh - (np.arange(H) + 0.5) * py
    Xc, Yc = np.meshgrid(xc - c[0], yc - c[1])
    rc = Xc * Xc + Yc * Yc
    inc = rc < R * R
    Nc = np.stack([Xc / R, Yc / R, np.sqrt(np.where(inc, R * R - rc, 0.0)) / R], -1)
    Nc[~inc] = 0.0
    return SphereReference(radiance=cov * meanL, coverage=cov, normals=navg, centre_normals=Nc)


# -------------------------------------------------------------------- integrating sphere
def integrating_sphere_radiance(albedo: float, intensity: float, radius: float = 1.0) -> tuple[float, float]:
    """(direct, global) radiance inside a closed Lambertian sphere with a point source at its centre.

    Direct: every wall point is at distance R with normal incidence, ``E = I / R^2`` and
    ``L_d = rho I / (pi R^2)``.  Global: the uniform enclosure multiplies the radiosity by the
    geometric series ``1 + rho + rho^2 + ... = 1 / (1 - rho)`` (the form factor from any wall
    patch to the rest of a sphere is 1), so ``L = L_d / (1 - rho)``.

    References
    ----------
    D. A. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, §2 (radiosity,
    interreflections; the "white room" limit); docs/science.md §3.
    """
    rho = float(albedo)
    if not 0 <= rho < 1:
        raise ValueError(f"albedo: must be in [0, 1) for a convergent enclosure, got {albedo}")
    check_positive(intensity, "intensity")
    check_positive(radius, "radius")
    direct = rho * float(intensity) / (np.pi * float(radius) ** 2)
    return direct, direct / (1.0 - rho)


# ------------------------------------------------------------------------- shadow regions
@dataclass(frozen=True)
class ShadowRegions:
    """Umbra (points that see none of the source) and penumbra outline on the receiving plane,
    as convex polygons in that plane's (x, y); ``umbra`` is empty (0, 2) when there is none."""

    umbra: np.ndarray
    penumbra: np.ndarray


def _convex_hull_2d(pts: np.ndarray) -> np.ndarray:
    P = sorted(map(tuple, np.round(pts, 15)))
    if len(P) <= 2:
        return np.array(P)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in P:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(P):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def shadow_regions(source_xy, source_height: float, occluder_xy, occluder_height: float,
                   receiver_height: float = 0.0) -> ShadowRegions:
    """Umbra and penumbra of a convex occluder under a convex source, all on horizontal planes.

    Projecting the occluder from a source point ``s`` onto the receiver ``z = z_r`` maps an
    occluder point ``o`` to ``s + (o - s) (z_s - z_r) / (z_s - z_o)``.  A receiver point is in the
    umbra when it lies in the shadow of *every* source point -- the intersection of the projections
    from the source's vertices (convexity makes vertices enough) -- and in the shadow at all when
    it lies in the projection from *some* source point, whose outline is the convex hull of the
    projections from the vertices.  These are the lines through the source's and the occluder's
    edges of the chapter's Fig 1.5.

    Parameters
    ----------
    source_xy, occluder_xy : array_like (M, 2)
        Convex polygons (x, y) at heights ``source_height`` > ``occluder_height`` >
        ``receiver_height``.
    """
    s = as_float_array(source_xy, "source_xy")
    o = as_float_array(occluder_xy, "occluder_xy")
    for a, nm in ((s, "source_xy"), (o, "occluder_xy")):
        if a.ndim != 2 or a.shape[1] != 2 or len(a) < 3:
            raise ValueError(f"{nm}: expected (M >= 3, 2) polygon vertices, got shape {a.shape}")
    zs, zo, zr = float(source_height), float(occluder_height), float(receiver_height)
    if not zs > zo > zr:
        raise ValueError(f"heights: need source_height > occluder_height > receiver_height, got {zs}, {zo}, {zr}")
    k = (zs - zr) / (zs - zo)
    projections = [sv + (o - sv) * k for sv in s]
    umbra = projections[0]
    for pr in projections[1:]:
        umbra = _convex_intersection_2d(umbra, pr)
        if len(umbra) < 3:
            umbra = np.zeros((0, 2))
            break
    if len(umbra) >= 3 and abs(_area2d(umbra)) < 1e-14:
        umbra = np.zeros((0, 2))
    pen = _convex_hull_2d(np.concatenate(projections))
    return ShadowRegions(umbra=umbra, penumbra=pen)


def interval_on_line(poly: np.ndarray, y: float = 0.0) -> tuple[float, float] | None:
    """The x-interval where the horizontal line at ``y`` crosses a convex polygon (None if it misses)."""
    if len(poly) < 3:
        return None
    xs = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        if (a[1] - y) * (b[1] - y) <= 0 and a[1] != b[1]:
            t = (y - a[1]) / (b[1] - a[1])
            xs.append(a[0] + t * (b[0] - a[0]))
        elif a[1] == y:
            xs.append(a[0])
    if not xs:
        return None
    return float(min(xs)), float(max(xs))
