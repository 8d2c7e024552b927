r"""Photometric stereo by inverse rendering: a height field and an albedo texture fitted so that
Mitsuba's rendering with full light transport matches the images.

Model.  The surface is a height field on the camera's pixel-corner grid, Lambertian with one
albedo per pixel (:mod:`pbrbench.inverse.heightfield`); the camera, the lights and the transport
(``max_depth``) are those of the images.  With ``R_k(z, \rho)`` Mitsuba's path-traced render of
light ``k`` (interreflection included), the estimate minimises

.. math::

    E(z, \rho) = \frac{1}{K |D|\, \overline{I^2}} \sum_{k=1}^{K} \sum_{p \in D}
                 c^2 \log\Bigl(1 + \frac{(R_{kp}(z, \rho) - I_{kp})^2}{c^2}\Bigr)
                 \;+\; \frac{w}{f^2 |T|} \lVert T z \rVert^2

over the data pixels ``D`` (the mask, :func:`~pbrbench.inverse.heightfield.pixel_sets`): a Cauchy
loss whose scale ``c = robust * 1.4826 * median |R - I|`` is re-estimated every iteration (a shadow
the current shape puts in the wrong place weighs less; 0 gives least squares), plus a thin-plate
prior ``T`` (:func:`~pbrbench.inverse.heightfield.thin_plate_matrix`; zero for planes and
quadrics, it averages the Monte Carlo noise of the images, which at 72 spp limits a per-pixel
method to 6 degrees on the cup) of weight ``w = smoothness`` (``f`` the level's downsampling).

Gradient (``adjoint="direct"``, the default).  The residual of the full-transport render is
back-propagated through a *direct-light* differentiable render (Mitsuba's ``prb``, path replay
backpropagation, Vicini et al. 2021, at ``max_depth = 2``): ``J_direct^T r``.  The full path-replay
gradient (``adjoint="full"``) differentiates every bounce, but in a concave scene its height
derivative is dominated by the variance of the geometric terms between nearby points (at the
crease of a groove, signal-to-noise ratio 0.3 against 13 for the direct one, ``docs/inverse.md``).
Per-vertex values beyond 20 medians are clamped (fireflies).  The direct adjoint misses how the
interreflection responds to the *global* shape, which in a deep cavity has the opposite sign to
the local response (a deeper bowl is darker in direct light but brighter overall): optionally
(``relief_every > 0``; off by default) every ``relief_every`` iterations a Gauss-Newton step is
taken in the span of a few *relief modes* (:func:`relief_modes`: the relief rescaled and
re-profiled) with the full-transport Jacobian from finite differences under common random
numbers (:func:`_global_step`).  At the standard budget it did not pay: on the cup it brought
the normals from 8.1 to 6.4 degrees but on the groove it took them from 1.2 to 4.6
(``docs/inverse.md``).

Optimiser (fixed budget, seeded).  Coarse to fine over the ``levels`` (film downsampling
factors; the images box-averaged, as a coarser box-filtered film records them; the default is the
full resolution alone, see Start), ``iterations`` per level.  Heights: Adam (Kingma & Ba 2015) with one normalisation for the whole vector (the
RMS of the second moments; Nicolet et al. 2021 use the maximum) on the Sobolev gradient
``(I + \lambda L)^{-1} \nabla_z E`` (``L`` the grid Laplacian, ``\lambda = (s/h)^2`` for a smoothing
length ``s = sobolev`` film widths: the preconditioner of the large-steps method of Nicolet et al.
2021; the Hessian of a shape-from-normals energy is a Laplacian, so this equalises the rate of
every frequency above ``1/s``), mean removed (a constant height is invisible to an orthographic
camera).  Albedo: Adam per texel on ``log rho``, ``rho`` in [0.01, 0.99].  Learning rates decay
exponentially from ``lr`` to ``decay * lr`` over all iterations (``lr_height`` in film widths);
Adam's moments restart at each level.  The result averages the iterates of the last ``average``
fraction of the last level (Polyak averaging of the stochastic steps).

Start.  A photometric-stereo estimate on the images, its normals integrated into corner heights
by least squares (:func:`~pbrbench.inverse.heightfield.heights_from_normals`), its albedo where
valid (the median elsewhere): by default the one whose model matches the transport of the images,
Nayar et al.'s interreflection-corrected estimate
(:func:`pbrbench.infer.photometric_stereo.photometric_stereo_nayar1991`) for images with
interreflection (``max_depth`` other than 2), Woodham's local one
(:func:`pbrbench.infer.photometric_stereo.photometric_stereo_woodham1980`) for direct light only
(Nayar's correction on such images removes light that is not there where its premise test
cannot refute it: 27 degrees on the groove).  The
fit is a refinement: the direct adjoint cannot undo the flattening that interreflection gives a
local start (from Woodham's start the cup ends at 7.2 degrees with the former coarse-to-fine
schedule), and even from the true surface a large step size walks the iterates away from it (the
Adam steps are as long as the learning rate whatever the gradient, and at the optimum the
gradient is the renders' noise), so the default schedule is one level at full resolution with a
small height step (``docs/inverse.md``).  ``start`` may also name the method or give the start.

Keeping the start.  Where the start's model holds (Woodham's on direct light) the fit can only
add the renders' noise to it.  After the last level the start and the fit are rendered with one
fresh seed (common random numbers) and their data terms compared pixel by pixel
(:func:`_compare_to_start`); where the fit matches the images worse than the start by more than
``keep_start`` standard errors of the difference, the start stands: its heights and albedo, and
the start method's own normals where it solved them (the integrated start loses detail).  A fit
whose data term is level with the start's is kept: its gain can lie below what the data term
resolves (ps_cap under interreflection: 0.11 % +- 0.21 % of the data term for 1.00 -> 0.59
degrees, the thin-plate prior averaging the renders' noise; ``docs/inverse.md``).

Per-pixel refinement under direct light (version 5).  A height field cannot hold every pixel's
own normal (integrating Woodham's normals into the mesh already costs 0.8 degrees on the cup),
but under direct light (``max_depth == 2``) the only thing a pixel's measurements need from the
rest of the surface is which sources reach it.  So the shape that stands (fit or start) is
rendered (the comparison's render, or one at ``spp``), and a measurement ``I_k`` counts as lit
where that render is at least ``refine_lit`` of the shape's unshadowed shading
``(\rho / \pi) \max(0, N \cdot s_k)`` (the pixel wholly lit: no cast shadow, no part of its
footprint in one) and above ``0.01`` of the pixel's brightest (Woodham's threshold); each pixel
with at least 3 such measurements whose sources span 3-D gets ``g = \rho N / \pi`` by least
squares on them (:func:`_refine_direct`), the others keep the shape's normal.  Under
interreflection the rest of the surface also sends light, and taking it from the fit's render
brings the fit's shape errors and the renders' noise into every pixel (ps_cup global: 7.8 degrees
against the fit's 1.4): the refinement is off there.

Assumed known (``docs/inverse.md``): the camera (orthographic); the lights as rendered
(``light_model="scene"``: the scene's emitters, area sources included; ``"vectors"``: distant
sources from the light vectors); the transport of the images (``max_depth``); that the scene holds
nothing but the surface seen in the mask, Lambertian, continued beyond the frame over the scene's
lateral extent as the linear extrapolation of its border; no ambient light.

References
----------
- B. Nicolet, A. Jacobson and W. Jakob, "Large steps in inverse rendering of geometry", ACM
  Transactions on Graphics 40(6), 2021.
- D. Vicini, S. Speierers and W. Jakob, "Path replay backpropagation: differentiating light
  paths using constant memory and linear time", ACM Transactions on Graphics 40(4), 2021.
- D. P. Kingma and J. Ba, "Adam: a method for stochastic optimization", ICLR 2015.
- S. K. Nayar, K. Ikeuchi and T. Kanade, "Shape from interreflections", International Journal
  of Computer Vision 6(3):173-195, 1991 (the local estimate corrected by the interreflection
  of the current shape, which the direct adjoint iterates).
- R. J. Woodham, "Photometric method for determining surface orientation from multiple images",
  Optical Engineering 19(1), 1980.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from pbrbench.checks import (
    as_float_array,
    check_finite,
    check_int,
    check_mask,
    check_number,
    check_positive,
)

VERSION = "5"  # under direct light each pixel's normal is refitted on the measurements the standing shape lights
# fully (version 4 returned the height field's normals; version 4 gave the start back where the fit matched the
# images worse than it beyond the renders' noise, keep_start = 2 standard errors; version 3 always returned the fit)
STARTS = ("woodham1980", "nayar1991")
# the methods it starts from and refits with, imported from their own modules: their code is part of this one's
# version (pbrbench.registry.helper_modules)
ADJOINTS = ("direct", "full")
LIGHT_MODELS = ("scene", "vectors")
CLAMP = 20.0           # per-vertex gradient clamp, in medians of |dE/dz|


@dataclass
class InverseRenderingResult:
    """Output of :func:`inverse_rendering_nicolet2021`.

    ``normals`` (H, W, 3) unit normals (camera frame), ``albedo`` (H, W) = rho / pi (the
    photometric-stereo convention for radiance images), ``valid`` (H, W) the data pixels,
    ``height`` (H, W) pixel-centre heights along the camera axis (mean 0), ``corner_heights``
    (H+1, W+1) the mesh's vertex heights (NaN off the surface), ``initial_normals`` /
    ``initial_albedo`` the start (``options["start"]`` names it), ``loss`` the objective per iteration
    (``level`` the level of each), ``wall_s`` / ``cpu_s`` the time, ``paths`` the camera paths
    traced (every render, primal and adjoint), ``options`` the settings used.
    """

    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    height: np.ndarray
    corner_heights: np.ndarray
    initial_normals: np.ndarray
    initial_albedo: np.ndarray
    loss: np.ndarray
    level: np.ndarray
    wall_s: float
    cpu_s: float
    paths: int
    options: dict = field(default_factory=dict)


def _fill_nearest(a: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """``a`` with the entries outside ``ok`` replaced by the nearest entry inside."""
    from scipy.ndimage import distance_transform_edt

    if ok.all():
        return a
    if not ok.any():
        return np.zeros_like(a)
    _, (ii, jj) = distance_transform_edt(~ok, return_indices=True)
    return a[ii, jj]


def _cauchy_scale2(res_data: np.ndarray, kappa: float) -> float:
    """``c^2`` of the Cauchy loss for the residuals ``res_data`` of the data pixels:
    ``c = kappa * 1.4826 * median |r|`` (a robust standard deviation), plus a floor."""
    return (kappa * 1.4826 * float(np.median(np.abs(res_data)))) ** 2 + 1e-30


def _robust(res: np.ndarray, data: np.ndarray, wts: np.ndarray, kappa: float):
    r"""``(loss, dE/dR, IRLS weights)`` of the residuals ``res`` (K, H, W): least squares
    (``kappa = 0``) or Cauchy, ``c^2 log(1 + r^2 / c^2)`` with ``c = kappa * 1.4826 * median |r|``
    over the data pixels."""
    w = wts[None]
    if kappa <= 0:
        return float((w * res * res).sum()), 2.0 * w * res, np.ones_like(res)
    c2 = _cauchy_scale2(res[:, data], kappa)
    irls = 1.0 / (1.0 + res * res / c2)
    return float((w * c2 * np.log1p(res * res / c2)).sum()), 2.0 * w * res * irls, irls


def _albedo_scale(R: np.ndarray, targets: np.ndarray, data: np.ndarray | None = None, sigma: float = 0.0) -> np.ndarray:
    """Per-pixel least-squares factor ``sum_k I R / sum_k R^2``: a Lambertian pixel's radiance is
    proportional to its own albedo under any transport.  With ``sigma > 0`` both sums are
    Gaussian-averaged (``sigma`` pixels, over ``data``) first: the factor of a noisy render
    varies smoothly instead of carrying the render's per-pixel noise into the albedo."""
    num, den = (targets * R).sum(axis=0), (R * R).sum(axis=0)
    if sigma > 0 and data is not None:
        from scipy.ndimage import gaussian_filter

        w = data.astype(float)
        num, den = gaussian_filter(num * w, sigma), gaussian_filter(den * w, sigma)
    return num / np.maximum(den, 1e-30)


