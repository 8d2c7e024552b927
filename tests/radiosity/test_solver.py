"""The radiosity model: meshes from scene specs, the direct term, the solvers, enclosures, images."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.radiosity.solver import (
    direct_radiosity,
    form_factor_matrix,
    make_patches,
    patch_index_image,
    patches_from_spec,
    radiosity_image,
    solve_radiosity,
    solve_scene,
)
from pbrbench.scene.spec import SceneSpec
from pbrbench.shading.irradiance import polygon_irradiance


def scene(shapes, lights=({"type": "directional", "direction": [0, 0, 1]},), **kw):
    return SceneSpec(name="t", description="t", shapes=list(shapes), lights=list(lights), **kw)


def cube_room(rho, patch_size, light=None):
    return scene([{"type": "box", "size": [2, 2, 2], "flip_normals": True, "material": {"type": "diffuse", "albedo": rho}}],
                 [light or {"type": "point", "position": [0.1, -0.2, 0.3], "intensity": 2.0}])


# ------------------------------------------------------------------------------ meshes
@pytest.mark.render
def test_rectangles_and_boxes_match_mitsuba_transforms():
    from pbrbench.render.variant import mitsuba
    from pbrbench.scene.mitsuba_dict import shape_dict

    mi = mitsuba()
    spec = scene([
        {"type": "rectangle", "center": [0.3, -1, 0.2], "size": [2.0, 1.5], "rotate": [{"axis": [1, 0, 0], "angle": -90}]},
        # a non-unit axis: Mitsuba does not normalise it (a non-rigid transform), nor do the patches
        {"type": "rectangle", "center": [1, 0, 0], "size": [1.0, 2.0], "rotate": [{"axis": [0, 1, 0], "angle": -70},
                                                                                  {"axis": [1, 1, 0], "angle": 20}]},
        {"type": "box", "center": [0.35, 0.35, -0.6], "size": [0.35, 0.5, 0.2],
         "rotate": [{"axis": [1, 0, 0], "angle": 35}, {"axis": [0, 0, 1], "angle": 30}]},
    ])
    p = patches_from_spec(spec, patch_size=0.25)
    for i, sh in enumerate(spec.shapes):
        M = np.array(shape_dict(mi, spec, i, sh)["to_world"].matrix, float).reshape(4, 4)
        if sh.type == "rectangle":
            loc = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
            n = np.linalg.inv(M[:3, :3]).T @ [0, 0, 1.0]  # a normal transforms by the inverse transpose
            np.testing.assert_allclose(p.normals[p.object_id == i], np.tile(n / np.linalg.norm(n), (np.sum(p.object_id == i), 1)), atol=1e-6)
        else:
            loc = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        corners = loc @ M[:3, :3].T + M[:3, 3]
        v = p.vertices[p.object_id == i].reshape(-1, 3)
        assert np.min(np.linalg.norm(v[None] - corners[:, None], axis=-1), axis=1).max() < 1e-6
    box = p.object_id == 2  # outward normals
    c = np.array([0.35, 0.35, -0.6])
    assert np.all(np.sum(p.normals[box] * (p.centres[box] - c), 1) > 0)


def test_box_area_flip_normals_and_refinement():
    spec = scene([{"type": "box", "size": [0.6, 1.0, 0.4], "center": [1, 2, 3], "flip_normals": True}])
    for ps, n in ((0.2, 2 * (3 * 5 + 5 * 2 + 3 * 2)), (0.1, 4 * 2 * (3 * 5 + 5 * 2 + 3 * 2))):
        p = patches_from_spec(spec, patch_size=ps)
        assert len(p) == n
        assert p.areas.sum() == pytest.approx(2 * (0.6 + 0.24 + 0.4), rel=1e-12)
        assert np.all(np.sum(p.normals * (p.centres - [1, 2, 3]), 1) < 0)  # flipped: inward
    assert np.all(p.grid_index == -1)


def test_heightfield_patches_follow_the_mitsuba_mesh_layout():
    from pbrbench.scene.mitsuba_dict import heightfield_mesh

    spec = scene([{"type": "heightfield", "surface": "plane", "params": {"fx": 0.3, "fy": -0.2}, "half_width": 0.9,
                   "center": [0.1, 0.0, 0.2], "rotate": [{"axis": [0, 0, 1], "angle": 30}]}])
    p = patches_from_spec(spec, heightfield_cells=8)
    sh = spec.shapes[0]
    v, _, _, f = heightfield_mesh(sh.model_copy(update={"resolution": 9}), "")
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(p.vertices[:, :3], v[f] @ R.T, atol=1e-12)
    assert len(p) == 2 * 8 * 8 and p.areas.sum() == pytest.approx(1.8 ** 2 * np.sqrt(1 + 0.09 + 0.04), rel=1e-12)
    # grid cells: row 0 at +y, col 0 at -x (before the rotation)
    local = p.centres @ R  # undo the rotation
    h = 1.8 / 8
    np.testing.assert_array_equal(p.grid_index[:, 1], np.floor((local[:, 0] - 0.1 + 0.9) / h).astype(int))
    np.testing.assert_array_equal(p.grid_index[:, 0], np.floor((0.9 - local[:, 1]) / h).astype(int))
    # the plane's mask is |x|, |y| < 1 (strict): a grid reaching the boundary loses its outer cells, as in Mitsuba
    edge = patches_from_spec(scene([{"type": "heightfield", "surface": "plane", "half_width": 1.0}]), heightfield_cells=8)
    assert len(edge) == 2 * 6 * 6
    assert np.all(p.normals[:, 2] > 0)


def test_unsupported_shapes_and_materials_are_refused():
    with pytest.raises(ValueError, match=r"shapes\[1\] is a 'sphere'.*supports rectangle, box, cylinder, heightfield"):
        patches_from_spec(scene([{"type": "rectangle"}, {"type": "sphere"}]))
    with pytest.raises(ValueError, match=r"shapes\[0\] \(rectangle\): material type 'plastic'"):
        patches_from_spec(scene([{"type": "rectangle", "material": {"type": "plastic"}}]))
    with pytest.raises(ValueError, match="'checker' albedo texture"):
        patches_from_spec(scene([{"type": "rectangle", "material": {"type": "diffuse", "albedo": {"type": "checker"}}}]))
    with pytest.raises(ValueError, match="max_patches"):
        patches_from_spec(scene([{"type": "rectangle", "size": [10, 10]}]), patch_size=0.01)
    with pytest.raises(ValueError, match="degenerate"):
        make_patches(np.array([[[0, 0, 0], [1, 1, 1], [2, 2, 2.0]]]))


def test_cylinder_is_an_inscribed_prism_with_outward_normals():
    spec = scene([{"type": "cylinder", "p0": [0, -1, 0.2], "p1": [0, 2, 0.2], "radius": 0.5}])
    p = patches_from_spec(spec, patch_size=0.1)
    n_around = int(np.ceil(2 * np.pi * 0.5 / 0.1))
    assert len(p) == n_around * 30
    axis_pt = np.array([0, 0, 0.2])
    radial = p.centres - axis_pt
    radial[:, 1] = 0
    assert np.all(np.sum(p.normals * radial, 1) > 0.99 * np.linalg.norm(radial, axis=1))  # outward
    v = p.vertices.reshape(-1, 3) - axis_pt
    np.testing.assert_allclose(np.hypot(v[:, 0], v[:, 2]), 0.5, rtol=1e-12)  # vertices on the tube
    # the prism's area: length x perimeter of the inscribed polygon
    assert p.areas.sum() == pytest.approx(3.0 * 2 * n_around * 0.5 * np.sin(np.pi / n_around), rel=1e-12)
    flipped = patches_from_spec(scene([{"type": "cylinder", "p0": [0, -1, 0.2], "p1": [0, 2, 0.2], "radius": 0.5,
                                        "flip_normals": True}]), patch_size=0.1)
    np.testing.assert_allclose(flipped.normals, -p.normals, atol=1e-12)
    with pytest.raises(ValueError, match="textured cylinders"):
        patches_from_spec(scene([{"type": "cylinder", "material": {"type": "diffuse", "albedo": {"type": "checker"}}}]))


def test_mondrian_albedo_is_looked_up_at_patch_centres():
    from pbrbench.scene.textures import texture_array

    spec = scene([{"type": "rectangle", "material": {"type": "diffuse", "albedo": {
        "type": "mondrian", "patches": 4, "resolution": 64, "seed": 3}}}])
    p = patches_from_spec(spec, patch_size=0.25)  # 8 x 8 patches, 2 x 2 per paper
    tex = texture_array(spec.shapes[0].material.albedo, "")
    u, v = (p.centres[:, 0] + 1) / 2, (p.centres[:, 1] + 1) / 2
    np.testing.assert_allclose(p.albedo, tex[((1 - v) * 64).astype(int), (u * 64).astype(int)])


# --------------------------------------------------------------------------- direct term
def test_point_light_flux_lands_on_the_closed_room():
    """All of a point source's flux 4 pi I reaches the walls of a closed room: sum_i A_i E_i / rho = 4 pi I."""
    spec = cube_room(0.5, 0.5)
    p = patches_from_spec(spec, patch_size=0.5)
    E = direct_radiosity(spec, p, order=8)
    assert np.sum(p.areas * E[:, 0]) / 0.5 == pytest.approx(4 * np.pi * 2.0, rel=1e-5)


