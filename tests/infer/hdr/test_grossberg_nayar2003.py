"""Grossberg & Nayar (2003) calibration from histograms (pbrbench.infer.hdr.grossberg_nayar2003)."""

import numpy as np
import pytest

from pbrbench.camera import Camera, bracket_exposure_times
from pbrbench.infer.hdr import calibrate_debevec1997, merge_hdr
from pbrbench.infer.hdr.grossberg_nayar2003 import (
    brightness_transfer,
    calibrate_grossberg_nayar2003,
)
from pbrbench.metrics.hdr import response_rmse
from pbrbench.perf.hdr import synthetic_radiance
from tests.infer.hdr._data import TIMES, check_linear_response, log2_rmse, scene, true_response

BIG = synthetic_radiance(160, seed=0).astype(float)
INNER = (slice(16, 144), slice(16, 144))
# the levels the 7-exposure bracket of the inner crop reaches (none below 12 in any exposure)
SEEN = np.zeros(256, bool)
SEEN[16:250] = True


def brackets(name, max_shift=4, seed=1):
    """A registered bracket of the inner 128 x 128 crop and an unregistered one: each exposure
    cropped at its own offset of up to ``max_shift`` pixels (the camera moved between shots)."""
    L = BIG[INNER]
    times = bracket_exposure_times(L, stops=1.0, count=7, headroom=0.9)
    cam = Camera(name, bit_depth=8)
    br = cam.capture(L, times)
    rng = np.random.default_rng(seed)
    shots = []
    for tk in times:
        dy, dx = rng.integers(-max_shift, max_shift + 1, 2)
        shots.append(cam.capture(BIG[16 + dy:144 + dy, 16 + dx:144 + dx], [tk]).images[0])
    return br, np.stack(shots)


def test_linear_camera_recovers_linear_response():
    check_linear_response(calibrate_grossberg_nayar2003)


def test_transfer_function_of_a_linear_camera_is_the_exposure_ratio():
    # linear 12-bit camera, exposures 1 and 2: f^-1(T(z)) = 2 f^-1(z), i.e. T(z) = 2 z, from the
    # histograms alone (the second image is shuffled: no pixel correspondence at all)
    rng = np.random.default_rng(0)
    L = rng.uniform(0.01, 0.45, (64, 64))
    br = Camera("linear", bit_depth=12).capture(L, [1.0, 2.0])
    shuffled = rng.permutation(br.images[1].ravel())
    z, T, frac = brightness_transfer(br.images[0], shuffled, 4096)
    ok = (z > 100) & (z < 1800)
    assert ok.sum() > 500
    np.testing.assert_allclose(T[ok], 2.0 * z[ok], rtol=0.02)
    assert np.all(frac > 0) and frac.sum() <= 1.0


@pytest.mark.parametrize("name", ["gamma", "film"])
def test_registered_bracket_recovers_the_true_response(name):
    # measured (levels 16..249, stops): gamma 0.0007, film 0.0017; debevec1997 0.0012, 0.0011
    br, _ = brackets(name)
    resp = calibrate_grossberg_nayar2003(br.images, br.exposure_times)
    assert resp.method == "grossberg_nayar2003"
    assert response_rmse(resp.inverse, br.true_inverse, levels=SEEN) < 0.005
    assert np.all(np.diff(resp.inverse, axis=0) > 0)
    np.testing.assert_allclose(resp.inverse[-1], 1.0)


@pytest.mark.parametrize("name", ["gamma", "film"])
def test_unregistered_bracket_histograms_suffice_where_registration_fails(name):
    # exposures shifted by up to 4 px against each other.  Measured (stops): this method 0.011
    # (gamma), 0.020 (film) -- only the crops' different borders change the histograms;
    # debevec1997, which pairs pixels by position, 0.069 and 0.066
    br, shifted = brackets(name)
    ours = response_rmse(calibrate_grossberg_nayar2003(shifted, br.exposure_times).inverse, br.true_inverse,
                         levels=SEEN)
    dm = response_rmse(calibrate_debevec1997(shifted, br.exposure_times).inverse, br.true_inverse, levels=SEEN)
    dm_reg = response_rmse(calibrate_debevec1997(br.images, br.exposure_times).inverse, br.true_inverse,
                           levels=SEEN)
    assert ours < 0.03
    assert dm > 10 * dm_reg  # registration-dependent: degrades measurably
    assert ours < 0.5 * dm


def test_merge_with_the_recovered_response_is_near_the_floor():
    # a log-uniform scene (_data.scene), film camera: merged radiance within 1.5x the floor
    # of merging with the true response (8-bit quantisation)
    L = scene(96)
    br = Camera("film", bit_depth=8).capture(L, TIMES)
    floor = log2_rmse(merge_hdr(br.images, br.exposure_times, true_response(br)), L)
    resp = calibrate_grossberg_nayar2003(br.images, br.exposure_times)
    assert log2_rmse(merge_hdr(br.images, br.exposure_times, resp), L) < 1.5 * floor


def test_one_exposure_raises():
    br = Camera("gamma").capture(scene(16), [1.0])
    with pytest.raises(ValueError, match="at least 2"):
        calibrate_grossberg_nayar2003(br.images, br.exposure_times)


def test_equal_times_raise():
    br = Camera("gamma").capture(scene(16), [0.25, 1.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        calibrate_grossberg_nayar2003(br.images, [0.5, 0.5])


def test_constant_images_raise():
    Z = np.full((3, 16, 16), 128, np.uint8)
    with pytest.raises(ValueError, match="no information"):
        calibrate_grossberg_nayar2003(Z, [0.25, 0.5, 1.0])


def test_disjoint_ranges_raise():
    # each exposure uses one unclipped level only: no transfer between two unclipped levels
    Z = np.zeros((2, 8, 8), np.uint8)
    Z[0, :4] = 10
    Z[1, :4] = 255
    Z[1, 4:] = 20
    with pytest.raises(ValueError, match="brightness transfer"):
        calibrate_grossberg_nayar2003(Z, [1.0, 4.0])


def test_option_errors():
    br = Camera("gamma").capture(scene(16), [0.25, 1.0])
    with pytest.raises(ValueError, match="smoothness"):
        calibrate_grossberg_nayar2003(br.images, br.exposure_times, smoothness=-1.0)
