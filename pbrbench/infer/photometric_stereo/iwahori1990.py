r"""Near-light photometric stereo: point sources at known positions near the object.

A point source of intensity ``E_k`` at ``P_k`` lights the surface point ``X`` with irradiance
``E_k / r_k^2`` from the direction ``(P_k - X) / r_k``, ``r_k = |P_k - X|`` (inverse-square law),
so a Lambertian surface of albedo ``rho`` and normal ``N`` gives

.. math:: I_k(x) = \rho E_k \max\!\Big(0, N \cdot \frac{P_k - X}{|P_k - X|^3}\Big),

and the source vector depends on the unknown depth of ``X`` (Iwahori, Sugie & Ishii 1990; the
chapter's "refine the method to take into account nearby sources").  With an orthographic camera
the image position of a pixel gives ``X = (x, y, z)`` up to its height ``z``; the method
alternates

(a) per-pixel Woodham least squares for ``g = rho N`` with the source vectors evaluated at the
    current points ``X``, and
(b) integration of the normals to a height map (masked least squares,
    :func:`pbrbench.infer.integration.integrate_lsq`), placed at the depth the caller gives or at
    the offset that minimises the image residual (a 1-D search),

until the heights stop changing.  Far sources make the source vectors constant and the method
Woodham's.

References
----------
- Y. Iwahori, H. Sugie and N. Ishii, "Reconstructing shape from shading images under point
  light source illumination", Proc. 10th International Conference on Pattern Recognition
  (ICPR), 1990.
- J. J. Clark, "Active photometric stereo", CVPR 1992.
- R. J. Woodham, "Photometric method for determining surface orientation from multiple images",
  Optical Engineering 19(1), 1980.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_int,
    check_mask,
    check_number,
    check_pixel_size,
)
from pbrbench.infer.integration import integrate_lsq
from pbrbench.infer.photometric_stereo._common import (
    PhotometricStereoResult,
    finish,
    prepare,
    sym_solve,
)

__all__ = ["NearLightResult", "photometric_stereo_iwahori1990"]

_CHUNK = 4096
_OFFSETS = ("fixed", "search")


@dataclass(frozen=True)
class NearLightResult(PhotometricStereoResult):
    """:class:`PhotometricStereoResult` plus the surface found on the way.

    Attributes
    ----------
    height : (H, W) surface height ``z`` (camera frame, same units as ``lights`` and
        ``depth0``) where ``valid``; 0 elsewhere.
    offset : the shift (world units) the residual search added to the placement given by
        ``depth0`` (0 with ``offset="fixed"``).
    iterations : number of integrate-and-update steps made.
    converged : the last step moved no height by more than ``tol`` times the distance scale.
    """

    height: np.ndarray
    offset: float
    iterations: int
    converged: bool


def _pixel_xy(h: int, w: int, pixel_size: float, center) -> tuple[np.ndarray, np.ndarray]:
    """World (x, y) of the pixel centres: the grid of :func:`pbrbench.shading.surfaces.pixel_grid`."""
    x = (np.arange(w) - (w - 1) / 2.0) * pixel_size + center[0]
    y = ((h - 1) / 2.0 - np.arange(h)) * pixel_size + center[1]
    return np.meshgrid(x, y)


class _Near:
    """Per-pixel normal equations of the near-light model at given heights (masked pixels)."""

    def __init__(self, p, pos, xy):
        self.p, self.pos, self.xy = p, pos, xy   # xy (2, N) of the masked pixels

    def sources(self, z, sl):
        """(K, n, 3) source vectors ``(P_k - X)/r^3`` and (K, n) ``r^2`` at heights ``z`` (n,)."""
        d = self.pos[:, None, :] - np.stack([self.xy[0, sl], self.xy[1, sl], z], axis=-1)[None]
        r2 = np.einsum("kni,kni->kn", d, d)
        return d / (r2 * np.sqrt(r2))[..., None], r2

    def measurements(self, sl):
        p = self.p
        mc = p.flat[:, sl, :] if p.sel is None else p.flat[:, p.sel[sl], :]
        return mc if p.ein is None else mc / p.ein[:, None, :], mc

    def classify(self, z):
        """(K, N) used flags: lit (distance-normalised channel sum above the threshold), unsaturated."""
        p = self.p
        n = z.size
        used = np.empty((p.k, n), dtype=bool)
        for start in range(0, n, _CHUNK):
            sl = slice(start, min(start + _CHUNK, n))
            jc, mc = self.measurements(sl)
            _, r2 = self.sources(z[sl], sl)
            js = jc.sum(axis=-1) * r2        # rho E cos: the falloff does not decide what is shadowed
            u = js > p.thr * js.max(axis=0)
            if p.sat is not None:
                u &= ~np.any(mc >= p.sat, axis=-1)
            used[:, sl] = u
        return used

    def equations(self, z, used, *, per_channel=True):
        """Normal equations ``a`` (7, N), ``b`` (C, 3, N), ``bsum`` (3, N), ``q`` (C, N), ``qsum`` (N,)."""
        p = self.p
        n, nc = z.size, p.nc
        a = np.empty((7, n))
        b = np.empty((nc, 3, n))
        bsum = np.empty((3, n))
        q = np.empty((nc, n))
        qsum = np.empty(n)
        for start in range(0, n, _CHUNK):
            sl = slice(start, min(start + _CHUNK, n))
            jc, _ = self.measurements(sl)
            s, _ = self.sources(z[sl], sl)
            wt = used[:, sl].astype(float)
            sw = s * wt[..., None]
            a[0, sl], a[1, sl], a[2, sl] = (np.einsum("kn,kn->n", sw[..., i], s[..., i]) for i in range(3))
            a[3, sl] = np.einsum("kn,kn->n", sw[..., 0], s[..., 1])
            a[4, sl] = np.einsum("kn,kn->n", sw[..., 0], s[..., 2])
            a[5, sl] = np.einsum("kn,kn->n", sw[..., 1], s[..., 2])
            a[6, sl] = wt.sum(axis=0)
            js = jc.sum(axis=-1)
            bsum[:, sl] = np.einsum("kni,kn->in", sw, js)
            qsum[sl] = np.einsum("kn,kn->n", wt * js, js)
            if per_channel:
                for c in range(nc):
                    b[c][:, sl] = np.einsum("kni,kn->in", sw, jc[..., c])
                    q[c, sl] = np.einsum("kn,kn->n", wt * jc[..., c], jc[..., c])
        return a, b, bsum, q, qsum

    def cost(self, z, used):
        """Sum over the solved pixels of the squared residual of the channel-sum fit, and the solution."""
        a, _, bsum, _, qsum = self.equations(z, used, per_channel=False)
        g, ok = sym_solve(a[:6], bsum)
        ok &= a[6] >= self.p.min_lights
        res = np.where(ok, qsum - np.einsum("in,in->n", g, bsum), 0.0)
        return float(np.sum(np.maximum(res, 0.0))), g, ok


def photometric_stereo_iwahori1990(images, lights, *, mask=None, intensities=None, pixel_size, depth0,
                                   center=(0.0, 0.0), offset: str = "fixed", search_range: float | None = None,
                                   iterations: int = 30, tol: float = 1e-7, shadow_threshold: float = 0.01,
                                   saturation: float | None = None, min_lights: int = 3) -> NearLightResult:
    r"""Normals, albedo and height of a Lambertian surface lit by nearby point sources.

    Per pixel, with the used lights ``U`` and the current surface point ``X = (x, y, z)``,

    .. math:: g = \arg\min_g \sum_{k \in U} \big(s_k(X) \cdot g - I_k / E_k\big)^2, \quad
              s_k(X) = \frac{P_k - X}{|P_k - X|^3}, \quad \rho = |g|, \quad N = g / |g|,

    then ``z <- integrate(N) + c`` (masked least squares) and repeat.  The constant ``c`` is fixed
    per connected component of the solved pixels so that the mean height there equals the mean of
    ``depth0`` (``offset="fixed"``), or in addition shifted by the one ``delta`` minimising
    :math:`\sum_x \min_g \sum_k (s_k(X + \delta e_z) \cdot g - I_k/E_k)^2` over
    ``|delta| <= search_range`` (``offset="search"``; bounded Brent search, repeated each step).

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear images, one per source.
    lights : (K, 3) array
        Source **positions** ``P_k`` in the camera frame (x right, y up, z toward the camera), in
        the units of ``pixel_size`` and ``depth0``.
    mask : (H, W) bool, optional
        Pixels to solve (default all).
    intensities : (K,) or (K, C) array, optional
        Source intensities ``E_k`` (irradiance ``E_k / r^2`` at distance ``r``), all > 0.
        Default 1.
    pixel_size : float
        World size of one pixel of the orthographic film (``2 half_width / W`` for the scene
        camera); pixel ``(i, j)`` sees ``x = (j - (W-1)/2) s + center[0]``,
        ``y = ((H-1)/2 - i) s + center[1]``.
    depth0 : float or (H, W) array
        Initial height ``z`` of the surface (camera frame): a plane at that height, or a height
        map.  Its mean over each connected part of the solved pixels fixes the unknown offset of
        the integrated heights (``offset="fixed"``), or starts the search.
    center : (2,) sequence
        World ``(x, y)`` of the image centre (default the optical axis).
    offset : {"fixed", "search"}
        How the integration constant is chosen (above).
    search_range : float, optional
        Half-width of the offset search. Default: half the smallest distance from the initial
        surface to a source.
    iterations : int
        Maximum number of integrate-and-update steps (>= 1).
    tol : float
        Stop when no height moves by more than ``tol`` times the median source distance.
    shadow_threshold : float
        A measurement is dropped when its distance-normalised value ``r^2 I_k / E_k`` (channel
        sum) is <= ``shadow_threshold`` times the pixel's brightest one.
    saturation : float, optional
        Measurements >= this value (in any channel) are dropped. Default: none.
    min_lights : int
        Minimum number of used lights for a valid pixel (>= 3).

    Returns
    -------
    NearLightResult
        ``normals``, ``albedo`` (``rho`` in image units per unit intensity times length squared),
        ``residual``, ``n_used``, ``valid`` as :class:`PhotometricStereoResult` (colour: one
        normal from the channel sum, albedo per channel), plus ``height``, ``offset``,
        ``iterations`` and ``converged``.

    Raises
    ------
    ValueError
        On bad shapes or values (as :func:`photometric_stereo_woodham1980`), a light position on
        the surface, sources whose directions from the surface are degenerate (coplanar), a
        non-positive ``pixel_size``, a non-finite ``depth0`` inside the mask, or an unknown
        ``offset``.

    References
    ----------
    Y. Iwahori, H. Sugie and N. Ishii, "Reconstructing shape from shading images under point
    light source illumination", ICPR 1990; J. J. Clark, "Active photometric stereo", CVPR 1992.
    """
    img = as_float_array(images, "images", ndim=(3, 4))
    k, h, w = img.shape[:3]
    pos = as_float_array(lights, "lights", ndim=(2,))
    if pos.shape != (k, 3):
        raise ValueError(f"lights: expected shape ({k}, 3) (one source position per image), got {pos.shape}")
    check_finite(pos, "lights")
    ps = check_pixel_size(pixel_size)
    m = check_mask(mask, (h, w))
    check_finite(img, "images", where=np.broadcast_to(m.reshape((1, h, w) + (1,) * (img.ndim - 3)), img.shape))
    cen = as_float_array(center, "center", ndim=(1,))
    if cen.shape != (2,):
        raise ValueError(f"center: expected (x, y) of the image centre, got shape {cen.shape}")
    check_finite(cen, "center")
    d0 = as_float_array(depth0, "depth0", ndim=(0, 2))
    if d0.ndim == 2 and d0.shape != (h, w):
        raise ValueError(f"depth0: shape {d0.shape} does not match the image shape {(h, w)}; pass a number "
                         "(the height of the surface) or an (H, W) height map")
    d0 = np.broadcast_to(d0, (h, w))
    check_finite(d0, "depth0", where=m)
    if offset not in _OFFSETS:
        raise ValueError(f"offset={offset!r} is not known; choose one of {', '.join(map(repr, _OFFSETS))}")
    n_iter = check_int(iterations, "iterations", 1)
    tol = check_number(tol, "tol", lo=0.0, lo_open=True, hi=1.0)

    xs, ys = _pixel_xy(h, w, ps, cen)
    flat_m = m.ravel()
    xy = np.stack([xs.ravel()[flat_m], ys.ravel()[flat_m]])
    z = d0.ravel()[flat_m].astype(float)
    x0 = np.array([xy[0].mean(), xy[1].mean(), z.mean()])
    dist = np.linalg.norm(pos - x0, axis=1)
    pts = np.vstack([xy, z[None]])
    closest = np.array([np.sqrt(np.min(np.sum((pts - pk[:, None]) ** 2, axis=0))) for pk in pos])
    on = closest <= 1e-6 * max(float(np.median(dist)), ps)
    if np.any(on):
        raise ValueError(f"lights: source(s) {np.flatnonzero(on).tolist()} lie on the surface (at depth0); give "
                         "source positions away from the object (in the units of pixel_size and depth0)")
    # the directions from the surface's centre: the usual checks of a light matrix (>= 3 lights,
    # not coplanar) and of images / mask / intensities / options, with the usual messages
    p = prepare(img, (pos - x0) / dist[:, None], m, intensities, shadow_threshold, saturation, min_lights)
    near = _Near(p, pos, xy)
    scale = float(np.median(dist))
    span = 0.5 * float(dist.min()) if search_range is None else check_number(
        search_range, "search_range", lo=0.0, lo_open=True)

    mask_flat_idx = np.flatnonzero(flat_m)
    shift, steps, converged = 0.0, 0, False
    for steps in range(1, n_iter + 1):  # noqa: B007 - steps is reported
        used = near.classify(z)
        _, g, ok = near.cost(z, used)
        nz = np.where(ok, g[2], 0.0)
        dom_flat = ok & (nz > 1e-3 * np.sqrt(np.einsum("in,in->n", g, g)))
        if not dom_flat.any():
            break
        nimg = np.zeros((h * w, 3))
        nimg[mask_flat_idx[dom_flat]] = (g[:, dom_flat] / np.linalg.norm(g[:, dom_flat], axis=0)).T
        dom = np.zeros(h * w, dtype=bool)
        dom[mask_flat_idx[dom_flat]] = True
        dom = dom.reshape(h, w)
        hz = integrate_lsq(nimg.reshape(h, w, 3), mask=dom, pixel_size=ps)
        # place each connected component at the mean of depth0 there
        lab, nlab = ndimage.label(dom)
        cnt = np.bincount(lab.ravel(), minlength=nlab + 1)
        want = np.bincount(lab.ravel(), weights=d0.ravel(), minlength=nlab + 1) / np.maximum(cnt, 1)
        have = np.bincount(lab.ravel(), weights=hz.ravel(), minlength=nlab + 1) / np.maximum(cnt, 1)
        placed = (hz + (want - have)[lab]).ravel()[mask_flat_idx]
        znew = np.where(dom_flat, placed, z)
        if offset == "search":
            def f(delta, znew=znew, used=used, dom_flat=dom_flat, z=z):
                return near.cost(np.where(dom_flat, znew + delta, z), used)[0]

            # not at import: the CLI's methods tables import this package
            from scipy import optimize

            shift = float(optimize.minimize_scalar(f, bounds=(-span, span), method="bounded",
                                                   options={"xatol": tol * scale}).x)
            znew = np.where(dom_flat, znew + shift, z)
        change = float(np.max(np.abs(znew - z)))
        z = znew
        if change <= tol * scale:
            converged = True
            break

    used = near.classify(z)
    a, b, bsum, q, _ = near.equations(z, used)
    g, ok = sym_solve(a[:6], bsum)
    res = finish(p, g, ok, a, b, q)
    height = np.zeros(h * w)
    height[mask_flat_idx] = z
    height = np.where(res.valid, height.reshape(h, w), 0.0)
    return NearLightResult(normals=res.normals, albedo=res.albedo, residual=res.residual, n_used=res.n_used,
                           valid=res.valid, height=height, offset=shift, iterations=steps, converged=converged)
