r"""Shape from shading: height, normals and light from one shaded image.

Model (all methods): a Monge patch ``z = f(x, y)`` seen orthographically along ``z`` in the
camera frame of ``docs/conventions.md`` (x right, y up, z toward the camera; row 0 is the top),
of uniform Lambertian albedo ``rho``, lit by one distant source of unit direction ``S`` (toward
the source).  With ``p = f_x``, ``q = f_y`` the image irradiance equation is

.. math::
    I(x, y) = \rho\, R(p, q), \qquad
    R(p, q) = \max\Big(0, \frac{S_z - S_x p - S_y q}{\sqrt{1 + p^2 + q^2}}\Big),

the normal being ``N = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``.  Every method works on the
normalised image ``E = I / rho`` (clipped to [0, 1]) in **pixel units** (slopes are unitless; the
height is computed in pixels and multiplied by ``pixel_size`` at the end).

Objects
-------
shape_from_shading
    Dispatcher over ``METHODS``: height and normals from one image under a known light.
    Each method is also a public function ``fn(image, light, *, albedo=None, mask=None,
    pixel_size=1.0, <its own options>) -> SFSResult``:

    - ``"horn1989"``: :func:`shape_from_shading_horn1989` (Horn 1989), coupled height and
      gradient iteration (the default);
    - ``"tsai_shah1994"``: :func:`shape_from_shading_tsai_shah1994` (Tsai & Shah 1994),
      linearisation in the height, solved by damped Newton steps;
    - ``"pentland1990"``: :func:`shape_from_shading_pentland1990` (Pentland 1990), linear
      shape from shading in the Fourier domain;
    - ``"kimmel2001"``: :func:`shape_from_shading_kimmel2001` (Kimmel & Sethian 2001), fast
      marching of the eikonal equation (scikit-fmm, imported when called);
    - ``"zheng_chellappa1991"``: :func:`shape_from_shading_zheng_chellappa1991` (Zheng &
      Chellappa 1991), albedo and light estimated from the image statistics, then Horn's
      scheme: the one method that ignores the given light and albedo (``light=None`` allowed).
light_from_shading
    Dispatcher over ``LIGHT_METHODS``: light direction (and albedo) from one image:
    ``"contour"`` (:func:`light_from_shading_contour`, occluding-contour robust fit; a
    descriptive name), ``"lee_rosenfeld1985"`` (:func:`light_from_shading_lee_rosenfeld1985`,
    image statistics) and ``"zheng_chellappa1991"`` (:func:`light_from_shading_zheng_chellappa1991`,
    the brightness moments' closed form).
SFSResult, LightEstimate
    Frozen result records.
integrate_gradients, occluding_boundary
    The shared least-squares integrator and the silhouette's contour pixels.

References
----------
- B. K. P. Horn, "Height and gradient from shading", International Journal of Computer Vision
  5(1):37-75, 1990 (MIT AI Memo 1105, 1989).
- P.-S. Tsai and M. Shah, "Shape from shading using linear approximation", Image and Vision
  Computing 12(8):487-498, 1994.
- A. P. Pentland, "Linear shape from shading", International Journal of Computer Vision
  4(2):153-162, 1990.
- R. Kimmel and J. A. Sethian, "Optimal algorithm for shape from shading and path planning",
  Journal of Mathematical Imaging and Vision 14(3):237-244, 2001.
- C.-H. Lee and A. Rosenfeld, "Improved methods of estimating shape from shading using the light
  source coordinate system", Artificial Intelligence 26(2):125-143, 1985.
- A. P. Pentland, "Finding the illuminant direction", Journal of the Optical Society of America
  72(4):448-455, 1982.
- P. Nillius and J.-O. Eklundh, "Automatic estimation of the projected light source direction",
  CVPR 2001 (light from the occluding contour).
- Q. Zheng and R. Chellappa, "Estimation of illuminant direction, albedo, and shape from
  shading", IEEE TPAMI 13(7):680-702, 1991.
- R. Zhang, P.-S. Tsai, J. E. Cryer and M. Shah, "Shape from shading: a survey", IEEE TPAMI
  21(8):690-706, 1999.
"""

from __future__ import annotations

from pbrbench.checks import call_method
from pbrbench.infer.sfs._common import (
    LightEstimate,
    SFSResult,
    integrate_gradients,
    occluding_boundary,
)
from pbrbench.infer.sfs.contour import light_from_shading_contour
from pbrbench.infer.sfs.horn1989 import shape_from_shading_horn1989
from pbrbench.infer.sfs.kimmel2001 import shape_from_shading_kimmel2001
from pbrbench.infer.sfs.lee_rosenfeld1985 import light_from_shading_lee_rosenfeld1985
from pbrbench.infer.sfs.pentland1990 import shape_from_shading_pentland1990
from pbrbench.infer.sfs.tsai_shah1994 import shape_from_shading_tsai_shah1994
from pbrbench.infer.sfs.zheng_chellappa1991 import (
    light_from_shading_zheng_chellappa1991,
    shape_from_shading_zheng_chellappa1991,
)

__all__ = [
    "METHODS",
    "LIGHT_METHODS",
    "SFSResult",
    "LightEstimate",
    "shape_from_shading",
    "shape_from_shading_horn1989",
    "shape_from_shading_tsai_shah1994",
    "shape_from_shading_pentland1990",
    "shape_from_shading_kimmel2001",
    "shape_from_shading_zheng_chellappa1991",
    "light_from_shading",
    "light_from_shading_contour",
    "light_from_shading_lee_rosenfeld1985",
    "light_from_shading_zheng_chellappa1991",
    "integrate_gradients",
    "occluding_boundary",
]

