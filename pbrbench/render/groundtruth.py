"""Render the ground truth of a scene.

Passes (each radiance-like pass is rendered as two half-sample renders with independent seeds,
whose mean is the image and whose difference estimates its Monte Carlo noise):

* ``radiance``: full global illumination (``max_depth`` of the scene, -1 = unlimited);
* ``direct``: ``max_depth = 2``; ``indirect = radiance - direct`` (same seeds, so in LLVM the two
  renders share their first bounce and the difference is low-variance);
* ``light{k}.radiance`` / ``light{k}.direct``: one light of the light set in the scene at a time
  (never zeroed lights: docs/rendering.md);
* ``unoccluded_fraction`` (scenes with occluders): direct / direct-without-occluders;
* ``diffuse_only`` (scenes with glossy materials): the twin with every coating removed;
* AOVs (a separate pass, docs/rendering.md): ``albedo``, ``normals`` (camera frame of docs/conventions.md:
  x right, y up, z toward the camera), ``position`` (world), ``depth`` (along the view axis, from
  the position AOV, not Mitsuba's depth AOV), ``coverage`` and ``mask`` (pure pixels: fully covered by
  geometry and not on a boundary between two objects, where the AOVs are mixtures),
  ``object_id`` (0 background, k + 1 for shape k; from a one-sample pass so ids are not averaged).

``*_sd`` arrays are the per-pixel standard deviation of the corresponding image estimate.
Box reconstruction filter, float32 everywhere, seeds from the scene's ``render.seed``.
"""

from __future__ import annotations

import gc
import importlib.metadata
import platform
import time
from dataclasses import dataclass, field

import numpy as np

from pbrbench.render.quality import get_quality
from pbrbench.render.variant import current_choice, mitsuba
from pbrbench.scene import spec as S
from pbrbench.scene.mitsuba_dict import scene_dict, shape_key

GT_FORMAT = 3  # bump when the content of a ground truth changes (invalidates caches)


