"""Tests of Horn's (1989) height-and-gradient scheme (``pbrbench.infer.sfs.horn1989``)."""

import warnings

import numpy as np
import pytest

from pbrbench.infer.sfs import occluding_boundary, shape_from_shading, shape_from_shading_horn1989
from pbrbench.metrics.sfs import normal_angle
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid
from tests.infer.sfs._scenes import HW, OBLIQUE, flat_angle, scene


def test_horn_is_accurate_on_oblique_sphere():
    s, img, h = scene("sphere", 64, OBLIQUE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        hn = shape_from_shading(img, OBLIQUE, method="horn1989", albedo=0.8, mask=s.mask, pixel_size=h, max_iter=100)
    assert normal_angle(hn.normals, s.normals, s.mask) < 15.0
    assert hn.method == "horn1989"


def test_horn_coarse_to_fine_sweeps_reported():
    s, img, h = scene("sphere", 64, OBLIQUE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = shape_from_shading(img, OBLIQUE, method="horn1989", albedo=0.8, mask=s.mask, pixel_size=h, max_iter=30)
    # n_iter counts sweeps on the finest grid; coarser grids add theirs to total_sweeps
    assert r.n_iter <= 30 and r.info["total_sweeps"] > r.n_iter
    assert np.isfinite(r.info["final_update"])


def test_iteration_budget_exhausted_warns_without_nan():
    s, img, h = scene("sphere", 48, OBLIQUE)
    with pytest.warns(RuntimeWarning, match="horn1989"):
        r = shape_from_shading(img, OBLIQUE, method="horn1989", albedo=0.8, mask=s.mask, max_iter=2, tol=1e-12)
    assert not r.converged and r.n_iter == 2
    assert np.all(np.isfinite(r.height))


def test_horn_auto_boundary_ignores_a_cut_edge():
    # a random smooth surface cut by a disc: its edge is no occluding contour; fixing contour
    # slopes there (boundary="occluding") ruins the solve, "auto" detects it and uses none
    n = 96
    s = on_grid("random_smooth", n, half_width=HW)
    yy, xx = np.mgrid[:n, :n]
    m = s.mask & ((yy - n / 2) ** 2 + (xx - n / 2) ** 2 < (0.45 * n) ** 2)
    img = np.where(m, lambertian_images(s.normals, 0.8, OBLIQUE[None])[0], 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        auto = shape_from_shading(img, OBLIQUE, method="horn1989", albedo=0.8, mask=m, pixel_size=2 * HW / n)
        occ = shape_from_shading(img, OBLIQUE, method="horn1989", albedo=0.8, mask=m, pixel_size=2 * HW / n,
                                 boundary="occluding")
        sph, simg, h = scene("sphere", n, OBLIQUE)
        sp = shape_from_shading(simg, OBLIQUE, method="horn1989", albedo=0.8, mask=sph.mask, pixel_size=h)
    assert auto.info["n_boundary"] == 0 and occ.info["n_boundary"] > 0
    assert normal_angle(auto.normals, s.normals, m) < 15.0 < normal_angle(occ.normals, s.normals, m)
    # on a sphere the whole silhouette is a contour and "auto" keeps (nearly) all of it
    assert sp.info["n_boundary"] > 0.9 * occluding_boundary(sph.mask).sum()


def test_boundary_array_fixes_exactly_those_pixels():
    s, img, h = scene("sphere", 32, OBLIQUE)
    b = occluding_boundary(s.mask)
    b[: 16] = False  # the lower half of the silhouette only
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = shape_from_shading_horn1989(img, OBLIQUE, albedo=0.8, mask=s.mask, pixel_size=h, boundary=b,
                                        max_iter=5, levels=1)
        free = shape_from_shading_horn1989(img, OBLIQUE, albedo=0.8, mask=s.mask, pixel_size=h, boundary="free",
                                           max_iter=5, levels=1)
    assert r.info["n_boundary"] == b.sum() and free.info["n_boundary"] == 0


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"max_iter": 0}, "max_iter"), ({"tol": 0.0}, "tol"), ({"boundary": "wrong"}, "boundary"),
    ({"boundary": np.ones((8, 8), bool)}, "boundary"), ({"theta_max_deg": 90.0}, "theta_max_deg"),
    ({"smoothness": -1.0}, "smoothness"), ({"smoothness_min": 0.0}, "smoothness_min"),
    ({"integrability": 0.0}, "integrability"), ({"n_stages": 1.5}, "n_stages"), ({"levels": 0}, "levels"),
])
def test_option_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        shape_from_shading_horn1989(np.full((16, 16), 0.5), [0.3, 0.0, 1.0], **kwargs)


VIEW = np.array([0.0, 0.0, 1.0])


