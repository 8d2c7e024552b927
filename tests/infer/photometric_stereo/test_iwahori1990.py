"""Near-light photometric stereo (pbrbench.infer.photometric_stereo.iwahori1990) on Lambertian
spheres and planes lit by point sources, images synthesised here by the inverse-square law."""

import numpy as np
import pytest

from pbrbench.checks import call_method
from pbrbench.infer.photometric_stereo import (
    PhotometricStereoResult,
    photometric_stereo_woodham1980,
)
from pbrbench.infer.photometric_stereo.iwahori1990 import (
    NearLightResult,
    photometric_stereo_iwahori1990,
)
from pbrbench.shading.surfaces import pixel_grid
from tests.infer.photometric_stereo._data import CHAPTER_LIGHTS, ang

SIZE, HALF = 96, 1.0
PS = 2 * HALF / SIZE


def point_lit(x, y, z, normals, albedo, positions, intensities=None):
    """I_k = rho E_k max(0, N . (P_k - X)) / |P_k - X|^3 (zero outside the normals' support)."""
    d = positions[:, None, None, :] - np.stack([x, y, z], axis=-1)[None]
    r = np.linalg.norm(d, axis=-1)
    e = np.ones(len(positions)) if intensities is None else np.asarray(intensities, float)
    return (np.asarray(albedo) * e[:, None, None] * np.maximum(np.einsum("khwi,hwi->khw", d, normals), 0.0)
            / r ** 3)


@pytest.fixture(scope="module")
def sphere():
    """Unit sphere at the origin, seen inside radius 0.8 (slopes up to 53 degrees)."""
    x, y = pixel_grid(SIZE, SIZE, HALF)
    m = x ** 2 + y ** 2 < 0.8 ** 2
    z = np.where(m, np.sqrt(np.maximum(1.0 - x ** 2 - y ** 2, 0.0)), 0.0)
    n = np.where(m[..., None], np.stack([x, y, z], axis=-1), 0.0)
    return x, y, z, n, m


def woodham_from_centre(imgs, positions, centre, mask, intensities=None):
    """Woodham given only the directions (and inverse-square irradiance) from the object centre."""
    d = positions - centre
    r = np.linalg.norm(d, axis=1)
    e = np.ones(len(positions)) if intensities is None else np.asarray(intensities, float)
    return photometric_stereo_woodham1980(imgs, d / r[:, None], mask=mask, intensities=e / r ** 2)


def test_sphere_sources_at_two_and_a_half_radii_far_below_woodham(sphere):
    x, y, z, n, m = sphere
    pos = 2.5 * CHAPTER_LIGHTS
    e = np.array([1.0, 0.8, 1.2, 1.0, 0.9])
    imgs = point_lit(x, y, z, n, 0.7, pos, e)
    lit = (np.einsum("khwi,hwi->khw", pos[:, None, None, :] - np.stack([x, y, z], -1)[None], n) > 0).sum(0)
    r = photometric_stereo_iwahori1990(imgs, pos, mask=m, intensities=e, pixel_size=PS, depth0=z[m].mean())
    assert isinstance(r, NearLightResult) and isinstance(r, PhotometricStereoResult)
    sel = m & (lit >= 3)
    assert r.converged and r.valid[sel].all()
    near = ang(r.normals, n)[sel]
    wood = ang(woodham_from_centre(imgs, pos, 0.0, m, e).normals, n)[sel]
    # measured: near 4e-4 deg mean, 3e-3 max (the integrator's O(h^2) height error); Woodham ~31 deg
    assert near.mean() < 0.01 and near.max() < 0.05
    assert wood.mean() > 10.0 and wood.mean() > 1000 * near.mean()
    assert np.abs(r.height - z)[sel].max() < 1e-3
    np.testing.assert_allclose(r.albedo[sel], 0.7, rtol=1e-3)


def test_offset_search_finds_a_wrong_depth(sphere):
    x, y, z, n, m = sphere
    pos = 2.5 * CHAPTER_LIGHTS
    imgs = point_lit(x, y, z, n, 0.5, pos)
    r = photometric_stereo_iwahori1990(imgs, pos, mask=m, pixel_size=PS, depth0=z[m].mean() + 0.3,
                                       offset="search")
    assert abs(r.offset + 0.3) < 1e-3
    assert np.abs(r.height - z)[r.valid].max() < 2e-3
    assert ang(r.normals, n)[r.valid].mean() < 0.01
    # without the search the wrong depth stays: the normals are then biased
    rf = photometric_stereo_iwahori1990(imgs, pos, mask=m, pixel_size=PS, depth0=z[m].mean() + 0.3)
    assert rf.offset == 0.0 and ang(rf.normals, n)[rf.valid].mean() > 1.0