def relief_modes(z: np.ndarray, n: int) -> np.ndarray:
    """(m, n_params) global deformations of a height field built from its own relief
    ``u = (z - mean) / sd``: ``u, u^2, ..., u^n`` (a rescaling and monotone re-profilings: a
    cavity made deeper, its rim steeper relative to its floor), centred, Gram-Schmidt
    orthogonalised and scaled to an RMS of ``sd`` (modes that vanish are dropped)."""
    sd = float(z.std())
    if sd <= 0:
        return np.zeros((0, z.size))
    u = (z - z.mean()) / sd
    out: list[np.ndarray] = []
    for p in range(1, n + 1):
        m = u ** p
        m = m - m.mean()
        for q in out:
            m = m - (m @ q) / (q @ q) * q
        nm = float(np.sqrt((m * m).mean()))
        if nm > 1e-6:
            out.append(m / nm * sd)
    return np.array(out).reshape(len(out), z.size)


def _global_step(sc, z, rho, targets, data, wts, irls, seed, spp, delta, n_modes, sigma=0.0):
    """Gauss-Newton step in the span of :func:`relief_modes` with the full-transport Jacobian
    from one-sided finite differences of relative size ``delta``, all with one seed (common
    random numbers: the differences carry far less Monte Carlo noise than the renders), and the
    residual from one more render with another seed (were it the Jacobian's base render, its
    noise would enter both and bias ``J^T r`` by ``-|noise|^2 / delta``: a step that deepens the
    relief every time); the coefficients are clamped to ``2 delta`` and each pixel's albedo is
    rescaled to the predicted renders (:func:`_albedo_scale`, its sums averaged over ``sigma``
    pixels).  Returns ``(z, rho, render sets used)``."""
    modes = relief_modes(z, n_modes)
    if len(modes) == 0:
        return z, rho, 0
    sc.set_state(z, rho, grad=False)
    R0 = sc.renders(seed, spp)
    # the residual from an independent render: with the Jacobian's own base render its noise
    # would correlate with the Jacobian's (J^T r would carry -|noise|^2 / delta, a bias that
    # deepens the relief at every step)
    Rr = sc.renders(seed + 1, spp)
    w = (wts[None] * irls)[:, data].ravel()
    r0 = (Rr - targets)[:, data].ravel()
    cols = []
    for m in modes:
        sc.set_state(z + delta * m, rho, grad=False)
        cols.append(((sc.renders(seed, spp) - R0)[:, data] / delta).ravel())
    J = np.stack(cols, 1)
    A = J.T @ (w[:, None] * J)
    A += 1e-6 * np.trace(A) / len(A) * np.eye(len(A))
    c = np.clip(-np.linalg.solve(A, J.T @ (w * r0)), -2 * delta, 2 * delta)
    pred = Rr.copy()
    pred[:, data] += (J @ c).reshape(len(R0), -1)
    f = np.clip(np.where(data, _albedo_scale(pred, targets, data, sigma), 1.0), 0.8, 1.25)
    return z + c @ modes, np.clip(rho * f, 0.01, 0.99), len(modes) + 2


