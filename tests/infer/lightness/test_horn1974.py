"""Retinex on a 1-D profile, Horn's (1974) difference-threshold-sum scheme (the chapter's
Fig. 1.11; pbrbench.infer.lightness.horn1974)."""

import numpy as np
import pytest

from pbrbench.infer.lightness import lightness_1d_horn1974, retinex_1d


def test_retinex_1d_is_this_method():
    assert retinex_1d is lightness_1d_horn1974


def test_retinex_1d_fig_1_11():
    x = np.linspace(0, 1, 400)
    rho = np.where(x < 0.3, 0.8, np.where(x < 0.6, 0.2, 0.5))
    light = 2.0 + np.sin(2 * x)  # slow: per-sample log change < 0.003
    r, s = retinex_1d(rho * light, threshold=0.05)
    np.testing.assert_allclose(r * s, rho * light, rtol=1e-12)
    assert r.max() == pytest.approx(1.0)
    # ratios between the papers are off only by the light's change across one sample per edge
    assert r[180] / r[60] == pytest.approx(0.25, rel=0.01)
    assert r[300] / r[180] == pytest.approx(2.5, rel=0.01)
    # failure mode: a threshold above an edge's contrast (log 2.5 = 0.92) merges those papers
    r_hi, _ = retinex_1d(rho * light, threshold=1.0)
    assert r_hi[300] / r_hi[180] == pytest.approx(1.0)
    assert r_hi[180] / r_hi[60] == pytest.approx(0.25, rel=0.01)
    # colour profile, mean anchor
    rc, _ = retinex_1d(np.stack([rho * light, 0.5 * rho * light], -1), anchor="mean", mean_lightness=0.4)
    np.testing.assert_allclose(rc.mean(axis=0), 0.4)


def test_retinex_1d_bad_inputs():
    with pytest.raises(ValueError, match="<= 0"):
        retinex_1d(np.array([1.0, 0.0, 2.0]))
    with pytest.raises(ValueError, match="non-finite"):
        retinex_1d(np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="anchor"):
        retinex_1d(np.ones(4), anchor="x")
    with pytest.raises(ValueError, match="empty"):
        retinex_1d(np.ones(0))
