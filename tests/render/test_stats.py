"""Statistical image comparison: calibrated under the null, detects a small bias, writes diagnostics."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.render import stats


def _renders(rng, mean, sigma, n_half=2):
    """Mean and sd (|a - b| / 2) of two half renders, as the ground truth stores them."""
    a = mean + rng.normal(0, sigma, mean.shape)
    b = mean + rng.normal(0, sigma, mean.shape)
    return 0.5 * (a + b), 0.5 * np.abs(a - b)


def test_unbiased_renders_pass_at_the_family_wise_rate():
    rng = np.random.default_rng(0)
    mean = np.linspace(0.2, 2.0, 48 * 48 * 3).reshape(48, 48, 3)
    sigma = 0.05 * mean
    fails = 0
    for _ in range(40):
        x, sx = _renders(rng, mean, sigma)
        mu, sm = _renders(rng, mean, sigma)
        fails += not stats.compare_images(x, mu, sm, image_sd=sx, alpha=0.05).passed
    assert fails <= 8  # expected <= 2 of 40 at alpha 0.05; 8 would be p < 1e-3 under a calibrated test


def test_small_bias_is_detected_and_diagnostics_written(tmp_path):
    rng = np.random.default_rng(1)
    mean = np.full((64, 64, 3), 1.0)
    sigma = np.full_like(mean, 0.02)
    x, sx = _renders(rng, mean, sigma)
    mu, sm = _renders(rng, mean, sigma)
    x[20:30, 20:30] *= 1.2  # a bias of 10 sd of the difference in a 10 x 10 block
    res = stats.compare_images(x, mu, sm, image_sd=sx, diagnostics_dir=tmp_path, name="biased")
    assert not res.passed
    assert res.rejected[20:30, 20:30].any() and not res.rejected[:20].any()
    for f in ("biased_image.png", "biased_reference.png", "biased_t.png", "biased.txt"):
        assert (tmp_path / f).is_file()
    ok = stats.compare_images(mu, mu, sm, diagnostics_dir=tmp_path / "none")
    assert ok.passed and ok.max_abs_t == 0 and not (tmp_path / "none").exists()


def test_zero_variance_pixels_use_atol_and_mask():
    mu = np.zeros((8, 8))
    sd = np.zeros((8, 8))
    x = mu.copy()
    assert stats.compare_images(x, mu, sd).passed
    x[3, 3] = 1e-3
    assert not stats.compare_images(x, mu, sd).passed
    assert stats.compare_images(x, mu, sd, atol=1e-2).passed
    m = np.ones((8, 8), bool)
    m[3, 3] = False
    assert stats.compare_images(x, mu, sd, mask=m).passed


def test_corrections_and_reference_round_trip(tmp_path):
    assert stats.corrected_threshold(0.01, 100, "bonferroni") == pytest.approx(1e-4)
    assert stats.corrected_threshold(0.01, 100, "sidak") == pytest.approx(1 - 0.99 ** 0.01)
    assert stats.corrected_threshold(0.01, 100, "none") == 0.01
    mean = np.random.default_rng(2).random((6, 5, 3)).astype(np.float32)
    stats.save_reference(tmp_path / "ref.exr", mean, 0.1 * mean)
    m, s = stats.load_reference(tmp_path / "ref.exr")
    assert np.array_equal(m, mean) and np.allclose(s, 0.1 * mean)


@pytest.mark.parametrize("kw,match", [
    ({"correction": "holm"}, "correction"),
    ({"alpha": 1.5}, "alpha"),
    ({"pool": 0}, "pool"),
    ({"mask": np.ones((3, 3), bool)}, "mask"),
    ({"image_sd": np.zeros((2, 2))}, "image_sd"),
])
def test_errors(kw, match):
    a = np.ones((4, 4))
    with pytest.raises(ValueError, match=match):
        stats.compare_images(a, a, a, **kw)


def test_shape_and_nan_errors():
    with pytest.raises(ValueError, match="shapes"):
        stats.compare_images(np.ones((4, 4)), np.ones((4, 5)), np.ones((4, 5)))
    bad = np.ones((4, 4))
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="image"):
        stats.compare_images(bad, np.ones((4, 4)), np.ones((4, 4)))
