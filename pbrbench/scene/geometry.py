"""Scene geometry in the camera frame: the camera's axes, the nominal light vectors, and the
description of a scene's lights and camera that ``pbrbench render`` writes beside its EXR.

Frame (``docs/conventions.md``): **x right, y up, z toward the camera**; a light direction points
from the surface toward the source.  Everything here is a pure function of a
:class:`~pbrbench.scene.spec.SceneSpec` (NumPy only, no renderer), used by the benchmark tasks
(their inputs) and by the render command (its JSON), so both give the same numbers.

Units are those of the scene file: lengths in world units; radiance in the emitter's units
(``W m^-2 sr^-1`` when the scene file's values are read as SI), irradiance ``E`` (``W m^-2``),
intensity of a point source (``W sr^-1``), with ``E = I / r^2``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["camera_rotation", "nominal_light", "light_vectors", "describe_lights", "describe_camera",
           "UNITS"]

UNITS = {
    "length": "world units of the scene file",
    "radiance": "W m^-2 sr^-1 (the scene file's emitter units; images are linear radiance)",
    "irradiance": "W m^-2 (perpendicular to the rays; same units as radiance x sr)",
    "intensity": "W sr^-1 (point sources; E = I / r^2)",
    "direction": "unit vector from the surface toward the source, camera frame (x right, y up, z toward the camera)",
    "light_vector": "direction x irradiance at the camera target (the `lights` argument of photometric stereo)",
}


def camera_rotation(camera) -> np.ndarray:
    """(3, 3) rotation whose rows are the camera axes (x right, y up, z toward the camera) in
    world coordinates: ``R @ v`` expresses a world vector ``v`` in the camera frame."""
    o = np.asarray(camera.origin, float)
    t = np.asarray(camera.target, float)
    up = np.asarray(camera.up, float)
    z = o - t
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def _mean(v) -> float:
    return float(np.mean(np.asarray(v, float)))


def nominal_light(light, camera) -> tuple[np.ndarray, float]:
    """Nominal distant-source model of one light of a SceneSpec: ``(unit direction in the camera
    frame, irradiance at the camera target)``.

    * directional: its direction and (channel-mean) irradiance;
    * area rectangle: direction ``normalize(center - target)``; irradiance of a small source,
      ``L A cos(theta_s) / d^2`` (radiance, area, the emitter's tilt away from the target,
      distance) -- the value a user would measure at the target;
    * point: direction ``normalize(position - target)``, irradiance ``I / d^2``.
    """
    R = camera_rotation(camera)
    target = np.asarray(camera.target, float)
    kind = light.type
    if kind == "directional":
        d = np.asarray(light.direction, float)
        e = _mean(light.irradiance)
    elif kind == "area":
        d = np.asarray(light.center, float) - target
        dist = float(np.linalg.norm(d))
        n = np.asarray(light.normal, float)
        cos_s = max(0.0, float(np.dot(-d / dist, n / np.linalg.norm(n))))
        e = _mean(light.radiance) * light.size[0] * light.size[1] * cos_s / dist ** 2
    elif kind == "point":
        d = np.asarray(light.position, float) - target
        e = _mean(light.intensity) / float(np.dot(d, d))
    else:
        raise ValueError(f"light: a {kind!r} light has no direction; photometric models need "
                         "directional, area or point lights")
    d = R @ (d / np.linalg.norm(d))
    return d, e


def light_vectors(spec, which: str = "light_set") -> np.ndarray:
    """(K, 3) source vectors (unit direction x irradiance) in the camera frame, from the spec's
    ``light_set`` (default) or ``lights``."""
    lights = getattr(spec, which)
    if not lights:
        raise ValueError(f"spec {spec.name!r} has no {which}")
    return np.array([d * e for d, e in (nominal_light(li, spec.camera) for li in lights)])


def _to_camera(R, v) -> list[float]:
    return [float(x) for x in R @ np.asarray(v, float)]


def _one_light(light, camera, R, origin) -> dict:
    """One light as a JSON-ready dict: its type and scene-file values, and (for sources with a
    direction) the nominal direction and irradiance in the camera frame."""
    out: dict = {"type": light.type}
    if light.type == "directional":
        out["irradiance_rgb"] = list(light.irradiance)
    elif light.type == "point":
        out["intensity_rgb"] = list(light.intensity)
        out["position_world"] = list(light.position)
        out["position_camera"] = _to_camera(R, np.asarray(light.position, float) - origin)
    elif light.type == "area":
        out["radiance_rgb"] = list(light.radiance)
        out["size"] = list(light.size)
        out["center_world"] = list(light.center)
        out["center_camera"] = _to_camera(R, np.asarray(light.center, float) - origin)
        out["normal_camera"] = _to_camera(R, light.normal)
    elif light.type == "ambient":
        out["radiance_rgb"] = list(light.radiance)
        out["note"] = "uniform environment: no direction"
        return out
    d, e = nominal_light(light, camera)
    out["direction"] = [float(x) for x in d]
    out["irradiance"] = float(e)
    out["light_vector"] = [float(x) for x in d * e]
    return out


def describe_lights(spec) -> dict:
    """The spec's lights as JSON-ready dicts: ``{"lights": [...], "light_set": [...],
    "light_vectors": (K, 3) list or None}``; ``light_set[k]`` is the light of the per-light
    images ``lightNN.*`` (``NN = k``).  Positions are given in world coordinates and in the
    camera frame with the origin at the camera (``position_camera``)."""
    cam = spec.camera
    R = camera_rotation(cam)
    origin = np.asarray(cam.origin, float)
    out = {"lights": [_one_light(li, cam, R, origin) for li in spec.lights],
           "light_set": [_one_light(li, cam, R, origin) for li in spec.light_set]}
    try:
        out["light_vectors"] = light_vectors(spec).tolist() if spec.light_set else None
    except ValueError:
        out["light_vectors"] = None
    return out


def describe_camera(spec, resolution) -> dict:
    """The camera as a JSON-ready dict: type, frame (the camera axes in world coordinates),
    resolution ``[width, height]`` and, for an orthographic camera, the pixel size in world
    units; for a perspective one the horizontal field of view and the focal length in pixels."""
    cam = spec.camera
    w, h = int(resolution[0]), int(resolution[1])
    R = camera_rotation(cam)
    out = {"type": cam.type, "origin": list(cam.origin), "target": list(cam.target), "up": list(cam.up),
           "frame": {"x_right": R[0].tolist(), "y_up": R[1].tolist(), "z_toward_camera": R[2].tolist(),
                     "note": "rows of the world-to-camera rotation; image row 0 is the top (largest y)"},
           "resolution": [w, h]}
    if cam.type == "orthographic":
        out["half_width"] = float(cam.half_width)
        out["pixel_size"] = 2.0 * float(cam.half_width) / w
        out["film_extent"] = {"x": [-cam.half_width, cam.half_width],
                              "y": [-cam.half_width * h / w, cam.half_width * h / w]}
    else:
        out["fov_deg"] = float(cam.fov)
        out["fov_axis"] = "x"
        out["focal_px"] = 0.5 * w / math.tan(math.radians(cam.fov) / 2)
    return out
