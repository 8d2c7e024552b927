"""Helpers shared by the benchmark tasks: scene families, nominal lights, noise, display images.

Everything here is a pure function of its arguments (no renderer): tasks resolve what they need
from the scene specs when they *list* jobs (:meth:`Task.jobs`), store it in the job's ``params``,
and :meth:`Task.run_job` then works from the job and the ground-truth arrays alone, so jobs can
run in worker processes and tests can build jobs from synthetic ground truths.
"""

from __future__ import annotations

import math
import time
import warnings
import zlib

import numpy as np

from pbrbench.scene.geometry import camera_rotation, light_vectors, nominal_light  # noqa: F401 (re-exported)
from pbrbench.tasks.base import Job, Score

# ------------------------------------------------------------------------------- scene lists


def family_scenes(family: str) -> list:
    """SceneSpecs of a library family (a file stem; its sweep expanded), [] if the file is absent.

    Tasks list every family of the naming contract; families the library does not have (yet)
    contribute no jobs instead of failing the whole task.
    """
    from pbrbench.scene.load import load_scene_file, scenes_dir

    path = scenes_dir() / f"{family}.toml"
    if not path.is_file():
        return []
    return load_scene_file(path)


def sweep_value(spec, key: str):
    """The value a swept spec took for ``key`` (the last part of a key path), parsed from its name
    ``family[key=value,...]``; None when the spec is not swept on it."""
    name = spec.name if not isinstance(spec, str) else spec
    if "[" not in name or not name.endswith("]"):
        return None
    for part in name[name.index("[") + 1:-1].split(","):
        k, _, v = part.partition("=")
        if k == key:
            try:
                return float(v)
            except ValueError:
                return v
    return None


# ----------------------------------------------------------------------------- light vectors
# camera_rotation, nominal_light and light_vectors live in pbrbench.scene.geometry (the render
# command's JSON uses them too) and are re-exported here for the tasks.


def as_param(a) -> tuple:
    """A float array as a nested tuple of rounded floats (hashable, for :class:`Job` params)."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        return round(float(a), 9)
    return tuple(as_param(x) for x in a)


def pixel_size(half_width: float, width: int) -> float:
    """World size of one pixel of an orthographic film ``[-half_width, half_width]`` wide."""
    return 2.0 * float(half_width) / int(width)


# ----------------------------------------------------------------------------- image helpers


def grey(img) -> np.ndarray:
    """Channel mean of an (..., 3) image (the grey level used by every task); 2-D passes through."""
    a = np.asarray(img, np.float64)
    return a.mean(axis=-1) if a.ndim >= 3 and a.shape[-1] in (3, 4) else a


def parse_condition(condition: str) -> tuple[str, dict[str, float]]:
    """``"local+noise0.01"`` -> ``("local", {"noise": 0.01})``; ``"local+3x3stops"`` ->
    ``("local", {"3x3stops": 1.0})`` (a flag without a number)."""
    base, *mods = condition.split("+")
    out: dict[str, float] = {}
    for m in mods:
        i = 0
        while i < len(m) and (m[i].isalpha() or m[i] == "_"):
            i += 1
        key, num = m[:i], m[i:]
        try:
            out[key or m] = float(num) if num and key else 1.0
        except ValueError:
            out[m] = 1.0
    return base, out


def job_rng(job: Job, seed: int) -> np.random.Generator:
    """A generator determined by ``seed`` and the job's key (stable across processes)."""
    return np.random.default_rng([int(seed), zlib.crc32(job.key.encode())])


def add_noise(images, level: float, rng: np.random.Generator, *, peak: float | None = None) -> np.ndarray:
    """Images plus Gaussian noise of standard deviation ``level`` x ``peak`` (default: the
    stack's maximum), clipped at 0 -- a linear camera with read noise ``level`` of full scale."""
    a = np.asarray(images, np.float64)
    if level <= 0:
        return a.copy()
    peak = float(a.max()) if peak is None else float(peak)
    return np.maximum(a + rng.normal(0.0, level * peak, a.shape), 0.0)


