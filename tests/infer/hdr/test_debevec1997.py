"""Debevec & Malik (1997) calibration (pbrbench.infer.hdr.debevec1997)."""

import numpy as np
import pytest

from pbrbench.camera import Camera
from pbrbench.infer.hdr import calibrate_debevec1997, merge_hdr
from tests.infer.hdr._data import TIMES, check_linear_response, log2_rmse, scene


def test_linear_camera_recovers_linear_response():
    check_linear_response(calibrate_debevec1997)


@pytest.mark.parametrize("bits", [10, 12, 16])
def test_high_bit_depth(bits):
    L = scene(32)
    br = Camera("gamma", bit_depth=bits).capture(L, TIMES[::2])
    resp = calibrate_debevec1997(br.images, br.exposure_times)
    assert resp.levels == 1 << bits
    assert resp.method == "debevec1997"
    rad = merge_hdr(br.images, br.exposure_times, resp)
    assert log2_rmse(rad, L) < 0.01


def test_deterministic_given_seed():
    br = Camera("gamma", read_noise=0.01).capture(scene(), TIMES, seed=2)
    a = calibrate_debevec1997(br.images, br.exposure_times, seed=3)
    b = calibrate_debevec1997(br.images, br.exposure_times, seed=3)
    np.testing.assert_array_equal(a.inverse, b.inverse)


def test_fully_clipped_bracket_raises():
    # failure mode: every pixel is 0 or 255 in every exposure, no level carries data
    Z = np.zeros((2, 8, 8), np.uint8)
    Z[:, :4] = 255
    with pytest.raises(ValueError, match="channel 0"):
        calibrate_debevec1997(Z, [1.0, 2.0])


def test_option_value_errors():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    Z, t = br.images, br.exposure_times
    with pytest.raises(ValueError, match="weighting"):
        calibrate_debevec1997(Z, t, weighting="triangle")
    with pytest.raises(ValueError, match="smoothness"):
        calibrate_debevec1997(Z, t, smoothness=-1)
    with pytest.raises(ValueError, match="samples"):
        calibrate_debevec1997(Z, t, samples=0)
    with pytest.raises(ValueError, match="bit_depth"):
        calibrate_debevec1997(Z, t, bit_depth=4)
    with pytest.raises(ValueError, match="bit_depth"):
        calibrate_debevec1997(Z, t, bit_depth=17)
