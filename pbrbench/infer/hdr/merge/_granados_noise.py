"""The noise estimate of Granados et al. (2010): read noise and gain from pairs of exposures,
for :func:`pbrbench.infer.hdr.merge.granados2010.merge_granados2010` when no noise model is given
(kept apart so that the method's module stays one readable room).  The registry versions a method
by its own module's source, so a change here must bump ``granados2010.VERSION``.

Reference: M. Granados, B. Ajdin, M. Wand, C. Theobalt, H.-P. Seidel and H. P. A. Lensch,
"Optimal HDR reconstruction with linear digital cameras", CVPR 2010.
"""

from __future__ import annotations

import functools

import numpy as np

from pbrbench.checks import check_int

__all__ = ["estimate_noise_levels"]


def estimate_noise_levels(Z: np.ndarray, t: np.ndarray, inv: np.ndarray, q: np.ndarray, c: int,
                          max_pixels: int = 4096, min_count: int = 8, n_bins: int = 48,
                          reweight: int = 2) -> tuple[float, float]:
    r"""Fit the camera noise model ``var(x) = a + b x`` (``a = sigma_r^2``, ``b = 1 / N_fw``,
    ``a, b >= 0``) of channel ``c`` from the spread of adjacent exposures.

    For each pair of adjacent exposures ``k, k+1`` (ratio ``r = t_{k+1} / t_k``) the
    differences ``d = x_{k+1} - r x_k`` of a pixel cancel its radiance and have

    .. math:: \mathrm{var}(d) = a (1 + r^2) + b (\bar x_{k+1} + r^2 \bar x_k)
              + \bar q_{k+1} + r^2 \bar q_k,

    with ``q`` the known quantisation variance.  Pixels are grouped by ``f^{-1}`` at the mean
    level of their 8 neighbours in exposure ``k`` (interpolated linearly between levels;
    independent of the pixel's own noise, so the grouping does not select the noise: grouping
    by the pixel's own level would) into ``n_bins`` bins of ``r x_k / 0.8`` per pair, finer at
    the dark end, and only the spread about each group's mean counts, so a calibration error
    or a mis-stated exposure time (a systematic offset of ``d``) is not taken for noise.
    Differences beyond 4 robust standard deviations of their group (``4 \cdot 1.4826`` MADs
    about the median: edges, motion) are dropped first.  Pairs where either level is black or
    clipped are left out, and so are groups whose prediction ``r x_k`` is above 0.8 (their
    partner is censored by clipping).  With ``s_g^2`` the variance of group ``g`` (``n_g``
    pixels), ``u_{0g} = 1 + r^2``, ``u_{1g}`` and ``\bar q_g`` its means of ``x_{k+1} + r^2 x_k``
    and ``q_{k+1} + r^2 q_k``, ``(a, b)`` is the weighted least-squares fit (relative errors)

    .. math:: \min_{a, b \ge 0} \sum_g w_g \left(s_g^2 - \bar q_g - a\, u_{0g} - b\, u_{1g}\right)^2,
              \qquad w_g = \frac{n_g}{\max(\hat v_g, v_{10})^2},

    over the groups of at least ``min_count`` pixels, ``a`` or ``b`` clamped at 0 if the
    unconstrained fit is negative.  ``\hat v_g`` is ``s_g^2`` in the first pass and the fitted
    model ``a u_{0g} + b u_{1g} + \bar q_g`` in each of ``reweight`` further passes
    (iteratively reweighted: weights from the noisy ``s_g^2`` themselves favour the groups
    whose spread came out low and bias the fit low, the more so the fewer pixels a group has;
    a first fit of ``a = b = 0`` is reweighted too, from the quantisation-only model: kept as
    it was, it made the estimate jump between ``b = 0`` and the reweighted ``b`` when a few
    low-spread groups tipped the first fit, as on one of four renders of the HDR task's
    noise-free bracket under a linear response, 3.4e-4 against 0 and a 40 % higher error);
    the floor ``v_{10}``, the 10th percentile of the ``s_g^2``, keeps a few groups of (nearly)
    constant differences (a black or clipped plateau seen through a coarse level) from
    dominating the fit.

    ``Z``: (K, H, W, C) levels, each below ``len(inv)``; ``t``: (K,) times; ``inv``: (levels, C)
    inverse response (gauge ``inv[-1] = 1``); ``q``: (levels,) quantisation variance of channel
    ``c``; ``max_pixels``: at most that many pixels per pair are used, a regular grid of step
    ``ceil(sqrt((H - 2) (W - 2) / max_pixels))``.  Returns ``(a, b)``; ``(0, 0)`` when no group
    has ``min_count`` pixels.
    """
    max_pixels = check_int(max_pixels, "max_pixels", 1)
    min_count = check_int(min_count, "min_count", 1)
    n_bins = check_int(n_bins, "n_bins", 1)
    reweight = check_int(reweight, "reweight", 0)
    return _noise_levels(Z, t, inv, [(c, np.asarray(q, dtype=np.float64))], max_pixels, min_count, n_bins,
                         reweight)[0]


