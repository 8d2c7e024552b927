"""Render the ground truth of a scene.

Passes (each radiance-like pass is rendered as two half-sample renders ``a`` and ``b`` with
independent seeds; the image is their mean ``(a + b) / 2`` and the signed half-difference
``X_delta = (a - b) / 2`` is kept, so both halves can be rebuilt, ``a = X + X_delta`` and
``b = X - X_delta`` (:meth:`GroundTruth.replicate`), and ``X_sd = |X_delta|`` is the per-pixel
standard deviation of the image estimate):

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

``*_sd`` (derived from ``*_delta`` on access) is the per-pixel standard deviation of the
corresponding image estimate.  Box reconstruction filter, float32 everywhere, seeds from the
scene's ``render.seed``.
"""

from __future__ import annotations

import gc
import importlib.metadata
import math
import platform
import time
from dataclasses import dataclass, field

import numpy as np

from pbrbench.render.quality import get_quality
from pbrbench.render.variant import current_choice, mitsuba
from pbrbench.scene import spec as S
from pbrbench.scene.mitsuba_dict import scene_dict, shape_key

GT_FORMAT = 7  # bump when the content of a ground truth changes (invalidates caches)
RADIANCE_LIKE = ("radiance", "direct", "diffuse_only", "direct_unoccluded")  # plus lightNN.radiance/direct
AOV_REPLICATED = ("albedo", "normals", "depth")  # AOVs whose half-sample deltas are kept


def is_radiance_like(name: str) -> bool:
    """Whether ``name`` is a rendered (Monte Carlo) pass that has a ``<name>_delta``."""
    return name in RADIANCE_LIKE or (name.startswith("light") and name.endswith((".radiance", ".direct")))


