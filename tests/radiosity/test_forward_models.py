"""Forward models of radiance: meshes (ring mesh of a cap, conforming cuts), visibility rules,
bounce counts, memoisation, bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.radiosity import forward_models as FM
from pbrbench.radiosity.patches import patches_from_spec
from pbrbench.scene.load import load_scene_file
from pbrbench.settings import LIBRARY_DIR


def lib(family, k=0):
    return load_scene_file(LIBRARY_DIR / f"{family}.toml")[k]


def _inside(pts2, poly2):
    """Signed side of each point w.r.t. each edge of a convex ccw polygon: all >= -tol -> inside."""
    d = np.roll(poly2, -1, axis=0) - poly2
    rel = pts2[:, None, :] - poly2[None]
    return np.min(d[None, :, 0] * rel[..., 1] - d[None, :, 1] * rel[..., 0], axis=1)


def test_conforming_cuts_keep_the_area_and_leave_no_patch_across_a_footprint():
    spec = lib("room_white")
    size = FM.view_width(spec) / 12
    plain = patches_from_spec(spec, patch_size=size)
    cut = FM.model_patches(spec, size)
    assert len(cut) > len(plain)
    for oid in np.unique(plain.object_id):
        assert cut.areas[cut.object_id == oid].sum() == pytest.approx(plain.areas[plain.object_id == oid].sum(), rel=1e-12)
    floor = cut.object_id == 0
    for box in [s for s in spec.shapes if s.type == "box"]:
        bottom = min(FM._box_faces(box), key=lambda f: f[1][1])[0]   # the face with the most downward normal
        if abs(bottom[:, 1].max() + 1.0) > 1e-9:
            continue  # not resting on the floor (y = -1)
        poly = bottom[:, [0, 2]]
        e1, e2 = poly[1] - poly[0], poly[2] - poly[0]
        poly = poly if e1[0] * e2[1] - e1[1] * e2[0] > 0 else poly[::-1]
        for k in np.flatnonzero(floor):
            v = cut.vertices[k][: cut.n_vertices[k], [0, 2]]
            side = _inside(v, poly)
            assert side.min() >= -1e-9 or side.max() <= 1e-9, k
    ceiling = cut.object_id == 1
    x, z = cut.vertices[ceiling][:, :, 0], cut.vertices[ceiling][:, :, 2]
    over = (x.max(1) > -0.3 + 1e-9) & (x.min(1) < 0.3 - 1e-9)   # beside the light's x range
    for edge in (-0.4, 0.2):  # the light's outline z = -0.4, 0.2 (|x| < 0.3): no ceiling patch crosses it
        assert not np.any(over & (z.min(1) < edge - 1e-9) & (z.max(1) > edge + 1e-9))
    assert np.any((z.min(1) < 0.2 - 1e-9) & (z.max(1) > 0.2 + 1e-9))  # beyond it the grid is as it was


def test_the_cap_is_a_ring_mesh_without_visibility_and_the_room_needs_it():
    cap = lib("ps_cap")
    p = FM.model_patches(cap, 0.2)
    R, a = 1.0, np.radians(60.0)
    assert p.areas.sum() == pytest.approx(2 * np.pi * R * R * (1 - np.cos(a)), rel=0.03)  # inscribed: slightly less
    np.testing.assert_allclose(np.linalg.norm(p.vertices.reshape(-1, 3) - [0, 0, np.cos(a)], axis=1), 1.0, atol=1e-12)
    assert not FM.needs_visibility(cap)
    assert not FM.needs_visibility(lib("groove_reflex_parallel"))
    assert FM.needs_visibility(lib("room_black")) and FM.needs_visibility(lib("cylinder_bump"))


def test_bounces_count_up_to_the_converged_solution_and_are_memoised():
    spec = lib("groove_reflex_parallel", 5)   # albedo 0.9
    imgs = [FM.predict_radiance(spec, (32, 16), bounces=k, cells=6) for k in (0, 1, 2, 4)]
    conv = FM.predict_radiance(spec, (32, 16), cells=6)
    means = [im.mean() for im in imgs] + [conv.mean()]
    assert all(b > a for a, b in zip(means, means[1:], strict=False))
    m = FM.scene_model(spec, cells=6)
    assert m is FM.scene_model(spec, cells=6) and m.converged and not m.visibility
    np.testing.assert_array_equal(m.bounce(0), m.E)
    assert imgs[0].shape == (16, 32, 3)
    # the local model on the lit face: rho E0 cos / pi, whatever the mesh
    assert np.median(imgs[0][:, 20:28, 0]) == pytest.approx(0.9 * 3.14159 / np.pi, rel=1e-6)


def test_bad_arguments_are_refused():
    spec = lib("groove_reflex_parallel", 1)
    with pytest.raises(ValueError, match="resolution"):
        FM.predict_radiance(spec, (0, 4))
    with pytest.raises(ValueError, match="bounces"):
        FM.predict_radiance(spec, (8, 4), bounces=-1)
    with pytest.raises(ValueError, match="cells"):
        FM.scene_model(spec, cells=0)
    with pytest.raises(ValueError, match="sphere"):
        FM.predict_radiance(lib("sphere_5lights"), (8, 8))


def test_form_factors_are_kept_on_disk_by_geometry_and_survive_a_new_process(tmp_path, monkeypatch):
    from pbrbench.bench.source import reseeded
    from pbrbench.radiosity import form_factor_matrix as FFM

    spec = lib("room_white")
    FM.set_disk_cache(tmp_path / "ff")
    try:
        FM._MEMO.clear()
        FM._MESH.clear()
        first = FM.scene_model(spec, cells=4)
        (f,) = list((tmp_path / "ff").iterdir())
        assert f.suffix == ".npz" and FM.mesh_hash(first.patches, first.visibility)[:32] in f.name
        # a fresh process (memo empty) and a re-seeded render of the same geometry: read, not solved
        FM._MEMO.clear()
        FM._MESH.clear()

        def boom(*a, **k):
            raise AssertionError("form factors solved again")

        monkeypatch.setattr(FFM, "form_factor_matrix", boom)
        again = FM.scene_model(reseeded(spec, 5), cells=4)
        np.testing.assert_array_equal(again.bounce(None), first.bounce(None))
        # a truncated file is ignored (solved again), never an error
        f.write_bytes(f.read_bytes()[:100])
        FM._MEMO.clear()
        FM._MESH.clear()
        monkeypatch.undo()
        np.testing.assert_array_equal(FM.scene_model(spec, cells=4).bounce(None), first.bounce(None))
    finally:
        FM.set_disk_cache(None)
        FM._MEMO.clear()
        FM._MESH.clear()


def test_scenes_that_differ_only_in_albedo_share_their_form_factors(tmp_path, monkeypatch):
    from pbrbench.radiosity import form_factor_matrix as FFM

    a, b = lib("groove_reflex_parallel", 1), lib("groove_reflex_parallel", 4)   # one groove, two albedos
    assert FM.geometry_hash(a) != FM.geometry_hash(b)
    try:
        FM.set_disk_cache(None)
        for m in (FM._MEMO, FM._MESH, FM._FF):
            m.clear()
        fresh_b = FM.scene_model(b, cells=4)          # solved on its own
        for m in (FM._MEMO, FM._MESH, FM._FF):
            m.clear()
        FM.set_disk_cache(tmp_path / "ff")
        first = FM.scene_model(a, cells=4)
        for m in (FM._MEMO, FM._MESH, FM._FF):     # a fresh process: the disk holds a's form factors
            m.clear()

        def boom(*args, **kw):
            raise AssertionError("form factors solved again")

        monkeypatch.setattr(FFM, "form_factor_matrix", boom)
        shared = FM.scene_model(b, cells=4)
        assert len(list((tmp_path / "ff").iterdir())) == 1
        assert not np.array_equal(shared.patches.albedo, first.patches.albedo)
        np.testing.assert_array_equal(shared.bounce(None), fresh_b.bounce(None))   # its own albedo's solution
        assert not np.allclose(shared.bounce(None), first.bounce(None))
    finally:
        FM.set_disk_cache(None)
        for m in (FM._MEMO, FM._MESH, FM._FF):
            m.clear()
