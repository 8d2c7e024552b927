"""Planar patch meshes for the radiosity model, built from a :class:`~pbrbench.scene.spec.SceneSpec`.

Geometry follows the Mitsuba builder (:mod:`pbrbench.scene.mitsuba_dict`) exactly:

* ``rectangle``: the square ``[-1, 1]^2`` of ``z = 0`` (normal +z) scaled by ``size / 2``,
  rotated (the ``rotate`` list in order) and translated to ``center``; cut into
  ``ceil(size / patch_size)`` cells per side;
* ``box``: the six faces of ``[-1, 1]^3`` (outward normals) scaled by ``size / 2``, rotated and
  translated; each face cut like a rectangle;
* ``cylinder``: Mitsuba's open tube from ``p0`` to ``p1`` (no end caps, outward normals) as an
  inscribed prism of ``max(8, ceil(2 pi radius / patch_size))`` planar facets around (vertices on
  the cylinder, the first at azimuth 0 of the frame ``u = `` the world axis least aligned with
  the cylinder's, made orthogonal to it, ``v = a x u``), each cut into ``ceil(length / patch_size)``
  patches along; its area and normals differ from the round tube's by ``O(1 / facets^2)`` and
  ``pi / facets``;
* ``heightfield``: the triangle mesh of :func:`pbrbench.scene.mitsuba_dict.heightfield_mesh`
  (same vertex layout, same triangles, same mask) evaluated on a coarser grid of
  ``cells + 1`` vertices per side, then rotated about the world origin (as the builder does);
  each triangle is a patch and remembers its grid cell ``(row, col)`` (row 0 at +y).
  The analytic ``spherical_cap`` surface is a heightfield like any other.

``flip_normals`` reverses every patch.  Patches are one-sided: they emit and receive on the side
of their normal only (Mitsuba's ``diffuse`` BSDF is black from behind) and every patch occludes.
Area lights are not patches but their rectangles occlude, as they do in Mitsuba.

Only diffuse materials with a constant albedo or a Mondrian texture (looked up at the patch
centroid's uv) are accepted; spheres, disks, image textures and glossy materials are refused with a
``ValueError`` naming the shape.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pbrbench.checks import as_float_array, check_int, check_positive
from pbrbench.radiosity.raycast import Occluders, build_occluders
from pbrbench.shading.form_factors import as_patch_vertices, patch_geometry

__all__ = ["Patches", "make_patches", "patches_from_spec", "rotation_matrix", "SUPPORTED_SHAPES"]

SUPPORTED_SHAPES = ("rectangle", "box", "cylinder", "heightfield")


@dataclass(frozen=True, eq=False)
class Patches:
    """A mesh of planar, one-sided, diffuse polygon patches (triangles or quads).

    Attributes
    ----------
    vertices : ndarray (N, 4, 3)
        Corners in order (counter-clockwise seen from the front); a triangle repeats its last one.
    n_vertices : ndarray (N,)
        3 or 4.
    albedo : ndarray (N, 3)
        Diffuse RGB albedo in [0, 1].
    object_id : ndarray (N,)
        Index of the shape in the scene (or any label).
    grid_index : ndarray (N, 2)
        ``(row, col)`` of a heightfield patch's grid cell, ``(-1, -1)`` for other patches.
    face_id : ndarray (N,)
        Label of the planar face (or heightfield) the patch belongs to.
    occluder_triangles : ndarray (K, 3, 3)
        Everything that blocks light: the unrefined faces of rectangles and boxes, the triangles
        of heightfields, the rectangles of area lights (which block but are not patches).
    occluder_groups : ndarray (K,)
        Face label of each occluder triangle (culling works per face).
    centres, normals, areas, radii : ndarray
        Area centroids (N, 3), unit normals (N, 3), areas (N,), bounding radii (N,).
    """

    vertices: np.ndarray
    n_vertices: np.ndarray
    albedo: np.ndarray
    object_id: np.ndarray
    grid_index: np.ndarray
    face_id: np.ndarray
    occluder_triangles: np.ndarray
    occluder_groups: np.ndarray
    centres: np.ndarray = field(init=False, repr=False)
    normals: np.ndarray = field(init=False, repr=False)
    areas: np.ndarray = field(init=False, repr=False)
    radii: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        c, n, a, r = patch_geometry(self.vertices)
        for k, val in (("centres", c), ("normals", n), ("areas", a), ("radii", r)):
            object.__setattr__(self, k, val)

    def __len__(self) -> int:
        return len(self.vertices)

    @property
    def planes(self) -> np.ndarray:
        """(N, 4): unit normal and offset ``d`` of each patch's plane (``n . x = d``)."""
        return np.concatenate([self.normals, np.sum(self.normals * self.centres, 1, keepdims=True)], axis=1)

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, 3, 3) triangles of the patches (a quad gives two) and the patch of each."""
        v = self.vertices
        quad = self.n_vertices == 4
        return (np.concatenate([v[:, [0, 1, 2]], v[quad][:, [0, 2, 3]]]),
                np.concatenate([np.arange(len(v)), np.flatnonzero(quad)]))

    def occluders(self, *, cluster_size: int = 8) -> Occluders:
        """The blocking triangles, grouped and clustered for ray casting (built once)."""
        if "_occ" not in self.__dict__:
            occ = build_occluders(self.occluder_triangles, self.occluder_groups, cluster_size=cluster_size)
            object.__setattr__(self, "_occ", occ)
        return self.__dict__["_occ"]

    def subset(self, mask) -> Patches:
        """The patches selected by a boolean mask or index array (the occluders are kept whole)."""
        idx = np.arange(len(self))[mask]
        return Patches(self.vertices[idx], self.n_vertices[idx], self.albedo[idx], self.object_id[idx],
                       self.grid_index[idx], self.face_id[idx], self.occluder_triangles, self.occluder_groups)


def make_patches(vertices, albedo=0.5, *, object_id=None, face_id=None, grid_index=None,
                 extra_occluders=None) -> Patches:
    """Patches from raw vertices (N, 3, 3) triangles or (N, 4, 3) quads and an albedo.

    ``albedo`` is a number, an RGB triple or an (N,) / (N, 3) array in [0, 1].  ``face_id``
    labels planar faces for the visibility culling (default: one per patch).  The occluders are
    the patches' own triangles plus ``extra_occluders`` (K, 3, 3), each its own group.
    """
    raw = as_float_array(vertices, "vertices", ndim=(3,))
    v = as_patch_vertices(raw)
    N = len(v)
    nv = np.full(N, raw.shape[1], int)
    if raw.shape[1] == 4:
        nv[np.all(np.isclose(v[:, 3], v[:, 2]), axis=1)] = 3
    rho = as_float_array(albedo, "albedo")
    if rho.ndim == 0 or rho.shape == (3,):
        rho = np.broadcast_to(rho, (N, 3))
    elif rho.shape == (N,):
        rho = np.repeat(rho[:, None], 3, axis=1)
    if rho.shape != (N, 3):
        raise ValueError(f"albedo: expected a number, [r, g, b], (N,) or (N, 3) with N = {N}, got shape {rho.shape}")
    if not np.all(np.isfinite(rho)) or rho.min() < 0 or rho.max() > 1:
        raise ValueError("albedo: values must be finite and in [0, 1]")
    oid = np.zeros(N, int) if object_id is None else np.broadcast_to(np.asarray(object_id, int), (N,)).copy()
    fid = np.arange(N) if face_id is None else np.broadcast_to(np.asarray(face_id, int), (N,)).copy()
    gi = np.full((N, 2), -1, int) if grid_index is None else np.asarray(grid_index, int).reshape(N, 2)
    quad = nv == 4
    tris = np.concatenate([v[:, [0, 1, 2]], v[quad][:, [0, 2, 3]]])
    groups = np.concatenate([fid, fid[quad]])
    if extra_occluders is not None:
        extra = np.asarray(extra_occluders, float).reshape(-1, 3, 3)
        tris = np.concatenate([tris, extra])
        groups = np.concatenate([groups, (groups.max() + 1 if len(groups) else 0) + np.arange(len(extra))])
    return Patches(v, nv, np.array(rho, float), oid, gi, fid, tris, groups)


# ---------------------------------------------------------------------------- the builder
def rotation_matrix(axis, angle_deg: float) -> np.ndarray:
    """Mitsuba's ``rotate(axis, angle)``: ``cos(t) I + (1 - cos(t)) a a^T + sin(t) [a]_x`` (t in degrees).

    Right-handed about ``axis``.  Like Mitsuba (drjit's ``rotate``), the axis is *not*
    normalised: a non-unit axis gives a non-rigid transform, reproduced here so that the patches
    coincide with the rendered shapes.
    """
    a = np.asarray(axis, float)
    t = math.radians(angle_deg)
    c, s = math.cos(t), math.sin(t)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return c * np.eye(3) + (1 - c) * np.outer(a, a) + s * K


def _rotations(rotate) -> np.ndarray:
    m = np.eye(3)
    for r in rotate:
        m = rotation_matrix(r.axis, r.angle) @ m
    return m


def _grid_quads(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Quads of the [-1, 1]^2 square cut nu x nv, counter-clockwise from +z, and their centre uv."""
    u = np.linspace(-1, 1, nu + 1)
    w = np.linspace(-1, 1, nv + 1)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    i, j = i.ravel(), j.ravel()
    q = np.stack([np.stack([u[i], w[j]], -1), np.stack([u[i + 1], w[j]], -1),
                  np.stack([u[i + 1], w[j + 1]], -1), np.stack([u[i], w[j + 1]], -1)], axis=1)
    uv = np.stack([(0.5 * (u[i] + u[i + 1]) + 1) / 2, (0.5 * (w[j] + w[j + 1]) + 1) / 2], -1)
    return q, uv


def _lift(q: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Square-local (..., 2) corners scaled by ``half`` and placed in the z = 0 plane."""
    return np.concatenate([q * half, np.zeros(q.shape[:-1] + (1,))], axis=-1)


def _cells(length: float, patch_size: float) -> int:
    return max(1, int(math.ceil(length / patch_size - 1e-9)))


def _cylinder_cells(shape, patch_size: float) -> tuple[int, int]:
    p0, p1 = np.asarray(shape.p0, float), np.asarray(shape.p1, float)
    length = float(np.linalg.norm(p1 - p0))
    return max(8, _cells(2 * math.pi * shape.radius, patch_size)), _cells(length, patch_size)


def _cylinder_facets(shape, patch_size: float):
    """Per facet around the tube: its ``n_along`` quads (n_along, 4, 3), counter-clockwise seen
    from outside, and the whole facet strip (4, 3)."""
    p0, p1 = np.asarray(shape.p0, float), np.asarray(shape.p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    if length < 1e-12:
        raise ValueError("cylinder: p0 and p1 coincide; give a cylinder of non-zero length")
    a = axis / length
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = e - (e @ a) * a
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    n_around, n_along = _cylinder_cells(shape, patch_size)
    phi = 2 * np.pi * np.arange(n_around + 1) / n_around
    ring = shape.radius * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
    t = np.linspace(0.0, 1.0, n_along + 1)[:, None] * axis
    for k in range(n_around):
        r0, r1 = ring[k], ring[k + 1]
        q = np.stack([p0 + r0 + t[:-1], p0 + r1 + t[:-1], p0 + r1 + t[1:], p0 + r0 + t[1:]], axis=1)
        strip = np.stack([p0 + r0, p0 + r1, p1 + r1, p1 + r0])
        yield q, strip


def _albedo_of(spec, i: int, shape, uv, n: int):
    mat = spec.material_of(shape)
    if mat.type != "diffuse":
        raise ValueError(f"shapes[{i}] ({shape.type}): material type {mat.type!r} is not supported by the radiosity "
                         "model; it needs diffuse materials (render with diffuse_only or change the material)")
    alb = mat.albedo
    if isinstance(alb, tuple):
        return np.broadcast_to(np.asarray(alb, float), (n, 3))
    if getattr(alb, "type", None) == "mondrian" and uv is not None:
        from pbrbench.scene.textures import texture_array

        tex = texture_array(alb, spec.data_root).astype(float)
        R, C = tex.shape[:2]
        rows = np.clip(((1.0 - uv[:, 1]) * R).astype(int), 0, R - 1)
        cols = np.clip((uv[:, 0] * C).astype(int), 0, C - 1)
        return tex[rows, cols]
    raise ValueError(f"shapes[{i}] ({shape.type}): a {getattr(alb, 'type', '?')!r} albedo texture is not supported by "
                     "the radiosity model on this shape; use a constant albedo (or a mondrian texture on a "
                     "rectangle or heightfield)")


def patches_from_spec(spec, *, patch_size: float = 0.1, heightfield_cells: int | None = None,
                      max_patches: int = 20000) -> Patches:
    """The patch mesh of a scene.

    Parameters
    ----------
    spec : SceneSpec
    patch_size : float
        Target side length of rectangle and box patches (world units); heightfields get
        ``ceil(2 half_width / patch_size)`` grid cells per side unless ``heightfield_cells`` is
        given.  Halving it quadruples the number of patches.
    heightfield_cells : int, optional
        Grid cells per side of every heightfield.
    max_patches : int
        Refuse meshes larger than this (the form-factor matrix is dense, N^2 doubles).

    Raises
    ------
    ValueError
        For a shape the model does not support (sphere, disk), a non-diffuse
        material, an unsupported texture, or too many patches.
    """
    check_positive(patch_size, "patch_size")
    max_patches = check_int(max_patches, "max_patches", 1)
    count = 0
    for shape in spec.shapes:  # refuse before building: meshes grow as 1 / patch_size^2
        if shape.type == "rectangle":
            count += _cells(shape.size[0], patch_size) * _cells(shape.size[1], patch_size)
        elif shape.type == "box":
            a, b, c = shape.size
            count += 2 * sum(_cells(u, patch_size) * _cells(v, patch_size) for u, v in ((a, b), (b, c), (c, a)))
        elif shape.type == "heightfield":
            count += 2 * (heightfield_cells or _cells(2 * shape.half_width, patch_size)) ** 2
        elif shape.type == "cylinder":
            n_around, n_along = _cylinder_cells(shape, patch_size)
            count += n_around * n_along
    if count > max_patches:
        raise ValueError(f"patch_size={patch_size}: gives {count} patches, more than max_patches={max_patches}; "
                         "use a larger patch_size (or raise max_patches: memory grows as N^2)")
    if heightfield_cells is not None:
        heightfield_cells = check_int(heightfield_cells, "heightfield_cells", 1, 4096)
    verts, nvs, rhos, oids, fids, gis = [], [], [], [], [], []
    occ_tris, occ_groups = [], []
    face = 0

    def add_quads(pts, rho, obj: int, fid: int) -> None:
        """Quadrilateral patches ``pts`` (N, 4, 3) of object ``obj`` on face ``fid``, albedo ``rho``."""
        verts.append(pts)
        nvs.append(np.full(len(pts), 4))
        rhos.append(rho)
        oids.append(np.full(len(pts), obj))
        fids.append(np.full(len(pts), fid))
        gis.append(np.full((len(pts), 2), -1))
    for i, shape in enumerate(spec.shapes):
        if shape.type not in SUPPORTED_SHAPES:
            raise ValueError(f"shapes[{i}] is a {shape.type!r}: the radiosity model supports "
                             f"{', '.join(SUPPORTED_SHAPES)} (a heightfield may use the 'spherical_cap' surface); "
                             "remove the shape or approximate it by a heightfield")
        R = _rotations(shape.rotate)
        if shape.type == "cylinder":
            if not isinstance(spec.material_of(shape).albedo, tuple):
                raise ValueError(f"shapes[{i}] (cylinder): textured cylinders are not supported by the radiosity model; "
                                 "use a constant albedo")
            for quads, strip in _cylinder_facets(shape, patch_size):
                pts = quads[:, ::-1] if shape.flip_normals else quads
                add_quads(pts, _albedo_of(spec, i, shape, None, len(pts)), i, face)
                full = strip[::-1] if shape.flip_normals else strip
                occ_tris.append(full[[[0, 1, 2], [0, 2, 3]]].reshape(2, 3, 3))
                occ_groups.append(np.full(2, face))
                face += 1
            continue
        if shape.type == "rectangle":
            sx, sy = shape.size
            q, uv = _grid_quads(_cells(sx, patch_size), _cells(sy, patch_size))
            half2 = np.array([sx / 2, sy / 2])
            faces = [(_lift(q, half2), uv, _lift(_grid_quads(1, 1)[0], half2))]
        elif shape.type == "box":
            if not isinstance(spec.material_of(shape).albedo, tuple):
                raise ValueError(f"shapes[{i}] (box): textured boxes are not supported by the radiosity model; "
                                 "use a constant albedo")
            faces = []
            half = np.asarray(shape.size, float) / 2
            for ax in range(3):
                t1, t2 = (ax + 1) % 3, (ax + 2) % 3  # (t1, t2, ax) is right-handed
                q, _ = _grid_quads(_cells(2 * half[t1], patch_size), _cells(2 * half[t2], patch_size))
                q1, _ = _grid_quads(1, 1)
                for sgn in (1.0, -1.0):
                    locs = []
                    for qq in (q, q1):
                        loc = np.zeros(qq.shape[:2] + (3,))
                        loc[..., t1], loc[..., t2], loc[..., ax] = qq[..., 0], qq[..., 1], sgn
                        locs.append((loc if sgn > 0 else loc[:, ::-1]) * half)
                    faces.append((locs[0], None, locs[1]))
        else:  # heightfield
            from pbrbench.scene.mitsuba_dict import heightfield_mesh

            cells = heightfield_cells or _cells(2 * shape.half_width, patch_size)
            coarse = shape.model_copy(update={"resolution": cells + 1})
            vtx, _, uvs, tri = heightfield_mesh(coarse, spec.data_root)
            n = cells + 1
            second = (tri[:, 1] - tri[:, 0]) == n - 1
            row = tri[:, 0] // n
            col = tri[:, 0] % n - second.astype(int)
            pts = vtx[tri] @ R.T
            if shape.flip_normals:
                pts = pts[:, ::-1]
            v4 = np.concatenate([pts, pts[:, 2:3]], axis=1)
            verts.append(v4)
            nvs.append(np.full(len(tri), 3))
            rhos.append(_albedo_of(spec, i, shape, uvs[tri].mean(axis=1), len(tri)))
            oids.append(np.full(len(tri), i))
            fids.append(np.full(len(tri), face))
            gis.append(np.stack([row, col], -1))
            occ_tris.append(pts)
            occ_groups.append(np.full(len(tri), face))
            face += 1
            continue
        c = np.asarray(shape.center, float)
        for loc, uv, full_loc in faces:
            pts = loc @ R.T + c
            if shape.flip_normals:
                pts = pts[:, ::-1]
            add_quads(pts, _albedo_of(spec, i, shape, uv, len(pts)), i, face)
            full = full_loc @ R.T + c
            if shape.flip_normals:
                full = full[:, ::-1]
            occ_tris.append(full[:, [[0, 1, 2], [0, 2, 3]]].reshape(2, 3, 3))
            occ_groups.append(np.full(2, face))
            face += 1
    from pbrbench.shading.irradiance import rectangle_polygon

    for light in list(spec.lights) + list(spec.light_set):
        if light.type == "area":
            p = rectangle_polygon(light.center, light.size, light.normal, light.up)
            occ_tris.append(np.stack([p[[0, 1, 2]], p[[0, 2, 3]]]))
            occ_groups.append(np.full(2, face))
            face += 1
    return Patches(np.concatenate(verts), np.concatenate(nvs), np.concatenate(rhos).astype(float),
                   np.concatenate(oids), np.concatenate(gis), np.concatenate(fids),
                   np.concatenate(occ_tris), np.concatenate(occ_groups))
