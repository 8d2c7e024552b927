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
    # level 0 records no exposure: no -40 at the black end to squash the curves
    assert all(curve[0] is None and min(x for x in curve if x is not None) > -20 for curve in plot["series"].values())
    # Fig 1.10: the bracket, the per-channel curves and the composite with its boxes
    figs = [n for n in (*res.images, *res.plots) if n.startswith("Fig 1.10")]
    assert len(figs) == 3
    (curves,) = [v for n, v in res.plots.items() if n.startswith("Fig 1.10")]
    assert {k.split(":")[0] for k in curves["series"]} == {"R", "G", "B"}


def test_fig_1_10_bracket_and_composite_on_known_images():
    from pbrbench.tasks.hdr import _log2_inverse, bracket_montage, composite_with_boxes

    imgs = np.stack([np.full((6, 5, 3), 10 * k, np.uint8) for k in range(7)])     # exposure k: level 10 k
    m = bracket_montage(imgs, 256, n=4, gap=2)
    assert m.shape == (6, 4 * 5 + 3 * 2, 3)
    assert m[0, 0, 0] == 0 and m[0, -1, 0] == pytest.approx(60 / 255)             # the shortest and the longest
    assert np.all(m[:, 5:7] == 1.0)                                                # a white gap
    assert np.isnan(_log2_inverse(np.array([0.0, 0.25, 1.0]))[0])
    assert _log2_inverse(np.array([0.0, 0.25, 1.0]))[1:].tolist() == [-2.0, 0.0]
    # a bright square top left, a dark one bottom right: each box found, each scaled to [0, 1]
    L = np.full((16, 16, 3), 1.0)
    L[:4, :4] = 1000.0 * (1 + np.arange(4))[None, :, None]
    L[12:, 12:] = 0.001 * (1 + np.arange(4))[:, None, None]
    out = composite_with_boxes(L, np.ones((16, 16), bool))
    assert out.shape[0] == 16 and out.shape[1] == 16 + 2 * (2 + 16)
    bright, dark = out[:, 18:34], out[:, 36:52]
    assert bright.max() == 1.0 and np.ptp(bright) > 0.5          # the bright box's gradient is visible
    assert dark.max() == 1.0 and np.ptp(dark[:16, :16]) > 0.5    # so is the dark one's
    assert tuple(out[0, 0]) == (1.0, 0.0, 0.0) and tuple(out[15, 15]) == (0.0, 0.3, 1.0)  # the outlines



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


def test_every_hdr_score_records_a_version_that_follows_the_merge_it_went_through(monkeypatch):
    # the merges alone recorded no version, and a calibration's radiance scores (merged by the task)
    # did not change version when its merge did
    from pbrbench import registry
    from pbrbench.tasks.hdr import TASK, default_merge

    res = run_task(TASK, Job("hdr", "hdr_scene", "global+noise0"), {"hdr_scene": hdr_gt()})
    algs = {s.algorithm for s in res.scores}
    assert {"merge:debevec1997", f"merge:{default_merge()}", "debevec1997+merge:debevec1997"} <= algs
    assert all(s.algorithm_version for s in res.scores), sorted({s.algorithm for s in res.scores if not s.algorithm_version})
    before = {a.name: a.full_version for a in TASK.builtin_algorithms()}
    real = registry.source_hash
    # another source for the debevec1997 merge only (its function's module), the calibrations unchanged
    monkeypatch.setattr(registry, "source_hash", lambda fn, *a: "edited" if getattr(fn, "__module__", "") ==
                        "pbrbench.infer.hdr.merge.debevec1997" else real(fn, *a))
    after = {a.name: a.full_version for a in TASK.builtin_algorithms()}
    moved = {n for n in before if before[n] != after[n]}
    assert {"merge:debevec1997", "debevec1997+merge:debevec1997", "robertson2003+merge:debevec1997"} <= moved
    assert not {"debevec1997", "robertson2003", f"merge:{default_merge()}"} & moved
