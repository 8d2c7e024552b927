"""The linear-domain inverse-variance merge of Granados et al. (2010) (pbrbench.infer.hdr.merge.granados2010)."""

import numpy as np
import pytest

from pbrbench.camera import Camera
from pbrbench.infer.hdr import CameraResponse, merge_debevec1997, merge_granados2010
from pbrbench.infer.hdr.merge.granados2010 import estimate_noise_levels
from tests.infer.hdr._data import TIMES, linear_bracket, log2_rmse, scene, true_response


def test_linear_camera_exact_merge():
    # radiance j/255 with times 1, 2, 4: every unclipped level is exact, so the merge is exact
    L, br = linear_bracket()
    rad = merge_granados2010(br.images, br.exposure_times, true_response(br), noise_model=(0.01, np.inf))
    np.testing.assert_allclose(rad[..., 0], L, rtol=1e-6)


def test_known_answer_inverse_variance_weights():
    # one pixel, two exposures, read noise only: x = (0.2, 0.5) at t = (1, 2), var = rn^2 + q
    inv = np.linspace(0.0, 1.0, 256)[:, None]
    inv[0] = 1e-6
    resp = CameraResponse(np.maximum.accumulate(inv, axis=0), 256, "test")
    Z = np.array([[[[51]]], [[[127]]]], np.uint8)  # levels of x = 0.2 and ~0.498
    rn = 0.01
    q = (1 / 255) ** 2 / 12
    x = resp.inverse[[51, 127], 0]
    t = np.array([1.0, 2.0])
    w = t**2 / (rn**2 + q)
    expect = np.sum(w * x / t) / np.sum(w)
    rad = merge_granados2010(Z, t, resp, noise_model=(rn, np.inf))
    assert rad[0, 0, 0] == pytest.approx(expect, rel=1e-6)
    # shot noise: the variance grows with x, so the brighter (longer) exposure gets less weight
    fw = 100.0
    w2 = t**2 / (rn**2 + x / fw + q)
    rad2 = merge_granados2010(Z, t, resp, noise_model=(rn, fw))
    assert rad2[0, 0, 0] == pytest.approx(np.sum(w2 * x / t) / np.sum(w2), rel=1e-6)


def test_dark_noisy_pixels_unbiased_where_the_log_average_is_not():
    # darkest pixels at SNR ~2 in the longest exposure: the linear average stays close to the
    # oracle, the log-domain average (same response, same noise model) is biased and heavy-tailed
    L = scene(64, lo=-2.2, hi=0.3)
    br = Camera("gamma", read_noise=0.004, full_well=1e4).capture(L, TIMES, seed=4)
    resp = true_response(br)
    nm = (0.004, 1e4)
    lin = merge_granados2010(br.images, br.exposure_times, resp, noise_model=nm)
    log = merge_debevec1997(br.images, br.exposure_times, resp, noise_model=nm)
    dark = L.mean(axis=2) < np.quantile(L.mean(axis=2), 0.05)
    e_lin = log2_rmse(lin[dark], L[dark])
    e_log = log2_rmse(log[dark], L[dark])
    assert e_lin < 0.8 * e_log
    assert log2_rmse(lin, L) < log2_rmse(log, L)


def smooth_bracket(camera, n=256):
    """A spatially smooth HDR scene (the noise estimate groups pixels by their neighbours) and
    its bracket: 7 exposures one stop apart."""
    from pbrbench.camera import bracket_exposure_times
    from pbrbench.perf.hdr import synthetic_radiance

    L = synthetic_radiance(n).astype(float)
    return L, camera.capture(L, bracket_exposure_times(L, stops=1.0, count=7, headroom=0.9), seed=2)


def test_estimated_noise_model_matches_the_camera():
    L, br = smooth_bracket(Camera("gamma", read_noise=0.004, full_well=2e3))
    resp = true_response(br)
    inv = resp.inverse
    q = np.gradient(inv, axis=0) ** 2 / 12
    a, b = estimate_noise_levels(br.images, br.exposure_times, inv, q[:, 1], 1)
    assert np.sqrt(a) == pytest.approx(0.004, rel=0.15)
    assert 1 / b == pytest.approx(2e3, rel=0.15)
    # and the merge with the estimate is as good as with the true model
    e_est = log2_rmse(merge_granados2010(br.images, br.exposure_times, resp), L)
    e_true = log2_rmse(merge_granados2010(br.images, br.exposure_times, resp, noise_model=(0.004, 2e3)), L)
    assert e_est < 1.05 * e_true


