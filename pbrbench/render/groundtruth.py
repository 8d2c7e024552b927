"""Render the ground truth of a scene.

Passes (each radiance-like pass is rendered as ``G`` sample groups with independent seeds,
``G`` from the quality profile; the image is their mean and the delete-one-group deviations
``X_jk<i>`` (the mean of every group but ``i``, minus the mean) are kept, so each delete-one-group
ground truth can be rebuilt, ``X_(i) = X + X_jk<i>`` (:meth:`GroundTruth.replicate`), and ``X_sd``
is the per-pixel jackknife standard deviation of the image estimate):

* ``radiance``: full global illumination (``max_depth`` of the scene, -1 = unlimited);
* ``direct``: ``max_depth = 2``; ``indirect = radiance - direct`` (same seeds, so in LLVM the two
  renders share their first bounce and the difference is low-variance);
* ``light{k}.radiance`` / ``light{k}.direct``: one light of the light set in the scene at a time
  (never zeroed lights: docs/rendering.md); where the light set is every light of the scene,
  ``radiance`` and ``direct`` are the sums of these (linearity in the sources), not renders of
  their own;
* ``unoccluded_fraction`` (scenes with occluders): direct / direct-without-occluders;
* ``diffuse_only`` (scenes with glossy materials): the twin with every coating removed;
* AOVs (a separate pass, docs/rendering.md): ``albedo``, ``normals`` (camera frame of docs/conventions.md:
  x right, y up, z toward the camera), ``position`` (world), ``depth`` (along the view axis, from
  the position AOV, not Mitsuba's depth AOV), ``coverage`` and ``mask`` (pure pixels: fully covered by
  geometry and not on a boundary between two objects, where the AOVs are mixtures),
  ``object_id`` (0 background, k + 1 for shape k; from a one-sample pass so ids are not averaged).

``*_sd`` (derived from the deviations on access) is the per-pixel standard deviation of the
corresponding image estimate.  Box reconstruction filter, float32 everywhere, seeds from the
scene's ``render.seed``.
"""

from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass, field

import numpy as np

from pbrbench.quality import Quality, require
from pbrbench.render.variant import current_choice, mitsuba
from pbrbench.scene import spec as S
from pbrbench.scene.mitsuba_dict import scene_dict, shape_key

GT_FORMAT = 14  # bump when the content of a ground truth changes (invalidates caches; 12 was a reverted trial; 14: shape ids to rounding)
RADIANCE_LIKE = ("radiance", "direct", "diffuse_only", "direct_unoccluded")  # plus lightNN.radiance/direct
AOV_REPLICATED = ("albedo", "normals", "position", "depth", "coverage", "mask")  # AOVs with delete-one-group deviations (not in the replicates by default)
SEED_STRIDE = 16   # render seeds of one pass: SEED_STRIDE * (seed * 1000 + pass offset) + group (< 16 groups)
SEED_MOD = 1 << 32   # Mitsuba's seeds are 32-bit
OBJECT_ID_SEED = 0   # the one-sample object-id pass: the same for every render seed
AOV_SEED = 0         # the geometry passes (AOVs, coverage, pure mask): the same for every render seed
ID_TOLERANCE = 1e-4   # a shape-index AOV value within this relative distance of a shape's index is that shape (float32 means)
JK = "_jk"         # ``<name>_jk<i>``: the delete-one-group deviation of ``<name>`` for group ``i``


def pass_seed(seed: int, offset: int, k: int) -> int:
    """The 32-bit render seed of sample group (or extra render) ``k`` of the pass at ``offset``
    of a scene whose ``render.seed`` is ``seed``."""
    return (SEED_STRIDE * (seed * 1000 + offset) + k) % SEED_MOD


def is_radiance_like(name: str) -> bool:
    """Whether ``name`` is a rendered (Monte Carlo) pass that has delete-one-group deviations."""
    return name in RADIANCE_LIKE or (name.startswith("light") and name.endswith((".radiance", ".direct")))


def loo_deviations(groups) -> tuple[np.ndarray, np.ndarray]:
    """``(mean, jk)`` of ``G`` equally weighted sample groups: ``mean = sum_g X_g / G`` and the
    delete-one-group deviations ``jk[i] = mean_{g != i} X_g - mean = -(X_i - mean) / (G - 1)``."""
    x = np.stack([np.asarray(g, np.float64) for g in groups])
    G = x.shape[0]
    if G < 2:
        raise ValueError(f"groups: at least 2 sample groups are needed for a standard error, got {G}")
    mean = x.mean(0)
    return mean, -(x - mean) / (G - 1)


