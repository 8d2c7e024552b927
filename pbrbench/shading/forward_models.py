"""Forward models of a scene's radiance: the local shading model and the radiosity model after k bounces.

Each model takes a :class:`~pbrbench.scene.spec.SceneSpec` and the ``(width, height)`` of the
image to predict and returns the radiance ``B / pi`` seen by each pixel (H, W, 3) of the scene's
camera (:func:`pbrbench.shading.radiosity_image.radiosity_image`, 3 x 3 points per pixel
averaged, as the renders' box filter averages the footprint).  All of them come
from one solution of the radiosity system (:mod:`pbrbench.shading.radiosity`)

.. math::  B = E + \\rho F B, \\qquad B^{(0)} = E, \\quad B^{(k+1)} = E + \\rho F B^{(k)},

by the Jacobi iteration, whose step ``k`` holds exactly the light interreflected at most ``k``
times: ``local`` is ``B^(0) = E`` (the direct light of every source, with shadows: the local
shading model), ``radiosity:k`` is ``B^(k)``, ``radiosity`` the converged ``B``.

The mesh (:func:`model_patches`): :func:`pbrbench.shading.patches.patches_from_spec` with patches
of side ``view_width / cells`` (``view_width`` the width the camera sees at its target, ``cells``
the model's option: 16 by default, fewer in a draft run through the quality profile), except that
a lone, unrotated ``spherical_cap`` heightfield is meshed as the inscribed ring mesh of
:func:`pbrbench.shading.concave_cap.spherical_cap_patches` (planar facets on the sphere: no area is
lost at the rim, as the masked grid loses it).  Visibility in the form factors is sampled by rays
unless no part of the scene can hide another (:func:`needs_visibility`: two planar faces, or a
cap on its own, where the visibility term is exactly 1); the direct term always casts shadow rays.

Each scene's solution is computed once per process and kept (memoised by the spec's content hash
and the patch size; at most :data:`MEMO_SIZE` scenes), so the models of one scene, and the
benchmark's rescoring of a job on the two half-sample renders, share it.

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
from pbrbench.shading.patches import Patches, make_patches, patches_from_spec

__all__ = [
    "SceneModel",
    "view_width",
    "needs_visibility",
    "model_patches",
    "scene_model",
    "predict_radiance",
    "MODELS",
    "MEMO_SIZE",
]

VERSION = "1"
MEMO_SIZE = 6
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


def model_patches(spec, patch_size: float) -> Patches:
    """The model's mesh of ``spec`` (see the module docstring) at patches of side ``patch_size``."""
    from pbrbench.shading.concave_cap import spherical_cap_patches

    caps = [i for i, s in enumerate(spec.shapes) if _cap_shape(s)]
    if not caps:
        return patches_from_spec(spec, patch_size=patch_size)
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


_MEMO: OrderedDict = OrderedDict()
_INDEX: OrderedDict = OrderedDict()


def _remember(store: OrderedDict, key, value):
    store[key] = value
    store.move_to_end(key)
    while len(store) > MEMO_SIZE:
        store.popitem(last=False)
    return value


def scene_model(spec, *, cells: int = DEFAULT_CELLS, area_samples: int = 4, max_bounces: int = 1000,
                tol: float = 1e-8) -> SceneModel:
    """The radiosity solution of ``spec`` at patches of side ``view_width(spec) / cells`` (memoised);
    ``area_samples`` x ``area_samples`` shadow-ray points on each patch and area light sample the
    lights' visibility (:func:`pbrbench.shading.radiosity.direct_radiosity`)."""
    from pbrbench.shading.form_factor_matrix import form_factor_matrix
    from pbrbench.shading.radiosity import direct_radiosity, solve_radiosity

    cells = check_int(cells, "cells", 1, 512)
    patch_size = view_width(spec) / cells
    key = (spec.content_hash(), round(patch_size, 12), int(area_samples), int(max_bounces), float(tol))
    if key in _MEMO:
        _MEMO.move_to_end(key)
        return _MEMO[key]
    t0 = time.process_time()
    patches = model_patches(spec, patch_size)
    vis = needs_visibility(spec)
    F = form_factor_matrix(patches, visibility=vis)
    E = direct_radiosity(spec, patches, shadows=True, area_samples=area_samples)
    sol = solve_radiosity(F, patches.albedo, E, method="jacobi", max_bounces=max_bounces, tol=tol)
    model = SceneModel(spec, patch_size, patches, E, sol.history, sol.converged, vis, time.process_time() - t0)
    return _remember(_MEMO, key, model)


def _index(spec, model: SceneModel, resolution) -> np.ndarray:
    from pbrbench.shading.radiosity_image import patch_index_image

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
    from pbrbench.shading.radiosity_image import radiosity_image

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