def test_noise_estimate_ignores_wrong_exposure_times():
    # a 10 % error in the stated times is a systematic offset per level, not noise
    L, br = smooth_bracket(Camera("gamma", read_noise=0.004))
    inv = true_response(br).inverse
    q = np.gradient(inv, axis=0) ** 2 / 12
    t_wrong = br.exposure_times * (1 + 0.1 * (np.arange(len(br.exposure_times)) % 2))
    a0, b0 = estimate_noise_levels(br.images, br.exposure_times, inv, q[:, 0], 0)
    a, b = estimate_noise_levels(br.images, t_wrong, inv, q[:, 0], 0)
    for x in (0.05, 0.3, 0.6):  # the noise variance at these exposures changes by < 20 %
        assert a + b * x == pytest.approx(a0 + b0 * x, rel=0.3)
        assert np.sqrt(a + b * x) < 0.006


def test_unmeasured_pixels_get_finite_bounds_and_mask():
    L = scene(16)
    L[:4, :4] = 500.0  # clipped in every exposure (t_min = 1/64)
    br = Camera("gamma").capture(L, TIMES)
    resp = true_response(br)
    rad, mask = merge_granados2010(br.images, br.exposure_times, resp, return_mask=True)
    assert rad.dtype == np.float32 and rad.shape == L.shape and mask.dtype == bool
    assert np.all(np.isfinite(rad)) and np.all(rad > 0)
    np.testing.assert_array_equal(mask, br.saturated)
    np.testing.assert_allclose(rad[:4, :4], np.broadcast_to(resp.inverse[-1] / br.exposure_times[0], (4, 4, 3)), rtol=1e-5)
    # black in every exposure: the upper bound f^-1(1) / t_max
    Z = np.zeros((3, 2, 2), np.uint8)
    Z[:, 1, 1] = [10, 40, 120]
    r2 = CameraResponse(np.linspace(1e-3, 1, 256)[:, None], 256, "test")
    out = merge_granados2010(Z, [1.0, 4.0, 16.0], r2)
    assert np.all(np.isfinite(out)) and np.all(out > 0)
    assert out[0, 0, 0] == pytest.approx(r2.inverse[1, 0] / 16.0, rel=1e-5)


def test_sixteen_bit_bracket():
    L = scene(32, lo=-2.0, hi=0.5)
    br = Camera("gamma", bit_depth=12, read_noise=0.001).capture(L, TIMES, seed=3)
    resp = true_response(br)
    rad = merge_granados2010(br.images, br.exposure_times, resp)
    assert rad.shape == L.shape and np.all(rad > 0)
    assert log2_rmse(rad, L) < 0.08
    assert log2_rmse(rad, L) < log2_rmse(merge_debevec1997(br.images, br.exposure_times, resp), L)


def test_iterations_reweight_only_with_shot_noise():
    L = scene(32)
    br = Camera("gamma", read_noise=0.002).capture(L, TIMES, seed=1)
    resp = true_response(br)
    a = merge_granados2010(br.images, br.exposure_times, resp, noise_model=(0.002, np.inf))
    b = merge_granados2010(br.images, br.exposure_times, resp, noise_model=(0.002, np.inf), iterations=3)
    np.testing.assert_array_equal(a, b)
    br2 = Camera("gamma", read_noise=0.002, full_well=300).capture(L, TIMES, seed=1)
    c0 = merge_granados2010(br2.images, br2.exposure_times, resp, noise_model=(0.002, 300))
    c2 = merge_granados2010(br2.images, br2.exposure_times, resp, noise_model=(0.002, 300), iterations=2)
    assert not np.array_equal(c0, c2)
    assert log2_rmse(c2, L) < 1.02 * log2_rmse(c0, L)


