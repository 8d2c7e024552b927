"""Mitsunaga & Nayar (1999) self-calibration (pbrbench.infer.hdr.mitsunaga1999)."""

import numpy as np
import pytest

from pbrbench.camera import Camera
from pbrbench.infer.hdr import calibrate_mitsunaga1999
from tests.infer.hdr._data import TIMES, check_linear_response, scene


def test_linear_camera_recovers_linear_response():
    check_linear_response(calibrate_mitsunaga1999)


def test_exact_polynomial_and_ratio_reestimation():
    L = scene(seed=1)
    cam = Camera("polynomial", bit_depth=12, exposure_error=0.08)
    br = cam.capture(L, TIMES, seed=5)
    resp = calibrate_mitsunaga1999(br.images, br.exposure_times, degree=3)
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
    assert resp.method == "mitsunaga1999"


def test_no_pair_unclipped_in_adjacent_exposures_raises():
    # failure mode: each pixel is clipped (0 or 255) in one of the two exposures
    Z = np.zeros((2, 8, 8), np.uint8)
    Z[0] = 100
    Z[1] = 255
    with pytest.raises(ValueError, match="too few pixels"):
        calibrate_mitsunaga1999(Z, [1.0, 4.0], degree=2)


def test_option_value_errors():
    br = Camera("gamma").capture(scene(8), [0.25, 1.0])
    with pytest.raises(ValueError, match="degree"):
        calibrate_mitsunaga1999(br.images, br.exposure_times, degree=0)


def test_order_by_the_papers_rule_finds_the_true_degree_and_black_at_zero():
    # a cubic inverse with c_0 = 0: the rule (smallest pair error among monotone fits) needs
    # no more than the true order, and the fit is exact to quantisation
    L = scene(48, seed=2)
    br = Camera("polynomial", bit_depth=12).capture(L, TIMES, seed=1)
    resp = calibrate_mitsunaga1999(br.images, br.exposure_times, estimate_ratios=False)
    z = np.arange(8, 4095)
    err = np.log2(resp.inverse[z]) - np.log2(br.true_inverse[z])
    assert np.max(np.abs(err - err.mean(axis=0))) < 0.01
    assert resp.coefficients.shape[0] - 1 >= 3


def test_dark_end_of_a_gamma_camera_is_within_the_floor():
    # the failure of the unconstrained fit: a gamma-2.2 camera, whose inverse M^2.2 a
    # polynomial follows badly near black; the dark end is constrained (monotone, black at 0)
    from pbrbench.camera import bracket_exposure_times
    from pbrbench.infer.hdr import CameraResponse, merge_hdr
    from pbrbench.metrics.hdr import hdr_scores
    from pbrbench.perf.hdr import synthetic_radiance

    L = synthetic_radiance(128).astype(float)
    br = Camera("gamma").capture(L, bracket_exposure_times(L, stops=1.0, count=7, headroom=0.9), seed=11)
    resp = calibrate_mitsunaga1999(br.images, br.exposure_times)
    true = CameraResponse(np.maximum.accumulate(np.maximum(br.true_inverse, 1e-9), axis=0), 256, "true")
    ours = hdr_scores(merge_hdr(br.images, resp.exposure_times, resp), L)
    floor = hdr_scores(merge_hdr(br.images, br.exposure_times, true), L)
    assert ours["log2_rmse"] < 1.3 * floor["log2_rmse"]
    assert ours["dark1"] < 1.3 * floor["dark1"]
    assert np.all(np.diff(resp.inverse, axis=0) > 0)


def test_monotone_even_when_least_squares_is_not():
    from pbrbench.infer.hdr.mitsunaga1999 import _mn_fit, _moments

    # pairs that a free cubic fits best with a dip: p(0.1) must not fall below p(0)
    ma = np.linspace(0.05, 0.9, 200)
    mb = np.minimum(ma * 1.3 + 0.02 * np.sin(40 * ma), 0.99)
    kk = np.zeros(ma.size, int)
    mom = _moments(ma, mb, kk, 1, 6)
    free = _mn_fit(mom, np.array([0.7]), 6, True, 1 / 255, False)
    cons = _mn_fit(mom, np.array([0.7]), 6, True, 1 / 255, True)
    M = np.linspace(0, 1, 501)
    assert np.any(np.diff(np.polynomial.polynomial.polyval(M, free)) < 0)
    assert np.all(np.diff(np.polynomial.polynomial.polyval(M, cons)) >= -1e-9)
    assert cons[-1] + cons[:-1].sum() == pytest.approx(1.0)


