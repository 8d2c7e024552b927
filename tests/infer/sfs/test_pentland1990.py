"""Tests of Pentland's (1990) linear shape from shading (``pbrbench.infer.sfs.pentland1990``)."""

import numpy as np
import pytest

from pbrbench.infer.sfs import shape_from_shading, shape_from_shading_pentland1990
from pbrbench.metrics.sfs import normal_angle
from pbrbench.shading.lambert import lambertian_images
from tests.infer.sfs._scenes import FRONTAL, OBLIQUE, flat_angle, scene


def test_pentland_frontal_light_warns_and_returns_flat():
    s, img, h = scene("sphere", 48, FRONTAL)
    with pytest.warns(RuntimeWarning, match="pentland1990"):
        r = shape_from_shading(img, FRONTAL, method="pentland1990", albedo=0.8, mask=s.mask)
    assert not r.converged
    assert np.all(r.height == 0)


def test_pentland_regularisation_is_scale_free():
    # eps is relative to the grid's lowest frequency: the sphere's shape is recovered in part
    # (with eps ~ pi^2 it came out flat: 44.4 vs 45 deg), and a light 0.006 deg from the view
    # gives a near-flat surface instead of huge heights
    s, img, h = scene("sphere", 96, OBLIQUE)
    r = shape_from_shading(img, OBLIQUE, method="pentland1990", albedo=0.8, mask=s.mask, pixel_size=h)
    assert normal_angle(r.normals, s.normals, s.mask) < 0.6 * flat_angle(s)
    near = np.array([1e-4, 0.0, 1.0]) / np.hypot(1e-4, 1.0)
    img_f = lambertian_images(s.normals, 0.8, FRONTAL[None])[0]
    r = shape_from_shading(img_f, near, method="pentland1990", albedo=0.8, mask=s.mask, pixel_size=h)
    assert np.abs(r.height).max() < 0.1
    assert normal_angle(r.normals, s.normals, s.mask) < flat_angle(s) + 1.0


def test_linear_model_inverts_a_plane_wave_made_with_it():
    # E - S_z = -S_x f_x - S_y f_y is linear in f: an image made with that model (full frame,
    # unclipped) is inverted back to the height.  The image uses central differences, whose
    # response to sin(k x) is sin(k)/k = 0.975 of the derivative at k = 2 pi 4/64, so the
    # height comes back ~2.5 % small: the bound leaves room for that and the regularisation
    n = 64
    x = np.arange(n)
    f = 0.5 * np.sin(2 * np.pi * 4 * x / n)[None, :] * np.ones((n, 1))  # heights in pixels
    e = OBLIQUE[2] - OBLIQUE[0] * np.gradient(f, axis=1)
    r = shape_from_shading_pentland1990(e, OBLIQUE, albedo=1.0)
    inner = (slice(None), slice(8, -8))  # away from the zero padding's edges
    d = (r.height - f)[inner]
    d -= d.mean()
    assert np.sqrt(np.mean(d ** 2)) < 0.05 * np.sqrt(np.mean(f[inner] ** 2))
    assert r.method == "pentland1990" and r.n_iter == 0 and r.converged


def test_option_errors():
    with pytest.raises(ValueError, match="regularization"):
        shape_from_shading_pentland1990(np.full((16, 16), 0.5), [0.3, 0.0, 1.0], regularization=0.0)
