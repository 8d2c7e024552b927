"""Tests of the surface-integration dispatcher (``pbrbench.infer.integration``) on analytic surfaces."""

import numpy as np
import pytest

from pbrbench.infer.integration import METHODS, integrate_lsq, integrate_normals
from pbrbench.shading.surfaces import on_grid, pixel_grid
from tests.infer.integration._fields import HW, H, N, irregular_mask, rel_rmse


def test_rectangle_methods_are_far_worse_on_a_mask():
    s = on_grid("bumps", N, HW)
    m = irregular_mask(s)
    errs = {meth: rel_rmse(integrate_normals(s.normals, mask=m, method=meth, pixel_size=H), s.z, m)
            for meth in ("lsq", "path", "frankot1988", "simchony1990")}
    for meth in ("path", "frankot1988", "simchony1990"):
        assert errs[meth] > 10 * errs["lsq"], errs


@pytest.mark.parametrize("method", ["lsq", "path", "frankot1988", "simchony1990"])
def test_all_methods_accurate_on_periodic_surface_over_full_rectangle(method):
    x, y = pixel_grid(N, N, HW)  # the film spans 2 world units: period 2 is periodic on it
    z = 0.1 * np.sin(np.pi * x) * np.cos(np.pi * y) + 0.05 * np.sin(2 * np.pi * y)
    p = 0.1 * np.pi * np.cos(np.pi * x) * np.cos(np.pi * y)
    q = -0.1 * np.pi * np.sin(np.pi * x) * np.sin(np.pi * y) + 0.1 * np.pi * np.cos(2 * np.pi * y)
    est = integrate_normals(gradients=(p, q), method=method, pixel_size=H)
    # FC is spectrally exact here; the others carry the O(h^2) trapezoid error
    bound = 1e-10 if method == "frankot1988" else 2e-3
    assert rel_rmse(est, z, np.ones_like(z, bool)) < bound


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(), "normals/gradients"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], gradients=(np.zeros((4, 4)),) * 2), "normals/gradients"),
        (dict(normals=np.zeros((4, 4, 2))), "normals"),
        (dict(gradients=np.zeros((4, 4))), "gradients"),
        (dict(gradients=(np.zeros((4, 4)), np.zeros((4, 5)))), "gradients"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], method="poisson"), "method"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], pixel_size=0.0), "pixel_size"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, 1], mask=np.ones((3, 3), bool)), "mask"),
        (dict(normals=np.zeros((4, 4, 3)) + [0, 0, -1]), "mask"),
        (dict(gradients=(np.full((4, 4), np.nan), np.zeros((4, 4))), mask=np.ones((4, 4), bool)), "gradients"),
    ],
)
def test_integrate_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        integrate_normals(**kwargs)


def test_methods_table():
    assert list(METHODS) == ["lsq", "path", "frankot1988", "simchony1990"]
    assert all(fn.__name__ == f"integrate_{k}" for k, fn in METHODS.items())


def test_unknown_method_lists_the_methods():
    with pytest.raises(ValueError, match="method='dct' is not known.*'lsq', 'path', 'frankot1988', 'simchony1990'"):
        integrate_normals(np.zeros((4, 4, 3)) + [0, 0, 1], method="dct")


def test_an_option_of_another_method_is_refused_with_the_methods_options():
    with pytest.raises(ValueError, match=r"integrate_normals\(method='path'\): unknown option\(s\) tol; path "
                                         "accepts normals, gradients, mask, pixel_size$"):
        integrate_normals(np.zeros((4, 4, 3)) + [0, 0, 1], method="path", tol=1e-3)


def test_a_forwarded_option_changes_the_result():
    s = on_grid("bumps", N, HW)
    m = irregular_mask(s)
    default = integrate_normals(s.normals, mask=m, pixel_size=H)
    loose = integrate_normals(s.normals, mask=m, pixel_size=H, tol=1e-2)
    assert not np.array_equal(loose, default)
    assert np.array_equal(loose, integrate_lsq(s.normals, mask=m, pixel_size=H, tol=1e-2))
    assert np.array_equal(default, integrate_lsq(s.normals, mask=m, pixel_size=H))
