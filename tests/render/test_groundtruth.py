"""Ground-truth passes: camera-frame normals, depth, ids, mask, per-light images, previews."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.quality import STANDARD
from pbrbench.render.cache import RenderCache, ground_truth
from pbrbench.scene.spec import SceneSpec
from pbrbench.shading.surfaces import pixel_grid

RES, HW = 48, 1.2
SCENE = {
    "name": "gt_probe",
    "description": "sphere in front of a tilted plane, two lights one at a time",
    "camera": {"half_width": HW, "origin": [0, 0, 5]},
    "render": {"resolution": RES, "spp": 64},
    "materials": {"paint": {"type": "diffuse", "albedo": [0.2, 0.5, 0.8]}},
    "shapes": [
        {"type": "sphere", "name": "ball", "radius": 0.8, "material": "paint"},
        {"type": "rectangle", "name": "wall", "center": [0, 0, -1], "size": [4, 4],
         "rotate": [{"axis": [0, 1, 0], "angle": 30}]},
    ],
    "light_set": [
        {"type": "directional", "direction": [0.3, 0.2, 1.0], "irradiance": 2.0},
        {"type": "directional", "direction": [-0.5, 0.0, 1.0], "irradiance": 1.0},
    ],
}


@pytest.fixture(scope="module")
def gt(cache_dir):
    g, _ = ground_truth(SceneSpec.model_validate(SCENE), STANDARD, cache=RenderCache(cache_dir))
    return g


@pytest.mark.render
def test_normals_in_camera_frame(gt):
    x, y = pixel_grid(RES, RES, HW)
    r2 = x * x + y * y
    inside = (r2 < 0.7 ** 2) & gt.mask
    expect = np.stack([x, y, np.sqrt(np.maximum(0.8 ** 2 - r2, 0))], -1) / 0.8
    # pixel-centre normals vs footprint-averaged AOV normals: well within 1 degree inside
    cos = np.sum(gt["normals"][inside] * expect[inside], -1)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1.0
    assert gt["normals"][inside][:, 2].min() > 0  # z toward the camera


@pytest.mark.render
def test_depth_ids_mask(gt):
    x, y = pixel_grid(RES, RES, HW)
    ball = gt["object_id"] == 1
    wall = gt["object_id"] == 2
    assert ball.sum() > 0.25 * RES * RES and wall.sum() > 0.2 * RES * RES
    # depth along the view axis: camera at z=5 -> sphere front at 5 - sqrt(0.64 - r^2)
    r2 = x * x + y * y
    centre = ball & (r2 < 0.3 ** 2) & gt.mask
    np.testing.assert_allclose(gt["depth"][centre], 5 - np.sqrt(0.64 - r2[centre]), atol=5e-3)
    # the wall: z = -1 - x tan(30 deg) (rotation about y), depth = 5 - z
    w = wall & gt.mask & (np.abs(x) < 1.0)
    np.testing.assert_allclose(gt["depth"][w], 6 + x[w] * np.tan(np.radians(30)), atol=5e-3)
    assert set(np.unique(gt["object_id"])) <= {0.0, 1.0, 2.0}
    assert not np.any(gt.mask & (gt["coverage"] < 0.999))
    assert not np.any(gt.mask & (gt["object_id"] == 0))


@pytest.mark.render
def test_albedo_aov_exact(gt):
    ball = (gt["object_id"] == 1) & gt.mask
    np.testing.assert_allclose(gt["albedo"][ball], np.broadcast_to([0.2, 0.5, 0.8], (ball.sum(), 3)), atol=1e-6)


@pytest.mark.render
def test_light_stack_and_direct_split(gt, cache_dir):
    stack = gt.light_stack("direct")
    assert stack.shape == (2, RES, RES, 3)
    # the light set is every light of the scene: the all-lights passes are the sums of the
    # per-light ones, in every delete-one-group replicate too
    np.testing.assert_allclose(gt["direct"], stack.sum(0), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(gt["radiance"], gt.light_stack("radiance").sum(0), rtol=1e-5, atol=1e-7)
    for i in range(gt.groups):
        rep = gt.replicate(i)
        np.testing.assert_allclose(rep["radiance"], rep.light_stack("radiance").sum(0), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(gt["indirect"], gt["radiance"] - gt["direct"], atol=1e-6)
    assert gt["indirect"][gt["object_id"] == 1].mean() > 0  # the wall lights the ball
    # linearity: the sum agrees, within noise, with an independent render of every light at once
    # (the same lights as the scene's own lights, not a light set)
    twin = SceneSpec.model_validate({**SCENE, "name": "gt_probe_all_lights", "lights": SCENE["light_set"],
                                     "light_set": []})
    g2, _ = ground_truth(twin, STANDARD, cache=RenderCache(cache_dir))
    assert g2.n_lights == 0
    for kind in ("direct", "radiance"):
        n = gt[kind].size
        diff = gt[kind].astype(np.float64).mean() - g2[kind].astype(np.float64).mean()
        sigma = np.sqrt(np.sum(gt[f"{kind}_sd"].astype(np.float64) ** 2) + np.sum(g2[f"{kind}_sd"].astype(np.float64) ** 2)) / n
        assert abs(diff) < 4 * sigma + 1e-6 * g2[kind].mean(), (kind, diff, sigma)
        assert not np.array_equal(gt[kind], g2[kind])      # a render of its own, not the sum


@pytest.mark.render
def test_render_cli_writes_exr_and_previews(tmp_path, cache_dir, monkeypatch):
    from pbrbench.cli.main import main

    monkeypatch.setenv("PBRBENCH_CACHE", str(cache_dir))
    import json

    p = tmp_path / "probe.toml"
    p.write_text(
        'name = "cli_probe"\ndescription = "x"\n[render]\nresolution = 16\nspp = 4\n'
        '[[shapes]]\ntype = "sphere"\n[[lights]]\ntype = "directional"\ndirection = [0, 0, 1]\n'
    )
    assert main(["render", str(p), "--quality", "draft", "--out", str(tmp_path / "out")]) == 0
    d = tmp_path / "out" / "cli_probe"
    names = {f.name for f in d.iterdir()}
    assert {"gt.exr", "gt.json", "radiance.png", "normals.png", "depth.png", "albedo.png", "radiance_sd.png"} <= names
    meta = json.loads((d / "gt.json").read_text())
    assert meta["quality"] == "draft" and meta["spp"] == 4
    assert main(["render", "no_such_scene"]) == 1


@pytest.mark.render
@pytest.mark.slow
def test_scalar_variant_ground_truth_has_the_same_mask_as_llvm(tmp_path):
    """scalar variants leave the coverage alpha at 0; the white-albedo fallback gives the covered
    fraction, so the scalar fallback's mask and albedo match the LLVM variant's."""
    import json
    import subprocess
    import sys

    code = ("import sys, json; from pbrbench.render import variant; from pbrbench.settings import Settings; "
            "variant.configure(Settings.from_env(variant=sys.argv[1])); "
            "from pbrbench.render.groundtruth import render_ground_truth; from pbrbench.scene.load import resolve; "
            "from pbrbench.quality import get_quality; "
            "(s,) = resolve(['sphere_5lights']); g = render_ground_truth(s, get_quality('draft'), variant=sys.argv[1]); "
            "print(json.dumps([int(g.mask.sum()), float(g['albedo'][g.mask].mean())]))")
    out = {}
    for v in ("scalar_rgb", "llvm_ad_rgb"):
        p = subprocess.run([sys.executable, "-c", code, v], capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stderr[-2000:]
        out[v] = json.loads(p.stdout.strip().splitlines()[-1])
    (ns, albs), (nl, albl) = out["scalar_rgb"], out["llvm_ad_rgb"]
    assert nl > 1000 and abs(ns - nl) <= 0.01 * nl and abs(albs - albl) < 1e-3


@pytest.mark.render
def test_the_geometry_does_not_move_with_the_render_seed():
    """Two render seeds: the same mask, normals, depth and coverage bit for bit (the AOV groups
    take fixed seeds), other radiance.  Within one render the geometry's sample groups differ
    (each its own seed) and their deviations are kept, but a replicate has the full geometry
    unless asked for its own (``geometry=True``): a re-render does not move it."""
    from pbrbench.quality import DRAFT
    from pbrbench.render.groundtruth import render_ground_truth

    spec = SceneSpec.model_validate(SCENE)
    a, b = (render_ground_truth(spec.model_copy(update={"render": spec.render.model_copy(update={"seed": s})}), DRAFT)
            for s in (3, 4))
    for name in ("mask", "normals", "depth", "coverage", "albedo", "object_id"):
        assert np.array_equal(a[name], b[name]), name
    assert not np.array_equal(a["light00.radiance"], b["light00.radiance"])
    # the ball's silhouette against the wall (which fills the view): the replicates' normals and
    # depths, footprint averages across the edge, differ
    assert any(np.abs(a[f"depth_jk{i}"]).max() > 0 for i in range(a.meta["groups"]))
    assert any(np.abs(a[f"normals_jk{i}"]).max() > 0 for i in range(a.meta["groups"]))
    moved = [i for i in range(a.groups) if np.abs(a[f"normals_jk{i}"]).max() > 0]
    for i in range(a.groups):
        rep = a.replicate(i)
        assert np.array_equal(rep["normals"], a["normals"]) and np.array_equal(rep["mask"], a["mask"])
        assert not np.array_equal(rep["light00.radiance"], a["light00.radiance"])
        assert a.varies(i, ["light00.radiance"]) and not a.varies(i, ["normals", "mask", "depth"])
    i = moved[0]
    assert not np.array_equal(a.replicate(i, geometry=True)["normals"], a["normals"])
    assert a.varies(i, ["normals"], geometry=True)


@pytest.mark.render
def test_a_scene_asking_for_more_sample_groups_gets_them_at_draft():
    """``render.min_groups = 8``: every pass in eight groups (two samples each at draft), the
    replicates of all eight groups, and their delete-one-group estimate of the pass's mean agrees
    with the four-group render's within both their errors."""
    from pbrbench.quality import DRAFT
    from pbrbench.render.groundtruth import render_ground_truth

    spec = SceneSpec.model_validate(SCENE)
    eight = spec.model_copy(update={"render": spec.render.model_copy(update={"min_groups": 8})})
    a, b = render_ground_truth(spec, DRAFT), render_ground_truth(eight, DRAFT)
    assert (a.groups, a.meta["groups"], a.meta["spp"]) == (4, 4, 8)
    assert (b.groups, b.meta["groups"], b.meta["spp"]) == (8, 8, 16)
    assert np.array_equal(a["mask"], b["mask"])           # the geometry does not depend on the groups
    m = a["mask"] > 0.5

    def mean_and_se(g):
        v = float(g["light00.radiance"][m].mean())
        reps = np.array([float(g.replicate(i)["light00.radiance"][m].mean()) for i in range(g.groups)])
        return v, float(np.sqrt((g.groups - 1) / g.groups * np.sum((reps - reps.mean()) ** 2)))

    (va, sa), (vb, sb) = mean_and_se(a), mean_and_se(b)
    assert sa > 0 and sb > 0
    assert abs(va - vb) < 4 * np.hypot(sa, sb)