def test_the_constrained_fit_is_the_exact_minimiser():
    """The monotone fit's quadratic programme: a closed-form case, and the KKT conditions
    (stationarity with non-negative multipliers on the active constraints only) on random
    convex problems of the fit's size, where the active set is not known in advance."""
    from scipy.optimize import nnls

    from pbrbench.infer.hdr.mitsunaga1999 import _convex_qp

    # min |v - (1, 1)|^2 with v_0 <= 0.5: (0.5, 1)
    v = _convex_qp(np.eye(2), np.ones(2), np.array([[-1.0, 0.0]]), np.array([0.5]))
    np.testing.assert_allclose(v, [0.5, 1.0], atol=1e-12)
    # a feasible unconstrained minimiser is returned as it is
    np.testing.assert_allclose(_convex_qp(np.eye(2), np.ones(2), np.array([[-1.0, 0.0]]), np.array([2.0])), [1, 1])
    rng = np.random.default_rng(0)
    for _ in range(20):
        n, m = 9, 66
        B = rng.normal(size=(n, n))
        G = B @ B.T + 0.1 * np.eye(n)
        h, A, b = rng.normal(size=n), rng.normal(size=(m, n)), rng.uniform(0.1, 1.0, m)
        v = _convex_qp(G, h, A, b)
        slack = A @ v + b
        assert slack.min() > -1e-9
        active = slack < 1e-8
        assert active.any()       # the unconstrained minimiser of these problems is infeasible
        lam, res = nnls(A[active].T, 2 * (G @ v - h))      # 2 (G v - h) = A_active' lam, lam >= 0
        assert res < 1e-7 * max(1.0, float(np.linalg.norm(G @ v - h)))


def test_many_exposures_of_a_small_image_keep_their_ratios():
    # 14 exposures one stop apart of a 32 x 32 image, film response, no noise: the ratio update
    # that minimises the pair error (least squares) keeps every ratio at 2; averaging per-pixel
    # ratios lets the dark pixels pull them off (1.97-2.02 here, 1.6-2.1 on a rendered scene)
    from pbrbench.camera import bracket_exposure_times
    from pbrbench.perf.hdr import synthetic_radiance

    L = synthetic_radiance(32, seed=1)
    br = Camera("film", bit_depth=8).capture(L, bracket_exposure_times(L, stops=1.0, count=14, headroom=0.9), seed=0)
    resp = calibrate_mitsunaga1999(br.images, br.exposure_times)
    ratios = resp.exposure_times[1:] / resp.exposure_times[:-1]
    assert np.max(np.abs(ratios / 2.0 - 1.0)) < 0.005, ratios


def test_screening_fit_has_the_pair_error_of_the_least_squares():
    # the screen that skips orders that cannot win solves the unconstrained least squares of
    # every channel at once, rounded differently; its pair error must be that of _mn_fit's
    from pbrbench.camera import bracket_exposure_times
    from pbrbench.infer.hdr.mitsunaga1999 import _mn_fit, _mn_fit_free, _moments
    from pbrbench.perf.hdr import synthetic_radiance

    L = synthetic_radiance(48, seed=3)
    br = Camera("film", bit_depth=8, read_noise=0.002).capture(L, bracket_exposure_times(L, stops=1.0, count=5, headroom=0.9), seed=1)
    Z, K = br.images.astype(float) / 255, br.images.shape[0]
    rows = []
    for c in range(3):
        ok = (Z[:-1, ..., c] > 0) & (Z[:-1, ..., c] < 1) & (Z[1:, ..., c] > 0) & (Z[1:, ..., c] < 1)
        kk = np.nonzero(ok)[0]
        rows.append((Z[:-1, ..., c][ok], Z[1:, ..., c][ok], kk))
    moms = np.stack([_moments(ma, mb, kk, K - 1, 10) for ma, mb, kk in rows])
    R = br.exposure_times[:-1] / br.exposure_times[1:]

    def pair_error(coefs):
        P = np.polynomial.polynomial.polyval
        return sum(np.sum((P(ma, cf) - R[kk] * P(mb, cf)) ** 2) for (ma, mb, kk), cf in zip(rows, coefs, strict=True))

    for deg in (1, 3, 6, 10):
        for black in (True, False):
            ref = pair_error([_mn_fit(m, R, deg, black, 1 / 255, False) for m in moms])
            # (the screen allows 1e-4: an order is skipped only if its error exceeds the bound by that)
            assert pair_error(_mn_fit_free(moms, R, deg, black)) == pytest.approx(ref, rel=1e-5)


