"""The HDR task's unregistered and rough-exposure-time conditions and the histogram calibration."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from pbrbench.camera import Camera
from pbrbench.quality import get_quality
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.tasks.base import Job
from tests.fakes import hdr_gt, run_task, scores_of


def texture_gt(size=48):
    """A statistically stationary radiance (log-normal texture over ~3.5 decades): shifted crops
    have nearly the same histogram, as the chapter's unregistered exposures of one scene."""
    rng = np.random.default_rng(1)
    f = ndimage.gaussian_filter(rng.normal(size=(size, size, 1)), (4, 4, 0))
    rad = 10 ** (1.3 * (f - f.mean()) / f.std()) * np.array([0.7, 0.85, 1.0])
    return GroundTruth({"radiance": rad.astype(np.float32), "direct": rad.astype(np.float32),
                        "mask": np.ones((size, size), np.float32)}, {"scene_hash": "synthetic-texture"})


def test_new_hdr_conditions_have_jobs_at_draft_and_standard():
    from pbrbench.tasks.hdr import TASK

    for q in ("draft", "standard"):
        conds = {j.condition for j in TASK.jobs(get_quality(q))}
        assert {"global+unregistered", "global+rough_times0.07"} <= conds <= set(TASK.conditions)


def test_unregistered_bracket_is_the_offset_crops_in_closed_form():
    from pbrbench.tasks.hdr import unregistered_bracket

    rng = np.random.default_rng(0)
    rad = rng.uniform(0.01, 1.0, (20, 24, 3))
    times = np.array([0.25, 0.5, 1.0])
    offsets = np.array([[0, 0], [2, -1], [-3, 3]])
    cam = Camera("linear", bit_depth=8)
    common, reg, imgs = unregistered_bracket(cam, rad, times, offsets, shift=3)
    assert common.shape == (14, 18, 3) and imgs.shape == reg.images.shape == (3, 14, 18, 3)
    np.testing.assert_array_equal(common, rad[3:17, 3:21])
    for k, (dy, dx) in enumerate(offsets):
        # linear 8-bit camera: Z = round(255 clip(L t)); exposure k sees rad shifted by (dy, dx)
        want = np.rint(np.clip(rad[3 + dy:17 + dy, 3 + dx:21 + dx] * times[k], 0, 1) * 255)
        np.testing.assert_array_equal(imgs[k], want)
        np.testing.assert_array_equal(reg.images[k], np.rint(np.clip(common * times[k], 0, 1) * 255))
    assert np.array_equal(imgs[0], reg.images[0]) and not np.array_equal(imgs[1], reg.images[1])
    # pixel (i, j) of exposure 1 is pixel (i + 2, j - 1) of the registered one
    np.testing.assert_array_equal(imgs[1][:-2, 1:], reg.images[1][2:, :-1])


def test_the_task_shifts_the_exposures_by_its_seeded_offsets():
    from pbrbench.tasks.hdr import SHIFT, TASK

    gt = texture_gt()
    job = Job("hdr", "hdr_scene", "global+unregistered")
    rad, mask, br, domain, cov, imgs = TASK._bracket(job, gt, 0)
    assert rad.shape[:2] == (48 - 2 * SHIFT,) * 2 and imgs.shape == br.images.shape
    full = np.asarray(gt["radiance"], float)
    found = []
    for k in range(imgs.shape[0]):
        hits = [(dy, dx) for dy in range(-SHIFT, SHIFT + 1) for dx in range(-SHIFT, SHIFT + 1)
                if np.array_equal(imgs[k], Camera("film", bit_depth=8).capture(
                    full[SHIFT + dy:48 - SHIFT + dy, SHIFT + dx:48 - SHIFT + dx], br.exposure_times[k:k + 1]).images[0])]
        assert hits
        found.append(hits[0])
    assert sum(o != (0, 0) for o in found) >= len(found) // 2
    again = TASK._bracket(job, gt, 0)[5]
    np.testing.assert_array_equal(again, imgs)                       # the job's seeded generator
    assert not np.array_equal(TASK._bracket(job, gt, 1)[5], imgs)    # another seed, other offsets


