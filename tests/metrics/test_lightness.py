"""Lightness scores (pbrbench.metrics.lightness): exact values on constructed inputs."""

import numpy as np
import pytest

from pbrbench.metrics.lightness import (
    albedo_abs_error,
    intrinsic_lmse,
    lmse,
    lmse_map,
    ratio_errors,
    si_mse,
)


def _mit_local_error(correct, estimate, mask, window_size, window_shift):
    """Loop transcription of the MIT Intrinsic Images ``local_error`` (reference)."""
    m, n = correct.shape
    ssq = total = 0.0
    for i in range(0, m - window_size + 1, window_shift):
        for j in range(0, n - window_size + 1, window_shift):
            c = correct[i:i + window_size, j:j + window_size]
            e = estimate[i:i + window_size, j:j + window_size]
            k = mask[i:i + window_size, j:j + window_size]
            alpha = np.sum(c * e * k) / np.sum(e ** 2 * k) if np.sum(e ** 2 * k) > 1e-5 else 0.0
            ssq += np.sum(k * (c - alpha * e) ** 2)
            total += np.sum(k * c ** 2)
    return ssq / total


def test_lmse_matches_mit_loop():
    rng = np.random.default_rng(0)
    t = rng.uniform(0.1, 1, (57, 63))
    e = t * rng.uniform(0.8, 1.2, t.shape)
    mask = rng.random(t.shape) > 0.2
    ref = _mit_local_error(t, e, mask, 20, 10)
    assert lmse(e, t, mask=mask) == pytest.approx(ref, rel=1e-10)
    assert lmse(e, t, mask=mask, window=8, step=3) == pytest.approx(_mit_local_error(t, e, mask, 8, 3), rel=1e-10)
    # the block-sum path (step divides window) with 3 and 4 blocks a side, and a window of one block
    for w, st in ((9, 3), (12, 3), (5, 5)):
        assert lmse(e, t, mask=mask, window=w, step=st) == pytest.approx(_mit_local_error(t, e, mask, w, st), rel=1e-10)