def test_directional_light_and_its_shadow():
    """A card above a floor under a vertical sun: the patch mean of the lit fraction, exactly.

    Floor patches are 0.5 wide; the card's edges fall on patch midlines, so the 2 x 2 Gauss
    points of a straddling patch split evenly and each patch gets its exact lit fraction.
    """
    floor = {"type": "rectangle", "size": [2, 2], "material": {"type": "diffuse", "albedo": 0.5}}
    card = {"type": "rectangle", "size": [1.0, 1.0], "center": [0.25, 0.25, 0.5]}
    spec = scene([floor, card], [{"type": "directional", "direction": [0, 0, 1], "irradiance": 2.0}])
    p = patches_from_spec(spec, patch_size=0.5)
    E = direct_radiosity(spec, p)[:, 0]
    on = p.object_id == 0
    c = p.centres[on]

    def overlap(x):
        return np.clip(np.minimum(x + 0.25, 0.75) - np.maximum(x - 0.25, -0.25), 0, None) / 0.5

    shaded = overlap(c[:, 0]) * overlap(c[:, 1])
    assert set(np.round(shaded, 6)) == {0.0, 0.25, 0.5, 1.0}
    np.testing.assert_allclose(E[on], 0.5 * 2.0 * (1 - shaded), atol=1e-12)
    np.testing.assert_allclose(E[~on], 1.0)  # the card itself is lit
    np.testing.assert_allclose(direct_radiosity(spec, p, shadows=False)[on, 0], 1.0)