def _check_levels(levels, iterations, shape) -> tuple[tuple[int, ...], tuple[int, ...]]:
    levels = tuple(check_int(f, "levels", lo=1) for f in levels)
    iterations = tuple(check_int(n, "iterations", lo=0) for n in iterations)
    if len(levels) == 0 or len(levels) != len(iterations):
        raise ValueError(f"levels / iterations: give one iteration count per level, got {len(levels)} levels and "
                         f"{len(iterations)} counts")
    if levels[-1] != 1:
        raise ValueError(f"levels: the last level must be 1 (the full resolution), got {levels}")
    if sum(iterations) == 0:
        raise ValueError("iterations: the budget is 0; give at least one iteration")
    h, w = shape
    for f in levels:
        if h % f or w % f or h // f < 4 or w // f < 4:
            raise ValueError(f"levels: factor {f} does not divide the image size {h}x{w} into at least 4x4 pixels; "
                             "choose factors that divide both sides")
    return levels, iterations


@dataclass(frozen=True)
class Options:
    """The schedule and model options of :func:`inverse_rendering_nicolet2021` (its Parameters
    say what each means); :meth:`checked` validates them for an image size."""

    levels: tuple = (1,)
    iterations: tuple = (20,)
    spp: int = 16
    spp_grad: int = 4
    lr_height: float = 0.0005
    lr_albedo: float = 0.02
    decay: float = 0.05
    smoothness: float = 0.5
    sobolev: float = 0.5
    average: float = 0.3
    robust: float = 3.0
    relief_every: int = 0
    relief_modes_n: int = 3
    relief_step: float = 0.05
    relief_spp: int = 8
    relief_sigma: float = 0.0
    keep_start: float = 2.0
    refine_lit: float = 0.9
    light_model: str = "scene"
    adjoint: str = "direct"
    extend: bool = True
    seed: int = 0

    def checked(self, shape: tuple[int, int]) -> Options:
        """The options validated for (H, W) images (``ValueError`` naming the option and the fix)."""
        if self.adjoint not in ADJOINTS:
            raise ValueError(f"adjoint: {self.adjoint!r}; use one of {', '.join(ADJOINTS)}")
        if self.light_model not in LIGHT_MODELS:
            raise ValueError(f"light_model: {self.light_model!r}; use 'scene' (the scene's emitters) or 'vectors' "
                             "(distant sources from the light vectors)")
        levels, iterations = _check_levels(self.levels, self.iterations, shape)
        return replace(
            self, levels=levels, iterations=iterations,
            spp=check_int(self.spp, "spp", lo=1), spp_grad=check_int(self.spp_grad, "spp_grad", lo=1),
            relief_spp=check_int(self.relief_spp, "relief_spp", lo=1),
            relief_every=check_int(self.relief_every, "relief_every", lo=0),
            relief_modes_n=check_int(self.relief_modes_n, "relief_modes_n", lo=1),
            relief_step=check_number(self.relief_step, "relief_step", lo=0.0, hi=0.5),
            relief_sigma=check_number(self.relief_sigma, "relief_sigma", lo=0.0),
            lr_height=check_positive(self.lr_height, "lr_height"), lr_albedo=check_positive(self.lr_albedo, "lr_albedo"),
            decay=check_number(self.decay, "decay", lo=0.0, hi=1.0),
            smoothness=check_number(self.smoothness, "smoothness", lo=0.0),
            sobolev=check_number(self.sobolev, "sobolev", lo=0.0),
            average=check_number(self.average, "average", lo=0.0, hi=1.0),
            robust=check_number(self.robust, "robust", lo=0.0), seed=check_int(self.seed, "seed", lo=0),
            keep_start=check_number(self.keep_start, "keep_start", lo=0.0),
            refine_lit=check_number(self.refine_lit, "refine_lit", lo=0.0, hi=1.0))


