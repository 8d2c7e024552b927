"""Tests for the simulated camera (pbrbench.camera)."""

import numpy as np
import pytest

from pbrbench.camera import RESPONSE_NAMES, Camera, bracket_exposure_times, response_curve


@pytest.mark.parametrize("name", RESPONSE_NAMES)
def test_response_curves_monotone_and_invertible(name):
    f = response_curve(name)
    x = np.linspace(0, 1, 2001)
    y = f.forward(x)
    assert y[0] == pytest.approx(0, abs=1e-12) and y[-1] == pytest.approx(1, abs=1e-9)
    assert np.all(np.diff(y) > 0)
    ys = np.linspace(0.01, 1, 200)
    np.testing.assert_allclose(f.forward(f.inverse(ys)), ys, atol=1e-5)


def test_gamma_curve_is_analytic():
    f = response_curve("gamma", gamma=2.2)
    np.testing.assert_allclose(f.forward(np.array([0.25])), 0.25 ** (1 / 2.2))


def test_random_curves_seeded():
    a, b, c = (response_curve("random", seed=s) for s in (1, 1, 2))
    y = np.linspace(0, 1, 50)
    np.testing.assert_array_equal(a.inverse(y), b.inverse(y))
    assert np.max(np.abs(a.inverse(y) - c.inverse(y))) > 1e-3


def test_linear_capture_exact_levels_and_clipping():
    L = np.array([[0.1, 0.5, 2.0]])  # (1, 3) grey
    br = Camera("linear", bit_depth=10).capture(L, [1.0, 0.25])
    assert br.images.dtype == np.uint16 and br.images.shape == (2, 1, 3, 1)
    np.testing.assert_array_equal(br.exposure_times, [0.25, 1.0])  # sorted
    np.testing.assert_array_equal(br.images[:, 0, :, 0], np.rint([[0.025 * 1023, 0.125 * 1023, 0.5 * 1023],
                                                                  [0.1 * 1023, 0.5 * 1023, 1023]]))
    assert br.true_inverse.shape == (1024, 1) and br.true_inverse[-1, 0] == 1.0
    np.testing.assert_array_equal(br.saturated[0, :, 0], [False, False, False])
    br2 = Camera("linear", bit_depth=8).capture(L, [0.6])
    assert br2.images.dtype == np.uint8
    np.testing.assert_array_equal(br2.saturated[0, :, 0], [False, False, True])


@pytest.mark.parametrize("bits", [8, 10, 12, 14, 16])
def test_bit_depth_range(bits):
    L = np.linspace(0, 3, 100).reshape(10, 10)
    br = Camera("gamma", bit_depth=bits).capture(L, [1.0])
    assert br.images.max() == (1 << bits) - 1 and br.images.min() == 0
    assert br.true_inverse.shape == (1 << bits, 1)


def test_read_noise_statistics():
    L = np.full((200, 200), 0.5)
    br = Camera("linear", bit_depth=16, read_noise=0.01).capture(L, [1.0], seed=3)
    x = br.images[0].astype(float) / 65535
    assert np.std(x) == pytest.approx(0.01, rel=0.05)
    assert np.mean(x) == pytest.approx(0.5, abs=1e-3)


def test_shot_noise_statistics():
    L = np.full((200, 200), 0.4)
    br = Camera("linear", bit_depth=16, full_well=1000).capture(L, [1.0], seed=3)
    x = br.images[0].astype(float) / 65535
    assert np.var(x) == pytest.approx(0.4 / 1000, rel=0.05)


def test_seeded_capture_and_exposure_errors():
    L = np.random.default_rng(0).random((20, 20, 3))
    cam = Camera("random", read_noise=0.01, exposure_error=0.05, seed=4)
    a, b, c = (cam.capture(L, [0.5, 1, 2], seed=s) for s in (7, 7, 8))
    np.testing.assert_array_equal(a.images, b.images)
    assert not np.array_equal(a.images, c.images)
    assert not np.allclose(a.true_exposure_times, a.exposure_times)
    np.testing.assert_allclose(a.true_exposure_times / a.exposure_times, 1, rtol=0.3)
    # per-channel random responses differ
    assert np.max(np.abs(a.true_inverse[:, 0] - a.true_inverse[:, 1])) > 1e-3


def test_bracket_exposure_times_cover_range():
    L = np.geomspace(1e-2, 1e2, 400).reshape(20, 20)
    t = bracket_exposure_times(L, stops=1.0, headroom=0.8, dark_target=0.25)
    assert np.all(np.diff(np.log2(t)) == pytest.approx(1.0))
    assert L.max() * t[0] == pytest.approx(0.8)
    assert L.min() * t[-1] >= 0.25
    assert bracket_exposure_times(L, count=7).size == 7


@pytest.mark.parametrize("kwargs", [dict(bit_depth=9), dict(gain=0), dict(full_well=-1), dict(read_noise=-0.1),
                                    dict(exposure_error=np.nan)])
def test_camera_value_errors(kwargs):
    with pytest.raises(ValueError):
        Camera("gamma", **kwargs)


def test_capture_and_curve_value_errors():
    cam = Camera("linear")
    with pytest.raises(ValueError, match="radiance"):
        cam.capture(-np.ones((2, 2)), [1.0])
    with pytest.raises(ValueError, match="exposure_times"):
        cam.capture(np.ones((2, 2)), [0.0, 1.0])
    with pytest.raises(ValueError, match="name"):
        response_curve("sigmoid")
    with pytest.raises(ValueError, match="coefficients"):
        response_curve("polynomial", coefficients=(0, 0.5, 0.4))
    with pytest.raises(ValueError, match="response"):
        Camera(["linear", "gamma"]).capture(np.ones((2, 2, 3)), [1.0])
    with pytest.raises(ValueError, match="radiance"):
        bracket_exposure_times(np.zeros((3, 3)))
