"""Tests of the shape-from-shading dispatchers (``pbrbench.infer.sfs``) on analytic Lambertian
images (exact shapes known)."""

import numpy as np
import pytest

from pbrbench.infer.sfs import (
    LIGHT_METHODS,
    METHODS,
    SFSResult,
    light_from_shading,
    light_from_shading_contour,
    shape_from_shading,
    shape_from_shading_pentland1990,
)
from pbrbench.metrics.sfs import normal_angle
from tests.infer.sfs._scenes import OBLIQUE, flat_angle, scene


def test_methods_tables_name_the_papers():
    assert list(METHODS) == ["horn1989", "tsai_shah1994", "pentland1990", "kimmel2001", "zheng_chellappa1991"]
    assert list(LIGHT_METHODS) == ["contour", "lee_rosenfeld1985", "zheng_chellappa1991"]
    assert all(fn.__name__ == f"shape_from_shading_{k}" for k, fn in METHODS.items())
    assert all(fn.__name__ == f"light_from_shading_{k}" for k, fn in LIGHT_METHODS.items())


@pytest.mark.parametrize("surface", ["sphere", "vase"])
@pytest.mark.parametrize("method", METHODS)
def test_every_method_beats_flat_on_oblique_light(method, surface):
    s, img, h = scene(surface, 64, OBLIQUE)
    r = shape_from_shading(img, OBLIQUE, method=method, albedo=0.8, mask=s.mask, pixel_size=h,
                           **({"max_iter": 100} if method == "horn1989" else {}))
    assert isinstance(r, SFSResult)
    assert np.all(np.isfinite(r.height)) and np.all(np.isfinite(r.normals))
    assert np.all(r.height[~s.mask] == 0)
    assert abs(r.height[s.mask].mean()) < 1e-9
    assert normal_angle(r.normals, s.normals, s.mask) < flat_angle(s)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"method": "nope"}, "method"),
        ({"light": [0, 0, -1]}, "light"),
        ({"light": [0, 0]}, "light"),
        ({"light": [0, 0, 0]}, "light"),
        ({"albedo": -1.0}, "albedo"),
        ({"pixel_size": 0.0}, "pixel_size"),
        ({"mask": np.zeros((16, 16), bool)}, "mask"),
        ({"mask": np.ones((8, 8), bool)}, "mask"),
        ({"max_iter": 0}, "max_iter"),
        ({"boundary": "wrong"}, "boundary"),
        ({"seeds": "wrong"}, "seeds"),
        ({"seeds": "wrong", "method": "kimmel2001"}, "seeds"),
        ({"theta_max_deg": 95.0}, "theta_max_deg"),
        ({"image": -np.ones((16, 16))}, "image"),
        ({"image": np.full((16, 16), np.nan)}, "image"),
        ({"image": np.ones(16)}, "image"),
    ],
)
def test_value_errors(kwargs, match):
    args = {"image": np.full((16, 16), 0.5), "light": [0.3, 0.0, 1.0]}
    args.update(kwargs)
    image, light = args.pop("image"), args.pop("light")
    with pytest.raises(ValueError, match=match):
        shape_from_shading(image, light, **args)


def test_light_from_shading_value_errors():
    with pytest.raises(ValueError, match="method"):
        light_from_shading(np.ones((8, 8)), method="nope")
    with pytest.raises(ValueError, match="image"):
        light_from_shading(np.zeros((8, 8)))


def test_unknown_method_lists_the_methods():
    with pytest.raises(ValueError, match="method='fast_marching' is not known.*'kimmel2001'"):
        shape_from_shading(np.full((16, 16), 0.5), [0.3, 0.0, 1.0], method="fast_marching")
    with pytest.raises(ValueError, match="method='ransac' is not known.*'contour', 'lee_rosenfeld1985'"):
        light_from_shading(np.full((16, 16), 0.5), method="ransac")


def test_an_option_of_another_method_is_refused_with_the_methods_options():
    img = np.full((16, 16), 0.5)
    with pytest.raises(ValueError, match=r"shape_from_shading\(method='pentland1990'\): unknown option\(s\) "
                                         "max_iter; pentland1990 accepts albedo, mask, pixel_size, regularization"):
        shape_from_shading(img, [0.3, 0.0, 1.0], method="pentland1990", max_iter=5)
    with pytest.raises(ValueError, match="unknown option\\(s\\) damping, tol; kimmel2001 accepts albedo, mask, "
                                         "pixel_size, seeds, singular_delta, e_min$"):
        shape_from_shading(img, [0.3, 0.0, 1.0], method="kimmel2001", seeds="auto", tol=1.0, damping=1.0)
    with pytest.raises(ValueError, match="lee_rosenfeld1985 accepts mask$"):
        light_from_shading(img, method="lee_rosenfeld1985", seed=1)


def test_a_forwarded_option_changes_the_result():
    s, img, h = scene("sphere", 48, OBLIQUE)
    a = shape_from_shading(img, OBLIQUE, method="pentland1990", albedo=0.8, mask=s.mask, pixel_size=h)
    b = shape_from_shading(img, OBLIQUE, method="pentland1990", albedo=0.8, mask=s.mask, pixel_size=h,
                           regularization=10.0)
    direct = shape_from_shading_pentland1990(img, OBLIQUE, albedo=0.8, mask=s.mask, pixel_size=h,
                                             regularization=10.0)
    assert not np.allclose(a.height, b.height)
    assert np.array_equal(b.height, direct.height) and np.array_equal(b.normals, direct.normals)
    assert np.abs(b.height).max() < np.abs(a.height).max()  # more damping, flatter
    # the contour fit's RANSAC seed reaches the method: another seed, another (close) estimate
    noisy = np.where(s.mask, np.clip(img + 0.01 * np.random.default_rng(0).standard_normal(img.shape), 0, None), 0)
    e0 = light_from_shading(noisy, s.mask)
    e3 = light_from_shading(noisy, s.mask, seed=3)
    assert np.array_equal(e3.direction, light_from_shading_contour(noisy, s.mask, seed=3).direction)
    assert not np.array_equal(e0.direction, e3.direction)