def test_value_errors():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    Z, t = br.images, br.exposure_times
    resp = true_response(br)
    with pytest.raises(ValueError, match="response"):
        merge_granados2010(Z, t, resp.inverse)
    with pytest.raises(ValueError, match="noise_model"):
        merge_granados2010(Z, t, resp, noise_model=(-1.0, 10.0))
    with pytest.raises(ValueError, match="iterations"):
        merge_granados2010(Z, t, resp, iterations=-1)
    with pytest.raises(ValueError, match="exposure_times"):
        merge_granados2010(Z, t[::-1], resp)
    with pytest.raises(ValueError, match="images"):
        merge_granados2010(Z.astype(float), t, resp)


def test_noise_estimate_does_not_depend_on_the_sample_size():
    # weights from the noisy group variances themselves bias the fit low, more so with fewer
    # pixels per group (full well 1.7x too large from 1024 pixels a pair); reweighting with the
    # fitted model removes that
    L, br = smooth_bracket(Camera("gamma", read_noise=0.004, full_well=2e3))
    inv = true_response(br).inverse
    q = np.gradient(inv, axis=0) ** 2 / 12
    a0, b0 = estimate_noise_levels(br.images, br.exposure_times, inv, q[:, 1], 1, max_pixels=65536)
    for n in (1024, 2048, 8192):
        a, b = estimate_noise_levels(br.images, br.exposure_times, inv, q[:, 1], 1, max_pixels=n)
        assert np.sqrt(a) == pytest.approx(np.sqrt(a0), rel=0.05)
        assert b == pytest.approx(b0, rel=0.06)
    # the merge estimates all channels at once: the same model as channel by channel
    from pbrbench.infer.hdr.merge.granados2010 import _noise_levels

    joint = _noise_levels(br.images, br.exposure_times, inv, [(c, q[:, c]) for c in range(3)])
    for c in range(3):
        np.testing.assert_allclose(joint[c], estimate_noise_levels(br.images, br.exposure_times, inv, q[:, c], c),
                                   rtol=1e-9)


def test_group_order_statistics_and_bins():
    from pbrbench.infer.hdr.merge.granados2010 import _bin_index, _bin_table, _group_median_mad

    rng = np.random.default_rng(1)
    for trial in range(60):
        m = int(rng.integers(1, 30))
        g = rng.integers(0, m, int(rng.integers(1, 400)))
        d = [rng.normal(size=g.size), rng.integers(0, 5, g.size) * 0.1, np.clip(rng.standard_cauchy(g.size), -8, 1)][trial % 3]
        med, mad = _group_median_mad(g, d, m)
        for j in range(m):
            v = np.sort(d[g == j])
            if v.size == 0:
                assert med[j] == 0 and mad[j] == 0
                continue
            mj = v[v.size // 2]  # the upper median, and the (n // 2)-th smallest deviation
            assert med[j] == pytest.approx(mj, abs=1e-12)
            assert mad[j] == pytest.approx(np.sort(np.abs(v - mj))[v.size // 2], abs=1e-12)
    for n_bins in (1, 7, 48):
        edges = np.linspace(0.0, 1.0, n_bins + 1) ** 2
        v = np.concatenate([rng.random(20000), edges, np.nextafter(edges, 2)[:-1], np.nextafter(edges, -1)[1:]])
        np.testing.assert_array_equal(_bin_index(v, _bin_table(n_bins)),
                                      np.clip(np.searchsorted(edges, v, side="right") - 1, 0, n_bins - 1))


def test_a_first_noise_fit_of_zero_is_reweighted_like_any_other():
    # group statistics where the low-spread groups (quantisation above their spread) dominate the
    # first fit's weights n / s_g^2 and pull it to a = b = 0; reweighted from the model, the
    # groups of real shot noise (variance 0.01 + 0.02 x above the quantisation's 0.01) give b > 0.
    # Stopping at the first zero made the estimate jump between 0 and the reweighted b
    from pbrbench.infer.hdr.merge._granados_noise import _fit_noise_model, _weighted_fit

    x = np.linspace(0.05, 0.8, 20)
    u0, q, n = np.full(20, 5.0), np.full(20, 0.01), np.full(20, 50.0)
    var = np.where(x < 0.3, 0.005, 0.01 + 0.02 * x)
    y = var - q
    assert _weighted_fit(n / var ** 2, u0, x, y) == (0.0, 0.0)      # the first pass alone
    a, b = _fit_noise_model(n, var, q, u0, x, 8, 2)
    assert a == 0.0 and 0.01 < b < 0.02
