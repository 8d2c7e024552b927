"""Photometric stereo: albedo and normals from K images under distant sources.

Model (SCIENCE.md §0, §6): orthographic camera, distant sources, Lambertian surface, no ambient,

    I_k(x) = rho(x) E_k max(0, N(x) . S_k),

with ``S_k`` the unit direction from the surface toward source k and ``E_k`` its irradiance.
Writing ``V_k = E_k S_k`` (the rows of ``lights``) and ``g = rho N``, every lit, unsaturated
measurement gives one linear equation ``V_k . g = I_k``; three or more independent ones fix
``g``: albedo ``|g|``, normal ``g / |g|`` (Woodham 1980; Forsyth & Ponce, Algorithm 1.2).

Frame: x right, y up, z toward the camera (DiLiGenT convention); image row 0 is the top.
Images must be linear. With radiance images ``rho E cos / pi`` the recovered albedo is
``rho / pi`` unless the intensities carry the ``1/pi``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_mask, check_method

__all__ = ["PhotometricStereoResult", "photometric_stereo", "METHODS"]

METHODS = ("woodham1980", "ikehata2012_l1")


@dataclass(frozen=True)
class PhotometricStereoResult:
    """Output of :func:`photometric_stereo`.

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


def _check_lights(lights, k):
    s = as_float_array(lights, "lights", ndim=(2,))
    if s.shape != (k, 3):
        raise ValueError(f"lights: expected shape ({k}, 3) (one source vector per image), got {s.shape}")
    check_finite(s, "lights")
    if k < 3:
        raise ValueError(f"lights: photometric stereo needs at least 3 lights, got {k}; add images under more sources")
    norms = np.linalg.norm(s, axis=1)
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


def _sym_solve(a, b):
    """Solve batched symmetric 3x3 systems ``A x = b`` by cofactors (pixels along the last axis).

    ``a``: (6, N) packed as (xx, yy, zz, xy, xz, yz); ``b``: (3, N).
    Returns ``(x, ok)``: (3, N) solutions and a flag for well-conditioned systems (others 0).
    """
    axx, ayy, azz, axy, axz, ayz = a
    c00 = ayy * azz - ayz * ayz
    c01 = axz * ayz - axy * azz
    c02 = axy * ayz - axz * ayy
    c11 = axx * azz - axz * axz
    c12 = axy * axz - axx * ayz
    c22 = axx * ayy - axy * axy
    det = axx * c00 + axy * c01 + axz * c02
    tr = axx + ayy + azz
    ok = det > 1e-9 * (tr * (1.0 / 3.0)) ** 3
    inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    b0, b1, b2 = b
    x = np.empty_like(b)
    np.multiply(c00 * b0 + c01 * b1 + c02 * b2, inv_det, out=x[0])
    np.multiply(c01 * b0 + c11 * b1 + c12 * b2, inv_det, out=x[1])
    np.multiply(c02 * b0 + c12 * b1 + c22 * b2, inv_det, out=x[2])
    return x, ok


def _outer6(s):
    """(K, 7) packed outer products ``S_k S_k^T`` (xx, yy, zz, xy, xz, yz) and a column of ones.

    ``_outer6(s).T @ w`` gives the normal matrices (rows 0-5) and the weight sums (row 6).
    """
    return np.stack([s[:, 0] ** 2, s[:, 1] ** 2, s[:, 2] ** 2,
                     s[:, 0] * s[:, 1], s[:, 0] * s[:, 2], s[:, 1] * s[:, 2],
                     np.ones(len(s))], axis=1)


def _weighted_fit(w, j, s, s6):
    """Per-pixel weighted least squares ``min_g sum_k w_k (S_k . g - j_k)^2``.

    ``w``, ``j``: (K, N) weights and measurements; ``s``: (K, 3); ``s6``: (K, 6).
    Returns ``(g, ok, a, b)`` with the normal-equation matrices ``a`` (6, N) and ``b`` (3, N).
    """
    a = s6.T @ w
    b = s.T @ (w * j)
    g, ok = _sym_solve(a[:6], b)
    return g, ok, a, b


_CHUNK = 4096  # pixels per block: temporaries stay in cache, and the small GEMMs stay
# below the size where BLAS starts threads (whose start-up costs more than the product)


