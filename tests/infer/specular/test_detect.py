"""Specularity detection (pbrbench.infer.specular.detect) on an analytic glossy sphere."""

import numpy as np
import pytest

from pbrbench.infer.specular import detect_specularities, remove_specularities
from pbrbench.metrics.specular import mask_iou, specular_mask_from_twin
from pbrbench.perf.lightness import glossy_sphere


@pytest.fixture(scope="module")
def sharp():
    return glossy_sphere(256, shininess=300.0)


def test_detects_small_highlight(sharp):
    image, diffuse, _ = sharp
    truth = specular_mask_from_twin(image, diffuse, threshold=0.1)
    det = detect_specularities(image)
    assert mask_iou(det, truth) > 0.85
    # one blob, around the mirror direction (the half-vector's image position)
    assert det.sum() < 2 * truth.sum()


def test_no_false_positive_on_lambertian_sphere():
    image, diffuse, _ = glossy_sphere(256, specular=0.0)
    assert not detect_specularities(image).any()
    np.testing.assert_array_equal(remove_specularities(image), image)


def test_broad_lobe_is_not_small():
    # Failure mode: a wide glossy lobe (Blinn-Phong n = 20 covers ~1/6 of the sphere) is not
    # a small blob; the detector, by design, leaves most of it.
    image, diffuse, _ = glossy_sphere(256, shininess=20.0)
    truth = specular_mask_from_twin(image, diffuse, threshold=0.1)
    assert mask_iou(detect_specularities(image), truth) < 0.5


@pytest.mark.parametrize("kwargs, match", [
    ({"radius": 0}, "radius"),
    ({"ratio": 1.05, "low_ratio": 1.1}, "low_ratio"),
    ({"low_ratio": 1.0}, "low_ratio"),
    ({"min_excess": -1}, "min_excess"),
    ({"max_area": 0}, "max_area"),
    ({"mask": np.ones((2, 2), bool)}, "mask"),
])
def test_detect_bad_options(sharp, kwargs, match):
    with pytest.raises(ValueError, match=match):
        detect_specularities(sharp[0], **kwargs)


def test_isolated_bright_square_is_found_exactly():
    # known answer: on a flat background the opening removes a 3x3 blob entirely, so the
    # top-hat ratio is 2 there and 1 elsewhere: the mask is the blob, nothing more
    img = np.full((40, 40), 0.5)
    img[10:13, 20:23] = 1.0
    det = detect_specularities(img, radius=3)
    expected = np.zeros((40, 40), bool)
    expected[10:13, 20:23] = True
    np.testing.assert_array_equal(det, expected)
    # outside the given domain nothing is detected
    domain = np.ones((40, 40), bool)
    domain[:20] = False
    assert not detect_specularities(img, radius=3, mask=domain).any()
    # a blob wider than the opening is not small: the octagon of radius 3 (square + cross +
    # square, Minkowski sum) has its corners cut by one pixel, so the opening keeps the whole
    # square except its four corner pixels, and only those are left as "small"
    big = np.full((40, 40), 0.5)
    big[5:25, 5:25] = 1.0
    np.testing.assert_array_equal(np.argwhere(detect_specularities(big, radius=3)),
                                  [[5, 5], [5, 24], [24, 5], [24, 24]])
