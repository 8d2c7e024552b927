"""Radiometric calibration and HDR merging from an exposure bracket (SCIENCE.md §4).

Objects
-------
- :class:`CameraResponse`: a calibrated inverse response, tabulated per pixel level and channel.
- :func:`calibrate_debevec`: Debevec & Malik (1997), least squares for ``g = ln f^{-1}``.
- :func:`calibrate_robertson`: Robertson, Borman & Stevenson (1999, 2003), ML alternation.
- :func:`calibrate_mitsunaga_nayar`: Mitsunaga & Nayar (1999), polynomial ``f^{-1}`` and
  re-estimated exposure ratios.
- :func:`merge_hdr`: per-pixel weighted merge in the log domain.

Model: a pixel level ``Z = f(E * t)`` for irradiance ``E`` and exposure time ``t`` (reciprocity),
``f`` monotone and unknown.  ``inverse[z, c]`` is ``f_c^{-1}(z)`` up to the free scale, which is
fixed the same way for every method and channel: ``inverse[levels - 1, c] == 1``, i.e. exposure is
measured relative to the clipping point.  All channels of a sensor clip at the same exposure, so this
gauge keeps the colour balance (the classical ``g(Z_mid) = 0`` gauge per channel does not).

Images are ``(K, H, W[, C])`` unsigned integers of any bit depth up to 16 (or a sequence of
``(H, W[, C])`` arrays), sorted by strictly increasing exposure time (seconds).  The lowest and the
highest level are treated as clipped: they get weight zero everywhere.

References
----------
- P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from Photographs",
  SIGGRAPH 1997.
- M. A. Robertson, S. Borman and R. L. Stevenson, "Dynamic range improvement through multiple
  exposures", ICIP 1999; "Estimation-theoretic approach to dynamic range enhancement using
  multiple exposures", Journal of Electronic Imaging 12(2), 2003.
- T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999.
- M. Granados, B. Ajdin, M. Wand, C. Theobalt, H.-P. Seidel and H. P. A. Lensch, "Optimal HDR
  reconstruction with linear digital cameras", CVPR 2010 (inverse-variance weights).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import isotonic_regression

from pbrbench.checks import check_method

__all__ = [
    "CALIBRATION_WEIGHTINGS",
    "MERGE_WEIGHTINGS",
    "CameraResponse",
    "calibrate_debevec",
    "calibrate_mitsunaga_nayar",
    "calibrate_robertson",
    "merge_hdr",
]

CALIBRATION_WEIGHTINGS = ("hat", "uniform", "gaussian")
MERGE_WEIGHTINGS = ("variance", "hat", "uniform", "gaussian")
_MAX_KNOTS = 1024


@dataclass(frozen=True, eq=False)
class CameraResponse:
    """A calibrated inverse camera response.

    Attributes
    ----------
    inverse : ndarray, (levels, C), float64
        ``f_c^{-1}(z)``: relative linear exposure of level ``z``; strictly increasing, finite and
        positive, with ``inverse[-1, c] == 1`` for every channel (the clipping point).
    levels : int
        Number of pixel levels (``2 ** bit_depth``).
    method : str
        ``"debevec"``, ``"robertson"`` or ``"mitsunaga_nayar"``.
    exposure_times : ndarray (K,) or None
        Re-estimated exposure times (Mitsunaga–Nayar), else None.  Pass them to
        :func:`merge_hdr` in place of the stated times.
    coefficients : ndarray (degree + 1, C) or None
        Polynomial coefficients of ``f^{-1}(z / (levels - 1))`` (Mitsunaga–Nayar), else None.
    """

    inverse: np.ndarray
    levels: int
    method: str
    exposure_times: np.ndarray | None = None
    coefficients: np.ndarray | None = None

    @property
    def log_inverse(self) -> np.ndarray:
        """``g = ln f^{-1}``, shape (levels, C)."""
        return np.log(self.inverse)

    @property
    def channels(self) -> int:
        return self.inverse.shape[1]


# ----------------------------------------------------------------------------------- validation
def _as_stack(images, bit_depth: int | None = None) -> tuple[np.ndarray, int]:
    """Return ``(Z (K, H, W, C) unsigned ints, levels)``; raise ValueError on bad input."""
    if isinstance(images, np.ndarray):
        arr = images
    else:
        try:
            items = [np.asarray(im) for im in images]
        except TypeError as exc:
            raise ValueError("images: pass an array (K, H, W[, C]) or a sequence of (H, W[, C]) arrays") from exc
        if len(items) == 0:
            raise ValueError("images: got no image; pass at least 2 exposures")
        shapes = {im.shape for im in items}
        if len(shapes) != 1:
            raise ValueError(f"images: the exposures have different shapes {sorted(shapes)}; crop/resize them to one (H, W[, C])")
        dts = {im.dtype for im in items}
        if len(dts) != 1:
            raise ValueError(f"images: the exposures have different dtypes {sorted(map(str, dts))}; convert them to one unsigned integer type")
        arr = np.stack(items)
    if arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(
            f"images: expected unsigned integer pixel levels, got dtype {arr.dtype}; pass the camera's raw "
            "levels (e.g. np.round(img * 255).astype(np.uint8)), not floating-point or boolean images")
    if arr.ndim == 3:
        arr = arr[..., None]
    if arr.ndim != 4:
        raise ValueError(f"images: expected shape (K, H, W) or (K, H, W, C), got {arr.shape}")
    if arr.shape[0] < 2:
        raise ValueError(f"images: got {arr.shape[0]} exposure(s); calibration and merging need at least 2")
    if arr.size == 0:
        raise ValueError(f"images: empty array of shape {arr.shape}")
    if arr.dtype not in (np.uint8, np.uint16):
        lo, hi = int(arr.min()), int(arr.max())
        if lo < 0 or hi > 65535:
            raise ValueError(f"images: levels must lie in [0, 65535] (at most 16 bits), got [{lo}, {hi}]")
        arr = arr.astype(np.uint16)
    if bit_depth is not None:
        if int(bit_depth) != bit_depth or not 1 <= bit_depth <= 16:
            raise ValueError(f"bit_depth={bit_depth!r}: must be an integer in 1..16, or None to infer it")
        levels = 1 << int(bit_depth)
        if int(arr.max()) >= levels:
            raise ValueError(f"images: level {int(arr.max())} exceeds bit_depth={bit_depth}; pass the right bit_depth")
    elif arr.dtype == np.uint8:
        levels = 256
    else:
        levels = 1 << max(8, int(np.ceil(np.log2(int(arr.max()) + 1))))
    return arr, levels


def _check_times(exposure_times, K: int) -> np.ndarray:
    try:
        t = np.asarray(exposure_times, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError("exposure_times: pass a 1-D sequence of numbers (seconds)") from exc
    if t.ndim != 1:
        raise ValueError(f"exposure_times: expected a 1-D sequence, got shape {t.shape}")
    if t.size != K:
        raise ValueError(f"exposure_times: got {t.size} times for {K} images; pass one time per exposure")
    if not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise ValueError(f"exposure_times: must be finite and > 0 (seconds), got {t.tolist()}")
    if np.any(np.diff(t) <= 0):
        raise ValueError(
            "exposure_times: must be strictly increasing; sort the bracket "
            "(order = np.argsort(times); images = images[order]; times = times[order]) and average repeated shots")
    return t


def _check_int(value, name: str, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise ValueError(f"{name}: must be an integer >= {lo}, got {value!r}")
    return int(value)


def _check_float(value, name: str, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be a number, got {value!r}") from exc
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name}: must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return v


# ------------------------------------------------------------------------------------- weights
def _level_weights(name: str, levels: int) -> np.ndarray:
    """Weight per level (peak 1), zero at the clipped ends 0 and ``levels - 1``."""
    z = np.arange(levels, dtype=np.float64)
    top = levels - 1
    mid = top / 2.0
    if name == "hat":
        w = np.minimum(z, top - z) / mid
    elif name == "uniform":
        w = np.ones(levels)
    elif name == "gaussian":
        w = np.exp(-4.0 * ((z - mid) / mid) ** 2)
    else:  # pragma: no cover - validated by callers
        raise ValueError(name)
    w[0] = w[-1] = 0.0
    return w


# ------------------------------------------------------------------------------------ sampling
def _sample_pixels(Z: np.ndarray, levels: int, samples: int, seed, per_level: int = 2) -> list[np.ndarray]:
    """Flat pixel indices per channel: ``samples`` random pixels, plus pixels that cover levels.

    Every level that occurs in any exposure of a channel is represented by at least
    ``min(per_level, its count)`` sampled pixels.  Deterministic given ``seed``.
    """
    K, H, W, C = Z.shape
    P = H * W
    rng = np.random.default_rng(seed)
    base = rng.choice(P, size=min(samples, P), replace=False) if samples < P else np.arange(P)
    flat = Z.reshape(K, P, C)
    out = []
    for c in range(C):
        sub = flat[:, base, c]
        have = np.zeros(levels, dtype=np.int64)
        for k in range(K):
            have += np.bincount(sub[k], minlength=levels)[:levels]
        need = have < per_level
        extra = []
        if need.any() and base.size < P:
            for k in range(K):
                cand = np.flatnonzero(need[flat[k, :, c]])
                if cand.size == 0:
                    continue
                cand = cand[rng.permutation(cand.size)]
                lv = flat[k, cand, c]
                order = np.argsort(lv, kind="stable")
                lv_sorted = lv[order]
                first = np.searchsorted(lv_sorted, lv_sorted, side="left")
                rank = np.arange(lv_sorted.size) - first
                extra.append(cand[order[rank < per_level]])
        idx = np.unique(np.concatenate([base] + extra)) if extra else np.sort(base)
        out.append(idx)
    return out


# ---------------------------------------------------------------------------------- finalising
def _extrapolate(v: np.ndarray, ok: np.ndarray, n_fit: int = 16) -> np.ndarray:
    """Fill non-``ok`` entries of a log curve: linear interpolation inside, linear fits outside."""
    z = np.arange(v.size, dtype=np.float64)
    zi = z[ok]
    vi = v[ok]
    out = np.interp(z, zi, vi)
    for side in ("lo", "hi"):
        sel = slice(0, n_fit) if side == "lo" else slice(-n_fit, None)
        zz, vv = zi[sel], vi[sel]
        slope = np.polyfit(zz, vv, 1)[0] if zz.size >= 2 else 0.0
        slope = max(slope, 1e-6)
        if side == "lo":
            m = z < zi[0]
            out[m] = vi[0] + slope * (z[m] - zi[0])
        else:
            m = z > zi[-1]
            out[m] = vi[-1] + slope * (z[m] - zi[-1])
    return out


def _finalise(logx: np.ndarray, counts: np.ndarray | None) -> np.ndarray:
    """Monotone, finite, positive inverse (levels, C) with ``inverse[-1] == 1`` per channel.

    ``logx`` holds ``ln f^{-1}`` with NaN where unknown; ``counts`` (levels, C) weights the
    isotonic regression that enforces monotonicity.
    """
    levels, C = logx.shape
    inv = np.empty_like(logx)
    ramp = np.arange(levels) * 1e-9
    for c in range(C):
        v = logx[:, c].copy()
        ok = np.isfinite(v)
        if ok.sum() < 2:
            raise ValueError(
                f"images: channel {c} has fewer than 2 usable pixel levels; the bracket is clipped or flat. "
                "Use more exposures or exposures that cover the scene")
        w = np.ones(ok.sum()) if counts is None else np.maximum(counts[ok, c], 1e-3)
        v[ok] = isotonic_regression(v[ok], weights=w, increasing=True).x
        v = _extrapolate(v, ok)
        v = np.maximum.accumulate(v + ramp)
        inv[:, c] = np.exp(v - v[-1])
    return inv


# --------------------------------------------------------------------------------- Debevec-Malik
def _smoothness_operator(pos: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Mean weighted squared curvature ``sum_j w_j^2 h_j g''(u_j)^2 / sum_j w_j^2 h_j`` as a matrix.

    ``u = ln(z + 1/2)`` is log pixel level, ``pos`` the knot levels, ``h_j`` the local spacing in
    ``u``.  Curvature is measured per unit ``u`` and averaged over ``u``, so the penalty does not
    depend on the number of levels or knots (bit depth): the same ``smoothness`` smooths over the
    same fraction of the log-level range at 8 and at 16 bits.  A power-law response
    (``g = gamma ln z``) has zero curvature in ``u`` and is not biased by the penalty.
    """
    n = pos.size
    u = np.log(pos + 0.5)
    du = np.diff(u)
    h = 0.5 * (du[1:] + du[:-1])
    j = np.arange(n - 2)
    rows = np.repeat(j, 3)
    cols = np.stack([j, j + 1, j + 2], axis=1).ravel()
    vals = np.stack([1 / du[:-1], -(1 / du[:-1] + 1 / du[1:]), 1 / du[1:]], axis=1) / h[:, None]
    D = sp.csr_matrix((vals.ravel(), (rows, cols)), shape=(n - 2, n))
    ww = np.maximum(w, 0.05)[1:-1] ** 2 * h
    return (D.T @ sp.diags(ww / ww.sum()) @ D).toarray()


