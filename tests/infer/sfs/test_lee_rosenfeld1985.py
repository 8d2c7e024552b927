"""Tests of Lee & Rosenfeld's (1985) light estimate from image statistics
(``pbrbench.infer.sfs.lee_rosenfeld1985``)."""

import numpy as np
import pytest

from pbrbench.infer.sfs import light_from_shading, light_from_shading_lee_rosenfeld1985
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid
from tests.infer.sfs._scenes import OBLIQUE, scene


def test_light_from_shading_statistics():
    for light in (OBLIQUE, np.array([-0.3, 0.4, 0.866])):
        light = light / np.linalg.norm(light)
        s, img, _ = scene("sphere", 128, light)
        lr = light_from_shading(img, s.mask, method="lee_rosenfeld1985")
        assert np.degrees(np.arccos(lr.direction @ light)) < 10.0
        assert lr.method == "lee_rosenfeld1985"


def test_a_plane_breaks_the_sphere_assumption():
    # every normal the same: <I>^2 / <I^2> = 1, above any sphere's ratio (8/9 at slant 0), so the
    # slant clamps to 0 and the estimate is the view direction whatever the light (45 deg off)
    pl = on_grid("plane", 32, 1.0)
    img = lambertian_images(pl.normals, 0.8, OBLIQUE[None])[0]
    est = light_from_shading_lee_rosenfeld1985(img)
    np.testing.assert_allclose(est.direction, [0.0, 0.0, 1.0], atol=1e-12)
    assert np.degrees(np.arccos(est.direction @ OBLIQUE)) == pytest.approx(45.0)


def test_image_errors():
    with pytest.raises(ValueError, match="negative"):
        light_from_shading_lee_rosenfeld1985(-np.ones((8, 8)))
    with pytest.raises(ValueError, match="mask"):
        light_from_shading_lee_rosenfeld1985(np.ones((8, 8)), np.ones((4, 4), bool))
