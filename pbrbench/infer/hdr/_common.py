"""Shared pieces of the HDR methods: input checks, level weights, pixel sampling, finalising.

Calibration (:mod:`~pbrbench.infer.hdr.debevec1997`, :mod:`~pbrbench.infer.hdr.robertson2003`,
:mod:`~pbrbench.infer.hdr.mitsunaga1999`) uses :func:`as_stack`, :func:`check_times`,
:func:`level_weights`, :func:`sample_pixels` and :func:`finalise`; merging
(:mod:`pbrbench.infer.hdr.merge`) uses :func:`as_stack`, :func:`check_times`,
:func:`check_response`, :func:`response_table`, :func:`check_noise_model`,
:func:`estimate_noise`, :func:`fill_unexposed` (or :func:`unexposed_bounds`) and
:func:`merge_output`.
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_array, as_float_array, check_int, check_seed
from pbrbench.infer.hdr.response import CameraResponse

__all__ = [
    "CALIBRATION_WEIGHTINGS",
    "as_stack",
    "check_informative",
    "check_noise_model",
    "check_response",
    "check_times",
    "prepare_bracket",
    "estimate_noise",
    "fill_unexposed",
    "finalise",
    "level_weights",
    "merge_output",
    "response_table",
    "sample_pixels",
    "unexposed_bounds",
]

CALIBRATION_WEIGHTINGS = ("hat", "uniform", "gaussian")


# ----------------------------------------------------------------------------------- validation
def as_stack(images, bit_depth: int | None = None) -> tuple[np.ndarray, int]:
    """Return ``(Z (K, H, W, C) unsigned ints, levels)``; raise ValueError on bad input."""
    if isinstance(images, np.ndarray):
        arr = images
    else:
        try:
            items = [as_array(im, "images") for im in images]
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
        try:
            bit_depth = check_int(bit_depth, "bit_depth", 1, 16)
        except ValueError:
            raise ValueError(f"bit_depth={bit_depth!r}: must be an integer in 1..16, or None to infer it") from None
        levels = 1 << bit_depth
        if int(arr.max()) >= levels:
            raise ValueError(f"images: level {int(arr.max())} exceeds bit_depth={bit_depth}; pass the right bit_depth")
    elif arr.dtype == np.uint8:
        levels = 256
    else:
        levels = 1 << max(8, int(np.ceil(np.log2(int(arr.max()) + 1))))
    return arr, levels


# numpydoc fragments shared by the methods' docstrings (pbrbench.infer._docstring)
DOCS = {
    "bracket": """\
images : array (K, H, W[, C]) or sequence, unsigned integers
exposure_times : sequence of K floats, strictly increasing, seconds""",
    "merge_bracket": """\
images : array (K, H, W[, C]) or sequence, unsigned integers
exposure_times : sequence of K floats, strictly increasing, seconds (for a
    ``"mitsunaga1999"`` response, pass ``response.exposure_times``)""",
    "calibrated": """\
CameraResponse
    With ``method`` the method's name in :data:`pbrbench.infer.hdr.CALIBRATION_METHODS`.""",
}


def check_times(exposure_times, K: int) -> np.ndarray:
    """``exposure_times`` as a (K,) float array, finite, > 0 and strictly increasing."""
    t = as_array(exposure_times, "exposure_times")
    if t.ndim != 1:
        raise ValueError(f"exposure_times: expected a 1-D sequence, got shape {t.shape}")
    t = as_float_array(t, "exposure_times", ndim=(1,))
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


# ------------------------------------------------------------------------------------- weights
def level_weights(name: str, levels: int) -> np.ndarray:
    """Weight per level (peak 1), zero at the clipped ends 0 and ``levels - 1``.

    ``"hat"``: ``min(z, top - z)`` (Debevec & Malik 1997); ``"uniform"``; ``"gaussian"``:
    ``exp(-4 ((z - mid) / mid)^2)`` (Robertson et al. 2003).
    """
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
def check_informative(Z: np.ndarray, levels: int) -> None:
    """Refuse a bracket that says nothing about the response: in some channel no pixel has two
    different unclipped levels in two exposures (all exposures alike, or all clipped)."""
    top = levels - 1
    for c in range(Z.shape[3]):
        z = Z[..., c].reshape(Z.shape[0], -1)
        ok = (z > 0) & (z < top)
        lo = np.where(ok, z, top + 1).min(axis=0)
        hi = np.where(ok, z, -1).max(axis=0)
        if not (hi > lo).any():
            raise ValueError(
                f"images: channel {c} carries no information about the response: no pixel changes level between "
                "exposures (the exposures are alike, constant or clipped); use a bracket of different exposure "
                "times over a scene with varied brightness")



def prepare_bracket(images, exposure_times, bit_depth):
    """The checked input of every calibration: ``(Z, levels, t)`` from :func:`as_stack`,
    :func:`check_times` and :func:`check_informative`, in that order."""
    Z, levels = as_stack(images, bit_depth)
    t = check_times(exposure_times, Z.shape[0])
    check_informative(Z, levels)
    return Z, levels, t


def sample_pixels(Z: np.ndarray, levels: int, samples: int, seed, per_level: int = 2) -> list[np.ndarray]:
    """Flat pixel indices per channel: ``samples`` random pixels, plus pixels that cover levels.

    Every level that occurs in any exposure of a channel is represented by at least
    ``min(per_level, its count)`` sampled pixels.  Deterministic given ``seed``.
    """
    check_seed(seed)
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


def finalise(logx: np.ndarray, counts: np.ndarray | None) -> np.ndarray:
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
        # not at import: the CLI's methods tables import this module
        from scipy.optimize import isotonic_regression

        v[ok] = isotonic_regression(v[ok], weights=w, increasing=True).x
        v = _extrapolate(v, ok)
        v = np.maximum.accumulate(v + ramp)
        inv[:, c] = np.exp(v - v[-1])
    return inv


