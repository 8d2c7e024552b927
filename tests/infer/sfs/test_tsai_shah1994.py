"""Tests of Tsai & Shah's (1994) linearisation, solved by damped Newton steps
(``pbrbench.infer.sfs.tsai_shah1994``)."""

import warnings

import numpy as np
import pytest

from pbrbench.infer.sfs import shape_from_shading, shape_from_shading_tsai_shah1994
from pbrbench.metrics.sfs import normal_angle
from tests.infer.sfs._scenes import OBLIQUE, flat_angle, scene


def test_iteration_budget_exhausted_warns_without_nan():
    s, img, h = scene("sphere", 48, OBLIQUE)
    # tsai_shah1994 stops at the budget or earlier (stalled): both warn, neither converges
    with pytest.warns(RuntimeWarning, match="tsai_shah1994"):
        r = shape_from_shading(img, OBLIQUE, method="tsai_shah1994", albedo=0.8, mask=s.mask, max_iter=2, tol=1e-12)
    assert not r.converged and 1 <= r.n_iter <= 2
    assert np.all(np.isfinite(r.height))


def test_tsai_shah_newton_steps_lower_the_brightness_residual():
    # the damped Newton iteration accepts a step only when sum (E - R)^2 decreases; when no
    # damped step does, it stops with a warning instead of oscillating (the per-pixel Jacobi
    # update of the paper oscillated with an RMS height update of ~0.06 px forever)
    s, img, h = scene("vase", 96, OBLIQUE)
    with pytest.warns(RuntimeWarning, match="tsai_shah1994: stopped after"):
        r = shape_from_shading(img, OBLIQUE, method="tsai_shah1994", albedo=0.8, mask=s.mask, pixel_size=h)
    assert r.info["stalled"] and not r.converged
    assert r.info["residual_rms"] < 0.5 * r.info["initial_residual_rms"]
    assert normal_angle(r.normals, s.normals, s.mask) < 0.7 * flat_angle(s)
    assert r.method == "tsai_shah1994"


def test_tsai_shah_mirror_symmetric_in_the_light():
    # the causal solve runs from the lit side: a mirrored image under the mirrored light gives
    # the mirrored height (light from the left used to be as bad as flat)
    s, img, h = scene("sphere", 64, OBLIQUE)
    left = OBLIQUE * np.array([-1.0, 1.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        a = shape_from_shading(img, OBLIQUE, method="tsai_shah1994", albedo=0.8, mask=s.mask, pixel_size=h)
        b = shape_from_shading(img[:, ::-1], left, method="tsai_shah1994", albedo=0.8, mask=s.mask[:, ::-1],
                               pixel_size=h)
    np.testing.assert_allclose(b.height[:, ::-1], a.height, atol=1e-9)
    assert normal_angle(b.normals[:, ::-1] * np.array([-1.0, 1.0, 1.0]), s.normals, s.mask) < 0.7 * flat_angle(s)


def test_tsai_shah_tiny_damping_stays_finite():
    # a tiny damping lets the diagonal of the Newton system approach 0; the line search keeps
    # the iterate finite and no worse than the start
    s, img, h = scene("sphere", 48, OBLIQUE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = shape_from_shading(img, OBLIQUE, method="tsai_shah1994", albedo=0.8, mask=s.mask, damping=1e-12)
    assert np.all(np.isfinite(r.height)) and np.all(np.isfinite(r.normals))
    assert r.info["residual_rms"] <= r.info["initial_residual_rms"]


@pytest.mark.parametrize(("kwargs", "match"), [({"max_iter": 0}, "max_iter"), ({"tol": -1.0}, "tol"),
                                               ({"damping": 0.0}, "damping")])
def test_option_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        shape_from_shading_tsai_shah1994(np.full((16, 16), 0.5), [0.3, 0.0, 1.0], **kwargs)
