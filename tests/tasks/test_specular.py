"""The specular task on a synthetic glossy sphere."""

from __future__ import annotations

from pbrbench.tasks.base import Job
from tests.fakes import (
    run_task,
    scores_of,
    specular_gt,
)


def test_specular_removal_beats_no_removal():
    from pbrbench.tasks.specular import TASK

    res = run_task(TASK, Job("specular", "s", "global"), {"s": specular_gt()})
    sc = scores_of(res)
    assert sc[("harmonic", "mask_iou")] > 0.5 and sc[("baseline:no_removal", "mask_iou")] == 0
    for alg in ("harmonic", "biharmonic", "harmonic+true_mask"):
        assert sc[(alg, "inside_rel")] < 0.1 * sc[("baseline:no_removal", "inside_rel")]
    assert ("harmonic+true_mask", "mask_iou") not in sc

