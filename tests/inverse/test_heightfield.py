"""The height-field mesh and its priors (NumPy, analytic inputs)."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.inverse import heightfield as HF


def _grid(hf: HF.HeightField):
    x, y = hf.corner_xy()
    return x, y


def test_corner_grid_coordinates_follow_the_film():
    hf = HF.HeightField(np.ones((4, 6), bool), half_width=1.5)
    x, y = hf.corner_xy()
    assert hf.h == pytest.approx(0.5)
    assert x[0, 0] == pytest.approx(-1.5) and x[0, -1] == pytest.approx(1.5)
    assert y[0, 0] == pytest.approx(1.0) and y[-1, 0] == pytest.approx(-1.0)   # row 0 at the top


@pytest.mark.parametrize("p, q", [(0.0, 0.0), (0.3, -0.2), (-1.2, 0.7)])
def test_plane_corners_give_the_plane_normal_everywhere(p, q):
    hf = HF.HeightField(np.ones((5, 7), bool), half_width=1.0)
    x, y = _grid(hf)
    zc = p * x + q * y + 0.4
    n = HF.pixel_normals(zc, hf.h)
    want = np.array([-p, -q, 1.0]) / np.sqrt(1 + p * p + q * q)
    assert np.allclose(n, want, atol=1e-12)


def test_plane_normals_integrate_back_to_the_plane():
    surf = np.ones((8, 8), bool)
    hf = HF.HeightField(surf, half_width=1.0)
    x, y = _grid(hf)
    zc = 0.5 * x - 0.25 * y
    n = HF.pixel_normals(zc, hf.h)
    z = HF.heights_from_normals(n, surf, hf)
    assert np.allclose(hf.corners(z), zc - zc.mean(), atol=1e-6)


def test_paraboloid_round_trip_is_close():
    """Corner heights -> pixel normals -> corner heights recovers a curved surface."""
    surf = np.ones((16, 16), bool)
    hf = HF.HeightField(surf, half_width=1.0)
    x, y = _grid(hf)
    zc = 0.3 * (x * x + 0.5 * y * y)
    z = HF.heights_from_normals(HF.pixel_normals(zc, hf.h), surf, hf)
    err = hf.corners(z) - (zc - zc.mean())
    assert np.abs(err).max() < 0.02 * np.ptp(zc)


def test_masked_pixels_continue_the_surface():
    """Pixels without a valid normal are bridged by the weak second-difference term (a plane
    stays a plane across a hole)."""
    surf = np.ones((10, 10), bool)
    valid = surf.copy()
    valid[4:6, 4:6] = False
    hf = HF.HeightField(surf, half_width=1.0)
    x, y = _grid(hf)
    zc = 0.4 * x + 0.1 * y
    z = HF.heights_from_normals(HF.pixel_normals(zc, hf.h), valid, hf)
    assert np.allclose(hf.corners(z), zc - zc.mean(), atol=1e-4)


def _thin_plate(z_fn, n=12):
    hf = HF.HeightField(np.ones((n, n), bool), half_width=1.0)
    x, y = _grid(hf)
    z = hf.params_from_corners(z_fn(x, y))
    T = HF.thin_plate_matrix(hf)
    return hf, T, z


def test_thin_plate_energy_is_zero_on_planes():
    hf, T, z = _thin_plate(lambda x, y: 0.7 * x - 0.3 * y + 2.0)
    assert np.abs(T @ z).max() < 1e-12


def test_thin_plate_gradient_vanishes_inside_on_quadrics_but_not_on_quartics():
    """``T^T T z`` (the prior's gradient) is zero away from the border for any quadratic surface
    (the discrete biharmonic of a quadric), and not for ``x^2 y^2`` (biharmonic 8)."""
    def interior_gradient(fn):
        hf, T, z = _thin_plate(fn)
        g = hf.corners(T.T @ (T @ z))
        return np.abs(g[3:-3, 3:-3]).max(), np.abs(T @ z).max()

    for fn in (lambda x, y: x * x, lambda x, y: 0.5 * x * x + 0.3 * x * y - 0.8 * y * y):
        g, e = interior_gradient(fn)
        assert e > 1e-3            # the energy itself is not zero on a curved surface
        assert g < 1e-9
    g, _ = interior_gradient(lambda x, y: x * x * y * y)
    assert g > 1e-3


def test_thin_plate_twist_row_sees_the_checkerboard():
    """The quad twist term penalises the checkerboard mode (invisible to a pixel-mean slope)."""
    hf, T, _ = _thin_plate(lambda x, y: 0 * x)
    i, j = np.indices((hf.H + 1, hf.W + 1))
    z = hf.params_from_corners(((i + j) % 2).astype(float))
    assert np.linalg.norm(T @ z) > 1.0


def test_up_and_down_sampling():
    i, j = np.indices((5, 5))
    z = 0.3 * i - 0.7 * j + 0.1 * i * j       # bilinear: reproduced exactly
    f = 3
    up = HF.upsample_corners(z, f)
    ii, jj = np.indices(up.shape) / f
    assert np.allclose(up, 0.3 * ii - 0.7 * jj + 0.1 * ii * jj)
    imgs = np.arange(2 * 4 * 6, dtype=float).reshape(2, 4, 6)
    d = HF.downsample_images(imgs, 2)
    assert d.shape == (2, 2, 3)
    assert d[1, 0, 0] == pytest.approx(imgs[1, :2, :2].mean())
    m = np.zeros((4, 4), bool)
    m[:2, :3] = True
    assert HF.downsample_mask(m, 2).tolist() == [[True, False], [False, False]]
    assert HF.downsample_any(m, 2).tolist() == [[True, True], [False, False]]


def test_pixel_sets_close_a_lit_crease_and_add_a_ring():
    mask = np.zeros((9, 9), bool)
    mask[2:7, 2:7] = True
    mask[:, 4] = False                       # the crease left out of the mask
    mask[:2] = mask[7:] = False
    imgs = np.zeros((3, 9, 9))
    imgs[:, 1:8, 1:8] = 1.0                  # lit a little beyond the mask
    data, surf = HF.pixel_sets(mask, imgs)
    assert data[2:7, 4].all()                # the gap is lit and closed
    assert surf[1, 1] and not data[1, 1]     # the ring: surface without loss
    assert not surf[0, 0]                    # unlit background stays out


def test_extension_continues_the_border_slope():
    surf = np.ones((4, 4), bool)
    hf = HF.HeightField(surf, half_width=1.0, extend=(0.8, 0.0, 0.0, 0.0))
    x, y = _grid(hf)
    zc = 0.5 * x
    v = hf.vertex_heights(hf.params_from_corners(zc))
    outer = hf.vertex_xy[:, 0] < -1.0 - 1e-9
    assert outer.any()
    assert np.allclose(v[outer], 0.5 * hf.vertex_xy[outer, 0])   # a plane extends as itself
    assert hf.faces.max() < len(hf.vertex_xy)


def test_laplacian_is_a_graph_laplacian():
    hf = HF.HeightField(np.ones((3, 4), bool), half_width=1.0)
    L = hf.laplacian().toarray()
    assert np.allclose(L, L.T)
    assert np.allclose(L.sum(axis=1), 0.0)
    assert np.all(np.linalg.eigvalsh(L) > -1e-10)