def _check_inputs(images, lights, mask, scene, max_depth):
    """The images (K, H, W) (colour: the channel mean), the light vectors, the mask and the
    transport, checked; ``ValueError`` naming the input and the fix otherwise."""
    from pbrbench.inverse.scene import check_camera

    imgs = as_float_array(images, "images", ndim=(3, 4))
    if imgs.ndim == 4:
        imgs = imgs.mean(axis=-1)
    k, h, w = imgs.shape
    lv = as_float_array(lights, "lights", ndim=(2,))
    if lv.shape != (k, 3):
        raise ValueError(f"lights: shape {lv.shape}, expected ({k}, 3): one source vector per image")
    if k < 3:
        raise ValueError(f"images: {k} image(s); photometric stereo needs at least 3 lights")
    if mask is None:
        raise ValueError("mask: required; inverse rendering fits the images over the object's pixels: pass the (H, W) "
                         "boolean object mask")
    m = check_mask(mask, (h, w))
    if not m.any():
        raise ValueError("mask: no pixel is set; pass the object's pixels")
    check_finite(imgs, "images", where=np.broadcast_to(m, imgs.shape))
    check_finite(lv, "lights")
    if scene is None or not hasattr(scene, "camera") or not hasattr(scene, "light_set"):
        raise ValueError("scene: required; pass the SceneSpec of the images (camera, light set, extent)")
    check_camera(scene)
    max_depth = check_int(max_depth, "max_depth", lo=-1)
    if max_depth in (0, 1):
        raise ValueError(f"max_depth: {max_depth}; use -1 (full interreflection) or >= 2 (2 = direct light only)")
    return imgs, lv, m, max_depth


