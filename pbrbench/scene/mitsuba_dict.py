"""SceneSpec -> Mitsuba scene dictionary.

Frames: the spec's world frame is Mitsuba's world frame.  Directional-light ``direction`` (toward
the source) becomes Mitsuba's direction of travel ``-direction``.  Area lights are one-sided
rectangles facing ``normal``.  Heightfields become triangle meshes (PLY files written to a
scratch directory) with the surface's exact normals as vertex normals.
"""

from __future__ import annotations

import hashlib
import os

import numpy as np

from pbrbench.scene import spec as S
from pbrbench.scene.textures import texture_array
from pbrbench.shading import surfaces


def _scratch_dir() -> str:
    """This process's scratch directory for meshes, removed at exit (:mod:`pbrbench.scratch`)."""
    from pbrbench.scratch import scratch_dir

    return scratch_dir("mesh")


def _rgb(mi, v):
    return {"type": "rgb", "value": [float(c) for c in v]}


def _texture(mi, t, base_dir):
    if isinstance(t, S.CheckerTexture):
        return {"type": "checkerboard", "color0": _rgb(mi, t.color0), "color1": _rgb(mi, t.color1),
                "to_uv": mi.ScalarTransform4f().scale([t.scale, t.scale, 1])}
    arr = np.ascontiguousarray(np.flipud(texture_array(t, base_dir)), dtype=np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(arr), "raw": True, "filter_type": "nearest", "wrap_mode": "clamp"}


def _reflectance(mi, albedo, base_dir):
    if isinstance(albedo, tuple):
        return _rgb(mi, albedo)
    return _texture(mi, albedo, base_dir)


def bsdf_dict(mi, m: S.Material, base_dir: str, *, diffuse_only: bool = False) -> dict:
    refl = _reflectance(mi, m.albedo, base_dir)
    if m.type == "diffuse" or diffuse_only:
        return {"type": "diffuse", "reflectance": refl}
    if m.type == "plastic":
        return {"type": "plastic", "diffuse_reflectance": refl, "int_ior": m.int_ior, "nonlinear": False}
    return {"type": "roughplastic", "distribution": "ggx", "alpha": m.alpha, "diffuse_reflectance": refl,
            "int_ior": m.int_ior, "nonlinear": False}


def _rotations(mi, rot) -> object:
    T = mi.ScalarTransform4f
    m = T()
    for r in rot:
        m = T().rotate(list(r.axis), r.angle) @ m
    return m


def _frame(mi, center, normal, up, scale):
    T = mi.ScalarTransform4f
    from pbrbench.shading.irradiance import rectangle_basis

    c = np.asarray(center, float)
    _, u, n = rectangle_basis(normal, up)
    return T().look_at(origin=c.tolist(), target=(c + n).tolist(), up=u.tolist()) @ T().scale(list(scale))


def write_ply(path: str, verts: np.ndarray, normals: np.ndarray, uvs: np.ndarray, faces: np.ndarray) -> None:
    """Binary little-endian PLY with positions, normals, uvs and triangles."""
    nv, nf = len(verts), len(faces)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n"
        f"element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    vdata = np.concatenate([verts, normals, uvs], axis=1).astype("<f4")
    fdata = np.empty(nf, dtype=[("n", "u1"), ("i", "<i4", (3,))])
    fdata["n"] = 3
    fdata["i"] = faces
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vdata.tobytes())
        f.write(fdata.tobytes())


