"""Colour retinex of Grosse et al. (2009) (pbrbench.infer.lightness.grosse2009)."""

import numpy as np
import pytest

from pbrbench.infer.lightness import (
    METHODS,
    estimate_lightness,
    lightness_blake1985,
    lightness_grosse2009,
    select_thresholds_hold_one_out,
)
from pbrbench.metrics.lightness import intrinsic_lmse
from pbrbench.shading.mondrian import colour_mondrian_scene


def two_papers(chroma=0.08):
    """Two iso-luminant papers (same mean log, chromaticity step of norm ~chroma * sqrt(2))
    under a smooth, slowly recolouring light."""
    h, w = 32, 64
    a = np.ones((h, w, 3)) * 0.5
    v = np.array([1.0, -1.0, 0.0]) * chroma
    a[:, w // 2:] *= np.exp(v)
    yy, xx = np.mgrid[0:h, 0:w]
    light = np.exp(0.01 * xx)[..., None] * np.stack([np.exp(0.002 * xx), np.ones((h, w)), np.exp(-0.002 * xx)], -1)
    return a, light


def test_known_answer_iso_luminant_step():
    a, light = two_papers()
    r, s = lightness_grosse2009(a * light, threshold=0.05, chromaticity_threshold=0.05, anchor="mean",
                                mean_lightness=float(a.mean()))
    # the step is recovered exactly (ratio of the two papers per channel), the light is shading
    ratio = r[:, -1] / r[:, 0]
    # (up to the light's change across the kept pixel pair, 1.2 % per pixel here)
    np.testing.assert_allclose(ratio, np.broadcast_to(np.exp([0.08, -0.08, 0.0]), ratio.shape), rtol=0.02)
    assert abs(np.log(ratio[0, 0]) - 0.08) < 0.013
    np.testing.assert_allclose(r * s, a * light, rtol=1e-12)
    # the luminance rule alone (chromaticity test off) sees no edge: flat reflectance
    r0, _ = lightness_grosse2009(a * light, threshold=0.05, chromaticity_threshold=np.inf)
    assert np.ptp(np.log(r0)) < 1e-9
    # and the RMS rule of blake1985 at the same threshold misses it too
    rb, _ = lightness_blake1985(a * light, threshold=0.07)
    assert np.ptp(np.log(rb)) < 1e-9


def test_grey_image_is_grey_retinex_with_the_component_rule():
    a, light = two_papers(0.0)
    g = (a * light).mean(-1) * np.where(np.arange(64) < 20, 1.0, 0.6)[None, :]
    r1, s1 = lightness_grosse2009(g, threshold=0.05)
    r2, s2 = lightness_blake1985(g, threshold=0.05, edge_rule="component")
    np.testing.assert_allclose(r1, r2, rtol=1e-10)
    assert r1.shape == g.shape


def test_beats_blake_colour_and_grey_mode_on_coloured_mondrians():
    scs = [colour_mondrian_scene(96, seed=s) for s in range(3)]

    def mean_lmse(fn):
        return np.mean([intrinsic_lmse(*fn(sc["image"]), sc["albedo"], sc["shading"], window=16) for sc in scs])

    ours = mean_lmse(lambda im: lightness_grosse2009(im, threshold=0.1, chromaticity_threshold=0.03))
    blake = mean_lmse(lambda im: lightness_blake1985(im, threshold=0.05))
    grey = mean_lmse(lambda im: lightness_grosse2009(im, threshold=0.05, chromaticity_threshold=np.inf))
    assert ours < 0.7 * blake
    assert ours < 0.1 * grey


def test_hold_one_out_never_scores_an_image_with_its_own_choice():
    scs = [colour_mondrian_scene(48, seed=s) for s in range(3)]
    out = select_thresholds_hold_one_out([s["image"] for s in scs], [s["albedo"] for s in scs],
                                         [s["shading"] for s in scs], thresholds=[0.03, 0.1],
                                         chromaticity_thresholds=[0.03, np.inf],
                                         score=lambda r, s, R, S, m: intrinsic_lmse(r, s, R, S, mask=m, window=12))
    assert out["scores"].shape == (3, 4) and len(out["chosen"]) == 3
    for i, pair in enumerate(out["chosen"]):
        others = np.delete(out["scores"], i, axis=0).mean(axis=0)
        assert pair == out["grid"][int(np.argmin(others))]
        assert out["held_out"][i] == out["scores"][i, out["grid"].index(pair)]
    assert out["best"] in out["grid"]
    with pytest.raises(ValueError, match="n >= 2"):
        select_thresholds_hold_one_out([scs[0]["image"]], [scs[0]["albedo"]], [scs[0]["shading"]],
                                       score=lambda *a: 0.0)
    with pytest.raises(ValueError, match="score"):
        select_thresholds_hold_one_out([s["image"] for s in scs], [s["albedo"] for s in scs],
                                       [s["shading"] for s in scs])


def test_registered_and_dispatched():
    assert METHODS["grosse2009"] is lightness_grosse2009
    a, light = two_papers()
    r1, _ = estimate_lightness(a * light, method="grosse2009", threshold=0.05)
    r2, _ = lightness_grosse2009(a * light, threshold=0.05)
    np.testing.assert_array_equal(r1, r2)


def test_failure_modes():
    a, light = two_papers()
    img = a * light
    with pytest.raises(ValueError, match="chromaticity_threshold"):
        lightness_grosse2009(img, chromaticity_threshold=-1)
    with pytest.raises(ValueError, match="threshold"):
        lightness_grosse2009(img, threshold=np.nan)
    bad = img.copy()
    bad[0, 0, 1] = 0.0
    with pytest.raises(ValueError, match="<= 0"):
        lightness_grosse2009(bad)
    r, s = lightness_grosse2009(bad, min_value=1e-6)  # dropped from the domain instead
    assert r[0, 0].tolist() == [0, 0, 0] and np.all(r[1:] > 0)
