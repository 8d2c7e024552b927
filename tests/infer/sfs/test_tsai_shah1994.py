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


def _reference_tsai_shah(E, s, m, *, max_iter, tol, damping, init, mu_schedule=(0.0, 0.1, 0.3, 1.0, 3.0, 10.0),
                         n_halvings=8):
    """The same damped Newton iteration written plainly: every pixel an unknown, the Jacobian a
    SciPy sparse matrix and each step SciPy's sparse triangular solve."""
    import math

    from scipy.sparse import csr_matrix
    from scipy.sparse.linalg import spsolve_triangular

    from pbrbench.infer.sfs._common import _reflectance

    H, W = E.shape
    n = H * W
    ef, mf = E[::-1].ravel(), m[::-1].ravel()
    shadow = ef <= 0.0
    col, idx = np.tile(np.arange(W), H), np.arange(n)
    has_l = np.zeros(n, bool)
    has_l[1:] = mf[:-1] & (col[1:] > 0)
    has_b = np.zeros(n, bool)
    has_b[W:] = mf[:-W]
    has_l &= mf
    has_b &= mf
    z = np.zeros(n) if init is None else np.where(mf, np.asarray(init, float)[::-1].ravel(), 0.0)
    rows = np.concatenate([idx, idx[has_l], idx[has_b]])
    cols = np.concatenate([idx, idx[has_l] - 1, idx[has_b] - W])

    def residual(zv):
        zl, zb = np.zeros(n), np.zeros(n)
        zl[1:], zb[W:] = zv[:-1], zv[:-W]
        r, rp, rq = _reflectance(zv - np.where(has_l, zl, 0.0), zv - np.where(has_b, zb, 0.0), s)
        g = np.where(shadow & (r <= 0.0), 0.0, 1.0)
        return np.where(mf, np.where(shadow, -np.maximum(r, 0.0), ef - r), 0.0), rp * g, rq * g

    f, rp, rq = residual(z)
    cost, nm, steps, delta, converged = float(f @ f), max(int(mf.sum()), 1), 0, np.inf, False
    for _ in range(max_iter):
        d0 = -(rp + rq)
        sgn = np.where(d0 < 0, -1.0, 1.0)
        accepted = False
        for mu in mu_schedule:
            dg = d0 + mu * sgn
            dg = np.where(mf, np.where(np.abs(dg) < damping, damping * sgn, dg), 1.0)
            J = csr_matrix((np.concatenate([dg, rp[has_l], rq[has_b]]), (rows, cols)), shape=(n, n))
            d = np.where(mf, spsolve_triangular(J, -f, lower=True), 0.0)
            if not np.all(np.isfinite(d)):
                continue
            dmax = float(np.abs(d).max())
            a = min(1.0, max(H, W) / dmax) if dmax > 0 else 1.0
            for _ in range(n_halvings):
                zn = z + a * d
                fn, rpn, rqn = residual(zn)
                cn = float(fn @ fn)
                if np.isfinite(cn) and cn < cost * (1.0 - 1e-4 * a):
                    accepted = True
                    break
                a *= 0.5
            if accepted:
                break
        if not accepted:
            break
        steps += 1
        delta = a * math.sqrt(float(np.sum(d * d)) / nm)
        z, f, rp, rq, cost = zn, fn, rpn, rqn, cn
        if delta < tol:
            converged = True
            break
    return np.where(m, z.reshape(H, W)[::-1], 0.0), converged, steps


@pytest.mark.parametrize("shape", ["sphere", "vase"])
def test_the_substitution_gives_the_sparse_solvers_iterates(shape):
    # the iteration does not converge on such images, and a different rounding anywhere sends it
    # elsewhere (height differences of tens of pixels after 100 steps): the solve over the mask's
    # pixels by anti-diagonals must give the sparse solver's numbers bit for bit
    from pbrbench.infer.sfs.tsai_shah1994 import _tsai_shah

    s, img, _ = scene(shape, 40, OBLIQUE)
    img = np.where(s.mask, img + 0.02 * np.random.default_rng(3).standard_normal(img.shape), 0.0)
    light = np.array([abs(OBLIQUE[0]), 0.25, OBLIQUE[2]])
    light /= np.linalg.norm(light)
    kw = dict(max_iter=12, tol=1e-9, damping=1e-2, init=None)
    with np.errstate(all="ignore"):
        z, converged, steps, _ = _tsai_shah(img, light, s.mask, **kw)
        z_ref, converged_ref, steps_ref = _reference_tsai_shah(img, light, s.mask, **kw)
    assert steps == steps_ref and steps >= 3 and converged == converged_ref
    assert np.array_equal(z, z_ref)