def _start(imgs, lv, data, surf, hf_full, start, max_depth):
    """Corner heights, albedo rho, the start's name and its own normals (None for a given pair):
    the normals of the photometric-stereo method ``start`` names (None: :func:`_start_method`)
    integrated and its albedo (the median where it is not valid), or the pair ``start``."""
    from pbrbench.infer.photometric_stereo.nayar1991 import photometric_stereo_nayar1991
    from pbrbench.infer.photometric_stereo.woodham1980 import photometric_stereo_woodham1980
    from pbrbench.inverse import heightfield as HF

    # the two starts by name (their own modules, not the package's table: the table's other methods are
    # no part of this one's version, pbrbench.registry.helper_modules)
    methods = {"woodham1980": photometric_stereo_woodham1980, "nayar1991": photometric_stereo_nayar1991}
    h, w = data.shape
    if start is None or isinstance(start, str):
        name = _start_method(max_depth) if start is None else start
        if name not in STARTS:
            raise ValueError(f"start: {name!r}; use one of {', '.join(STARTS)}, None (by the transport) or a pair "
                             "(corner heights, albedo)")
        try:
            est = methods[name](imgs, lv, mask=data)
        except ValueError as e:
            if start is not None or name == "woodham1980":
                raise
            est, name = methods["woodham1980"](imgs, lv, mask=data), f"woodham1980 (nayar1991 refused: {e})"
        zc = _fill_nearest(hf_full.corners(HF.heights_from_normals(est.normals, est.valid, hf_full)), hf_full.active)
        rho0 = np.pi * est.albedo
        med = float(np.median(rho0[est.valid])) if est.valid.any() else 0.5
        rho = np.clip(np.where(est.valid, rho0, med), 0.01, 0.99)
        return zc, rho, name, np.where(est.valid[..., None], est.normals, np.nan)
    if len(start) != 2:
        raise ValueError("start: give a method name or a pair (corner heights (H+1, W+1), albedo (H, W))")
    zc = as_float_array(start[0], "start heights", ndim=(2,))
    rho = as_float_array(start[1], "start albedo", ndim=(2,))
    if zc.shape != (h + 1, w + 1) or rho.shape != (h, w):
        raise ValueError(f"start: heights {zc.shape} and albedo {rho.shape}; expected {(h + 1, w + 1)} and {(h, w)}")
    zc = _fill_nearest(np.nan_to_num(zc), hf_full.active & np.isfinite(zc))
    return zc, np.clip(rho, 0.01, 0.99), "given", None


def _start_method(max_depth: int) -> str:
    """The start whose model matches the transport of the images: Woodham's for direct light
    (``max_depth == 2``), Nayar et al.'s interreflection-corrected one otherwise."""
    return "woodham1980" if max_depth == 2 else "nayar1991"


@dataclass
class _Fit:
    """What the levels share: the problem, and the running iteration count, losses and paths."""

    imgs: np.ndarray
    data: np.ndarray
    surf: np.ndarray
    scene: object
    emitters: list
    max_depth: int
    opt: Options
    ext: tuple
    adj: object
    it: int = 0
    paths: int = 0
    losses: list = field(default_factory=list)
    lev: list = field(default_factory=list)


