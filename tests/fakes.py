"""Shared fakes of the test suite: a synthetic ground-truth source and task (no renderer), and
synthetic ground truths for every task built in NumPy from analytic surfaces."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pbrbench.bench.source import GroundTruthSource
from pbrbench.quality import DRAFT
from pbrbench.registry import Algorithm
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.report.figures import slug
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.mondrian import cast_shadow, mondrian_scene
from pbrbench.shading.surfaces import on_grid
from pbrbench.tasks.base import Job, JobResult, Task
from pbrbench.tasks.common.inputs import as_param
from pbrbench.tasks.common.scoring import ScoreBook

EVIL = "<script>alert('x')</script>"
HW = 1.05
FIVE = np.array([[0, 0, 1], [0.6, 0, 0.8], [-0.6, 0, 0.8], [0, 0.6, 0.8], [0, -0.6, 0.8]], float)


# ----------------------------------------------------------------------------- source and task
@dataclass(frozen=True)
class FakeSpec:
    name: str

    @property
    def render(self):
        """The render settings the runner reads (``spp``: the file's samples per pixel; the fake
        ground truths have 4, the file 64, so a fake run is one below its files' samples)."""
        from types import SimpleNamespace

        return SimpleNamespace(spp=64)

    def content_hash(self) -> str:
        return "hash-" + self.name


class FakeCache:
    def __init__(self, root):
        self.root = Path(root)


class FakeSource(GroundTruthSource):
    """Synthetic ground truths; 'rendering' writes a marker file so the cache check is real."""

    def __init__(self, root, quality=DRAFT):
        super().__init__(quality, cache=FakeCache(root), variant="fake")

    def specs(self, names):
        return {n: FakeSpec(n) for n in names}

    def _file(self, spec):
        return self.cache.root / f"{slug(spec.name)}.json"

    def cached_meta(self, spec):
        p = self._file(spec)
        return json.loads(p.read_text()) if p.is_file() else None

    def render(self, spec):
        meta = self.cached_meta(spec)
        if meta is not None:
            return meta, True
        meta = {"scene_hash": spec.content_hash(), "quality": self.quality.name, "spp": 4, "resolution": [16, 12],
                "noise": {"radiance_rel_sd_rms": 0.01, "radiance_rel_sd_median": 0.005}, "wall_s": 0.0}
        self.cache.root.mkdir(parents=True, exist_ok=True)
        self._file(spec).write_text(json.dumps(meta))
        return meta, False

    def load(self, spec):
        rng = np.random.default_rng(sum(map(ord, spec.name)))
        rad = rng.uniform(0.1, 1.0, (12, 16, 3)).astype(np.float32)
        return GroundTruth({"radiance": rad, "direct": 0.8 * rad, "radiance_sd": 0.01 * rad,
                            "direct_sd": 0.008 * rad}, {"scene_hash": spec.content_hash()})


def good_estimate(truth, *, seed=0, scene="", condition=""):
    """A fake algorithm: the truth plus seeded noise."""
    rng = np.random.default_rng([seed, len(scene), len(condition)])
    return truth + 0.01 * rng.standard_normal(truth.shape)


def zero_estimate(truth, *, seed=0, scene="", condition=""):
    """A fake baseline: zero."""
    return np.zeros_like(truth)


class FakeTask(Task):
    """Scores ``rmse`` (lower) and ``psnr``-like ``coverage`` (higher) of fake estimates of the
    radiance (global) or direct (local) image."""

    name = "fake"
    description = f"A fake task {EVIL}"
    conditions = ("local", "global")
    headline_metric = "height_rmse"
    scenes = ("scene_a", "scene_b")
    fail_scene = None

    def builtin_algorithms(self):
        return [Algorithm("good", self.name, good_estimate),
                Algorithm("baseline:zero", self.name, zero_estimate, kind="baseline")]

    def jobs(self, quality):
        return [Job(self.name, s, c) for s in self.scenes for c in self.conditions]

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        if job.scene == self.fail_scene:
            raise RuntimeError("deliberate failure")
        gt = gts[job.scene]
        truth = gt["radiance"] if job.condition == "global" else gt["direct"]
        out = JobResult(job)
        book = ScoreBook(job, gt.meta["scene_hash"], algorithms)
        ests = {}
        for alg in algorithms:
            est = alg(truth, seed=seed, scene=job.scene, condition=job.condition, quality=quality)
            ests[alg.name] = est
            err = np.abs(est - truth).mean(-1)
            rmse = float(np.sqrt((err ** 2).mean()))
            book.add(alg.name, {"height_rmse": rmse, "coverage": float(-20 * np.log10(rmse + 1e-12))}, 0.001)
            out.error_maps[f"{alg.name} |error|"] = err
        out.scores = book.scores
        out.images["input"] = np.clip(truth, 0, 1)
        out.images["linear:truth"] = truth
        out.images[EVIL] = np.clip(truth[..., 0], 0, 1)
        if "good" in ests:
            out.plots["profile"] = {"x": list(range(16)), "series": {"truth": truth[6, :, 0].tolist(),
                                                                       "good": ests["good"][6, :, 0].tolist()},
                                    "xlabel": "column", "ylabel": "radiance"}
        return out


def settings_for(tmp_path, **kw):
    """Settings that keep a test's reports, store and render cache inside ``tmp_path``."""
    from pbrbench.settings import Settings

    return Settings.from_env(**{"out": tmp_path / "reports", "store": tmp_path / "h.sqlite",
                                "cache": tmp_path / "render-cache", "progress": False, **kw})


def fake_run(tmp_path, task=None, *, registry=None, **kw):
    from pbrbench.bench.run import RunConfig, run_benchmark

    task = task or FakeTask()
    return run_benchmark(RunConfig(quality="draft", **kw), settings=settings_for(tmp_path), tasks={"fake": task},
                         source=FakeSource(tmp_path / "cache"), registry=registry, log=lambda m: None)


# ----------------------------------------------------------------------------- ground truths
def ps_gt(surface="sphere", size=40, albedo=0.6, lights=FIVE, gi_gain=1.0):
    """Per-light Lambertian radiance images (E = pi) of an analytic surface; ``radiance`` passes are
    the direct ones times ``gi_gain`` (a stand-in for interreflection inflating brightness)."""
    s = on_grid(surface, size, HW)
    vec = np.asarray(lights, float) * np.pi
    imgs = lambertian_images(s.normals, albedo, vec, mask=s.mask, radiance=True)
    arr = {}
    for k in range(len(vec)):
        im = np.repeat(imgs[k][..., None], 3, -1).astype(np.float32)
        arr[f"light{k:02d}.direct"] = im
        arr[f"light{k:02d}.radiance"] = (im * gi_gain).astype(np.float32)
    arr["direct"] = sum(arr[f"light{k:02d}.direct"] for k in range(len(vec)))
    arr["radiance"] = arr["direct"] * gi_gain
    arr["normals"] = s.normals.astype(np.float32)
    arr["albedo"] = np.repeat(np.where(s.mask, albedo, 0.0)[..., None], 3, -1).astype(np.float32)
    arr["depth"] = np.where(s.mask, 5.0 - s.z, 0.0).astype(np.float32)
    arr["mask"] = s.mask.astype(np.float32)
    return GroundTruth(arr, {"scene_hash": f"synthetic-{surface}", "n_light_set": len(vec)}), vec


def ps_job(cond="local", lights=None, scene="s", **extra):
    lights = FIVE * np.pi if lights is None else lights
    return Job("photometric_stereo", scene, cond,
               (("lights", as_param(lights)), ("half_width", HW)) + tuple(extra.items()))


def mondrian_gt(size=64, colour=False, shadow=False):
    d = mondrian_scene(size, seed=0, colour=colour, shadow=shadow, n_patches=12)
    img, alb = d["image"], d["albedo"]
    if img.ndim == 2:
        img, alb = np.repeat(img[..., None], 3, -1), np.repeat(alb[..., None], 3, -1)
    arr = {"radiance": img.astype(np.float32), "direct": img.astype(np.float32),
           "albedo": alb.astype(np.float32), "mask": np.ones((size, size), np.float32),
           "object_id": np.ones((size, size), np.float32)}
    if shadow:
        arr["unoccluded_fraction"] = cast_shadow(size).astype(np.float32)
    return GroundTruth(arr, {"scene_hash": "synthetic-mondrian"})


def sfs_gt(size=32, light=(0.7071, 0.0, 0.7071), albedo=0.8):
    s = on_grid("sphere", size, HW)
    L = np.asarray(light, float) / np.linalg.norm(light)
    img = np.where(s.mask, np.clip(s.normals @ L, 0, None) * albedo, 0.0)  # rho E cos / pi, E = pi
    im3 = np.repeat(img[..., None], 3, -1).astype(np.float32)
    arr = {"light00.direct": im3, "light00.radiance": im3 * 1.1, "direct": im3, "radiance": im3,
           "normals": s.normals.astype(np.float32),
           "albedo": np.repeat(np.where(s.mask, albedo, 0.0)[..., None], 3, -1).astype(np.float32),
           "depth": np.where(s.mask, 5.0 - s.z, 0.0).astype(np.float32), "mask": s.mask.astype(np.float32)}
    job = Job("sfs", "sfs_sphere", "local",
              (("light", as_param(L)), ("irradiance", np.pi), ("light_index", 0), ("label", "oblique"),
               ("half_width", HW)))
    return GroundTruth(arr, {"scene_hash": "synthetic-sfs", "n_light_set": 1}), job


def hdr_gt(size=24):
    rng = np.random.default_rng(0)
    ramp = 1e-3 * 10 ** (4 * np.linspace(0, 1, size))[None, :] * np.ones((size, 1))
    rad = (ramp[..., None] * rng.uniform(0.5, 1.0, (size, size, 3))).astype(np.float32)
    return GroundTruth({"radiance": rad, "direct": rad, "mask": np.ones((size, size), np.float32)},
                       {"scene_hash": "synthetic-hdr"})


def specular_gt(size=64):
    s = on_grid("sphere", size, 1.1)
    L = np.array([0.5, 0.5, 0.7071])
    L /= np.linalg.norm(L)
    H = (L + [0, 0, 1]) / np.linalg.norm(L + [0, 0, 1])
    diffuse = np.where(s.mask[..., None], np.clip(s.normals @ L, 0, None)[..., None] * [0.54, 0.3, 0.18], 0.0)
    spec = np.where(s.mask, 2.0 * np.clip(s.normals @ H, 0, None) ** 200, 0.0)
    arr = {"radiance": (diffuse + spec[..., None]).astype(np.float32), "diffuse_only": diffuse.astype(np.float32),
           "mask": s.mask.astype(np.float32)}
    return GroundTruth(arr, {"scene_hash": "synthetic-specular"})


def scores_of(res: JobResult) -> dict:
    return {(s.algorithm, s.metric): s.value for s in res.scores}


def run_task(task, job, gts, *, seed=0, quality="draft", registry=None):
    """``task.run_job`` with the task's built-in algorithms (or ``registry``'s)."""
    from pbrbench.quality import get_quality
    from pbrbench.registry import builtin_registry

    reg = registry or builtin_registry({task.name: task})
    return task.run_job(job, gts, seed=seed, algorithms=reg.for_task(task.name), quality=get_quality(quality))


def with_groups(gt, sigma: float, *, seed: int = 0, groups: int = 4):
    """``gt`` with every rendered pass split into ``groups`` noisy sample groups (relative noise
    ``sigma`` of the mean): the passes become the groups' mean and get their delete-one-group
    deviations, as a Mitsuba ground truth has (:mod:`pbrbench.render.groundtruth`)."""
    from pbrbench.render.groundtruth import JK, is_radiance_like, loo_deviations

    rng = np.random.default_rng(seed)
    arr = dict(gt.arrays)
    for n, a in gt.arrays.items():
        if not is_radiance_like(n):
            continue
        gs = [a * (1 + sigma * np.sqrt(groups) * rng.standard_normal(a.shape)) for _ in range(groups)]
        m, jk = loo_deviations(gs)
        arr[n] = m.astype(np.float32)
        for i in range(groups):
            arr[f"{n}{JK}{i}"] = jk[i].astype(np.float32)
    if "radiance" in arr and "direct" in arr and "indirect" in arr:
        arr["indirect"] = arr["radiance"] - arr["direct"]
    return GroundTruth(arr, dict(gt.meta))


# ------------------------------------------------------------------ one photometric-stereo job
def _ps_task_class():
    from pbrbench.tasks.photometric_stereo import PhotometricStereoTask

    class TinyPS(PhotometricStereoTask):
        """The photometric-stereo task on one synthetic sphere (no renderer)."""

        fail_once = None   # a file: the job fails while it does not exist (then it is created)

        def jobs(self, quality):
            return [ps_job("local", scene="s")]

        def run_job(self, job, gts, **kw):
            if self.fail_once is not None and not self.fail_once.exists():
                self.fail_once.write_text("failed once")
                raise RuntimeError("interrupted")
            return super().run_job(job, gts, **kw)

    TinyPS.__module__, TinyPS.__qualname__ = __name__, "TinyPS"   # picklable by reference
    return TinyPS


def __getattr__(name):       # TinyPS made on first use: importing tests.fakes imports no task
    if name == "TinyPS":
        globals()["TinyPS"] = cls = _ps_task_class()
        return cls
    raise AttributeError(name)


class SphereSource(FakeSource):
    """The synthetic sphere of :func:`ps_gt` for every scene; ``groups``: with sample groups
    (relative noise 0.01), so the jobs get standard errors."""

    def __init__(self, root, quality=DRAFT, *, groups: bool = False):
        super().__init__(root, quality)
        self.groups = groups

    def load(self, spec):
        gt, _ = ps_gt()
        if self.groups:
            gt = with_groups(gt, 0.01)
        gt.meta["scene_hash"] = spec.content_hash()
        return gt


class SlowTask(FakeTask):
    """:class:`FakeTask` on 6 scenes (12 jobs) whose jobs append ``pid ppid job`` to a log file
    when they start and then sleep ``delay`` seconds; the scores depend on neither (for the Dask
    executor's tests and fault corpus)."""

    scenes = tuple(f"scene_{c}" for c in "abcdef")

    def __init__(self, delay: float = 0.0, log: str | None = None):
        self.delay, self.log = delay, log

    def run_job(self, job, gts, **kw):
        import os
        import time

        if self.log:
            with open(self.log, "a") as fh:
                fh.write(f"{os.getpid()} {os.getppid()} {job.key}\n")
        time.sleep(self.delay)
        return super().run_job(job, gts, **kw)
