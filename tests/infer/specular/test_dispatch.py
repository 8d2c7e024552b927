"""The specularity-removal dispatcher and FILL_METHODS table (pbrbench.infer.specular)."""

import numpy as np
import pytest

from pbrbench.infer.specular import (
    FILL_METHODS,
    remove_specularities,
    remove_specularities_biharmonic,
    remove_specularities_harmonic,
)


@pytest.fixture(scope="module")
def spoiled():
    yy, xx = np.mgrid[0:32, 0:32].astype(float)
    img = 1.0 + 0.02 * xx ** 1.5 - 0.03 * yy
    img[12:15, 14:17] = 5.0  # a small bright blob
    hole = np.zeros((32, 32), bool)
    hole[12:15, 14:17] = True
    return img, hole


def test_table_and_default(spoiled):
    img, hole = spoiled
    assert FILL_METHODS == {"harmonic": remove_specularities_harmonic, "biharmonic": remove_specularities_biharmonic}
    np.testing.assert_array_equal(remove_specularities(img, hole), remove_specularities_harmonic(img, hole))
    np.testing.assert_array_equal(remove_specularities(img, hole, method="biharmonic"),
                                  remove_specularities_biharmonic(img, hole))


def test_unknown_method(spoiled):
    img, hole = spoiled
    with pytest.raises(ValueError, match="method='telea' is not known; choose one of 'harmonic', 'biharmonic'"):
        remove_specularities(img, hole, method="telea")


def test_option_the_method_does_not_accept(spoiled):
    img, hole = spoiled
    with pytest.raises(ValueError, match=r"remove_specularities\(method='harmonic'\): unknown option\(s\) radius; "
                                         r"harmonic accepts mask, dilate, detect_options$"):
        remove_specularities(img, hole, radius=3)  # a detection option, not a fill option


def test_forwarded_option_changes_the_result(spoiled):
    img, hole = spoiled
    a = remove_specularities(img, hole)
    b = remove_specularities(img, hole, dilate=0)
    assert not np.array_equal(a, b)
    np.testing.assert_array_equal(b, remove_specularities_harmonic(img, hole, dilate=0))
    # detect_options is forwarded to the detection when no mask is given
    assert np.array_equal(remove_specularities(img, detect_options={"max_area": 1}), img)
    assert not np.array_equal(remove_specularities(img, detect_options={"radius": 3}), img)