METHODS = {
    "horn1989": shape_from_shading_horn1989,
    "tsai_shah1994": shape_from_shading_tsai_shah1994,
    "pentland1990": shape_from_shading_pentland1990,
    "kimmel2001": shape_from_shading_kimmel2001,
    "zheng_chellappa1991": shape_from_shading_zheng_chellappa1991,
}
LIGHT_METHODS = {
    "contour": light_from_shading_contour,
    "lee_rosenfeld1985": light_from_shading_lee_rosenfeld1985,
    "zheng_chellappa1991": light_from_shading_zheng_chellappa1991,
}


def shape_from_shading(image, light, *, method: str = "horn1989", **options) -> SFSResult:
    r"""Height and normals of a Lambertian surface from one image under a known distant light.

    Solves the image irradiance equation

    .. math:: E(x, y) = \frac{I(x, y)}{\rho} = R(p, q)

    (module docstring) for ``z = f(x, y)``: orthographic view along ``-z``, uniform known albedo,
    one distant source of known direction, no interreflections, no cast shadows (attached
    shadows, ``E = 0``, are treated as "no constraint where ``R <= 0``").  Dispatches to
    ``METHODS[method]``, forwarding ``options``; an option the chosen method does not take
    raises ``ValueError`` listing the ones it does.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    light : (3,) array
        Direction toward the source in the camera frame (normalised here); needs ``z > 0``.
    method : {"horn1989", "tsai_shah1994", "pentland1990", "kimmel2001"}
        ``"horn1989"`` (default; Horn, IJCV 1990 / AI Memo 1989),
        ``"tsai_shah1994"`` (Tsai & Shah, IVC 1994), ``"pentland1990"`` (Pentland, IJCV 1990),
        ``"kimmel2001"`` (Kimmel & Sethian, JMIV 2001): see the method functions
        :func:`shape_from_shading_horn1989` and the others for the algorithm and its options.
    albedo : float, optional
        Uniform albedo (times source intensity).  Default: the brightest pixel in the mask,
        i.e. assume some visible point faces the light (Pentland 1982's assumption).
    mask : (H, W) bool, optional
        Pixels of the surface.  Default: the whole image (then there is no occluding contour).
    pixel_size : float
        Pixel pitch in world units; the height is returned in these units.
    **options
        The chosen method's own options: ``horn1989``: ``max_iter`` (100), ``tol`` (1e-4),
        ``boundary`` ("auto"), ``theta_max_deg`` (88), ``smoothness`` (1), ``smoothness_min``
        (0.02), ``integrability`` (1), ``n_stages`` (4), ``levels`` (5); ``tsai_shah1994``:
        ``max_iter`` (100), ``tol`` (1e-4), ``damping`` (1e-2); ``pentland1990``:
        ``regularization`` (0.1); ``kimmel2001``: ``seeds`` ("auto"), ``singular_delta``
        (1e-3), ``e_min`` (1e-2).

    Returns
    -------
    SFSResult
        ``height`` (H, W) in ``pixel_size`` units with mean zero on the mask (the offset is
        free), ``normals`` (H, W, 3), ``converged``, ``n_iter``, ``method``, ``light``,
        ``albedo``, ``seconds``, ``info``.  A method that stops without meeting its tolerance
        issues a ``RuntimeWarning`` naming the method and the last update size.  The outputs
        never contain NaN.

    Raises
    ------
    ValueError
        On an unknown method or option, or bad input (wrong shapes, NaN, negative pixels, light
        with ``z <= 0``, non-positive albedo / pixel size, bad option values).

    Notes
    -----
    Convex/concave ambiguity: under a frontal light ``f`` and ``-f`` give the same image; all
    methods here pick the convex solution (contour boundary conditions, dome start, maxima at
    the singular points).  Score with :func:`pbrbench.metrics.sfs.ambiguity_aware_scores`.

    References
    ----------
    R. Zhang, P.-S. Tsai, J. E. Cryer and M. Shah, "Shape from shading: a survey", IEEE TPAMI
    21(8):690-706, 1999 (and the method functions' own references).
    """
    return call_method(METHODS, method, "shape_from_shading", image, light, **options)


def light_from_shading(image, mask=None, *, method: str = "contour", **options) -> LightEstimate:
    r"""Estimate the distant light direction (and albedo) from one image of a Lambertian object.

    Dispatches to ``LIGHT_METHODS[method]``, forwarding ``options`` (an option the chosen method
    does not take raises ``ValueError`` listing the ones it does).  Both methods assume one
    object of uniform albedo under ``I = rho max(0, N . S)``.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    mask : (H, W) bool, optional
        The object's pixels; ``"contour"`` needs a mask whose edge is an occluding contour.
    method : {"contour", "lee_rosenfeld1985"}
        ``"contour"`` (default; :func:`light_from_shading_contour`: occluding-contour robust fit,
        Nillius & Eklundh, CVPR 2001, with the albedo of Pentland 1982) or
        ``"lee_rosenfeld1985"`` (:func:`light_from_shading_lee_rosenfeld1985`: image
        statistics, Lee & Rosenfeld, Artificial Intelligence 1985).
    **options
        ``contour``: ``seed`` (0), the seed of its RANSAC sampling; ``lee_rosenfeld1985``: none.

    Returns
    -------
    LightEstimate
        ``direction`` (3,) unit vector toward the source (``z >= 0``), ``albedo``, ``method``.

    Raises
    ------
    ValueError
        On an unknown method or option, bad image or mask, or too few lit contour pixels.
    """
    return call_method(LIGHT_METHODS, method, "light_from_shading", image, mask, **options)