def _fit_level(fit: _Fit, f: int, n_it: int, last: bool, zc: np.ndarray, rho: np.ndarray):
    """One level of the coarse-to-fine schedule at downsampling ``f``: ``n_it`` Adam iterations
    (and the global steps) from corner heights ``zc`` and albedo ``rho`` at full resolution;
    returns them after the level, at full resolution."""
    from pbrbench.inverse import heightfield as HF
    from pbrbench.inverse.optim import Adam, LargeSteps, schedule
    from pbrbench.inverse.render import HeightFieldScene

    o, scene, imgs, data, surf = fit.opt, fit.scene, fit.imgs, fit.data, fit.surf
    k = imgs.shape[0]
    hw = float(scene.camera.half_width)
    film = 2.0 * hw
    total = sum(o.iterations)
    d_l = HF.downsample_mask(data, f) if f > 1 else data
    s_l = HF.downsample_any(surf, f) if f > 1 else surf
    t_l = HF.downsample_images(imgs, f) if f > 1 else imgs
    if not d_l.any():
        raise ValueError(f"levels: at factor {f} no coarse pixel lies wholly inside the mask; drop that level")
    hf = HF.HeightField(s_l, hw, extend=fit.ext)
    z = hf.params_from_corners(zc[::f, ::f])
    r_l = HF.downsample_images(rho[None], f)[0] if f > 1 else rho.copy()
    sc = HeightFieldScene(scene, hf, z, r_l, fit.emitters, max_depth=fit.max_depth, rr_depth=int(scene.render.rr_depth),
                          spp=o.spp, integrator="prb" if o.adjoint == "full" else "path")
    wts = np.where(d_l, 1.0, 0.0) / (d_l.sum() * k * max(float((t_l[:, d_l] ** 2).mean()), 1e-30))
    T = HF.thin_plate_matrix(hf)
    tw = o.smoothness / (f * f * max(T.shape[0], 1))   # the same curvature penalty at every level
    TT = (T.T @ T).tocsr()
    pre = LargeSteps(hf.laplacian(), (o.sobolev * film / hf.h) ** 2)
    opt_z, opt_a = Adam(hf.n_params, uniform="rms"), Adam(r_l.size)
    n_avg = max(1, int(round(o.average * n_it))) if last else 0
    z_sum, a_sum = np.zeros_like(z), np.zeros_like(r_l)
    for t in range(n_it):
        sd = o.seed * 100003 + fit.it
        if o.adjoint == "full":
            loss, gz, ga, R = sc.full_gradients(z, r_l, t_l, wts, sd, o.spp_grad)
            irls = np.ones_like(R)
        else:
            sc.set_state(z, r_l, grad=False)
            R = sc.renders(sd)
            loss, adj_img, irls = _robust(R - t_l, d_l, wts, o.robust)
            gz, ga = sc.backward(z, r_l, adj_img, sd, o.spp_grad, fit.adj)
        fit.paths += k * (o.spp + 2 * o.spp_grad) * s_l.size
        cap = CLAMP * float(np.median(np.abs(gz))) + 1e-30   # fireflies of the MC gradient
        gz = np.clip(gz, -cap, cap) + 2.0 * tw * (TT @ z)
        loss += tw * float(z @ (TT @ z))
        rate = schedule(fit.it, total, 1.0, o.decay)
        g = pre.gradient_u(gz)
        z = z + opt_z.step(g - g.mean(), rate * o.lr_height * film)
        r_l = np.clip(np.exp(np.log(r_l) + opt_a.step((ga * r_l).ravel(), rate * o.lr_albedo).reshape(r_l.shape)),
                      0.01, 0.99)
        if o.relief_every and t % o.relief_every == o.relief_every - 1:
            z, r_l, n_sets = _global_step(sc, z, r_l, t_l, d_l, wts, irls, sd + 7919, o.relief_spp,
                                          o.relief_step, o.relief_modes_n, o.relief_sigma)
            fit.paths += n_sets * k * o.relief_spp * s_l.size
        fit.losses.append(loss)
        fit.lev.append(f)
        fit.it += 1
        if t >= n_it - n_avg:
            z_sum += z
            a_sum += r_l
    if n_avg:
        z, r_l = z_sum / n_avg, a_sum / n_avg
    del sc
    # to the next level: corners bilinearly, albedo by pixel replication
    zc_l = _fill_nearest(hf.corners(z), hf.active)
    zc = HF.upsample_corners(zc_l, f) if f > 1 else zc_l
    rho = np.kron(r_l, np.ones((f, f))) if f > 1 else r_l
    return zc, rho


def _renders(fit: _Fit, states, spp: int) -> list[np.ndarray]:
    """(K, H, W) renders of each ``(corner heights, albedo)`` of ``states`` at full resolution under
    the images' transport, all with one seed that none of the fit's renders uses (common random
    numbers: the noise of two states' renders largely cancels in their difference)."""
    from pbrbench.inverse import heightfield as HF
    from pbrbench.inverse.render import HeightFieldScene

    hf = HF.HeightField(fit.surf, float(fit.scene.camera.half_width), extend=fit.ext)
    zs = [hf.params_from_corners(zc) for zc, _ in states]
    sc = HeightFieldScene(fit.scene, hf, zs[0], states[0][1], fit.emitters, max_depth=fit.max_depth,
                          rr_depth=int(fit.scene.render.rr_depth), spp=spp, integrator="path")
    seed = fit.opt.seed * 100003 + 7_000_003
    out = []
    for z, (_, rho) in zip(zs, states, strict=True):
        sc.set_state(z, rho, grad=False)
        out.append(sc.renders(seed))
    fit.paths += len(states) * fit.imgs.shape[0] * spp * fit.surf.size
    return out


def _compare_to_start(fit: _Fit, zc0, rho0, zc, rho, spp: int, z_crit: float) -> dict:
    """Whether the fit ``(zc, rho)`` matches the images worse than its start ``(zc0, rho0)`` by
    more than the renders' noise.  Both are rendered at full resolution with one fresh seed
    (:func:`_renders`); the data term is the fit's (the Cauchy scale of the start's residuals for
    both), per data pixel summed over the lights.  Returns ``{"improvement", "se", "kept_fit"}``:
    the data term's decrease and its standard error (``sqrt(n) sd`` of the ``n`` per-pixel
    differences), both relative to the start's data term; the fit is kept unless
    ``improvement < -z_crit * se``; and the two renders, (K, H, W) each."""
    o, imgs, data = fit.opt, fit.imgs, fit.data
    renders = _renders(fit, ((zc0, rho0), (zc, rho)), spp)
    per, c2 = [], None
    for r in renders:
        res = (r - imgs)[:, data]
        if c2 is None:
            c2 = _cauchy_scale2(res, o.robust) if o.robust > 0 else 0.0
        per.append((c2 * np.log1p(res * res / c2) if c2 > 0 else res * res).sum(axis=0))
    d = per[1] - per[0]
    total0 = max(float(per[0].sum()), 1e-300)
    se = float(np.sqrt(d.size) * d.std(ddof=1)) / total0 if d.size > 1 else float("inf")
    imp = -float(d.sum()) / total0
    return {"improvement": imp, "se": se, "kept_fit": not imp < -z_crit * se}, renders


