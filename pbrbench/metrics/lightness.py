"""Scores for lightness / intrinsic-image estimates (docs/science.md §5).

Objects
-------
- :func:`lmse` -- local scale-invariant MSE of Grosse et al. 2009, exactly the MIT Intrinsic
  Images code's ``local_error`` (see its docstring for the variant).
- :func:`lmse_map` -- the per-window normalised errors behind :func:`lmse` (an error map).
- :func:`intrinsic_lmse` -- the average of reflectance and shading LMSE (the published score).
- :func:`si_mse` -- scale-invariant MSE (one best global scale).
- :func:`albedo_abs_error` -- mean absolute error, no rescaling (compares anchor rules).
- :func:`ratio_errors` -- relative errors of reflectance ratios between labelled patches.

Reference: R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset
and baseline evaluations for intrinsic image algorithms", ICCV 2009.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from pbrbench.checks import as_float_array, check_finite, check_mask
from pbrbench.metrics.table import table

__all__ = ["lmse", "lmse_map", "intrinsic_lmse", "si_mse", "albedo_abs_error", "ratio_errors",
           "lightness_scores", "METRICS"]

_ALPHA_MIN_ENERGY = 1e-5  # the MIT code's guard: alpha = 0 when sum(est^2) <= 1e-5


def _pair(est, true, mask, names=("est", "true")):
    e = as_float_array(est, names[0], ndim=(2, 3))
    t = as_float_array(true, names[1], ndim=(2, 3))
    if e.shape != t.shape:
        raise ValueError(f"{names[0]}: shape {e.shape} differs from {names[1]} shape {t.shape}; "
                         "pass arrays of one shape")
    m = check_mask(mask, e.shape[:2])
    check_finite(e, names[0], where=m)
    check_finite(t, names[1], where=m)
    e3 = e[..., None] if e.ndim == 2 else e
    t3 = t[..., None] if t.ndim == 2 else t
    return np.where(m[..., None], e3, 0.0), np.where(m[..., None], t3, 0.0), m


def _window_sums(a: np.ndarray, window: int, step: int) -> np.ndarray:
    """Sums of ``a`` (H, W, C) over windows ``[i:i+window, j:j+window]`` at i, j = 0, step, ...

    When ``step`` divides ``window`` (the default ``step = window // 2`` of an even window), the
    sums are built from the ``step`` x ``step`` block sums (a reshape, no running sums over the
    whole image); otherwise from the summed-area table."""
    ni = (a.shape[0] - window) // step + 1
    nj = (a.shape[1] - window) // step + 1
    if window % step == 0:
        r = window // step
        nb_i, nb_j = ni - 1 + r, nj - 1 + r
        blocks = a[:nb_i * step, :nb_j * step].reshape(nb_i, step, nb_j, step, a.shape[2]).sum((1, 3))
        out = np.zeros((ni, nj, a.shape[2]))
        for di in range(r):
            for dj in range(r):
                out += blocks[di:di + ni, dj:dj + nj]
        return out
    s = np.zeros((a.shape[0] + 1, a.shape[1] + 1, a.shape[2]))
    s[1:, 1:] = a.cumsum(0).cumsum(1)
    i0 = np.arange(ni) * step
    j0 = np.arange(nj) * step
    i1, j1 = i0 + window, j0 + window
    return (s[i1][:, j1] - s[i0][:, j1] - s[i1][:, j0] + s[i0][:, j0])


def _local_terms(est, true, mask, window, step):
    """Per-window (ssq, energy) arrays of shape (ni, nj, C)."""
    return _local_terms_checked(*_pair(est, true, mask), window, step)


def _local_terms_checked(e, t, m, window, step):
    """:func:`_local_terms` of arrays :func:`_pair` has checked and masked (zero outside ``m``)."""
    window, step = int(window), int(step)
    if window < 1 or step < 1:
        raise ValueError(f"window/step: must be positive integers, got window={window}, step={step}")
    if window > min(m.shape):
        raise ValueError(f"window: {window} exceeds the image size {m.shape}; use a smaller window")
    # e and t are zero outside the mask, so the products need no mask factor
    stt = _window_sums(t * t, window, step)
    ste = _window_sums(t * e, window, step)
    see = _window_sums(e * e, window, step)
    ok = see > _ALPHA_MIN_ENERGY
    alpha = np.where(ok, ste / np.where(ok, see, 1.0), 0.0)
    ssq = np.maximum(stt - 2 * alpha * ste + alpha * alpha * see, 0.0)
    return ssq, stt


def _lmse_checked(e, t, m, window, step) -> float:
    ssq, stt = _local_terms_checked(e, t, m, window, step)
    total = stt.sum()
    if total <= 0:
        raise ValueError("true: zero energy inside the mask (all values 0); LMSE is undefined")
    return float(ssq.sum() / total)


def lmse(est, true, *, mask=None, window: int = 20, step: int | None = None) -> float:
    r"""Local scale-invariant mean squared error (Grosse et al. 2009, the MIT variant).

    The image is covered by ``window`` x ``window`` windows whose top-left corners are at
    ``0, step, 2 step, ...`` (only windows that fit entirely: ``i <= H - window``).  In each
    window ``w`` the estimate is rescaled by its best scale
    ``alpha_w = sum_w m t e / sum_w m e^2`` (``alpha_w = 0`` when ``sum_w m e^2 <= 1e-5``, as
    in the MIT code), and

    .. math:: \mathrm{LMSE} = \frac{\sum_w \sum_{x \in w} m (t - \alpha_w e)^2}
                                   {\sum_w \sum_{x \in w} m\, t^2}

    i.e. the *sum* of the windows' squared errors normalised by the *sum* of the ground
    truth's own local energies (not the mean of per-window ratios, and not divided by the
    error of an all-zero estimate per window).  This is ``local_error`` of the MIT Intrinsic
    Images code; the published score averages it over shading and reflectance
    (:func:`intrinsic_lmse`).  Colour (H, W, C): each channel has its own ``alpha_w`` and the
    sums run over channels too.

    Parameters
    ----------
    est, true : (H, W) or (H, W, C) arrays of one shape.
    mask : (H, W) bool, optional; pixels outside count as zero in every sum.
    window : int, default 20
    step : int, optional, default ``window // 2``

    Returns
    -------
    float in [0, 1] (1 = no better than zero).

    References
    ----------
    R. Grosse, M. K. Johnson, E. H. Adelson and W. T. Freeman, "Ground truth dataset and
    baseline evaluations for intrinsic image algorithms", ICCV 2009.
    """
    step = int(window) // 2 if step is None else step
    return _lmse_checked(*_pair(est, true, mask), window, step)


def lmse_map(est, true, *, mask=None, window: int = 20, step: int | None = None) -> np.ndarray:
    """Per-window normalised error ``ssq_w / energy_w`` (ni, nj), summed over channels.

    The error map behind :func:`lmse` (NaN where a window has no ground-truth energy); upsample
    it by ``step`` to overlay it on the image.
    """
    step = int(window) // 2 if step is None else step
    ssq, stt = _local_terms(est, true, mask, window, step)
    s, e = ssq.sum(-1), stt.sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(e > 0, s / np.where(e > 0, e, 1.0), np.nan)


def intrinsic_lmse(refl_est, shad_est, refl_true, shad_true, *, mask=None, window: int = 20,
                   step: int | None = None) -> float:
    """Grosse et al. (2009) score: ``0.5 * LMSE(shading) + 0.5 * LMSE(reflectance)``.

    Both terms are :func:`lmse` with the same ``mask``, ``window`` and ``step``.
    """
    return 0.5 * (lmse(shad_est, shad_true, mask=mask, window=window, step=step)
                  + lmse(refl_est, refl_true, mask=mask, window=window, step=step))


def si_mse(est, true, *, mask=None) -> float:
    r"""Scale-invariant MSE: ``min_alpha mean_m (t - alpha e)^2`` over the masked pixels.

    One global least-squares scale ``alpha = sum m t e / sum m e^2`` per channel (0 if the
    estimate is zero); the mean runs over masked pixels and channels.  Not normalised.
    """
    return _si_mse_checked(*_pair(est, true, mask))


def _si_mse_checked(e, t, m) -> float:
    see = (e * e).sum((0, 1))
    alpha = np.where(see > 0, (t * e).sum((0, 1)) / np.where(see > 0, see, 1.0), 0.0)
    err = (t - alpha * e)[m]
    return float(np.mean(err * err))


def albedo_abs_error(est, true, *, mask=None) -> float:
    """Mean absolute error ``mean_m |est - true|`` with no rescaling.

    Scores the constant of integration: with the anchor rules of retinex, a perfect
    decomposition with the wrong constant has a large error here and none in :func:`lmse`.
    """
    return _abs_error_checked(*_pair(est, true, mask))


def _abs_error_checked(e, t, m) -> float:
    return float(np.mean(np.abs(e - t)[m]))


def _group_medians(vals: np.ndarray, groups: np.ndarray, n_groups: int) -> np.ndarray:
    """Per group ``g`` (``0 .. n_groups - 1``, each non-empty) and column, the median of
    ``vals[groups == g]`` (``vals`` (n, C)): the value ``np.median`` gives (the middle value,
    or the mean of the two middle ones), from one sort per column."""
    counts = np.bincount(groups, minlength=n_groups)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    lo, hi = start + (counts - 1) // 2, start + counts // 2
    out = np.empty((n_groups, vals.shape[1]))
    for c in range(vals.shape[1]):
        sv = vals[np.lexsort((vals[:, c], groups)), c]
        out[:, c] = (sv[lo] + sv[hi]) / 2.0
    return out


def ratio_errors(est, true, labels, *, mask=None, erode: int = 2) -> np.ndarray:
    r"""Relative errors of reflectance ratios between every pair of labelled patches.

    For each patch ``a`` (a label in ``labels``), ``E_a`` and ``T_a`` are medians of ``est`` and
    ``true`` over its pixels that lie at least ``erode`` pixels (Chebyshev distance) away from
    any other label and inside ``mask``; patches with no such pixel are skipped.  For each
    pair ``a < b`` the error is

    .. math:: \epsilon_{ab} = \frac{E_a / E_b}{T_a / T_b} - 1,

    which is invariant to a global scale of ``est`` (so it ignores the anchor rule).

    Returns
    -------
    (P,) array for grey, (P, C) for colour, with ``P = n (n - 1) / 2`` pairs in the order of
    ``itertools.combinations(sorted(labels), 2)``.  Take ``np.abs(...).max()`` for a worst case.
    """
    e, t, m = _pair(est, true, None)
    lab = np.asarray(labels)
    if lab.shape != m.shape or not np.issubdtype(lab.dtype, np.integer):
        raise ValueError(f"labels: need an integer (H, W) array matching the image shape {m.shape}, "
                         f"got {lab.dtype} {lab.shape}")
    m = check_mask(mask, m.shape)
    k = 2 * int(erode) + 1
    interior = m & (ndimage.maximum_filter(lab, k, mode="nearest")
                    == ndimage.minimum_filter(lab, k, mode="nearest"))
    ids, group = np.unique(lab[interior], return_inverse=True)
    if ids.size < 2:
        raise ValueError("labels: fewer than two patches keep pixels after erosion; lower erode")
    group = group.ravel()
    em = _group_medians(e[interior], group, ids.size)  # (n, C)
    tm = _group_medians(t[interior], group, ids.size)
    a, b = np.triu_indices(ids.size, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        err = (em[a] / em[b]) / (tm[a] / tm[b]) - 1.0
    return err[:, 0] if e.shape[2] == 1 and np.asarray(est).ndim == 2 else err


def lightness_scores(refl, shad, refl_true, shad_true, *, mask, labels=None, window: int = 20) -> dict[str, float]:
    """The lightness task's scores of one (reflectance, shading) estimate: ``lmse`` (reflectance),
    ``intrinsic_lmse``, ``si_mse``, ``albedo_abs_err`` and, when patch ``labels`` are given and
    at least two patches survive the erosion, ``ratio_err_max`` / ``ratio_err_median`` (the
    largest and median absolute reflectance-ratio errors, :func:`ratio_errors` with ``erode=1``)."""
    step = int(window) // 2
    er, tr, m = _pair(refl, refl_true, mask)
    lmse_r = _lmse_checked(er, tr, m, window, step)
    lmse_s = _lmse_checked(*_pair(shad, shad_true, mask), window, step)
    out = {"lmse": lmse_r,
           "intrinsic_lmse": 0.5 * (lmse_s + lmse_r),
           "si_mse": _si_mse_checked(er, tr, m),
           "albedo_abs_err": _abs_error_checked(er, tr, m)}
    if labels is not None:
        try:
            r = np.abs(ratio_errors(refl, refl_true, labels, mask=mask, erode=1))
        except ValueError:
            r = np.zeros(0)
        r = r[np.isfinite(r)]
        if r.size:
            out["ratio_err_max"] = float(r.max())
            out["ratio_err_median"] = float(np.median(r))
    return out


METRICS = table("""
lmse             | lower | -        | lightness_scores | local scale-invariant MSE of the reflectance (Grosse et al. 2009, MIT variant)
intrinsic_lmse   | lower | -        | lightness_scores | mean of the reflectance and shading LMSE (the published score)
si_mse           | lower | -        | lightness_scores | scale-invariant MSE of the reflectance (one best global scale)
albedo_abs_err   | lower | albedo   | lightness_scores | mean absolute reflectance error, no rescaling (scores the anchor rule)
ratio_err_max    | lower | fraction | lightness_scores | largest relative error of reflectance ratios between papers
ratio_err_median | lower | fraction | lightness_scores | median relative error of reflectance ratios between papers
""")
