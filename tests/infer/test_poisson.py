"""Tests of the shared least-squares gradient-field solver ``pbrbench.infer.poisson``."""

import numpy as np
import pytest

from pbrbench.infer.poisson import solve_gradient_field


def _dense_lstsq(gx, gy, mask, wx=None, wy=None):
    """Independent reference: build the equations one by one and call np.linalg.lstsq."""
    h, w = gx.shape
    wx = np.ones((h, w)) if wx is None else wx
    wy = np.ones((h, w)) if wy is None else wy
    rows, rhs = [], []
    for i in range(h):
        for j in range(w):
            if j + 1 < w and mask[i, j] and mask[i, j + 1] and wx[i, j] > 0:
                r = np.zeros(h * w)
                r[i * w + j + 1], r[i * w + j] = 1.0, -1.0
                s = np.sqrt(wx[i, j])
                rows.append(s * r)
                rhs.append(s * gx[i, j])
            if i + 1 < h and mask[i, j] and mask[i + 1, j] and wy[i, j] > 0:
                r = np.zeros(h * w)
                r[(i + 1) * w + j], r[i * w + j] = 1.0, -1.0
                s = np.sqrt(wy[i, j])
                rows.append(s * r)
                rhs.append(s * gy[i, j])
    u = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0].reshape(h, w)
    return u


def _blob_mask(h, w):
    yy, xx = np.mgrid[:h, :w]
    m = (yy - h / 2) ** 2 + (xx - w / 2.5) ** 2 < (0.35 * h) ** 2
    m |= (yy < 3) & (xx > w - 4)  # a second, separate component in the corner
    return m


def _zero_mean_per_component(u, mask):
    from scipy import ndimage

    lab, n = ndimage.label(mask)
    return all(abs(u[lab == k].mean()) < 1e-9 for k in range(1, n + 1))


def test_dct_matches_independent_lstsq_on_rectangle():
    rng = np.random.default_rng(1)
    gx, gy = rng.normal(size=(2, 9, 11))
    ref = _dense_lstsq(gx, gy, np.ones((9, 11), bool))
    ref -= ref.mean()
    u = solve_gradient_field(gx, gy, method="dct")
    np.testing.assert_allclose(u, ref, atol=1e-10)
    # auto picks dct here and gives the same answer
    np.testing.assert_allclose(solve_gradient_field(gx, gy), u, atol=1e-12)


@pytest.mark.parametrize("method", ["cg", "direct", "auto"])
def test_masked_weighted_matches_independent_lstsq(method):
    rng = np.random.default_rng(2)
    h, w = 11, 13
    gx, gy = rng.normal(size=(2, h, w))
    wx, wy = rng.uniform(0.2, 2.0, size=(2, h, w))
    wx[3, 4] = 0.0  # a dropped equation
    mask = _blob_mask(h, w)
    ref = _dense_lstsq(gx, gy, mask, wx, wy)
    u = solve_gradient_field(gx, gy, mask=mask, wx=wx, wy=wy, method=method, tol=1e-12)
    # the reference is defined up to one constant per component: compare differences
    from scipy import ndimage

    lab, n = ndimage.label(mask)
    assert n == 2
    for k in (1, 2):
        sel = lab == k
        d = (u - ref)[sel]
        np.testing.assert_allclose(d - d.mean(), 0.0, atol=1e-8)
    assert _zero_mean_per_component(u, mask)
    assert np.all(u[~mask] == 0.0)


@pytest.mark.parametrize("method", ["cg", "direct"])
def test_exact_recovery_of_known_function_on_mask(method):
    h, w = 60, 70
    yy, xx = np.mgrid[:h, :w].astype(float)
    truth = np.sin(xx / 7.0) * np.cos(yy / 9.0) + 0.01 * xx * yy
    gx = np.zeros((h, w))
    gy = np.zeros((h, w))
    gx[:, :-1] = np.diff(truth, axis=1)
    gy[:-1, :] = np.diff(truth, axis=0)
    mask = _blob_mask(h, w)
    u = solve_gradient_field(gx, gy, mask=mask, method=method, tol=1e-12)
    from scipy import ndimage

    lab, _ = ndimage.label(mask)
    for k in (1, 2):
        sel = lab == k
        np.testing.assert_allclose(u[sel], truth[sel] - truth[sel].mean(), atol=1e-8)