def _refine_direct(imgs, lv, data, normals, rho, rendered, lit_fraction: float):
    """Per-pixel least squares under direct light on the measurements the shape lights fully
    (module docstring, Per-pixel refinement): ``(normals, albedo rho / pi, refined mask)``.

    ``normals`` (H, W, 3) and ``rho`` (H, W) are the shape's, ``rendered`` (K, H, W) its direct
    render; a measurement is lit where ``rendered >= lit_fraction * (rho / pi) max(0, N.s_k)``
    and the image is above 0.01 of the pixel's brightest measurement.  The solve is Woodham's
    least squares on those measurements (at least 3, sources spanning 3-D), kept where the normal
    faces the camera."""
    from pbrbench.infer.photometric_stereo.woodham1980 import photometric_stereo_woodham1980

    shade = (rho / np.pi)[None] * np.maximum(0.0, np.einsum("hwc,kc->khw", normals, lv))
    peak = np.maximum(imgs.max(axis=0, keepdims=True), np.finfo(float).tiny)
    lit = (shade > 0) & (rendered >= lit_fraction * shade) & (imgs > 0.01 * peak) & data[None]
    r = photometric_stereo_woodham1980(imgs, lv, mask=data, used=lit)
    ok = r.valid & (r.normals[..., 2] > 0)                                 # facing the camera
    n = np.where(ok[..., None], r.normals, normals)
    return n, np.where(ok, r.albedo, rho / np.pi), ok