def calibrate_debevec(images, exposure_times, *, smoothness: float = 1e-7, samples: int = 4096,
                      weighting: str = "hat", seed: int = 0, bit_depth: int | None = None,
                      _data_weight=None) -> CameraResponse:
    r"""Recover the inverse response with the method of Debevec & Malik (1997).

    Minimises, per channel, over ``g = ln f^{-1}`` (at every level) and ``ln E_i`` (at sampled pixels)

    .. math::

        \sum_{i,k} \left[w(Z_{ik})\,(g(Z_{ik}) - \ln E_i - \ln \Delta t_k)\right]^2
        + \lambda' \sum_z \left[w(z)\, g''(z)\right]^2 .

    The ``ln E_i`` are eliminated in closed form (Schur complement), leaving a
    ``levels x levels`` system; above 1024 levels ``g`` is piecewise linear on 1024 knots.
    The gauge is ``g(levels - 1) = 0`` for every channel (see the module notes).

    Parameters
    ----------
    images : array (K, H, W[, C]) or sequence, unsigned integers
    exposure_times : sequence of K floats, strictly increasing, seconds
    smoothness : float
        ``lambda``.  The penalty actually added is ``lambda * A * s^2 * mean_u[w^2 g_uu^2]``:
        ``A`` the total data weight (so ``lambda`` does not depend on the sample count), the
        curvature ``g_uu`` taken in ``u = ln(z + 1/2)`` and averaged over ``u`` (so it does not
        depend on bit depth, and a power-law response is not biased), ``s = max(1, log2 r)``
        for the widest exposure ratio ``r`` (the periodic ambiguity grows with the spacing).
        The default was chosen on 8- to 12-bit brackets 1 to 3 stops apart.
    samples : int
        Random pixels used; pixels are added so that every level present is sampled.
    weighting : {"hat", "uniform", "gaussian"}
        ``w(z)``; all are zero at the clipped ends.
    seed : int
        Seeds the pixel sampling (the result is deterministic given it).
    bit_depth : int or None
        Number of bits; inferred from the dtype / largest level when None.

    Returns
    -------
    CameraResponse

    References
    ----------
    P. E. Debevec and J. Malik, "Recovering High Dynamic Range Radiance Maps from Photographs",
    SIGGRAPH 1997.
    """
    Z, levels = _as_stack(images, bit_depth)
    t = _check_times(exposure_times, Z.shape[0])
    lam = _check_float(smoothness, "smoothness", allow_zero=True)
    n_samp = _check_int(samples, "samples", 1)
    check_method(weighting, CALIBRATION_WEIGHTINGS, "weighting")
    K, H, W, C = Z.shape
    # centred log times: g does not depend on the unit of time, and scaling every time by a
    # constant leaves the linear system (not only its solution) unchanged; rounding to 1e-12
    # (far below any shutter's precision) removes the last-bit differences of the logs, which
    # the ill-conditioned low-level rows (cond ~ 1e10) would amplify to ~1e-5
    lnt = np.round(np.log(t) - np.log(t).mean(), 12)
    wl = _level_weights(weighting, levels)
    n_knots = min(levels, _MAX_KNOTS)
    scale = (n_knots - 1) / (levels - 1)
    knot_pos = np.arange(n_knots) / scale
    idx_c = _sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    # smoothness operator on the knots (second differences), weighted by w at the knots + floor
    DtWD = _smoothness_operator(knot_pos, np.interp(knot_pos, np.arange(levels), wl))
    # Equal exposure ratios r leave g undetermined up to a ripple periodic in ln E with period
    # ln r (Grossberg & Nayar 2003); only the smoothness term fixes it, and the wider the
    # spacing the more of g it must decide.  The penalty is scaled by (log2 r)^2 (empirical: on
    # the benchmark bracket, 3 exposures 3 stops apart, ^4 over-smooths the true curvature and
    # ^0 leaves the ripple; see pbrbench/perf/hdr.py).
    stretch = max(1.0, float(np.max(np.diff(np.log2(t))))) ** 2
    logx = np.empty((levels, C))
    counts = np.zeros((levels, C))
    mid_knot = n_knots // 2
    for c in range(C):
        z = flat[:, idx_c[c], c].T.astype(np.int64)  # (n, K)
        n = z.shape[0]
        a = wl[z] ** 2 if _data_weight is None else _data_weight[z, c]
        A = a.sum(axis=1)
        keep = A > 0
        z, a, A = z[keep], a[keep], A[keep]
        n = z.shape[0]
        if n == 0:
            raise ValueError(f"images: channel {c} has no pixel with a usable (unclipped) level; use other exposures")
        u = z * scale
        j0 = np.minimum(np.floor(u).astype(np.int64), n_knots - 2)
        al = u - j0
        rows = np.repeat(np.arange(n), K)
        # S: (n, n_knots) rows s_i = sum_k a_ik b_ik ; B^T diag(a) B via coo (sums duplicates)
        cols = np.concatenate([j0.ravel(), j0.ravel() + 1])
        vals_s = np.concatenate([(a * (1 - al)).ravel(), (a * al).ravel()])
        S = sp.csr_matrix((vals_s, (np.concatenate([rows, rows]), cols)), shape=(n, n_knots))
        b0, b1 = (1 - al).ravel(), al.ravel()
        av = a.ravel()
        jj = j0.ravel()
        M1 = sp.coo_matrix((np.concatenate([av * b0 * b0, av * b0 * b1, av * b0 * b1, av * b1 * b1]),
                            (np.concatenate([jj, jj, jj + 1, jj + 1]), np.concatenate([jj, jj + 1, jj, jj + 1]))),
                           shape=(n_knots, n_knots)).toarray()
        Sinv = sp.diags(1.0 / A) @ S
        M = M1 - (S.T @ Sinv).toarray()
        alt = (a * lnt).sum(axis=1)  # sum_k a_ik ln t_k
        rhs = np.bincount(cols, weights=np.concatenate([(a * lnt * (1 - al)).ravel(), (a * lnt * al).ravel()]),
                          minlength=n_knots) - S.T @ (alt / A)
        lam_eff = lam * stretch * a.sum()
        M += lam_eff * DtWD
        M[mid_knot, mid_knot] += a.sum() / n_knots
        g = np.linalg.solve(M, rhs)
        logx[:, c] = np.interp(np.arange(levels), knot_pos, g)
        counts[:, c] = np.bincount(z.ravel(), minlength=levels)[:levels]
    logx[-1] = np.nan  # the clipped top level carries no data: extrapolate it like the other methods
    inverse = _finalise(logx, counts + 1.0)
    return CameraResponse(inverse, levels, "debevec")


