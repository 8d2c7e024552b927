"""Forward models of a scene's radiance: the local shading model and the radiosity model after k bounces.

Each model takes a :class:`~pbrbench.scene.spec.SceneSpec` and the ``(width, height)`` of the
image to predict and returns the radiance ``B / pi`` seen by each pixel (H, W, 3) of the scene's
camera (:func:`pbrbench.radiosity.image.radiosity_image`, 3 x 3 points per pixel
averaged, as the renders' box filter averages the footprint).  All of them come
from one solution of the radiosity system (:mod:`pbrbench.radiosity.solver`)

.. math::  B = E + \\rho F B, \\qquad B^{(0)} = E, \\quad B^{(k+1)} = E + \\rho F B^{(k)},

by the Jacobi iteration, whose step ``k`` holds exactly the light interreflected at most ``k``
times: ``local`` is ``B^(0) = E`` (the direct light of every source, with shadows: the local
shading model), ``radiosity:k`` is ``B^(k)``, ``radiosity`` the converged ``B``.

The mesh (:func:`model_patches`): :func:`pbrbench.radiosity.patches.patches_from_spec` with patches
of side ``view_width / cells`` (``view_width`` the width the camera sees at its target, ``cells``
the model's option: 16 by default, fewer in a draft run through the quality profile), cut along the
outlines of the boxes and area lights that rest on a rectangle (:func:`conforming_cuts`), except that a lone,
unrotated ``spherical_cap`` heightfield is meshed as the inscribed ring mesh of
:func:`pbrbench.radiosity.concave_cap.spherical_cap_patches` (planar facets on the sphere: no area is
lost at the rim, as the masked grid loses it).  Visibility in the form factors is sampled by rays
unless no part of the scene can hide another (:func:`needs_visibility`: two planar faces, or a
cap on its own, where the visibility term is exactly 1); the direct term always casts shadow rays.

Each scene's solution is computed once per process and kept (memoised by the spec's content hash
and the patch size; at most :data:`MEMO_SIZE` scenes), so the models of one scene, and the
benchmark's rescoring of a job on its delete-one-group replicates, share it.  The form-factor
matrix, the costly part, is also kept on disk when a folder is set (:func:`set_disk_cache`; the
benchmark sets ``<render cache>/form_factors``), keyed by the scene's geometry (its canonical
description without the render settings: a re-seeded render shares it), the patch size and
:data:`VERSION`, so a second run, or a render seed, does not solve it again.

References
----------
C. M. Goral, K. E. Torrance, D. P. Greenberg and B. Battaile, "Modeling the interaction of light
between diffuse surfaces", SIGGRAPH 1984; D. A. Forsyth and A. Zisserman, "Reflections on
shading", IEEE PAMI 13(7), 1991 (the local model's failure in concave scenes).
"""

from __future__ import annotations

import functools
import math
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from pbrbench.checks import check_int
from pbrbench.memo import Memo
from pbrbench.radiosity.patches import Patches, make_patches, patches_from_spec

__all__ = [
    "SceneModel",
    "view_width",
    "needs_visibility",
    "model_patches",
    "conforming_cuts",
    "scene_model",
    "predict_radiance",
    "MODELS",
    "MEMO_SIZE",
    "set_disk_cache",
    "geometry_hash",
]

VERSION = "1"
FF_FORMAT = 2        # bump when the form factors of a mesh change (invalidates the disk cache); 2: keyed by the mesh
MEMO_SIZE = 6
MESH_MEMO_SIZE = 3   # form-factor matrices kept (dense: N^2 doubles each)
DEFAULT_CELLS = 16
DEFAULT_SUPERSAMPLE = 3


def view_width(spec) -> float:
    """Width of the scene the camera sees at its target: ``2 half_width`` (orthographic) or
    ``2 |target - origin| tan(fov / 2)`` (perspective)."""
    cam = spec.camera
    if cam.type == "orthographic":
        return 2.0 * float(cam.half_width)
    dist = float(np.linalg.norm(np.asarray(cam.target, float) - np.asarray(cam.origin, float)))
    return 2.0 * dist * math.tan(math.radians(cam.fov) / 2.0)


def _cap_shape(shape) -> bool:
    """A heightfield that is a whole spherical cap (rim inside the grid), unrotated and unscaled."""
    if shape.type != "heightfield" or shape.surface != "spherical_cap" or shape.rotate or shape.flip_normals:
        return False
    if shape.z_scale != 1.0:
        return False
    R = float(shape.params.get("radius", 1.0))
    a = math.radians(float(shape.params.get("half_angle_deg", 60.0)))
    c = shape.params.get("center", (0.0, 0.0))
    return R * math.sin(a) + max(abs(float(c[0])), abs(float(c[1]))) <= shape.half_width


