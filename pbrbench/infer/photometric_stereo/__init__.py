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
method's name to it and :func:`solve_photometric_stereo` dispatches by name (the list of methods
is in its docstring, generated from :data:`METHODS`).

Adding a method is exactly one new module, built on the shared checks, accumulation of the
normal equations, least-squares solve, outlier rejection, result and docstring fragments of
:mod:`pbrbench.infer.photometric_stereo._common`, plus its line in :data:`METHODS` (with its
import) here: the dispatcher, its docstring, its option checking, :data:`__all__`, the index of
:mod:`pbrbench.infer` and the benchmark task (:mod:`pbrbench.tasks.photometric_stereo`) all read
:data:`METHODS`.

Baselines (:data:`BASELINES`, not methods): ``"naive_lstsq_all_lights"``,
:func:`photometric_stereo_naive_lstsq`, one least-squares solve with every light.

References
----------
- R. J. Woodham, "Photometric method for determining surface orientation from multiple images",
  Optical Engineering 19(1), 1980 (the model; each method's docstring gives its own paper).
"""

from __future__ import annotations

from pbrbench.checks import call_method
from pbrbench.infer._docstring import docstring, methods_list
from pbrbench.infer.photometric_stereo._common import DOCS, PhotometricStereoResult
from pbrbench.infer.photometric_stereo.baselines import BASELINES, photometric_stereo_naive_lstsq
from pbrbench.infer.photometric_stereo.ikehata2012 import photometric_stereo_ikehata2012_l1
from pbrbench.infer.photometric_stereo.ikehata2012_sbl import photometric_stereo_ikehata2012_sbl
from pbrbench.infer.photometric_stereo.iwahori1990 import photometric_stereo_iwahori1990
from pbrbench.infer.photometric_stereo.nayar1991 import photometric_stereo_nayar1991
from pbrbench.infer.photometric_stereo.woodham1980 import photometric_stereo_woodham1980
from pbrbench.infer.photometric_stereo.woodham1980_colour import (
    photometric_stereo_woodham1980_colour,
)
from pbrbench.infer.photometric_stereo.wu2010 import photometric_stereo_wu2010

METHODS = {
    "woodham1980": photometric_stereo_woodham1980,
    "ikehata2012_l1": photometric_stereo_ikehata2012_l1,
    "ikehata2012_sbl": photometric_stereo_ikehata2012_sbl,
    "wu2010": photometric_stereo_wu2010,
    "nayar1991": photometric_stereo_nayar1991,
    "woodham1980_colour": photometric_stereo_woodham1980_colour,
    "iwahori1990": photometric_stereo_iwahori1990,
}

__all__ = ["BASELINES", "METHODS", "PhotometricStereoResult", "photometric_stereo_naive_lstsq",
           "solve_photometric_stereo", *(fn.__name__ for fn in METHODS.values())]


@docstring({**DOCS, "methods": methods_list(METHODS)})
def solve_photometric_stereo(images, lights, *, method: str = "woodham1980", **options) -> PhotometricStereoResult:
    r"""Recover normals and albedo from K images of a Lambertian surface with the method ``method``.

    .. math:: I_k = \rho\, E_k \max(0, N \cdot S_k)

    solved for ``g = rho N`` per pixel by the chosen method (module docstring).

    Parameters
    ----------
    %(inputs)s
    method : str
        A key of :data:`METHODS`:

        %(methods)s
    **options
        ``mask`` and the options of that method (``intensities``, ``shadow_threshold``,
        ``saturation``, ``min_lights``; ``max_iter`` for ``"ikehata2012_l1"``); an option it does
        not accept raises ``ValueError`` listing those it accepts.

    Returns
    -------
    PhotometricStereoResult

    References
    ----------
    Each method's own (its docstring); Woodham, Optical Engineering 1980 for the model.
    """
    return call_method(METHODS, method, "solve_photometric_stereo", images, lights, **options)