def inverse_rendering_nicolet2021(images, lights, *, mask, scene, max_depth: int = -1,
                                  levels=(1,), iterations=(20,), spp: int = 16, spp_grad: int = 4,
                                  lr_height: float = 0.0005, lr_albedo: float = 0.02, decay: float = 0.05,
                                  smoothness: float = 0.5, sobolev: float = 0.5, average: float = 0.3,
                                  robust: float = 3.0, relief_every: int = 0, relief_modes_n: int = 3,
                                  relief_step: float = 0.05, relief_spp: int = 8, relief_sigma: float = 0.0,
                                  keep_start: float = 2.0, refine_lit: float = 0.9, light_model: str = "scene",
                                  adjoint: str = "direct", extend: bool = True,
                                  seed: int = 0, start=None, callback=None) -> InverseRenderingResult:
    r"""Height field and albedo by inverse rendering (module docstring: model, gradient, optimiser).

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear radiance images, one per light of the light set (colour: the channel mean).
    lights : (K, 3) array
        Source vectors (camera frame, toward the source, length = irradiance): the start's
        photometric stereo, and the emitters with ``light_model="vectors"``.
    mask : (H, W) bool
        The object's pixels (required: the loss is taken over them).
    scene : pbrbench.scene.spec.SceneSpec
        The scene description of the images: its camera (orthographic), light set, lateral extent
        and ``render.rr_depth`` are read, never its shapes' geometry or materials
        (:mod:`pbrbench.inverse.scene`).
    max_depth : int
        Transport of the images: -1 full interreflection, 2 direct light only.
    levels, iterations : sequences of int
        Film downsampling factors (coarse to fine, ending with 1) and the iterations at each.
    spp, spp_grad : int
        Samples per pixel of the full-transport render and of the adjoint (direct) render.
    lr_height : float
        Initial height step, in film widths (``2 * half_width``).
    lr_albedo : float
        Initial step of ``log rho``.
    decay : float
        Final learning rate / initial one (exponential schedule over all iterations).
    smoothness : float
        Weight ``w`` of the thin-plate prior.
    sobolev : float
        Smoothing length of the Sobolev preconditioner, in film widths.
    average : float
        Fraction of the last level's iterations averaged into the result.
    robust : float
        Cauchy scale in robust standard deviations of the residuals (0: least squares).
    relief_every, relief_modes_n, relief_step, relief_spp : int, int, float, int
        Global Gauss-Newton step every ``relief_every`` iterations (0, the default: never) over
        ``relief_modes_n`` relief modes, finite differences of relative size ``relief_step`` from
        renders at ``relief_spp`` samples per pixel.
    relief_sigma : float
        Smoothing (pixels of the level) of the albedo factor of the global step (0: per pixel).
    keep_start : float
        The start is returned where the fit's data term exceeds the start's by more than
        ``keep_start`` standard errors of the difference (module docstring, Keeping the start;
        0: the fit is always returned).  ``options["versus_start"]`` records the comparison.
    refine_lit : float
        Under direct light (``max_depth == 2``), refit each pixel's normal and albedo on the
        measurements where the standing shape's render is at least this fraction of its unshadowed
        shading (module docstring, Per-pixel refinement; 0: no refinement).
        ``options["refined"]`` records the fraction of data pixels refitted.
    light_model : {"scene", "vectors"}
    adjoint : {"direct", "full"}
        Back-propagate the residual through direct light only, or through every bounce.
    extend : bool
        Continue the surface beyond the frame over the scene's lateral extent.
    seed : int
        Seed of every Monte Carlo render: the result is a function of the inputs, the options and
        the seed, up to the order in which the adjoint render's threads add into the vertex
        gradients (floating-point sums; two calls on ps_cap[albedo=0.9] ``global`` differed by up
        to 6e-4 in a normal component, 0.568 against 0.569 degrees; ``docs/inverse.md``).
    start : None, str or (heights, albedo)
        None (the default): ``"nayar1991"`` for images with interreflection (``max_depth`` other
        than 2), ``"woodham1980"`` for direct light; where Nayar's method refuses the images
        (e.g. a surface of fewer than 4 facets), Woodham's, recorded in ``options["start"]``.  A
        name of :data:`STARTS`: that method's estimate.  A pair: corner heights (H+1, W+1) along
        the camera axis (row 0 at the top) and the albedo rho (H, W) (not divided by pi).
    callback : callable, optional
        Called after each level as ``callback(factor, normals, albedo)`` (full resolution,
        albedo divided by pi).

    Returns
    -------
    InverseRenderingResult

    Raises
    ------
    ValueError
        On a missing or empty mask, mismatched shapes or light counts, a non-orthographic camera,
        bad options, or a Mitsuba build without a differentiable variant.
    """
    from pbrbench.inverse import heightfield as HF
    from pbrbench.inverse.render import ad_mitsuba
    from pbrbench.inverse.scene import frame_extension, light_dicts

    t0, c0 = time.perf_counter(), time.process_time()
    imgs, lv, m, max_depth = _check_inputs(images, lights, mask, scene, max_depth)
    o = Options(levels=levels, iterations=iterations, spp=spp, spp_grad=spp_grad, lr_height=lr_height,
                lr_albedo=lr_albedo, decay=decay, smoothness=smoothness, sobolev=sobolev, average=average,
                robust=robust, relief_every=relief_every, relief_modes_n=relief_modes_n, relief_step=relief_step,
                relief_spp=relief_spp, relief_sigma=relief_sigma, keep_start=keep_start, refine_lit=refine_lit,
                light_model=light_model, adjoint=adjoint,
                extend=extend, seed=seed).checked(imgs.shape[1:])

    mi = ad_mitsuba()
    h, w = imgs.shape[1:]
    ext = frame_extension(scene, h, w) if o.extend else (0.0, 0.0, 0.0, 0.0)
    data, surf = HF.pixel_sets(m, imgs)
    hf_full = HF.HeightField(surf, float(scene.camera.half_width))
    zc, rho, start_name, start_normals = _start(imgs, lv, data, surf, hf_full, start, max_depth)
    zc0, rho0 = zc.copy(), rho.copy()
    initial_normals = np.where(surf[..., None], HF.pixel_normals(zc, hf_full.h), 0.0)
    initial_albedo = np.where(data, rho / np.pi, 0.0)

    fit = _Fit(imgs, data, surf, scene, light_dicts(mi, scene, lv, o.light_model), max_depth, o, ext,
               mi.load_dict({"type": "prb", "max_depth": 2}) if o.adjoint == "direct" else None)
    for li, (f, n_it) in enumerate(zip(o.levels, o.iterations, strict=True)):
        if n_it == 0:
            continue
        zc, rho = _fit_level(fit, f, n_it, li == len(o.levels) - 1, zc, rho)
        if callback is not None:
            callback(f, np.where(surf[..., None], HF.pixel_normals(zc, hf_full.h), 0.0), rho / np.pi)

    verdict, rendered = None, None
    if o.keep_start > 0:
        verdict, renders = _compare_to_start(fit, zc0, rho0, zc, rho, o.spp, o.keep_start)
        rendered = renders[1]
        if not verdict["kept_fit"]:          # no better than the start beyond the noise: the start stands
            zc, rho, rendered = zc0, rho0, renders[0]
    normals = np.where(surf[..., None], HF.pixel_normals(zc, hf_full.h), 0.0)
    mesh_normals = normals
    if verdict is not None and not verdict["kept_fit"] and start_normals is not None:
        # the start method's own normals where it solved (integrating them lost detail)
        normals = np.where(np.isfinite(start_normals), np.nan_to_num(start_normals), normals)
        normals = np.where(surf[..., None], normals, 0.0)
    albedo = np.where(data, rho / np.pi, 0.0)
    refined = None
    if max_depth == 2 and o.refine_lit > 0:  # direct light: each pixel refitted where the shape lights it fully
        if rendered is None:
            rendered = _renders(fit, ((zc, rho),), o.spp)[0]
        n_r, a_r, ok = _refine_direct(imgs, lv, data, mesh_normals, rho, rendered, o.refine_lit)
        normals = np.where(ok[..., None], n_r, normals)
        albedo = np.where(ok, a_r, albedo)
        refined = float(ok.sum() / max(int(data.sum()), 1))
    height = np.where(surf, HF.pixel_heights(zc), 0.0)
    height = np.where(surf, height - height[surf].mean(), 0.0)
    opts = {**asdict(o), "extend": ext, "max_depth": max_depth, "variant": mi.variant(), "start": start_name,
            "versus_start": verdict, "refined": refined}
    return InverseRenderingResult(
        normals=normals, albedo=albedo, valid=data, height=height,
        corner_heights=np.where(hf_full.active, zc, np.nan), initial_normals=initial_normals,
        initial_albedo=initial_albedo, loss=np.asarray(fit.losses), level=np.asarray(fit.lev),
        wall_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0, paths=int(fit.paths), options=opts)