def needs_visibility(spec) -> bool:
    """False when no surface of the scene can hide one patch from another: at most two planar
    convex faces (rectangles; a segment between two points of two planes crosses neither plane in
    between) and no other shape or area light, or one spherical cap on its own (the chord between
    two points of a sphere lies inside it)."""
    shapes = list(spec.shapes)
    area = [lt for lt in list(spec.lights) + list(spec.light_set) if lt.type == "area"]
    if len(shapes) == 1 and _cap_shape(shapes[0]) and not area:
        return False
    return not (all(s.type == "rectangle" for s in shapes) and len(shapes) + len(area) <= 2)


def _concat(parts: list[Patches]) -> Patches:
    """One mesh from several (face labels kept apart)."""
    if len(parts) == 1:
        return parts[0]
    v, nv, rho, oid, gi, fid, occ, grp = [], [], [], [], [], [], [], []
    off = 0
    for p in parts:
        v.append(p.vertices)
        nv.append(p.n_vertices)
        rho.append(p.albedo)
        oid.append(p.object_id)
        gi.append(p.grid_index)
        fid.append(p.face_id + off)
        occ.append(p.occluder_triangles)
        grp.append(p.occluder_groups + off)
        off = max(int(fid[-1].max(initial=-1)), int(grp[-1].max(initial=-1))) + 1
    return Patches(np.concatenate(v), np.concatenate(nv), np.concatenate(rho), np.concatenate(oid),
                   np.concatenate(gi), np.concatenate(fid), np.concatenate(occ), np.concatenate(grp))