def _noise_levels(Z, t, inv, channels, max_pixels=4096, min_count=8, n_bins=48, reweight=2):
    """:func:`estimate_noise_levels` of several channels at once (one sort and one set of group
    sums for all): ``channels`` is a list of ``(c, q_c)``; returns one ``(a, b)`` per entry."""
    K, H, W = Z.shape[:3]
    top = inv.shape[0] - 1
    if H < 3 or W < 3:
        return [(0.0, 0.0)] * len(channels)
    step = max(1, int(np.ceil(np.sqrt((H - 2) * (W - 2) / max_pixels))))
    m = (K - 1) * n_bins  # groups per channel
    parts = []
    for j, (c, qc) in enumerate(channels):
        part = _pair_differences(Z, t, np.ascontiguousarray(inv[:, c], dtype=np.float64), qc, c, top, step, n_bins)
        if part is not None:
            part[0] += j * m
            parts.append(part)
    if not parts:
        return [(0.0, 0.0)] * len(channels)
    g, d, qs, u1 = (np.concatenate(a) for a in zip(*parts, strict=True))
    M = m * len(channels)
    # robust rejection: median and MAD per group
    med, mad = _group_median_mad(g, d, M)
    dev = d - np.take(med, g)
    keep = np.abs(dev) <= np.take(4.0 * 1.4826 * mad + 1e-12, g)
    if not keep.all():
        g, dev, qs, u1 = g[keep], dev[keep], qs[keep], u1[keep]
    n = np.bincount(g, minlength=M).astype(float)
    nn = np.maximum(n, 1.0)
    # the variance about the group mean from the sums of the deviations from the group median
    # (one pass; the median is close to the mean, so nothing cancels)
    s1 = np.bincount(g, weights=dev, minlength=M)
    var = np.maximum(np.bincount(g, weights=dev * dev, minlength=M) - s1 * s1 / nn, 0.0) / np.maximum(nn - 1, 1)
    qs = np.bincount(g, weights=qs, minlength=M) / nn
    u1 = np.bincount(g, weights=u1, minlength=M) / nn
    r = t[1:] / t[:-1]
    u0 = np.repeat(1.0 + r * r, n_bins)
    out = []
    for j in range(len(channels)):
        sl = slice(j * m, (j + 1) * m)
        out.append(_fit_noise_model(n[sl], var[sl], qs[sl], u0, u1[sl], min_count, reweight))
    return out


def _fit_noise_model(n, var, qs, u0, u1, min_count, reweight) -> tuple[float, float]:
    """``(a, b)`` from the group statistics of one channel: pixel count, variance of ``d``,
    mean ``q_b + r^2 q_a``, ``1 + r^2`` and mean ``x_b + r^2 x_a``."""
    good = n >= min_count
    if not good.any():
        return 0.0, 0.0
    u0, u1, v, n, qg = u0[good], u1[good], var[good], n[good], qs[good]
    y = v - qg
    # relative weights n / var^2, the variance from the fitted model after the first pass (with
    # the noisy group variances themselves the weights favour the groups whose spread came out
    # low: the fit is biased low, the more so the fewer pixels per group); the floor keeps a few
    # groups of (nearly) constant differences (a black or clipped plateau seen through a coarse
    # level) from dominating the fit
    floor = max(float(np.percentile(v, 10)), 1e-30)
    model = v
    for _ in range(1 + reweight):
        a, b = _weighted_fit(n / np.maximum(model, floor) ** 2, u0, u1, y)
        model = a * u0 + b * u1 + qg
    return a, b


