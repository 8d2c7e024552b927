"""The weighted log-domain merge of Debevec & Malik (1997) (pbrbench.infer.hdr.merge.debevec1997)."""

import numpy as np
import pytest

from pbrbench.camera import Camera
from pbrbench.infer.hdr import (
    MERGE_WEIGHTINGS,
    CameraResponse,
    calibrate_debevec1997,
    merge_debevec1997,
)
from tests.infer.hdr._data import TIMES, linear_bracket, log2_rmse, scene, true_response


def test_linear_camera_exact_merge():
    # radiance j/255 with times 1, 2, 4: every unclipped level is exact, so the merge is exact
    L, br = linear_bracket()
    rad = merge_debevec1997(br.images, br.exposure_times, true_response(br), weighting="hat")
    np.testing.assert_allclose(rad[..., 0], L, rtol=1e-6)


def test_clipped_ends_get_zero_weight():
    # one pixel: valid in the short exposure, clipped (255) in the long one, black (0) pixel elsewhere
    Z = np.array([[[[100]]], [[[255]]]], np.uint8)
    resp = CameraResponse(np.linspace(1e-3, 1, 256)[:, None], 256, "test")
    for w in MERGE_WEIGHTINGS:
        rad = merge_debevec1997(Z, [1.0, 4.0], resp, weighting=w, noise_model=(0.0, np.inf))
        assert rad[0, 0, 0] == pytest.approx(resp.inverse[100, 0], rel=1e-6)


def test_saturated_everywhere_gets_lower_bound_and_mask():
    L = scene(16)
    L[:4, :4] = 500.0  # far above clipping in every exposure (t_min = 1/64)
    br = Camera("gamma").capture(L, TIMES)
    resp = calibrate_debevec1997(br.images, br.exposure_times)
    rad, mask = merge_debevec1997(br.images, br.exposure_times, resp, return_mask=True)
    assert rad.dtype == np.float32 and mask.dtype == bool
    assert np.all(np.isfinite(rad)) and np.all(rad > 0)
    np.testing.assert_array_equal(mask, br.saturated)
    assert mask[:4, :4].all() and mask.sum() == 16 * 3
    bound = resp.inverse[-1] / br.exposure_times[0]
    np.testing.assert_allclose(rad[:4, :4], np.broadcast_to(bound, (4, 4, 3)), rtol=1e-5)
    # scaled to the truth, the bound is below the true radiance but at least the brightest valid pixel
    assert np.all(rad[:4, :4] * br.gain <= L[:4, :4] * 1.0001)
    assert rad[:4, :4].min() >= rad[~mask].max()


def test_black_in_every_exposure_is_finite_upper_bound():
    Z = np.zeros((3, 2, 2), np.uint8)
    Z[:, 1, 1] = [10, 40, 120]
    resp = CameraResponse(np.linspace(1e-3, 1, 256)[:, None], 256, "test")
    rad, mask = merge_debevec1997(Z, [1.0, 4.0, 16.0], resp, return_mask=True)
    assert np.all(np.isfinite(rad)) and np.all(rad > 0)
    assert not mask.any()
    assert rad[0, 0, 0] == pytest.approx(resp.inverse[1, 0] / 16.0, rel=1e-5)


def test_inverse_variance_weights_beat_hat_under_read_noise():
    # darkest pixel: sensor exposure ~0.02 in the longest frame, SNR ~5 at sigma = 0.004.  (With
    # a darker scene, lo=-2.5, the darkest pixels have SNR < 1 in every frame: no weighting can
    # recover them, they dominate the log error and the comparison says nothing.)
    L = scene(64, lo=-1.5)
    br = Camera("gamma", read_noise=0.004).capture(L, TIMES, seed=4)
    resp = true_response(br)
    e_var = log2_rmse(merge_debevec1997(br.images, br.exposure_times, resp), L)
    e_hat = log2_rmse(merge_debevec1997(br.images, br.exposure_times, resp, weighting="hat"), L)
    e_known = log2_rmse(merge_debevec1997(br.images, br.exposure_times, resp, noise_model=(0.004, np.inf)), L)
    assert e_var < 0.8 * e_hat
    assert e_known < 0.8 * e_hat


def test_merge_value_errors():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    Z, t = br.images, br.exposure_times
    resp = calibrate_debevec1997(Z, t)
    with pytest.raises(ValueError, match="weighting"):
        merge_debevec1997(Z, t, resp, weighting="triangle")
    with pytest.raises(ValueError, match="response"):
        merge_debevec1997(Z, t, resp.inverse)
    with pytest.raises(ValueError, match="levels"):
        merge_debevec1997(Z.astype(np.uint16) * 4, t, resp)
    with pytest.raises(ValueError, match="channels"):
        two = np.tile(np.linspace(1e-3, 1.0, 256)[:, None], (1, 2))  # a valid 2-channel response
        merge_debevec1997(np.repeat(Z, 3, axis=3), t, CameraResponse(two, 256, "x"))
    with pytest.raises(ValueError, match="noise_model"):
        merge_debevec1997(Z, t, resp, noise_model=(-1.0, 100.0))
    with pytest.raises(ValueError, match="increasing"):
        merge_debevec1997(Z, t[::-1], resp)
    with pytest.raises(ValueError, match="images"):
        merge_debevec1997(Z.astype(float), t, resp)
