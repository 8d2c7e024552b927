"""Lightness and specularity scores: exact values on constructed inputs."""

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
from pbrbench.metrics.specular import mask_iou, removal_errors, specular_mask_from_twin


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


def test_specular_mask_from_twin_modes():
    dif = np.full((4, 4), 0.5)
    dif[0, 0] = 1.0
    rad = dif.copy()
    rad[1, 1] += 0.2   # 20 % of peak, 40 % of local
    rad[2, 2] += 0.08  # 8 % of peak, 16 % of local
    peak = specular_mask_from_twin(rad, dif, threshold=0.1)
    assert peak.sum() == 1 and peak[1, 1]
    local = specular_mask_from_twin(rad, dif, threshold=0.1, reference="local")
    assert local.sum() == 2
    ab = specular_mask_from_twin(rad, dif, threshold=0.1, reference="absolute")
    assert ab.sum() == 1
    with pytest.raises(ValueError, match="reference"):
        specular_mask_from_twin(rad, dif, reference="max")
    with pytest.raises(ValueError, match="diffuse_only"):
        specular_mask_from_twin(rad, dif[:3])
    with pytest.raises(ValueError, match="threshold"):
        specular_mask_from_twin(rad, dif, threshold=-1)


def test_mask_iou_and_removal_errors():
    a = np.zeros((10, 10), bool)
    b = np.zeros((10, 10), bool)
    assert mask_iou(a, b) == 1.0
    a[2:6, 2:6] = True
    b[4:8, 2:6] = True
    assert mask_iou(a, b) == pytest.approx(8 / 24)
    with pytest.raises(ValueError, match="shape"):
        mask_iou(a, b[:5])
    truth = np.full((10, 10), 2.0)
    est = truth.copy()
    est[a] += 0.5
    err = removal_errors(est, truth, a, ring=2)
    assert err["inside_rmse"] == pytest.approx(0.5)
    assert err["inside_rel"] == pytest.approx(0.25)
    assert err["ring_rmse"] == pytest.approx(0.0)
    assert np.isnan(removal_errors(est, truth, np.zeros((10, 10), bool))["inside_rmse"])
    with pytest.raises(ValueError, match="ring"):
        removal_errors(est, truth, a, ring=0)