def test_a_flat_start_that_never_moves_is_a_failure_not_a_success():
    """Light along the view: the flat start is a fixed point of Horn's iteration (R_p = R_q = 0
    there); without an occluding contour it stays flat.  That is reported: converged False, the
    reason in info, a warning -- never converged with the start surface."""
    s, img, h = scene("vase", 64, VIEW)
    with pytest.warns(RuntimeWarning, match="flat surface"):
        r = shape_from_shading_horn1989(img, VIEW, albedo=0.8, mask=s.mask, pixel_size=h, boundary="free")
    assert not r.converged and "fixed point" in r.info["failure"] and "boundary='occluding'" in r.info["failure"]
    assert np.ptp(r.height[s.mask]) == 0.0


def test_auto_contour_under_a_view_light_uses_the_silhouette_even_on_a_cut_mask():
    """A vase whose mask is cut by the image rows (less than 60 % of its edge is a contour): under
    an oblique light the cut edge is not trusted, but under a view light the flat start would be a
    fixed point, so the pixels that look like a contour start the solve and the result is far
    better than flat."""
    s, img, h = scene("vase", 64, VIEW)
    m = s.mask.copy()
    rows = np.where(m.any(axis=1))[0]
    keep = (np.arange(m.shape[0]) > rows[0] + 20) & (np.arange(m.shape[0]) < rows[-1] - 20)
    m &= keep[:, None]
    edge = occluding_boundary(m)
    assert edge.sum() > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = shape_from_shading_horn1989(img * m, VIEW, albedo=0.8, mask=m, pixel_size=h)
        flat = shape_from_shading_horn1989(img * m, VIEW, albedo=0.8, mask=m, pixel_size=h, boundary="free")
    assert r.info["n_boundary"] > 0 and np.ptp(r.height[m]) > 0
    assert normal_angle(r.normals, s.normals, m) < 0.95 * normal_angle(flat.normals, s.normals, m)
    # the whole vase, its silhouette an occluding contour: the view-light solve is far from flat
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        whole = shape_from_shading_horn1989(img, VIEW, albedo=0.8, mask=s.mask, pixel_size=h)
    assert normal_angle(whole.normals, s.normals, s.mask) < 0.5 * normal_angle(flat.normals, s.normals, m)


@pytest.mark.parametrize("offset", [(0, 0), (3, 6), (5, 2)])
def test_sweeping_the_bounding_box_gives_the_numbers_of_the_whole_image(offset):
    # the sweeps run on the mask's bounding box (grown by one pixel); red-black colours keep the
    # image's parity and the update norm is summed over the whole image, so the iterates are the
    # same numbers bit for bit wherever the mask sits (an odd offset moves the box's parity)
    from pbrbench.infer.sfs.horn1989 import _horn

    s, img, _ = scene("sphere", 32, OBLIQUE)
    big_E = np.zeros((48, 44))
    big_m = np.zeros((48, 44), bool)
    r0, c0 = offset
    big_E[r0:r0 + 32, c0:c0 + 32] = img * s.mask
    big_m[r0:r0 + 32, c0:c0 + 32] = s.mask
    kw = dict(max_iter=25, tol=1e-12, lam=1.0, lam_min=0.02, mu=1.0, boundary=occluding_boundary(big_m),
              theta_max=np.radians(88.0), n_stages=4)
    with np.errstate(all="ignore"):
        crop = _horn(big_E, OBLIQUE, big_m, **kw)
        whole = _horn(big_E, OBLIQUE, big_m, crop=False, **kw)
    for a, b in zip(crop[:3], whole[:3], strict=True):
        assert np.array_equal(a, b)
    assert crop[3:] == whole[3:]
    assert np.abs(crop[0][big_m]).max() > 0.1      # the iteration moved: the comparison is not of two starts


def test_a_light_a_few_degrees_off_the_view_keeps_the_contour():
    """An estimated light is never exactly along the view (the contour estimator's is 3-9 degrees
    off on the draft vase): within NEAR_VIEW_DEG the contour pixels that pass the test start the
    solve whatever their fraction.  With a 5-degree cone a light 8 degrees off fell to the
    fraction rule, and a mask inside the silhouette (a rendered pure mask; here eroded by 2 px:
    40 % of its edge passes) lost its contour and ended near the flat start."""
    from scipy import ndimage

    from pbrbench.infer.sfs.horn1989 import AUTO_CONTOUR_FRACTION

    t = np.radians(8.0)
    light = np.array([0.0, np.sin(t), np.cos(t)])
    s, img, h = scene("vase", 64, light)
    m = ndimage.binary_erosion(s.mask, iterations=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = shape_from_shading_horn1989(img * m, light, albedo=0.8, mask=m, pixel_size=h)
    assert 0 < r.info["n_boundary"] < AUTO_CONTOUR_FRACTION * occluding_boundary(m).sum()
    assert normal_angle(r.normals, s.normals, m) < 0.5 * flat_angle(s)
