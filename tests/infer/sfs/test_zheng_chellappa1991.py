"""Tests of Zheng & Chellappa's (1991) albedo, light and shape estimate
(``pbrbench.infer.sfs.zheng_chellappa1991``)."""

import math
import warnings

import numpy as np
import pytest

from pbrbench.infer.sfs import shape_from_shading_horn1989
from pbrbench.infer.sfs.zheng_chellappa1991 import (
    light_from_shading_zheng_chellappa1991,
    shape_from_shading_zheng_chellappa1991,
    zheng_chellappa_moments,
)
from pbrbench.metrics.sfs import normal_angle
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid
from tests.infer.sfs._scenes import FRONTAL, OBLIQUE, scene


def _deg(a, b):
    return math.degrees(math.acos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


@pytest.mark.parametrize("slant_deg", [0.0, 20.0, 45.0, 70.0])
def test_moments_invert_in_closed_form(slant_deg):
    # E{I} = pi/4 lam cos s, E{I^2} = lam^2 (1 + 3 cos^2 s) / 6 give back lam and s exactly
    lam, s = 0.7, math.radians(slant_deg)
    m1 = math.pi / 4 * lam * math.cos(s)
    m2 = lam * lam * (1 + 3 * math.cos(s) ** 2) / 6
    lam_e, s_e, clamped = zheng_chellappa_moments(m1, m2)
    assert lam_e == pytest.approx(lam, rel=1e-12)
    assert s_e == pytest.approx(s, abs=1e-6)
    assert not clamped


def test_moment_formulas_hold_for_their_normal_distribution():
    # Monte Carlo over the assumed distribution (tilt uniform, slant density cos a, i.e.
    # sin a uniform), signed shading (no self-shadowing): the two moment formulas
    rng = np.random.default_rng(0)
    n = 400_000
    a = np.arcsin(rng.uniform(0, 1, n))
    t = rng.uniform(0, 2 * np.pi, n)
    N = np.stack([np.sin(a) * np.cos(t), np.sin(a) * np.sin(t), np.cos(a)], axis=1)
    s = math.radians(35.0)
    S = np.array([math.sin(s), 0.0, math.cos(s)])
    i = 0.9 * N @ S
    assert i.mean() == pytest.approx(math.pi / 4 * 0.9 * math.cos(s), rel=5e-3)
    assert (i * i).mean() == pytest.approx(0.81 * (1 + 3 * math.cos(s) ** 2) / 6, rel=5e-3)


def test_sphere_statistics_frontal_light_closed_form():
    # a sphere's normals are uniform over the image disc, not the assumed distribution: under a
    # frontal light <I> = 2/3 rho and <I^2> = rho^2 / 2, so the estimator returns
    # lam = rho sqrt(3 - 64 / (3 pi^2)) = 0.916 rho and cos s = 8 / (3 pi sqrt(...)) (s = 22 deg):
    # the method's known bias, reproduced to the image's discretisation
    s, img, _ = scene("sphere", 256, FRONTAL, albedo=0.8)
    est = light_from_shading_zheng_chellappa1991(img, s.mask)
    root = math.sqrt(3 - 64 / (3 * math.pi**2))
    assert est.albedo == pytest.approx(0.8 * root, rel=0.01)
    assert math.degrees(math.acos(est.direction[2])) == pytest.approx(
        math.degrees(math.acos(8 / (3 * math.pi * root))), abs=1.0)
    assert est.method == "zheng_chellappa1991"


@pytest.mark.parametrize("tilt_deg", [0.0, 60.0, 150.0, -100.0])
def test_sphere_oblique_light_within_tolerance(tilt_deg):
    # 45 degree slant: measured light error 3.9 deg, albedo -2.4 %; the tilt is within 1 deg
    t = math.radians(tilt_deg)
    light = np.array([math.cos(t) / math.sqrt(2), math.sin(t) / math.sqrt(2), 1 / math.sqrt(2)])
    s, img, _ = scene("sphere", 128, light, albedo=0.8)
    est = light_from_shading_zheng_chellappa1991(img, s.mask)
    assert _deg(est.direction, light) < 5.0
    tilt = math.degrees(math.atan2(est.direction[1], est.direction[0]))
    assert abs((tilt - tilt_deg + 180) % 360 - 180) < 1.0
    assert est.albedo == pytest.approx(0.8, rel=0.04)


@pytest.mark.parametrize("light", [OBLIQUE, np.array([-0.3, 0.4, 0.866]) / np.linalg.norm([-0.3, 0.4, 0.866])])
def test_estimating_albedo_beats_sfs_given_a_wrong_albedo(light):
    # measured normal error (deg): this method (no albedo, no light given) 6.9 / 9.8; horn1989
    # given the true light but 0.7x the albedo 16.9 / 19.0 (with the true albedo 3.9 / 3.7)
    s, img, h = scene("sphere", 64, light, albedo=0.8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ours = shape_from_shading_zheng_chellappa1991(img, None, mask=s.mask, pixel_size=h)
        wrong = shape_from_shading_horn1989(img, light, albedo=0.7 * 0.8, mask=s.mask, pixel_size=h)
    e_ours = normal_angle(ours.normals, s.normals, s.mask)
    e_wrong = normal_angle(wrong.normals, s.normals, s.mask)
    assert e_ours < 12.0
    assert e_ours < 0.7 * e_wrong
    assert ours.method == "zheng_chellappa1991" and ours.info["shape_method"] == "horn1989"
    assert ours.albedo == pytest.approx(0.8, rel=0.04)
    np.testing.assert_allclose(ours.light, ours.info["estimated_light"])
    assert np.all(np.isfinite(ours.height)) and ours.height.shape == img.shape


def test_given_light_and_wrong_albedo_are_ignored_by_default():
    s, img, h = scene("sphere", 48, OBLIQUE, albedo=0.8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        a = shape_from_shading_zheng_chellappa1991(img, FRONTAL, albedo=0.3, mask=s.mask, pixel_size=h,
                                                   shape_options={"max_iter": 10})
        b = shape_from_shading_zheng_chellappa1991(img, None, mask=s.mask, pixel_size=h,
                                                   shape_options={"max_iter": 10})
        c = shape_from_shading_zheng_chellappa1991(img, OBLIQUE, mask=s.mask, pixel_size=h, estimate="albedo",
                                                   shape_options={"max_iter": 10})
    np.testing.assert_array_equal(a.height, b.height)
    assert a.info["given_albedo"] == 0.3
    # estimate="albedo": the given light is used as is, the albedo is the estimate
    np.testing.assert_allclose(c.light, OBLIQUE)
    assert c.albedo == pytest.approx(a.albedo)


def test_a_plane_breaks_the_assumption_and_clamps_the_slant():
    # every normal the same: <I>^2 / <I^2> = 1 > what uniform normals allow, cos s = 1.19 > 1
    pl = on_grid("plane", 32, 1.0)
    img = lambertian_images(pl.normals, 0.8, OBLIQUE[None])[0]
    with pytest.warns(RuntimeWarning, match="pentland1990"):   # frontal: pentland's flat answer
        r = shape_from_shading_zheng_chellappa1991(img, None, shape_method="pentland1990")
    assert r.info["clamped"]
    np.testing.assert_allclose(r.light, [0.0, 0.0, 1.0], atol=1e-12)
    est = light_from_shading_zheng_chellappa1991(img)
    assert est.albedo == pytest.approx(math.sqrt(6 - 48 / math.pi**2) * img.mean(), rel=1e-9)


def test_input_errors():
    img = np.ones((16, 16))
    with pytest.raises(ValueError, match="negative"):
        light_from_shading_zheng_chellappa1991(-img)
    with pytest.raises(ValueError, match="all zero"):
        shape_from_shading_zheng_chellappa1991(0 * img)
    with pytest.raises(ValueError, match="mask"):
        light_from_shading_zheng_chellappa1991(img, np.ones((4, 4), bool))
    with pytest.raises(ValueError, match="estimate"):
        shape_from_shading_zheng_chellappa1991(img, estimate="shape")
    with pytest.raises(ValueError, match="light: estimate='albedo'"):
        shape_from_shading_zheng_chellappa1991(img, None, estimate="albedo")
    with pytest.raises(ValueError, match="albedo: estimate='light'"):
        shape_from_shading_zheng_chellappa1991(img, None, estimate="light")
    with pytest.raises(ValueError, match="z component"):
        shape_from_shading_zheng_chellappa1991(img, [0, 0, -1], estimate="albedo")
    with pytest.raises(ValueError, match="shape_method"):
        shape_from_shading_zheng_chellappa1991(img, shape_method="kimmel2001")
    with pytest.raises(ValueError, match="unknown option"):
        shape_from_shading_zheng_chellappa1991(img, shape_options={"smoothnes": 1.0})
    with pytest.raises(ValueError, match="shape_options"):
        shape_from_shading_zheng_chellappa1991(img, shape_options=[("max_iter", 3)])
    with pytest.raises(ValueError, match="sigma"):
        light_from_shading_zheng_chellappa1991(img, sigma=-1.0)
