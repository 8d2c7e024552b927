"""Photometric stereo: albedo and normals from K images under distant sources.

Model: orthographic camera, distant sources, Lambertian surface, no ambient,

    I_k(x) = rho(x) E_k max(0, N(x) . S_k),

with ``S_k`` the unit direction from the surface toward source k and ``E_k`` its irradiance.
Writing ``V_k = E_k S_k`` (the rows of ``lights``) and ``g = rho N``, every lit, unsaturated
measurement gives one linear equation ``V_k . g = I_k``; three or more independent ones fix
``g``: albedo ``|g|``, normal ``g / |g|`` (Woodham 1980; Forsyth & Ponce, Algorithm 1.2).

Frame: x right, y up, z toward the camera (DiLiGenT convention; see ``docs/conventions.md``);
image row 0 is the top.  Images must be linear.  With radiance images ``rho E cos / pi`` the
recovered albedo is ``rho / pi`` unless the intensities carry the ``1/pi``.

Every method is a function ``fn(images, lights, *, mask=None, <own options>) ->
PhotometricStereoResult`` in its own module named after its paper; :data:`METHODS` maps the
method's name to it and :func:`photometric_stereo` dispatches by name.

Adding a method is exactly one new module, built on the shared checks, accumulation of the
normal equations and result of :mod:`pbrbench.infer.photometric_stereo._common`, plus one line in
:data:`METHODS`: the dispatcher, its option checking and the benchmark task
(:mod:`pbrbench.tasks.photometric_stereo`) all read :data:`METHODS`.

Methods
-------
- ``"woodham1980"``: :func:`photometric_stereo_woodham1980`, least squares over the lit,
  unsaturated lights.
- ``"ikehata2012_l1"``: :func:`photometric_stereo_ikehata2012_l1`, robust L1 fit that treats
  highlights and residual shadows as sparse outliers.
- ``"ikehata2012_sbl"``: :func:`photometric_stereo_ikehata2012_sbl`, sparse Bayesian learning
  of the outliers (evidence maximisation; close to counting them).
- ``"wu2010"``: :func:`photometric_stereo_wu2010`, low-rank matrix completion and recovery
  (RPCA by inexact ALM) of the observation matrix, then least squares on the trusted entries.
- ``"nayar1991"``: :func:`photometric_stereo_nayar1991`, undoes interreflection: local solve,
  facets, interreflection kernel, corrected images, iterated (images must hold all the light).

Baselines (:data:`BASELINES`, not methods): ``"naive_lstsq_all_lights"``,
:func:`photometric_stereo_naive_lstsq`, one least-squares solve with every light.

References
----------
- R. J. Woodham, "Photometric method for determining surface orientation from multiple images",
  Optical Engineering 19(1), 1980.
- S. Ikehata, D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo using sparse
  regression", CVPR 2012.
- L. Wu, A. Ganesh, B. Shi, Y. Matsushita, Y. Wang and Y. Ma, "Robust photometric stereo via
  low-rank matrix completion and recovery", ACCV 2010.
- S. K. Nayar, K. Ikeuchi and T. Kanade, "Shape from interreflections", International Journal of
  Computer Vision 6(3):173-195, 1991.
"""

from __future__ import annotations

from pbrbench.checks import call_method
from pbrbench.infer.photometric_stereo._common import PhotometricStereoResult
from pbrbench.infer.photometric_stereo.baselines import BASELINES, photometric_stereo_naive_lstsq
from pbrbench.infer.photometric_stereo.ikehata2012 import photometric_stereo_ikehata2012_l1
from pbrbench.infer.photometric_stereo.ikehata2012_sbl import photometric_stereo_ikehata2012_sbl
from pbrbench.infer.photometric_stereo.nayar1991 import photometric_stereo_nayar1991
from pbrbench.infer.photometric_stereo.woodham1980 import photometric_stereo_woodham1980
from pbrbench.infer.photometric_stereo.wu2010 import photometric_stereo_wu2010

__all__ = [
    "BASELINES",
    "METHODS",
    "PhotometricStereoResult",
    "photometric_stereo",
    "photometric_stereo_ikehata2012_l1",
    "photometric_stereo_ikehata2012_sbl",
    "photometric_stereo_naive_lstsq",
    "photometric_stereo_nayar1991",
    "photometric_stereo_woodham1980",
    "photometric_stereo_wu2010",
]

METHODS = {
    "woodham1980": photometric_stereo_woodham1980,
    "ikehata2012_l1": photometric_stereo_ikehata2012_l1,
    "ikehata2012_sbl": photometric_stereo_ikehata2012_sbl,
    "wu2010": photometric_stereo_wu2010,
    "nayar1991": photometric_stereo_nayar1991,
}


def photometric_stereo(images, lights, *, method: str = "woodham1980", **options) -> PhotometricStereoResult:
    """Recover normals and albedo from K images of a Lambertian surface with the method ``method``.

    Parameters
    ----------
    images : (K, H, W) or (K, H, W, C) array
        Linear images, one per light.
    lights : (K, 3) array
        Source vectors in the camera frame (x right, y up, z toward the camera), pointing from
        the surface toward the source; the length scales the intensity.
    method : str
        A key of :data:`METHODS`.
    **options
        ``mask`` and the options of that method (``intensities``, ``shadow_threshold``,
        ``saturation``, ``min_lights``; ``max_iter`` for ``"ikehata2012_l1"``); an option it does
        not accept raises ``ValueError`` listing those it accepts.

    Returns
    -------
    PhotometricStereoResult

    References
    ----------
    See :data:`METHODS`: Woodham, Optical Engineering 1980; Ikehata et al., CVPR 2012.
    """
    return call_method(METHODS, method, "photometric_stereo", images, lights, **options)
