"""Statistical comparison of Monte Carlo renders: per-pixel t-tests with a multiple-comparison correction.

Two renders of the same scene never agree bit for bit across platforms, samplers or seeds; they
agree *in distribution*.  A render is therefore compared with a reference by a per-pixel test of
the null hypothesis "same expected value", as Mitsuba's own render regression tests do: the
difference of the two means divided by its standard error, a p-value per pixel and channel, and a
family-wise significance level ``alpha`` split over all the tests (Bonferroni or Šidák), so that
an unbiased render fails with probability at most ``alpha`` however many pixels it has.

Variance estimates.  The ground truth gives ``*_sd``: the standard deviation of each pixel's
estimate from its ``G`` sample groups, a ``G - 1``-degree-of-freedom estimate (taken here as one
degree of freedom, which keeps the test conservative).  A t statistic with so few degrees of
freedom is heavy-tailed and has little power, so the variance is pooled over a
``pool`` x ``pool`` neighbourhood (noise varies slowly across an image); the pooled estimate has
about ``pool**2`` degrees of freedom per image and the two images' variances combine by the
Welch-Satterthwaite rule.  p-values come from Student's t distribution with those degrees of freedom.

References
----------
B. L. Welch, "The generalization of Student's problem when several different population variances
are involved", Biometrika 34, 1947.  A. Jung, J. Hanika, C. Dachsbacher, "Detecting bias in Monte
Carlo renderers using Welch's t-test", JCGT 9(2), 2020.  Mitsuba 3, ``src/render/tests/test_renders.py``
(per-pixel test against a stored reference mean and variance, Bonferroni-corrected).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage, stats

from pbrbench.checks import as_float_array, check_method

CORRECTIONS = ("bonferroni", "sidak", "none")


@dataclass
class StatResult:
    """Outcome of :func:`compare_images`."""

    passed: bool
    n_tests: int
    n_rejected: int
    alpha: float
    threshold: float  # per-test p-value threshold after the correction
    min_p: float
    max_abs_t: float
    t: np.ndarray = field(repr=False)  # (H, W[, C]) t statistic (0 where not tested)
    p: np.ndarray = field(repr=False)  # (H, W[, C]) p-values (1 where not tested)
    rejected: np.ndarray = field(repr=False)
    diagnostics: Path | None = None

    def summary(self) -> str:
        return (f"{'pass' if self.passed else 'FAIL'}: {self.n_rejected}/{self.n_tests} pixel tests rejected at "
                f"family-wise alpha {self.alpha:g} (per-test p < {self.threshold:.3g}); min p {self.min_p:.3g}, "
                f"max |t| {self.max_abs_t:.2f}")


def pooled_variance(sd, pool: int = 3) -> np.ndarray:
    """Mean of ``sd**2`` over a ``pool`` x ``pool`` neighbourhood of each pixel (per channel)."""
    v = as_float_array(sd, "sd") ** 2
    if pool <= 1:
        return v
    size = (pool, pool) + (1,) * (v.ndim - 2)
    return ndimage.uniform_filter(v, size=size, mode="nearest")


def corrected_threshold(alpha: float, n_tests: int, correction: str = "bonferroni") -> float:
    """Per-test p-value threshold keeping the family-wise error rate at ``alpha``.

    Bonferroni: ``alpha / n``; Šidák: ``1 - (1 - alpha)**(1/n)`` (exact for independent tests);
    none: ``alpha``.
    """
    check_method(correction, CORRECTIONS, "correction")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha: must be in (0, 1), got {alpha}")
    n = max(int(n_tests), 1)
    if correction == "bonferroni":
        return alpha / n
    if correction == "sidak":
        return float(-np.expm1(np.log1p(-alpha) / n))
    return alpha


def compare_images(image, ref_mean, ref_sd, *, image_sd=None, alpha: float = 0.01, pool: int = 3,
                   correction: str = "bonferroni", mask=None, atol: float = 0.0, rtol: float = 1e-5,
                   diagnostics_dir: str | Path | None = None, name: str = "comparison") -> StatResult:
    """Per-pixel Welch t-test of ``image`` against a reference mean with noise estimates.

    .. math::  t = \\frac{x - \\mu}{\\sqrt{\\bar s_x^2 + \\bar s_\\mu^2}}, \\qquad
               \\nu = \\frac{(\\bar s_x^2 + \\bar s_\\mu^2)^2}{\\bar s_x^4/k_x + \\bar s_\\mu^4/k_\\mu}

    with ``s`` the standard deviations of the two pixel estimates, pooled over ``pool`` x ``pool``
    pixels (``k = pool**2`` degrees of freedom each, one-degree-of-freedom inputs).  The two-sided
    p-value of each pixel and channel is compared with the corrected threshold
    (:func:`corrected_threshold`); the comparison passes when no test is rejected.  Pixels whose
    combined variance is 0 (e.g. an empty background) pass when ``|x - mu| <= atol``.

    Parameters
    ----------
    image, ref_mean : array_like (H, W) or (H, W, C)
    ref_sd : array_like, same shape
        Standard deviation of the reference mean's estimate.
    image_sd : array_like, optional
        Standard deviation of ``image``'s estimate (0 when omitted: a converged image).
    alpha : float, keyword-only
        Family-wise significance level.
    pool : int, keyword-only
        Neighbourhood size for pooling the variances (1: no pooling).
    correction : {'bonferroni', 'sidak', 'none'}, keyword-only
    mask : array_like (H, W) of bool, optional
        Pixels to test.
    atol : float, keyword-only
        Tolerance for zero-variance pixels.
    rtol : float, keyword-only
        Floor on the standard error relative to ``|ref_mean|`` (added in quadrature): float32
        accumulation and stratified samplers leave deterministic errors of ~1e-6 that the
        sample groups cannot see (they can agree to 1e-7 with a multijitter sampler).
    diagnostics_dir : path, optional
        On failure, write ``<name>_image.png``, ``<name>_reference.png`` and ``<name>_t.png``
        (t map with a colour bar) and ``<name>.txt`` there.

    Returns
    -------
    StatResult
    """
    x = as_float_array(image, "image")
    mu = as_float_array(ref_mean, "ref_mean")
    sm = as_float_array(ref_sd, "ref_sd")
    if x.shape != mu.shape or sm.shape != mu.shape:
        raise ValueError(f"image, ref_mean, ref_sd: shapes {x.shape}, {mu.shape}, {sm.shape} must be equal")
    if x.ndim not in (2, 3):
        raise ValueError(f"image: expected (H, W) or (H, W, C), got shape {x.shape}")
    sx = np.zeros_like(x) if image_sd is None else as_float_array(image_sd, "image_sd")
    if sx.shape != x.shape:
        raise ValueError(f"image_sd: shape {sx.shape} does not match image {x.shape}")
    if int(pool) < 1:
        raise ValueError(f"pool: must be >= 1, got {pool}")
    pool = int(pool)
    for a, nm in ((x, "image"), (mu, "ref_mean"), (sm, "ref_sd"), (sx, "image_sd")):
        if not np.isfinite(a).all():
            raise ValueError(f"{nm}: contains NaN or inf; render again or mask those pixels")
    if mask is None:
        m = np.ones(x.shape[:2], bool)
    else:
        m = np.asarray(mask, bool)
        if m.shape != x.shape[:2]:
            raise ValueError(f"mask: shape {m.shape} does not match the image's (H, W) {x.shape[:2]}")
    mfull = m if x.ndim == 2 else np.repeat(m[..., None], x.shape[2], axis=2)
    k = float(pool * pool)
    vm = pooled_variance(sm, pool)
    vx = pooled_variance(sx, pool) if image_sd is not None else np.zeros_like(x)
    if rtol < 0:
        raise ValueError(f"rtol: must be >= 0, got {rtol}")
    var = vm + vx + (rtol * np.abs(mu)) ** 2
    diff = x - mu
    zero = var <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(zero, 0.0, diff / np.sqrt(np.where(zero, 1.0, var)))
        denom = vm * vm / k + (vx * vx / k if image_sd is not None else 0.0)
        nu = np.where(denom > 0, var * var / np.where(denom > 0, denom, 1.0), 1e6)
    nu = np.clip(nu, 1.0, 1e6)
    p = np.where(zero, np.where(np.abs(diff) <= atol, 1.0, 0.0), 2.0 * stats.t.sf(np.abs(t), nu))
    p = np.where(mfull, p, 1.0)
    t = np.where(mfull, t, 0.0)
    n_tests = int(mfull.sum())
    thr = corrected_threshold(alpha, n_tests, correction)
    rejected = (p < thr) & mfull
    res = StatResult(passed=not rejected.any(), n_tests=n_tests, n_rejected=int(rejected.sum()), alpha=alpha,
                     threshold=thr, min_p=float(p[mfull].min()) if n_tests else 1.0,
                     max_abs_t=float(np.abs(t[mfull]).max()) if n_tests else 0.0, t=t, p=p, rejected=rejected)
    if not res.passed and diagnostics_dir is not None:
        res.diagnostics = write_diagnostics(diagnostics_dir, name, x, mu, t, res)
    return res


def write_diagnostics(directory, name: str, image, reference, t, result: StatResult) -> Path:
    """Write the two images (shared exposure), the t map with a colour bar and a text summary."""
    from pbrbench.io import ensure_dir, write_colormap_png, write_preview

    d = ensure_dir(directory)
    pos = reference[reference > 0]
    exposure = 1.0 / float(np.percentile(pos, 99.5)) if pos.size else 1.0
    write_preview(d / f"{name}_image.png", np.maximum(image, 0), exposure=exposure)
    write_preview(d / f"{name}_reference.png", np.maximum(reference, 0), exposure=exposure)
    tmap = t if t.ndim == 2 else t[..., np.argmax(np.abs(t).reshape(-1, t.shape[-1]).max(0))]
    lim = max(float(np.abs(tmap).max()), 1e-6)
    write_colormap_png(d / f"{name}_t.png", tmap, label="t statistic (image - reference) / sd", cmap="RdBu_r",
                       vmin=-lim, vmax=lim)
    (d / f"{name}.txt").write_text(result.summary() + "\n")
    return d


def save_reference(path, mean, sd) -> None:
    """Store a reference mean and its per-pixel sd as a float32 EXR (``mean`` and ``sd`` layers)."""
    from pbrbench.io import write_exr

    write_exr(path, {"mean": np.asarray(mean, np.float32), "sd": np.asarray(sd, np.float32)})


def load_reference(path) -> tuple[np.ndarray, np.ndarray]:
    """(mean, sd) from :func:`save_reference`."""
    from pbrbench.io import read_exr

    a = read_exr(path)
    return a["mean"], a["sd"]
