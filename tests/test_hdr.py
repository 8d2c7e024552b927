"""Tests for radiometric calibration and HDR merging (pbrbench.infer.hdr)."""

import numpy as np
import pytest

from pbrbench.camera import Camera, response_curve
from pbrbench.infer import hdr
from pbrbench.infer.hdr import (
    CameraResponse,
    calibrate_debevec,
    calibrate_mitsunaga_nayar,
    calibrate_robertson,
    merge_hdr,
)

TIMES = 2.0 ** np.arange(-6, 1)  # 7 exposures one stop apart


def calibrate_mn5(images, times):
    """Mitsunaga-Nayar with a fixed degree: automatic selection fits 7 degrees (~5 s per call)."""
    return calibrate_mitsunaga_nayar(images, times, degree=5)


def scene(n=48, channels=3, lo=-1.5, hi=0.5, seed=0):
    """log-uniform radiance in [10**lo, 10**hi] (shuffled), per-channel tint."""
    rng = np.random.default_rng(seed)
    v = 10 ** rng.permutation(np.linspace(lo, hi, n * n)).reshape(n, n)
    tint = np.linspace(1.0, 0.6, channels)
    return v[..., None] * tint


def log2_rmse(est, truth):
    d = np.log2(est) - np.log2(truth)
    return float(np.sqrt(np.mean((d - d.mean()) ** 2)))


def true_response(br):
    return CameraResponse(np.maximum(br.true_inverse, 1e-12), br.levels, "true")


# ------------------------------------------------------------------------------- exact cases
def test_linear_camera_exact_merge():
    # radiance j/255 with times 1, 2, 4: every unclipped level is exact, so the merge is exact
    j = np.arange(1, 256, dtype=float)
    L = np.tile(j / 255.0, (4, 1))
    br = Camera("linear", bit_depth=8).capture(L, [1.0, 2.0, 4.0])
    rad = merge_hdr(br.images, br.exposure_times, true_response(br), weighting="hat")
    np.testing.assert_allclose(rad[..., 0], L, rtol=1e-6)


def test_linear_camera_debevec_recovers_linear_response():
    j = np.arange(1, 256, dtype=float)
    L = np.tile(j / 255.0, (4, 1))
    br = Camera("linear", bit_depth=8).capture(L, [1.0, 2.0, 4.0])
    for cal in (calibrate_debevec, calibrate_robertson, calibrate_mitsunaga_nayar):
        resp = cal(br.images, br.exposure_times)
        z = np.arange(8, 255)
        err = np.log2(resp.inverse[z, 0]) - np.log2(z / 255.0)
        assert np.max(np.abs(err)) < 0.02, cal.__name__
        rad = merge_hdr(br.images, br.exposure_times, resp)
        assert log2_rmse(rad[..., 0], L) < 0.02, cal.__name__


@pytest.mark.parametrize("name", ["gamma", "film", "polynomial"])
def test_calibration_accuracy_no_noise(name):
    L = scene(96)
    br = Camera(name, bit_depth=8).capture(L, TIMES)
    # the floor: merging with the true response leaves only 8-bit quantisation (0.0065 gamma,
    # 0.015 film, 0.008 polynomial: the film curve's flat shoulder quantises coarsely).  The
    # issue's target is 0.015 for a floor of 0.01, i.e. 1.5x the floor; a fixed 0.02 for every
    # curve was loose for gamma and below 1.35x the floor for film.
    floor = log2_rmse(merge_hdr(br.images, br.exposure_times, true_response(br)), L)
    for cal in (calibrate_debevec, calibrate_robertson):
        resp = cal(br.images, br.exposure_times)
        rad = merge_hdr(br.images, br.exposure_times, resp)
        assert log2_rmse(rad, L) < 1.5 * floor, (name, cal.__name__)