def test_lightness_scores_are_the_single_metrics():
    from pbrbench.metrics.lightness import lightness_scores

    rng = np.random.default_rng(3)
    t = rng.uniform(0.1, 1, (40, 52, 3))
    e = t * rng.uniform(0.7, 1.3, t.shape)
    s_t, s_e = rng.uniform(0.2, 1, t.shape), rng.uniform(0.2, 1, t.shape)
    mask = rng.random(t.shape[:2]) > 0.1
    lab = (np.arange(40)[:, None] // 10 * 10 + np.arange(52)[None, :] // 13).astype(int)
    out = lightness_scores(e, s_e, t, s_t, mask=mask, labels=lab, window=12)
    assert out["lmse"] == pytest.approx(lmse(e, t, mask=mask, window=12), rel=1e-12)
    assert out["intrinsic_lmse"] == pytest.approx(intrinsic_lmse(e, s_e, t, s_t, mask=mask, window=12), rel=1e-12)
    assert out["si_mse"] == si_mse(e, t, mask=mask)
    assert out["albedo_abs_err"] == albedo_abs_error(e, t, mask=mask)
    r = np.abs(ratio_errors(e, t, lab, mask=mask, erode=1))
    assert out["ratio_err_max"] == r.max() and out["ratio_err_median"] == np.median(r)


def test_group_medians_are_numpy_medians():
    from pbrbench.metrics.lightness import _group_medians

    rng = np.random.default_rng(5)
    g = rng.integers(0, 7, 500)
    g[:7] = np.arange(7)                           # every group present; counts odd and even
    v = rng.normal(size=(500, 2))
    got = _group_medians(v, g, 7)
    want = np.array([np.median(v[g == k], axis=0) for k in range(7)])
    assert np.array_equal(got, want)
    assert {int((g == k).sum()) % 2 for k in range(7)} == {0, 1}


def test_lmse_local_scale_invariance():
    rng = np.random.default_rng(1)
    t = rng.uniform(0.1, 1, (60, 60))
    assert lmse(3.0 * t, t) == pytest.approx(0.0, abs=1e-12)
    # a different scale in each 10x10 block only hurts windows that straddle blocks
    blocks = np.kron(rng.uniform(0.5, 2, (6, 6)), np.ones((10, 10)))
    assert lmse(blocks * t, t, window=10, step=10) == pytest.approx(0.0, abs=1e-12)
    assert lmse(blocks * t, t) > 0.01
    assert si_mse(blocks * t, t) > 0.01
    assert lmse(np.zeros_like(t), t) == pytest.approx(1.0)


def test_lmse_colour_scales_per_channel():
    rng = np.random.default_rng(2)
    t = rng.uniform(0.1, 1, (40, 40, 3))
    assert lmse(t * np.array([1.0, 2.0, 0.5]), t) == pytest.approx(0.0, abs=1e-12)
    assert si_mse(t * np.array([1.0, 2.0, 0.5]), t) == pytest.approx(0.0, abs=1e-12)


def test_lmse_map_and_intrinsic_average():
    rng = np.random.default_rng(3)
    t = rng.uniform(0.1, 1, (40, 40))
    e = t.copy()
    e[:20, :20] += 0.5 * rng.random((20, 20))
    emap = lmse_map(e, t)
    assert emap.shape == (3, 3)
    assert emap[2, 2] == pytest.approx(0.0, abs=1e-12) and emap[0, 0] > 0
    s = rng.uniform(0.5, 2, t.shape)
    assert intrinsic_lmse(e, s, t, s) == pytest.approx(0.5 * lmse(e, t))


def test_albedo_abs_error_not_scale_invariant():
    t = np.full((10, 10), 0.4)
    assert albedo_abs_error(2 * t, t) == pytest.approx(0.4)
    assert si_mse(2 * t, t) == pytest.approx(0.0)


def test_ratio_errors_exact():
    labels = np.zeros((30, 30), np.int64)
    labels[:, 10:20] = 1
    labels[:, 20:] = 2
    t = np.choose(labels, [0.2, 0.5, 0.8]).astype(float)
    e = 7.0 * t
    np.testing.assert_allclose(ratio_errors(e, t, labels), 0.0, atol=1e-12)
    e[labels == 1] *= 1.1  # paper 1 is 10 % too light
    err = ratio_errors(e, t, labels)  # pairs (0,1), (0,2), (1,2)
    np.testing.assert_allclose(err, [1 / 1.1 - 1, 0.0, 0.1], atol=1e-12)
    # edge pixels are excluded by the erosion
    e2 = 7.0 * t
    e2[:, 9:11] = 100.0
    np.testing.assert_allclose(ratio_errors(e2, t, labels, erode=2), 0.0, atol=1e-12)
    assert ratio_errors(np.stack([e] * 3, -1), np.stack([t] * 3, -1), labels).shape == (3, 3)


def test_metric_value_errors():
    t = np.ones((20, 20))
    with pytest.raises(ValueError, match="shape"):
        lmse(np.ones((20, 21)), t)
    with pytest.raises(ValueError, match="window"):
        lmse(t, t, window=50)
    with pytest.raises(ValueError, match="zero energy"):
        lmse(t, np.zeros((20, 20)))
    with pytest.raises(ValueError, match="labels"):
        ratio_errors(t, t, np.zeros((20, 20)))
    with pytest.raises(ValueError, match="fewer than two"):
        ratio_errors(t, t, np.zeros((20, 20), np.int64))
    bad = t.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        si_mse(bad, t)


def test_non_finite_values_count_only_inside_the_mask():
    from pbrbench.checks import check_finite

    a = np.ones((4, 5))
    a[0, 0] = np.nan
    inside = np.ones((4, 5), bool)
    outside = inside.copy()
    outside[0, 0] = False
    check_finite(a, "est", where=outside)             # the NaN is outside: accepted
    check_finite(np.arange(6), "levels")              # integers are finite
    with pytest.raises(ValueError, match="est: 1 non-finite"):
        check_finite(a, "est", where=inside)
    with pytest.raises(ValueError, match="est: 1 non-finite"):
        check_finite(a, "est")
    t = np.full((30, 30), 0.5)
    e = t.copy()
    e[0, 0] = np.inf
    m = np.ones((30, 30), bool)
    m[0, 0] = False
    assert lmse(e, t, mask=m) == 0.0                  # a bad value outside the mask is not read