@dataclass
class GroundTruth:
    """Named float32 arrays plus metadata (scene hash, variant, spp, seed, versions, timings, noise)."""

    arrays: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.arrays[name]
        except KeyError:
            raise KeyError(f"ground truth has no {name!r}; it has {', '.join(sorted(self.arrays))}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.arrays

    @property
    def n_lights(self) -> int:
        return int(self.meta.get("n_light_set", 0))

    def light_stack(self, kind: str = "radiance") -> np.ndarray:
        """(K, H, W, 3) per-light images of the light set (``kind`` = radiance or direct)."""
        return np.stack([self.arrays[f"light{k:02d}.{kind}"] for k in range(self.n_lights)])

    @property
    def mask(self) -> np.ndarray:
        return self.arrays["mask"] > 0.5


def versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("pbrbench", "mitsuba", "drjit", "numpy", "scipy"):
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def _film_arrays(scene) -> dict[str, np.ndarray]:
    bmp = scene.sensors()[0].film().bitmap()
    names = [f.name for f in bmp.struct_()]
    a = np.array(bmp, dtype=np.float32)
    return {n: a[..., i] for i, n in enumerate(names)}


class _Renderer:
    def __init__(self, spec: S.SceneSpec, quality: str, variant: str | None, progress=None):
        self.mi = mitsuba(variant)
        self.spec = spec
        q = get_quality(quality)
        self.quality = q.name
        self.res = q.resolution(spec.render.resolution)
        self.spp = q.spp(spec.render.spp)
        self.seed = spec.render.seed
        self.progress = progress
        self.cpu0 = time.process_time()
        self.t0 = time.perf_counter()

    def _tick(self, what):
        if self.progress is not None:
            self.progress(what)

    def render_pair(self, what: str, seed_offset: int, **kw) -> tuple[np.ndarray, np.ndarray]:
        """Mean and per-pixel sd of the mean of two half-sample renders with independent seeds."""
        mi = self.mi
        half = max(1, self.spp // 2)
        # samplers such as multijitter round the count up (with a warning): use what they take
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)
        try:
            scene = mi.load_dict(scene_dict(mi, self.spec, self.res, half, **kw), optimize=False)
        finally:
            mi.set_log_level(level)
        half = int(scene.sensors()[0].sampler().sample_count())
        self.spp_used = 2 * half
        base = 2 * (self.seed * 1000 + seed_offset)
        a = np.array(mi.render(scene, seed=base, spp=half), dtype=np.float32)[..., :3]
        b = np.array(mi.render(scene, seed=base + 1, spp=half), dtype=np.float32)[..., :3]
        del scene
        gc.collect()
        self._tick(what)
        mean = 0.5 * (a + b)
        sd = 0.5 * np.abs(a - b)  # sd of the mean of two draws, one-sample estimate
        return mean, sd

    def aovs(self) -> dict[str, np.ndarray]:
        mi = self.mi
        integ = {"type": "aov", "aovs": "alb:albedo,nn:sh_normal,pp:position,si:shape_index",
                 "cov": {"type": "path", "max_depth": 1}}
        scene = mi.load_dict(scene_dict(mi, self.spec, self.res, self.spp, integrator=integ, drop_occluders=False), optimize=False)
        mi.render(scene, seed=self.seed)
        ch = _film_arrays(scene)
        M = np.array(scene.sensors()[0].world_transform().matrix, dtype=np.float64).reshape(4, 4)
        obj_avg = self._object_ids(scene, ch["si.I"])  # footprint-averaged: mixed pixels -> -1
        del scene
        cov = ch["cov.A"]
        safe = np.where(cov > 0, cov, 1.0)
        alb = np.stack([ch["alb.R"], ch["alb.G"], ch["alb.B"]], -1) / safe[..., None]
        nw = np.stack([ch["nn.X"], ch["nn.Y"], ch["nn.Z"]], -1).astype(np.float64) / safe[..., None]
        pos = np.stack([ch["pp.X"], ch["pp.Y"], ch["pp.Z"]], -1).astype(np.float64) / safe[..., None]
        R = M[:3, :3] / np.linalg.norm(M[:3, :3], axis=0)  # columns: left, up, view direction
        n_cam = (nw @ R) * np.array([-1.0, 1.0, -1.0])  # x right, y up, z toward the camera
        norm = np.linalg.norm(n_cam, axis=-1, keepdims=True)
        n_cam = np.where(norm > 1e-8, n_cam / np.where(norm > 1e-8, norm, 1.0), 0.0)
        origin, view = M[:3, 3], R[:, 2]
        depth = (pos - origin) @ view
        covered = cov > 0
        for a in (alb, n_cam, pos):
            a[~covered] = 0
        depth[~covered] = 0
        # object ids from a one-sample pass (ids must not be averaged across an edge)
        integ1 = {"type": "aov", "aovs": "si:shape_index"}
        scene = mi.load_dict(scene_dict(mi, self.spec, self.res, 1, integrator=integ1, sampler="independent"), optimize=False)
        mi.render(scene, seed=self.seed, spp=1)
        obj = np.maximum(self._object_ids(scene, _film_arrays(scene)["si.I"]), 0)
        del scene
        gc.collect()
        # pure pixels: fully covered and not on a boundary between two objects (there the
        # footprint-averaged AOVs are mixtures)
        pad = np.pad(obj, 1, mode="edge")
        same = np.ones(obj.shape, bool)
        for di, dj in ((0, 1), (2, 1), (1, 0), (1, 2)):
            same &= pad[di:di + obj.shape[0], dj:dj + obj.shape[1]] == obj
        # and the footprint-averaged index equals the point-sampled one (no mixture inside the pixel)
        pure = (cov > 0.999) & same & (obj > 0) & (obj_avg == obj)
        self._tick("aovs")
        return {"albedo": alb.astype(np.float32), "normals": n_cam.astype(np.float32),
                "position": pos.astype(np.float32), "depth": depth.astype(np.float32),
                "coverage": cov.astype(np.float32), "mask": pure.astype(np.float32),
                "object_id": obj}

    def _object_ids(self, scene, si: np.ndarray) -> np.ndarray:
        """Map Mitsuba's ``shape_index`` AOV to 0 (background / emitters), k + 1 (shape k), or -1
        where the value is no shape's index (an average across several shapes).

        ``shape_index`` is the 1-based position in ``scene.shapes()`` in scalar variants and the
        shape's JIT registry id in LLVM/CUDA ones (docs/rendering.md): map each scene with
        its own table.
        """
        mi = self.mi
        if mi.variant().startswith("scalar"):
            idmap = {i + 1: s.id() for i, s in enumerate(scene.shapes())}
        else:
            import drjit as dr

            idmap = {int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]): s.id() for s in scene.shapes()}
        keys = {shape_key(self.spec, i): i + 1 for i in range(len(self.spec.shapes))}
        out = np.where(si == 0, 0, -1).astype(np.float32)
        for raw, sid in idmap.items():
            out[si == raw] = keys.get(sid, 0)  # emitters (area lights) -> 0
        return out


