"""The HDR task on a synthetic high-dynamic-range ramp."""

from __future__ import annotations

import numpy as np

from pbrbench.tasks.base import Job
from tests.fakes import (
    hdr_gt,
    run_task,
    scores_of,
)


def test_hdr_camera_conditions():
    from pbrbench.tasks.hdr import camera_setup

    rad = np.geomspace(1e-3, 10, 1000)
    cam, t = camera_setup("global+3x3stops", rad)
    assert len(t) == 3 and np.allclose(t[1:] / t[:-1], 8)
    cam, t = camera_setup("global+noise0", rad)
    assert np.allclose(t[1:] / t[:-1], 2) and cam.read_noise == 0 and cam.full_well is None
    cam, _ = camera_setup("global+readnoise0.002", rad)
    assert cam.read_noise == 0.002 and cam.full_well is not None


def test_hdr_true_response_floor_beats_ignoring_the_response():
    from pbrbench.tasks.hdr import TASK

    res = run_task(TASK, Job("hdr", "hdr_scene", "global+noise0"), {"hdr_scene": hdr_gt()})
    sc = scores_of(res)
    assert sc[("floor:true_response", "log2_rmse")] < 0.05
    assert sc[("baseline:ignore_response", "log2_rmse")] > 2 * sc[("floor:true_response", "log2_rmse")]
    for alg in ("debevec1997", "robertson2003", "mitsunaga1999"):
        assert sc[(alg, "invalid_fraction")] == 0 and np.isfinite(sc[(alg, "log2_rmse")])
        assert sc[(alg, "response_rmse")] < sc[("baseline:ignore_response", "response_rmse")]
    plot = res.plots["inverse response (green channel)"]
    assert len(plot["x"]) == 256 and {"true", "debevec1997", "baseline:ignore_response"} <= set(plot["series"])