def test_shape_ids_are_read_to_float32_rounding():
    # the film holds a pixel's weighted mean of its samples' shape indices in float32: 2.9999998
    # for a pixel that sees only shape 3.  Compared exactly, such shapes fell out of object_id and
    # of the pure mask (odd indices above 1, in some runs and not others); a mixture of two shapes
    # stays unmapped (-1)
    from types import SimpleNamespace

    from pbrbench.render.groundtruth import _Renderer
    from pbrbench.scene.mitsuba_dict import shape_key

    spec = SceneSpec.model_validate({**SCENE, "shapes": SCENE["shapes"] + [
        {"type": "sphere", "name": f"extra{k}", "radius": 0.1, "center": [k, 2, 0], "material": "paint"}
        for k in range(4)]})
    keys = [shape_key(spec, i) for i in range(len(spec.shapes))]
    scene = SimpleNamespace(shapes=lambda: [SimpleNamespace(id=lambda k=k: k) for k in keys])
    fake = SimpleNamespace(mi=SimpleNamespace(variant=lambda: "scalar_rgb"), spec=spec)
    w = np.float32(0.9)
    rounded = [np.float32(np.float32(w * np.float32(r)) / w) for r in (3, 6)]
    assert all(v != r for v, r in zip(rounded, (3, 6), strict=True))    # the rounding the film gives
    si = np.array([0.0, 1.0, 2.0, rounded[0], 4.0, 5.0, rounded[1], 2.5], np.float32)
    ids = _Renderer._object_ids(fake, scene, si)
    np.testing.assert_array_equal(ids, [0, 1, 2, 3, 4, 5, 6, -1])