def n_passes(spec: S.SceneSpec) -> int:
    """Progress steps of :func:`render_ground_truth`: radiance, direct, two per light of the light
    set, the unoccluded and diffuse-only passes where they apply, and the AOVs."""
    return 3 + 2 * len(spec.light_set) + int(spec.has_occluders) + int(spec.has_glossy)


def render_ground_truth(spec: S.SceneSpec, quality: str = "standard", *, variant: str | None = None,
                        progress=None) -> GroundTruth:
    """Render every pass of the ground truth of ``spec`` (no cache: see :mod:`.cache`)."""
    r = _Renderer(spec, quality, variant, progress)
    md = spec.render.max_depth
    path = {"type": "path", "max_depth": md, "rr_depth": spec.render.rr_depth}
    direct = {"type": "path", "max_depth": 2}
    arrays: dict[str, np.ndarray] = {}
    arrays["radiance"], arrays["radiance_sd"] = r.render_pair("radiance", 0, integrator=path)
    arrays["direct"], arrays["direct_sd"] = r.render_pair("direct", 0, integrator=direct)
    arrays["indirect"] = arrays["radiance"] - arrays["direct"]
    for k, light in enumerate(spec.light_set):
        arrays[f"light{k:02d}.radiance"], _ = r.render_pair(f"light {k}", 10 + k, integrator=path, lights=[light])
        arrays[f"light{k:02d}.direct"], _ = r.render_pair(f"light {k} direct", 10 + k, integrator=direct, lights=[light])
    if spec.has_occluders:
        unocc, _ = r.render_pair("unoccluded", 0, integrator=direct, drop_occluders=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            lum_o = arrays["direct"].mean(-1)
            lum_u = unocc.mean(-1)
            frac = np.where(lum_u > 1e-6 * max(lum_u.max(), 1e-30), lum_o / lum_u, 1.0)
        arrays["unoccluded_fraction"] = np.clip(frac, 0, 1).astype(np.float32)
        arrays["direct_unoccluded"] = unocc
    if spec.has_glossy:
        arrays["diffuse_only"], _ = r.render_pair("diffuse-only twin", 0, integrator=path, diffuse_only=True)
    arrays.update(r.aovs())

    rad, sd = arrays["radiance"], arrays["radiance_sd"]
    sig = rad.mean(-1) > 1e-3 * max(float(rad.mean(-1).max()), 1e-30)
    rel = (sd.mean(-1)[sig] / rad.mean(-1)[sig]) if sig.any() else np.zeros(1)
    choice = current_choice()
    meta = {
        "format": GT_FORMAT,
        "scene": spec.name,
        "scene_hash": spec.content_hash(),
        "description": spec.description,
        "reference": spec.reference,
        "quality": r.quality,
        "resolution": list(r.res),
        "spp": getattr(r, "spp_used", r.spp),
        "spp_nominal": r.spp,
        "seed": spec.render.seed,
        "max_depth": md,
        "variant": choice.variant if choice else None,
        "versions": versions(),
        "wall_s": time.perf_counter() - r.t0,
        "cpu_s": time.process_time() - r.cpu0,
        "n_light_set": len(spec.light_set),
        "noise": {
            "radiance_rel_sd_rms": float(np.sqrt(np.mean(rel ** 2))),
            "radiance_rel_sd_median": float(np.median(rel)),
            "note": "per-pixel sd of the image estimate from two half-sample renders (|a-b|/2), relative to the pixel value; pixels above 1e-3 of the peak",
        },
    }
    return GroundTruth({k: np.ascontiguousarray(v, dtype=np.float32) for k, v in arrays.items()}, meta)
