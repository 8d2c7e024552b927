"""The photometric-stereo task's own inputs of standard renders, for the scripts beside it."""

from __future__ import annotations

import numpy as np

CONDITIONS = ("local", "global", "local+noise0.01")


def ps_inputs(scenes, cache=None, conditions=CONDITIONS, seed: int = 0, render_seed: int = 0,
              library=None):
    """Yield ``(scene, condition, images, lights, mask, domain, true normals)`` per scene and
    condition: the task's inputs (``_inputs``, noise seed ``seed``) and evaluation domain on the
    standard renders of ``cache`` (pbrbench's cache by default; a missing scene is rendered) at
    render seed ``render_seed``, from ``library`` (pbrbench's own by default)."""
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.settings import Settings
    from pbrbench.tasks.base import Job
    from pbrbench.tasks.photometric_stereo import PhotometricStereoTask

    lib = library or SceneLibrary()
    task = PhotometricStereoTask().bind(lib)
    src = GroundTruthSource(get_quality("standard"), cache=RenderCache(cache or Settings.from_env().cache), library=lib,
                             render_seed=render_seed)
    specs = src.specs(list(scenes))
    for name in scenes:
        gt = src.load(specs[name])
        params = task._params(lib.spec(name))
        lights = np.asarray(dict(params)["lights"], float)
        domain, n_true = task._domain(gt, lights), gt["normals"].astype(float)
        for cond in conditions:
            yield name, cond, task._inputs(Job(task.name, name, cond, params), gt, seed), lights, gt.mask, domain, n_true