def test_mitsunaga_nayar_exact_polynomial_and_ratio_reestimation():
    L = scene(seed=1)
    cam = Camera("polynomial", bit_depth=12, exposure_error=0.08)
    br = cam.capture(L, TIMES, seed=5)
    resp = calibrate_mitsunaga_nayar(br.images, br.exposure_times, degree=3)
    z = np.arange(40, 4095)
    # with wrong stated times the response is only defined up to f^-1 -> (f^-1)^gamma (ratios
    # R -> R^gamma); the method fixes gamma by keeping the stated span t_max/t_min, so the best
    # it can return is the true inverse to the power gamma = stated span / true span (0.995
    # here: without it the error at level 40 is 0.048 stops, all of it this gauge)
    gamma = np.ptp(np.log(br.exposure_times)) / np.ptp(np.log(br.true_exposure_times))
    err = np.log2(resp.inverse[z]) - gamma * np.log2(br.true_inverse[z])
    assert np.max(np.abs(err)) < 0.03
    true_r = np.diff(np.log2(br.true_exposure_times))
    est_r = np.diff(np.log2(resp.exposure_times))
    stated_r = np.diff(np.log2(br.exposure_times))
    assert np.abs(est_r - true_r).max() < 0.5 * np.abs(stated_r - true_r).max()
    assert resp.coefficients.shape == (4, 3)


@pytest.mark.parametrize("bits", [10, 12, 16])
def test_high_bit_depth(bits):
    L = scene(32)
    br = Camera("gamma", bit_depth=bits).capture(L, TIMES[::2])
    resp = calibrate_debevec(br.images, br.exposure_times)
    assert resp.levels == 1 << bits
    rad = merge_hdr(br.images, br.exposure_times, resp)
    assert log2_rmse(rad, L) < 0.01


# ----------------------------------------------------------------------- properties
@pytest.mark.parametrize("cal", [calibrate_debevec, calibrate_robertson, calibrate_mn5])
def test_response_monotone_finite_positive(cal):
    br = Camera("random", read_noise=0.01, full_well=2000, seed=2).capture(scene(seed=3), TIMES, seed=1)
    resp = cal(br.images, br.exposure_times)
    inv = resp.inverse
    assert inv.shape == (256, 3)
    assert np.all(np.isfinite(inv)) and np.all(inv > 0)
    assert np.all(np.diff(inv, axis=0) > 0)
    np.testing.assert_allclose(inv[-1], 1.0)


@pytest.mark.parametrize("cal", [calibrate_debevec, calibrate_robertson, calibrate_mn5])
def test_scale_invariance(cal):
    br = Camera("gamma").capture(scene(), TIMES)
    r1 = cal(br.images, br.exposure_times)
    r2 = cal(br.images, 7.0 * br.exposure_times)
    np.testing.assert_allclose(r1.inverse, r2.inverse, rtol=1e-6)
    t1 = br.exposure_times if r1.exposure_times is None else r1.exposure_times
    t2 = 7.0 * br.exposure_times if r2.exposure_times is None else r2.exposure_times
    np.testing.assert_allclose(merge_hdr(br.images, t2, r2), merge_hdr(br.images, t1, r1) / 7.0, rtol=1e-5)


def test_debevec_deterministic_given_seed_and_covers_levels():
    br = Camera("gamma", read_noise=0.01).capture(scene(), TIMES, seed=2)
    a = calibrate_debevec(br.images, br.exposure_times, seed=3)
    b = calibrate_debevec(br.images, br.exposure_times, seed=3)
    np.testing.assert_array_equal(a.inverse, b.inverse)
    # a level present at one single pixel is sampled even with few random samples
    Z = np.zeros((2, 64, 64, 1), np.uint8)
    Z[0] = 10
    Z[1] = 20
    Z[0, 5, 7, 0] = 200
    idx = hdr._sample_pixels(Z, 256, 16, seed=0)[0]
    assert 5 * 64 + 7 in idx


# ---------------------------------------------------------------------- failure modes
def test_clipped_ends_get_zero_weight():
    # one pixel: valid in the short exposure, clipped (255) in the long one, black (0) pixel elsewhere
    Z = np.array([[[[100]]], [[[255]]]], np.uint8)
    resp = CameraResponse(np.linspace(1e-3, 1, 256)[:, None], 256, "test")
    for w in hdr.MERGE_WEIGHTINGS:
        rad = merge_hdr(Z, [1.0, 4.0], resp, weighting=w, noise_model=(0.0, np.inf))
        assert rad[0, 0, 0] == pytest.approx(resp.inverse[100, 0], rel=1e-6)


