"""Tests of pbrbench.metrics.sfs on analytic surfaces."""

import numpy as np
import pytest

from pbrbench.metrics.sfs import (
    ambiguity_aware_scores,
    flat_baseline,
    floor_height,
    floor_scores,
    height_errors,
    normal_angle,
    sfs_scores,
)
from pbrbench.shading.surfaces import on_grid

N = 64
HW = 1.1


@pytest.fixture(scope="module")
def sphere():
    return on_grid("sphere", N, half_width=HW)


def test_height_errors_ignore_offset_and_scale(sphere):
    m = sphere.mask
    z = sphere.z
    e = height_errors(z + 3.0, z, m)
    assert e["rmse"] == pytest.approx(0.0, abs=1e-12) and e["mae"] == pytest.approx(0.0, abs=1e-12)
    s = height_errors(2.0 * z + 1.0, z, m)
    assert s["rmse"] > 0.1  # the offset-only score sees the wrong scale
    assert s["rmse_scaled"] == pytest.approx(0.0, abs=1e-12)
    assert s["scale"] == pytest.approx(0.5)


def test_height_errors_known_value():
    t = np.zeros((4, 4))
    e = np.zeros((4, 4))
    e[0, 0] = 1.0
    out = height_errors(e, t)
    d = np.full(16, -1 / 16)
    d[0] += 1
    assert out["rmse"] == pytest.approx(np.sqrt(np.mean(d * d)))
    assert out["mae"] == pytest.approx(np.mean(np.abs(d)))


def test_normal_angle_known_value():
    a = np.zeros((2, 2, 3))
    a[..., 2] = 1
    b = np.zeros((2, 2, 3))
    b[..., 0] = 1
    b[..., 2] = 1  # 45 degrees, not unit: normalised inside
    assert normal_angle(a, b) == pytest.approx(45.0)
    assert normal_angle(a, a) == pytest.approx(0.0, abs=1e-6)


def test_flat_baseline_of_sphere_is_45_degrees(sphere):
    # mean slant of a hemisphere seen from above: 2 * int_0^1 r asin(r) dr = pi/4
    fb = flat_baseline(sphere.z, sphere.normals, sphere.mask)
    assert fb["normal_mean_deg"] == pytest.approx(45.0, abs=1.0)
    assert fb["height_rmse"] > 0.2


def test_floor_is_far_below_flat(sphere):
    h = 2 * HW / N
    z = floor_height(sphere.normals, sphere.mask, pixel_size=h)
    assert np.all(np.isfinite(z)) and abs(z[sphere.mask].mean()) < 1e-9
    fl = floor_scores(sphere.z, sphere.normals, sphere.mask, pixel_size=h)
    fb = flat_baseline(sphere.z, sphere.normals, sphere.mask)
    assert fl["height_rmse"] < 0.1 * fb["height_rmse"]
    assert fl["normal_mean_deg"] < 0.2 * fb["normal_mean_deg"]


def test_floor_is_exact_for_a_plane():
    s = on_grid("plane", 32, half_width=1.0, fx=0.3, fy=-0.2)
    fl = floor_scores(s.z, s.normals, s.mask, pixel_size=2 / 32)
    assert fl["height_rmse"] < 1e-6 and fl["normal_mean_deg"] < 1e-4


def test_ambiguity_aware_score_forgives_inversion(sphere):
    m = sphere.mask
    cup = on_grid("cup", N, half_width=HW)
    amb = ambiguity_aware_scores(cup.z, cup.normals, sphere.z, sphere.normals, m)
    plain = sfs_scores(cup.z, cup.normals, sphere.z, sphere.normals, m)
    assert amb["flipped"]
    assert amb["normal_angle"] == pytest.approx(0.0, abs=1e-6)
    assert amb["rmse"] == pytest.approx(0.0, abs=1e-12)
    assert plain["normal_mean_deg"] > 60.0
    assert plain["normal_mean_deg_flip"] == pytest.approx(0.0, abs=1e-6)


def test_value_errors(sphere):
    with pytest.raises(ValueError, match="height"):
        height_errors(np.zeros((3, 3)), np.zeros((4, 4)))
    with pytest.raises(ValueError, match="height"):
        height_errors(np.full((3, 3), np.nan), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="normals"):
        normal_angle(np.zeros((3, 3, 3)), np.ones((3, 3, 3)))
    with pytest.raises(ValueError, match="normals"):
        normal_angle(np.ones((3, 3, 2)), np.ones((3, 3, 2)))
    with pytest.raises(ValueError, match="mask"):
        height_errors(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3), bool))
    flipped = sphere.normals.copy()
    flipped[..., 2] *= -1
    with pytest.raises(ValueError, match="true_normals"):
        floor_height(flipped, sphere.mask)
    with pytest.raises(ValueError, match="pixel_size"):
        floor_height(sphere.normals, sphere.mask, pixel_size=0)


def test_score_names_are_the_metrics_table_and_height_range_gives_relative_rmse(sphere):
    from pbrbench.metrics import METRICS

    sc = sfs_scores(sphere.z, sphere.normals, sphere.z, sphere.normals, sphere.mask, height_range=2.0)
    assert set(sc) <= set(METRICS) and "height_rmse_rel" in sc
    assert sc["height_rmse_rel"] == pytest.approx(sc["height_rmse"] / 2.0)
    assert "height_rmse_rel" not in sfs_scores(sphere.z, sphere.normals, sphere.z, sphere.normals, sphere.mask)
    fb = flat_baseline(sphere.z, sphere.normals, sphere.mask, height_range=2.0)
    assert set(fb) <= set(METRICS) and fb["height_rmse_rel"] == pytest.approx(fb["height_rmse"] / 2.0)
