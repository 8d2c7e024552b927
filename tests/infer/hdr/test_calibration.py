"""Properties every calibration of CALIBRATION_METHODS must have (pbrbench.infer.hdr)."""

import numpy as np
import pytest

from pbrbench.camera import Camera, response_curve
from pbrbench.infer.hdr import (
    CALIBRATION_METHODS,
    calibrate_debevec1997,
    calibrate_grossberg_nayar2003,
    calibrate_mitsunaga1999,
    calibrate_robertson2003,
    merge_hdr,
)
from tests.infer.hdr._data import TIMES, log2_rmse, scene, true_response


def calibrate_mn5(images, times):
    """Mitsunaga-Nayar with a fixed degree: automatic selection fits 7 degrees (~5 s per call)."""
    return calibrate_mitsunaga1999(images, times, degree=5)


FAST = [calibrate_debevec1997, calibrate_robertson2003, calibrate_mn5]


def test_methods_table_names_the_papers():
    assert CALIBRATION_METHODS == {"debevec1997": calibrate_debevec1997, "robertson2003": calibrate_robertson2003,
                                   "mitsunaga1999": calibrate_mitsunaga1999,
                                   "grossberg_nayar2003": calibrate_grossberg_nayar2003}


@pytest.mark.parametrize("name", ["gamma", "film", "polynomial"])
def test_calibration_accuracy_no_noise(name):
    L = scene(96)
    br = Camera(name, bit_depth=8).capture(L, TIMES)
    # the floor: merging with the true response leaves only 8-bit quantisation (0.0065 gamma,
    # 0.015 film, 0.008 polynomial: the film curve's flat shoulder quantises coarsely).  The
    # target is 0.015 for a floor of 0.01, i.e. 1.5x the floor; a fixed 0.02 for every
    # curve was loose for gamma and below 1.35x the floor for film.
    floor = log2_rmse(merge_hdr(br.images, br.exposure_times, true_response(br)), L)
    for cal in (calibrate_debevec1997, calibrate_robertson2003):
        resp = cal(br.images, br.exposure_times)
        rad = merge_hdr(br.images, br.exposure_times, resp)
        assert log2_rmse(rad, L) < 1.5 * floor, (name, cal.__name__)


@pytest.mark.parametrize("cal", FAST)
def test_response_monotone_finite_positive(cal):
    br = Camera("random", read_noise=0.01, full_well=2000, seed=2).capture(scene(seed=3), TIMES, seed=1)
    resp = cal(br.images, br.exposure_times)
    inv = resp.inverse
    assert inv.shape == (256, 3)
    assert np.all(np.isfinite(inv)) and np.all(inv > 0)
    assert np.all(np.diff(inv, axis=0) > 0)
    np.testing.assert_allclose(inv[-1], 1.0)


@pytest.mark.parametrize("cal", FAST)
def test_scale_invariance(cal):
    br = Camera("gamma").capture(scene(), TIMES)
    r1 = cal(br.images, br.exposure_times)
    r2 = cal(br.images, 7.0 * br.exposure_times)
    np.testing.assert_allclose(r1.inverse, r2.inverse, rtol=1e-6)
    t1 = br.exposure_times if r1.exposure_times is None else r1.exposure_times
    t2 = 7.0 * br.exposure_times if r2.exposure_times is None else r2.exposure_times
    np.testing.assert_allclose(merge_hdr(br.images, t2, r2), merge_hdr(br.images, t1, r1) / 7.0, rtol=1e-5)


def test_colour_balance_does_not_drift():
    # a grey scene seen through very different per-channel responses must stay grey
    curves = [response_curve("gamma", gamma=1.6), response_curve("film"), response_curve("gamma", gamma=2.6)]
    L = scene(channels=1)[..., 0]
    L3 = np.repeat(L[..., None], 3, axis=2)
    br = Camera(curves).capture(L3, TIMES)
    mid = br.true_inverse[128]
    assert mid.max() / mid.min() > 1.5  # a mid-level gauge would shift the channels this much
    for cal in FAST:
        resp = cal(br.images, br.exposure_times)
        times = br.exposure_times if resp.exposure_times is None else resp.exposure_times
        rad = merge_hdr(br.images, times, resp)
        ratio = np.median(rad / rad[..., :1], axis=(0, 1))
        np.testing.assert_allclose(ratio, 1.0, atol=0.03, err_msg=cal.__name__)


@pytest.fixture(scope="module")
def small():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    return br.images, br.exposure_times


@pytest.mark.parametrize("cal", list(CALIBRATION_METHODS.values()))
def test_input_value_errors(cal, small):
    Z, t = small
    negative = Z.astype(np.int32)
    negative[0, 0, 0, 0] = -1  # a signed type is accepted only when every level fits 16 bits
    cases = [
        (Z.astype(np.float32), t, "images"),
        (Z.astype(bool), t, "images"),
        (Z[:1], t[:1], "at least 2"),
        (Z, t[::-1], "increasing"),
        (Z, [0.0, 1.0], "> 0"),
        (Z, [1.0, 2.0, 3.0], "one time per exposure"),
        ([Z[0], Z[1, :4]], t, "shapes"),
        (negative, t, r"\[0, 65535\]"),
        (negative + 70000, t, r"\[0, 65535\]"),
        (Z[0, 0], t, "dimensions|shape"),
    ]
    for images, times, msg in cases:
        with pytest.raises(ValueError, match=msg):
            cal(images, times)