def jackknife_sd(jk) -> np.ndarray:
    """Per-pixel standard deviation of the full-sample mean from its delete-one-group deviations:
    ``sqrt((G - 1) / G * sum_i jk_i^2)`` (the jackknife variance; for a pass that is a mean of
    ``G`` groups it equals the sample variance of the groups over ``G``)."""
    jk = np.asarray(jk, np.float64)
    G = jk.shape[0]
    return np.sqrt((G - 1) / G * np.sum(jk * jk, axis=0))


def unoccluded_fraction(direct: np.ndarray, unoccluded: np.ndarray) -> np.ndarray:
    """``direct / direct-without-occluders`` (grey, in [0, 1]; 1 where the unoccluded pass is dark)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        lum_o = np.asarray(direct, np.float64).mean(-1)
        lum_u = np.asarray(unoccluded, np.float64).mean(-1)
        frac = np.where(lum_u > 1e-6 * max(lum_u.max(), 1e-30), lum_o / lum_u, 1.0)
    return np.clip(frac, 0, 1).astype(np.float32)


@dataclass
class GroundTruth:
    """Named float32 arrays plus metadata (scene hash, variant, spp, seed, versions, timings, noise).

    Every Monte Carlo array ``X`` (rendered passes, and the footprint-averaged AOVs albedo,
    normals, depth, coverage and the pure mask) comes with ``G = meta["groups"]`` delete-one-group
    deviations ``X_jk0 .. X_jk{G-1}``: ``X + X_jk{i}`` is ``X`` computed from every sample group
    but ``i`` (:meth:`replicate`), and ``X_sd`` (derived on access) the per-pixel standard
    deviation of ``X``'s estimate (:func:`jackknife_sd`)."""

    arrays: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)
    reads: set = field(default_factory=set, repr=False, compare=False)   # names read (see :meth:`varies`)

    def __getitem__(self, name: str) -> np.ndarray:
        self.reads.add(name)
        try:
            return self.arrays[name]
        except KeyError:
            if name.endswith("_sd") and f"{name[:-3]}{JK}0" in self.arrays:
                return jackknife_sd(self.jk(name[:-3])).astype(np.float32)
            raise KeyError(f"ground truth has no {name!r}; it has {', '.join(sorted(self.arrays))}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.arrays or (name.endswith("_sd") and f"{name[:-3]}{JK}0" in self.arrays)

    @property
    def groups(self) -> int:
        """The number of independent sample groups (0 when the deviations were not kept)."""
        g = 0
        while f"radiance{JK}{g}" in self.arrays:
            g += 1
        return g

    def jk(self, name: str) -> np.ndarray:
        """``(G, ...)`` delete-one-group deviations of ``name``."""
        return np.stack([self.arrays[f"{name}{JK}{i}"] for i in range(self.groups)])

    def sd_of(self, name: str, fn) -> np.ndarray:
        """Per-pixel jackknife standard deviation of ``fn(X)`` (e.g. a grey conversion) for the
        array ``name``: ``sqrt((G - 1) / G * sum_i (fn(X_(i)) - mean_j fn(X_(j)))^2)``."""
        x = self.arrays[name]
        loo = np.stack([np.asarray(fn(x + self.arrays[f"{name}{JK}{i}"]), np.float64) for i in range(self.groups)])
        G = loo.shape[0]
        return np.sqrt((G - 1) / G * np.sum((loo - loo.mean(0)) ** 2, axis=0))

    @property
    def base_names(self) -> list[str]:
        """The arrays proper (without their deviations)."""
        return [n for n in self.arrays if JK not in n]

    @property
    def has_replicates(self) -> bool:
        """Whether the delete-one-group ground truths can be built (every rendered pass has its
        deviations, at least 2 groups)."""
        passes = [n for n in self.arrays if is_radiance_like(n)]
        G = self.groups
        return bool(passes) and G >= 2 and all(f"{n}{JK}{G - 1}" in self.arrays for n in passes)

    def replicate(self, group: int, *, geometry: bool = False) -> GroundTruth:
        """The ground truth computed from every sample group but ``group`` (``0 .. G-1``): every
        rendered pass with deviations is replaced by ``X + X_jk{group}``; ``indirect`` and
        ``unoccluded_fraction`` are rebuilt from the replicate's own passes; ids, position and
        metadata are shared.  Its passes have ``G / (G - 1)`` times the variance of the full
        ground truth's.

        The geometry (albedo, normals, depth, coverage and the pure mask, :data:`AOV_REPLICATED`)
        is the full ground truth's unless ``geometry``: its sample groups take fixed seeds
        (:data:`AOV_SEED`), so a run at another render seed has the same geometry, and a standard
        error that is to say how far a score moves when the scene is rendered again must not
        include it.  ``geometry=True`` replaces it by its own replicate too (its deviations are
        kept in the cache), which measures the footprint-sampling error of the geometry itself
        (the difference of a score's spread with and without it; docs/uncertainty.md)."""
        G = self.groups
        if not (isinstance(group, (int, np.integer)) and 0 <= group < G):
            raise ValueError(f"group: an integer in 0..{G - 1} (the ground truth has {G} sample groups), got {group!r}")
        arrays = {}
        for n in self.base_names:
            d = None if (n in AOV_REPLICATED and not geometry) else self.arrays.get(f"{n}{JK}{group}")
            arrays[n] = self.arrays[n] if d is None else (self.arrays[n] + d).astype(np.float32)
        if "mask" in arrays:
            arrays["mask"] = (arrays["mask"] > 0.5).astype(np.float32)
        if "radiance" in arrays and "direct" in arrays and "indirect" in self.arrays:
            arrays["indirect"] = arrays["radiance"] - arrays["direct"]
        if "unoccluded_fraction" in arrays and "direct_unoccluded" in arrays:
            arrays["unoccluded_fraction"] = unoccluded_fraction(arrays["direct"], arrays["direct_unoccluded"])
        return GroundTruth(arrays, dict(self.meta, replicate=int(group)))

    def perturbed(self, eps: float, group: int = 0) -> GroundTruth:
        """This ground truth moved by the fraction ``eps`` of the way toward its replicate without
        ``group`` (:meth:`replicate`): every array the replicate rebuilds becomes ``X + eps (X_(group)
        - X)``, the others are shared.  A score smooth in its input moves by ``eps (v_(group) - v)``
        to first order; one that moves much more is chaotic in it (:func:`pbrbench.uncertainty.chaotic`)."""
        if not (isinstance(eps, (int, float)) and 0 < eps < 1):
            raise ValueError(f"eps: a fraction in (0, 1) of the way toward the replicate, got {eps!r}")
        rep = self.replicate(group)
        arrays = dict(self.arrays)
        for n, x in rep.arrays.items():
            if x is not self.arrays[n]:
                arrays[n] = (self.arrays[n] + eps * (x - self.arrays[n])).astype(np.float32)
        return GroundTruth(arrays, dict(self.meta, perturbed=float(eps)))

    @property
    def n_lights(self) -> int:
        return int(self.meta.get("n_light_set", 0))

    def light_stack(self, kind: str = "radiance") -> np.ndarray:
        """(K, H, W, 3) per-light images of the light set (``kind`` = radiance or direct)."""
        names = [f"light{k:02d}.{kind}" for k in range(self.n_lights)]
        self.reads.update(names)
        return np.stack([self.arrays[n] for n in names])

    @property
    def mask(self) -> np.ndarray:
        self.reads.add("mask")
        return self.arrays["mask"] > 0.5

    def varies(self, group: int, names=None, *, geometry: bool = False) -> bool:
        """Whether the replicate without ``group`` (:meth:`replicate`, with the same
        ``geometry``) differs from this ground truth in any of ``names`` (default: the arrays
        read since the last :meth:`reads.clear`): a replicate that does not is the same input, so
        a job that read only those arrays scores the same on it (:mod:`pbrbench.bench.uncertainty`
        then reuses the full score)."""
        names = set(self.reads if names is None else names)
        base = set()
        for n in names:
            n = n[:-3] if n.endswith("_sd") else n
            base |= set(DERIVED.get(n, (n,)))
        if not geometry:
            base -= set(AOV_REPLICATED)
        for n in base:
            d = self.arrays.get(f"{n}{JK}{group}")
            if d is not None and np.any(d != 0):
                return True
        return False


DERIVED = {"indirect": ("radiance", "direct"), "unoccluded_fraction": ("direct", "direct_unoccluded")}


def versions() -> dict:
    """The versions a ground truth records (:func:`pbrbench.versions.versions`)."""
    from pbrbench.versions import versions as recorded

    return recorded()


def _film_arrays(scene) -> dict[str, np.ndarray]:
    bmp = scene.sensors()[0].film().bitmap()
    names = [f.name for f in bmp.struct_()]
    a = np.array(bmp, dtype=np.float32)
    return {n: a[..., i] for i, n in enumerate(names)}


class _Renderer:
    def __init__(self, spec: S.SceneSpec, quality: Quality, variant: str | None, progress=None):
        self.mi = mitsuba(variant)
        self.spec = spec
        q = require(quality)
        self.quality = q.name
        self.res = q.resolution(spec.render.resolution, spec.render.min_resolution)
        self.groups = q.groups_for(spec.render.min_groups)   # independent sample groups of every pass
        self.spp = q.spp(spec.render.spp, self.groups)
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

    def render_groups(self, what: str, seed_offset: int, **kw) -> tuple[np.ndarray, np.ndarray]:
        """Mean of ``G`` independent sample groups (:meth:`pbrbench.quality.Quality.groups_for`,
        each with ``spp / G`` samples and its own seed) and the delete-one-group deviations
        ``jk`` of shape ``(G, H, W, 3)``: ``X + jk[i]`` is the mean of every group but ``i``
        (:func:`loo_deviations`).

        With a noise target (:attr:`pbrbench.quality.Quality.noise_target`) the first
        groups, at the scene's samples per pixel, are the pilot: where their relative noise over
        the lit pure pixels (:func:`pass_noise`) is above the target, every group gets the missing
        samples (noise ~ 1/sqrt(spp)), at most ``max_spp`` in all, rendered with seeds of its own
        and merged into the group weighted by samples, so no sample is wasted."""
        mi = self.mi
        G = self.groups
        per = max(1, self.spp // G)
        # samplers such as multijitter round the count up (with a warning): use what they take
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)
        try:
            scene = mi.load_dict(scene_dict(mi, self.spec, self.res, per, **kw), optimize=False)
            per = int(scene.sensors()[0].sampler().sample_count())
            groups = [np.array(mi.render(scene, seed=pass_seed(self.seed, seed_offset, g), spp=per),
                               dtype=np.float64)[..., :3]
                      for g in range(G)]
            n = per
            if self.target is not None and self.mask is not None:
                mean, jk = loo_deviations(groups)
                med, rms = pass_noise(mean, jackknife_sd(jk), self.mask)
                need = max((med / self.target[0]) ** 2, (rms / self.target[1]) ** 2)
                total = min(int(math.ceil(need * n)), max(self.max_spp // G, n))
                extra = total - n
                if extra >= max(1, n // 4):
                    top = 4_000_037   # seeds no other pass uses
                    groups = [(n * a + extra * np.array(mi.render(scene, seed=pass_seed(self.seed, seed_offset, top + g),
                                                                  spp=extra),
                                                          dtype=np.float64)[..., :3]) / (n + extra)
                              for g, a in enumerate(groups)]
                    n += extra
        finally:
            mi.set_log_level(level)
        self.spp_used = G * per
        self.spp_per_pass[what] = G * n
        del scene
        # the young generations only: a Mitsuba scene holds no reference cycle that outlives them
        # (the same kernels, the same peak memory and bit-identical passes with none at all),
        # and a full collection of this process's heap cost ~12 ms a pass, 30 % of the draft
        # library's render time with Dr.Jit's kernels cached (30.6 s against 21.8 s)
        gc.collect(1)
        self._tick(what)
        mean, jk = loo_deviations(groups)
        return mean.astype(np.float32), jk.astype(np.float32)

    def aovs(self) -> dict[str, np.ndarray]:
        """The AOVs (albedo, normals, position, depth, coverage) as the mean of ``G`` sample
        groups with their own seeds, with the delete-one-group deviations of albedo, normals,
        position, depth, coverage and the pure mask (footprint averages are Monte Carlo estimates too: at a
        curved or tilted surface, and at a silhouette, they move with the samples); plus the
        object ids and the pure-pixel mask.

        The groups' seeds are fixed (:data:`AOV_SEED`), not the scene's ``render.seed``: the
        geometry a score is measured on (its mask, normals, depth) is then a function of the scene
        file and the quality, and a run at another render seed moves only the light transport.
        The groups still differ from each other (each has its own seed); their deviations are
        kept, but the replicates a standard error comes from use the full geometry
        (:meth:`GroundTruth.replicate`).  With a seed-dependent mask,
        one silhouette pixel in or out moved the flat baseline's height error, and with it every
        SFS method that returns a flat surface, between render seeds (docs/uncertainty.md)."""
        mi = self.mi
        G = self.groups
        integ = {"type": "aov", "aovs": "alb:albedo,nn:sh_normal,pp:position,si:shape_index",
                 "cov": {"type": "path", "max_depth": 1}}
        per = max(1, self.spp // G)
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)   # samplers round some counts up, with a warning: use what they take
        try:
            scene = mi.load_dict(scene_dict(mi, self.spec, self.res, per, integrator=integ, drop_occluders=False),
                                 optimize=False)
        finally:
            mi.set_log_level(level)
        per = int(scene.sensors()[0].sampler().sample_count())
        M = np.array(scene.sensors()[0].world_transform().matrix, dtype=np.float64).reshape(4, 4)
        films = []
        for k in range(G):
            mi.render(scene, seed=pass_seed(AOV_SEED, 500, k), spp=per)
            films.append(_film_arrays(scene))
        obj_avg = [self._object_ids(scene, f["si.I"]) for f in films]  # footprint-averaged: mixed pixels -> -1
        del scene
        if all(float(f["cov.A"].max()) == 0.0 for f in films) and any(float(f["alb.R"].max()) > 0 for f in films):
            # scalar variants leave the nested integrator's alpha at 0: measure the covered fraction of
            # each pixel as the albedo AOV of the same samples with every surface white instead
            d = scene_dict(mi, self.spec, self.res, per, integrator={"type": "aov", "aovs": "w:albedo"},
                           drop_occluders=False)
            for v in d.values():
                if isinstance(v, dict) and "bsdf" in v:
                    v["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}
            white = mi.load_dict(d, optimize=False)
            for k in range(G):
                mi.render(white, seed=pass_seed(AOV_SEED, 500, k), spp=per)
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

        def mean_of(fs):
            return {k: sum(f[k].astype(np.float64) for f in fs) / len(fs) for k in fs[0]}

        cov, alb, n_cam, pos, depth = derived(mean_of(films))
        loo = [derived(mean_of(films[:i] + films[i + 1:])) for i in range(G)]
        def agreed(ids):   # a shape index every group saw alone (no mixture in the pixel in any group)
            return np.where(np.all([o == ids[0] for o in ids], axis=0), ids[0], -1)

        obj_loo = [agreed(obj_avg[:i] + obj_avg[i + 1:]) for i in range(G)]
        obj_avg = agreed(obj_avg)
        # object ids from a one-sample pass (ids must not be averaged across an edge), with a fixed
        # seed: the map of pixels to shapes is a function of the geometry, not a Monte Carlo estimate,
        # so the pure mask moves with the render seed only through the coverage, which every
        # replicate has its own of (a seed-dependent id pass moved it between render seeds in a way
        # no replicate saw: SFS scores 5x their standard error apart)
        integ1 = {"type": "aov", "aovs": "si:shape_index"}
        scene = mi.load_dict(scene_dict(mi, self.spec, self.res, 1, integrator=integ1, sampler="independent"), optimize=False)
        mi.render(scene, seed=OBJECT_ID_SEED, spp=1)
        obj = np.maximum(self._object_ids(scene, _film_arrays(scene)["si.I"]), 0)
        del scene
        gc.collect(1)
        # pure pixels: fully covered and not on a boundary between two objects (there the
        # footprint-averaged AOVs are mixtures), and the footprint-averaged index equals the
        # point-sampled one (no mixture inside the pixel); each replicate has its own coverage
        pad = np.pad(obj, 1, mode="edge")
        same = np.ones(obj.shape, bool)
        for di, dj in ((0, 1), (2, 1), (1, 0), (1, 2)):
            same &= pad[di:di + obj.shape[0], dj:dj + obj.shape[1]] == obj
        fixed = same & (obj > 0) & (obj_avg == obj)
        pure = (cov > 0.999) & fixed
        self._tick("aovs")
        out = {"albedo": alb.astype(np.float32), "normals": n_cam.astype(np.float32),
               "position": pos.astype(np.float32), "depth": depth.astype(np.float32),
               "coverage": cov.astype(np.float32), "mask": pure.astype(np.float32),
               "object_id": obj}
        for i, (c_i, a_i, n_i, p_i, d_i) in enumerate(loo):
            pure_i = (c_i > 0.999) & same & (obj > 0) & (obj_loo[i] == obj)
            for name, full, rep in (("albedo", alb, a_i), ("normals", n_cam, n_i), ("position", pos, p_i), ("depth", depth, d_i),
                                    ("coverage", cov, c_i), ("mask", pure.astype(np.float64), pure_i.astype(np.float64))):
                out[f"{name}{JK}{i}"] = (rep - full).astype(np.float32)
        return out

    def _object_ids(self, scene, si: np.ndarray) -> np.ndarray:
        """Map Mitsuba's ``shape_index`` AOV to 0 (background / emitters), k + 1 (shape k), or -1
        where the value is no shape's index (an average across several shapes).

        ``shape_index`` is the 1-based position in ``scene.shapes()`` in scalar variants and the
        shape's JIT registry id in LLVM/CUDA ones (docs/rendering.md): map each scene with
        its own table.  The film stores a pixel's weighted mean of its samples' indices in
        float32, so a pixel that sees one shape holds its index only to rounding (2.9999998 for
        3, in an order of accumulation that varies between runs): a value within
        :data:`ID_TOLERANCE` (relative) of an index is that shape.  Compared exactly, the shapes
        of odd indices other than 1 fell out of the pure mask of every multi-shape scene, in some
        runs and not others.
        """
        mi = self.mi
        if mi.variant().startswith("scalar"):
            idmap = {i + 1: s.id() for i, s in enumerate(scene.shapes())}
        else:
            import drjit as dr

            idmap = {int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]): s.id() for s in scene.shapes()}
        keys = {shape_key(self.spec, i): i + 1 for i in range(len(self.spec.shapes))}
        si = np.asarray(si, np.float64)
        out = np.where(si == 0, 0, -1).astype(np.float32)
        for raw, sid in idmap.items():
            out[np.abs(si - raw) <= ID_TOLERANCE * max(raw, 1)] = keys.get(sid, 0)  # emitters (area lights) -> 0
        return out


def pass_noise(image: np.ndarray, sd: np.ndarray, mask: np.ndarray | None = None, lit: float = 0.05) -> tuple[float, float]:
    """Median and RMS relative sd ``sd / image`` (channel means) over the *lit pure* pixels:
    inside ``mask`` (the ground truth's pure pixels) and above ``lit`` of the pass's peak there —
    the pixels the tasks measure (shadowed and silhouette pixels are left to the tasks' own
    domains).  Without a mask (or no lit pure pixel) every pixel above ``lit`` of the peak counts."""
    lum = np.asarray(image, np.float64).mean(-1)
    sd = np.abs(np.asarray(sd, np.float64)).mean(-1)
    m = np.asarray(mask, bool) if mask is not None else np.ones(lum.shape, bool)
    if not m.any() or lum[m].max() <= 0:
        m = np.ones(lum.shape, bool)
    sel = m & (lum > lit * max(float(lum[m].max()), 1e-30))
    if not sel.any():
        return 0.0, 0.0
    rel = sd[sel] / lum[sel]
    return float(np.median(rel)), float(np.sqrt(np.mean(rel ** 2)))


def relative_noise(image: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """Per-pixel relative sd ``sd / image`` (channel means) over the pixels above 1e-3 of
    the image's peak (the lit pixels)."""
    lum = np.asarray(image, np.float64).mean(-1)
    sd = np.abs(np.asarray(sd, np.float64)).mean(-1)
    sig = lum > 1e-3 * max(float(lum.max()), 1e-30)
    return sd[sig] / lum[sig] if sig.any() else np.zeros(1)


def noise_summary(arrays: dict, jks: dict, spec) -> dict:
    """Median and RMS relative sd of the radiance, and of the passes the tasks consume (the
    per-light passes when the scene has a light set, else radiance and direct); ``jks``: each
    pass's delete-one-group deviations."""
    rel = relative_noise(arrays["radiance"], jackknife_sd(jks["radiance"]))
    if spec.light_set:
        names = [f"light{k:02d}.{kind}" for k in range(len(spec.light_set)) for kind in ("direct", "radiance")]
    else:
        names = ["radiance", "direct"]
    mask = arrays["mask"] > 0.5 if "mask" in arrays else None
    lit = np.array([pass_noise(arrays[n], jackknife_sd(jks[n]), mask) for n in names])
    G = jks["radiance"].shape[0]
    return {
        "radiance_rel_sd_rms": float(np.sqrt(np.mean(rel ** 2))),
        "radiance_rel_sd_median": float(np.median(rel)),
        "inputs_rel_sd_median": float(lit[:, 0].max()),
        "inputs_rel_sd_rms": float(lit[:, 1].max()),
        "inputs": names,
        "note": f"per-pixel sd of the image estimate from {G} independent sample groups (jackknife), relative "
                "to the pixel value; radiance: pixels above 1e-3 of the peak; inputs: the passes the tasks consume, "
                "over their lit pure pixels (mask, above 5 % of the pass's peak), the worst pass",
    }


def render_ground_truth(spec: S.SceneSpec, quality: Quality, *, variant: str | None = None,
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
    jks: dict[str, np.ndarray] = {}

    def put(name, mean_jk):
        arrays[name], jks[name] = mean_jk

    # Where the light set is every light of the scene, the all-lights passes are the sums of the
    # per-light ones (light transport is linear in the sources; the sample groups line up, so the
    # delete-one-group deviations add too): no render of their own.  The sum is less noisy than one
    # all-lights render at the same samples, which spends each sample on one of the sources.
    # ``pbrbench validate`` (proof 5) checks the sum against an independent all-lights render.
    summed = bool(spec.light_set) and not spec.lights
    if not summed:
        put("radiance", r.render_groups("radiance", 0, integrator=path))
        if direct_only:
            arrays["direct"], jks["direct"] = arrays["radiance"], jks["radiance"]
            r._tick("direct (= radiance)")
        else:
            put("direct", r.render_groups("direct", 0, integrator=direct))
    for k, light in enumerate(spec.light_set):
        n = f"light{k:02d}"
        put(f"{n}.radiance", r.render_groups(f"light {k}", 10 + k, integrator=path, lights=[light]))
        if direct_only:
            arrays[f"{n}.direct"], jks[f"{n}.direct"] = arrays[f"{n}.radiance"], jks[f"{n}.radiance"]
            r._tick(f"light {k} direct (= radiance)")
        else:
            put(f"{n}.direct", r.render_groups(f"light {k} direct", 10 + k, integrator=direct, lights=[light]))
    if summed:
        ks = range(len(spec.light_set))
        for kind, what in (("radiance", "light {}"), ("direct", "light {} direct")):
            if kind == "direct" and direct_only:   # the per-light direct passes are the radiance ones
                arrays["direct"], jks["direct"] = arrays["radiance"], jks["radiance"]
                r.spp_per_pass["direct"] = r.spp_per_pass["radiance"]
            else:
                arrays[kind] = np.sum([arrays[f"light{k:02d}.{kind}"].astype(np.float64) for k in ks],
                                      axis=0).astype(np.float32)
                jks[kind] = np.sum([jks[f"light{k:02d}.{kind}"].astype(np.float64) for k in ks],
                                   axis=0).astype(np.float32)
                r.spp_per_pass[kind] = sum(r.spp_per_pass[what.format(k)] for k in ks)
            r._tick(f"{kind} (= the sum of the lights)")
    arrays["indirect"] = arrays["radiance"] - arrays["direct"]
    if spec.has_occluders:
        put("direct_unoccluded", r.render_groups("unoccluded", 0, integrator=direct, drop_occluders=True))
        arrays["unoccluded_fraction"] = unoccluded_fraction(arrays["direct"], arrays["direct_unoccluded"])
    if spec.has_glossy:
        put("diffuse_only", r.render_groups("diffuse-only twin", 0, integrator=path, diffuse_only=True))
    noise = noise_summary(arrays, jks, spec)
    for name, jk in jks.items():
        for i in range(jk.shape[0]):
            arrays[f"{name}{JK}{i}"] = jk[i]

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
        "groups": r.groups,
        "noise": noise,
    }
    return GroundTruth({k: np.ascontiguousarray(v, dtype=np.float32) for k, v in arrays.items()}, meta)
