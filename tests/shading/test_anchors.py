"""Closed-form anchors of the interreflection model: the concave spherical cap and the V groove."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.radiosity.concave_cap import (
    cap_form_factor,
    cap_lit,
    cap_mean_direct,
    cap_photometric_stereo,
    cap_photometric_stereo_bias,
    cap_radiosity,
    cap_recovered_normals,
    cap_shadow_free,
    spherical_cap_patches,
)
from pbrbench.radiosity.groove_profile import groove_lit_fraction, groove_profile, groove_segments
from pbrbench.radiosity.solver import (
    direct_radiosity,
    form_factor_matrix,
    patches_from_spec,
    solve_radiosity,
)
from pbrbench.scene.spec import Directional, SceneSpec
from pbrbench.shading import surfaces
from pbrbench.shading.form_factors import strip_form_factors_2d


def toward(gamma_deg, azimuth=0.7):
    g = np.radians(gamma_deg)
    return np.array([np.sin(g) * np.cos(azimuth), np.sin(g) * np.sin(azimuth), np.cos(g)])


# ----------------------------------------------------------------------- the surface
def test_spherical_cap_surface():
    assert "spherical_cap" in surfaces.SURFACES
    R, a = 0.8, 50.0
    x, y = np.meshgrid(np.linspace(-0.7, 0.7, 141), np.linspace(-0.7, 0.7, 141))
    s = surfaces.evaluate("spherical_cap", x, y, radius=R, half_angle_deg=a, center=(0.05, -0.02))
    r = np.hypot(x - 0.05, y + 0.02)
    np.testing.assert_array_equal(s.mask, r < R * np.sin(np.radians(a)))
    c = np.array([0.05, -0.02, R * np.cos(np.radians(a))])
    p = np.stack([x, y, s.z], -1)[s.mask]
    np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), R, rtol=1e-12)  # on the sphere
    np.testing.assert_allclose(s.normals[s.mask], (c - p) / R, atol=1e-12)  # facing the centre
    assert s.z[s.mask].min() >= -R * (1 - np.cos(np.radians(a))) and s.z[s.mask].max() < 1e-2  # rim at z = 0
    h = x[0, 1] - x[0, 0]
    gy, gx = np.gradient(s.z, h)
    inner = s.mask & (r < 0.9 * R * np.sin(np.radians(a)))
    inner[[0, -1], :] = inner[:, [0, -1]] = False
    np.testing.assert_allclose(gx[inner], s.fx[inner], atol=2e-3)
    np.testing.assert_allclose(gy[inner], s.fy[inner], atol=2e-3)
    cup = surfaces.evaluate("cup", x, y, radius=R)
    hemi = surfaces.evaluate("spherical_cap", x, y, radius=R, half_angle_deg=90)
    np.testing.assert_allclose(hemi.z, cup.z, atol=1e-12)
    with pytest.raises(ValueError, match="half_angle_deg"):
        surfaces.evaluate("spherical_cap", x, y, half_angle_deg=120)


# ---------------------------------------------------------------------------- the cap
def test_cap_closed_forms_agree_with_each_other():
    for rho, a in ((0.3, 30), (0.9, 60), (0.6, 85)):
        f = cap_form_factor(a)
        assert f == pytest.approx((1 - np.cos(np.radians(a))) / 2)
        S = toward(0.5 * (90 - a))
        assert cap_shadow_free(S, a)
        beta = cap_photometric_stereo_bias(rho, a)
        # B - rho E0 N.S = rho E0 beta a.S, with B from the f / E-bar form
        th, ph = np.meshgrid(np.linspace(0, np.radians(a), 7), np.linspace(0, 6, 9))
        u = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), -np.cos(th)], -1)
        c = np.array([0, 0, np.cos(np.radians(a))])
        B = cap_radiosity(u + c, rho=rho, half_angle_deg=a, direction=S, irradiance=2.0)
        np.testing.assert_allclose(B - rho * 2.0 * ((-u) @ S), rho * 2.0 * beta * S[2], rtol=1e-12)
    # the mean of the shadowed direct term is continuous at the shadow-free limit
    lim = cap_mean_direct(0.5, 40, toward(50.0))
    assert cap_mean_direct(0.5, 40, toward(50.05), n=800) == pytest.approx(lim, rel=2e-3)


def test_cap_lit_region():
    a = 60.0
    th, ph = np.meshgrid(np.linspace(0, np.radians(a), 30), np.linspace(0, 2 * np.pi, 60))
    u = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), -np.cos(th)], -1)
    pts = u + [0, 0, np.cos(np.radians(a))]
    assert cap_lit(pts, toward(29.0), half_angle_deg=a).all()
    lit = cap_lit(pts, toward(45.0), half_angle_deg=a)
    assert 0 < lit.mean() < 1
    # a cast-shadowed point: the ray toward the source meets the cap again
    k = np.flatnonzero(~lit.ravel() & ((-u.reshape(-1, 3)) @ toward(45.0) > 0.05))[0]
    x, s = pts.reshape(-1, 3)[k], toward(45.0)
    t = 2 * ((-u.reshape(-1, 3)[k]) @ s)
    assert (x + t * s)[2] < 0  # the second intersection is below the rim: on the cap


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
@pytest.mark.parametrize("rho,alpha", [(0.3, 30.0), (0.9, 60.0), (0.6, 85.0)])
def test_cap_interreflection_is_uniform_and_matches_the_closed_form(rho, alpha):
    S = toward(0.5 * (90 - alpha))
    f = cap_form_factor(alpha)
    want = rho * f * cap_mean_direct(rho, alpha, S) / (1 - rho * f)
    errs = []
    for n in (5, 10):
        p = spherical_cap_patches(1.0, alpha, n_rings=n, albedo=rho)
        F = form_factor_matrix(p, visibility=False)  # inside a sphere nothing is hidden
        E = rho * np.maximum(p.normals @ S, 0.0)
        B = solve_radiosity(F, rho, E, method="direct").B
        errs.append(np.abs((B - E) / want - 1).max())
    assert errs[1] < 0.012 and errs[1] < errs[0] / 2.5  # inscribed facets: the kernel is constant to O(h^2)


def test_cap_visibility_finds_no_false_occlusion():
    p = spherical_cap_patches(1.0, 70.0, n_rings=4)
    np.testing.assert_array_equal(form_factor_matrix(p), form_factor_matrix(p, visibility=False))


@pytest.mark.slow
def test_cap_with_cast_shadows():
    """A source beyond the shadow-free limit: shadow rays in the direct term, still a uniform interreflection."""
    rho, a, S = 0.6, 60.0, toward(50.0)
    assert not cap_shadow_free(S, a)
    f = cap_form_factor(a)
    want = rho * f * cap_mean_direct(rho, a, S) / (1 - rho * f)
    errs = []
    for n in (5, 10):
        p = spherical_cap_patches(1.0, a, n_rings=n, albedo=rho)
        E = direct_radiosity(None, p, lights=[Directional(type="directional", direction=tuple(S))], order=4)[:, 0]
        assert (E == 0).any() and (E > 0).any()
        B = solve_radiosity(form_factor_matrix(p, visibility=False), rho, E, method="direct").B
        errs.append(np.abs((B - E) / want - 1).max())
    assert errs[1] < 0.03 and errs[1] < 0.6 * errs[0]  # shadow edges cut patches: first order


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
def test_photometric_stereo_on_the_cap_recovers_the_biased_normals():
    rho, a = 0.9, 60.0
    p = spherical_cap_patches(1.0, a, n_rings=10, albedo=rho)
    F = form_factor_matrix(p, visibility=False)
    L = np.array([toward(25.0, az) for az in (0.3, 2.4, 4.5)])
    B = np.stack([solve_radiosity(F, rho, rho * np.maximum(p.normals @ s, 0), method="direct").B for s in L], 1)
    g = np.linalg.solve(L, B.T).T
    n_hat = g / np.linalg.norm(g, axis=1, keepdims=True)
    want, inflation = cap_recovered_normals(p.normals, rho, a)
    err = np.degrees(np.arccos(np.clip(np.sum(n_hat * want, 1), -1, 1)))
    bias = np.degrees(np.arccos(np.clip(np.sum(n_hat * p.normals, 1), -1, 1)))
    assert err.max() < 0.3 and bias.max() > 8.0
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), rho * inflation, rtol=2e-3)
    x, y = surfaces.pixel_grid(32, 32, 1.0)
    N, Nh, alb, m = cap_photometric_stereo(x, y, rho=rho, half_angle_deg=a)
    assert np.all(Nh[m, 2] >= N[m, 2]) and np.all(alb[m] >= rho) and np.all(alb[~m] == 0)


@pytest.mark.slow
def test_the_rendered_heightfield_cap_converges_at_first_order():
    """The Mitsuba mesh of the cap drops the cells cut by the rim: its error is O(h) (half per halving)."""
    S = toward(15.0)
    want = 0.8 * cap_form_factor(60) * cap_mean_direct(0.8, 60, S) / (1 - 0.8 * cap_form_factor(60))
    errs = []
    for cells in (12, 24):
        spec = SceneSpec(name="c", description="c", lights=[{"type": "directional", "direction": S.tolist()}],
                         shapes=[{"type": "heightfield", "surface": "spherical_cap", "half_width": 1.0,
                                  "params": {"radius": 0.9, "half_angle_deg": 60},
                                  "material": {"type": "diffuse", "albedo": 0.8}}])
        p = patches_from_spec(spec, heightfield_cells=cells)
        E = direct_radiosity(spec, p, shadows=False)[:, 0]
        B = solve_radiosity(form_factor_matrix(p, visibility=False), 0.8, E, method="direct").B
        errs.append(np.median(np.abs((B - E) / want - 1)))
    assert errs[1] < 0.6 * errs[0]


# ------------------------------------------------------------------------- the groove
def test_groove_local_model():
    g = groove_profile(0.5, (0, 1), n=16)
    np.testing.assert_allclose(g.E, 0.5 * np.cos(np.pi / 4))  # bisector: a constant
    step = groove_profile(0.5, (-1, 1), n=16)  # parallel to the left face
    np.testing.assert_allclose(step.E[step.face == 0], 0.0, atol=1e-15)
    np.testing.assert_allclose(step.E[step.face == 1], 0.5)
    black = groove_profile(0.0, (-1, 1), n=16)
    np.testing.assert_array_equal(black.B, black.E)


def test_groove_reflex_at_the_crease():
    g = groove_profile(0.7, (0, 1), n=32)
    left = g.B[g.face == 0]
    assert np.all(np.diff(left) > 0)  # rising toward the crease: the roof
    np.testing.assert_allclose(g.B, g.B[::-1], rtol=1e-12)  # symmetric about the bisector
    assert left[-1] > 1.3 * left[0] and np.all(g.B > g.E)
    step = groove_profile(0.7, (-1, 1), n=32)
    dark = step.B[step.face == 0]
    assert np.all(np.diff(dark) > 0) and dark[0] > 0  # the dark face lit by the other one, most at the crease


def test_groove_2d_profile_converges():
    def quarters(n):
        g = groove_profile(0.7, (-1, 1), n=n)
        return g.B.reshape(8, -1).mean(axis=1)  # means over quarters of each face

    q = [quarters(n) for n in (16, 32, 64)]
    d1, d2 = np.abs(q[1] - q[0]).max(), np.abs(q[2] - q[1]).max()
    assert d2 < 0.6 * d1 and d2 < 2e-3


@pytest.mark.slow
def test_groove_3d_long_faces_approach_the_2d_kernel():
    ref = groove_profile(0.7, (0, 1), n=16)
    errs = [np.abs(groove_profile(0.7, (0, 1), n=16, method="3d", length=L).B - ref.B).max() / ref.B.max()
            for L in (2.0, 8.0)]
    assert errs[1] < 3e-3 and errs[1] < errs[0] / 10  # the missing ends: O((w / L)^2..3)


def test_groove_strip_factors_add_up():
    segs, normals, s = groove_segments(8)
    F = strip_form_factors_2d(segs, segs)
    right_face = np.array([[[0.0, 0.0], segs[-1, 1]]])
    np.testing.assert_allclose(F[:8, 8:].sum(1), strip_form_factors_2d(segs[:8], right_face)[:, 0], rtol=1e-12)
    # a strip of a right-angled groove sees sum F = (1 + u - sqrt(1 + u^2)) ... check the crease strip by crossed strings
    a = segs[7]
    L = np.linalg.norm(a[1] - a[0])
    w = np.linalg.norm(segs[-1, 1])
    want = (L + w - np.hypot(L, w)) / (2 * L)
    assert F[7, 8:].sum() == pytest.approx(want, rel=1e-12)


def test_groove_shadow_boundary():
    S = np.array([-1.5, 1.0])
    s = np.linspace(0.005, 0.995, 100)
    lit = groove_lit_fraction(s, S)
    # brute force: does the ray from the right-face point toward S cross the left face segment?
    uR, uL = np.array([1, 1]) / np.sqrt(2), np.array([-1, 1]) / np.sqrt(2)
    Sn = S / np.linalg.norm(S)
    brute = []
    for t in s:
        p = t * uR
        A = np.array([Sn, -uL]).T
        k, m = np.linalg.solve(A, -p)  # p + k S = m uL
        brute.append(not (k > 0 and 0 <= m <= 1))
    np.testing.assert_array_equal(lit > 0.5, brute)
    assert np.all(groove_lit_fraction(-s, S) == 0)  # the left face is back-lit
