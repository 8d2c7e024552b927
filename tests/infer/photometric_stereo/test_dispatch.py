"""The photometric-stereo dispatcher and METHODS table (pbrbench.infer.photometric_stereo)."""

import numpy as np
import pytest

import pbrbench.infer.photometric_stereo as ps
from pbrbench.infer.photometric_stereo import (
    METHODS,
    photometric_stereo_woodham1980,
    solve_photometric_stereo,
)
from pbrbench.shading.lambert import blinn_phong_highlights, lambertian_images, ring_lights
from pbrbench.shading.surfaces import on_grid


@pytest.fixture(scope="module")
def glossy():
    s = on_grid("sphere", 40, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.8, lights, mask=s.mask)
    imgs = imgs + blinn_phong_highlights(s.normals, lights, 100.0, mask=s.mask)
    return imgs, lights, s.mask


def test_table():
    # derived from the table: a new method needs no edit here
    assert METHODS["woodham1980"] is photometric_stereo_woodham1980
    for name, fn in METHODS.items():
        assert fn.__module__.startswith("pbrbench.infer.photometric_stereo."), (name, fn.__module__)
        assert fn.__name__ in ps.__all__ and getattr(ps, fn.__name__) is fn
        assert f'``"{name}"``: :func:`{fn.__name__}`' in solve_photometric_stereo.__doc__
        assert "References" in fn.__doc__ and ".. math::" in fn.__doc__ and "%(" not in fn.__doc__, name


def _extra(name, imgs) -> dict:
    """The options a method requires beyond (images, lights, mask): near-light photometric stereo's
    pixel size and depth (sources 30 image widths away: the distant case)."""
    import inspect

    need = [p.name for p in inspect.signature(METHODS[name]).parameters.values()
            if p.kind is p.KEYWORD_ONLY and p.default is p.empty]
    return {"pixel_size": 2.0 / imgs.shape[-1], "depth0": 0.0} if need else {}


@pytest.mark.parametrize("name", list(METHODS))
def test_dispatch_equals_the_method(glossy, name):
    imgs, lights, mask = glossy
    kw = _extra(name, imgs)
    if kw:   # its lights are source positions: put the distant sources far away along the directions
        lights = 60.0 * lights / np.linalg.norm(lights, axis=1, keepdims=True)
    a = solve_photometric_stereo(imgs, lights, mask=mask, method=name, **kw)
    b = METHODS[name](imgs, lights, mask=mask, **kw)
    for f in ("normals", "albedo", "residual", "n_used", "valid"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    if name == "woodham1980":
        np.testing.assert_array_equal(solve_photometric_stereo(imgs, lights, mask=mask).normals, a.normals)


def test_unknown_method(glossy):
    imgs, lights, _ = glossy
    with pytest.raises(ValueError, match="method='svd' is not known; choose one of 'woodham1980', 'ikehata2012_l1'"):
        solve_photometric_stereo(imgs, lights, method="svd")


def test_option_the_method_does_not_accept(glossy):
    imgs, lights, _ = glossy
    with pytest.raises(ValueError, match=r"photometric_stereo\(method='woodham1980'\): unknown option\(s\) max_iter; "
                                         r"woodham1980 accepts mask, intensities, shadow_threshold, saturation, "
                                         r"min_lights, used$"):
        solve_photometric_stereo(imgs, lights, max_iter=10)
    with pytest.raises(ValueError, match=r"unknown option\(s\) shadow; ikehata2012_l1 accepts .*max_iter"):
        solve_photometric_stereo(imgs, lights, method="ikehata2012_l1", shadow=0.1)


def test_forwarded_option_changes_the_result(glossy):
    imgs, lights, mask = glossy
    a = solve_photometric_stereo(imgs, lights, mask=mask, method="ikehata2012_l1")
    b = solve_photometric_stereo(imgs, lights, mask=mask, method="ikehata2012_l1", max_iter=1)
    assert not np.array_equal(a.normals, b.normals)
    c = solve_photometric_stereo(imgs, lights, mask=mask, shadow_threshold=0.3)
    assert (c.n_used[mask] <= solve_photometric_stereo(imgs, lights, mask=mask).n_used[mask]).all()
    assert not np.array_equal(c.normals, solve_photometric_stereo(imgs, lights, mask=mask).normals)
