r"""Photometric stereo that undoes interreflection (Nayar, Ikeuchi & Kanade 1991).

Reference: S. K. Nayar, K. Ikeuchi and T. Kanade, "Shape from interreflections", International
Journal of Computer Vision 6(3):173-195, 1991.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pbrbench.checks import check_finite, check_int, check_number
from pbrbench.infer.photometric_stereo import _interreflection as _ir
from pbrbench.infer.photometric_stereo._common import (
    PhotometricStereoResult,
    accumulate,
    finish,
    prepare,
    sym_solve,
)

__all__ = ["InterreflectionResult", "photometric_stereo_nayar1991"]

VERSION = "2"  # the premise test: where the local estimate's shadows are dark but its kernel predicts light there,
# the images hold no interreflection and the local solve is returned (was: always corrected)

MIN_FACETS = 4
FACETS_PER_SIDE = 32   # default facet grid along the larger image side
IR_FRACTION = 0.01     # pixels with more removed interreflection than this share of their light
#                        use ir_shadow_threshold


@dataclass(frozen=True)
class InterreflectionResult(PhotometricStereoResult):
    """:class:`PhotometricStereoResult` of the last local solve, plus the iteration's record.

    Attributes
    ----------
    interreflection : (K, H, W) or (K, H, W, C) the interreflected radiance removed from the
        images (``images - interreflection`` are the local images of the last solve); 0 outside
        the used pixels.
    iterations : number of corrections applied (0: the local solve alone).
    changes : mean angular change of the normals (degrees) after each correction.
    n_facets : number of facets on the surface in the last correction (its continuation beyond the
        image borders not counted; 0 when no correction ran).
    shadow_light : the premise test (``photometric_stereo_nayar1991``'s Shadows): measured light
        over the interreflection the kernel predicts, summed over the measurements the local
        estimate puts in shadow; NaN where too few are in shadow to test (or the test is off).
    refuted : True when that ratio fell below ``shadow_light_min``: the images lack the
        interreflection the method would remove, and the result is the local solve.
    """

    interreflection: np.ndarray
    iterations: int
    changes: tuple[float, ...]
    n_facets: int
    shadow_light: float = float("nan")
    refuted: bool = False


def _shadow_light(res, meas, predicted, lights, sel, support: float) -> float:
    """Measured light over predicted interreflection on the measurements in the shadows of the
    local estimate ``res`` (:func:`._interreflection.shadowed`; its valid pixels lie inside the
    mask), NaN where fewer than ``support`` of the valid pixels' measurements are in shadow."""
    sh = _ir.shadowed(res.normals, res.valid, lights)
    n_meas = len(lights) * int(res.valid.sum())
    if n_meas == 0 or sh.sum() < max(1.0, support * n_meas):
        return float("nan")
    s = sh.reshape(len(lights), -1)[:, sel]                     # (K, N) over the masked pixels
    pred = float(predicted.sum(axis=-1)[s].sum())
    if pred <= 0:
        return float("nan")
    return float(meas.sum(axis=-1)[s].sum()) / pred


def _mean_change(n0, n1, m) -> float:
    """Mean angle (degrees) between two normal fields on ``m``, by atan2 (exact near 0)."""
    a, b = n0[m], n1[m]
    if not a.size:
        return 0.0
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("ij,ij->i", a, b))).mean())


