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



def test_figs_1_1_and_1_2_mark_the_specular_direction_where_the_highlight_is():
    """A sphere lit by the scene file's source with a sharp lobe about the half vector: the
    marked pixel (normal closest to H = (S + V) / |S + V|) is the highlight's peak, within a pixel;
    a scene without a directional source gives no figure."""
    import numpy as np

    from pbrbench.render.groundtruth import GroundTruth
    from pbrbench.scene.geometry import nominal_light
    from pbrbench.scene.load import resolve
    from pbrbench.shading.surfaces import on_grid
    from pbrbench.tasks.specular import specular_direction_figure

    (spec,) = resolve(["specular_sphere"])
    s = on_grid("sphere", 64, 1.1)
    S, _ = nominal_light(spec.lights[0], spec.camera)
    H = (S + [0, 0, 1]) / np.linalg.norm(S + [0, 0, 1])
    lobe = np.where(s.mask, np.clip(s.normals @ H, 0, None) ** 400, 0.0)
    img = np.repeat((np.where(s.mask, 0.2, 0.0) + 5.0 * lobe)[..., None], 3, axis=-1)
    gt = GroundTruth({"radiance": img.astype(np.float32), "normals": s.normals.astype(np.float32),
                      "mask": s.mask.astype(np.float32)}, {"scene_hash": "t"})
    fig = specular_direction_figure(spec, gt, img)
    red = np.argwhere((fig[..., 0] == 1.0) & (fig[..., 1] == 0.0) & (fig[..., 2] == 0.0))
    centre = np.array([np.median(red[:, 0]), np.median(red[:, 1])])
    peak = np.array(np.unravel_index(np.argmax(lobe), lobe.shape))
    assert np.all(np.abs(centre - peak) <= 1)
    assert specular_direction_figure(spec.model_copy(update={"lights": spec.lights[1:]}), gt, img) is None
