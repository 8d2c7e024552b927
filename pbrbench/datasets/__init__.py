"""Loaders for the real-data layouts researchers already have on disk.

* :mod:`~pbrbench.datasets.diligent` -- DiLiGenT photometric stereo (16-bit PNGs, light
  directions and intensities, mask, ground-truth normals);
* :mod:`~pbrbench.datasets.psm` -- the psmImages photometric-stereo layout (TGA images,
  ``lights.txt``, a mask image; no ground truth);
* :mod:`~pbrbench.datasets.mit` -- the MIT Intrinsic Images data set (diffuse / reflectance /
  shading / mask per object) and its LMSE protocol;
* :mod:`~pbrbench.datasets.bracket` -- an exposure bracket (images plus a times file or EXIF).

Every loader returns linear float64 arrays in pbrbench's conventions (``docs/conventions.md``:
images (H, W[, C]) row 0 at the top, camera frame x right, y up, z toward the camera) and
raises :class:`pbrbench.errors.UserError` with one line for a malformed folder.  Nothing is
downloaded: point them at the folders you have.  ``pbrbench infer`` and ``pbrbench evaluate``
use them (``docs/plugins.md``).
"""

from pbrbench.datasets.bracket import Bracket, load_bracket
from pbrbench.datasets.diligent import (
           DiLiGenTObject,
           diligent_objects,
           frame_check,
           is_diligent,
           load_diligent,
)
from pbrbench.datasets.mit import MITObject, is_mit, load_mit_object, mit_objects, mit_scores
from pbrbench.datasets.psm import is_psm, load_psm, psm_lights

__all__ = ["Bracket", "load_bracket", "DiLiGenTObject", "diligent_objects", "frame_check", "is_diligent",
           "load_diligent", "MITObject", "is_mit", "load_mit_object", "mit_objects", "mit_scores", "is_psm",
           "load_psm", "psm_lights"]
