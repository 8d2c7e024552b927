"""The NumPy inference package: algorithms that run on linear images, rendered or real.

Imports only NumPy and SciPy at import time (never mitsuba or drjit), so it works on real
photographs.  Optional packages are loaded only when a method that needs them is called:

- scikit-image by ``remove_specularities(method="biharmonic")``;
- pyamg by the algebraic-multigrid branch of :func:`solve_gradient_field` (``method="cg"``, which
  ``"auto"`` picks on a masked domain when the DCT-preconditioned iteration stalls), so possibly by
  masked lightness, the ``lsq`` surface integration and ``horn1989``;
- scikit-fmm by ``shape_from_shading(method="kimmel2001")`` under a frontal light.

For each problem: one module per method named after its paper, a methods table (name ->
function) and one dispatcher that forwards only the options the chosen method accepts
(:func:`pbrbench.checks.call_method`).  Adding a method is one module plus one line in its table.

========================  =====================================================================
area                      functions
========================  =====================================================================
HDR                       calibrate_response (CALIBRATION_METHODS: calibrate_debevec1997,
                          calibrate_robertson2003, calibrate_mitsunaga1999), merge_hdr
                          (MERGE_METHODS: merge_debevec1997), CameraResponse
lightness                 lightness (LIGHTNESS_METHODS: lightness_blake1985 = retinex),
                          lightness_1d_horn1974 = retinex_1d
specularities             detect_specularities, remove_specularities (FILL_METHODS:
                          remove_specularities_harmonic, remove_specularities_biharmonic)
photometric stereo        photometric_stereo (PS_METHODS: photometric_stereo_woodham1980,
                          photometric_stereo_ikehata2012_l1), PS_BASELINES
                          (photometric_stereo_naive_lstsq), PhotometricStereoResult
surface integration       integrate_normals (INTEGRATION_METHODS: integrate_lsq, integrate_path,
                          integrate_frankot1988, integrate_simchony1990), integrability_residual,
                          normals_to_gradients, normals_from_gradients, gradients_from_height,
                          solve_gradient_field (the shared least-squares Poisson solver)
shape from shading        shape_from_shading (SFS_METHODS: shape_from_shading_horn1989,
                          shape_from_shading_tsai_shah1994, shape_from_shading_pentland1990,
                          shape_from_shading_kimmel2001), light_from_shading (SFS_LIGHT_METHODS:
                          light_from_shading_contour, light_from_shading_lee_rosenfeld1985),
                          SFSResult, LightEstimate
========================  =====================================================================
"""

from pbrbench.infer.hdr import (
    CALIBRATION_METHODS,
    MERGE_METHODS,
    CameraResponse,
    calibrate_debevec1997,
    calibrate_mitsunaga1999,
    calibrate_response,
    calibrate_robertson2003,
    merge_debevec1997,
    merge_hdr,
)
from pbrbench.infer.integration import METHODS as INTEGRATION_METHODS
from pbrbench.infer.integration import (
    gradients_from_height,
    integrability_residual,
    integrate_frankot1988,
    integrate_lsq,
    integrate_normals,
    integrate_path,
    integrate_simchony1990,
    normals_from_gradients,
    normals_to_gradients,
)
from pbrbench.infer.lightness import METHODS as LIGHTNESS_METHODS
from pbrbench.infer.lightness import (
    lightness,
    lightness_1d_horn1974,
    lightness_blake1985,
    retinex,
    retinex_1d,
)
from pbrbench.infer.photometric_stereo import BASELINES as PS_BASELINES
from pbrbench.infer.photometric_stereo import METHODS as PS_METHODS
from pbrbench.infer.photometric_stereo import (
    PhotometricStereoResult,
    photometric_stereo,
    photometric_stereo_ikehata2012_l1,
    photometric_stereo_naive_lstsq,
    photometric_stereo_woodham1980,
)
from pbrbench.infer.poisson import solve_gradient_field
from pbrbench.infer.sfs import LIGHT_METHODS as SFS_LIGHT_METHODS
from pbrbench.infer.sfs import METHODS as SFS_METHODS
from pbrbench.infer.sfs import (
    LightEstimate,
    SFSResult,
    light_from_shading,
    light_from_shading_contour,
    light_from_shading_lee_rosenfeld1985,
    shape_from_shading,
    shape_from_shading_horn1989,
    shape_from_shading_kimmel2001,
    shape_from_shading_pentland1990,
    shape_from_shading_tsai_shah1994,
)
from pbrbench.infer.specular import (
    FILL_METHODS,
    detect_specularities,
    remove_specularities,
    remove_specularities_biharmonic,
    remove_specularities_harmonic,
)

__all__ = [
    "CALIBRATION_METHODS", "FILL_METHODS", "INTEGRATION_METHODS", "LIGHTNESS_METHODS", "MERGE_METHODS",
    "PS_BASELINES", "PS_METHODS", "SFS_LIGHT_METHODS", "SFS_METHODS",
    "CameraResponse", "LightEstimate", "PhotometricStereoResult", "SFSResult",
    "calibrate_debevec1997", "calibrate_mitsunaga1999", "calibrate_response", "calibrate_robertson2003",
    "detect_specularities", "gradients_from_height", "integrability_residual", "integrate_frankot1988",
    "integrate_lsq", "integrate_normals", "integrate_path", "integrate_simchony1990",
    "light_from_shading", "light_from_shading_contour", "light_from_shading_lee_rosenfeld1985",
    "lightness", "lightness_1d_horn1974", "lightness_blake1985", "merge_debevec1997", "merge_hdr",
    "normals_from_gradients", "normals_to_gradients", "photometric_stereo",
    "photometric_stereo_ikehata2012_l1", "photometric_stereo_naive_lstsq", "photometric_stereo_woodham1980",
    "remove_specularities", "remove_specularities_biharmonic", "remove_specularities_harmonic", "retinex",
    "retinex_1d", "shape_from_shading", "shape_from_shading_horn1989", "shape_from_shading_kimmel2001",
    "shape_from_shading_pentland1990", "shape_from_shading_tsai_shah1994", "solve_gradient_field",
]
