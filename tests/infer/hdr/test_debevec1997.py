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
    with pytest.raises(ValueError, match="curvature"):
        calibrate_debevec1997(Z, t, curvature="cubic")


def test_widely_spaced_exposures_take_the_level_curvature():
    """Three exposures 3 stops apart of a film-like camera (toe and shoulder, read and shot noise):
    the log curvature prefers a ripple of period ln r to the film's shoulder; the level curvature
    (the paper's g''(z)) does not.  ``"auto"`` takes it for 2.5 stops or more, and keeps the log
    curvature for a 1-stop bracket."""
    from pbrbench.camera import bracket_exposure_times
    from pbrbench.metrics.hdr import hdr_scores
    from pbrbench.perf.hdr import synthetic_radiance

    L = synthetic_radiance(96)
    t = bracket_exposure_times(L, stops=3.0, count=3, headroom=0.9)
    br = Camera("film", bit_depth=8, read_noise=0.002, full_well=1e4).capture(L, t, seed=11)

    def err(**kw):
        r = calibrate_debevec1997(br.images, br.exposure_times, **kw)
        return hdr_scores(merge_hdr(br.images, br.exposure_times, r), L, mask=~br.saturated)["log2_rmse"]

    auto, log, level = err(), err(curvature="log"), err(curvature="level")
    assert auto == level and level < log / 3          # 0.062 against 0.286 stops
    t7 = bracket_exposure_times(L, stops=1.0, count=7, headroom=0.9)
    br7 = Camera("film", bit_depth=8).capture(L, t7, seed=11)
    a = calibrate_debevec1997(br7.images, br7.exposure_times).inverse
    assert np.array_equal(a, calibrate_debevec1997(br7.images, br7.exposure_times, curvature="log").inverse)