def test_area_light_matches_lamberts_formula():
    floor = {"type": "rectangle", "size": [2, 2], "material": {"type": "diffuse", "albedo": 0.8}}
    light = {"type": "area", "center": [0.3, 0.0, 1.0], "size": [0.6, 0.4], "normal": [0, 0, -1], "radiance": 3.0}
    spec = scene([floor], [light])
    p = patches_from_spec(spec, patch_size=0.25)
    E = direct_radiosity(spec, p)[:, 0]
    from pbrbench.shading.form_factors import patch_quadrature
    from pbrbench.shading.irradiance import rectangle_polygon

    pts, w = patch_quadrature(p.vertices, 8, 4)
    poly = rectangle_polygon(light["center"], light["size"], light["normal"])
    irr = polygon_irradiance(pts.reshape(-1, 3), np.repeat(p.normals, pts.shape[1], 0), poly, 3.0).reshape(pts.shape[:2])
    np.testing.assert_allclose(E, 0.8 * np.sum(w * irr, 1), rtol=1e-3)


def test_area_light_penumbra_converges_to_the_exact_occluded_irradiance():
    """Card under a square light: sampled shadow rays vs the exact projected-occluder formula."""
    from pbrbench.shading.form_factors import patch_quadrature
    from pbrbench.shading.irradiance import rectangle_polygon, visible_polygon_irradiance

    floor = {"type": "rectangle", "size": [2, 2], "material": {"type": "diffuse", "albedo": 1.0}}
    card = {"type": "rectangle", "size": [0.5, 0.5], "center": [0.0, 0.0, 1.0]}
    light = {"type": "area", "center": [0.0, 0.0, 3.0], "size": [1.0, 1.0], "normal": [0, 0, -1], "radiance": 10.0}
    spec = scene([floor, card], [light])
    p = patches_from_spec(spec, patch_size=0.25)
    on = p.object_id == 0
    pts, w = patch_quadrature(p.vertices[on], 2, 3)  # the exact reference loops over points in Python
    n = np.tile([0.0, 0.0, 1.0], (pts.shape[0] * pts.shape[1], 1))
    exact = visible_polygon_irradiance(pts.reshape(-1, 3), n, rectangle_polygon(light["center"], light["size"], light["normal"]),
                                       [rectangle_polygon(card["center"], card["size"], [0, 0, 1.0])], 10.0)
    ref = np.sum(w * exact.reshape(pts.shape[:2]), 1)
    errs = [np.abs(direct_radiosity(spec, p, area_samples=k)[on, 0] - ref).max() / ref.max() for k in (2, 4, 8)]
    assert errs[2] < 0.02 and errs[2] < errs[1] < errs[0]


