"""The lightness dispatcher and METHODS table (pbrbench.infer.lightness)."""

import numpy as np
import pytest

from pbrbench.infer.lightness import (
    METHODS,
    estimate_lightness,
    lightness_blake1985,
    lightness_grosse2009,
)
from pbrbench.shading.mondrian import mondrian_scene


@pytest.fixture(scope="module")
def image():
    return mondrian_scene(64, seed=3)["image"]


def test_table_and_default(image):
    assert METHODS == {"blake1985": lightness_blake1985, "grosse2009": lightness_grosse2009}
    r, s = estimate_lightness(image)
    r0, s0 = lightness_blake1985(image)
    np.testing.assert_array_equal(r, r0)
    np.testing.assert_array_equal(s, s0)


def test_unknown_method(image):
    with pytest.raises(ValueError, match="method='horn1974' is not known; choose one of 'blake1985'"):
        estimate_lightness(image, method="horn1974")


def test_option_the_method_does_not_accept(image):
    with pytest.raises(ValueError, match=r"lightness\(method='blake1985'\): unknown option\(s\) anchors; "
                                         r"blake1985 accepts threshold, anchor, mean_lightness, mask, edge_rule, "
                                         r"edge_illumination, min_value, brightest_percentile, solver$"):
        estimate_lightness(image, anchors="mean")


def test_forwarded_options_change_the_result(image):
    r0, _ = estimate_lightness(image)
    for opts in ({"anchor": "mean"}, {"edge_rule": "component", "threshold": 0.02},
                 {"edge_illumination": "subtract"}):
        r, _ = estimate_lightness(image, **opts)
        assert not np.array_equal(r, r0), opts
        np.testing.assert_array_equal(r, lightness_blake1985(image, **opts)[0])
