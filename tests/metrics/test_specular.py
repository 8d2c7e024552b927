"""Specularity scores (pbrbench.metrics.specular): exact values on constructed inputs."""

import numpy as np
import pytest

from pbrbench.metrics.specular import mask_iou, removal_errors, specular_mask_from_twin


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


def test_windowed_true_mask_keeps_a_smooth_lobe_and_drops_single_noisy_pixels():
    """A smooth specular lobe (a Gaussian of peak 1 on a diffuse of 1) plus isolated noisy pixels
    above the level: pixelwise they enter the mask; with a 3 x 3 mean they do not, and the lobe's
    mask is the disc where its 3 x 3 mean exceeds the level (the lobe is nearly linear across a
    window, so that disc is within a pixel of the pixelwise one)."""
    H = W = 64
    y, x = np.mgrid[0:H, 0:W]
    lobe = np.exp(-((x - 32.0) ** 2 + (y - 32.0) ** 2) / (2 * 6.0 ** 2))
    diffuse = np.ones((H, W))
    spikes = np.zeros((H, W))
    spikes[5, 5] = spikes[50, 10] = spikes[10, 55] = 0.5       # 5x the level, one pixel each
    rad = diffuse + lobe + spikes
    raw = specular_mask_from_twin(rad, diffuse, threshold=0.1)
    win = specular_mask_from_twin(rad, diffuse, threshold=0.1, window=3)
    assert raw[5, 5] and raw[50, 10] and raw[10, 55]
    assert not (win[5, 5] or win[50, 10] or win[10, 55])
    lobe_only = specular_mask_from_twin(diffuse + lobe, diffuse, threshold=0.1)
    r = 6.0 * np.sqrt(2 * np.log(10.0))                       # lobe = 0.1 at this radius
    assert abs(int(win.sum()) - int(lobe_only.sum())) <= 2 * np.pi * r   # within a pixel of the disc's edge
    assert win[32, 32] and not win[32, 32 + int(r) + 2]
    # the window averages the object's pixels only: a lobe at the object's edge is not diluted by the background
    obj = x < 34
    edge = specular_mask_from_twin(rad, diffuse, threshold=0.1, mask=obj, window=3)
    assert edge[32, 33] and not edge[32, 34]


@pytest.mark.parametrize("window", [0, 2, -3, 1.5, True])
def test_true_mask_window_must_be_odd_positive(window):
    with pytest.raises(ValueError, match="window: must be an odd integer"):
        specular_mask_from_twin(np.ones((4, 4)), np.ones((4, 4)), window=window)