# ------------------------------------------------------------------------------------- Robertson
def calibrate_robertson(images, exposure_times, *, max_iter: int = 30, tol: float = 1e-4,
                        samples: int = 50000, seed: int = 0, bit_depth: int | None = None) -> CameraResponse:
    r"""Recover the inverse response with the ML alternation of Robertson et al. (1999, 2003).

    With ``x = f^{-1}`` and Gaussian-shaped weights ``w`` (zero at the clipped ends), alternate

    .. math::

        E_i = \frac{\sum_k w(Z_{ik})\, \Delta t_k\, x(Z_{ik})}{\sum_k w(Z_{ik})\, \Delta t_k^2},
        \qquad x(m) = \frac{1}{|\Omega_m|} \sum_{(i,k) \in \Omega_m} E_i\, \Delta t_k ,

    where ``Omega_m`` is the set of observations at level ``m``, until the largest change of
    ``ln x`` is below ``tol``.  The result is made monotone (isotonic regression), extrapolated
    to the clipped ends in the log domain and normalised to ``x(levels - 1) = 1``.

    Parameters
    ----------
    images, exposure_times
        As for :func:`calibrate_debevec`.
    max_iter : int
        Maximum number of alternations.
    tol : float
        Convergence threshold on ``max |Delta ln x|``.
    samples : int
        Random pixels used (plus pixels covering every level), seeded by ``seed``.
    bit_depth : int or None
        Inferred when None.

    Returns
    -------
    CameraResponse

    References
    ----------
    M. A. Robertson, S. Borman and R. L. Stevenson, "Dynamic range improvement through multiple
    exposures", ICIP 1999; "Estimation-theoretic approach to dynamic range enhancement using
    multiple exposures", Journal of Electronic Imaging 12(2), 2003.
    """
    Z, levels = _as_stack(images, bit_depth)
    t = _check_times(exposure_times, Z.shape[0])
    max_iter = _check_int(max_iter, "max_iter", 1)
    tol = _check_float(tol, "tol")
    n_samp = _check_int(samples, "samples", 1)
    K, H, W, C = Z.shape
    wl = _level_weights("gaussian", levels)
    idx_c = _sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    logx = np.full((levels, C), np.nan)
    counts = np.zeros((levels, C))
    top = levels - 1
    # the fixed-point iteration converges slowly from a linear start: start from Debevec-Malik
    init = calibrate_debevec(Z, t, samples=min(n_samp, 4096), seed=seed, bit_depth=int(np.log2(levels))).inverse
    for c in range(C):
        z = flat[:, idx_c[c], c].astype(np.int64)  # (K, n)
        w = wl[z]
        tt = t[:, None]
        valid = (z > 0) & (z < top)
        cnt = np.bincount(z[valid], minlength=levels).astype(float)
        x = init[:, c].copy()
        denom = (w * tt**2).sum(axis=0)
        use = denom > 0
        z, w, valid, denom = z[:, use], w[:, use], valid[:, use], denom[use]
        zv = z[valid]
        tv = np.broadcast_to(tt, z.shape)[valid]
        pop = cnt > 0
        for _ in range(max_iter):
            E = (w * tt * x[z]).sum(axis=0) / denom
            Ev = np.broadcast_to(E, z.shape)[valid]
            new = np.bincount(zv, weights=Ev * tv, minlength=levels)
            new = np.where(pop, new / np.maximum(cnt, 1), x)
            new /= new[levels // 2] if pop[levels // 2] else new[pop].max()
            change = np.max(np.abs(np.log(new[pop]) - np.log(np.maximum(x[pop], 1e-300))))
            x = new
            if change < tol:
                break
        v = np.full(levels, np.nan)
        v[pop] = np.log(x[pop])
        logx[:, c] = v
        counts[:, c] = cnt
    inverse = _finalise(logx, counts)
    return CameraResponse(inverse, levels, "robertson")


# ------------------------------------------------------------------------------ Mitsunaga-Nayar
def _mn_fit(Ma, Mb, R_pair, degree):
    """Least squares for polynomial coefficients with p(1) = 1; rows are pairs (a, b)."""
    N = degree
    n = np.arange(N)
    Pa = Ma[:, None] ** n - (Ma**N)[:, None]
    Pb = Mb[:, None] ** n - (Mb**N)[:, None]
    Aa = Pa - R_pair[:, None] * Pb
    y = -(Ma**N - R_pair * Mb**N)
    coef, *_ = np.linalg.lstsq(Aa, y, rcond=None)
    return np.concatenate([coef, [1.0 - coef.sum()]])


def calibrate_mitsunaga_nayar(images, exposure_times, *, degree: int | None = None, max_iter: int = 20,
                              tol: float = 1e-6, estimate_ratios: bool = True, samples: int = 4096,
                              seed: int = 0, bit_depth: int | None = None) -> CameraResponse:
    r"""Polynomial inverse response and exposure ratios by Mitsunaga & Nayar (1999).

    With ``M = z / (levels - 1)`` and ``f^{-1}(M) = \sum_{n=0}^{N} c_n M^n``, ``f^{-1}(1) = 1``,
    minimise over pairs of adjacent exposures ``k, k+1``

    .. math::

        \sum_{i,k} \left[ f^{-1}(M_{i,k}) - R_k\, f^{-1}(M_{i,k+1}) \right]^2,
        \qquad R_k = \Delta t_k / \Delta t_{k+1},

    alternating a linear solve for ``c`` with the ratio update
    ``R_k = \sum_i f^{-1}(M_{ik}) f^{-1}(M_{i,k+1}) / \sum_i f^{-1}(M_{i,k+1})^2``.  Response and
    ratios are ambiguous up to ``f^{-1} -> (f^{-1})^\gamma, R -> R^\gamma`` (Grossberg & Nayar);
    the stated span ``\sum_k \ln R_k = \ln(\Delta t_0 / \Delta t_{K-1})`` is kept fixed, which
    removes that ambiguity while the individual ratios are re-estimated.  Ratios are shared by
    all channels.

    Parameters
    ----------
    images, exposure_times
        As for :func:`calibrate_debevec`; the times are the initial guess.
    degree : int or None
        Polynomial degree ``N`` (>= 1); None picks 2..8 by error on held-out pixels.
    max_iter, tol
        Alternations and convergence threshold on ``max |Delta ln R_k|``.
    estimate_ratios : bool
        Re-estimate the exposure ratios (default) or trust the stated times.
    samples, seed, bit_depth
        As for :func:`calibrate_debevec`.

    Returns
    -------
    CameraResponse
        With ``exposure_times`` (re-estimated, geometric mean equal to the stated one) and
        ``coefficients`` (degree + 1, C).

    References
    ----------
    T. Mitsunaga and S. K. Nayar, "Radiometric Self Calibration", CVPR 1999.
    """
    Z, levels = _as_stack(images, bit_depth)
    t = _check_times(exposure_times, Z.shape[0])
    if degree is not None:
        degree = _check_int(degree, "degree", 1)
    max_iter = _check_int(max_iter, "max_iter", 1)
    tol = _check_float(tol, "tol")
    n_samp = _check_int(samples, "samples", 1)
    K, H, W, C = Z.shape
    top = levels - 1
    idx_c = _sample_pixels(Z, levels, n_samp, seed)
    flat = Z.reshape(K, H * W, C)
    # pairs (channel, pair index k, Ma, Mb)
    pairs = []
    for c in range(C):
        z = flat[:, idx_c[c], c].astype(np.float64)
        for k in range(K - 1):
            za, zb = z[k], z[k + 1]
            ok = (za > 0) & (za < top) & (zb > 0) & (zb < top)
            pairs.append((c, k, za[ok] / top, zb[ok] / top))
    lnR_nom = np.log(t[:-1] / t[1:])
    span = lnR_nom.sum()
    for c in range(C):
        if sum(p[2].size for p in pairs if p[0] == c) < 4:
            raise ValueError(f"images: channel {c} has too few pixels unclipped in two adjacent exposures; "
                             "use exposures closer together or that cover the scene")

    # per channel: stacked pair rows (Ma, Mb, pair index k)
    rows = []
    for c in range(C):
        sel = [p for p in pairs if p[0] == c]
        rows.append((np.concatenate([p[2] for p in sel]), np.concatenate([p[3] for p in sel]),
                     np.concatenate([np.full(p[2].size, p[1]) for p in sel])))

    def subset(part):
        """Rows of every channel: all (part None), even (0) or odd (1) positions."""
        if part is None:
            return rows
        return [(ma[part::2], mb[part::2], kk[part::2]) for ma, mb, kk in rows]

    def run(deg, data):
        lnR = lnR_nom.copy()
        coefs = [None] * C
        for _ in range(max_iter):
            # plain (absolute-error) least squares, as in the paper: rescaling rows by 1/f^{-1}
            # (relative error) rewards a curve that is small wherever there are data and rises
            # only near M = 1, the degenerate solution of the ratio equations
            coefs = [_mn_fit(ma, mb, np.exp(lnR[kk]), deg) for ma, mb, kk in data]
            if not estimate_ratios:
                break
            num = np.zeros(K - 1)
            den = np.zeros(K - 1)
            for (ma, mb, kk), cf in zip(data, coefs, strict=True):
                pa = np.polynomial.polynomial.polyval(ma, cf)
                pb = np.polynomial.polynomial.polyval(mb, cf)
                num += np.bincount(kk, weights=pa * pb, minlength=K - 1)
                den += np.bincount(kk, weights=pb * pb, minlength=K - 1)
            new = lnR.copy()
            good = (num > 0) & (den > 0)
            new[good] = np.log(num[good] / den[good])
            if np.all(new < 0):
                new *= span / new.sum()
            change = np.max(np.abs(new - lnR))
            lnR = new
            if change < tol:
                break
        return coefs, lnR

    def error(coefs, lnR, data):
        err = 0.0
        for (ma, mb, kk), cf in zip(data, coefs, strict=True):
            pa = np.polynomial.polynomial.polyval(ma, cf)
            pb = np.polynomial.polynomial.polyval(mb, cf)
            err += float(np.sum((pa - np.exp(lnR[kk]) * pb) ** 2))
        return err

    if degree is None:
        best = None
        train, test = subset(0), subset(1)
        for deg in range(2, 9):
            cf, lr = run(deg, train)
            e = error(cf, lr, test)
            if best is None or e < best[0] * (1 - 1e-3):
                best = (e, deg)
        degree = best[1]
    coefs, lnR = run(degree, subset(None))
    M = np.arange(levels) / top
    logx = np.full((levels, C), np.nan)
    for c in range(C):
        p = np.polynomial.polynomial.polyval(M, coefs[c])
        p = np.maximum.accumulate(p)
        good = p > 1e-6 * p[-1]
        logx[good, c] = np.log(p[good])
    inverse = _finalise(logx, None)
    lnt = np.concatenate([[0.0], np.cumsum(-lnR)])
    lnt += np.log(t).mean() - lnt.mean()
    return CameraResponse(inverse, levels, "mitsunaga_nayar", exposure_times=np.exp(lnt),
                          coefficients=np.stack(coefs, axis=1))


# ------------------------------------------------------------------------------------- merging
def _estimate_noise(Zt: np.ndarray, t: np.ndarray, inv: np.ndarray, q: np.ndarray, c: int,
                    max_pixels: int = 16384) -> tuple[float, float]:
    """Fit ``var(x) = a + b x`` (+ known quantisation ``q``), ``a, b >= 0``, from the differences
    ``x_{k+1} - r_k x_k`` of adjacent exposures (``r_k = t_{k+1} / t_k``) on a pixel subset."""
    K = Zt.shape[0]
    top = inv.shape[0] - 1
    flatz = Zt[:, c].reshape(K, -1)
    step = max(1, flatz.shape[1] // max_pixels)
    G = np.zeros((2, 2))
    h = np.zeros(2)
    for k in range(K - 1):
        za = flatz[k, ::step].astype(np.intp)
        zb = flatz[k + 1, ::step].astype(np.intp)
        ok = (za > 0) & (za < top) & (zb > 0) & (zb < top)
        za, zb = za[ok], zb[ok]
        if za.size == 0:
            continue
        r = t[k + 1] / t[k]
        xa, xb = inv[za, c], inv[zb, c]
        y = (xb - r * xa) ** 2 - (q[zb] + r * r * q[za])
        u0 = np.full(xa.size, 1 + r * r)
        u1 = xb + r * r * xa
        G += [[u0 @ u0, u0 @ u1], [u0 @ u1, u1 @ u1]]
        h += [u0 @ y, u1 @ y]
    if G[0, 0] <= 0:
        return 0.0, 0.0
    try:
        a, b = np.linalg.solve(G + 1e-30 * np.eye(2), h)
    except np.linalg.LinAlgError:
        a, b = -1.0, -1.0
    if a >= 0 and b >= 0:
        return float(a), float(b)
    # one of the two is clamped at zero: keep the better single-term fit
    fits = [(max(h[0] / G[0, 0], 0.0), 0.0), (0.0, max(h[1] / G[1, 1], 0.0) if G[1, 1] > 0 else 0.0)]
    sse = [G[0, 0] * f[0] ** 2 - 2 * h[0] * f[0] + G[1, 1] * f[1] ** 2 - 2 * h[1] * f[1] for f in fits]
    return fits[int(np.argmin(sse))]


def merge_hdr(images, exposure_times, response: CameraResponse, *, weighting: str = "variance",
              noise_model: tuple[float, float] | None = None, return_mask: bool = False):
    r"""Merge an exposure bracket into linear radiance (up to one global scale).

    Per pixel and channel, in the log domain,

    .. math::

        \ln E = \frac{\sum_k w_k(Z_k)\,(g(Z_k) - \ln \Delta t_k)}{\sum_k w_k(Z_k)}, \qquad
        g = \ln f^{-1},

    with ``w = 0`` at the clipped levels ``0`` and ``levels - 1``.  The default ``"variance"``
    weights are the inverse variance of ``ln E_k``: ``w = x^2 / var(x)`` with ``x = f^{-1}(Z)``
    (proportional to ``\Delta t_k^2 / var`` for a given pixel: exposure-aware, Granados et al.
    2010) and ``var(x) = \sigma_r^2 + x / N_{fw} + q(Z)``, ``q`` the quantisation variance
    ``(dx/dz)^2 / 12``.  ``(\sigma_r, N_{fw})`` come from ``noise_model`` or are estimated from the
    differences between adjacent exposures.  A pixel with no usable exposure gets the best
    bound: ``f^{-1}(top) / \Delta t_{min}`` (a lower bound) when it is clipped high, the upper
    bound ``f^{-1}(1) / \Delta t_{max}`` when it is black in every exposure, and the geometric
    mean of both bounds if both apply; never 0 or NaN.

    Parameters
    ----------
    images : array (K, H, W[, C]) or sequence, unsigned integers
    exposure_times : sequence of K floats, strictly increasing, seconds (for a Mitsunaga–Nayar
        response, pass ``response.exposure_times``)
    response : CameraResponse
        One channel is broadcast to all image channels.
    weighting : {"variance", "hat", "uniform", "gaussian"}
    noise_model : (read_noise, full_well) or None
        Read noise standard deviation as a fraction of full scale and the full-well capacity in
        electrons (``np.inf`` for no shot noise); None estimates them (``"variance"`` only).
    return_mask : bool
        Also return the (H, W, C) boolean mask of pixels saturated in every exposure (their
        value is the lower bound above).

    Returns
    -------
    radiance : ndarray (H, W, C) float32, > 0
    saturated : ndarray (H, W, C) bool, only if ``return_mask``

    References
    ----------
    P. E. Debevec and J. Malik, SIGGRAPH 1997 (merge equation); M. Granados et al., "Optimal HDR
    reconstruction with linear digital cameras", CVPR 2010 (inverse-variance weights).
    """
    if not isinstance(response, CameraResponse):
        raise ValueError("response: expected a CameraResponse from calibrate_debevec/robertson/mitsunaga_nayar")
    Z, _ = _as_stack(images, None)
    K, H, W, C = Z.shape
    t = _check_times(exposure_times, K)
    check_method(weighting, MERGE_WEIGHTINGS, "weighting")
    levels = response.levels
    if int(Z.max()) >= levels:
        raise ValueError(f"images: level {int(Z.max())} does not exist in a response with {levels} levels; "
                         "calibrate on images of the same bit depth")
    inv = np.asarray(response.inverse, dtype=np.float64)
    if inv.shape[1] == 1 and C > 1:
        inv = np.repeat(inv, C, axis=1)
    if inv.shape[1] != C:
        raise ValueError(f"response: has {inv.shape[1]} channels, the images have {C}; calibrate on the same images")
    if noise_model is not None:
        try:
            rn, fw = (float(v) for v in noise_model)
        except (TypeError, ValueError) as exc:
            raise ValueError("noise_model: pass (read_noise, full_well) or None") from exc
        if not (np.isfinite(rn) and rn >= 0 and fw > 0):
            raise ValueError(f"noise_model: need read_noise >= 0 and full_well > 0, got {noise_model!r}")
    top = levels - 1
    lnt = np.log(t)
    logx = np.log(inv)
    Zt = np.ascontiguousarray(np.moveaxis(Z, 3, 1))  # (K, C, H, W)
    if Zt.dtype != np.uint8 and levels <= 256:
        Zt = Zt.astype(np.uint8)
    wlut = np.empty((levels, C))
    if weighting == "variance":
        dx = np.gradient(inv, axis=0)
        q = dx**2 / 12.0
        for c in range(C):
            if noise_model is None:
                a, b = _estimate_noise(Zt, t, inv, q[:, c], c)
            else:
                a, b = rn**2, (0.0 if np.isinf(fw) else 1.0 / fw)
            wlut[:, c] = inv[:, c] ** 2 / (a + b * inv[:, c] + q[:, c])
    else:
        wlut[:] = _level_weights(weighting, levels)[:, None]
    wlut[0] = wlut[-1] = 0.0
    wlut /= wlut.max(axis=0, keepdims=True)
    wg = (wlut * logx).astype(np.float32)
    wf = wlut.astype(np.float32)
    num = np.zeros((C, H, W), np.float32)
    den = np.zeros((C, H, W), np.float32)
    for k in range(K):
        for c in range(C):
            z = Zt[k, c]
            lut_n = wg[:, c] - np.float32(lnt[k]) * wf[:, c]
            num[c] += np.take(lut_n, z)
            den[c] += np.take(wf[:, c], z)
    empty = den <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        lnE = num / den
    saturated = np.zeros((C, H, W), bool)
    if empty.any():
        ci, yi, xi = np.nonzero(empty)
        zz = Zt[:, ci, yi, xi].astype(np.int64)  # (K, n)
        hi = zz >= top
        lo = zz <= 0
        # lower bound from the shortest clipped-high exposure, upper from the longest black one
        k_hi = np.where(hi.any(axis=0), np.argmax(hi, axis=0), -1)
        k_lo = np.where(lo.any(axis=0), K - 1 - np.argmax(lo[::-1], axis=0), -1)
        lb = logx[top, ci] - lnt[np.maximum(k_hi, 0)]
        ub = logx[1, ci] - lnt[np.maximum(k_lo, 0)]
        val = np.where(k_hi >= 0, np.where(k_lo >= 0, 0.5 * (lb + ub), lb), ub)
        # a pixel can only be empty here if each of its levels is 0 or top
        lnE[ci, yi, xi] = val
        saturated[ci, yi, xi] = hi.all(axis=0)
    rad = np.exp(lnE, dtype=np.float32)
    rad = np.ascontiguousarray(np.moveaxis(rad, 0, 2))
    if return_mask:
        return rad, np.ascontiguousarray(np.moveaxis(saturated, 0, 2))
    return rad
