"""Specularity filling, harmonic and biharmonic (pbrbench.infer.specular.fill), on an analytic
glossy sphere."""

import numpy as np
import pytest

from pbrbench.infer.specular import (
    detect_specularities,
    remove_specularities_biharmonic,
    remove_specularities_harmonic,
)
from pbrbench.metrics.specular import removal_errors, specular_mask_from_twin
from pbrbench.perf.lightness import glossy_sphere


@pytest.fixture(scope="module")
def sharp():
    return glossy_sphere(256, shininess=300.0)


def test_removal_restores_diffuse(sharp):
    image, diffuse, _ = sharp
    truth = specular_mask_from_twin(image, diffuse, threshold=0.1)
    before = removal_errors(image, diffuse, truth)
    out = remove_specularities_harmonic(image)
    after = removal_errors(out, diffuse, truth)
    assert after["inside_rel"] < 0.05 < before["inside_rel"]
    assert after["ring_rel"] < before["ring_rel"]
    # far from the highlight nothing changes
    far = np.ones(image.shape[:2], bool)
    far[60:200, 60:200] = False
    np.testing.assert_array_equal(out[far], image[far])


def test_fills_reproduce_a_linear_function():
    # known answer: a linear function is harmonic and biharmonic, so both fills restore it
    yy, xx = np.mgrid[0:40, 0:50].astype(float)
    img = 1.0 + 0.02 * xx - 0.03 * yy
    hole = np.zeros((40, 50), bool)
    hole[10:25, 15:30] = True
    spoiled = np.where(hole, 9.0, img)
    out = remove_specularities_harmonic(spoiled, hole, dilate=0)
    np.testing.assert_allclose(out, img, atol=1e-10)
    out_b = remove_specularities_biharmonic(spoiled, hole, dilate=0)
    np.testing.assert_allclose(out_b, img, atol=1e-6)


def test_colour_highlight_removed_per_channel(sharp):
    image, diffuse, _ = sharp
    det = detect_specularities(image)
    out = remove_specularities_harmonic(image, det)
    peak = np.unravel_index(np.argmax(image.mean(-1) - diffuse.mean(-1)), det.shape)
    # the white highlight is gone: the sphere's colour (0.7, 0.5, 0.3) is back at the peak
    np.testing.assert_allclose(out[peak] / out[peak].sum(), np.array([0.7, 0.5, 0.3]) / 1.5, atol=0.01)


def test_mask_argument_and_detect_options(sharp):
    image, _, _ = sharp
    none = remove_specularities_harmonic(image, np.zeros(image.shape[:2], bool))
    np.testing.assert_array_equal(none, image)
    tiny = detect_specularities(image, max_area=10)
    assert not tiny.any()
    out = remove_specularities_harmonic(image, detect_options={"max_area": 10})
    np.testing.assert_array_equal(out, image)


def test_grey_image_supported(sharp):
    image, diffuse, _ = sharp
    grey = image.mean(-1)
    det = detect_specularities(grey)
    assert det.any()
    out = remove_specularities_harmonic(grey, det)
    assert out.shape == grey.shape


@pytest.mark.parametrize("fill", [remove_specularities_harmonic, remove_specularities_biharmonic])
def test_remove_bad_inputs(sharp, fill):
    # failure modes: a mask that covers everything leaves nothing to interpolate from
    image = sharp[0]
    with pytest.raises(ValueError, match="dilate"):
        fill(image, dilate=-1)
    with pytest.raises(ValueError, match="mask"):
        fill(image, np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="whole image"):
        fill(image, np.ones(image.shape[:2], bool))
    with pytest.raises(ValueError, match="mask"):
        fill(image, np.full(image.shape[:2], 2))
    bad = image.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        detect_specularities(bad)
    with pytest.raises(ValueError, match="non-finite"):
        fill(bad, np.zeros(image.shape[:2], bool))