def photometric_stereo_nayar1991(images, lights, *, mask=None, block: int | None = None, pad: float = 0.5,
                                 max_iter: int = 10, tol: float = 0.05, history: int = 3,
                                 ir_shadow_threshold: float = 0.2, albedo_scale: float = np.pi,
                                 max_reflectance: float = 0.99, shadow_threshold: float = 0.01,
                                 saturation: float | None = None, min_lights: int = 3,
                                 shadow_light_min: float = 0.5, shadow_support: float = 0.005) -> InterreflectionResult:
    r"""Normals and albedo of a Lambertian surface with its interreflections undone (Nayar et al. 1991).

    The images of a surface with interreflections are (radiance form of the radiosity equation)

    .. math:: I = I_{\mathrm{local}} + P K I
        \quad\Longleftrightarrow\quad I = (\mathbf 1 - P K)^{-1} I_{\mathrm{local}},

    with ``P = diag(rho)`` the reflectances and ``K`` the facet transport

    .. math:: K_{ij} = \frac{\max(0, n_i \cdot d_{ij})\,\max(0, -n_j \cdot d_{ij})}{\pi\,|d_{ij}|^4}\,A_j
        \qquad (d_{ij} = x_j - x_i),

    the form factor ``cos(theta_i) cos(theta_j) A_j / (pi r^2)`` of facet ``j`` (area ``A_j``)
    seen from facet ``i`` (:mod:`pbrbench.infer.photometric_stereo._interreflection`).  Local
    photometric stereo (Woodham's least squares, as
    :func:`~pbrbench.infer.photometric_stereo.photometric_stereo_woodham1980`) on ``I`` gives the
    pseudo shape and pseudo albedo; then, until the normals stop changing,

    .. math:: I_{\mathrm{local}}^{(t)} = I - P^{(t)} K^{(t)} I, \qquad
        (N, \rho)^{(t+1)} = \mathrm{PS}\big(I_{\mathrm{local}}^{(t)}\big),

    with ``K^(t)`` built from the normals ``N^(t)`` integrated to heights
    (:func:`pbrbench.infer.integration.integrate_lsq`) and ``P^(t) = albedo_scale * albedo^(t)``:
    the iteration of Nayar, Ikeuchi & Kanade (1991).  ``I`` enters only multiplied; no inverse of
    ``1 - P K`` is formed.  The fixed-point map ``R -> P K I`` (``R`` the removed interreflection)
    is accelerated by Anderson mixing of the last ``history`` steps (Anderson, "Iterative
    procedures for nonlinear integral equations", J. ACM 12(4), 1965), which needs about half
    the corrections of the plain iteration (``history=0``) for the same fixed point.

    Shadows: a measurement is used when its corrected value exceeds ``shadow_threshold`` times
    the pixel's brightest corrected one (Woodham's rule), and, on pixels where the removed
    interreflection exceeds 1 % of their light, ``ir_shadow_threshold`` times it: a shadowed
    measurement of a concave surface is pure interreflection, and what the correction leaves of
    it (its error) would otherwise pass as a dim lit measurement and bias the normal.  Where
    that leaves fewer than ``min_lights`` lights Woodham's rule alone decides.  Where nothing is
    removed (a convex surface: the kernel vanishes) the result is Woodham's, bit for bit.

    Premise test.  Images without interreflection (direct light only) are explained exactly by
    the local model, and also by a deeper surface whose interreflection the method would remove:
    intensities alone cannot tell the two apart.  Shadows can: a measurement in shadow receives no
    direct light, so under interreflection it holds the interreflected light, and without it, none.
    Before the first correction, over the measurements the local estimate puts in shadow
    (attached, ``N . s <= 0``, or cast by its integrated height field,
    :func:`._interreflection.shadowed`), the ratio ``shadow_light`` of the measured light to the
    interreflection ``P K I`` its kernel predicts there is formed; below ``shadow_light_min`` the
    images lack that light, the premise is refuted and the local solve is returned (``refuted``,
    no correction).  The test needs shadows: with fewer than ``shadow_support`` of the
    measurements in them (e.g. a shallow groove under high sources) it does not decide, and the
    method corrects as before.  On the benchmark's direct renders of ps_cup the ratio is 0.02 to
    0.3; on its interreflected ones 1.0 to 1.3 where it is defined (``docs/nayar1991.md``).

    Discretisation: the kernel lives on ``block`` x ``block`` pixel facets (default: about 32
    facets along the larger image side; a 128 x 128 image: ``block=4``, 32 x 32 = 1024 facets);
    ``K I`` is computed from the facets' mean radiances and brought back to every pixel by
    bilinear interpolation between facet centres weighted by normal similarity (no mixing across
    a crease), then multiplied by the pixel's own reflectance.  The geometry is in pixel units:
    the kernel is invariant to the scale of the scene, so no pixel size is needed.

    Assumptions (beyond the local model's Lambertian surface, orthographic camera and distant
    sources): the images hold all the interreflected light (on images without it, e.g. direct
    renders of a concave surface, the method removes light that is not there and is worse than
    the local solve, unless the premise test refutes it); shadowed measurements hold no light but
    the interreflected one (ambient light counts as interreflection); facets see each other when each lies in front of the other, with no
    occlusion by a third part (exact on concave and on convex surfaces); pixels outside ``mask``
    are empty space; where the mask touches an image border and the surface crosses it
    unchanged (a groove or a cylinder whose axis crosses the border, a level plane) it continues
    beyond the border by translation, ``pad`` times the image size deep, and elsewhere ends at
    the border; separate parts of the mask are integrated independently, each with mean height
    zero.

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear radiance images, one per light: ``rho E max(0, N.S) / pi`` plus interreflection
        in pbrbench's convention (``docs/conventions.md``).  The absolute scale matters: the
        reflectance used in the kernel is ``albedo_scale`` times the recovered albedo.
    lights : (K, 3) array
        Source vectors (unit direction toward the source times irradiance) in the camera frame
        (x right, y up, z toward the camera).
    mask : (H, W) bool, optional
        Pixels of the surface (default all).
    block : int, optional
        Facet side in pixels (>= 1); default ``max(1, round(max(H, W) / 32))``.  Time and memory
        grow as ``(H W / block^2)^2``.
    pad : float
        Depth of the continuation beyond an image border, as a fraction of the image size (in
        [0, 1]; 0: the surface ends at the border).
    max_iter : int
        Maximum number of corrections (>= 0; 0 returns the local solve).
    tol : float
        Stop when the mean angular change of the normals in one correction falls below ``tol``
        degrees (> 0).
    history : int
        Steps of Anderson mixing (>= 0; 0: Nayar et al.'s plain iteration).
    ir_shadow_threshold : float
        Shadow threshold, relative to the pixel's brightest corrected measurement, on pixels
        with interreflection removed (in [0, 1)).
    albedo_scale : float
        Reflectance per unit of recovered albedo: ``pi`` for radiance images and source vectors
        in irradiance (pbrbench's convention), 1 when the images are already ``rho E cos``.
    max_reflectance : float
        The reflectance in ``P`` is clipped to ``[0, max_reflectance]`` (in (0, 1]): an early
        pseudo albedo can reach or exceed the physical bound 1 and would overcorrect.  The
        returned albedo is the local solve's, not clipped.
    shadow_light_min : float
        Premise test: the local solve is returned when the measured light in the local
        estimate's shadows is below this fraction of the interreflection predicted there (>= 0;
        0 turns the test off).
    shadow_support : float
        The fraction of the valid pixels' measurements that must be in shadow for the test to
        decide (in (0, 1]).
    shadow_threshold, saturation, min_lights
        As in :func:`~pbrbench.infer.photometric_stereo.photometric_stereo_woodham1980`
        (applied to the corrected images; ``saturation`` to the measured ones).

    Returns
    -------
    InterreflectionResult
        ``normals``, ``albedo`` (``rho / albedo_scale``), ``residual``, ``n_used``, ``valid``
        of the local solve on the corrected images, and ``interreflection`` (the removed light),
        ``iterations``, ``changes``, ``n_facets``, ``shadow_light`` and ``refuted`` (the
        premise test).

    Raises
    ------
    ValueError
        On the local solve's errors (bad shapes, fewer than 3 lights, coplanar lights,
        non-finite values inside the mask), bad options, or a surface covering fewer than 4
        facets (pass a smaller ``block``).

    References
    ----------
    S. K. Nayar, K. Ikeuchi and T. Kanade, "Shape from interreflections", International Journal
    of Computer Vision 6(3):173-195, 1991.
    R. J. Woodham, "Photometric method for determining surface orientation from multiple
    images", Optical Engineering 19(1), 1980.
    D. G. Anderson, "Iterative procedures for nonlinear integral equations", Journal of the ACM
    12(4):547-560, 1965.
    """
    if block is not None:
        block = check_int(block, "block", lo=1)
    pad = check_number(pad, "pad", lo=0.0, hi=1.0)
    max_iter = check_int(max_iter, "max_iter", lo=0)
    tol = check_number(tol, "tol", lo=0.0, lo_open=True)
    history = check_int(history, "history", lo=0)
    ir_shadow_threshold = check_number(ir_shadow_threshold, "ir_shadow_threshold", lo=0.0, hi=1.0, hi_open=True)
    shadow_light_min = check_number(shadow_light_min, "shadow_light_min", lo=0.0)
    shadow_support = check_number(shadow_support, "shadow_support", lo=0.0, hi=1.0, lo_open=True)
    albedo_scale = check_number(albedo_scale, "albedo_scale", lo=0.0, lo_open=True)
    max_reflectance = check_number(max_reflectance, "max_reflectance", lo=0.0, hi=1.0, lo_open=True)
    p = prepare(images, lights, mask, None, shadow_threshold, saturation, min_lights)
    check_finite(p.img, "images", where=np.broadcast_to(p.m[None, :, :, None], p.img.shape))
    kk, h, w, nc = p.img.shape
    if block is None:
        block = max(1, int(round(max(h, w) / FACETS_PER_SIDE)))
    sel = np.arange(h * w) if p.sel is None else p.sel
    meas = p.flat[:, sel, :]                                   # (K, N, C) measured, masked pixels
    sat = None if p.sat is None else np.any(meas >= p.sat, axis=-1)

    def solve(removed):
        """Local photometric stereo on ``meas - removed`` with the shadow test of the docstring."""
        cor = meas - removed
        js = cor.sum(axis=-1)
        strong = removed.sum(axis=(0, 2)) > IR_FRACTION * meas.sum(axis=(0, 2))
        thr = np.where(strong, max(p.thr, ir_shadow_threshold), p.thr)
        peak = js.max(axis=0)
        used = js > thr * peak
        base = js > p.thr * peak
        if sat is not None:
            used &= ~sat
            base &= ~sat
        few = used.sum(axis=0) < p.min_lights
        used[:, few] = base[:, few]
        flat = np.zeros_like(p.flat)
        flat[:, sel, :] = cor
        q = replace(p, img=flat.reshape(p.img.shape), flat=flat)
        amat, bmat, bsum, qq, _, _ = accumulate(q, used_in=used)
        g, ok = sym_solve(amat[:6], bsum)
        return finish(q, g, ok, amat, bmat, qq)

    def predict(res):
        """The interreflected radiance ``P K I`` (K, N, C) of the estimate ``res``."""
        f = _ir.build_facets(res.normals, res.valid, block, pad)
        if f.n < MIN_FACETS:
            raise ValueError(
                f"mask: the surface covers {f.n} facet(s) of {block} x {block} pixels, fewer than "
                f"{MIN_FACETS}; the interreflection kernel needs more: pass a smaller block or a larger mask")
        k = _ir.kernel(f)
        out = np.zeros((kk, h * w, nc))
        rho = np.clip(albedo_scale * res.albedo.reshape(h * w, nc)[f.pix], 0.0, max_reflectance)
        for c in range(nc):
            g = _ir.transport(f, k, p.flat[:, f.pix, c].T)     # (n_pix, K)
            out[:, f.pix, c] = (rho[:, c][:, None] * g).T
        return out[:, sel, :], f.n

    removed = np.zeros_like(meas)
    res = solve(removed)
    changes: list[float] = []
    n_facets = 0
    xs: list[np.ndarray] = []
    gs: list[np.ndarray] = []
    ratio = float("nan")
    for i in range(max_iter):
        fx, n_facets = predict(res)
        if i == 0 and shadow_light_min > 0:
            ratio = _shadow_light(res, meas, fx, p.s, sel, shadow_support)
            if ratio < shadow_light_min:        # the premise refuted: the local solve stands
                return InterreflectionResult(
                    normals=res.normals, albedo=res.albedo, residual=res.residual, n_used=res.n_used,
                    valid=res.valid, interreflection=np.zeros(p.img.shape if p.colour else p.img.shape[:3]),
                    iterations=0, changes=(), n_facets=n_facets, shadow_light=ratio, refuted=True)
        # Anderson mixing of the fixed-point map removed -> P K I (plain Nayar iteration: history=0)
        gx = fx - removed
        xs.append(removed.ravel())
        gs.append(gx.ravel())
        xs, gs = xs[-(history + 1):], gs[-(history + 1):]
        nxt_x = fx
        if len(gs) > 1:
            dg = np.stack([gs[i + 1] - gs[i] for i in range(len(gs) - 1)], axis=1)
            dx = np.stack([xs[i + 1] - xs[i] for i in range(len(xs) - 1)], axis=1)
            gam = np.linalg.lstsq(dg, gs[-1], rcond=None)[0]
            nxt_x = np.maximum((xs[-1] + gs[-1] - (dx + dg) @ gam).reshape(meas.shape), 0.0)
        removed = nxt_x
        nxt = solve(removed)
        changes.append(_mean_change(res.normals, nxt.normals, res.valid & nxt.valid))
        res = nxt
        if changes[-1] < tol:
            break
    full = np.zeros((kk, h * w, nc))
    full[:, sel, :] = removed
    albedo = res.albedo
    ir = full.reshape(p.img.shape)
    return InterreflectionResult(
        normals=res.normals, albedo=albedo, residual=res.residual, n_used=res.n_used, valid=res.valid,
        interreflection=ir if p.colour else ir[..., 0], iterations=len(changes), changes=tuple(changes),
        n_facets=n_facets, shadow_light=ratio)
