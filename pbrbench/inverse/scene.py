"""What inverse rendering takes from a scene description (a :class:`pbrbench.scene.spec.SceneSpec`),
and nothing more (NumPy only; no renderer):

* the camera (:func:`check_camera`: orthographic; its origin, target, up and half width);
* the lights of the light set as the renderer sees them (:func:`light_dicts`: the spec's own
  emitters, or distant sources built from the light vectors);
* the lateral extent of the scene's geometry beyond the camera's frame (:func:`frame_extension`),
  over which the recovered surface is continued (not the geometry itself);
* the render settings that define the transport (``rr_depth``; ``max_depth`` comes from the
  caller, since it is a property of the images, not of the scene).

The object's shape and reflectance (``spec.shapes``, ``spec.materials``) are never read.
"""

from __future__ import annotations

import numpy as np


def check_camera(spec) -> None:
    cam = spec.camera
    if cam.type != "orthographic":
        raise ValueError(f"scene: camera type {cam.type!r}; inverse rendering of a height field on the image grid "
                         "needs an orthographic camera (a perspective one is not supported)")


def _shape_points(shape) -> np.ndarray:
    """World points whose convex hull contains the shape (a bounding set, possibly loose)."""
    from pbrbench.scene import spec as S

    def rot(pts):
        m = np.eye(3)
        for r in shape.rotate:
            a = np.asarray(r.axis, float)
            a = a / np.linalg.norm(a)
            t = np.radians(r.angle)
            k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
            m = (np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k) @ m
        return pts @ m.T

    if isinstance(shape, S.Rectangle):
        sx, sy = shape.size[0] / 2, shape.size[1] / 2
        pts = np.array([[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]], float)
        return rot(pts) + np.asarray(shape.center, float)
    if isinstance(shape, S.Heightfield):
        w = shape.half_width
        pts = np.array([[-w, -w, 0], [w, -w, 0], [w, w, 0], [-w, w, 0]], float) + np.asarray(shape.center, float)
        return rot(pts)
    if isinstance(shape, S.Box):
        s = np.asarray(shape.size, float) / 2
        pts = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * s
        return rot(pts) + np.asarray(shape.center, float)
    if isinstance(shape, (S.Sphere, S.Disk)):
        r = shape.radius
        pts = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * r
        return pts + np.asarray(shape.center, float)
    if isinstance(shape, S.Cylinder):
        r = shape.radius
        cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * r
        return np.concatenate([cube + np.asarray(shape.p0, float), cube + np.asarray(shape.p1, float)])
    raise TypeError(shape)  # pragma: no cover


def frame_extension(spec, height: int, width: int) -> tuple[float, float, float, float]:
    """(left, right, top, bottom): how far (world units, >= 0) the scene's geometry reaches beyond
    each side of the camera's frame, from the bounding points of its shapes projected onto the
    film plane.  Only this extent is taken from the scene: the surface beyond the frame is the
    continuation of the recovered one."""
    from pbrbench.scene.geometry import camera_rotation

    cam = spec.camera
    R = camera_rotation(cam)
    t = np.asarray(cam.target, float)
    pts = [_shape_points(s) for s in spec.shapes if not s.occluder]
    if not pts:
        return (0.0, 0.0, 0.0, 0.0)
    xy = (np.concatenate(pts) - t) @ R[:2].T
    hw = float(cam.half_width)
    hh = hw * height / width
    return (max(0.0, -hw - xy[:, 0].min()), max(0.0, xy[:, 0].max() - hw),
            max(0.0, xy[:, 1].max() - hh), max(0.0, -hh - xy[:, 1].min()))


def light_dicts(mi, spec, lights: np.ndarray, model: str) -> list[tuple[str, dict]]:
    """Emitter dicts of the K lights: ``model="scene"``: the spec's light set (directional, area
    or point sources exactly as rendered); ``"vectors"``: distant sources built from the light
    vectors (direction and irradiance ``|l|``, camera frame), i.e. the photometric-stereo model."""
    from pbrbench.scene.geometry import camera_rotation
    from pbrbench.scene.mitsuba_dict import emitter_dict

    k = len(lights)
    if model == "scene":
        if len(spec.light_set) != k:
            raise ValueError(f"lights: {k} light vectors but the scene {spec.name!r} has {len(spec.light_set)} lights "
                             "in its light set; pass one image and one vector per light of the set, or "
                             "light_model='vectors'")
        return [emitter_dict(mi, li) for li in spec.light_set]
    if model == "vectors":
        R = camera_rotation(spec.camera)
        out = []
        for v in np.asarray(lights, float):
            e = float(np.linalg.norm(v))
            d = R.T @ (v / e)  # world direction toward the source
            out.append(("emitter", {"type": "directional", "direction": (-d).tolist(),
                                    "irradiance": {"type": "rgb", "value": [e, e, e]}}))
        return out
    raise ValueError(f"light_model: {model!r}; use 'scene' (the scene's emitters) or 'vectors' (distant sources)")
