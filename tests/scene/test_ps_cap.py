"""The concave-cap family: a valid scene file whose sources all light the whole cap (the condition of
the closed-form photometric-stereo bias)."""

from __future__ import annotations

import numpy as np

from pbrbench.radiosity.concave_cap import cap_shadow_free
from pbrbench.scene.load import load_scene_file
from pbrbench.settings import LIBRARY_DIR


def test_ps_cap_scene_file():
    specs = load_scene_file(LIBRARY_DIR / "ps_cap.toml")
    assert [s.name for s in specs] == [f"ps_cap[albedo={a:g}]" for a in (0.1, 0.3, 0.5, 0.7, 0.9)]
    for s in specs:
        (cap,) = s.shapes
        assert cap.type == "heightfield" and cap.surface == "spherical_cap"
        alpha, R = cap.params["half_angle_deg"], cap.params["radius"]
        assert R * np.sin(np.radians(alpha)) <= cap.half_width <= s.camera.half_width  # the rim on the grid and film
        assert s.camera.type == "orthographic" and tuple(s.camera.target) == (0.0, 0.0, 0.0)
        assert s.camera.origin[:2] == (0.0, 0.0)  # along the axis
        assert len(s.light_set) == 6 and not s.lights
        assert all(cap_shadow_free(lt.direction, alpha) for lt in s.light_set)
        assert {"photometric_stereo", "interreflection", "concave", "local", "global"} <= set(s.tags)


def test_photometric_stereo_and_interreflection_tasks_use_it():
    from pbrbench.tasks.interreflection import FAMILIES as IR
    from pbrbench.tasks.photometric_stereo import FAMILIES as PS

    assert "ps_cap" in PS and "ps_cap" in IR
