"""Scores of forward models of radiance: relative errors, bias and chromaticity on known inputs."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.metrics import METRICS, metric
from pbrbench.metrics.interreflection import chromaticity_error, radiosity_scores


def test_a_uniform_excess_gives_known_errors():
    rng = np.random.default_rng(0)
    ref = rng.uniform(0.1, 1.0, (8, 9, 3))
    sc = radiosity_scores(1.1 * ref, ref)
    assert sc["radiosity_rel_error"] == pytest.approx(0.1)
    assert sc["radiosity_abs_bias"] == pytest.approx(0.1)
    assert sc["radiosity_rel_rmse"] == pytest.approx(0.1 * np.sqrt(np.mean(ref ** 2)) / np.mean(ref))
    assert sc["chromaticity_error"] == pytest.approx(0.0, abs=1e-12)  # the same colours
    exact = radiosity_scores(ref, ref)
    assert exact["radiosity_rel_error"] == 0 and exact["radiosity_abs_bias"] == 0


def test_errors_of_opposite_sign_cancel_in_the_bias_only():
    ref = np.ones((4, 4))
    pred = ref.copy()
    pred[:2] = 1.5
    pred[2:] = 0.5
    sc = radiosity_scores(pred, ref)
    assert sc["radiosity_rel_error"] == pytest.approx(0.5) and sc["radiosity_abs_bias"] == pytest.approx(0.0)
    assert sc["chromaticity_error"] == 0.0  # grey images


def test_mask_and_chromaticity_of_a_missed_colour_bleed():
    ref = np.full((2, 2, 3), 0.3)
    ref[0, 0] = [0.5, 0.2, 0.2]      # a pink pixel (colour bled onto a white floor)
    pred = np.full((2, 2, 3), 0.3)   # a model that keeps it grey
    chi = np.abs(np.array([0.5, 0.2, 0.2]) / 0.9 - 1 / 3).sum()
    want = 0.9 * chi / (0.9 + 3 * 0.9)
    assert chromaticity_error(pred, ref) == pytest.approx(want)
    m = np.array([[False, True], [True, True]])
    assert radiosity_scores(pred, ref, m)["radiosity_rel_error"] == 0.0  # the pink pixel left out


def test_bad_inputs_are_refused():
    ref = np.ones((4, 4, 3))
    with pytest.raises(ValueError, match="pred"):
        radiosity_scores(np.ones((4, 5, 3)), ref)
    with pytest.raises(ValueError, match="no light"):
        radiosity_scores(ref, np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="mask"):
        radiosity_scores(ref, ref, np.zeros((4, 4), bool))


def test_metrics_are_in_the_table():
    for name in ("radiosity_rel_error", "radiosity_rel_rmse", "radiosity_abs_bias", "chromaticity_error"):
        assert name in METRICS and metric(name).better == "lower"


def test_delta_e2000_of_grey_levels_is_the_lightness_term_of_ciede2000():
    """Achromatic pixels: a* = b* = 0, so CIEDE2000 reduces to |L1 - L2| / S_L with
    S_L = 1 + 0.015 (L - 50)^2 / sqrt(20 + (L - 50)^2) at the mean lightness L (Sharma et al. 2005).
    The reference is white after scaling (Y = 1, L* = 100); the prediction at half its luminance."""
    from pbrbench.metrics.interreflection import delta_e2000

    ref = np.full((4, 5, 3), 2.0)
    pred = 0.5 * ref
    L1, L2 = 100.0, 116.0 * 0.5 ** (1 / 3) - 16.0
    Lm = (L1 + L2) / 2
    want = (L1 - L2) / (1 + 0.015 * (Lm - 50) ** 2 / np.sqrt(20 + (Lm - 50) ** 2))
    assert delta_e2000(pred, ref) == pytest.approx(want, rel=1e-6)
    assert delta_e2000(ref, ref) == pytest.approx(0.0, abs=1e-9)
    assert delta_e2000(pred[..., 0], ref[..., 0]) == pytest.approx(want, rel=1e-6)   # grey images
    assert delta_e2000(7 * pred, 7 * ref) == pytest.approx(want, rel=1e-6)           # scale-free


def test_delta_e2000_sees_colour_bleeding_that_brightness_misses():
    """A pink floor predicted white at the same luminance: no brightness error to speak of, a
    colour difference of several just-noticeable differences."""
    from pbrbench.metrics.interreflection import delta_e2000

    ref = np.broadcast_to([1.0, 0.8, 0.8], (3, 3, 3)).copy()
    pred = np.full((3, 3, 3), ref.mean())
    assert delta_e2000(pred, ref) > 5.0


def test_delta_e2000_refuses_inputs_it_cannot_read():
    from pbrbench.metrics.interreflection import delta_e2000

    with pytest.raises(ValueError, match="channels"):
        delta_e2000(np.ones((3, 3, 2)), np.ones((3, 3, 2)))
    with pytest.raises(ValueError, match="no light"):
        delta_e2000(np.ones((3, 3, 3)), np.zeros((3, 3, 3)))
    with pytest.raises(ValueError, match="mask"):
        delta_e2000(np.ones((3, 3, 3)), np.ones((3, 3, 3)), np.zeros((3, 3), bool))
