r"""Zheng & Chellappa (1991): illuminant direction, albedo and shape from one shaded image.

Under their assumption that the surface normals are uniformly distributed (tilt uniform on
``[0, 2 pi)``, slant ``alpha`` of density ``cos(alpha)`` on ``[0, pi/2]``) and that self-shadowing
is negligible, the first two moments of ``I = lambda N . S`` (``lambda`` the albedo times the
source intensity, ``sigma`` the light's slant) are

.. math::
    E\{I\} = \frac{\pi}{4}\,\lambda\cos\sigma, \qquad
    E\{I^2\} = \frac{1}{6}\,\lambda^2\,(1 + 3\cos^2\sigma),

which invert in closed form to

.. math::
    \lambda = \frac{\sqrt{6\pi^2 E\{I^2\} - 48 E\{I\}^2}}{\pi}, \qquad
    \cos\sigma = \frac{4 E\{I\}}{\sqrt{6\pi^2 E\{I^2\} - 48 E\{I\}^2}}.

The tilt ``tau`` is the direction of the mean (Gaussian-smoothed) image gradient.  With the
albedo and light so estimated the shape is solved by an SFS method of this package (Horn's 1989
scheme by default; see :func:`shape_from_shading_zheng_chellappa1991`).

References
----------
Q. Zheng and R. Chellappa, "Estimation of illuminant direction, albedo, and shape from shading",
IEEE Transactions on Pattern Analysis and Machine Intelligence 13(7):680-702, 1991.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from scipy import ndimage

from pbrbench.checks import as_float_array, call_method, check_finite, check_method, check_number
from pbrbench.infer.sfs._common import LightEstimate, SFSResult, _prepare_light_image
from pbrbench.infer.sfs.horn1989 import shape_from_shading_horn1989
from pbrbench.infer.sfs.pentland1990 import shape_from_shading_pentland1990
from pbrbench.infer.sfs.tsai_shah1994 import shape_from_shading_tsai_shah1994

__all__ = ["light_from_shading_zheng_chellappa1991", "shape_from_shading_zheng_chellappa1991",
           "zheng_chellappa_moments"]

SHAPE_METHODS = {
    "horn1989": shape_from_shading_horn1989,
    "tsai_shah1994": shape_from_shading_tsai_shah1994,
    "pentland1990": shape_from_shading_pentland1990,
}
ESTIMATES = ("both", "albedo", "light")


def zheng_chellappa_moments(m1: float, m2: float) -> tuple[float, float, bool]:
    r"""``(lambda, sigma, clamped)`` from the brightness moments ``m1 = E{I}``, ``m2 = E{I^2}``.

    .. math::
        \lambda = \sqrt{6 m_2 - 48 m_1^2 / \pi^2}, \qquad
        \cos\sigma = \frac{4 m_1}{\pi \lambda}

    (Zheng & Chellappa 1991).  Since ``m2 >= m1^2`` the root is always real, but ``cos sigma``
    exceeds 1 when the image is more uniform than uniformly distributed normals allow (a plane,
    a nearly flat surface): it is then clamped to 1 (``sigma = 0``) and ``clamped`` is True.
    """
    lam2 = 6.0 * m2 - 48.0 * m1 * m1 / (math.pi * math.pi)
    lam = math.sqrt(max(lam2, 0.0))
    if lam <= 0:
        return 0.0, 0.0, True
    cs = 4.0 * m1 / (math.pi * lam)
    return lam, math.acos(min(cs, 1.0)), cs > 1.0 + 1e-9   # (not rounding at sigma = 0)


def _estimate(image, mask, sigma):
    """``(direction, albedo, info)`` of the Zheng-Chellappa estimator (inputs checked here)."""
    img, m, imax = _prepare_light_image(image, mask)
    s = check_number(sigma, "sigma", lo=0.0, hi=64.0)
    u = img / imax                                   # the moments of 1e300 images stay finite
    # the tilt: mean smoothed gradient over the interior (away from the mask's edge, where the
    # jump to the background would dominate)
    sm = ndimage.gaussian_filter(np.where(m, u, 0.0), s) if s > 0 else np.where(m, u, 0.0)
    inner = ndimage.binary_erosion(m, iterations=2 + int(math.ceil(3 * s)), border_value=0)
    if inner.sum() < 16:
        inner = m
    gr, gc = np.gradient(sm)
    mx, my = float(gc[inner].mean()), float(-gr[inner].mean())   # y up: rows go down
    tilt = math.atan2(my, mx) if (mx or my) else 0.0
    lam, slant, clamped = zheng_chellappa_moments(float(u[m].mean()), float((u[m] ** 2).mean()))
    if lam <= 0:
        raise ValueError("image: zero variance and mean inside the mask; the albedo cannot be estimated")
    d = np.array([math.sin(slant) * math.cos(tilt), math.sin(slant) * math.sin(tilt), math.cos(slant)])
    info = {"tilt_deg": math.degrees(tilt), "slant_deg": math.degrees(slant), "clamped": clamped}
    return d, lam * imax, info


def light_from_shading_zheng_chellappa1991(image, mask=None, *, sigma: float = 1.0) -> LightEstimate:
    r"""Light direction and albedo from the brightness moments, by Zheng & Chellappa's closed form.

    .. math::
        \tau = \operatorname{atan2}(\langle \tilde I_y \rangle, \langle \tilde I_x \rangle),
        \qquad
        \lambda = \frac{\sqrt{6\pi^2 \langle I^2 \rangle - 48 \langle I \rangle^2}}{\pi},
        \qquad
        \cos\sigma = \frac{4 \langle I \rangle}{\pi \lambda}

    (Zheng & Chellappa, IEEE PAMI 1991): ``tilde I`` the image smoothed by a Gaussian of
    ``sigma`` pixels, its gradient averaged over the mask eroded by ``2 + ceil(3 sigma)``
    pixels; the moments over the whole mask.  Exact for normals uniformly distributed in their
    sense (tilt uniform, slant density ``cos alpha``) without self-shadowing; on a sphere's
    image (normals uniform over the image disc, attached shadows) it is biased: slant +22 degrees
    and albedo -8 % under a frontal light, +4 degrees and -2 % at a 45 degree slant.  When
    ``cos sigma > 1`` (an image more uniform than the assumption allows) the slant is clamped to 0.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    mask : (H, W) bool, optional
        The object's pixels (default: the whole image).
    sigma : float
        Gaussian smoothing of the image before the gradient (pixels, >= 0, at most 64).

    Returns
    -------
    LightEstimate
        ``direction`` (3,) unit vector toward the source (``z >= 0``), ``albedo`` (``lambda``:
        albedo times source intensity), ``method="zheng_chellappa1991"``.

    Raises
    ------
    ValueError
        On a bad image or mask (negative, non-finite, all zero) or ``sigma``.

    References
    ----------
    Q. Zheng and R. Chellappa, "Estimation of illuminant direction, albedo, and shape from
    shading", IEEE Transactions on Pattern Analysis and Machine Intelligence 13(7):680-702, 1991.
    """
    d, rho, _ = _estimate(image, mask, sigma)
    return LightEstimate(direction=d, albedo=float(rho), method="zheng_chellappa1991")


def shape_from_shading_zheng_chellappa1991(image, light=None, *, albedo=None, mask=None, pixel_size: float = 1.0,
                                           estimate: str = "both", sigma: float = 1.0,
                                           shape_method: str = "horn1989", shape_options=None) -> SFSResult:
    r"""Height, normals, albedo and light from one image: Zheng & Chellappa's estimates, then SFS.

    First the albedo ``lambda`` and the light ``S = (sin sigma cos tau, sin sigma sin tau,
    cos sigma)`` from the image statistics,

    .. math::
        \lambda = \frac{\sqrt{6\pi^2 E\{I^2\} - 48 E\{I\}^2}}{\pi}, \qquad
        \cos\sigma = \frac{4 E\{I\}}{\pi\lambda}, \qquad
        \tan\tau = \frac{E\{\tilde I_y\}}{E\{\tilde I_x\}}

    (:func:`light_from_shading_zheng_chellappa1991`), then the shape by solving
    ``I / lambda = R(p, q)`` for that light with the SFS method ``shape_method``.  Zheng &
    Chellappa's own shape iteration (brightness and intensity-gradient errors plus
    integrability, hierarchical) is **not** implemented: the default ``"horn1989"`` minimises
    the same brightness-plus-integrability energy with a smoothness term in place of the
    intensity-gradient term, by the same kind of coupled coarse-to-fine ``(p, q, z)`` iteration,
    and is the package's most accurate method under an oblique light; reusing it means that a
    comparison with ``horn1989`` given a (wrong) albedo isolates exactly what this method adds,
    the estimated albedo and light.

    Calling convention: that of every SFS method, ``fn(image, light, *, albedo, mask,
    pixel_size)``, but what is estimated is *not* taken from the arguments: with
    ``estimate="both"`` (default) ``light`` and ``albedo`` are ignored (pass None, or the task's
    nominal values, which are then only reported in ``info``); ``"albedo"`` uses the given
    ``light`` (required) and estimates the albedo; ``"light"`` uses the given ``albedo``
    (required) and estimates the light.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    light : (3,) array or None
        Direction toward the source; used only with ``estimate="albedo"`` (then ``z > 0``).
    albedo : float or None
        Albedo times source intensity; used only with ``estimate="light"``.
    mask : (H, W) bool, optional
        The object's pixels (default: the whole image).
    pixel_size : float
        Pixel pitch in world units; the height is returned in these units.
    estimate : {"both", "albedo", "light"}
        What to estimate from the image (the rest is taken from the arguments).
    sigma : float
        Gaussian smoothing (pixels) of the tilt estimate.
    shape_method : {"horn1989", "tsai_shah1994", "pentland1990"}
        The SFS method run with the estimated albedo and light.
    shape_options : dict, optional
        Options forwarded to ``shape_method`` (e.g. ``{"max_iter": 50}``).

    Returns
    -------
    SFSResult
        ``method="zheng_chellappa1991"``; ``light`` and ``albedo`` are the ones used (the
        estimates); ``converged``, ``n_iter`` those of the SFS method; ``info`` holds the SFS
        method's own info plus ``shape_method``, ``estimate``, ``estimated_light``,
        ``estimated_albedo``, ``tilt_deg``, ``slant_deg``, ``clamped`` (the slant was clamped to
        0), ``given_light`` and ``given_albedo``.

    Raises
    ------
    ValueError
        On bad input (see :func:`pbrbench.infer.sfs.shape_from_shading`), an unknown
        ``estimate`` / ``shape_method`` / shape option, or a missing ``light`` (``estimate=
        "albedo"``) or ``albedo`` (``estimate="light"``).

    References
    ----------
    Q. Zheng and R. Chellappa, "Estimation of illuminant direction, albedo, and shape from
    shading", IEEE Transactions on Pattern Analysis and Machine Intelligence 13(7):680-702, 1991;
    B. K. P. Horn, "Height and gradient from shading", International Journal of Computer Vision
    5(1):37-75, 1990 (the default shape solver).
    """
    check_method(estimate, ESTIMATES, "estimate")
    check_method(shape_method, tuple(SHAPE_METHODS), "shape_method")
    if shape_options is None:
        shape_options = {}
    elif not isinstance(shape_options, dict):
        raise ValueError(f"shape_options: expected a dict of {shape_method} options, got {type(shape_options).__name__}")
    for k in ("albedo", "mask", "pixel_size"):
        if k in shape_options:
            raise ValueError(f"shape_options: {k!r} is an argument of this method, not a shape option; pass it directly")
    if light is not None:      # a given light is checked even where it is not used: a bad one is the caller's error
        given = as_float_array(light, "light", ndim=(1,))
        if given.shape != (3,):
            raise ValueError(f"light: expected a 3-vector (x, y, z) toward the source, got shape {given.shape}")
        check_finite(given, "light")
    if estimate == "albedo" and light is None:
        raise ValueError("light: estimate='albedo' uses the given light; pass it, or use estimate='both'")
    if estimate == "light" and albedo is None:
        raise ValueError("albedo: estimate='light' uses the given albedo; pass it, or use estimate='both'")
    t0 = time.perf_counter()
    d, rho, info = _estimate(image, mask, sigma)
    s_use = d if estimate in ("both", "light") else light
    rho_use = rho if estimate in ("both", "albedo") else albedo
    res = call_method(SHAPE_METHODS, shape_method, "zheng_chellappa1991", image, s_use, albedo=rho_use, mask=mask,
                      pixel_size=pixel_size, **shape_options)
    info = dict(res.info, shape_method=shape_method, estimate=estimate, estimated_light=d, estimated_albedo=rho,
                given_light=None if light is None else np.asarray(light, float), given_albedo=albedo, **info)
    return replace(res, method="zheng_chellappa1991", info=info, seconds=time.perf_counter() - t0)