def test_ambient_light_sees_the_sky_minus_an_occluder():
    """The sky fraction is a stratified cosine quadrature: error at most ~1/K for K x K rays at an occluder edge."""
    floor = {"type": "rectangle", "size": [0.02, 0.02], "material": {"type": "diffuse", "albedo": 0.5}}
    card = {"type": "rectangle", "size": [1.0, 1.0], "center": [0.2, 0.1, 0.5], "flip_normals": True}
    spec = scene([floor, card], [{"type": "ambient", "radiance": 2.0}])
    p = patches_from_spec(spec, patch_size=1.0)
    sq = np.array([[-0.3, -0.4, 0.5], [0.7, -0.4, 0.5], [0.7, 0.6, 0.5], [-0.3, 0.6, 0.5]])
    blocked = polygon_irradiance(p.centres[0], p.normals[0], sq, one_sided=False) / np.pi  # both sides block
    for K in (16, 32, 64):
        E = direct_radiosity(spec, p, ambient_rays=K)[0, 0]
        assert abs(E / (0.5 * np.pi * 2.0) - (1 - blocked)) < 1.0 / K
    alone = scene([floor], [{"type": "ambient", "radiance": 2.0}])
    assert direct_radiosity(alone, patches_from_spec(alone))[0, 0] == pytest.approx(0.5 * np.pi * 2.0, rel=1e-12)


# -------------------------------------------------------------------------------- solvers
def small_system():
    spec = cube_room(0.7, 0.5)
    p = patches_from_spec(spec, patch_size=0.5)
    F = form_factor_matrix(p)
    rho = np.array([0.7, 0.5, 0.2])[None] * np.ones((len(p), 1))
    return F, rho, direct_radiosity(spec, p)


def test_jacobi_converges_to_the_direct_solution_and_counts_bounces():
    F, rho, E = small_system()
    d = solve_radiosity(F, rho, E, method="direct")
    j = solve_radiosity(F, rho, E, method="jacobi", tol=1e-13)
    g = solve_radiosity(F, rho, E, method="gauss_seidel", tol=1e-13)
    assert j.converged and g.converged and g.bounces < j.bounces
    np.testing.assert_allclose(j.B, d.B, rtol=1e-11)
    np.testing.assert_allclose(g.B, d.B, rtol=1e-11)
    np.testing.assert_array_equal(j.history[0], E)  # bounce 0: the local model
    two = E + rho * (F @ E) + rho * (F @ (rho * (F @ E)))
    np.testing.assert_allclose(j.history[2], two, rtol=1e-13)
    assert np.all(np.diff(j.residuals) < 0)
    # residual of bounce k is (rho F)^(k+1) E: geometric decay at most the largest albedo
    assert j.residuals[10] / j.residuals[9] <= 0.7 + 1e-9
    one = solve_radiosity(F, rho, E, max_bounces=0)
    np.testing.assert_array_equal(one.B, E)
    assert not one.converged


def test_sparse_form_factors_give_the_same_solution():
    from scipy.sparse import csr_array

    F, rho, E = small_system()
    for m in ("direct", "jacobi", "gauss_seidel"):
        np.testing.assert_allclose(solve_radiosity(csr_array(F), rho, E, method=m, tol=1e-13).B,
                                   solve_radiosity(F, rho, E, method="direct").B, rtol=1e-10)


