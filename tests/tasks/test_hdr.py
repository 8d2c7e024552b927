"""The HDR task on a synthetic high-dynamic-range ramp."""

from __future__ import annotations

import numpy as np
import pytest

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



def test_the_bracket_follows_the_scene_not_the_render_noise():
    """An emitter covering a pixel partly: its Monte Carlo value moves the brightest pixel by a
    stop between renders.  The bracket maps the emitter's radiance from the scene file, and the
    dark end is a percentile, so the times do not move with it; without an emitter in view the
    brightest pixel is the bright end."""
    from pbrbench.scene.load import resolve
    from pbrbench.tasks.hdr import camera_setup, visible_emitter_radiance

    (spec,) = resolve(["hdr_scene"])
    rng = np.random.default_rng(3)
    base = np.geomspace(0.03, 5.0, 2000)
    brackets = set()
    for coverage in (0.3, 0.5, 0.9):           # the emitter pixel's value, 1600 x its estimated coverage
        L = np.concatenate([base * rng.uniform(0.95, 1.05, base.size), [1600.0 * coverage]])
        bright = visible_emitter_radiance(spec, L)
        assert bright == 1600.0
        for cond in ("global+noise0", "global+3x3stops"):
            _, t = camera_setup(cond, L, bright)
            brackets.add((cond, len(t), round(float(t[0]), 12)))
            assert 0.8 / t[0] == pytest.approx(1600.0)            # the shortest time maps the emitter to 80 %
    assert len(brackets) == 2                                      # one bracket per condition
    # without the hint, the brightest pixel decides: the bracket moved with the noise
    assert len({len(camera_setup("global+noise0", np.concatenate([base, [1600.0 * c]]))[1]) for c in (0.3, 0.9)}) == 2
    # no emitter in view (the brightest pixel far below it), or no scene file: the pixels decide
    assert visible_emitter_radiance(spec, base) is None and visible_emitter_radiance(None, base) is None
    with pytest.raises(ValueError, match="bright"):
        camera_setup("global+noise0", base, -1.0)
