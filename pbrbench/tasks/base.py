"""What a benchmark task is: scenes, inputs made from ground truth, algorithms, metrics, conditions.

A task module ``pbrbench/tasks/<name>.py`` defines a subclass of :class:`Task` and an instance
``TASK`` (discovered by :func:`pbrbench.tasks.get_tasks`).

The runner (:mod:`pbrbench.bench`) asks a task for its :class:`Job` list at a quality profile,
makes sure the ground truths each job needs are rendered (render cache), and calls
:meth:`Task.run_job` (possibly in a worker process, so jobs are pure functions of their inputs)
with the task's algorithms from the registry (:mod:`pbrbench.registry`).  A task never branches
on an algorithm's name: it calls every algorithm it is given with the task's calling convention
(``docs/adding.md``), checks what comes back, and scores it with the functions of
:mod:`pbrbench.metrics`, whose tables give each metric its direction and unit.  An algorithm that
raises or returns something unusable is scored as ``failed`` with its message; the job goes on.

Light-transport conditions (the columns of the report's headline table):

* ``local``  -- direct light from distant sources: the local shading model's own assumptions;
* ``area``   -- area / nearby sources (distant-source model violated);
* ``global`` -- full interreflection (global illumination);
plus, where a task needs it, modifiers appended as ``<condition>+noise<level>`` etc.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

CONDITIONS = ("local", "area", "global")


@dataclass(frozen=True)
class Job:
    """One unit of work: every algorithm of a task on one scene under one condition."""

    task: str
    scene: str                       # SceneSpec name (ground truth needed)
    condition: str                   # one of CONDITIONS, optionally "+noise0.01" etc.
    params: tuple = ()               # hashable extra parameters: tuple of (key, value) pairs
    extra_scenes: tuple[str, ...] = ()  # further ground truths the job needs (e.g. a twin)

    @property
    def key(self) -> str:
        p = ",".join(f"{k}={v}" for k, v in self.params)
        return f"{self.task}|{self.scene}|{self.condition}|{p}"

    def param(self, name: str, default=None):
        return dict(self.params).get(name, default)


@dataclass(frozen=True)
class Score:
    """One number: what was measured, on what, by which algorithm, and how long it took.

    ``uncertainty`` is one standard error of ``value`` (NaN when none was estimated) on ``dof``
    degrees of freedom and ``bias`` the estimated Monte Carlo bias of ``value``, from the replicate
    values ``replicates`` (the delete-one-group ground truths) and ``rep_noise`` (a second seed);
    ``unstable`` says the replicates are bimodal: :mod:`pbrbench.bench.uncertainty`.
    """

    task: str
    scene: str
    scene_hash: str
    condition: str
    algorithm: str
    algorithm_version: str
    metric: str
    value: float
    seconds: float
    better: str                      # "lower" or "higher": the direction of improvement (no default)
    unit: str = ""
    uncertainty: float = float("nan")
    dof: float = 0.0
    bias: float = float("nan")
    replicates: tuple | None = None
    rep_noise: float | None = None
    unstable: bool | None = None

    def __post_init__(self):
        if self.better not in ("lower", "higher"):
            raise ValueError(f"score {self.metric!r}: better={self.better!r}; the metrics table says 'lower' or 'higher'")

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class JobResult:
    """Scores plus figures for the report.

    ``images``: name -> (H, W) or (H, W, 3) float array (already display-ready in [0, 1], or
    linear radiance flagged by a name starting with "linear:"); ``error_maps``: name -> (H, W)
    float array (shown with a colour bar); ``plots``: name -> dict of plot data
    (``{"x": [...], "series": {label: [...]}, "xlabel": str, "ylabel": str}``); ``failures``:
    algorithm -> the one-line reason it was scored as failed.
    """

    job: Job
    scores: list[Score] = field(default_factory=list)
    images: dict[str, np.ndarray] = field(default_factory=dict)
    error_maps: dict[str, np.ndarray] = field(default_factory=dict)
    plots: dict[str, dict[str, Any]] = field(default_factory=dict)
    failures: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Prediction:
    """One output file an external program writes per job (``pbrbench export`` / ``evaluate``).

    ``name`` is the file stem (``<name>.exr`` or ``<name>.npy``; ``.png`` also for masks,
    ``.txt`` for a number); ``shape`` a template: ``"H,W"``, ``"H,W,3"`` (H, W of the job's
    image), ``"image"`` (the shape of the input ``image``), ``"levels,C"`` or ``"K"`` (free
    sizes) or ``"scalar"``; ``kind`` ``"float"`` or ``"mask"`` (non-zero = True)."""

    name: str
    shape: str
    required: bool = True
    meaning: str = ""
    kind: str = "float"


class Task:
    """Base class; subclasses set the class attributes and implement the three methods."""

    name: str = ""
    description: str = ""
    conditions: tuple[str, ...] = CONDITIONS
    headline_metric: str = ""            # the metric shown in the headline table
    families: tuple[str, ...] = ()       # scene families (library file stems)
    short_families: tuple[str, ...] = ()  # the representative subset of short quality profiles

    reference_condition: str = "local"   # the headline's first column; effects are costs against it
    notes: str = ""                      # shown in the report (e.g. why an effect axis is absent)
    library = None                       # the SceneLibrary it reads (bind()); None: the one shipped

    def bind(self, library) -> Task:
        """This task reading the scene library ``library`` (a
        :class:`pbrbench.scene.load.SceneLibrary`): a copy, the task module's instance unchanged."""
        import copy

        t = copy.copy(self)
        t.library = library
        return t

    @property
    def scenes(self):
        """The :class:`pbrbench.scene.load.SceneLibrary` the task lists its jobs from."""
        if self.library is None:
            from pbrbench.scene.load import SceneLibrary

            return SceneLibrary()
        return self.library

    def library_spec(self, name: str):
        """The scene file's spec of ``name`` from the task's library, or None when ``name`` is not
        a library scene (a ground truth made in a test or read from disk)."""
        try:
            return self.scenes.spec(name)
        except (ValueError, OSError):
            return None

    def seed_dependent(self, job: Job) -> bool:
        """Whether the job's inputs depend on the seed (then its standard error includes a second
        seed, :mod:`pbrbench.bench.uncertainty`): a noise modifier with a positive level."""
        _, mods = parse_condition(job.condition)
        return any(v > 0 for k, v in mods.items() if "noise" in k)

    def builtin_algorithms(self) -> list:
        """The task's own :class:`pbrbench.registry.Algorithm` entries (from the methods tables)."""
        return []

    def jobs(self, quality) -> list[Job]:
        """Every job of this task at the quality profile ``quality``."""
        raise NotImplementedError

    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        """Run ``algorithms`` on job ``job`` with ground truths ``gts`` (scene name -> GroundTruth)."""
        raise NotImplementedError

    # ------------------------------------------------- export / evaluate (pbrbench.bench.external)
    # ``pbrbench export`` records the arguments run_job passes an algorithm of the main calling
    # convention and writes them to files; ``pbrbench evaluate`` scores an external program's
    # files through run_job with an algorithm that returns them, so both see the same inputs.
    input_names: tuple[str, ...] = ()       # names of the positional arguments of the main convention
    predictions: tuple[Prediction, ...] = ()  # the files a prediction of one job provides

    def export_jobs(self, quality) -> list[Job]:
        """The jobs ``pbrbench export`` writes: the scored jobs (plot jobs are left out)."""
        return [j for j in self.jobs(quality) if j.param("plot") is None]

    def frame_shape(self, inputs: dict) -> tuple[int, int]:
        """(H, W) of a job's images, from its exported ``inputs`` (default: the mask's shape)."""
        m = inputs.get("mask")
        if m is not None and np.ndim(m) == 2:
            return tuple(np.shape(m))
        a = np.asarray(inputs[self.input_names[0]])
        return tuple(a.shape[:2])

    def prediction_output(self, files: dict, inputs: dict):
        """What the algorithm would have returned, from the prediction ``files`` (name -> array)
        of one job and its ``inputs``: by default the dict itself."""
        return dict(files)

    def score_outputs(self, job: Job, gts: dict, files: dict, *, algorithm, seed: int = 0, quality=None):
        """Score predictions that do not go through the calling convention (e.g. a radiance map
        where the algorithm returns a response curve), or None to score them through run_job."""
        return None


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