def test_solver_refuses_bad_input():
    F, rho, E = small_system()
    with pytest.raises(ValueError, match="ill-posed"):
        solve_radiosity(F, np.ones(len(F)), E)
    with pytest.raises(ValueError, match="method='lu' is not known"):
        solve_radiosity(F, rho, E, method="lu")
    with pytest.raises(ValueError, match="expected shape"):
        solve_radiosity(F, rho[:-1], E)
    with pytest.raises(ValueError, match="square"):
        solve_radiosity(F[:, :-1], rho, E)


@pytest.mark.parametrize("rho", [0.1, 0.5, 0.9])
def test_integrating_cube(rho):
    """A closed uniform enclosure multiplies uniform direct radiosity by 1/(1 - rho) (rows sum to 1)."""
    spec = cube_room(rho, 0.5)
    p = patches_from_spec(spec, patch_size=0.5)
    Fu = form_factor_matrix(p, quadrature=(2, 3))  # one rule per row: rows sum to 1 to rounding
    E = np.full(len(p), 0.3)
    np.testing.assert_allclose(solve_radiosity(Fu, rho, E, method="direct").B, 0.3 / (1 - rho), rtol=1e-12)
    # the adaptive default: rows sum to 1 - delta, so B is within rho delta / (1 - rho)^2 of the answer
    Fa = form_factor_matrix(p)
    delta = np.abs(Fa.sum(1) - 1).max()
    B = solve_radiosity(Fa, rho, E, method="direct").B
    assert np.abs(B - 0.3 / (1 - rho)).max() <= 0.3 * rho * delta / (1 - rho) ** 2 * 1.01 + 1e-15
    # a point source: the flux is multiplied by 1 / (1 - rho) (reciprocity + closure)
    Ep = direct_radiosity(spec, p)[:, 0]
    Bp = solve_radiosity(Fu, rho, Ep, method="direct").B
    assert np.sum(p.areas * Bp) == pytest.approx(np.sum(p.areas * Ep) / (1 - rho), rel=1e-6)


# -------------------------------------------------------------------------------- images
def groove_spec(albedo=0.6):
    return scene([
        {"type": "rectangle", "center": [-0.55, 0, 0.55], "size": [1.55564, 2.0], "material": {"type": "diffuse", "albedo": albedo},
         "rotate": [{"axis": [0, 1, 0], "angle": 45}]},
        {"type": "rectangle", "center": [0.55, 0, 0.55], "size": [1.55564, 2.0], "material": {"type": "diffuse", "albedo": albedo},
         "rotate": [{"axis": [0, 1, 0], "angle": -45}]},
    ], [{"type": "directional", "direction": [0, 0, 1], "irradiance": 2.0}],
        camera={"type": "orthographic", "origin": [0, 0, 3], "half_width": 1.0}, render={"resolution": [32, 16]})


def test_radiosity_image_samples_the_patch_under_each_pixel():
    spec = groove_spec()
    r = solve_scene(spec, patch_size=0.25, visibility=False)
    idx = patch_index_image(spec, r.patches)
    from pbrbench.shading.surfaces import pixel_grid

    X, Y = pixel_grid(16, 32, 1.0)
    hit = idx >= 0
    assert hit[:, 2:-2].all()
    # the patch found contains the pixel centre's vertical line
    for i, j in zip(*np.nonzero(hit), strict=True):
        v = r.patches.vertices[idx[i, j]]
        assert v[:, 0].min() - 1e-9 <= X[i, j] <= v[:, 0].max() + 1e-9 and v[:, 1].min() - 1e-9 <= Y[i, j] <= v[:, 1].max() + 1e-9
    local = r.image(bounce=0)
    np.testing.assert_allclose(local[hit], 0.6 * 2.0 * np.cos(np.pi / 4) / np.pi)  # rho E cos45 / pi
    full = radiosity_image(spec, r.patches, r.solution.B)
    assert np.all(full[hit] > local[hit])
    assert full.shape == (16, 32, 3)


def test_image_shows_lights_and_the_environment():
    spec = scene([{"type": "rectangle", "size": [1, 1]}],
                 [{"type": "ambient", "radiance": 0.25},
                  {"type": "area", "center": [0.6, 0, 1.0], "size": [0.2, 0.2], "normal": [0, 0, 1], "radiance": 7.0}],
                 camera={"type": "orthographic", "origin": [0, 0, 3], "half_width": 1.0}, render={"resolution": 20})
    p = patches_from_spec(spec, patch_size=0.5)
    img = radiosity_image(spec, p, np.full((len(p), 3), np.pi))
    assert img[10, 10, 0] == pytest.approx(1.0)  # B / pi
    assert img[0, 0, 0] == pytest.approx(0.25)  # the environment
    assert img[10, 16, 0] == pytest.approx(7.0)  # the light's front