def _weighted_fit(wgt, u0, u1, y) -> tuple[float, float]:
    """Weighted least squares ``y ~ a u0 + b u1`` with ``a, b >= 0`` (a negative one of the
    unconstrained pair clamped at 0: the better of the two one-term fits)."""
    U = np.stack([u0, u1])
    Uw = U * wgt
    G = Uw @ U.T
    h = Uw @ y
    det = G[0, 0] * G[1, 1] - G[0, 1] ** 2
    if det > 1e-12 * G[0, 0] * G[1, 1]:
        a = (G[1, 1] * h[0] - G[0, 1] * h[1]) / det
        b = (G[0, 0] * h[1] - G[0, 1] * h[0]) / det
        if a >= 0 and b >= 0:
            return float(a), float(b)
    fits = [(max(h[0] / G[0, 0], 0.0) if G[0, 0] > 0 else 0.0, 0.0),
            (0.0, max(h[1] / G[1, 1], 0.0) if G[1, 1] > 0 else 0.0)]
    sse = [float(np.sum(wgt * (y - f[0] * u0 - f[1] * u1) ** 2)) for f in fits]
    return fits[int(np.argmin(sse))]


def _neighbour_mean(Z, x, c, step):
    """``f^{-1}`` at the mean level of the 8 neighbours of the grid pixels ``Z[k, 1::step,
    1::step, c]`` of every exposure ``k < K - 1`` (the table ``x`` interpolated linearly between
    levels), shape (K - 1, ny, nx).  The levels are summed as integers: one lookup per pixel
    instead of eight."""
    H, W = Z.shape[1:3]
    top = x.size - 1
    acc = None
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                z = Z[:-1, 1 + dy:H - 1 + dy:step, 1 + dx:W - 1 + dx:step, c]
                if acc is None:
                    acc = z.astype(np.uint16 if 8 * top < 1 << 16 else np.uint32)
                else:
                    np.add(acc, z, out=acc)
    if 8 * top < 1 << 16:  # a table of x at every eighth of a level
        return np.take(np.interp(np.arange(8 * top + 1) / 8.0, np.arange(top + 1), x), acc)
    lo = np.minimum(acc >> 3, top - 1)
    return np.take(x, lo) + (acc / 8.0 - lo) * (np.take(x, lo + 1) - np.take(x, lo))


@functools.lru_cache(maxsize=8)
def _bin_table(n_bins: int):
    """Lookup tables for :func:`_bin_index`: the grid of ``G > n_bins^2`` cells on [0, 1] (a
    power of two, so ``v G`` is exact), the bin of each cell's left end and the next edge."""
    edges = np.linspace(0.0, 1.0, n_bins + 1) ** 2  # finer bins at the dark end
    G = 1 << int(np.ceil(np.log2(n_bins * n_bins + 1)))
    left = np.clip(np.searchsorted(edges, np.arange(G + 1) / G, side="right") - 1, 0, n_bins - 1)
    nxt = np.append(edges, np.inf)[left + 1]
    nxt[left == n_bins - 1] = np.inf
    left.flags.writeable = nxt.flags.writeable = False
    return G, left, nxt


def _bin_index(v, table):
    """``clip(searchsorted(edges, v, "right") - 1, 0, n_bins - 1)`` for ``0 <= v <= 1`` and the
    quadratic edges ``linspace(0, 1, n_bins + 1) ** 2``, by table (:func:`_bin_table`): a cell
    is narrower than any bin, so it holds at most one edge."""
    G, left, nxt = table
    j = (v * G).astype(np.intp)
    np.minimum(j, G, out=j)
    return np.take(left, j) + (v >= np.take(nxt, j))


