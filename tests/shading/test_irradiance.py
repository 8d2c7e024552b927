"""Closed forms of pbrbench.shading.irradiance against brute-force numerical integration."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.shading import irradiance as irr

SRC = irr.rectangle_polygon([0.0, 0.0, 3.0], [1.0, 1.0], [0.0, 0.0, -1.0])
OCC = irr.rectangle_polygon([0.0, 0.0, 1.0], [0.5, 0.5], [0.0, 0.0, 1.0])
UP = np.array([0.0, 0.0, 1.0])


def test_lambert_formula_matches_numeric_integration():
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(-2, 2, (12, 2)), np.zeros(12)]
    normals = np.array([[0.0, 0.0, 1.0]] * 6 + [[0.3, -0.2, 1.0]] * 6)
    e = irr.polygon_irradiance(pts, normals, SRC, 10.0)
    en = irr.polygon_irradiance_numeric(pts, normals, SRC, (), 10.0, n=300)
    assert np.max(np.abs(e - en)) / e.max() < 1e-4


def test_on_axis_closed_form_and_winding_invariance():
    # point on the axis of a square of half-size a at distance D: E/L = 4 (a/r) atan(a/r), r = sqrt(a^2 + D^2)
    a, D = 0.5, 3.0
    r = np.hypot(a, D)
    expected = 4 * (a / r) * np.arctan(a / r)
    e = irr.polygon_irradiance([0.0, 0.0, 0.0], UP, SRC, 1.0)
    e_rev = irr.polygon_irradiance([0.0, 0.0, 0.0], UP, SRC[::-1], 1.0, one_sided=False)
    assert e == pytest.approx(expected, rel=1e-12)
    assert e_rev == pytest.approx(expected, rel=1e-12)


def test_one_sided_and_horizon_clipping():
    # behind the emitter: nothing
    assert irr.polygon_irradiance([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], SRC, 1.0) == 0.0
    # a vertical receiver sees half the source above its horizon: clipped formula vs brute force
    p, n = np.array([[0.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0]])
    e = irr.polygon_irradiance(p, n, SRC, 1.0)
    en = irr.polygon_irradiance_numeric(p, n, SRC, (), 1.0, n=400)
    assert e[0] == pytest.approx(en[0], rel=1e-4)


def test_visible_part_matches_numeric_integration_through_the_penumbra():
    xs = np.linspace(-0.8, 0.8, 17)
    pts = np.c_[xs, np.full_like(xs, 0.07), np.zeros_like(xs)]
    ev = irr.visible_polygon_irradiance(pts, UP, SRC, [OCC], 10.0)
    en = irr.polygon_irradiance_numeric(pts, UP, SRC, [OCC], 10.0, n=400)
    full = irr.polygon_irradiance(pts, UP, SRC, 10.0)
    assert np.max(np.abs(ev - en)) / full.max() < 2e-3
    assert ev[8] == 0.0  # x = 0 is in the umbra
    assert np.all(ev <= full + 1e-12)


def test_shadow_regions_match_the_projection_through_the_edges():
    reg = irr.shadow_regions(SRC[:, :2], 3.0, OCC[:, :2], 1.0)
    # b + (b - a) h/(H - h) and b + (a + b) h/(H - h) with a = 0.5, b = 0.25, h = 1, H = 3
    assert irr.interval_on_line(reg.umbra, 0.0) == pytest.approx((-0.125, 0.125))
    assert irr.interval_on_line(reg.penumbra, 0.0) == pytest.approx((-0.625, 0.625))
    # umbra: zero visible irradiance just inside, positive just outside
    e = irr.visible_polygon_irradiance([[0.12, 0.0, 0.0], [0.13, 0.0, 0.0], [0.62, 0, 0], [0.63, 0, 0]], UP, SRC, [OCC], 1.0)
    full = irr.polygon_irradiance([[0.62, 0, 0], [0.63, 0, 0]], UP, SRC, 1.0)
    assert e[0] == 0.0 and e[1] > 0
    assert e[2] < full[0] and e[3] == pytest.approx(full[1], rel=1e-12)
    far = irr.shadow_regions(SRC[:, :2], 3.0, OCC[:, :2], 2.0)
    assert len(far.umbra) == 0  # occluder near the source: penumbra only


def test_disk_rectangle_area():
    assert irr.disk_rectangle_area(1.0, -1, 1, -1, 1) == pytest.approx(np.pi)
    assert irr.disk_rectangle_area(1.0, 0, 1, 0, 1) == pytest.approx(np.pi / 4)
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0.5, 0.7, 400000), rng.uniform(0.6, 0.9, 400000)
    mc = np.mean(u * u + v * v < 1) * 0.2 * 0.3
    assert irr.disk_rectangle_area(1.0, 0.5, 0.7, 0.6, 0.9) == pytest.approx(mc, abs=3e-4)


def test_sphere_reference_interior_equals_lambert_and_coverage_sums_to_disk_area():
    ref = irr.sphere_reference(32, 1.2, albedo=0.5, direction=[0, 0, 1], irradiance=np.pi)
    px = 2.4 / 32
    assert ref.coverage.sum() * px * px == pytest.approx(np.pi, rel=1e-9)
    # centre pixels: box average of 0.5 * n_z is within O(px^2) of the centre value
    c = ref.radiance[15:17, 15:17]
    assert np.all(np.abs(c - 0.5 * ref.centre_normals[15:17, 15:17, 2]) < 1e-3)
    pt = irr.sphere_reference(64, 1.2, albedo=1.0, position=[0, 0, 3.0], intensity=4.0)
    # interior pixels: the box average is within O(px^2) of I cos / (pi r^2) at the pixel centre
    n = pt.centre_normals
    d = np.array([0.0, 0.0, 3.0]) - n
    r2 = np.sum(d * d, -1)
    centre = 4.0 * np.sum(n * d, -1) / np.sqrt(r2) / (np.pi * r2)
    inner = n[..., 2] > 0.5
    assert np.max(np.abs(pt.radiance - centre)[inner] / centre[inner]) < 5e-3


def test_integrating_sphere():
    d, g = irr.integrating_sphere_radiance(0.5, 10.0, 2.0)
    assert d == pytest.approx(0.5 * 10 / (np.pi * 4))
    assert g == pytest.approx(2 * d)


@pytest.mark.parametrize("call,match", [
    (lambda: irr.polygon_irradiance([0, 0, 0], UP, SRC[:2], 1.0), "polygon"),
    (lambda: irr.polygon_irradiance([0, 0], UP, SRC, 1.0), "points"),
    (lambda: irr.polygon_irradiance([0, 0, 0], [0, 0, 0], SRC, 1.0), "normals"),
    (lambda: irr.polygon_irradiance([0, 0, 0], UP, SRC, -1.0), "radiance"),
    (lambda: irr.sphere_reference(8, 1.0), "exactly one of"),
    (lambda: irr.sphere_reference(8, -1.0, direction=[0, 0, 1]), "half_width"),
    (lambda: irr.integrating_sphere_radiance(1.0, 1.0), "albedo"),
    (lambda: irr.shadow_regions(SRC[:, :2], 1.0, OCC[:, :2], 2.0), "heights"),
    (lambda: irr.visible_polygon_irradiance([0, 0, 0], UP, SRC, [np.c_[OCC[:, :2], 3 + 2 * OCC[:, 1]]], 1.0), "occluders"),
])
def test_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()
