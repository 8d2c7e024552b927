"""Robertson, Borman & Stevenson (2003) calibration (pbrbench.infer.hdr.robertson2003)."""

import numpy as np
import pytest

from pbrbench.camera import Camera
from pbrbench.infer.hdr import calibrate_robertson2003
from tests.infer.hdr._data import check_linear_response, scene


def test_linear_camera_recovers_linear_response():
    check_linear_response(calibrate_robertson2003)


def test_flat_bracket_raises():
    # failure mode: a bracket clipped everywhere has no usable level
    t = [0.25, 1.0]
    flat = np.stack([np.full((8, 8), 255, np.uint8)] * 2)
    with pytest.raises(ValueError, match="channel 0"):
        calibrate_robertson2003(flat, t)


def test_option_value_errors():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    Z, t = br.images, br.exposure_times
    with pytest.raises(ValueError, match="max_iter"):
        calibrate_robertson2003(Z, t, max_iter=0)
    with pytest.raises(ValueError, match="tol"):
        calibrate_robertson2003(Z, t, tol=0)
    assert calibrate_robertson2003(Z, t).method == "robertson2003"
