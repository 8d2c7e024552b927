"""The lightness task on synthetic Mondrians."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.tasks.base import Job
from tests.fakes import (
    mondrian_gt,
    run_task,
    scores_of,
)


def test_lightness_retinex_beats_baselines_and_anchor_rules_differ():
    from pbrbench.tasks.lightness import TASK

    res = run_task(TASK, Job("lightness", "m", "local", (("paper_ids", (1,)),)), {"m": mondrian_gt()})
    sc = scores_of(res)
    for alg in ("blake1985", "blake1985:mean"):
        assert sc[(alg, "lmse")] < 0.1 * sc[("baseline:image_is_reflectance", "lmse")]
        assert sc[(alg, "lmse")] < 0.1 * sc[("baseline:uniform_reflectance", "lmse")]
    # same decomposition up to scale, different constants of integration
    assert sc[("blake1985:mean", "lmse")] == pytest.approx(sc[("blake1985", "lmse")], rel=1e-6)
    assert sc[("blake1985:mean", "albedo_abs_err")] != pytest.approx(sc[("blake1985", "albedo_abs_err")], rel=0.1)
    assert sc[("blake1985:subtract", "ratio_err_max")] < 0.02
    # a uniform reflectance gets every ratio between papers wrong
    assert sc[("baseline:uniform_reflectance", "ratio_err_max")] > 10 * sc[("blake1985:subtract", "ratio_err_max")]
    (plot,) = res.plots.values()
    assert plot["note"] == "middle row" and len(plot["x"]) == 64


def test_lightness_cast_shadow_is_the_failure_and_is_profiled():
    from pbrbench.tasks.lightness import TASK

    job = Job("lightness", "m", "local", (("paper_ids", (1,)),))
    clean = scores_of(run_task(TASK, job, {"m": mondrian_gt()}))
    res = run_task(TASK, job, {"m": mondrian_gt(shadow=True)})
    shadow = scores_of(res)
    assert shadow[("blake1985", "lmse")] > 10 * clean[("blake1985", "lmse")]
    (plot,) = res.plots.values()
    frac = np.array(plot["series"]["unoccluded fraction"], float)
    assert plot["note"] == "row crossing the cast shadow" and frac.min() < 0.5 < frac.max()


def test_lightness_colour_keeps_channels():
    from pbrbench.tasks.lightness import TASK

    res = run_task(TASK, Job("lightness", "m", "global", (("paper_ids", (1,)),)), {"m": mondrian_gt(colour=True)})
    assert res.images["reflectance: truth"].shape[-1] == 3
    assert scores_of(res)[("blake1985:subtract", "lmse")] < 1e-3


def test_lightness_scores_only_the_paper():
    from pbrbench.tasks.lightness import TASK

    job = Job("lightness", "m", "local", (("paper_ids", (1,)),))
    ref = scores_of(run_task(TASK, job, {"m": mondrian_gt()}))
    gt = mondrian_gt()
    gt.arrays["object_id"][:6, :6] = 2  # another object (an occluder seen by the camera)
    gt.arrays["direct"][:6, :6] = 50.0
    gt.arrays["albedo"][:6, :6] = 0.02
    sc = scores_of(run_task(TASK, job, {"m": gt}))
    assert sc[("blake1985", "lmse")] < 3 * ref[("blake1985", "lmse")]
    wrong = scores_of(run_task(TASK, Job("lightness", "m", "local", (("paper_ids", (1, 2)),)), {"m": gt}))
    assert wrong[("blake1985", "albedo_abs_err")] > 2 * sc[("blake1985", "albedo_abs_err")]


def test_lightness_labels():
    from pbrbench.tasks.lightness import patch_labels

    a = np.array([[0.1, 0.1, 0.5], [0.9, 0.5, 0.5]])
    lab = patch_labels(a, np.array([[True, True, True], [True, True, False]]))
    assert lab[0, 0] == lab[0, 1] != lab[0, 2] and lab[1, 1] == lab[0, 2] and lab[1, 2] == -1

