"""Adam, the Sobolev (large-steps) preconditioner and the schedule (NumPy, analytic inputs)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from pbrbench.inverse.heightfield import HeightField
from pbrbench.inverse.optim import Adam, LargeSteps, schedule


@pytest.mark.parametrize("uniform", [None, "max", "rms"])
def test_adam_minimises_a_quadratic(uniform):
    rng = np.random.default_rng(0)
    a = np.array([1.0, 4.0, 0.25])
    target = np.array([0.5, -1.0, 2.0])
    x = rng.normal(size=3)
    opt = Adam(3, uniform=uniform)
    f0 = float(a @ (x - target) ** 2)
    for t in range(600):
        x = x + opt.step(2 * a * (x - target), schedule(t, 600, 0.1, 0.01))
    assert float(a @ (x - target) ** 2) < 1e-4 * f0


def test_adam_first_step_is_the_learning_rate_along_the_sign():
    """Bias correction: the first update is ``-lr * g / |g|`` per parameter."""
    g = np.array([3.0, -0.01, 7.0])
    step = Adam(3).step(g, 0.2)
    assert np.allclose(step, -0.2 * np.sign(g), rtol=1e-5)
    # uniform: one normalisation, the direction of g is kept
    s = Adam(3, uniform="max").step(g, 0.2)
    assert np.allclose(s / np.linalg.norm(s), -g / np.linalg.norm(g))
    assert np.abs(s).max() == pytest.approx(0.2, rel=1e-6)


def test_adam_rejects_an_unknown_normalisation():
    with pytest.raises(ValueError, match="uniform"):
        Adam(3, uniform="mean")


def test_large_steps_round_trip_and_smoothing():
    hf = HeightField(np.ones((12, 12), bool), half_width=1.0)
    L = hf.laplacian()
    pre = LargeSteps(L, 4.0)
    rng = np.random.default_rng(1)
    z = rng.normal(size=hf.n_params)
    assert np.allclose(pre.to_z(pre.to_u(z)), z)
    # a gradient along a Laplacian eigenvector is scaled by 1 / (1 + lambda * eigenvalue)
    w, v = np.linalg.eigh(L.toarray())
    low, high = v[:, 1], v[:, -1]
    assert np.allclose(pre.gradient_u(low), low / (1 + 4.0 * w[1]))
    assert np.allclose(pre.gradient_u(high), high / (1 + 4.0 * w[-1]))
    # the constant mode passes unchanged, the checkerboard is damped by more than 10x
    ones = np.ones(hf.n_params)
    assert np.allclose(pre.gradient_u(ones), ones)
    assert np.linalg.norm(pre.gradient_u(high)) < 0.1


def test_large_steps_with_zero_lambda_is_the_identity():
    pre = LargeSteps(sp.csr_matrix((5, 5)), 0.0)
    g = np.arange(5.0)
    assert np.allclose(pre.gradient_u(g), g)


def test_schedule_endpoints():
    assert schedule(0, 10, 2.0, 0.05) == pytest.approx(2.0)
    assert schedule(9, 10, 2.0, 0.05) == pytest.approx(0.1)
    assert schedule(0, 1, 2.0, 0.05) == 2.0
    vals = [schedule(t, 10, 1.0, 0.1) for t in range(10)]
    assert all(b < a for a, b in zip(vals, vals[1:], strict=False))
