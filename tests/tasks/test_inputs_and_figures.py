"""Helpers shared by the benchmark tasks: inputs, figures, conditions (pbrbench.tasks.common.inputs, .figures, .base)."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.quality import get_quality
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.scene import spec as S
from pbrbench.scene.geometry import camera_rotation, light_vectors, nominal_light
from pbrbench.tasks.base import Job, parse_condition
from pbrbench.tasks.common.figures import display, display_map, normals_display
from pbrbench.tasks.common.inputs import add_noise, job_rng, visible_surface
from pbrbench.tasks.common.scenes import sweep_value


def test_nominal_light_directional_area_point():
    cam = S.Camera()
    d, e = nominal_light(S.Directional(type="directional", direction=(0, 3, 4), irradiance=2.0), cam)
    assert np.allclose(d, [0, 0.6, 0.8]) and e == pytest.approx(2.0)
    area = S.AreaRect(type="area", center=(0, 0, 4), size=(1.0, 0.5), normal=(0, 0, -1), radiance=8.0)
    d, e = nominal_light(area, cam)
    assert np.allclose(d, [0, 0, 1]) and e == pytest.approx(8.0 * 0.5 / 16)
    tilted = S.AreaRect(type="area", center=(3, 0, 0), size=(1.0, 1.0), normal=(-1, 1, 0), radiance=1.0)
    d, e = nominal_light(tilted, cam)
    assert np.allclose(d, [1, 0, 0]) and e == pytest.approx(np.cos(np.pi / 4) / 9)
    d, e = nominal_light(S.Point(type="point", position=(0, 2, 0), intensity=4.0), cam)
    assert np.allclose(d, [0, 1, 0]) and e == pytest.approx(1.0)
    with pytest.raises(ValueError, match="no direction"):
        nominal_light(S.Ambient(type="ambient"), cam)


def test_light_vectors_in_a_rotated_camera_frame():
    # camera on +x looking at the origin: a source on +x is along the view (camera z)
    cam = S.Camera(origin=(5, 0, 0), up=(0, 1, 0))
    R = camera_rotation(cam)
    assert np.allclose(R @ R.T, np.eye(3))
    assert np.allclose(R @ [1, 0, 0], [0, 0, 1]) and np.allclose(R @ [0, 1, 0], [0, 1, 0])
    assert np.allclose(R @ [0, 0, -1], [1, 0, 0])  # world -z is to the camera's right
    spec = S.SceneSpec(name="t", description="t", camera=cam, shapes=({"type": "sphere"},),
                       light_set=({"type": "directional", "direction": (1, 0, 0), "irradiance": 3.0},
                                  {"type": "directional", "direction": (0, 1, 0), "irradiance": 1.0}))
    v = light_vectors(spec)
    assert np.allclose(v, [[0, 0, 3], [0, 1, 0]])


def test_parse_condition_sweep_value_subsample():
    assert parse_condition("local") == ("local", {})
    assert parse_condition("local+noise0.01") == ("local", {"noise": 0.01})
    assert parse_condition("global+readnoise0.002+3x3stops") == ("global", {"readnoise": 0.002, "3x3stops": 1.0})
    assert sweep_value("ps_cup[albedo=0.3]", "albedo") == 0.3
    assert sweep_value("ps_cup", "albedo") is None
    from pbrbench.quality import subsample

    assert subsample([1, 2, 3, 4, 5], 2) == [1, 5]
    assert subsample([1, 2, 3, 4, 5], 3) == [1, 3, 5]
    assert subsample([1, 2], 5) == [1, 2]
    assert get_quality("draft").keep([1, 2, 3, 4, 5]) == [1, 5]
    assert get_quality("draft").keep([1, 2, 3, 4, 5], extra=1) == [1, 3, 5]
    assert get_quality("standard").keep([1, 2, 3, 4, 5]) == [1, 2, 3, 4, 5]


def test_noise_is_deterministic_and_scaled():
    job = Job("t", "s", "local+noise0.01")
    img = np.full((200, 200), 0.5)
    img[0, 0] = 2.0
    a = add_noise(img, 0.01, job_rng(job, 0))
    b = add_noise(img, 0.01, job_rng(job, 0))
    c = add_noise(img, 0.01, job_rng(job, 1))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.std(a - img) == pytest.approx(0.02, rel=0.05)  # 1 % of the peak (2.0)
    assert np.array_equal(add_noise(img, 0.0, job_rng(job, 0)), img)


def test_display_helpers_shrink_and_keep_nan():
    a = np.arange(300 * 200, dtype=float).reshape(300, 200)
    assert display(a).shape == (100, 66) and display(a).dtype == np.float32
    m = np.zeros((4, 4), bool)
    m[:2, :2] = True
    d = display_map(np.ones((4, 4)), m, max_size=2)
    assert d[0, 0] == 1 and np.isnan(d[1, 1])
    n = normals_display(np.dstack([np.zeros((4, 4)), np.zeros((4, 4)), np.ones((4, 4))]), m)
    assert np.allclose(n[0, 0], [0.5, 0.5, 1.0]) and np.allclose(n[3, 3], 0)


def test_the_visible_surface_leaves_out_pixels_whose_corner_touches_another_object():
    # a ceiling (id 2) with an emitter (id 0) in its lower left: the pixel diagonal to the
    # emitter's corner has four ceiling neighbours but its square touches the emitter
    obj = np.full((8, 8), 2)
    obj[4:, :4] = 0
    gt = GroundTruth({"object_id": obj.astype(np.float32), "coverage": np.ones((8, 8), np.float32),
                      "mask": np.ones((8, 8), np.float32)}, {})
    dom = visible_surface(gt)
    assert not dom[3, 4]                  # diagonal to the emitter's corner (4, 3)
    assert not dom[3, 3] and not dom[4, 4]
    assert dom[2, 2] and dom[2, 5] and dom[6, 6]
    assert not dom[5, 1]                  # the emitter itself
    assert dom.sum() == 64 - 16 - 9       # the emitter and the ring of 9 around its corner
    cov = np.ones((8, 8), np.float32)
    cov[0, 7] = 0.5                       # a partly covered pixel is out, its neighbours stay in
    gt2 = GroundTruth({"object_id": obj.astype(np.float32), "coverage": cov, "mask": cov}, {})
    assert not visible_surface(gt2)[0, 7] and visible_surface(gt2)[1, 6]