def _area2(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _clip(P: np.ndarray, a, b, left: bool) -> np.ndarray:
    """The part of convex polygon ``P`` (M, 2) left (or right) of the directed line a -> b."""
    if len(P) == 0:
        return P
    d = np.asarray(b, float) - a
    side = d[0] * (P[:, 1] - a[1]) - d[1] * (P[:, 0] - a[0])
    side = side if left else -side
    out = []
    for k in range(len(P)):
        p, q, sp, sq = P[k], P[(k + 1) % len(P)], side[k], side[(k + 1) % len(P)]
        if sp >= 0:
            out.append(p)
        if (sp >= 0) != (sq >= 0):
            out.append(p + (q - p) * (sp / (sp - sq)))
    return np.asarray(out).reshape(-1, 2)


def _pieces(P: np.ndarray, F: np.ndarray, eps: float) -> list[np.ndarray]:
    """Convex pieces of ``P`` (counter-clockwise) none of which crosses the outline of the convex,
    counter-clockwise polygon ``F``: ``P`` outside each edge of ``F`` in turn, and what is left."""
    inside, out = P, []
    for k in range(len(F)):
        a, b = F[k], F[(k + 1) % len(F)]
        piece = _clip(inside, a, b, left=False)
        if len(piece) >= 3 and _area2(piece) > eps:
            out.append(piece)
        inside = _clip(inside, a, b, left=True)
        if len(inside) < 3 or _area2(inside) <= eps:
            return out
    return out + [inside] if out else [P]


def _box_faces(shape) -> list[tuple[np.ndarray, np.ndarray]]:
    """(corners (4, 3) counter-clockwise from outside, outward unit normal) of a box's six faces."""
    from pbrbench.radiosity.patches import rotation_matrix

    R = np.eye(3)
    for r in shape.rotate:
        R = rotation_matrix(r.axis, r.angle) @ R
    half, c = np.asarray(shape.size, float) / 2, np.asarray(shape.center, float)
    out = []
    for ax in range(3):
        t1, t2 = (ax + 1) % 3, (ax + 2) % 3
        for sgn in (1.0, -1.0):
            loc = np.zeros((4, 3))
            loc[:, t1], loc[:, t2], loc[:, ax] = [-1, 1, 1, -1], [-1, -1, 1, 1], sgn
            loc = loc if sgn > 0 else loc[::-1]
            pts = (loc * half) @ R.T + c
            nrm = np.cross(pts[1] - pts[0], pts[3] - pts[0])
            out.append((pts, nrm / np.linalg.norm(nrm)))
    return out


def conforming_cuts(spec, patches: Patches, patch_size: float) -> Patches:
    """Cut the patches of each rectangle along the outlines of what rests on it.

    A box face lying on a rectangle (coplanar, facing it) hides the part of the rectangle under
    it from the whole scene, and an area light parallel to a rectangle within ``patch_size`` in
    front of it (a ceiling light) hides the part behind it from everything but the thin gap; a
    patch that straddles such an outline is half hidden, half open, and its piecewise-constant
    radiosity and its visibility (one ray from its centroid to a distant patch) mix the two: a
    first-order error that refinement removes slowly (the face of a box next to the floor sees
    that floor patch at close range).  Patches of the rectangle that cross such an outline are
    cut along it into convex pieces (quadrilaterals, or a fan of triangles), so that none
    straddles it; the rectangles' occluders are unchanged.
    """
    from pbrbench.radiosity.patches import rotation_matrix
    from pbrbench.shading.irradiance import rectangle_polygon

    lights = [lt for lt in list(spec.lights) + list(spec.light_set) if lt.type == "area"]
    boxes = [s for s in spec.shapes if s.type == "box"]
    if not lights and not boxes:
        return patches
    keep = np.ones(len(patches), bool)
    new_v, new_n, new_k = [], [], []
    for i, shape in enumerate(spec.shapes):
        if shape.type != "rectangle":
            continue
        R = np.eye(3)
        for r in shape.rotate:
            R = rotation_matrix(r.axis, r.angle) @ R
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-9):  # a non-rigid rotation (unnormalised axis): skip
            continue
        ex, ey, n = R[:, 0], R[:, 1], R[:, 2]
        c = np.asarray(shape.center, float)
        facing = -n if shape.flip_normals else n
        scale = max(shape.size)
        feet = []
        for lt in lights:
            ln = np.asarray(lt.normal, float) / np.linalg.norm(lt.normal)
            gap = (np.asarray(lt.center, float) - c) @ facing
            if abs(abs(ln @ n) - 1) < 1e-6 and 0 <= gap < patch_size and ln @ facing > 0:
                feet.append(rectangle_polygon(lt.center, lt.size, lt.normal, lt.up))
        for b in boxes:
            for pts, nrm in _box_faces(b):
                if nrm @ facing < -1 + 1e-6 and abs((pts.mean(0) - c) @ n) < 1e-6 * scale:
                    feet.append(pts)
        if not feet:
            continue
        feet2 = []
        for F in feet:
            f2 = np.stack([(F - c) @ ex, (F - c) @ ey], -1)
            feet2.append(f2 if _area2(f2) > 0 else f2[::-1])
        for k in np.flatnonzero(patches.object_id == i):
            q = patches.vertices[k][: patches.n_vertices[k]]
            P = np.stack([(q - c) @ ex, (q - c) @ ey], -1)
            P = P if _area2(P) > 0 else P[::-1]
            eps = 1e-9 * abs(_area2(P))
            pieces = [P]
            for F in feet2:
                pieces = [g for piece in pieces for g in _pieces(piece, F, eps)]
            if len(pieces) == 1:
                continue
            keep[k] = False
            w = (q[0] - c) @ n
            for g in pieces:
                polys = [g] if len(g) <= 4 else [g[[0, m, m + 1]] for m in range(1, len(g) - 1)]
                for h in polys:
                    v3 = c + h[:, :1] * ex + h[:, 1:] * ey + w * n
                    if np.cross(v3[1] - v3[0], v3[2] - v3[0]) @ patches.normals[k] < 0:
                        v3 = v3[::-1]
                    if len(v3) == 3:
                        v3 = np.concatenate([v3, v3[2:3]])
                    new_v.append(v3)
                    new_n.append(3 if np.allclose(v3[3], v3[2]) else 4)
                    new_k.append(k)
    if not new_v:
        return patches
    idx = np.concatenate([np.flatnonzero(keep), np.asarray(new_k, int)])
    v = np.concatenate([patches.vertices[keep], np.asarray(new_v)])
    return Patches(v, np.concatenate([patches.n_vertices[keep], np.asarray(new_n)]), patches.albedo[idx],
                   patches.object_id[idx], np.full((len(v), 2), -1), patches.face_id[idx],
                   patches.occluder_triangles, patches.occluder_groups)


