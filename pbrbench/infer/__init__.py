"""The NumPy inference package: algorithms that run on linear images, rendered or real.

Imports only NumPy and SciPy (never mitsuba or drjit; scikit-image and pyamg only lazily, inside
the functions that use them), so it works on real photographs.

========================  =====================================================================
area                      functions
========================  =====================================================================
HDR (§4)                  calibrate_debevec, calibrate_robertson, calibrate_mitsunaga_nayar,
                          merge_hdr, CameraResponse
lightness (§5)            retinex, retinex_1d
specularities (§1)        detect_specularities, remove_specularities
photometric stereo (§6)   photometric_stereo, PhotometricStereoResult
surface integration       integrate_normals (dispatcher over INTEGRATION_METHODS: integrate_lsq,
                          integrate_path, integrate_frankot1988, integrate_simchony1990),
                          integrability_residual, normals_to_gradients, normals_from_gradients,
                          gradients_from_height, solve_gradient_field (the shared least-squares
                          Poisson solver)
shape from shading        shape_from_shading (dispatcher over SFS_METHODS:
                          shape_from_shading_horn1989, shape_from_shading_tsai_shah1994,
                          shape_from_shading_pentland1990, shape_from_shading_kimmel2001),
                          light_from_shading (dispatcher over SFS_LIGHT_METHODS:
                          light_from_shading_contour, light_from_shading_lee_rosenfeld1985),
                          SFSResult, LightEstimate
========================  =====================================================================

Optional packages are loaded only when a method that needs them is called: ``kimmel2001``
(shape from shading) loads scikit-fmm under a frontal light; ``lsq`` (surface integration, the
default, and so ``horn1989`` and :func:`pbrbench.infer.sfs.integrate_gradients`) loads pyamg when
the domain is not the full rectangle.
"""

from pbrbench.infer.hdr import (
    CameraResponse,
    calibrate_debevec,
    calibrate_mitsunaga_nayar,
    calibrate_robertson,
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
from pbrbench.infer.lightness import retinex, retinex_1d
from pbrbench.infer.photometric_stereo import PhotometricStereoResult, photometric_stereo
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
from pbrbench.infer.specular import detect_specularities, remove_specularities

__all__ = [
    "INTEGRATION_METHODS",
    "SFS_LIGHT_METHODS",
    "SFS_METHODS",
    "CameraResponse",
    "LightEstimate",
    "PhotometricStereoResult",
    "SFSResult",
    "calibrate_debevec",
    "calibrate_mitsunaga_nayar",
    "calibrate_robertson",
    "detect_specularities",
    "gradients_from_height",
    "integrability_residual",
    "integrate_frankot1988",
    "integrate_lsq",
    "integrate_normals",
    "integrate_path",
    "integrate_simchony1990",
    "light_from_shading",
    "light_from_shading_contour",
    "light_from_shading_lee_rosenfeld1985",
    "merge_hdr",
    "normals_from_gradients",
    "normals_to_gradients",
    "photometric_stereo",
    "remove_specularities",
    "retinex",
    "retinex_1d",
    "shape_from_shading",
    "shape_from_shading_horn1989",
    "shape_from_shading_kimmel2001",
    "shape_from_shading_pentland1990",
    "shape_from_shading_tsai_shah1994",
    "solve_gradient_field",
]
