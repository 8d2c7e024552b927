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