def test_zero_weight_removes_an_outlier_equation():
    h, w = 20, 20
    yy, xx = np.mgrid[:h, :w].astype(float)
    truth = 0.1 * xx**2 - 0.05 * yy
    gx = np.zeros((h, w))
    gy = np.zeros((h, w))
    gx[:, :-1] = np.diff(truth, axis=1)
    gy[:-1, :] = np.diff(truth, axis=0)
    gx[10, 10] += 50.0  # a corrupted measurement
    bad = solve_gradient_field(gx, gy, method="dct")
    assert np.abs(bad - (truth - truth.mean())).max() > 1.0  # the outlier spreads
    wx = np.ones((h, w))
    wx[10, 10] = 0.0
    good = solve_gradient_field(gx, gy, wx=wx, method="cg", tol=1e-12)
    np.testing.assert_allclose(good, truth - truth.mean(), atol=1e-8)


def test_non_integrable_field_gives_least_squares_not_exact_fit():
    """A pure curl field has no potential: the least-squares answer is (nearly) flat."""
    h, w = 32, 32
    psi = np.zeros((h + 1, w + 1))
    yy, xx = np.mgrid[: h + 1, : w + 1]
    psi[:] = np.sin(np.pi * yy / h) * np.sin(np.pi * xx / w)  # zero on the border
    # discrete curl of psi: divergence-free, tangential at the border -> orthogonal to gradients
    gx = psi[1:, 1:] - psi[:-1, 1:]
    gy = -(psi[1:, 1:] - psi[1:, :-1])
    u = solve_gradient_field(gx, gy, method="dct")
    u2 = solve_gradient_field(gx, gy, mask=np.ones((h, w), bool), wx=np.full((h, w), 1.0 + 1e-15),
                              method="cg")
    assert np.abs(u).max() < 0.05 * np.abs(gx).max()
    np.testing.assert_allclose(u2, u, atol=1e-6)


def test_isolated_pixels_and_tiny_shapes():
    mask = np.zeros((5, 5), bool)
    mask[0, 0] = mask[2, 2] = mask[4, 4] = True  # no equation touches any pixel
    u = solve_gradient_field(np.ones((5, 5)), np.ones((5, 5)), mask=mask)
    assert np.all(u == 0.0)
    g = np.arange(6.0).reshape(1, 6)
    for method in ("dct", "cg", "direct"):
        u = solve_gradient_field(g, g, method=method)
        np.testing.assert_allclose(np.diff(u[0]), g[0, :-1], atol=1e-8)
        assert abs(u.mean()) < 1e-12


def test_values_outside_mask_are_ignored_even_if_nan():
    h, w = 12, 12
    mask = _blob_mask(h, w)
    rng = np.random.default_rng(3)
    gx, gy = rng.normal(size=(2, h, w))
    ref = solve_gradient_field(gx, gy, mask=mask, method="direct")
    gx[~mask] = np.nan
    gy[~mask] = np.inf
    u = solve_gradient_field(gx, gy, mask=mask, method="direct")
    np.testing.assert_allclose(u, ref, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 5))), "gy"),
        (dict(gx=np.zeros((4, 4, 2)), gy=np.zeros((4, 4))), "gx"),
        (dict(gx=np.full((4, 4), np.nan), gy=np.zeros((4, 4))), "gx"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), wx=-np.ones((4, 4))), "wx"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), wy=np.ones((3, 4))), "wy"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), method="fft"), "method"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), mask=np.eye(4, dtype=bool), method="dct"), "dct"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), wx=2 * np.ones((4, 4)), method="dct"), "dct"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), mask=np.ones((3, 3), bool)), "mask"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), tol=0.0), "tol"),
        (dict(gx=np.zeros((4, 4)), gy=np.zeros((4, 4)), maxiter=0), "maxiter"),
    ],
)
def test_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        solve_gradient_field(**kwargs)


def test_amg_fallback_after_stalled_dct_pcg_gives_same_answer(monkeypatch):
    """Thin domains make the DCT-preconditioned phase stall; the AMG phase must finish the job."""
    import pbrbench.infer.poisson as poisson

    h, w = 40, 41
    yy, xx = np.mgrid[:h, :w].astype(float)
    comb = (xx % 4 == 0) | (yy < 2)  # one-pixel teeth joined at the top: a thin domain
    truth = np.cos(xx / 5.0) + 0.1 * yy**1.5
    gx = np.zeros((h, w))
    gy = np.zeros((h, w))
    gx[:, :-1] = np.diff(truth, axis=1)
    gy[:-1, :] = np.diff(truth, axis=0)
    fast = solve_gradient_field(gx, gy, mask=comb, method="cg", tol=1e-12)
    monkeypatch.setattr(poisson, "_DCT_PCG_MAXITER", 1)
    slow = solve_gradient_field(gx, gy, mask=comb, method="cg", tol=1e-12)
    ref = truth - truth[comb].mean()
    np.testing.assert_allclose(fast[comb], ref[comb], atol=1e-8)
    np.testing.assert_allclose(slow[comb], ref[comb], atol=1e-8)
