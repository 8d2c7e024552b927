"""Radiosity on the camera's pixel grid: which patch each pixel centre sees, and its radiance ``B / pi``.

Exact ray casting of the pixel centres of the scene's camera (a z-buffer over the projected
patch triangles): Mitsuba's orthographic sensor scaled by ``half_width``
(:func:`pbrbench.shading.surfaces.pixel_grid`) or its perspective sensor (horizontal field of
view), so that later comparisons with the renders are pixel by pixel.  Reference: C. M. Goral et al., "Modeling the interaction of light between
diffuse surfaces", SIGGRAPH 1984 (radiance of a diffuse patch ``B / pi``).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array
from pbrbench.radiosity.patches import Patches

__all__ = ["patch_index_image", "radiosity_image"]


def _camera_frame(cam):
    o = np.asarray(cam.origin, float)
    d = np.asarray(cam.target, float) - o
    d /= np.linalg.norm(d)
    right = np.cross(d, np.asarray(cam.up, float))
    right /= np.linalg.norm(right)
    return o, d, right, np.cross(right, d)


def _film(cam, H: int, W: int):
    """Pixel-centre film coordinates ``(X, Y)`` (H, W): world units for an orthographic camera
    (:func:`pbrbench.shading.surfaces.pixel_grid`), ``tan`` of the angle from the view axis for
    a perspective one (horizontal field of view ``fov``, Mitsuba's ``fov_axis = "x"``)."""
    from pbrbench.shading.surfaces import pixel_grid

    if cam.type == "orthographic":
        return pixel_grid(H, W, cam.half_width)
    return pixel_grid(H, W, float(np.tan(np.radians(cam.fov) / 2)))


def _moller_trumbore(o, dirs, tri):
    """Distance along each ray ``o + t dirs`` (dirs (..., 3), one origin) to triangle ``tri``
    (3, 3), in units of ``|dirs|``; inf where the ray misses (Moller-Trumbore)."""
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    p = np.cross(dirs, e2)
    det = p @ e1
    ok = np.abs(det) > 1e-18
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - tri[0]
    u = (p @ s) * inv
    q = np.cross(s, e1)
    v = (dirs @ q) * inv
    t = float(e2 @ q) * inv
    hit = ok & (u >= -1e-12) & (v >= -1e-12) & (u + v <= 1 + 1e-12) & (t > 0)
    return np.where(hit, t, np.inf)


def patch_index_image(spec, patches: Patches, resolution=None) -> np.ndarray:
    """(H, W) index of the patch seen at each pixel centre of the scene's camera.

    ``-1``: nothing; ``-2 - k``: the front of area light ``k`` (in ``spec.lights + light_set``
    order); a back-facing patch or light gives ``-1 - 10**9`` (black, as Mitsuba's one-sided
    diffuse and area emitters).  Orthographic: the ray of pixel (row i, column j) starts at the
    camera origin offset by ``x_j right + y_i up`` (:func:`pbrbench.shading.surfaces.pixel_grid`,
    the film of Mitsuba's orthographic sensor scaled by ``half_width``) and runs along the view
    direction.  Perspective: the ray starts at the origin and runs along
    ``d + tan(fov / 2) (x_j right + y_i up)`` with ``x_j, y_i`` the pixel grid of half-width 1
    (Mitsuba's ``perspective`` sensor with ``fov_axis = "x"``).  Hits nearer than ``near_clip``
    along the view axis are ignored.  Exact ray casting of the pixel centres: a z-buffer over the
    projected triangles (perspective-correct depth), and ray-triangle tests for the triangles
    that cross the camera's plane.
    """
    cam = spec.camera
    if cam.type not in ("orthographic", "perspective"):  # pragma: no cover - the spec admits no other
        raise ValueError(f"camera.type={cam.type!r}: radiosity images support orthographic and perspective cameras")
    from pbrbench.shading.irradiance import rectangle_polygon

    W, H = spec.render.resolution if resolution is None else (
        (int(resolution), int(resolution)) if np.isscalar(resolution) else tuple(int(r) for r in resolution))
    persp = cam.type == "perspective"
    o, d, right, up = _camera_frame(cam)
    X, Y = _film(cam, H, W)
    tris, owner = patches.triangles()
    labels = owner.copy()
    lights = list(spec.lights) + list(spec.light_set)
    extra = []
    for k, light in enumerate(lights):
        if light.type == "area":
            p = rectangle_polygon(light.center, light.size, light.normal, light.up)
            extra += [(p[[0, 1, 2]], -2 - k), (p[[0, 2, 3]], -2 - k)]
    if extra:
        tris = np.concatenate([tris, np.stack([t for t, _ in extra])])
        labels = np.concatenate([labels, [lab for _, lab in extra]])
    rel = tris - o
    fx, fy, fz = rel @ right, rel @ up, rel @ d
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    if persp:  # seen from the origin: front-facing when the normal points back toward it
        facing = np.einsum("tk,tk->t", normal, rel[:, 0]) < 0
        crossing = fz.min(axis=1) <= cam.near_clip
        with np.errstate(divide="ignore", invalid="ignore"):
            sx, sy = fx / fz, fy / fz
    else:
        facing = np.einsum("tk,k->t", normal, d) < 0
        crossing = np.zeros(len(tris), bool)
        sx, sy = fx, fy
    depth = np.full((H, W), np.inf)
    out = np.full((H, W), -1, dtype=np.int64)
    px = X[0, 1] - X[0, 0] if W > 1 else 2 * (X[0, 0] if X.size else 1.0)
    x0, y0 = X[0, 0], Y[0, 0]
    for t in range(len(tris)):
        if crossing[t]:
            continue
        ax, ay, bx, by, cx, cy = sx[t, 0], sy[t, 0], sx[t, 1], sy[t, 1], sx[t, 2], sy[t, 2]
        den = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
        if abs(den) < 1e-18:
            continue
        j0 = max(0, int(np.floor((min(ax, bx, cx) - x0) / px)))
        j1 = min(W - 1, int(np.ceil((max(ax, bx, cx) - x0) / px)))
        i0 = max(0, int(np.floor((y0 - max(ay, by, cy)) / px)))
        i1 = min(H - 1, int(np.ceil((y0 - min(ay, by, cy)) / px)))
        if j0 > j1 or i0 > i1:
            continue
        xs, ys = X[i0:i1 + 1, j0:j1 + 1], Y[i0:i1 + 1, j0:j1 + 1]
        l1 = ((by - cy) * (xs - cx) + (cx - bx) * (ys - cy)) / den
        l2 = ((cy - ay) * (xs - cx) + (ax - cx) * (ys - cy)) / den
        l3 = 1 - l1 - l2
        inside = (l1 >= -1e-12) & (l2 >= -1e-12) & (l3 >= -1e-12)
        if persp:  # 1/z is affine in screen coordinates
            z = 1.0 / (l1 / fz[t, 0] + l2 / fz[t, 1] + l3 / fz[t, 2])
        else:
            z = l1 * fz[t, 0] + l2 * fz[t, 1] + l3 * fz[t, 2]
        win = inside & (z > cam.near_clip) & (z < depth[i0:i1 + 1, j0:j1 + 1])
        if win.any():
            depth[i0:i1 + 1, j0:j1 + 1][win] = z[win]
            out[i0:i1 + 1, j0:j1 + 1][win] = labels[t] if facing[t] else -1 - 10**9
    if crossing.any():  # triangles through the camera's plane: exact rays through every pixel
        dirs = d + X[..., None] * right + Y[..., None] * up
        for t in np.flatnonzero(crossing):
            dist = _moller_trumbore(o, dirs, tris[t])
            z = dist  # the view-axis depth of o + dist * dirs (d . dirs = 1)
            win = np.isfinite(dist) & (z > cam.near_clip) & (z < depth)
            if win.any():
                depth[win] = z[win]
                out[win] = labels[t] if facing[t] else -1 - 10**9
    return out


def radiosity_image(spec, patches: Patches, B, *, resolution=None, index=None, supersample: int = 1) -> np.ndarray:
    """Radiance ``B / pi`` of the patch seen at each pixel centre (H, W, C) of the scene's camera.

    Area lights seen from the front show their radiance, back faces are black, pixels that see
    nothing show the ambient light's radiance (0 without one), as in Mitsuba's renders.
    ``index`` may pass a precomputed :func:`patch_index_image` (at ``supersample`` times the
    resolution).  ``supersample = s > 1`` samples ``s x s`` points per pixel (the pixel centres of a
    film ``s`` times finer) and averages them: the pixel's footprint, as the renders' box filter
    averages it, so pixels across an edge are the same mixtures in both.
    """
    from pbrbench.checks import check_int

    s = check_int(supersample, "supersample", 1, 16)
    if s > 1:
        W, H = spec.render.resolution if resolution is None else (
            (int(resolution), int(resolution)) if np.isscalar(resolution) else tuple(int(r) for r in resolution))
        fine = radiosity_image(spec, patches, B, resolution=(W * s, H * s), index=index)
        return fine.reshape((H, s, W, s) + fine.shape[2:]).mean(axis=(1, 3))
    B = as_float_array(B, "B")
    if B.shape[0] != len(patches):
        raise ValueError(f"B: expected {len(patches)} patch values, got shape {B.shape}")
    B2 = B.reshape(len(patches), -1)
    C = B2.shape[1]
    idx = patch_index_image(spec, patches, resolution) if index is None else np.asarray(index)
    lights = list(spec.lights) + list(spec.light_set)
    env = np.zeros(C)
    for light in lights:
        if light.type == "ambient":
            env = env + np.broadcast_to(np.asarray(light.radiance, float)[:C], (C,))
    img = np.zeros(idx.shape + (C,))
    hit = idx >= 0
    img[hit] = B2[idx[hit]] / np.pi
    img[idx == -1] = env
    for k, light in enumerate(lights):
        if light.type == "area":
            img[idx == -2 - k] = np.broadcast_to(np.asarray(light.radiance, float)[:C], (C,))
    return img if B.ndim > 1 else img[..., 0]
