"""Calling an algorithm and recording its scores: the guarded call, its output checks, and the
score book of one job.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from pbrbench.tasks.base import Job, Score


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
