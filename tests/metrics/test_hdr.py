"""Tests for the HDR scores (pbrbench.metrics.hdr)."""

import numpy as np
import pytest

from pbrbench.metrics.hdr import (
    hdr_scores,
    invalid_fraction,
    log_radiance_rmse,
    log_radiance_rmse_extremes,
    response_rmse,
)


def truth(n=16, seed=0):
    rng = np.random.default_rng(seed)
    return 10 ** rng.uniform(-2, 2, (n, n, 3))


def test_global_scale_is_free_but_colour_drift_is_not():
    L = truth()
    assert log_radiance_rmse(7.3 * L, L) == pytest.approx(0.0, abs=1e-12)
    # one channel off by one stop: the best common offset is 1/3 stop, leaving sqrt(2/9) stops
    est = L * np.array([1.0, 1.0, 2.0])
    assert log_radiance_rmse(est, L) == pytest.approx(np.sqrt(2.0 / 9.0), rel=1e-9)
    per = log_radiance_rmse(est, L, per_channel=True)
    np.testing.assert_allclose(per, [1 / 3, 1 / 3, 2 / 3], rtol=1e-9)


def test_known_log_noise_and_mask():
    L = truth(64)
    rng = np.random.default_rng(1)
    d = rng.choice([-0.1, 0.1], L.shape)  # zero-mean +-0.1 stop errors
    d -= d.mean()
    est = L * 2.0**d
    assert log_radiance_rmse(est, L) == pytest.approx(np.sqrt(np.mean(d**2)), rel=1e-9)
    # pixels outside the mask, or invalid ones, are not scored
    est2 = est.copy()
    est2[0, 0] = np.nan
    est2[1, 1] = 1e9
    mask = np.ones(L.shape[:2], bool)
    mask[1, 1] = False
    e = log_radiance_rmse(est2, L, mask=mask)
    keep = np.broadcast_to(mask[..., None], L.shape).copy()
    keep[0, 0] = False  # the NaN pixel
    r = d[keep] - d[keep].mean()
    assert e == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-9)


def test_invalid_fraction():
    est = np.ones((4, 5, 3))
    est[0, 0, 0] = np.nan
    est[1, 1, 1] = 0.0
    est[2, 2, 2] = -1.0
    est[3, 3, 0] = np.inf
    assert invalid_fraction(est) == pytest.approx(4 / 60)
    m = np.zeros((4, 5), bool)
    m[0, 0] = True
    assert invalid_fraction(est, mask=m) == pytest.approx(1 / 3)


def test_extremes_pick_brightest_and_darkest():
    L = truth(32)
    lum = L.mean(axis=2)
    est = L.copy()
    hi = lum >= np.quantile(lum, 0.99)
    est[hi] *= 4.0  # brightest 1 % two stops too bright
    ext = log_radiance_rmse_extremes(est, L)
    assert ext["bright"] > 1.5
    assert ext["dark"] < 0.1
    with pytest.raises(ValueError, match="fraction"):
        log_radiance_rmse_extremes(est, L, fraction=0.0)


def test_response_rmse_alignment():
    z = np.arange(256) / 255.0
    true = np.stack([z**2.2] * 3, axis=1)
    assert response_rmse(3.0 * true, true) == pytest.approx(0.0, abs=1e-12)
    per_channel = true * np.array([1.0, 2.0, 4.0])
    assert response_rmse(per_channel, true) == pytest.approx(0.0, abs=1e-12)
    assert response_rmse(per_channel, true, align="global") > 0.5
    assert response_rmse(2.0 * true, true, align="none") == pytest.approx(1.0)
    # a gamma error: log2 difference 0.2 * log2(z), minus its mean
    est = true ** 1.2
    d = 0.2 * 2.2 * np.log2(z[1:-1])
    assert response_rmse(est, true) == pytest.approx(np.std(d), rel=1e-9)
    # one-channel estimate is broadcast
    assert response_rmse(true[:, :1], true) == pytest.approx(0.0, abs=1e-12)


def test_hdr_scores_keys():
    L = truth()
    s = hdr_scores(L * 3, L)
    assert set(s) == {"log2_rmse", "log2_rmse_c0", "log2_rmse_c1", "log2_rmse_c2", "bright1", "dark1",
                      "invalid_fraction"}
    assert all(v == pytest.approx(0.0, abs=1e-12) for v in s.values())


def test_value_errors():
    L = truth()
    with pytest.raises(ValueError, match="shape"):
        log_radiance_rmse(L[:2], L)
    with pytest.raises(ValueError, match="mask"):
        log_radiance_rmse(L, L, mask=np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="no pixel"):
        log_radiance_rmse(np.zeros_like(L), L)
    with pytest.raises(ValueError, match="per_channel"):
        log_radiance_rmse(L[..., 0], L[..., 0], per_channel=True)
    z = np.linspace(0, 1, 256)[:, None]
    with pytest.raises(ValueError, match="levels"):
        response_rmse(z[:128], z)
    with pytest.raises(ValueError, match="align"):
        response_rmse(z, z, align="best")
    with pytest.raises(ValueError, match="channels"):
        response_rmse(np.repeat(z, 2, axis=1), np.repeat(z, 3, axis=1))