def _brute_force_index(spec, patches, W, H):
    """The nearest front-facing triangle along each perspective pixel ray, by testing every triangle."""
    cam = spec.camera
    o = np.asarray(cam.origin, float)
    d = np.asarray(cam.target, float) - o
    d /= np.linalg.norm(d)
    right = np.cross(d, cam.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, d)
    t = np.tan(np.radians(cam.fov) / 2)
    xs = t * (2 * (np.arange(W) + 0.5) / W - 1)
    ys = t * (1 - 2 * (np.arange(H) + 0.5) / H) * H / W
    tris, owner = patches.triangles()
    X, Y = np.meshgrid(xs, ys)
    r = d + X[..., None] * right + Y[..., None] * up
    out = np.full((H, W), -1)
    best = np.full((H, W), np.inf)
    for k, tri in enumerate(tris):  # plane hit, then the point inside all three edges (same side as the normal)
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        den = r @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = (n @ (tri[0] - o)) / den
        q = o + dist[..., None] * r
        inside = np.ones((H, W), bool)
        for a, b in ((0, 1), (1, 2), (2, 0)):
            inside &= np.cross(tri[b] - tri[a], q - tri[a]) @ n >= -1e-9 * (n @ n)
        win = inside & (dist > 0) & (dist < best)
        best[win] = dist[win]
        out[win] = np.where(den[win] < 0, owner[k], -1 - 10**9)
    return out


def test_perspective_index_image_matches_brute_force_rays():
    spec = scene([{"type": "box", "center": [0.2, -0.1, 0], "size": [1, 0.8, 0.6],
                   "rotate": [{"axis": [0, 1, 0], "angle": 30}]},
                  {"type": "rectangle", "center": [0, 0, -1], "size": [4, 4]}],
                 camera={"type": "perspective", "origin": [0.3, 0.4, 3.0], "target": [0, 0, 0], "fov": 50.0},
                 render={"resolution": [24, 18]})
    p = patches_from_spec(spec, patch_size=0.5)
    idx = patch_index_image(spec, p)
    want = _brute_force_index(spec, p, 24, 18)
    assert (idx >= 0).mean() > 0.9
    # pixel centres on an edge between two triangles may go either way
    assert (idx != want).mean() < 0.01
    # a triangle through the camera's plane: the floor under the camera, seen by exact rays
    spec2 = scene([{"type": "rectangle", "center": [0, -1, 0], "size": [8, 8], "rotate": [{"axis": [1, 0, 0], "angle": -90}]}],
                  camera={"type": "perspective", "origin": [0.0, 0.0, 3.0], "fov": 60.0}, render={"resolution": 16})
    p2 = patches_from_spec(spec2, patch_size=8.0)
    np.testing.assert_array_equal(patch_index_image(spec2, p2), _brute_force_index(spec2, p2, 16, 16))


def test_modules_import_numpy_only():
    import json
    import subprocess
    import sys

    code = ("import sys, json, pbrbench.radiosity.solver, pbrbench.radiosity.concave_cap, "
            "pbrbench.radiosity.groove_profile, pbrbench.shading.gain_curve; "
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('mitsuba', 'drjit', 'pydantic', 'skimage', 'matplotlib'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []


def test_public_functions_are_documented_with_references():
    import pbrbench.radiosity.concave_cap as cap
    import pbrbench.radiosity.form_factor_matrix as ffm
    import pbrbench.radiosity.groove_profile as gp
    import pbrbench.radiosity.image as rim
    import pbrbench.radiosity.solver as rad
    import pbrbench.shading.form_factors as ff
    import pbrbench.shading.gain_curve as gc

    for mod in (rad, rim, ff, ffm, cap, gp, gc):
        assert "References" in mod.__doc__ or "Reference:" in mod.__doc__, mod.__name__
        for name in mod.__all__:
            obj = getattr(mod, name)
            if callable(obj):
                assert obj.__doc__ and len(obj.__doc__) > 40, f"{mod.__name__}.{name}"
