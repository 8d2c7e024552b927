"""Tests of the normal / albedo / height scores (``pbrbench.metrics.normals``)."""

import numpy as np
import pytest

from pbrbench.metrics.normals import (
    albedo_relative_error,
    angular_error_map,
    angular_error_stats,
    height_rmse,
    height_rmse_scaled,
)


def test_angular_error_known_rotation_and_stats():
    rng = np.random.default_rng(0)
    n = rng.normal(size=(20, 30, 3))
    n[..., 2] = np.abs(n[..., 2]) + 0.5
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    angles = np.where(np.arange(30)[None, :] < 10, 3.0, 12.0) * np.ones((20, 1))
    t = np.cross(n, rng.normal(size=n.shape))  # a unit tangent perpendicular to each normal
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    th = np.radians(angles)[..., None]
    est = np.cos(th) * n + np.sin(th) * t
    err = angular_error_map(2.5 * est, n)  # scale of the estimate does not matter
    np.testing.assert_allclose(err, angles, atol=1e-6)
    st = angular_error_stats(est, n)
    assert st["mean"] == pytest.approx((10 * 3 + 20 * 12) / 30, abs=1e-6)
    assert st["median"] == pytest.approx(12.0, abs=1e-6)
    assert st["frac_under_5"] == pytest.approx(1 / 3)
    assert st["frac_under_10"] == pytest.approx(1 / 3)
    assert st["n_pixels"] == 600


def test_angular_error_mask_and_invalid_estimates_count_as_90_degrees():
    n = np.zeros((4, 4, 3))
    n[..., 2] = 1.0
    est = n.copy()
    est[0, 0] = 0.0  # an invalid (zero) estimate inside the mask
    m = np.ones((4, 4), bool)
    m[3, 3] = False
    err = angular_error_map(est, n, m)
    assert err[0, 0] == pytest.approx(90.0) and np.isnan(err[3, 3])
    assert angular_error_stats(est, n, m)["mean"] == pytest.approx(90.0 / 15)
    # antiparallel normals give 180 degrees (the dot product is clipped, no NaN)
    assert angular_error_map(-n, n)[1, 1] == pytest.approx(180.0)


def test_albedo_relative_error_ignores_global_scale():
    rng = np.random.default_rng(1)
    true = rng.uniform(0.1, 0.9, size=(16, 16, 3))
    assert albedo_relative_error(3.7 * true, true) == pytest.approx(0.0, abs=1e-12)
    est = true.copy()
    est[:8] *= 1.2  # half the pixels 20 % too bright
    e = albedo_relative_error(est, true)
    assert 0.02 < e < 0.2


def test_height_rmse_offset_and_scale():
    y, x = np.mgrid[:10, :12].astype(float)
    z = np.sin(x / 3) + 0.1 * y
    m = np.ones_like(z, bool)
    assert height_rmse(z + 5.0, z, m) == pytest.approx(0.0, abs=1e-12)
    assert height_rmse(2 * z, z) > 0.1  # a wrong scale is an error ...
    assert height_rmse_scaled(2 * z - 1.0, z) == pytest.approx(0.0, abs=1e-12)  # ... unless scaled out
    noise = np.random.default_rng(2).normal(size=z.shape)
    noise -= noise.mean()
    assert height_rmse(z + noise, z) == pytest.approx(np.sqrt(np.mean(noise**2)))
    m[:5] = False
    d = (z + np.where(m, 0.0, 100.0))
    assert height_rmse(d, z, m) == pytest.approx(0.0, abs=1e-12)  # outside the mask ignored


@pytest.mark.parametrize(
    "fn, args, match",
    [
        (angular_error_map, (np.zeros((4, 4, 3)), np.zeros((4, 5, 3))), "n_est"),
        (angular_error_map, (np.ones((4, 4, 3)), np.zeros((4, 4, 3))), "n_true"),
        (angular_error_map, (np.full((4, 4, 3), np.nan), np.ones((4, 4, 3))), "n_est"),
        (albedo_relative_error, (np.zeros((4, 4)), np.ones((4, 4))), "est"),
        (albedo_relative_error, (np.ones((4, 4)), np.zeros((4, 4))), "true"),
        (albedo_relative_error, (np.ones((4, 4)), np.ones((4, 3))), "est"),
        (height_rmse, (np.ones((4, 4)), np.ones((4, 4)), np.ones((3, 3), bool)), "mask"),
        (height_rmse_scaled, (np.ones(4), np.ones(4)), "est"),
    ],
)
def test_errors(fn, args, match):
    with pytest.raises(ValueError, match=match):
        fn(*args)
