"""Shared HDR pieces (pbrbench.infer.hdr._common): pixel sampling and level weights."""

import numpy as np
import pytest

from pbrbench.infer.hdr import _common


def test_sampling_covers_a_level_present_at_one_pixel():
    # a level present at one single pixel is sampled even with few random samples
    Z = np.zeros((2, 64, 64, 1), np.uint8)
    Z[0] = 10
    Z[1] = 20
    Z[0, 5, 7, 0] = 200
    idx = _common.sample_pixels(Z, 256, 16, seed=0)[0]
    assert 5 * 64 + 7 in idx
    np.testing.assert_array_equal(idx, _common.sample_pixels(Z, 256, 16, seed=0)[0])


@pytest.mark.parametrize("name", _common.CALIBRATION_WEIGHTINGS)
def test_level_weights_zero_at_clipped_ends_peak_one(name):
    w = _common.level_weights(name, 256)
    assert w[0] == 0 and w[-1] == 0
    assert w.max() == pytest.approx(1.0, abs=0.005)
    np.testing.assert_allclose(w[1:-1], w[1:-1][::-1])  # symmetric about the middle level
