"""Interreflection checks of ``pbrbench validate``: the radiosity model and the closed forms against the path tracer.

Registered in :data:`pbrbench.render.proofs.CHECKS`; each returns records
``{"check", "measured", "bound", "passed", "detail"}`` and adds its figures (plot dicts in the
format of :class:`pbrbench.tasks.base.JobResult` plots) to ``figures`` when it is given.

* ``radiosity_groove``: the right-angled groove of ``groove_reflex_parallel`` and
  ``groove_reflex_bisector`` (and grooves of other angles, :func:`groove_spec`) for each albedo of
  the sweep: the rendered radiance across the groove against the radiosity solution of the same
  geometry (:func:`pbrbench.radiosity.groove_profile.groove_patches`, exact form factors without
  visibility -- nothing in a V hides anything -- and the direct term with shadow rays).
* ``radiosity_room``: ``room_black`` and ``room_white`` (perspective camera) against the model of
  :func:`pbrbench.radiosity.forward_models.scene_model` (visibility sampled by rays).
* ``radiosity_cap`` (:mod:`pbrbench.render.proofs.cap`): concave spherical caps (``ps_cap`` and other half-angles,
  :func:`cap_spec`): the render against the closed form ``B = rho E0 (N + beta a) . S``, the ring
  mesh's solution against it, and photometric stereo on the rendered per-light radiance against the
  closed-form bias (normals ``(N + beta a) / |N + beta a|``, albedo ``rho |N + beta a|``).
* ``gain_curve`` (:mod:`pbrbench.render.proofs.gain`): the kernel integral of :mod:`pbrbench.shading.gain_curve` against Mitsuba's
  irradiance meter above a plane of sinusoidal radiance (chapter Fig 1.19).

How render and model are compared (groove and room): pixels are grouped into *cells* (the strips
across the groove at the level compared; in the room the patches of a mesh coarser than the
model's), each pixel assigned to the patch its centre sees, every pixel whose footprint lies on
patches (:func:`_pixel_selection`); the model images average 4 x 4 points per pixel, as the
renders' box filter averages the footprint, so pixels across an edge are the same mixtures in
both and each cell's pixels sample the patch uniformly (no pixel is left out: leaving out the
pixels along an edge, as the ground truth's pure mask does, biases a cell's mean where the
radiance varies across it, e.g. a wall next to the light's plane).
Per cell, the render's mean ``r``, its Monte Carlo standard error ``s`` (from ``delta``, the per-pixel
half-difference of the two half-sample renders: :class:`Cells`) and the mean ``m_L`` of
the model image at mesh level ``L`` are formed; the discretisation error of level ``L`` is
estimated by ``d = |m_L - m_{L-1}|`` (the error of a first-order method whose patches halve from
one level to the next; better methods have less) plus ``|m_L - m'_L|``, ``m'_L`` the same level
sampled at 3 x 3 instead of 4 x 4 points per pixel (the footprint's sampling at edges) and, in the
rooms, plus ``|m_L - m''_L|`` with ``m''_L`` the same level with one more shadow-ray point per side
on the patches and the light (the penumbrae's sampling; not nested, so the two samplings' errors
differ).
Levels are refined until ``d <= 2 %`` of the peak and the difference beyond the noise,
``(|r - m_L| - z s)_+``, is ``<= 2 %`` of the peak, or the finest level is reached.  Two records per
case: ``max |r - m| / (z s + d + 0.003 peak) <= 1`` (agreement within the stated noise plus
discretisation, above a floor of 0.3 % of the peak that the comparison does not resolve: the form
factors are computed to about 1e-3 and the direct light of a dim face seen at a grazing angle
differs from the renderer's by about 1e-3 of the peak;
``z`` the two-sided normal quantile at a family-wise 1 % over the case's cells, Bonferroni) and
``max (|r - m| - z s)_+ / peak <= 0.02``.

The Woodham photometric stereo of the cap check is passed in (``photometric_stereo=``, by
``pbrbench validate``: the render layer does not import :mod:`pbrbench.infer`).

References
----------
C. M. Goral et al., "Modeling the interaction of light between diffuse surfaces", SIGGRAPH 1984;
D. A. Forsyth and A. Zisserman, "Reflections on shading", IEEE PAMI 13(7), 1991; R. J. Woodham,
"Photometric method for determining surface orientation from multiple images", Optical
Engineering 19(1), 1980; J. J. Koenderink and A. J. van Doorn, "Geometrical modes as a general
method to treat diffuse interreflections in radiometry", JOSA 73(6), 1983.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pbrbench.quality import Quality, require
from pbrbench.render.proofs.common import Record, ground_truth_of, record
from pbrbench.scene.spec import SceneSpec

__all__ = ["check_groove", "check_room", "groove_spec", "cap_spec", "groove_geometry", "groove_case", "room_case",
           "refine", "Cells", "Comparison"]

ALPHA = 0.01          # family-wise level of the agreement records
MAX_EXCESS = 0.02     # the difference beyond the noise, and the discretisation estimate, as a fraction of the peak
FLOOR = 0.003         # differences below this fraction of the peak are not resolved (the model's quadrature)
MIN_PIXELS = 4        # cells with fewer pixels are not compared
SUPERSAMPLE = 4       # model images: 4 x 4 points per pixel


# --------------------------------------------------------------------------- scenes
def _library(family: str) -> list[SceneSpec]:
    from pbrbench.scene.load import load_scene_file
    from pbrbench.settings import LIBRARY_DIR

    return load_scene_file(LIBRARY_DIR / f"{family}.toml")


def _edit(spec: SceneSpec, name: str, **changes) -> SceneSpec:
    d = spec.model_dump(mode="json", exclude={"base_dir", "source", "sweep"})
    d.update(changes)
    d["name"] = name
    return SceneSpec.model_validate(d)


def groove_spec(opening_deg: float = 90.0, rho: float = 0.5, source: str = "parallel", *,
                resolution=(128, 64), spp: int = 288) -> SceneSpec:
    """A V groove like ``groove_reflex_*`` with another opening angle, albedo and source.

    Faces of width ``1.1 / sin(opening / 2)`` (each reaches ``|x| = 1.1``, beyond the film's
    ``|x| <= 1``), 4 long in y, crease along the y axis at the origin; ``source`` is
    ``"parallel"`` (along the left face) or ``"bisector"`` (along +z).
    """
    half = math.radians(float(opening_deg)) / 2
    w = 1.1 / math.sin(half)
    theta = 90.0 - float(opening_deg) / 2
    cx, cz = (w / 2) * math.sin(half), (w / 2) * math.cos(half)
    base = _library("groove_reflex_parallel")[0]
    S = [-math.sin(half), 0.0, math.cos(half)] if source == "parallel" else [0.0, 0.0, 1.0]
    shapes = [{"name": "left_face", "type": "rectangle", "center": [-cx, 0.0, cz], "size": [w, 4.0], "material": "paint",
               "rotate": [{"axis": [0.0, 1.0, 0.0], "angle": theta}]},
              {"name": "right_face", "type": "rectangle", "center": [cx, 0.0, cz], "size": [w, 4.0], "material": "paint",
               "rotate": [{"axis": [0.0, 1.0, 0.0], "angle": -theta}]}]
    return _edit(base, f"validate_groove[opening={opening_deg:g},albedo={rho:g},source={source}]",
                 shapes=shapes, materials={"paint": {"type": "diffuse", "albedo": float(rho)}},
                 lights=[{"type": "directional", "direction": S, "irradiance": 3.14159}],
                 render={"resolution": list(resolution), "spp": int(spp), "max_depth": -1})


def groove_geometry(spec: SceneSpec) -> tuple[float, float, float]:
    """(opening angle in degrees, face width, length) of a groove spec made like the library's:
    two rectangles rotated by +-theta about y meeting at the y axis; ValueError otherwise."""
    rects = [s for s in spec.shapes if s.type == "rectangle"]
    if len(rects) != 2 or len(spec.shapes) != 2 or any(len(r.rotate) != 1 for r in rects):
        raise ValueError(f"{spec.name}: not a groove of two rotated rectangles")
    left = min(rects, key=lambda r: r.center[0])
    theta = float(left.rotate[0].angle)
    if tuple(left.rotate[0].axis) != (0.0, 1.0, 0.0):
        raise ValueError(f"{spec.name}: the groove's faces must be rotated about the y axis")
    w, length = float(left.size[0]), float(left.size[1])
    half = math.radians(90.0 - theta)
    want = np.array([-(w / 2) * math.sin(half), 0.0, (w / 2) * math.cos(half)])
    if not np.allclose(left.center, want, atol=1e-4):
        raise ValueError(f"{spec.name}: the faces do not meet at the y axis (left centre {left.center}, expected {want})")
    return 180.0 - 2.0 * theta, w, length


def cap_spec(rho: float = 0.5, half_angle_deg: float = 60.0, *, source_angle_deg: float | None = None,
             resolution: int = 128, spp: int = 72) -> SceneSpec:
    """The ``ps_cap`` scene with another albedo and half-angle; its six sources lie
    ``source_angle_deg`` from the axis (default ``min(25, 0.8 (90 - alpha))``: no shadows), and
    the grid and film cover the rim with a 4 % margin."""
    base = _library("ps_cap")[0]
    a = float(half_angle_deg)
    g = math.radians(min(25.0, 0.8 * (90.0 - a)) if source_angle_deg is None else float(source_angle_deg))
    hw = max(0.9, round(1.04 * math.sin(math.radians(a)), 3))
    d = base.model_dump(mode="json", exclude={"base_dir", "source", "sweep"})
    shape = dict(d["shapes"][0], half_width=hw, params={"radius": 1.0, "half_angle_deg": a})
    lights = [{"type": "directional", "irradiance": 3.14159,
               "direction": [math.sin(g) * math.cos(k * math.pi / 3), math.sin(g) * math.sin(k * math.pi / 3), math.cos(g)]}
              for k in range(6)]
    cam = dict(d["camera"], half_width=hw)
    return _edit(base, f"validate_cap[albedo={rho:g},alpha={a:g}]", shapes=[shape], light_set=lights, camera=cam,
                 materials={"paint": {"type": "diffuse", "albedo": float(rho)}},
                 render={"resolution": int(resolution), "spp": int(spp), "max_depth": -1})


# --------------------------------------------------------------------------- cells and refinement
def _grey(a) -> np.ndarray:
    a = np.asarray(a, np.float64)
    return a.mean(axis=-1) if a.ndim == 3 else a


def _z(m: int, alpha: float = ALPHA) -> float:
    from scipy.stats import norm

    return float(norm.isf(alpha / (2 * max(int(m), 1))))


def _film_coordinates(spec, pts: np.ndarray) -> np.ndarray:
    """(..., 2) film coordinates of world points: world units (orthographic) or tan of the angle
    from the view axis (perspective), x right, y up (as :func:`pbrbench.shading.surfaces.pixel_grid`)."""
    cam = spec.camera
    o = np.asarray(cam.origin, float)
    d = np.asarray(cam.target, float) - o
    d /= np.linalg.norm(d)
    right = np.cross(d, np.asarray(cam.up, float))
    right /= np.linalg.norm(right)
    up = np.cross(right, d)
    rel = pts - o
    xy = np.stack([rel @ right, rel @ up], -1)
    return xy if cam.type == "orthographic" else xy / np.maximum(rel @ d, 1e-12)[..., None]


def _pixel_selection(spec, patches, W: int, H: int, *, whole: bool = True) -> np.ndarray:
    """Pixels whose footprint (the model's 4 x 4 sub-samples), and their neighbours', lie wholly on
    patches that the camera sees whole: not partly on a light or the background (a pixel beside a
    bright area light is mostly its light), and not on a patch partly hidden or cut by the film's edge -- the visible
    part of such a patch is no uniform sample of it (a floor patch half behind a box is half in
    its shadow), so the patch's mean, which the model computes, is not what its pixels show.
    A patch counts as seen whole when its sub-samples cover >= 95 % of its projected area
    (``whole=False``: no such test, for the strips across a groove, which run beyond the film and
    which nothing hides)."""
    from pbrbench.radiosity.image import patch_index_image

    S = SUPERSAMPLE
    fine = patch_index_image(spec, patches, (W * S, H * S))
    cam = spec.camera
    ext = cam.half_width if cam.type == "orthographic" else float(np.tan(np.radians(cam.fov) / 2))
    sub = 2.0 * ext / (W * S)
    v = _film_coordinates(spec, patches.vertices)
    x, y = v[..., 0], v[..., 1]
    proj = 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)) / sub ** 2
    seen = np.bincount(fine[fine >= 0], minlength=len(patches))
    seen_whole = (seen >= 0.95 * proj) if whole else np.ones(len(patches), bool)
    ok = (fine >= 0) & seen_whole[np.maximum(fine, 0)]
    ok = np.all(ok.reshape(H, S, W, S), axis=(1, 3))
    # and not next to such a pixel: a sliver of a bright light at the edge of a footprint, which no
    # sub-sample hits, can still outweigh the rest of the pixel
    from scipy.ndimage import binary_erosion

    return binary_erosion(ok, structure=np.ones((3, 3), bool), border_value=1)


def _faces(patches, idx: np.ndarray) -> np.ndarray:
    """The planar face seen at each pixel of a patch index image (-1 where no patch is seen)."""
    return np.where(idx >= 0, patches.face_id[np.maximum(idx, 0)], -1)


@dataclass
class Cells:
    """Pixel groups: ``ids`` (H, W) cell of each pixel (-1: none; only ``pure`` pixels), the
    render's means and standard errors per cell, and which cells have enough pixels.

    The standard error of a cell's mean is ``sqrt(max(sum delta^2, sum v)) / n`` with ``v`` the
    mean ``delta^2`` over the pixel's face (``faces``; the whole image without): the cell's own
    sum is unbiased but, from a few pixels of a render with few samples (where most half-sample
    differences are exactly 0), often far too small; the face's pooled variance is not.
    """

    ids: np.ndarray
    count: np.ndarray
    render: np.ndarray
    se: np.ndarray

    @classmethod
    def of(cls, ids, pure, render, delta, n: int | None = None, faces=None) -> Cells:
        faces = np.zeros(np.shape(ids), int) if faces is None else np.asarray(faces)
        ids = np.where(np.asarray(pure, bool) & (ids >= 0), ids, -1)
        n = int(ids.max()) + 1 if n is None else n
        sel = ids >= 0
        cnt = np.bincount(ids[sel], minlength=n).astype(float)
        safe = np.maximum(cnt, 1)
        r = np.bincount(ids[sel], _grey(render)[sel], minlength=n) / safe
        d2 = _grey(delta)[sel] ** 2
        fl = faces[sel]
        _, inv = np.unique(fl, return_inverse=True)
        pooled = (np.bincount(inv, d2) / np.bincount(inv))[inv]
        se = np.sqrt(np.maximum(np.bincount(ids[sel], d2, minlength=n), np.bincount(ids[sel], pooled, minlength=n))) / safe
        return cls(ids, cnt, r, se)

    @property
    def used(self) -> np.ndarray:
        return self.count >= MIN_PIXELS

    def mean(self, image) -> np.ndarray:
        sel = self.ids >= 0
        return np.bincount(self.ids[sel], _grey(image)[sel], minlength=len(self.count)) / np.maximum(self.count, 1)


@dataclass
class Comparison:
    """The render against the model on the cells of the final level: model means, the
    discretisation estimate ``d`` per cell, the quantile ``z``, the peak and ``|render - model|``."""

    cells: Cells
    level: object          # the final mesh level
    levels: list
    model: np.ndarray      # cell means of the final level's image
    d: np.ndarray          # discretisation estimate per cell
    z: float
    peak: float
    diff: np.ndarray

    def agreement(self) -> float:
        u = self.cells.used
        return float(np.max(self.diff[u] / (self.z * self.cells.se[u] + self.d[u] + FLOOR * self.peak + 1e-300)))

    def excess(self) -> float:
        u = self.cells.used
        return float(np.max(np.maximum(self.diff[u] - self.z * self.cells.se[u], 0.0)) / self.peak)


def refine(cells_at, model_at, levels) -> Comparison:
    """Compare the render with ``model_at(level)`` (an image, or the image and alternates: the same
    level sampled otherwise) for ``levels`` in order, on the cells ``cells_at(level)``; ``d`` is
    how far the previous level's image is from the level's over the same pixels -- the error
    estimate of a first-order method whose patches halve -- plus how far each alternate is (the
    footprint's sampling, the lights' visibility sampling),
    until the discretisation estimate and the difference beyond the noise are both within 2 % of
    the peak, or the levels run out (at least two levels; see the module docstring)."""
    prev, done, cmp = None, [], None
    for lev in levels:
        img = model_at(lev)
        img, *alternates = img if isinstance(img, tuple) else (img,)
        done.append(lev)
        if prev is not None:
            cells = cells_at(lev)
            u = cells.used
            z = _z(int(u.sum()))
            peak = max(float(np.max(cells.render[u])) if u.any() else 0.0, 1e-30)   # a black scene: every ratio 0
            m = cells.mean(img)
            d = np.abs(m - cells.mean(prev))
            for alt in alternates:   # the same level sampled otherwise (footprint, the lights' visibility)
                d = d + np.abs(m - cells.mean(alt))
            cmp = Comparison(cells, lev, list(done), m, d, z, peak, np.abs(cells.render - m))
            if np.max(cmp.d[u], initial=0.0) <= MAX_EXCESS * peak and cmp.excess() <= MAX_EXCESS:
                return cmp
        prev = img
    if cmp is None:
        raise ValueError("refine: give at least two levels")
    return cmp


def _level(x) -> str:
    return "/".join(str(v) for v in x) if isinstance(x, tuple) else str(x)


def _records(name: str, c: Comparison, what: str, cells_are: str = "the patches of the final level") -> list[Record]:
    cells = c.cells
    u = cells.used
    noise = float(np.max(c.z * cells.se[u], initial=0.0) / c.peak)
    disc = float(np.max(c.d[u], initial=0.0) / c.peak)
    where = int(np.argmax(np.where(u, c.diff, -1)))
    tail = (f"{int(u.sum())} cells of >= {MIN_PIXELS} pixels ({int(cells.count[u].sum())} pixels; {cells_are}); noise z*se <= {100 * noise:.2f} % of the peak (z = {c.z:.2f}), discretisation "
            f"d <= {100 * disc:.2f} % of the peak (levels {', '.join(_level(x) for x in c.levels)}: {what}); largest "
            f"|render - model| {100 * c.diff[where] / c.peak:.2f} % of the peak {c.peak:.4g}")
    return [record(name, c.agreement(), 1.0, f"max |render - model| / (z se + d + {FLOOR:g} peak) over the cells; " + tail),
            record(f"{name}:peak", c.excess(), MAX_EXCESS,
                 "max (|render - model| - z se)_+ / peak (the difference beyond the noise, after refinement); " + tail)]


# --------------------------------------------------------------------------- the groove
GROOVE_LEVELS = (4, 8, 16, 32)   # strips per face (up to W / 4: strips about 2 pixels wide)


def groove_case(spec: SceneSpec, quality: Quality, cache) -> dict:
    """Render and model of one groove: the comparison on strips across the groove (each strip
    the whole visible length of the groove), the local model and the strips' centres."""
    from pbrbench.radiosity.form_factor_matrix import form_factor_matrix
    from pbrbench.radiosity.groove_profile import groove_patches, groove_segments
    from pbrbench.radiosity.image import patch_index_image, radiosity_image
    from pbrbench.radiosity.solver import direct_radiosity, solve_radiosity

    opening, w, length = groove_geometry(spec)
    gt = ground_truth_of(spec, quality, cache)
    H, W = gt["radiance"].shape[:2]
    local = {}

    def cells_at(n):
        strips, _, _ = groove_patches(n, 1, length=length, opening_deg=opening, width=w)
        idx = patch_index_image(spec, strips, (W, H))
        return Cells.of(idx, _pixel_selection(spec, strips, W, H, whole=False), gt["radiance"], gt.sd_of("radiance", _grey), 2 * n,
                        faces=_faces(strips, idx))

    def model_at(n):
        ds = w / n
        n_along = max(1, int(round(length / (4 * ds))))
        p, _, _ = groove_patches(n, n_along + 1 - n_along % 2, length=length, opening_deg=opening, width=w,
                                 albedo=spec.material_of(spec.shapes[0]).albedo)
        E = direct_radiosity(spec, p)
        B = solve_radiosity(form_factor_matrix(p, visibility=False), p.albedo, E, method="direct").B
        local[n] = radiosity_image(spec, p, E, resolution=(W, H), supersample=SUPERSAMPLE)
        return (radiosity_image(spec, p, B, resolution=(W, H), supersample=SUPERSAMPLE),
                radiosity_image(spec, p, B, resolution=(W, H), supersample=SUPERSAMPLE - 1))

    cmp = refine(cells_at, model_at, [n for n in GROOVE_LEVELS if n <= max(8, W // 4)])
    segs, _, _ = groove_segments(cmp.level, opening_deg=opening, width=w)
    return {"spec": spec, "cells": cmp.cells, "cmp": cmp, "x": 0.5 * (segs[:, 0, 0] + segs[:, 1, 0]),
            "local": cmp.cells.mean(local[cmp.level]), "rho": float(np.mean(spec.material_of(spec.shapes[0]).albedo))}


def check_groove(quality: Quality, cache, *, figures=None, specs=None) -> list[Record]:
    """``radiosity_groove``: every albedo of both library grooves (the sweep cut by the quality
    profile), or the grooves ``specs`` (e.g. :func:`groove_spec` of other angles)."""
    q = require(quality)
    if specs is None:
        fams = {f: q.keep(_library(f)) for f in ("groove_reflex_parallel", "groove_reflex_bisector")}
    else:
        fams = {"groove": list(specs)}
    out = []
    for fam, group in fams.items():
        cases = [groove_case(s, quality, cache) for s in group]
        for c in cases:
            label = c["spec"].name.replace("groove_reflex_", "radiosity_groove[").replace("[albedo=", ",rho=")
            label = label if label.startswith("radiosity_groove") else f"radiosity_groove:{c['spec'].name}"
            out += _records(label, c["cmp"], "strips per face")
        if figures is not None and cases:
            figures[f"radiosity_groove: {fam}: render vs radiosity model vs local model"] = _groove_plot(fam, cases)
    return out


def _groove_plot(fam: str, cases: list[dict]) -> dict:
    series = {}
    for k, c in enumerate(cases):
        u = c["cells"].used
        col = f"C{k % 10}"
        x = c["x"][u].tolist()
        series[f"rho {c['rho']:g}: path tracer"] = {"x": x, "y": (np.pi * c["cells"].render[u]).tolist(), "color": col}
        series[f"rho {c['rho']:g}: radiosity"] = {"x": x, "y": (np.pi * c["cmp"].model[u]).tolist(), "color": col,
                                                  "linestyle": "--", "marker": "x"}
        series[f"rho {c['rho']:g}: local"] = {"x": x, "y": (np.pi * c["local"][u]).tolist(), "color": col,
                                              "linestyle": ":", "marker": ""}
    return {"x": None, "series": series, "xlabel": "x across the groove (crease at 0)",
            "ylabel": "radiosity B = pi L (strip means)", "title": f"{fam}: path tracer, radiosity model, local model"}


# --------------------------------------------------------------------------- the rooms
ROOM_ROW = 0.72   # the section: the image row at this fraction of the height (through the cube and the tall box)


def room_case(spec: SceneSpec, quality: Quality, cache) -> dict:
    """Render and model of one room (:func:`pbrbench.radiosity.forward_models.scene_model` at 6 and
    12 patches across the view with 3 and 4 shadow-ray points per side, from 96 px at 12 and 24
    with 4 and 6; cells = the patches of a mesh of 3, from 96 px 6, patches across the view), and
    the section: a band of rows about :data:`ROOM_ROW` down the image."""
    from pbrbench.radiosity.forward_models import (
        model_patches,
        predict_radiance,
        scene_model,
        view_width,
    )
    from pbrbench.radiosity.image import patch_index_image

    gt = ground_truth_of(spec, quality, cache)
    H, W = gt["radiance"].shape[:2]
    # (patches across the view, shadow-ray points per side on patches and the light): both refined,
    # so that d also measures the sampled visibility of the area light; the patches halve each level.
    # The cells: the patches of a mesh twice coarser than the coarsest level (large against the
    # model's patches, so the model resolves how the radiance varies inside each cell)
    big = W >= 96
    levels = [(12, 4), (24, 6)] if big else [(6, 3), (12, 4)]
    mesh = model_patches(spec, view_width(spec) / (6 if big else 3))
    idx = patch_index_image(spec, mesh, (W, H))
    cells = Cells.of(idx, _pixel_selection(spec, mesh, W, H, whole=False), gt["radiance"], gt.sd_of("radiance", _grey),
                     len(mesh), faces=_faces(mesh, idx))
    images = {}

    def cells_at(level):
        return cells

    def model_at(level):
        c, a = level
        images[level] = predict_radiance(spec, (W, H), cells=c, area_samples=a, supersample=SUPERSAMPLE)
        return (images[level], predict_radiance(spec, (W, H), cells=c, area_samples=a, supersample=SUPERSAMPLE - 1),
                predict_radiance(spec, (W, H), cells=c, area_samples=a + 1, supersample=SUPERSAMPLE))

    cmp = refine(cells_at, model_at, levels)
    row = int(ROOM_ROW * H)
    band = slice(max(0, row - max(1, H // 32)), row + max(1, H // 32) + 1)
    c, a = cmp.level
    local = predict_radiance(spec, (W, H), bounces=0, cells=c, area_samples=a, supersample=SUPERSAMPLE)
    model = scene_model(spec, cells=c, area_samples=a)
    return {"spec": spec, "cells": cmp.cells, "cmp": cmp, "gt": gt, "band": band, "row": row, "cell_level": 6 if big else 3,
            "section": {"render": _grey(gt["radiance"])[band].mean(0), "direct": _grey(gt["direct"])[band].mean(0),
                        "model": _grey(images[cmp.level])[band].mean(0), "local": _grey(local)[band].mean(0)},
            "patches": len(model.patches)}


def check_room(quality: Quality, cache, *, figures=None, specs=None) -> list[Record]:
    """``radiosity_room``: the black and the white room (or ``specs``), patch cells."""
    specs = list(specs) if specs is not None else [_library("room_black")[0], _library("room_white")[0]]
    out, cases = [], []
    for s in specs:
        c = room_case(s, quality, cache)
        cases.append(c)
        out += _records(f"radiosity_room[{s.name}]", c["cmp"], "patches across the view, shadow-ray points per side",
                        f"the patches of a mesh of {c['cell_level']} patches across the view")
    if figures is not None:
        series = {}
        for k, c in enumerate(cases):
            nm, col = c["spec"].name, f"C{k}"
            x = list(range(len(c["section"]["render"])))
            series[f"{nm}: path tracer"] = {"x": x, "y": c["section"]["render"].tolist(), "color": col}
            series[f"{nm}: radiosity"] = {"x": x, "y": c["section"]["model"].tolist(), "color": col, "linestyle": "--"}
            series[f"{nm}: local model"] = {"x": x, "y": c["section"]["local"].tolist(), "color": col, "linestyle": ":"}
        figures["radiosity_room: sections (image rows about "
                f"{ROOM_ROW:.0%} down) of the black and the white room"] = {
            "x": None, "series": series, "xlabel": "image column", "ylabel": "radiance (band of rows)",
            "title": "black vs white room: path tracer, radiosity model, local model"}
    return out