# ------------------------------------------------------------------------------------- merging
def check_response(response) -> None:
    """Raise ``ValueError`` unless ``response`` is a :class:`CameraResponse`."""
    if not isinstance(response, CameraResponse):
        raise ValueError("response: expected a CameraResponse from calibrate_response "
                         "(or calibrate_debevec1997 / calibrate_robertson2003 / calibrate_mitsunaga1999)")


def response_table(response: CameraResponse, Z: np.ndarray) -> np.ndarray:
    """The (levels, C) float64 inverse of ``response`` for the images ``Z`` (K, H, W, C).

    One response channel is broadcast to every image channel.  Raises ``ValueError`` when a
    level of ``Z`` is not in the response's table or when the channel counts differ.
    """
    C = Z.shape[3]
    levels = response.levels
    if int(Z.max()) >= levels:
        raise ValueError(f"images: level {int(Z.max())} does not exist in a response with {levels} levels; "
                         "calibrate on images of the same bit depth")
    inv = np.asarray(response.inverse, dtype=np.float64)
    if inv.shape[1] == 1 and C > 1:
        inv = np.repeat(inv, C, axis=1)
    if inv.shape[1] != C:
        raise ValueError(f"response: has {inv.shape[1]} channels, the images have {C}; calibrate on the same images")
    return inv


def check_noise_model(noise_model) -> tuple[float, float] | None:
    """``(read_noise, full_well)`` as floats (``read_noise >= 0``, ``full_well > 0``), or None."""
    if noise_model is None:
        return None
    try:
        rn, fw = (float(v) for v in noise_model)
    except (TypeError, ValueError) as exc:
        raise ValueError("noise_model: pass (read_noise, full_well) or None") from exc
    if not (np.isfinite(rn) and rn >= 0 and fw > 0):
        raise ValueError(f"noise_model: need read_noise >= 0 and full_well > 0, got {noise_model!r}")
    return rn, fw


def estimate_noise(Zt: np.ndarray, t: np.ndarray, inv: np.ndarray, q: np.ndarray, c: int,
                   max_pixels: int = 16384) -> tuple[float, float]:
    """Fit ``var(x) = a + b x`` (+ known quantisation ``q``), ``a, b >= 0``, from the differences
    ``x_{k+1} - r_k x_k`` of adjacent exposures (``r_k = t_{k+1} / t_k``) on a pixel subset.

    ``Zt``: (K, C, H, W) levels; ``inv``: (levels, C) inverse response; ``c``: the channel.
    """
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


def fill_unexposed(lnE: np.ndarray, empty: np.ndarray, Zt: np.ndarray, logx: np.ndarray,
                   lnt: np.ndarray, top: int) -> np.ndarray:
    """Give the pixels with no usable exposure (``empty``, (C, H, W)) the best bound on ``ln E``.

    ``Zt``: (K, C, H, W) levels; ``logx``: (levels, C) ``ln f^{-1}``; ``lnt``: (K,) log times;
    ``top``: the top level.  A pixel can only be empty if each of its levels is 0 or ``top``:
    clipped high, it gets the lower bound ``ln f^{-1}(top) - ln t`` of its shortest clipped
    exposure; black in every exposure, the upper bound ``ln f^{-1}(1) - ln t`` of its longest
    black one; both, their mean (:func:`unexposed_bounds`).  ``lnE`` is changed in place.
    Returns the (C, H, W) mask of pixels saturated in every exposure.
    """
    K, C, H, W = Zt.shape
    saturated = np.zeros((C, H, W), bool)
    if empty.any():
        ci, yi, xi = np.unravel_index(np.flatnonzero(empty), empty.shape)  # np.nonzero, faster
        lnE[ci, yi, xi], saturated[ci, yi, xi] = unexposed_bounds(Zt, ci, yi, xi, logx, lnt, top)
    return saturated


def unexposed_bounds(Zt: np.ndarray, ci, yi, xi, logx: np.ndarray, lnt: np.ndarray, top: int):
    """The bounds of :func:`fill_unexposed` for the pixels ``(ci, yi, xi)`` of ``Zt`` (K, C,
    H, W) that no exposure measures: ``(ln E, saturated in every exposure)``, one each."""
    K = Zt.shape[0]
    zz = Zt[:, ci, yi, xi]  # (K, n), unsigned levels
    hi = zz >= top
    lo = zz == 0
    # lower bound from the shortest clipped-high exposure, upper from the longest black one
    # (-1: none); a loop over the few exposures beats argmax along the first axis
    k_hi = np.full(zz.shape[1], -1, np.intp)
    k_lo = np.full(zz.shape[1], -1, np.intp)
    for k in range(K - 1, -1, -1):
        k_hi[hi[k]] = k
    for k in range(K):
        k_lo[lo[k]] = k
    lb = logx[top, ci] - lnt[np.maximum(k_hi, 0)]
    ub = logx[1, ci] - lnt[np.maximum(k_lo, 0)]
    val = np.where(k_hi >= 0, np.where(k_lo >= 0, 0.5 * (lb + ub), lb), ub)
    return val, hi.all(axis=0)


def merge_output(lnE: np.ndarray, saturated: np.ndarray, return_mask: bool):
    """The merge result from ``ln E`` and the saturation mask, both (C, H, W): radiance (H, W, C)
    float32, and the (H, W, C) mask when ``return_mask``."""
    rad = np.exp(lnE, dtype=np.float32)
    rad = np.ascontiguousarray(np.moveaxis(rad, 0, 2))
    if return_mask:
        return rad, np.ascontiguousarray(np.moveaxis(saturated, 0, 2))
    return rad
