"""The HDR dispatchers calibrate_response and merge_hdr (pbrbench.infer.hdr)."""

import numpy as np
import pytest

from pbrbench.camera import Camera
from pbrbench.infer.hdr import (
    CALIBRATION_METHODS,
    MERGE_METHODS,
    calibrate_debevec1997,
    calibrate_response,
    merge_debevec1997,
    merge_granados2010,
    merge_hdr,
)
from tests.infer.hdr._data import scene


@pytest.fixture(scope="module")
def bracket():
    br = Camera("gamma", read_noise=0.004).capture(scene(24), 2.0 ** np.arange(-4, 1), seed=1)
    return br.images, br.exposure_times


def test_defaults_are_debevec1997_and_granados2010(bracket):
    Z, t = bracket
    a = calibrate_response(Z, t)
    np.testing.assert_array_equal(a.inverse, calibrate_debevec1997(Z, t).inverse)
    assert a.method == "debevec1997"
    np.testing.assert_array_equal(merge_hdr(Z, t, a), merge_granados2010(Z, t, a))
    np.testing.assert_array_equal(merge_hdr(Z, t, a, method="debevec1997"), merge_debevec1997(Z, t, a))
    assert set(MERGE_METHODS) == {"debevec1997", "granados2010"}


@pytest.mark.parametrize("name", list(CALIBRATION_METHODS))
def test_every_calibration_by_name(bracket, name):
    Z, t = bracket
    opts = {"degree": 3} if name == "mitsunaga1999" else {}
    r = calibrate_response(Z, t, method=name, **opts)
    np.testing.assert_array_equal(r.inverse, CALIBRATION_METHODS[name](Z, t, **opts).inverse)
    assert r.method == name


def test_unknown_method(bracket):
    Z, t = bracket
    with pytest.raises(ValueError, match="method='debevec'.*'debevec1997', 'robertson2003', 'mitsunaga1999'"):
        calibrate_response(Z, t, method="debevec")
    with pytest.raises(ValueError, match="method='granados'.*'debevec1997', 'granados2010'"):
        merge_hdr(Z, t, calibrate_response(Z, t), method="granados")


def test_option_of_another_method_is_rejected_with_the_options_listed(bracket):
    Z, t = bracket
    # degree belongs to mitsunaga1999, not debevec1997
    with pytest.raises(ValueError, match=r"calibrate_response\(method='debevec1997'\): unknown option\(s\) degree; "
                                         r"debevec1997 accepts smoothness, samples, weighting, seed, bit_depth"):
        calibrate_response(Z, t, degree=3)
    with pytest.raises(ValueError, match=r"unknown option\(s\) smoothness; robertson2003 accepts max_iter, tol"):
        calibrate_response(Z, t, method="robertson2003", smoothness=1e-3)
    with pytest.raises(ValueError, match=r"merge_hdr\(method='debevec1997'\): unknown option\(s\) weights; "
                                         r"debevec1997 accepts weighting, noise_model, return_mask"):
        merge_hdr(Z, t, calibrate_response(Z, t), method="debevec1997", weights="hat")
    with pytest.raises(ValueError, match=r"merge_hdr\(method='granados2010'\): unknown option\(s\) weighting; "
                                         r"granados2010 accepts noise_model, iterations, return_mask"):
        merge_hdr(Z, t, calibrate_response(Z, t), weighting="hat")


def test_forwarded_options_change_the_result(bracket):
    Z, t = bracket
    a = calibrate_response(Z, t)
    b = calibrate_response(Z, t, smoothness=1e-3)
    assert not np.array_equal(a.inverse, b.inverse)
    np.testing.assert_array_equal(b.inverse, calibrate_debevec1997(Z, t, smoothness=1e-3).inverse)
    m0 = merge_hdr(Z, t, a)
    m1 = merge_hdr(Z, t, a, method="debevec1997", weighting="hat")
    assert not np.array_equal(m0, m1)
    np.testing.assert_array_equal(m1, merge_debevec1997(Z, t, a, weighting="hat"))
    rad, sat = merge_hdr(Z, t, a, return_mask=True)
    np.testing.assert_array_equal(rad, m0)
    assert sat.shape == rad.shape and sat.dtype == bool
