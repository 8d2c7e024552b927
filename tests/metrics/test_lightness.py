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