def test_grossberg_nayar_beats_debevec_unregistered_and_rough_times_are_rough():
    from pbrbench.tasks.hdr import TASK, camera_setup

    gt = texture_gt()
    reg = scores_of(run_task(TASK, Job("hdr", "hdr_scene", "global+noise0"), {"hdr_scene": gt}))
    unr = scores_of(run_task(TASK, Job("hdr", "hdr_scene", "global+unregistered"), {"hdr_scene": gt}))
    assert ("grossberg_nayar2003", "failed") not in reg and ("grossberg_nayar2003", "failed") not in unr
    assert reg[("grossberg_nayar2003", "log2_rmse")] < 0.05
    assert unr[("grossberg_nayar2003", "response_rmse")] < 0.5 * unr[("debevec1997", "response_rmse")]
    assert unr[("debevec1997", "response_rmse")] > 3 * reg[("debevec1997", "response_rmse")]
    assert ("floor:true_response", "log2_rmse") in unr and ("floor:true_response", "response_rmse") not in unr
    cam, t = camera_setup("global+rough_times0.07", np.geomspace(1e-3, 10, 100))
    assert cam.exposure_error == 0.07
    br = cam.capture(np.geomspace(1e-3, 10, 100)[None, :], t, seed=0)
    err = np.log(br.true_exposure_times / br.exposure_times)
    assert np.all(br.exposure_times == t) and 0.01 < np.abs(err).max() < 0.5
    rough = scores_of(run_task(TASK, Job("hdr", "hdr_scene", "global+rough_times0.07"), {"hdr_scene": hdr_gt()}))
    assert rough[("floor:true_response", "log2_rmse")] > 0.01   # the merge is given the stated times
    assert np.isfinite(rough[("grossberg_nayar2003", "response_rmse")])


def test_every_merge_of_the_methods_table_is_scored_with_the_true_response():
    """The merges table is benchmarked: each merge, given the camera's true inverse response,
    is scored like the calibration methods (and the default merge equals the floor's)."""
    from pbrbench.infer.hdr import MERGE_METHODS
    from pbrbench.infer.hdr.merge import DEFAULT_MERGE
    from pbrbench.tasks.hdr import TASK

    names = [a.name for a in TASK.builtin_algorithms() if a.interface == "merge"]
    assert names == [f"merge:{n}" for n in MERGE_METHODS]
    job = next(j for j in TASK.jobs(get_quality("draft")) if j.condition == "global+noise0")
    res = run_task(TASK, job, {job.scene: hdr_gt()})
    got = {(s.algorithm, s.metric): s.value for s in res.scores}
    for n in MERGE_METHODS:
        assert np.isfinite(got[(f"merge:{n}", "log2_rmse")]), n
    assert got[(f"merge:{DEFAULT_MERGE}", "log2_rmse")] == got[("floor:true_response", "log2_rmse")]


def test_calibration_times_merge_is_scored_where_the_merges_differ():
    """Each calibration is also merged by the table's other merges (on the reference condition):
    the same response, another merge, another radiance."""
    from pbrbench.infer.hdr import CALIBRATION_METHODS, MERGE_METHODS
    from pbrbench.tasks.hdr import MERGE_SEP, TASK, default_merge

    others = [m for m in MERGE_METHODS if m != default_merge()]
    names = {a.name for a in TASK.builtin_algorithms() if a.variant_of in CALIBRATION_METHODS}
    assert names == {f"{n}{MERGE_SEP}{m}" for n in CALIBRATION_METHODS for m in others}
    job = next(j for j in TASK.jobs(get_quality("draft")) if j.condition == TASK.reference_condition)
    got = {(s.algorithm, s.metric): s.value for s in run_task(TASK, job, {job.scene: hdr_gt()}).scores}
    for m in others:
        a, b = got[("debevec1997", "log2_rmse")], got[(f"debevec1997{MERGE_SEP}{m}", "log2_rmse")]
        assert np.isfinite(b) and a != b
        assert got[("debevec1997", "response_rmse")] == got[(f"debevec1997{MERGE_SEP}{m}", "response_rmse")]