def model_patches(spec, patch_size: float) -> Patches:
    """The model's mesh of ``spec`` (see the module docstring) at patches of side ``patch_size``."""
    from pbrbench.radiosity.concave_cap import spherical_cap_patches

    caps = [i for i, s in enumerate(spec.shapes) if _cap_shape(s)]
    if not caps:
        return conforming_cuts(spec, patches_from_spec(spec, patch_size=patch_size), patch_size)
    rest = [s for i, s in enumerate(spec.shapes) if i not in caps]
    parts = []
    if rest:
        sub = spec.model_copy(update={"shapes": tuple(rest) if isinstance(spec.shapes, tuple) else rest})
        p = patches_from_spec(sub, patch_size=patch_size)
        keep = [i for i in range(len(spec.shapes)) if i not in caps]
        parts.append(Patches(p.vertices, p.n_vertices, p.albedo, np.asarray(keep)[p.object_id], p.grid_index,
                             p.face_id, p.occluder_triangles, p.occluder_groups))
    lights = [lt for lt in list(spec.lights) + list(spec.light_set) if lt.type == "area"]
    extra = None
    if lights and not rest:  # area lights occlude (patches_from_spec adds them to the other shapes)
        from pbrbench.shading.irradiance import rectangle_polygon

        polys = [rectangle_polygon(lt.center, lt.size, lt.normal, lt.up) for lt in lights]
        extra = np.concatenate([np.stack([p[[0, 1, 2]], p[[0, 2, 3]]]) for p in polys])
    for i in caps:
        s = spec.shapes[i]
        R = float(s.params.get("radius", 1.0))
        alpha = float(s.params.get("half_angle_deg", 60.0))
        c = s.params.get("center", (0.0, 0.0))
        alb = spec.material_of(s).albedo
        if spec.material_of(s).type != "diffuse" or not isinstance(alb, tuple):
            return patches_from_spec(spec, patch_size=patch_size)  # the generic path says what it refuses
        rings = max(2, int(math.ceil(R * math.radians(alpha) / patch_size - 1e-9)))
        cap = spherical_cap_patches(R, alpha, n_rings=rings, center=(float(c[0]), float(c[1])), albedo=alb)
        shift = np.asarray(s.center, float)
        parts.append(make_patches(cap.vertices + shift, cap.albedo, object_id=i, face_id=np.zeros(len(cap), int),
                                  extra_occluders=extra))
        extra = None
    return _concat(parts)


@dataclass(frozen=True)
class SceneModel:
    """One scene's radiosity solution: the mesh, the direct term ``E`` and ``B`` after each bounce
    (``history[0] = E``; the last entry is the converged ``B``)."""

    spec: object
    patch_size: float
    patches: Patches
    E: np.ndarray
    history: np.ndarray
    converged: bool
    visibility: bool
    seconds: float

    @property
    def B(self) -> np.ndarray:
        return self.history[-1]

    def bounce(self, k: int | None) -> np.ndarray:
        """``B`` after ``k`` bounces (None: converged; ``k`` beyond the iterations: converged)."""
        if k is None:
            return self.B
        return self.history[min(int(k), len(self.history) - 1)]


_MEMO = Memo("radiosity scene models", MEMO_SIZE)
_MESH = Memo("radiosity meshes and form factors", MESH_MEMO_SIZE)   # (mesh, F, visibility) by (geometry hash, patch size)
_FF = Memo("radiosity form factors", MESH_MEMO_SIZE)                # F by (mesh hash, patch size)
_DISK: dict = {"dir": None}


def set_disk_cache(directory) -> None:
    """Keep form-factor matrices in ``directory`` (None: only in memory)."""
    from pathlib import Path

    _DISK["dir"] = Path(directory) if directory is not None else None


def geometry_hash(spec) -> str:
    """sha256 of what the mesh and its form factors depend on: the scene without its render
    settings (resolution, samples, seed), plus the bytes of the files it reads."""
    import hashlib
    import json

    d = spec.canonical()
    d.pop("render", None)
    h = hashlib.sha256(json.dumps(d, sort_keys=True, separators=(",", ":"), default=str).encode())
    for p in spec.referenced_files():
        with open(p, "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def mesh_hash(patches: Patches, visibility: bool) -> str:
    """sha256 of what a form-factor matrix depends on: the patches' geometry and labels and the
    occluders (area lights included), not their albedo; scenes that differ only in their
    materials or light strengths (an albedo sweep, the black and the white room) share it."""
    import hashlib

    h = hashlib.sha256(b"visibility" if visibility else b"no visibility")
    for a in (patches.vertices, patches.n_vertices, patches.object_id, patches.grid_index, patches.face_id,
              patches.occluder_triangles, patches.occluder_groups):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _disk_path(key: str, patch_size: float):
    d = _DISK["dir"]
    if d is None:
        return None
    return d / f"{key[:32]}-{patch_size:.9g}-v{VERSION}.{FF_FORMAT}.npz"


def _load_form_factors(path, n: int):
    """(F, visibility) from ``path``, or None when absent, unreadable or for another mesh size."""
    if path is None or not path.is_file():
        return None
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as z:
            F, vis = z["F"], bool(z["visibility"])
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None     # truncated or foreign: solved again
    return (F, vis) if F.shape == (n, n) else None


def _save_form_factors(path, F, vis: bool) -> None:
    """Write atomically; a full or read-only disk only costs the cache (never the run)."""
    from pbrbench.io import atomic_path

    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, F=F, visibility=np.bool_(vis))
    except OSError:
        pass


