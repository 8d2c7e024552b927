"""Specularity detection and removal (SCIENCE.md §1) on an analytic glossy sphere."""

import numpy as np
import pytest

from pbrbench.infer.specular import detect_specularities, remove_specularities
from pbrbench.metrics.specular import mask_iou, removal_errors, specular_mask_from_twin
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


def test_removal_restores_diffuse(sharp):
    image, diffuse, _ = sharp
    truth = specular_mask_from_twin(image, diffuse, threshold=0.1)
    before = removal_errors(image, diffuse, truth)
    out = remove_specularities(image)
    after = removal_errors(out, diffuse, truth)
    assert after["inside_rel"] < 0.05 < before["inside_rel"]
    assert after["ring_rel"] < before["ring_rel"]
    # far from the highlight nothing changes
    far = np.ones(image.shape[:2], bool)
    far[60:200, 60:200] = False
    np.testing.assert_array_equal(out[far], image[far])


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


def test_harmonic_fill_reproduces_linear_function():
    yy, xx = np.mgrid[0:40, 0:50].astype(float)
    img = 1.0 + 0.02 * xx - 0.03 * yy
    hole = np.zeros((40, 50), bool)
    hole[10:25, 15:30] = True
    spoiled = np.where(hole, 9.0, img)
    out = remove_specularities(spoiled, hole, dilate=0)
    np.testing.assert_allclose(out, img, atol=1e-10)
    out_b = remove_specularities(spoiled, hole, dilate=0, method="biharmonic")
    np.testing.assert_allclose(out_b, img, atol=1e-6)


def test_colour_highlight_removed_per_channel(sharp):
    image, diffuse, _ = sharp
    det = detect_specularities(image)
    out = remove_specularities(image, det)
    peak = np.unravel_index(np.argmax(image.mean(-1) - diffuse.mean(-1)), det.shape)
    # the white highlight is gone: the sphere's colour (0.7, 0.5, 0.3) is back at the peak
    np.testing.assert_allclose(out[peak] / out[peak].sum(), np.array([0.7, 0.5, 0.3]) / 1.5, atol=0.01)


def test_mask_argument_and_detect_options(sharp):
    image, _, _ = sharp
    none = remove_specularities(image, np.zeros(image.shape[:2], bool))
    np.testing.assert_array_equal(none, image)
    tiny = detect_specularities(image, max_area=10)
    assert not tiny.any()
    out = remove_specularities(image, detect_options={"max_area": 10})
    np.testing.assert_array_equal(out, image)


def test_grey_image_supported(sharp):
    image, diffuse, _ = sharp
    grey = image.mean(-1)
    det = detect_specularities(grey)
    assert det.any()
    out = remove_specularities(grey, det)
    assert out.shape == grey.shape


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


def test_remove_bad_inputs(sharp):
    image = sharp[0]
    with pytest.raises(ValueError, match="method"):
        remove_specularities(image, method="telea")
    with pytest.raises(ValueError, match="dilate"):
        remove_specularities(image, dilate=-1)
    with pytest.raises(ValueError, match="mask"):
        remove_specularities(image, np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="whole image"):
        remove_specularities(image, np.ones(image.shape[:2], bool))
    with pytest.raises(ValueError, match="mask"):
        remove_specularities(image, np.full(image.shape[:2], 2))
    bad = image.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        detect_specularities(bad)
    with pytest.raises(ValueError, match="non-finite"):
        remove_specularities(bad, np.zeros(image.shape[:2], bool))