def test_saturated_everywhere_gets_lower_bound_and_mask():
    L = scene(16)
    L[:4, :4] = 500.0  # far above clipping in every exposure (t_min = 1/64)
    br = Camera("gamma").capture(L, TIMES)
    resp = calibrate_debevec(br.images, br.exposure_times)
    rad, mask = merge_hdr(br.images, br.exposure_times, resp, return_mask=True)
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
    rad, mask = merge_hdr(Z, [1.0, 4.0, 16.0], resp, return_mask=True)
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
    e_var = log2_rmse(merge_hdr(br.images, br.exposure_times, resp), L)
    e_hat = log2_rmse(merge_hdr(br.images, br.exposure_times, resp, weighting="hat"), L)
    e_known = log2_rmse(merge_hdr(br.images, br.exposure_times, resp, noise_model=(0.004, np.inf)), L)
    assert e_var < 0.8 * e_hat
    assert e_known < 0.8 * e_hat


def test_colour_balance_does_not_drift():
    # a grey scene seen through very different per-channel responses must stay grey
    curves = [response_curve("gamma", gamma=1.6), response_curve("film"), response_curve("gamma", gamma=2.6)]
    L = scene(channels=1)[..., 0]
    L3 = np.repeat(L[..., None], 3, axis=2)
    br = Camera(curves).capture(L3, TIMES)
    mid = br.true_inverse[128]
    assert mid.max() / mid.min() > 1.5  # a mid-level gauge would shift the channels this much
    for cal in (calibrate_debevec, calibrate_robertson, calibrate_mn5):
        resp = cal(br.images, br.exposure_times)
        times = br.exposure_times if resp.exposure_times is None else resp.exposure_times
        rad = merge_hdr(br.images, times, resp)
        ratio = np.median(rad / rad[..., :1], axis=(0, 1))
        np.testing.assert_allclose(ratio, 1.0, atol=0.03, err_msg=cal.__name__)


# ---------------------------------------------------------------------------- ValueErrors
@pytest.fixture(scope="module")
def small():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    return br.images, br.exposure_times


@pytest.mark.parametrize("cal", [calibrate_debevec, calibrate_robertson, calibrate_mitsunaga_nayar])
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


def test_option_value_errors(small):
    Z, t = small
    with pytest.raises(ValueError, match="weighting"):
        calibrate_debevec(Z, t, weighting="triangle")
    with pytest.raises(ValueError, match="smoothness"):
        calibrate_debevec(Z, t, smoothness=-1)
    with pytest.raises(ValueError, match="samples"):
        calibrate_debevec(Z, t, samples=0)
    with pytest.raises(ValueError, match="bit_depth"):
        calibrate_debevec(Z, t, bit_depth=4)
    with pytest.raises(ValueError, match="bit_depth"):
        calibrate_debevec(Z, t, bit_depth=17)
    with pytest.raises(ValueError, match="max_iter"):
        calibrate_robertson(Z, t, max_iter=0)
    with pytest.raises(ValueError, match="tol"):
        calibrate_robertson(Z, t, tol=0)
    with pytest.raises(ValueError, match="degree"):
        calibrate_mitsunaga_nayar(Z, t, degree=0)
    flat = np.stack([np.full((8, 8), 255, np.uint8)] * 2)
    with pytest.raises(ValueError, match="channel 0"):
        calibrate_robertson(flat, t)


def test_merge_value_errors(small):
    Z, t = small
    resp = calibrate_debevec(Z, t)
    with pytest.raises(ValueError, match="weighting"):
        merge_hdr(Z, t, resp, weighting="triangle")
    with pytest.raises(ValueError, match="response"):
        merge_hdr(Z, t, resp.inverse)
    with pytest.raises(ValueError, match="levels"):
        merge_hdr(Z.astype(np.uint16) * 4, t, resp)
    with pytest.raises(ValueError, match="channels"):
        merge_hdr(np.repeat(Z, 3, axis=3), t, CameraResponse(np.ones((256, 2)), 256, "x"))
    with pytest.raises(ValueError, match="noise_model"):
        merge_hdr(Z, t, resp, noise_model=(-1.0, 100.0))
    with pytest.raises(ValueError, match="increasing"):
        merge_hdr(Z, t[::-1], resp)
    with pytest.raises(ValueError, match="images"):
        merge_hdr(Z.astype(float), t, resp)
