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
surface integration       integrate_normals, integrability_residual, normals_to_gradients,
                          solve_gradient_field (the shared least-squares Poisson solver)
shape from shading (§7)   shape_from_shading, light_from_shading, SFSResult
========================  =====================================================================
"""

from pbrbench.infer.hdr import (
    CameraResponse,
    calibrate_debevec,
    calibrate_mitsunaga_nayar,
    calibrate_robertson,
    merge_hdr,
)
from pbrbench.infer.integration import (
    integrability_residual,
    integrate_normals,
    normals_to_gradients,
)
from pbrbench.infer.lightness import retinex, retinex_1d
from pbrbench.infer.photometric_stereo import PhotometricStereoResult, photometric_stereo
from pbrbench.infer.poisson import solve_gradient_field
from pbrbench.infer.sfs import SFSResult, light_from_shading, shape_from_shading
from pbrbench.infer.specular import detect_specularities, remove_specularities

__all__ = [
    "CameraResponse",
    "PhotometricStereoResult",
    "SFSResult",
    "calibrate_debevec",
    "calibrate_mitsunaga_nayar",
    "calibrate_robertson",
    "detect_specularities",
    "integrability_residual",
    "integrate_normals",
    "light_from_shading",
    "merge_hdr",
    "normals_to_gradients",
    "photometric_stereo",
    "remove_specularities",
    "retinex",
    "retinex_1d",
    "shape_from_shading",
    "solve_gradient_field",
]