def _accumulate(flat, sel, e, thr, saturation, s, s7, *, used_in=None, keep=False):
    """One blocked pass over the measurements: classify and build the normal equations.

    ``flat``: (K, H*W, C) images; ``sel``: None (all pixels) or flat indices of the mask.
    Returns ``a`` (7, N), ``b`` (C, 3, N) per channel, ``bsum`` (3, N) for the shared geometry,
    ``q`` (C, N) = sum of used squared measurements, and when ``keep`` the (K, N) channel-sum
    measurements ``jsum`` and the ``used`` flags. ``used_in`` replaces the classification.
    """
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


def photometric_stereo(images, lights, *, mask=None, method: str = "woodham1980", intensities=None,
                       shadow_threshold: float = 0.01, saturation: float | None = None,
                       min_lights: int = 3, max_iter: int = 50) -> PhotometricStereoResult:
    r"""Recover normals and albedo from K images of a Lambertian surface under distant sources.

    Per pixel, with the used lights ``U`` (lit and unsaturated),

    .. math:: g = \arg\min_g \sum_{k \in U} (V_k \cdot g - I_k)^2, \quad
              \rho = |g|, \quad N = g / |g|,

    where ``V_k`` is row k of ``lights`` (times ``intensities[k]`` if given).

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear images, one per light.
    lights : (K, 3) array
        Source vectors in the camera frame (x right, y up, z toward the camera), pointing from
        the surface toward the source; the length scales the intensity.
    mask : (H, W) bool, optional
        Pixels to solve (default all).
    method : {"woodham1980", "ikehata2012_l1"}
        ``"woodham1980"``: least squares over the used lights (R. J. Woodham, "Photometric method
        for determining surface orientation from multiple images", Optical Engineering 19(1),
        1980), vectorised as batched 3x3 normal equations. ``"ikehata2012_l1"``: the robust
        :math:`\ell_1` residual minimisation :math:`\min_g \sum_{k\in U} |V_k\cdot g - I_k|` of
        Ikehata, Wipf, Matsushita & Aizawa, "Robust photometric stereo using sparse
        regression", CVPR 2012 (their convex L1 variant), which treats highlights and residual
        shadows as sparse errors; solved by iteratively reweighted least squares, vectorised over
        pixels; measurements whose L1 residual exceeds 5 robust standard deviations of the noise
        (median absolute residual over the image) are dropped as outliers (they do not count in
        ``n_used``) and ``g`` is refitted by least squares on the inliers.
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
        Minimum number of used lights for a valid pixel (>= 3).
    max_iter : int
        Iterations of the robust solver.

    Returns
    -------
    PhotometricStereoResult
        ``normals`` (H, W, 3), ``albedo`` (H, W) or (H, W, C), ``residual`` (H, W), ``n_used``
        (H, W), ``valid`` (H, W). Colour: one normal shared by the channels (from the sum of the
        intensity-normalised channels), albedo per channel (least squares given the normal).

    Raises
    ------
    ValueError
        On bad shapes, non-finite input inside the mask, an unknown method, non-positive
        intensities, ``min_lights < 3``, or a degenerate light matrix (fewer than 3 lights, or
        all directions coplanar / collinear).
    """
    check_method(method, METHODS)
    img = as_float_array(images, "images", ndim=(3, 4))
    k = img.shape[0]
    colour = img.ndim == 4
    if not colour:
        img = img[..., None]
    _, h, w, nc = img.shape
    s = _check_lights(lights, k)
    m = check_mask(mask, (h, w))
    if intensities is None:
        e = np.ones((k, nc))
    else:
        e = as_float_array(intensities, "intensities", ndim=(1, 2))
        if e.shape[0] != k or (e.ndim == 2 and e.shape[1] not in (1, nc)):
            raise ValueError(f"intensities: expected shape ({k},) or ({k}, {nc}), got {e.shape}")
        check_finite(e, "intensities")
        if np.any(e <= 0):
            raise ValueError("intensities: every intensity must be > 0; drop images whose source is off")
        e = np.broadcast_to(e.reshape(k, -1), (k, nc)).astype(float)
    thr = float(shadow_threshold)
    if not (np.isfinite(thr) and 0.0 <= thr < 1.0):
        raise ValueError(f"shadow_threshold: must be in [0, 1), got {shadow_threshold!r}")
    if saturation is not None and not np.isfinite(float(saturation)):
        raise ValueError(f"saturation: must be a finite number or None, got {saturation!r}")
    if int(min_lights) < 3:
        raise ValueError(f"min_lights: must be >= 3 (three unknowns per pixel), got {min_lights!r}")
    min_lights = int(min_lights)
    if int(max_iter) < 1:
        raise ValueError(f"max_iter: must be >= 1, got {max_iter!r}")

    flat_m = m.ravel()
    full = bool(flat_m.all())
    sel = None if full else np.flatnonzero(flat_m)
    flat = img.reshape(k, h * w, nc)
    ein = None if intensities is None else e
    sat = None if saturation is None else float(saturation)
    s7 = _outer6(s)
    robust = method == "ikehata2012_l1"
    amat, bmat, bsum, q, jsum, used = _accumulate(flat, sel, ein, thr, sat, s, s7, keep=robust)
    if not (np.isfinite(bsum).all() and np.isfinite(q).all()):
        # NaN/inf propagate into the sums; report them the usual way
        check_finite(img, "images", where=np.broadcast_to(m[None, :, :, None], img.shape))
    npx = amat.shape[1]
    g, ok = _sym_solve(amat[:6], bsum)

    if robust:
        scale = np.maximum(jsum.max(axis=0), np.finfo(float).tiny)
        delta = 1e-9 * scale
        wsum = used.astype(float)
        for _ in range(int(max_iter)):
            r = np.abs(jsum - s @ g)
            wl1 = wsum / np.maximum(r, delta)
            g_new, ok_new, _, _ = _weighted_fit(wl1, jsum, s, s7)
            g_new = np.where(ok_new, g_new, g)
            step = np.max(np.abs(g_new - g) / scale) if g.size else 0.0
            g = g_new
            if step < 1e-10:
                break
        r = np.abs(jsum - s @ g)
        # Outliers: residual > 5 robust standard deviations of the image noise, estimated over
        # all pixels from the residuals the L1 fit did not interpolate exactly (an L1 fit passes
        # through >= 3 measurements, whose zero residuals say nothing about the noise).
        free = used & (r > 1e3 * delta)
        sigma = 1.4826 * float(np.median(r[free])) if free.any() else 0.0
        used &= r <= np.maximum(5.0 * sigma, 1e-6 * scale)
        del r, wl1, wsum, free
        # least-squares polish on the inliers (Gaussian-efficient, exact when inliers are exact)
        amat, bmat, bsum, q, _, _ = _accumulate(flat, sel, ein, thr, sat, s, s7, used_in=used)
        g_ls, ok = _sym_solve(amat[:6], bsum)
        g = np.where(ok, g_ls, g)

    n_used = np.rint(amat[6]).astype(np.int64)
    gn = np.sqrt(np.einsum("in,in->n", g, g))
    valid = ok & (n_used >= min_lights) & (gn > 0)
    nrm = np.divide(g, gn, out=np.zeros_like(g), where=valid)

    # Per-channel albedo: least squares given the normal over the used lights,
    # rho_c = sum_k (N.S_k) J_kc / sum_k (N.S_k)^2 = N.b_c / N^T A N (A, b: normal equations);
    # for one channel this is |g|. Residual: sum_k (rho_c N.S_k - J_kc)^2 = q_c - rho_c N.b_c.
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

    def scatter(vals, dtype=float):
        """(..., N) values of the masked pixels -> (H*W, ...) image, 0 outside the mask."""
        vals = np.asarray(vals)
        tail = vals.shape[:-1]
        out = np.zeros((h * w,) + tail, dtype=dtype)
        if full:
            out[...] = vals.T if tail else vals
        else:
            out[sel] = vals.T if tail else vals
        return out.reshape((h, w) + tail)

    albedo = scatter(alb)
    if not colour:
        albedo = albedo[..., 0]
    return PhotometricStereoResult(
        normals=scatter(nrm), albedo=albedo, residual=scatter(np.where(valid, res, 0.0)),
        n_used=scatter(n_used, np.int64), valid=scatter(valid, bool))