def test_stated_ratios_are_kept_unless_re_estimating_them_halves_the_pair_error():
    # exact stated times: the re-estimated ratios lower the pair error only by absorbing the
    # polynomial's misfit, so "auto" (the default) returns the stated times; with times 8 % off
    # (the ratio test above) it re-estimates them, and estimate_ratios=True always does
    L = scene(seed=1)
    br = Camera("film", bit_depth=8).capture(L, TIMES, seed=2)
    auto = calibrate_mitsunaga1999(br.images, br.exposure_times, degree=5)
    np.testing.assert_allclose(auto.exposure_times, br.exposure_times, rtol=1e-12)
    forced = calibrate_mitsunaga1999(br.images, br.exposure_times, degree=5, estimate_ratios=True)
    assert np.abs(np.log(forced.exposure_times / br.exposure_times)).max() > 1e-6
    rough = Camera("polynomial", bit_depth=12, exposure_error=0.08).capture(L, TIMES, seed=5)
    est = calibrate_mitsunaga1999(rough.images, rough.exposure_times, degree=3)
    assert np.abs(np.log(est.exposure_times / rough.exposure_times)).max() > 0.01


@pytest.mark.parametrize("kwargs, match", [(dict(estimate_ratios="sometimes"), "estimate_ratios"),
                                           (dict(ratio_gain=0.0), "ratio_gain"), (dict(ratio_gain=1.5), "ratio_gain")])
def test_ratio_option_errors(kwargs, match):
    br = Camera("gamma").capture(scene(8), [0.25, 0.5, 1.0])
    with pytest.raises(ValueError, match=match):
        calibrate_mitsunaga1999(br.images, br.exposure_times, degree=2, **kwargs)


def test_a_pair_with_too_few_rows_keeps_its_stated_ratio():
    # 3 exposures 3 stops apart, stated times 10 % off; most of the scene is black in the first
    # exposure, so the first pair has only the n bright pixels.  A degree-5 polynomial fits 12
    # rows at any ratio: below 4 (N + 1) = 24 rows the pair does not determine its ratio, and
    # with the stated span fixed neither ratio is re-estimated, even when asked to; with 200 rows
    # the re-estimated first ratio moves toward the true one
    def bracket(n_bright):
        rng = np.random.default_rng(0)
        L = np.exp(rng.uniform(np.log(3e-4), np.log(1.9e-3), (32, 32)))
        L.ravel()[:n_bright] = np.exp(rng.uniform(np.log(0.01), np.log(0.1), n_bright))
        return Camera("film", bit_depth=8, exposure_error=0.1).capture(np.repeat(L[..., None], 3, axis=-1),
                                                                        [1.0, 8.0, 64.0], seed=3)

    few = bracket(12)
    z = few.images
    assert (((z[0] > 0) & (z[0] < 255) & (z[1] > 0) & (z[1] < 255))[..., 0]).sum() == 12
    kept = calibrate_mitsunaga1999(few.images, few.exposure_times, degree=5, estimate_ratios=True)
    np.testing.assert_allclose(kept.exposure_times, few.exposure_times, rtol=1e-12)
    many = bracket(200)
    est = calibrate_mitsunaga1999(many.images, many.exposure_times, degree=5, estimate_ratios=True)
    first = [np.log(t[0] / t[1]) for t in (est.exposure_times, many.exposure_times, many.true_exposure_times)]
    assert abs(first[0] - first[2]) < 0.5 * abs(first[1] - first[2])