def heightfield_mesh(shape: S.Heightfield, base_dir: str):
    """Vertices, normals, uvs and faces of a heightfield (triangles with all vertices defined)."""
    n = shape.resolution
    hw = shape.half_width
    xs = np.linspace(-hw, hw, n)
    x, y = np.meshgrid(xs, xs[::-1])
    if shape.surface is not None:
        surf = surfaces.evaluate(shape.surface, x, y, **shape.params)
        z, fx, fy, mask = surf.z, surf.fx, surf.fy, surf.mask
    else:
        from pbrbench.scene.data import load_data

        z = load_data(base_dir, shape.path, "height", where=f"height array {os.path.join(base_dir, shape.path)}")
        if z.shape != (n, n):
            from scipy.ndimage import zoom

            z = zoom(z, (n / z.shape[0], n / z.shape[1]), order=3)
        h = xs[1] - xs[0]
        gy_rows, fx = np.gradient(z, h)
        fy = -gy_rows
        mask = np.ones_like(z, bool)
    z = z * shape.z_scale
    fx, fy = fx * shape.z_scale, fy * shape.z_scale
    nrm = np.stack([-fx, -fy, np.ones_like(fx)], -1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    c = np.asarray(shape.center, float)
    verts = np.stack([x + c[0], y + c[1], z + c[2]], -1).reshape(-1, 3)
    uvs = np.stack([(x + hw) / (2 * hw), (y + hw) / (2 * hw)], -1).reshape(-1, 2)
    idx = np.arange(n * n).reshape(n, n)
    a, b, cc, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    # rows go toward -y; counter-clockwise seen from +z: (a, c, b) and (b, c, d)
    t1 = np.stack([a, cc, b], -1).reshape(-1, 3)
    t2 = np.stack([b, cc, d], -1).reshape(-1, 3)
    faces = np.concatenate([t1, t2])
    m = mask.reshape(-1)
    faces = faces[m[faces].all(axis=1)]
    if not (np.isfinite(verts).all() and np.isfinite(nrm).all()) or len(faces) == 0:
        from pbrbench.errors import SceneError

        what = shape.surface or shape.path
        raise SceneError(f"heightfield {what!r}: the mesh is {'empty' if len(faces) == 0 else 'not finite'}; check its "
                         "params, half_width and z_scale")
    return verts, nrm.reshape(-1, 3), uvs, faces


def shape_dict(mi, spec: S.SceneSpec, i: int, shape, *, diffuse_only: bool = False) -> dict:
    T = mi.ScalarTransform4f
    mat = spec.material_of(shape)
    d: dict = {"bsdf": bsdf_dict(mi, mat, spec.data_root, diffuse_only=diffuse_only)}
    if shape.flip_normals:
        d["flip_normals"] = True
    rot = _rotations(mi, shape.rotate)
    if isinstance(shape, S.Sphere):
        d.update(type="sphere", to_world=T().translate(list(shape.center)) @ rot @ T().scale(shape.radius))
    elif isinstance(shape, S.Rectangle):
        d.update(type="rectangle", to_world=T().translate(list(shape.center)) @ rot @ T().scale([shape.size[0] / 2, shape.size[1] / 2, 1]))
    elif isinstance(shape, S.Box):
        d.update(type="cube", to_world=T().translate(list(shape.center)) @ rot @ T().scale([s / 2 for s in shape.size]))
    elif isinstance(shape, S.Disk):
        d.update(type="disk", to_world=T().translate(list(shape.center)) @ rot @ T().scale(shape.radius))
    elif isinstance(shape, S.Cylinder):
        d.update(type="cylinder", p0=list(shape.p0), p1=list(shape.p1), radius=shape.radius)
    elif isinstance(shape, S.Heightfield):
        key = hashlib.sha256(shape.model_dump_json().encode() + spec.content_hash().encode()).hexdigest()[:24]
        path = os.path.join(_scratch_dir(), f"hf_{key}.ply")
        if not os.path.exists(path):  # built once per process, reused by every pass
            mesh = heightfield_mesh(shape, spec.data_root)
            try:
                write_ply(path + ".tmp", *mesh)
                os.replace(path + ".tmp", path)
            except OSError as exc:
                from pbrbench.errors import disk_error

                raise disk_error(exc, f"scratch directory {os.path.dirname(path)} (heightfield meshes)",
                                 option="TMPDIR") from None
        d.update(type="ply", filename=path, face_normals=False)
        if shape.rotate:
            d["to_world"] = rot
    else:  # pragma: no cover
        raise TypeError(shape)
    return d


def emitter_dict(mi, light) -> tuple[str, dict]:
    """('emitter' | 'shape', dict) for a light spec."""
    if isinstance(light, S.Directional):
        d = np.asarray(light.direction, float)
        return "emitter", {"type": "directional", "direction": (-d / np.linalg.norm(d)).tolist(),
                           "irradiance": _rgb(mi, light.irradiance)}
    if isinstance(light, S.Point):
        return "emitter", {"type": "point", "position": list(light.position), "intensity": _rgb(mi, light.intensity)}
    if isinstance(light, S.Ambient):
        return "emitter", {"type": "constant", "radiance": _rgb(mi, light.radiance)}
    if isinstance(light, S.AreaRect):
        return "shape", {"type": "rectangle",
                         "to_world": _frame(mi, light.center, light.normal, light.up, (light.size[0] / 2, light.size[1] / 2, 1)),
                         "bsdf": {"type": "diffuse", "reflectance": _rgb(mi, (0, 0, 0))},
                         "emitter": {"type": "area", "radiance": _rgb(mi, light.radiance)}}
    raise TypeError(light)  # pragma: no cover


def sensor_dict(mi, spec: S.SceneSpec, resolution, spp: int, *, pixel_format: str = "rgb", sampler: str | None = None) -> dict:
    T = mi.ScalarTransform4f
    cam = spec.camera
    w, h = resolution
    film = {"type": "hdrfilm", "width": w, "height": h, "pixel_format": pixel_format,
            "component_format": "float32", "rfilter": {"type": "box"}}
    look = T().look_at(origin=list(cam.origin), target=list(cam.target), up=list(cam.up))
    sens = {"film": film, "sampler": {"type": sampler or spec.render.sampler, "sample_count": int(spp)},
            "near_clip": cam.near_clip, "far_clip": cam.far_clip}
    if cam.type == "orthographic":
        sens.update(type="orthographic", to_world=look @ T().scale([cam.half_width, cam.half_width, 1.0]))
    else:
        sens.update(type="perspective", fov=cam.fov, fov_axis="x", to_world=look)
    return sens


def shape_key(spec: S.SceneSpec, i: int) -> str:
    return f"s{i:03d}_" + "".join(ch if ch.isalnum() else "_" for ch in spec.shape_names()[i])


def scene_dict(mi, spec: S.SceneSpec, resolution, spp: int, *, lights=None, integrator=None,
               diffuse_only: bool = False, drop_occluders: bool = False, pixel_format: str = "rgb",
               sampler: str | None = None) -> dict:
    """The Mitsuba dict of ``spec`` with the given lights (default: lights + light_set)."""
    lights = list(spec.lights) + list(spec.light_set) if lights is None else list(lights)
    d: dict = {"type": "scene",
               "sensor": sensor_dict(mi, spec, resolution, spp, pixel_format=pixel_format, sampler=sampler),
               "integrator": integrator or {"type": "path", "max_depth": spec.render.max_depth, "rr_depth": spec.render.rr_depth}}
    for i, shape in enumerate(spec.shapes):
        if drop_occluders and shape.occluder:
            continue
        d[shape_key(spec, i)] = shape_dict(mi, spec, i, shape, diffuse_only=diffuse_only)
    for k, light in enumerate(lights):
        _, ld = emitter_dict(mi, light)
        d[f"light{k:03d}"] = ld
    return d
