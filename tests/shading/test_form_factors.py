"""Form factors: the exact point-to-polygon factor, quadrature, closed-form anchors, visibility."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.radiosity.form_factor_matrix import form_factor_matrix
from pbrbench.radiosity.patches import make_patches
from pbrbench.radiosity.raycast import build_occluders, ray_triangle_hits
from pbrbench.shading.form_factors import (
    parallel_rectangles_form_factor,
    patch_geometry,
    patch_quadrature,
    perpendicular_rectangles_form_factor,
    point_polygon_form_factors,
    strip_form_factors_2d,
)
from pbrbench.shading.irradiance import polygon_irradiance


def grid_square(n, z=0.0, size=1.0, flip=False, offset=(0.0, 0.0)):
    """n x n quads tiling [0, size]^2 + offset at height z, normal +z (-z if flip)."""
    u = np.linspace(0, size, n + 1)
    quads = []
    for i in range(n):
        for j in range(n):
            q = [[u[i], u[j], z], [u[i + 1], u[j], z], [u[i + 1], u[j + 1], z], [u[i], u[j + 1], z]]
            quads.append(q[::-1] if flip else q)
    q = np.array(quads, float)
    q[..., 0] += offset[0]
    q[..., 1] += offset[1]
    return q


def wall_square(n, size=1.0):
    """n x n quads tiling the square x = 0, y in [0, size], z in [0, size], normal +x."""
    u = np.linspace(0, size, n + 1)
    quads = []
    for i in range(n):
        for j in range(n):
            quads.append([[0, u[i], u[j]], [0, u[i + 1], u[j]], [0, u[i + 1], u[j + 1]], [0, u[i], u[j + 1]]])
    return np.array(quads, float)


def test_batched_factor_equals_polygon_irradiance():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(3000, 3))
    n = rng.normal(size=(3000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    poly = np.array([[-0.5, -0.5, 0], [0.6, -0.4, 0.1], [0.4, 0.5, 0.2], [-0.3, 0.7, 0.1]])
    poly[:, 2] = poly[:, 0] * 0.2 + poly[:, 1] * 0.1  # planar, tilted
    f = point_polygon_form_factors(x, n, np.repeat(poly[None], len(x), 0))
    ref = polygon_irradiance(x, n, poly) / np.pi
    clipped = (np.einsum("mk,pk->pm", poly, n) - np.sum(x * n, 1)[:, None] > 0).any(1) & \
              ~(np.einsum("mk,pk->pm", poly, n) - np.sum(x * n, 1)[:, None] > 0).all(1)
    assert clipped.sum() > 200  # the hemisphere clipping is exercised
    np.testing.assert_allclose(f, ref, atol=1e-14)


@pytest.mark.parametrize("d", [0.5, 1.0, 2.0])
def test_parallel_squares_against_closed_form(d):
    A, B = grid_square(1), grid_square(1, z=d, flip=True)
    pts, w = patch_quadrature(A, 8, 4)
    Q = pts.shape[1]
    ff = point_polygon_form_factors(pts[0], np.tile([0.0, 0.0, 1.0], (Q, 1)), np.repeat(B, Q, 0))
    assert abs(np.sum(ff * w[0]) - parallel_rectangles_form_factor(1, 1, d)) < 1e-9
    # refined meshes, adaptive quadrature: additivity A F(A->B) = sum_ij A_i F_ij
    p = make_patches(np.concatenate([grid_square(6), grid_square(6, z=d, flip=True)]), face_id=[0] * 36 + [1] * 36)
    F = form_factor_matrix(p)
    got = np.sum(p.areas[:36, None] * F[:36, 36:])
    assert abs(got - parallel_rectangles_form_factor(1, 1, d)) < 1e-3 * parallel_rectangles_form_factor(1, 1, d)


def test_closed_forms_known_values():
    assert parallel_rectangles_form_factor(1, 1, 1) == pytest.approx(0.19982, abs=1e-5)
    assert perpendicular_rectangles_form_factor(1, 1, 1) == pytest.approx(0.20004, abs=1e-5)
    # reciprocity of the perpendicular closed form: A1 F12 = A2 F21
    assert 1 * 2 * perpendicular_rectangles_form_factor(1, 2, 0.5) == pytest.approx(
        1 * 0.5 * perpendicular_rectangles_form_factor(1, 0.5, 2), rel=1e-12)


@pytest.mark.parametrize("n", [1, 4, 8])
def test_perpendicular_squares_sharing_an_edge(n):
    floor, wall = grid_square(n), wall_square(n)
    p = make_patches(np.concatenate([floor, wall]), face_id=[0] * n * n + [1] * n * n)
    F = form_factor_matrix(p)
    k = n * n
    got = np.sum(p.areas[:k, None] * F[:k, k:])
    assert abs(got - perpendicular_rectangles_form_factor(1, 1, 1)) < 2e-4


def test_reciprocity():
    rng = np.random.default_rng(3)
    floor, wall = grid_square(5), wall_square(5)
    ceil = grid_square(5, z=1.0, flip=True)
    p = make_patches(np.concatenate([floor, wall, ceil]), face_id=np.repeat([0, 1, 2], 25))
    for quad, tol in (("adaptive", 2e-3), ((2, 4), 1e-6)):
        F = form_factor_matrix(p, quadrature=quad)
        AF = p.areas[:, None] * F
        nz = AF > 0
        rel = np.abs(AF - AF.T)[nz] / AF[nz]
        assert rel.max() < tol, quad
    assert rng is not None


def closed_cube(n):
    """The six inward faces of [-1, 1]^3, n x n quads each."""
    faces, ids = [], []
    for ax in range(3):
        t1, t2 = (ax + 1) % 3, (ax + 2) % 3
        u = np.linspace(-1, 1, n + 1)
        for sgn in (1.0, -1.0):
            for i in range(n):
                for j in range(n):
                    q = np.zeros((4, 3))
                    for k, (a, b) in enumerate([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]):
                        q[k, t1], q[k, t2], q[k, ax] = u[a], u[b], sgn
                    faces.append(q if sgn < 0 else q[::-1])  # inward normals
                    ids.append(2 * ax + (sgn > 0))
    return np.array(faces), np.array(ids)


def test_closed_enclosure_rows_sum_to_one():
    v, ids = closed_cube(4)
    p = make_patches(v, 0.5, face_id=ids)
    assert np.allclose(np.sum(p.normals * p.centres, 1), -1.0)  # inward normals
    Fu = form_factor_matrix(p, quadrature=(2, 3))
    np.testing.assert_allclose(Fu.sum(1), 1.0, atol=1e-12)  # one rule per row: exact
    Fa = form_factor_matrix(p)
    assert np.abs(Fa.sum(1) - 1).max() < 1e-3  # adaptive rule: the outer quadrature error
    np.testing.assert_allclose(form_factor_matrix(p, visibility=False), Fa, atol=0)  # nothing blocks


def test_visibility_box_inside_room_converges():
    """Closed room with a floating box: rows sum to 1 only up to the sampled visibility, which converges."""
    def scene(n):
        room, rid = closed_cube(n)
        box, bid = closed_cube(max(1, n // 4))
        box = 0.3 * box[:, ::-1] + np.array([0.2, -0.1, 0.1])  # outward faces of a small cube
        return make_patches(np.concatenate([room, box]), 0.5, face_id=np.concatenate([rid, 6 + bid]))

    devs = []
    for n in (4, 8):
        p = scene(n)
        F = form_factor_matrix(p)
        F0 = form_factor_matrix(p, visibility=False)
        assert F0.sum(1).max() > 1.05  # without visibility the box is counted twice
        devs.append(np.mean(np.abs(F.sum(1) - 1)))
    assert devs[0] < 0.02 and devs[1] < 0.6 * devs[0]


def test_strip_form_factors_2d_against_kernel_integral():
    a = np.array([[[0.0, 0.0], [1.0, 0.0]]])  # normal +y
    b = np.array([[[0.2, 1.0], [1.5, 0.6]]])  # facing down-ish
    F = strip_form_factors_2d(a, b)[0, 0]
    # midpoint integration of cos cos' / (2 r) over both segments, / L_a
    m = 2000
    s = (np.arange(m) + 0.5) / m
    x = np.stack([s, 0 * s], -1)
    y = b[0, 0] + s[:, None] * (b[0, 1] - b[0, 0])
    nb = np.array([-(b[0, 1] - b[0, 0])[1], (b[0, 1] - b[0, 0])[0]])
    nb /= np.linalg.norm(nb)
    nb = -nb if nb[1] > 0 else nb
    d = y[None] - x[:, None]
    r = np.linalg.norm(d, axis=-1)
    k = (d[..., 1] / r) * (-(d @ nb) / r) / (2 * r)
    num = k.sum() / m * (1.0 / m) * np.linalg.norm(b[0, 1] - b[0, 0])
    assert F == pytest.approx(num, rel=1e-5)


def test_ray_triangle_hits():
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    o = np.array([[0.2, 0.2, 1.0], [0.8, 0.8, 1.0], [0.2, 0.2, 1.0]])
    d = np.array([[0, 0, -2.0], [0, 0, -2.0], [0, 0, -0.5]])
    np.testing.assert_array_equal(ray_triangle_hits(o, d, tri[None]), [True, False, False])
    occ = build_occluders(tri[None], [0])
    assert occ.n_clusters == 1 and not np.isnan(occ.group_plane[0, 0])


def test_degenerate_patch_is_refused():
    with pytest.raises(ValueError, match="degenerate"):
        patch_geometry(np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]]))
    with pytest.raises(ValueError, match="not planar"):
        patch_geometry(np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0.0]]]))
    with pytest.raises(ValueError, match="quadrature"):
        form_factor_matrix(make_patches(grid_square(1)), quadrature="gauss")
