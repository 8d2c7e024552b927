"""Radiosity on the camera's pixel grid: which patch each pixel centre sees, and its radiance ``B / pi``.

Exact ray casting of the pixel centres of an orthographic camera (a z-buffer over the projected
patch triangles), with the film of Mitsuba's orthographic sensor scaled by ``half_width``
(:func:`pbrbench.shading.surfaces.pixel_grid`), so that later comparisons with the renders are
pixel by pixel.  Reference: C. M. Goral et al., "Modeling the interaction of light between
diffuse surfaces", SIGGRAPH 1984 (radiance of a diffuse patch ``B / pi``).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array
from pbrbench.shading.patches import Patches

__all__ = ["patch_index_image", "radiosity_image"]


def _camera_frame(cam):
    o = np.asarray(cam.origin, float)
    d = np.asarray(cam.target, float) - o
    d /= np.linalg.norm(d)
    right = np.cross(d, np.asarray(cam.up, float))
    right /= np.linalg.norm(right)
    return o, d, right, np.cross(right, d)


def patch_index_image(spec, patches: Patches, resolution=None) -> np.ndarray:
    """(H, W) index of the patch seen at each pixel centre of the orthographic camera.

    ``-1``: nothing; ``-2 - k``: the front of area light ``k`` (in ``spec.lights + light_set``
    order); a back-facing patch or light gives ``-1 - 10**9`` (black, as Mitsuba's one-sided
    diffuse and area emitters).  The ray of pixel (row i, column j) starts at the camera origin
    offset by ``x_j right + y_i up`` (:func:`pbrbench.shading.surfaces.pixel_grid`, the film of
    Mitsuba's orthographic sensor scaled by ``half_width``) and runs along the view direction;
    hits nearer than ``near_clip`` are ignored (rays start on the near plane).  Exact ray casting
    of the pixel centres (a z-buffer over the projected triangles).
    """
    cam = spec.camera
    if cam.type != "orthographic":
        raise ValueError(f"camera.type={cam.type!r}: radiosity images support orthographic cameras only; "
                         "use an orthographic camera (or compare patch values directly)")
    from pbrbench.shading.irradiance import rectangle_polygon
    from pbrbench.shading.surfaces import pixel_grid

    W, H = spec.render.resolution if resolution is None else (
        (int(resolution), int(resolution)) if np.isscalar(resolution) else tuple(int(r) for r in resolution))
    o, d, right, up = _camera_frame(cam)
    X, Y = pixel_grid(H, W, cam.half_width)
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
    facing = np.einsum("tk,k->t", np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), d) < 0
    depth = np.full((H, W), np.inf)
    out = np.full((H, W), -1, dtype=np.int64)
    px = 2 * cam.half_width / W
    x0, y0 = X[0, 0], Y[0, 0]
    for t in range(len(tris)):
        ax, ay, bx, by, cx, cy = fx[t, 0], fy[t, 0], fx[t, 1], fy[t, 1], fx[t, 2], fy[t, 2]
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
        z = l1 * fz[t, 0] + l2 * fz[t, 1] + l3 * fz[t, 2]
        win = inside & (z > cam.near_clip) & (z < depth[i0:i1 + 1, j0:j1 + 1])
        if win.any():
            depth[i0:i1 + 1, j0:j1 + 1][win] = z[win]
            out[i0:i1 + 1, j0:j1 + 1][win] = labels[t] if facing[t] else -1 - 10**9
    return out


def radiosity_image(spec, patches: Patches, B, *, resolution=None, index=None) -> np.ndarray:
    """Radiance ``B / pi`` of the patch seen at each pixel centre (H, W, C) of an orthographic camera.

    Area lights seen from the front show their radiance, back faces are black, pixels that see
    nothing show the ambient light's radiance (0 without one), as in Mitsuba's renders.
    ``index`` may pass a precomputed :func:`patch_index_image`.
    """
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