def _pair_differences(Z, t, x, q, c, top, step, n_bins):
    """The grid pixels of every adjacent pair ``k, k+1`` used by :func:`estimate_noise_levels`:
    ``[group (gid + k n_bins), d = x_b - r x_a, q_b + r^2 q_a, x_b + r^2 x_a]``, or None when
    no pixel qualifies."""
    K, H, W = Z.shape[:3]
    ys, xs = slice(1, H - 1, step), slice(1, W - 1, step)
    r = t[1:] / t[:-1]
    prox = _neighbour_mean(Z, x, c, step)
    za, zb = Z[:-1, ys, xs, c], Z[1:, ys, xs, c]
    ok = (za > 0) & (za < top) & (zb > 0) & (zb < top) & (r[:, None, None] * prox <= 0.8)
    sel = np.flatnonzero(ok)
    if sel.size == 0:
        return None
    k = np.repeat(np.arange(K - 1), np.count_nonzero(ok.reshape(K - 1, -1), axis=1))
    rr = np.take(r, k)
    za = np.take(za, sel).astype(np.intp)
    zb = np.take(zb, sel).astype(np.intp)
    g = _bin_index(np.take(prox, sel) * rr / 0.8, _bin_table(n_bins))
    g += k * n_bins
    xa, xb = np.take(x, za), np.take(x, zb)
    r2 = rr * rr
    return [g, xb - rr * xa, np.take(q, zb) + r2 * np.take(q, za), xb + r2 * xa]


def _group_median_mad(g, d, m):
    """Per group ``0 .. m-1`` of the values ``d``: the median ``s[n // 2]`` and the median
    absolute deviation about it (the ``(n // 2)``-th smallest ``|s - median|``), with ``s`` the
    group's ``n`` values in increasing order; 0 for empty groups.

    One sort of ``g S + d`` (``S`` a power of two above the span of ``d``) orders every group;
    the deviations of a sorted group are two sorted runs (below and above the median), whose
    order statistic a vectorised bisection over all groups finds without a second sort."""
    cnt = np.bincount(g, minlength=m)
    lo_d = float(d.min())
    S = 2.0 ** np.ceil(np.log2(max(float(d.max()) - lo_d, 1e-300) * 1.25 + 1e-300))
    s = np.sort(g * S + (d - lo_d))
    s -= np.repeat(np.arange(m) * S - lo_d, cnt)
    has = np.flatnonzero(cnt)
    n = cnt[has]
    st = np.cumsum(cnt)[has] - n
    half = n // 2
    mi = st + half  # index of the median
    md = s[mi]
    # left run L[i] = md - s[mi - 1 - i] (i < half), right run R[j] = s[mi + j] - md (j < n - half),
    # both increasing; the (half + 1) smallest of their union take i from L: the largest i in
    # [lo, half] with not (i >= 1 and half + 1 - i < n - half and L[i - 1] > R[half + 1 - i])
    last = s.size - 1
    lo = (n % 2 == 0).astype(np.intp)  # max(0, 2 half + 1 - n)
    hi = half.copy()
    while True:
        act = np.flatnonzero(lo < hi)
        if act.size == 0:
            break
        a_lo, a_hi = lo[act], hi[act]
        mid = (a_lo + a_hi + 1) // 2
        jj = half[act] + 1 - mid  # >= 1
        m_a = mi[act]
        over = (jj < n[act] - half[act]) & (md[act] - s[m_a - mid] > s[np.minimum(m_a + jj, last)] - md[act])
        hi[act] = np.where(over, mid - 1, a_hi)
        lo[act] = np.where(over, a_lo, mid)
    left = np.where(lo >= 1, md - s[mi - lo], -np.inf)
    right = s[mi + half - lo] - md
    med = np.zeros(m)
    mad = np.zeros(m)
    med[has] = md
    mad[has] = np.maximum(left, right)
    return med, mad
