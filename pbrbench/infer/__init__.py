"""The NumPy inference package: algorithms that run on linear images, rendered or real.

Imports only NumPy and SciPy at import time (never mitsuba or drjit), so it works on real
photographs.  Optional packages are loaded only when a method that needs them is called:

- scikit-image by ``remove_specularities(method="biharmonic")``;
- pyamg by the algebraic-multigrid branch of :func:`solve_gradient_field` (``method="cg"``, which
  ``"auto"`` picks on a masked domain when the DCT-preconditioned iteration stalls), so possibly by
  masked lightness, the ``lsq`` surface integration and ``horn1989``;
- scikit-fmm by ``shape_from_shading(method="kimmel2001")`` under a frontal light.

For each problem: one subpackage, one module per method named after its paper, a methods table
(name -> function) and one dispatcher that forwards only the options the chosen method accepts
(:func:`pbrbench.checks.call_method`).  Adding a method is one module plus one line (and its
import) in its table.  The name of a subpackage always means the subpackage
(``import pbrbench.infer.photometric_stereo as ps`` is the module); the dispatchers have verb
names.

=====================  ====================  ==========================  =========================================
area                   subpackage            dispatcher(s)               tables; other public names
=====================  ====================  ==========================  =========================================
HDR                    :mod:`.hdr`           calibrate_response,         CALIBRATION_METHODS, MERGE_METHODS;
                                             merge_hdr                   CameraResponse
lightness              :mod:`.lightness`     estimate_lightness          LIGHTNESS_METHODS; lightness_1d_horn1974,
                                                                         retinex (= lightness_blake1985),
                                                                         retinex_1d (= lightness_1d_horn1974)
specularities          :mod:`.specular`      detect_specularities,       FILL_METHODS
                                             remove_specularities
photometric stereo     :mod:`.photometric_   solve_photometric_stereo    PS_METHODS, PS_BASELINES;
                       stereo`                                           PhotometricStereoResult
surface integration    :mod:`.integration`   integrate_normals           INTEGRATION_METHODS; integrability_residual,
                                                                         normals_to_gradients, normals_from_gradients,
                                                                         gradients_from_height
shape from shading     :mod:`.sfs`           shape_from_shading,         SFS_METHODS, SFS_LIGHT_METHODS;
                                             light_from_shading          SFSResult, LightEstimate
(shared)               :mod:`.poisson`       solve_gradient_field        the least-squares Poisson solver
=====================  ====================  ==========================  =========================================

Every function of every table is exported here under its own name (``photometric_stereo_woodham1980``,
...); the list below is generated from the tables when the package is imported, so it is always
the tables' content.

Methods by table
----------------
"""

from pbrbench.infer import hdr, integration, lightness, photometric_stereo, poisson, sfs, specular
from pbrbench.infer.hdr import (
    CALIBRATION_METHODS,
    MERGE_METHODS,
    CameraResponse,
    calibrate_response,
    merge_hdr,
)
from pbrbench.infer.integration import METHODS as INTEGRATION_METHODS
from pbrbench.infer.integration import (
    gradients_from_height,
    integrability_residual,
    integrate_normals,
    normals_from_gradients,
    normals_to_gradients,
)
from pbrbench.infer.lightness import METHODS as LIGHTNESS_METHODS
from pbrbench.infer.lightness import estimate_lightness, lightness_1d_horn1974, retinex, retinex_1d
from pbrbench.infer.photometric_stereo import BASELINES as PS_BASELINES
from pbrbench.infer.photometric_stereo import METHODS as PS_METHODS
from pbrbench.infer.photometric_stereo import PhotometricStereoResult, solve_photometric_stereo
from pbrbench.infer.poisson import solve_gradient_field
from pbrbench.infer.sfs import LIGHT_METHODS as SFS_LIGHT_METHODS
from pbrbench.infer.sfs import METHODS as SFS_METHODS
from pbrbench.infer.sfs import LightEstimate, SFSResult, light_from_shading, shape_from_shading
from pbrbench.infer.specular import FILL_METHODS, detect_specularities, remove_specularities

SUBPACKAGES = ("hdr", "integration", "lightness", "photometric_stereo", "sfs", "specular")
TABLES = {
    "CALIBRATION_METHODS": CALIBRATION_METHODS, "MERGE_METHODS": MERGE_METHODS,
    "LIGHTNESS_METHODS": LIGHTNESS_METHODS, "FILL_METHODS": FILL_METHODS,
    "PS_METHODS": PS_METHODS, "PS_BASELINES": PS_BASELINES, "INTEGRATION_METHODS": INTEGRATION_METHODS,
    "SFS_METHODS": SFS_METHODS, "SFS_LIGHT_METHODS": SFS_LIGHT_METHODS,
}

__all__ = [
    "hdr", "integration", "lightness", "photometric_stereo", "sfs", "specular", "poisson", "SUBPACKAGES", "TABLES",
    *TABLES,
    "CameraResponse", "LightEstimate", "PhotometricStereoResult", "SFSResult",
    "calibrate_response", "detect_specularities", "estimate_lightness", "gradients_from_height",
    "integrability_residual", "integrate_normals", "light_from_shading", "lightness_1d_horn1974",
    "merge_hdr", "normals_from_gradients", "normals_to_gradients", "remove_specularities", "retinex",
    "retinex_1d", "shape_from_shading", "solve_gradient_field", "solve_photometric_stereo",
]


def _export_tables() -> str:
    """Bind every table's functions here under their names; return the generated index text."""
    lines = []
    for table_name, table in TABLES.items():
        lines.append(f"- :data:`{table_name}`: " + ", ".join(f'``"{k}"`` :func:`{fn.__name__}`'
                                                            for k, fn in table.items()))
        for fn in table.values():
            if globals().setdefault(fn.__name__, fn) is not fn:
                raise ImportError(f"pbrbench.infer: two functions are named {fn.__name__}")
            if fn.__name__ not in __all__:
                __all__.append(fn.__name__)
    return "\n".join(lines) + "\n"


_index = _export_tables()
if __doc__:   # None under python -OO
    __doc__ += _index