@dataclass
class GroundTruth:
    """Named float32 arrays plus metadata (scene hash, variant, spp, seed, versions, timings, noise)."""

    arrays: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.arrays[name]
        except KeyError:
            if name.endswith("_sd") and f"{name[:-3]}_delta" in self.arrays:
                return np.abs(self.arrays[f"{name[:-3]}_delta"])
            raise KeyError(f"ground truth has no {name!r}; it has {', '.join(sorted(self.arrays))}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.arrays or (name.endswith("_sd") and f"{name[:-3]}_delta" in self.arrays)

    @property
    def has_replicates(self) -> bool:
        """Whether the half-sample renders can be rebuilt (every rendered pass has its delta)."""
        passes = [n for n in self.arrays if is_radiance_like(n)]
        return bool(passes) and all(f"{n}_delta" in self.arrays for n in passes)

    def replicate(self, half: int) -> GroundTruth:
        """The ground truth of one half-sample render (``half`` 0 or 1): every rendered pass and the
        Monte Carlo AOVs (albedo, normals, depth) are replaced by ``X + X_delta`` (half 0) or
        ``X - X_delta`` (half 1), normals renormalised, ``indirect`` rebuilt from the half's
        radiance and direct; the masks, ids and metadata are shared.  Its arrays have twice the
        variance of the full ground truth's."""
        if half not in (0, 1):
            raise ValueError(f"half: 0 or 1, got {half!r}")
        sign = 1.0 if half == 0 else -1.0
        arrays = dict(self.arrays)
        for n, a in self.arrays.items():
            d = self.arrays.get(f"{n}_delta")
            if d is not None and (is_radiance_like(n) or n in AOV_REPLICATED):
                arrays[n] = (a + sign * d).astype(np.float32)
        if "normals_delta" in self.arrays:
            nrm = arrays["normals"].astype(np.float64)
            ln = np.linalg.norm(nrm, axis=-1, keepdims=True)
            arrays["normals"] = np.where(ln > 1e-8, nrm / np.where(ln > 1e-8, ln, 1.0), 0.0).astype(np.float32)
        if "radiance" in arrays and "direct" in arrays and "indirect" in self.arrays:
            arrays["indirect"] = arrays["radiance"] - arrays["direct"]
        return GroundTruth(arrays, dict(self.meta, replicate=half))

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
        self.target = q.noise_target          # (median, rms) relative sd of the passes, or None
        self.max_spp = int(round(q.max_spp_factor * self.spp))
        self.mask = None                      # pure pixels (from the AOVs, rendered first)
        self.spp_per_pass: dict[str, int] = {}
        self.progress = progress
        self.cpu0 = time.process_time()
        self.t0 = time.perf_counter()

    def _tick(self, what):
        if self.progress is not None:
            self.progress(what)

    def render_pair(self, what: str, seed_offset: int, **kw) -> tuple[np.ndarray, np.ndarray]:
        """Mean ``(a + b) / 2`` and signed half-difference ``(a - b) / 2`` of two half-sample
        renders with independent seeds (``|(a - b) / 2|`` is the sd of the mean, one-sample).

        With a noise target (:attr:`pbrbench.render.quality.Quality.noise_target`) the first pair,
        at the scene's samples per pixel, is the pilot: where its relative noise over the lit pure
        pixels (:func:`pass_noise`) is above the target, a second pair with the missing samples
        (noise ~ 1/sqrt(spp)), at most ``max_spp`` in all, is rendered with its own seeds and
        merged into the two halves, weighted by their samples, so no sample is wasted."""
        mi = self.mi
        half = max(1, self.spp // 2)
        # samplers such as multijitter round the count up (with a warning): use what they take
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)
        try:
            scene = mi.load_dict(scene_dict(mi, self.spec, self.res, half, **kw), optimize=False)
            half = int(scene.sensors()[0].sampler().sample_count())
            base = 2 * (self.seed * 1000 + seed_offset)
            a = np.array(mi.render(scene, seed=base, spp=half), dtype=np.float64)[..., :3]
            b = np.array(mi.render(scene, seed=base + 1, spp=half), dtype=np.float64)[..., :3]
            n = half
            if self.target is not None and self.mask is not None:
                med, rms = pass_noise(0.5 * (a + b), 0.5 * (a - b), self.mask)
                need = max((med / self.target[0]) ** 2, (rms / self.target[1]) ** 2)
                total = min(int(math.ceil(need * n)), max(self.max_spp // 2, n))
                extra = total - n
                if extra >= max(1, n // 4):
                    top = base + 2_000_003   # seeds no other pass uses
                    a2 = np.array(mi.render(scene, seed=top, spp=extra), dtype=np.float64)[..., :3]
                    b2 = np.array(mi.render(scene, seed=top + 1, spp=extra), dtype=np.float64)[..., :3]
                    a = (n * a + extra * a2) / (n + extra)
                    b = (n * b + extra * b2) / (n + extra)
                    n += extra
        finally:
            mi.set_log_level(level)
        self.spp_used = 2 * half
        self.spp_per_pass[what] = 2 * n
        del scene
        gc.collect()
        self._tick(what)
        return (0.5 * (a + b)).astype(np.float32), (0.5 * (a - b)).astype(np.float32)

    def aovs(self) -> dict[str, np.ndarray]:
        """The AOVs (albedo, normals, position, depth, coverage) as the mean of two half-sample
        renders with their own seeds, with the signed half-differences of albedo, normals and
        depth (footprint averages are Monte Carlo estimates too: at a curved or tilted surface
        they move with the samples); plus the object ids and the pure-pixel mask."""
        mi = self.mi
        integ = {"type": "aov", "aovs": "alb:albedo,nn:sh_normal,pp:position,si:shape_index",
                 "cov": {"type": "path", "max_depth": 1}}
        half = max(1, self.spp // 2)
        scene = mi.load_dict(scene_dict(mi, self.spec, self.res, half, integrator=integ, drop_occluders=False), optimize=False)
        half = int(scene.sensors()[0].sampler().sample_count())
        M = np.array(scene.sensors()[0].world_transform().matrix, dtype=np.float64).reshape(4, 4)
        base = 2 * (self.seed * 1000 + 500)
        films = []
        for k in range(2):
            mi.render(scene, seed=base + k, spp=half)
            films.append(_film_arrays(scene))
        obj_avg = [self._object_ids(scene, f["si.I"]) for f in films]  # footprint-averaged: mixed pixels -> -1
        del scene
        if all(float(f["cov.A"].max()) == 0.0 for f in films) and any(float(f["alb.R"].max()) > 0 for f in films):
            # scalar variants leave the nested integrator's alpha at 0: measure the covered fraction of
            # each pixel as the albedo AOV of the same samples with every surface white instead
            d = scene_dict(mi, self.spec, self.res, half, integrator={"type": "aov", "aovs": "w:albedo"},
                           drop_occluders=False)
            for v in d.values():
                if isinstance(v, dict) and "bsdf" in v:
                    v["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}
            white = mi.load_dict(d, optimize=False)
            for k in range(2):
                mi.render(white, seed=base + k, spp=half)
                films[k]["cov.A"] = _film_arrays(white)["w.R"]
            del white
        R = M[:3, :3] / np.linalg.norm(M[:3, :3], axis=0)  # columns: left, up, view direction
        origin, view = M[:3, 3], R[:, 2]

        def derived(ch):
            cov = ch["cov.A"].astype(np.float64)
            safe = np.where(cov > 0, cov, 1.0)
            alb = np.stack([ch["alb.R"], ch["alb.G"], ch["alb.B"]], -1) / safe[..., None]
            nw = np.stack([ch["nn.X"], ch["nn.Y"], ch["nn.Z"]], -1).astype(np.float64) / safe[..., None]
            pos = np.stack([ch["pp.X"], ch["pp.Y"], ch["pp.Z"]], -1).astype(np.float64) / safe[..., None]
            n_cam = (nw @ R) * np.array([-1.0, 1.0, -1.0])  # x right, y up, z toward the camera
            norm = np.linalg.norm(n_cam, axis=-1, keepdims=True)
            n_cam = np.where(norm > 1e-8, n_cam / np.where(norm > 1e-8, norm, 1.0), 0.0)
            depth = (pos - origin) @ view
            covered = cov > 0
            for a in (alb, n_cam, pos):
                a[~covered] = 0
            depth[~covered] = 0
            return cov, alb, n_cam, pos, depth

        full = {k: 0.5 * (films[0][k].astype(np.float64) + films[1][k].astype(np.float64)) for k in films[0]}
        cov, alb, n_cam, pos, depth = derived(full)
        _, alb_a, n_a, _, d_a = derived(films[0])
        _, alb_b, n_b, _, d_b = derived(films[1])
        obj_avg = np.where(obj_avg[0] == obj_avg[1], obj_avg[0], -1)
        deltas = {"albedo_delta": 0.5 * (alb_a - alb_b), "normals_delta": 0.5 * (n_a - n_b),
                  "depth_delta": 0.5 * (d_a - d_b)}
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
        out = {"albedo": alb.astype(np.float32), "normals": n_cam.astype(np.float32),
               "position": pos.astype(np.float32), "depth": depth.astype(np.float32),
               "coverage": cov.astype(np.float32), "mask": pure.astype(np.float32),
               "object_id": obj}
        out.update({k: np.where(pure[..., None] if v.ndim == 3 else pure, v, 0.0).astype(np.float32)
                    for k, v in deltas.items()})
        return out

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


def pass_noise(image: np.ndarray, delta: np.ndarray, mask: np.ndarray | None = None, lit: float = 0.05) -> tuple[float, float]:
    """Median and RMS relative sd ``|delta| / image`` (channel means) over the *lit pure* pixels:
    inside ``mask`` (the ground truth's pure pixels) and above ``lit`` of the pass's peak there —
    the pixels the tasks measure (shadowed and silhouette pixels are left to the tasks' own
    domains).  Without a mask (or no lit pure pixel) every pixel above ``lit`` of the peak counts."""
    lum = np.asarray(image, np.float64).mean(-1)
    sd = np.abs(np.asarray(delta, np.float64)).mean(-1)
    m = np.asarray(mask, bool) if mask is not None else np.ones(lum.shape, bool)
    if not m.any() or lum[m].max() <= 0:
        m = np.ones(lum.shape, bool)
    sel = m & (lum > lit * max(float(lum[m].max()), 1e-30))
    if not sel.any():
        return 0.0, 0.0
    rel = sd[sel] / lum[sel]
    return float(np.median(rel)), float(np.sqrt(np.mean(rel ** 2)))


def relative_noise(image: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Per-pixel relative sd ``|delta| / image`` (channel means) over the pixels above 1e-3 of
    the image's peak (the lit pixels)."""
    lum = np.asarray(image, np.float64).mean(-1)
    sd = np.abs(np.asarray(delta, np.float64)).mean(-1)
    sig = lum > 1e-3 * max(float(lum.max()), 1e-30)
    return sd[sig] / lum[sig] if sig.any() else np.zeros(1)


def noise_summary(arrays: dict, spec) -> dict:
    """Median and RMS relative sd of the radiance, and of the passes the tasks consume (the
    per-light passes when the scene has a light set, else radiance and direct)."""
    rel = relative_noise(arrays["radiance"], arrays["radiance_delta"])
    if spec.light_set:
        names = [f"light{k:02d}.{kind}" for k in range(len(spec.light_set)) for kind in ("direct", "radiance")]
    else:
        names = ["radiance", "direct"]
    mask = arrays["mask"] > 0.5 if "mask" in arrays else None
    lit = np.array([pass_noise(arrays[n], arrays[f"{n}_delta"], mask) for n in names])
    return {
        "radiance_rel_sd_rms": float(np.sqrt(np.mean(rel ** 2))),
        "radiance_rel_sd_median": float(np.median(rel)),
        "inputs_rel_sd_median": float(lit[:, 0].max()),
        "inputs_rel_sd_rms": float(lit[:, 1].max()),
        "inputs": names,
        "note": "per-pixel sd of the image estimate from two half-sample renders (|a-b|/2), relative to the "
                "pixel value; radiance: pixels above 1e-3 of the peak; inputs: the passes the tasks consume, "
                "over their lit pure pixels (mask, above 5 % of the pass's peak), the worst pass",
    }


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
    # the AOVs first: their pure-pixel mask is where the noise target is measured
    arrays.update(r.aovs())
    r.mask = arrays["mask"] > 0.5
    # a direct-only scene (max_depth 2: e.g. an area-source twin, which isolates the source's
    # effect) renders each pass once: its radiance is its direct light
    direct_only = md == 2
    arrays["radiance"], arrays["radiance_delta"] = r.render_pair("radiance", 0, integrator=path)
    if direct_only:
        arrays["direct"], arrays["direct_delta"] = arrays["radiance"], arrays["radiance_delta"]
        r._tick("direct (= radiance)")
    else:
        arrays["direct"], arrays["direct_delta"] = r.render_pair("direct", 0, integrator=direct)
    arrays["indirect"] = arrays["radiance"] - arrays["direct"]
    for k, light in enumerate(spec.light_set):
        n = f"light{k:02d}"
        arrays[f"{n}.radiance"], arrays[f"{n}.radiance_delta"] = r.render_pair(
            f"light {k}", 10 + k, integrator=path, lights=[light])
        if direct_only:
            arrays[f"{n}.direct"], arrays[f"{n}.direct_delta"] = arrays[f"{n}.radiance"], arrays[f"{n}.radiance_delta"]
            r._tick(f"light {k} direct (= radiance)")
        else:
            arrays[f"{n}.direct"], arrays[f"{n}.direct_delta"] = r.render_pair(
                f"light {k} direct", 10 + k, integrator=direct, lights=[light])
    if spec.has_occluders:
        unocc, arrays["direct_unoccluded_delta"] = r.render_pair("unoccluded", 0, integrator=direct,
                                                                 drop_occluders=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            lum_o = arrays["direct"].mean(-1)
            lum_u = unocc.mean(-1)
            frac = np.where(lum_u > 1e-6 * max(lum_u.max(), 1e-30), lum_o / lum_u, 1.0)
        arrays["unoccluded_fraction"] = np.clip(frac, 0, 1).astype(np.float32)
        arrays["direct_unoccluded"] = unocc
    if spec.has_glossy:
        arrays["diffuse_only"], arrays["diffuse_only_delta"] = r.render_pair(
            "diffuse-only twin", 0, integrator=path, diffuse_only=True)

    choice = current_choice()
    meta = {
        "format": GT_FORMAT,
        "scene": spec.name,
        "scene_hash": spec.content_hash(),
        "description": spec.description,
        "reference": spec.reference,
        "tags": list(spec.tags),
        "quality": r.quality,
        "resolution": list(r.res),
        "spp": getattr(r, "spp_used", r.spp),
        "spp_nominal": r.spp,
        "spp_per_pass": dict(r.spp_per_pass),
        "noise_target": list(r.target) if r.target is not None else None,
        "seed": spec.render.seed,
        "max_depth": md,
        "variant": choice.variant if choice else None,
        "versions": versions(),
        "wall_s": time.perf_counter() - r.t0,
        "cpu_s": time.process_time() - r.cpu0,
        "n_light_set": len(spec.light_set),
        "noise": noise_summary(arrays, spec),
    }
    return GroundTruth({k: np.ascontiguousarray(v, dtype=np.float32) for k, v in arrays.items()}, meta)