def block_mean(a: np.ndarray, factor: int) -> np.ndarray:
    """Average ``factor`` x ``factor`` blocks of an (H, W[, C]) array (edges cropped)."""
    if factor <= 1:
        return a
    h, w = a.shape[0] // factor * factor, a.shape[1] // factor * factor
    a = a[:h, :w]
    shp = (h // factor, factor, w // factor, factor) + a.shape[2:]
    return a.reshape(shp).mean(axis=(1, 3))


def display(a, max_size: int = 128) -> np.ndarray:
    """A small float32 copy of an image or map for the report (block-averaged to <= max_size)."""
    a = np.nan_to_num(np.asarray(a, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    factor = max(1, math.ceil(max(a.shape[:2]) / max_size))
    return block_mean(a, factor).astype(np.float32)


def display_map(a, mask=None, max_size: int = 128) -> np.ndarray:
    """Like :func:`display` for an error map: NaN outside ``mask`` is kept NaN (blank in the
    report) by averaging the valid values only."""
    a = np.asarray(a, np.float64)
    m = np.isfinite(a) if mask is None else (np.asarray(mask, bool) & np.isfinite(a))
    factor = max(1, math.ceil(max(a.shape[:2]) / max_size))
    num = block_mean(np.where(m, a, 0.0), factor)
    den = block_mean(m.astype(float), factor)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan).astype(np.float32)


def normals_display(n, mask=None, max_size: int = 128) -> np.ndarray:
    """Normals as display RGB ``(n + 1) / 2`` in [0, 1]; black outside ``mask``."""
    rgb = np.clip((np.asarray(n, np.float64) + 1.0) / 2.0, 0.0, 1.0)
    if mask is not None:
        rgb = np.where(np.asarray(mask, bool)[..., None], rgb, 0.0)
    return display(rgb, max_size)


def profile_plot(x, series: dict, xlabel: str, ylabel: str, **extra) -> dict:
    """Plot data in the :class:`JobResult` format, as plain lists of floats (NaN -> None)."""

    def clean(v):
        return [None if not np.isfinite(f) else float(f) for f in np.asarray(v, float).ravel()]

    out = {"x": clean(x), "series": {k: clean(v) for k, v in series.items()},
           "xlabel": xlabel, "ylabel": ylabel}
    out.update(extra)
    return out


# ----------------------------------------------------------------------------------- scoring


class ScoreBook:
    """Collects :class:`Score` records for one job (scene hash and condition filled in); the
    direction and unit of each metric come from :data:`pbrbench.metrics.METRICS`.

    ``scene_label`` replaces the job's scene name in the scores when one ground truth holds
    several cases (e.g. ``sfs_sphere:oblique`` for light 1 of the light set of ``sfs_sphere``).
    """

    def __init__(self, job: Job, scene_hash: str, algorithms=(), scene_label: str | None = None):
        self.job = job
        self.scene_label = scene_label or job.scene
        self.scene_hash = scene_hash
        self.versions = {a.name: a.full_version for a in algorithms}
        self.scores: list[Score] = []

    def add(self, algorithm: str, values: dict, seconds: float) -> None:
        """One score per ``values`` item (metric name -> value)."""
        from pbrbench.metrics import metric

        for name, value in values.items():
            m = metric(name)
            self.scores.append(Score(task=self.job.task, scene=self.scene_label, scene_hash=self.scene_hash,
                                     condition=self.job.condition, algorithm=algorithm,
                                     algorithm_version=self.versions.get(algorithm, ""), metric=name,
                                     value=float(value), seconds=float(seconds), better=m.better, unit=m.unit))


def one_line(exc: BaseException) -> str:
    """``TypeName: message`` on one line (for a failed algorithm)."""
    msg = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {msg}"[:300]


def call(alg, *args, quality=None, check=None, **kwargs):
    """Run algorithm ``alg`` (a registry entry) and check its output.

    Returns ``(output, seconds, error)``: ``error`` is None, or the one-line reason when the
    algorithm raised or ``check(output)`` refused it (``check`` converts the output to the task's
    form and raises ``ValueError`` when it is unusable).  Any exception of the algorithm is
    caught: a failing algorithm is scored as failed, the job goes on.
    """
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out = alg(*args, quality=quality, **kwargs)
        seconds = time.perf_counter() - t0
        if check is not None:
            out = check(out)
        return out, seconds, None
    except Exception as e:  # noqa: BLE001 - a user's algorithm may raise anything
        return None, time.perf_counter() - t0, one_line(e)


def check_array(a, name: str, shape: tuple, *, where=None) -> np.ndarray:
    """``a`` as a real float64 array of ``shape`` with finite values (inside ``where``); raises
    ``ValueError`` naming the output otherwise."""
    from pbrbench.checks import as_float_array, check_finite

    arr = as_float_array(a, name)
    if arr.shape != tuple(shape):
        raise ValueError(f"{name}: returned shape {arr.shape}, expected {tuple(shape)}")
    check_finite(arr, name, where=where)
    return arr


def attribute(out, name: str, index: int | None = None, default=None):
    """``out.name``, else ``out[name]`` (a dict), else ``out[index]`` (a tuple), else ``default``."""
    if hasattr(out, name):
        return getattr(out, name)
    if isinstance(out, dict):
        return out.get(name, default)
    if isinstance(out, (tuple, list)) and index is not None and index < len(out):
        return out[index]
    return default


class Timer:
    """``with Timer() as t: ...; t.seconds`` (wall clock)."""

    def __enter__(self):
        self.t0 = time.perf_counter()
        self.seconds = 0.0
        return self

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.t0
        return False


def scene_hash(gt) -> str:
    return str(getattr(gt, "meta", {}).get("scene_hash", ""))


def erode(mask, iterations: int = 1) -> np.ndarray:
    from scipy import ndimage

    m = np.asarray(mask, bool)
    if iterations <= 0:
        return m.copy()
    return ndimage.binary_erosion(m, iterations=iterations, border_value=0)
