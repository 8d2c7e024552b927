"""Shared pieces of the photometric-stereo methods: result type, checks, the blocked accumulation.

A method checks its inputs with :func:`prepare` (which returns a :class:`Problem`), builds and
solves per-pixel normal equations with :func:`accumulate` and :func:`sym_solve` (or
:func:`weighted_fit` for reweighted fits), and turns the solution into a
:class:`PhotometricStereoResult` with :func:`finish` (per-channel albedo, residual, validity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_int, check_mask, check_number
from pbrbench.infer._scale import max_abs, pow2_exponent, robust_norm

__all__ = [
    "PhotometricStereoResult",
    "Problem",
    "accumulate",
    "check_intensities",
    "check_lights",
    "DOCS",
    "check_sums",
    "cofactors",
    "finish",
    "least_squares",
    "measurements",
    "outer6",
    "prepare",
    "reject_outliers",
    "scatter",
    "sym_solve",
    "weighted_fit",
]


@dataclass(frozen=True)
class PhotometricStereoResult:
    """Output of every photometric-stereo method.

    Attributes
    ----------
    normals : (H, W, 3) unit normals in the camera frame; (0, 0, 0) where not ``valid``.
    albedo : (H, W) or (H, W, C) albedo (per channel for colour input); 0 where not ``valid``.
    residual : (H, W) RMS difference between the fitted model and the used measurements, over
        the used lights and all channels, in image units divided by the source intensity
        (``intensities``; image units when it is not given); 0 where not ``valid``. It is formed
        from the normal equations, so its floor is ~1e-8 of the brightness. For the robust
        method it is the RMS over the lights it kept as inliers.
    n_used : (H, W) int, number of lights used per pixel (lit, unsaturated, and for the robust
        method not rejected as outliers).
    valid : (H, W) bool, inside the mask with >= 3 used lights of independent directions.
    """

    normals: np.ndarray
    albedo: np.ndarray
    residual: np.ndarray
    n_used: np.ndarray
    valid: np.ndarray


def check_lights(lights, k: int) -> np.ndarray:
    """``lights`` as a (k, 3) float array of >= 3 non-zero, non-coplanar source vectors."""
    s = as_float_array(lights, "lights", ndim=(2,))
    if s.shape != (k, 3):
        raise ValueError(f"lights: expected shape ({k}, 3) (one source vector per image), got {s.shape}")
    check_finite(s, "lights")
    if k < 3:
        raise ValueError(f"lights: photometric stereo needs at least 3 lights, got {k}; add images under more sources")
    norms = robust_norm(s, axis=1)   # lengths are intensities: 1e-300 is small, not zero
    if np.any(norms <= 0):
        bad = np.flatnonzero(norms <= 0).tolist()
        raise ValueError(f"lights: light(s) {bad} are zero vectors; give each light a direction toward the source")
    sv = np.linalg.svd(s / norms[:, None], compute_uv=False)
    if sv[2] < 1e-6 * sv[0]:
        rank = int(np.sum(sv > 1e-6 * sv[0]))
        raise ValueError(
            f"lights: the light matrix is degenerate (rank {rank} < 3: the directions are "
            f"{'collinear' if rank <= 1 else 'coplanar'}); normals are not determined; use at least "
            "3 lights whose directions are not in one plane")
    return s


def check_intensities(intensities, k: int, nc: int) -> np.ndarray:
    """Source intensities as a (k, nc) float array, all finite and > 0 (ones when None)."""
    if intensities is None:
        return np.ones((k, nc))
    e = as_float_array(intensities, "intensities", ndim=(1, 2))
    if e.shape[0] != k or (e.ndim == 2 and e.shape[1] not in (1, nc)):
        raise ValueError(f"intensities: expected shape ({k},) or ({k}, {nc}), got {e.shape}")
    check_finite(e, "intensities")
    if np.any(e <= 0):
        raise ValueError("intensities: every intensity must be > 0; drop images whose source is off")
    return np.broadcast_to(e.reshape(k, -1), (k, nc)).astype(float)


def cofactors(a):
    """Cofactors and determinant of batched symmetric 3x3 matrices (pixels along the last axis).

    ``a``: (6, N) packed as (xx, yy, zz, xy, xz, yz).  Returns ``(c00, c01, c02, c11, c12, c22,
    det)``: the adjugate ``adj(A) = det(A) A^{-1}`` (symmetric, so six entries) and
    ``det(A) = a_xx c00 + a_xy c01 + a_xz c02``.
    """
    axx, ayy, azz, axy, axz, ayz = a
    c00 = ayy * azz - ayz * ayz
    c01 = axz * ayz - axy * azz
    c02 = axy * ayz - axz * ayy
    c11 = axx * azz - axz * axz
    c12 = axy * axz - axx * ayz
    c22 = axx * ayy - axy * axy
    det = axx * c00 + axy * c01 + axz * c02
    return c00, c01, c02, c11, c12, c22, det


def sym_solve(a, b, cof=None):
    """Solve batched symmetric 3x3 systems ``A x = b`` by cofactors (pixels along the last axis).

    ``a``: (6, N) packed as (xx, yy, zz, xy, xz, yz); ``b``: (3, N); ``cof``: ``cofactors(a)``
    when the caller has them already.
    Returns ``(x, ok)``: (3, N) solutions and a flag for well-conditioned systems (others 0).
    """
    c00, c01, c02, c11, c12, c22, det = cofactors(a) if cof is None else cof
    tr = a[0] + a[1] + a[2]
    t = tr * (1.0 / 3.0)
    ok = det > 1e-9 * (t * t * t)   # a product, not ** 3: NumPy's power is ~17x slower than two multiplies
    inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    b0, b1, b2 = b
    x = np.empty_like(b)
    np.multiply(c00 * b0 + c01 * b1 + c02 * b2, inv_det, out=x[0])
    np.multiply(c01 * b0 + c11 * b1 + c12 * b2, inv_det, out=x[1])
    np.multiply(c02 * b0 + c12 * b1 + c22 * b2, inv_det, out=x[2])
    return x, ok


def outer6(s):
    """(K, 7) packed outer products ``S_k S_k^T`` (xx, yy, zz, xy, xz, yz) and a column of ones.

    ``outer6(s).T @ w`` gives the normal matrices (rows 0-5) and the weight sums (row 6).
    """
    return np.stack([s[:, 0] ** 2, s[:, 1] ** 2, s[:, 2] ** 2,
                     s[:, 0] * s[:, 1], s[:, 0] * s[:, 2], s[:, 1] * s[:, 2],
                     np.ones(len(s))], axis=1)


def weighted_fit(w, j, s, s6):
    """Per-pixel weighted least squares ``min_g sum_k w_k (S_k . g - j_k)^2``.

    ``w``, ``j``: (K, N) weights and measurements; ``s``: (K, 3); ``s6``: (K, 6).
    Returns ``(g, ok, a, b)`` with the normal-equation matrices ``a`` (6, N) and ``b`` (3, N).
    """
    a = s6.T @ w
    b = s.T @ (w * j)
    g, ok = sym_solve(a[:6], b)
    return g, ok, a, b


_CHUNK = 4096  # pixels per block: temporaries stay in cache, and the small GEMMs stay
# below the size where BLAS starts threads (whose start-up costs more than the product)


@dataclass
class Problem:
    """Checked inputs of one photometric-stereo call (built by :func:`prepare`).

    ``img`` (K, H, W, C) images; ``colour``: the input had a channel axis; ``s`` (K, 3) lights;
    ``s7`` their :func:`outer6`; ``m`` (H, W) mask; ``full``: the mask is everything; ``sel``:
    None or the flat indices of the mask; ``flat`` (K, H*W, C) view of the images; ``ein``:
    (K, C) intensities or None; ``thr``, ``sat``, ``min_lights``: the classification options.
    """

    img: np.ndarray
    colour: bool
    k: int
    h: int
    w: int
    nc: int
    s: np.ndarray
    s7: np.ndarray
    m: np.ndarray
    full: bool
    sel: np.ndarray | None
    flat: np.ndarray
    ein: np.ndarray | None
    thr: float
    sat: float | None
    min_lights: int
    scale: tuple[int, int] = (0, 0)   # (albedo, residual) powers of two undone by finish()


def prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights) -> Problem:
    """Check the inputs shared by every method and return them as a :class:`Problem`."""
    img = as_float_array(images, "images", ndim=(3, 4))
    k = img.shape[0]
    colour = img.ndim == 4
    if not colour:
        img = img[..., None]
    _, h, w, nc = img.shape
    s = check_lights(lights, k)
    m = check_mask(mask, (h, w))
    e = check_intensities(intensities, k, nc)
    thr = check_number(shadow_threshold, "shadow_threshold", lo=0.0, hi=1.0, hi_open=True)
    if saturation is not None:
        check_number(saturation, "saturation", lo=0.0, lo_open=True)
    if isinstance(min_lights, bool) or check_int(min_lights, "min_lights", 1) < 3:
        raise ValueError(f"min_lights: must be >= 3 (three unknowns per pixel), got {min_lights!r}")
    if int(min_lights) > k:
        raise ValueError(f"min_lights: {min_lights!r} is more than the {k} images; no pixel could be solved: "
                         f"pass min_lights between 3 and {k}")
    flat_m = m.ravel()
    full = bool(flat_m.all())
    sat = None if saturation is None else float(saturation)
    # magnitudes near 1e+-300 overflow the normal equations: rescale exactly by powers of two
    # (normals unchanged; albedo and residual scaled back in finish); ordinary input untouched
    ei = pow2_exponent(max_abs(img, np.broadcast_to(m[None, :, :, None], img.shape)))
    ee = pow2_exponent(float(e.max()))
    es = pow2_exponent(float(robust_norm(s, axis=1).max()))
    if ei or ee or es:
        img, e, s = np.ldexp(img, -ei), np.ldexp(e, -ee), np.ldexp(s, -es)
        sat = None if sat is None else float(np.ldexp(sat, -ei))
    return Problem(img=img, colour=colour, k=k, h=h, w=w, nc=nc, s=s, s7=outer6(s), m=m, full=full,
                   sel=None if full else np.flatnonzero(flat_m), flat=img.reshape(k, h * w, nc),
                   ein=None if intensities is None else e, thr=thr,
                   sat=sat, min_lights=int(min_lights), scale=(ei - ee - es, ei - ee))


def accumulate(p: Problem, *, used_in=None, keep=False):
    """One blocked pass over the measurements: classify and build the normal equations.

    A measurement is used when its intensity-normalised channel sum exceeds ``p.thr`` times the
    pixel's brightest one and no channel reaches ``p.sat``; ``used_in`` (K, N) replaces this
    classification.  Returns ``a`` (7, N), ``b`` (C, 3, N) per channel, ``bsum`` (3, N) for the
    shared geometry, ``q`` (C, N) = sum of used squared measurements, and when ``keep`` the
    (K, N) channel-sum measurements ``jsum`` and the ``used`` flags (else None, None).
    """
    flat, sel, e, thr, saturation, s, s7 = p.flat, p.sel, p.ein, p.thr, p.sat, p.s, p.s7
    k, hw, nc = flat.shape
    n = hw if sel is None else sel.size
    a = np.empty((7, n))
    b = np.empty((nc, 3, n))
    bsum = b[0] if nc == 1 else np.empty((3, n))
    q = np.empty((nc, n))
    jsum_all = np.empty((k, n)) if keep else None
    used_all = np.empty((k, n), dtype=bool) if keep else None
    for start in range(0, n, _CHUNK):
        stop = min(start + _CHUNK, n)
        out = slice(start, stop)
        mc = flat[:, out, :] if sel is None else flat[:, sel[out], :]  # (K, n, C)
        jc = mc if e is None else mc / e[:, None, :]
        js = jc[..., 0] if nc == 1 else jc.sum(axis=-1)
        if used_in is None:
            u = js > thr * js.max(axis=0)  # never true where the peak is <= 0
            if saturation is not None:
                u &= ~np.any(mc >= saturation, axis=-1)
        else:
            u = used_in[:, out]
        wt = u.astype(float)
        a[:, out] = s7.T @ wt
        wj = wt * js
        bsum[:, out] = s.T @ wj
        if nc == 1:
            q[0, out] = np.einsum("kn,kn->n", wj, js)
        else:
            for c in range(nc):
                wjc = wt * jc[..., c]
                b[c][:, out] = s.T @ wjc
                q[c, out] = np.einsum("kn,kn->n", wjc, jc[..., c])
        if keep:
            jsum_all[:, out] = js
            used_all[:, out] = u
    return a, b, bsum, q, jsum_all, used_all


def check_sums(p: Problem, bsum, q) -> None:
    """Report NaN/inf inside the mask (they propagate into the sums) the usual way."""
    if not (np.isfinite(bsum).all() and np.isfinite(q).all()):
        check_finite(p.img, "images", where=np.broadcast_to(p.m[None, :, :, None], p.img.shape))


def scatter(p: Problem, vals, dtype=float):
    """(..., N) values of the masked pixels -> (H, W, ...) image, 0 outside the mask."""
    vals = np.asarray(vals)
    tail = vals.shape[:-1]
    out = np.zeros((p.h * p.w,) + tail, dtype=dtype)
    if p.full:
        out[...] = vals.T if tail else vals
    else:
        out[p.sel] = vals.T if tail else vals
    return out.reshape((p.h, p.w) + tail)


def finish(p: Problem, g, ok, amat, bmat, q) -> PhotometricStereoResult:
    """Normals, per-channel albedo, residual and validity from the solution ``g`` (3, N).

    ``amat`` (7, N), ``bmat`` (C, 3, N), ``q`` (C, N): the normal equations of the used
    measurements (:func:`accumulate`).  Per channel the albedo is the least-squares fit given
    the normal over the used lights, ``rho_c = N.b_c / N^T A N`` (``|g|`` for one channel), and
    the residual is ``sum_k (rho_c N.S_k - J_kc)^2 = q_c - rho_c N.b_c``.
    """
    nc = p.nc
    npx = amat.shape[1]
    n_used = np.rint(amat[6]).astype(np.int64)
    gn = np.sqrt(np.einsum("in,in->n", g, g))
    valid = ok & (n_used >= p.min_lights) & (gn > 0)
    nrm = np.divide(g, gn, out=np.zeros_like(g), where=valid)
    ax = amat
    den = (ax[0] * nrm[0] ** 2 + ax[1] * nrm[1] ** 2 + ax[2] * nrm[2] ** 2
           + 2.0 * (ax[3] * nrm[0] * nrm[1] + ax[4] * nrm[0] * nrm[2] + ax[5] * nrm[1] * nrm[2]))
    okd = valid & (den > 0)
    alb = np.zeros((nc, npx))
    sq = np.zeros(npx)
    for c in range(nc):
        num = np.einsum("in,in->n", nrm, bmat[c])
        np.divide(num, den, out=alb[c], where=okd)
        sq += q[c] - alb[c] * num
    res = np.sqrt(np.maximum(sq, 0.0) / np.maximum(n_used * nc, 1))
    if p.scale != (0, 0):
        alb, res = np.ldexp(alb, p.scale[0]), np.ldexp(res, p.scale[1])
        if not (np.isfinite(alb).all() and np.isfinite(res).all()):
            raise ValueError("images/lights: the albedo (image / light length) overflows float64; divide the images "
                             "by a constant or give lights of ordinary length (the normals do not change)")
    albedo = scatter(p, alb)
    if not p.colour:
        albedo = albedo[..., 0]
    return PhotometricStereoResult(
        normals=scatter(p, nrm), albedo=albedo, residual=scatter(p, np.where(valid, res, 0.0)),
        n_used=scatter(p, n_used, np.int64), valid=scatter(p, valid, bool))


def measurements(p: Problem):
    """The start of every robust method: ``(jsum, used, g)``.

    ``jsum`` (K, N) the intensity-normalised channel sums, ``used`` (K, N) the lit, unsaturated
    measurements (:func:`accumulate`), and ``g`` (3, N) their least-squares fit (0 where
    ill-conditioned); NaN/inf inside the mask are reported (:func:`check_sums`).
    """
    amat, _, bsum, q, jsum, used = accumulate(p, keep=True)
    check_sums(p, bsum, q)
    g, _ = sym_solve(amat[:6], bsum)
    return jsum, used, g


def least_squares(p: Problem, used_in=None, fallback=None) -> PhotometricStereoResult:
    """Per-pixel least squares on the used measurements, as a :class:`PhotometricStereoResult`.

    ``used_in`` (K, N): the measurements to use (default: :func:`accumulate`'s classification,
    and then NaN/inf inside the mask are reported); ``fallback`` (3, N): the solution kept where
    the least-squares system is ill-conditioned (default: none, those pixels are not valid).
    """
    amat, bmat, bsum, q, _, _ = accumulate(p, used_in=used_in)
    if used_in is None:
        check_sums(p, bsum, q)
    g, ok = sym_solve(amat[:6], bsum)
    if fallback is not None:
        g = np.where(ok, g, fallback)
    return finish(p, g, ok, amat, bmat, q)


def reject_outliers(used, r, free, scale, min_lights: int, s7):
    """The used measurements less the outliers: residual ``r`` > 5 robust standard deviations.

    The noise is ``sigma = 1.4826 median(r)`` over the ``free`` measurements of the whole image
    (those the robust fit did not interpolate exactly), and a measurement is an outlier when
    ``r > max(5 sigma, 1e-6 scale)``.  A pixel never keeps fewer than ``min_lights``: one that
    would keeps all its used lights (on near-noise-free renders the image-wide sigma is tiny and
    the rejection would leave 1-2 lights on every pixel whose residual is a little larger:
    ps_cup direct, 6 lights).

    ``s7`` (K, 7): the lights' packed outer products (:func:`outer6`).  A pixel whose
    remaining lights determine no normal (three coplanar sources: :func:`sym_solve`'s test fails)
    also keeps all its used lights, instead of being left unsolved (docs/peers.md).
    """
    sigma = 1.4826 * float(np.median(r[free])) if free.any() else 0.0
    inl = used & (r <= np.maximum(5.0 * sigma, 1e-6 * scale))
    few = inl.sum(axis=0) < min_lights
    few |= ~_well_posed(s7[:, :6].T @ inl)
    return np.where(few[None, :], used, inl)


def _well_posed(a) -> np.ndarray:
    """(N,) bool: the packed normal matrices ``a`` (6, N) pass :func:`sym_solve`'s conditioning test."""
    return sym_solve(a, np.zeros((3, a.shape[1])))[1]


# numpydoc fragments shared by the methods' docstrings (pbrbench.infer._docstring)
DOCS = {
    "inputs": """\
images : (K, H, W) or (K, H, W, C) array
    Linear images, one per light.
lights : (K, 3) array
    Source vectors in the camera frame (x right, y up, z toward the camera), pointing from
    the surface toward the source; the length scales the intensity.""",
    "options": """\
mask : (H, W) bool, optional
    Pixels to solve (default all).
intensities : (K,) or (K, C) array, optional
    Source intensities multiplying ``lights`` (per channel for coloured sources), all > 0.
shadow_threshold : float
    A measurement is treated as shadowed and dropped when its intensity-normalised value is
    <= ``shadow_threshold`` times the pixel's brightest normalised measurement (0 drops only
    exact zeros and negatives). Shadowed measurements are clamped, not linear: leaving them in
    biases the normal.
saturation : float, optional
    Measurements >= this value (in any channel) are dropped. Default: none.
min_lights : int
    Minimum number of used lights for a valid pixel (>= 3).""",
    "result": """\
PhotometricStereoResult
    ``normals`` (H, W, 3), ``albedo`` (H, W) or (H, W, C), ``residual`` (H, W), ``n_used``
    (H, W), ``valid`` (H, W). Colour: one normal shared by the channels (from the sum of the
    intensity-normalised channels), albedo per channel (least squares given the normal).""",
    "raises": """\
ValueError
    On bad shapes, non-finite input inside the mask, non-positive intensities,
    ``min_lights < 3``, or a degenerate light matrix (fewer than 3 lights, or all directions
    coplanar / collinear).""",
}