_INDEX: OrderedDict = OrderedDict()


def _remember(store: Memo, key, value, size: int | None = None):
    store[key] = value
    return value


def scene_model(spec, *, cells: int = DEFAULT_CELLS, area_samples: int = 4, max_bounces: int = 1000,
                tol: float = 1e-8) -> SceneModel:
    """The radiosity solution of ``spec`` at patches of side ``view_width(spec) / cells`` (memoised);
    ``area_samples`` x ``area_samples`` shadow-ray points on each patch and area light sample the
    lights' visibility (:func:`pbrbench.radiosity.solver.direct_radiosity`)."""
    from pbrbench.radiosity.form_factor_matrix import form_factor_matrix
    from pbrbench.radiosity.solver import direct_radiosity, solve_radiosity

    cells = check_int(cells, "cells", 1, 512)
    patch_size = view_width(spec) / cells
    key = (spec.content_hash(), round(patch_size, 12), int(area_samples), int(max_bounces), float(tol))
    if key in _MEMO:
        return _MEMO[key]
    t0 = time.process_time()
    mkey = (geometry_hash(spec), key[1])   # the mesh and its form factors depend on neither the lights' sampling nor the render
    if mkey in _MESH:
        patches, F, vis = _MESH[mkey]
    else:
        patches = model_patches(spec, patch_size)
        vis = needs_visibility(spec)
        fkey = (mesh_hash(patches, vis), key[1])   # the form factors: shared by scenes of one mesh
        if fkey in _FF:
            F = _FF[fkey]
        else:
            path = _disk_path(fkey[0], patch_size)
            got = _load_form_factors(path, len(patches))
            if got is not None and got[1] == vis:
                F = got[0]
            else:
                F = form_factor_matrix(patches, visibility=vis)
                _save_form_factors(path, F, vis)
            _remember(_FF, fkey, F, size=MESH_MEMO_SIZE)
        _remember(_MESH, mkey, (patches, F, vis), size=MESH_MEMO_SIZE)
    E = direct_radiosity(spec, patches, shadows=True, area_samples=area_samples)
    sol = solve_radiosity(F, patches.albedo, E, method="jacobi", max_bounces=max_bounces, tol=tol)
    model = SceneModel(spec, patch_size, patches, E, sol.history, sol.converged, vis, time.process_time() - t0)
    return _remember(_MEMO, key, model)


def _index(spec, model: SceneModel, resolution) -> np.ndarray:
    from pbrbench.radiosity.image import patch_index_image

    key = (spec.content_hash(), round(model.patch_size, 12), tuple(resolution))
    if key not in _INDEX:
        _remember(_INDEX, key, patch_index_image(spec, model.patches, tuple(resolution)))
    return _INDEX[key]


def predict_radiance(spec, resolution, *, bounces: int | None = None, cells: int = DEFAULT_CELLS,
                     supersample: int = DEFAULT_SUPERSAMPLE, area_samples: int = 4) -> np.ndarray:
    """Radiance (H, W, 3) of ``spec`` at ``resolution = (width, height)`` after ``bounces``
    interreflections (0: the local model; None: converged), from :func:`scene_model`; each pixel
    the mean of ``supersample`` x ``supersample`` points of its footprint (as the renders' box
    filter); ``area_samples`` as in :func:`scene_model`."""
    from pbrbench.radiosity.image import radiosity_image

    try:
        w, h = (int(resolution), int(resolution)) if np.isscalar(resolution) else (int(resolution[0]), int(resolution[1]))
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"resolution: expected (width, height), got {resolution!r}") from None
    if w < 1 or h < 1:
        raise ValueError(f"resolution: expected positive (width, height), got {resolution!r}")
    if bounces is not None:
        bounces = check_int(bounces, "bounces", 0)
    supersample = check_int(supersample, "supersample", 1, 16)
    model = scene_model(spec, cells=cells, area_samples=area_samples)
    idx = _index(spec, model, (w * supersample, h * supersample))
    return radiosity_image(spec, model.patches, model.bounce(bounces), resolution=(w, h), index=idx,
                           supersample=supersample)


MODELS = {
    "local": functools.partial(predict_radiance, bounces=0),
    "radiosity:1": functools.partial(predict_radiance, bounces=1),
    "radiosity:2": functools.partial(predict_radiance, bounces=2),
    "radiosity:4": functools.partial(predict_radiance, bounces=4),
    "radiosity": functools.partial(predict_radiance, bounces=None),
}