def test_tilted_plane_near_sources_colour(sphere):
    x, y, _, _, _ = sphere
    m = np.ones_like(x, dtype=bool)
    fx, fy, z0 = 0.3, -0.2, 0.5
    z = z0 + fx * x + fy * y
    n = np.broadcast_to(np.array([-fx, -fy, 1.0]) / np.sqrt(1 + fx ** 2 + fy ** 2), x.shape + (3,)).copy()
    pos = 3.0 * CHAPTER_LIGHTS + [0.0, 0.0, z0]    # three half-widths from the plane's centre
    alb = np.array([0.9, 0.5, 0.2])
    imgs = point_lit(x, y, z, n, 1.0, pos)[..., None] * alb
    r = photometric_stereo_iwahori1990(imgs, pos, mask=m, pixel_size=PS, depth0=z0)
    assert r.albedo.shape == m.shape + (3,) and r.valid.all()
    assert ang(r.normals, n).max() < 1e-6            # a plane integrates exactly
    np.testing.assert_allclose(r.height, z, atol=1e-9)
    np.testing.assert_allclose(r.albedo, np.broadcast_to(alb, r.albedo.shape), rtol=1e-8)
    wood = ang(woodham_from_centre(imgs, pos, np.array([0.0, 0.0, z0]), m).normals, n)
    assert wood.mean() > 5.0


@pytest.mark.parametrize("distance", [1e3, 1e5])
def test_distant_sources_agree_with_woodham(sphere, distance):
    x, y, z, n, m = sphere
    d = CHAPTER_LIGHTS
    pos = distance * d
    imgs = point_lit(x, y, z, n, 0.6, pos) * distance ** 2
    imgs = imgs + 0.01 * np.random.default_rng(5).standard_normal(imgs.shape)   # the agreement is not exactness
    imgs[:, ~m] = 0.0
    r = photometric_stereo_iwahori1990(imgs, pos, mask=m, intensities=np.full(5, distance ** 2), pixel_size=PS,
                                       depth0=z[m].mean(), shadow_threshold=0.0)
    w = photometric_stereo_woodham1980(imgs, d, mask=m, shadow_threshold=0.0)
    v = r.valid & w.valid
    assert v.sum() > 0.95 * m.sum()
    # the source directions differ by ~ |X| / distance radians over the object
    assert ang(r.normals, w.normals)[v].max() < 3 * np.degrees(1.0 / distance)
    np.testing.assert_allclose(r.albedo[v], w.albedo[v], rtol=10 / distance)


def test_failure_modes(sphere):
    x, y, z, n, m = sphere
    pos = 2.5 * CHAPTER_LIGHTS
    imgs = point_lit(x, y, z, n, 0.7, pos)
    kw = dict(mask=m, pixel_size=PS, depth0=0.7)
    with pytest.raises(ValueError, match=r"lights: expected shape \(5, 3\) \(one source position"):
        photometric_stereo_iwahori1990(imgs, pos[:4], **kw)
    flat = pos.copy()
    flat[:, 1] = 0.0
    flat[:, 2] = 0.7      # every source in one plane through the surface's centre
    with pytest.raises(ValueError, match="degenerate.*coplanar"):
        photometric_stereo_iwahori1990(imgs, flat, **kw)
    on = pos.copy()
    on[2] = [x[48, 48], y[48, 48], 0.7]   # at a pixel of the plane z = depth0
    with pytest.raises(ValueError, match=r"lights: source\(s\) \[2\] lie on the surface"):
        photometric_stereo_iwahori1990(imgs, on, mask=np.ones_like(m), pixel_size=PS, depth0=0.7)
    with pytest.raises(ValueError, match="pixel_size"):
        photometric_stereo_iwahori1990(imgs, pos, mask=m, pixel_size=0.0, depth0=0.7)
    with pytest.raises(ValueError, match="depth0: shape"):
        photometric_stereo_iwahori1990(imgs, pos, mask=m, pixel_size=PS, depth0=np.zeros((3, 3)))
    bad = np.full(m.shape, 0.7)
    bad[48, 48] = np.nan
    with pytest.raises(ValueError, match="depth0: 1 non-finite"):
        photometric_stereo_iwahori1990(imgs, pos, mask=m, pixel_size=PS, depth0=bad)
    with pytest.raises(ValueError, match="offset='median' is not known"):
        photometric_stereo_iwahori1990(imgs, pos, offset="median", **kw)
    with pytest.raises(ValueError, match=r"intensities: every intensity must be > 0"):
        photometric_stereo_iwahori1990(imgs, pos, intensities=[1, 1, 0, 1, 1], **kw)
    with pytest.raises(TypeError):   # pixel grid and depth are required: no silent far-light fallback
        photometric_stereo_iwahori1990(imgs, pos, mask=m)
    # through the dispatcher (the METHODS convention): a misspelt option is refused by name
    with pytest.raises(ValueError, match="unknown option.*depth_0"):
        call_method({"iwahori1990": photometric_stereo_iwahori1990}, "iwahori1990", "photometric_stereo",
                    imgs, pos, mask=m, pixel_size=PS, depth_0=0.7)
