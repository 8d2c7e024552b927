r"""Surface integration: from a normal field (or surface gradients) to a height map.

Frame (``docs/conventions.md``): x right, y up, z toward the camera; row 0 is the top.  A Monge
patch ``z = f(x, y)`` has unit normal ``N = (-f_x, -f_y, 1)/|.|``, hence ``p = f_x = -N_x/N_z``
and ``q = f_y = -N_y/N_z``.  The least-squares integrators solve

.. math:: \min_z \int_\Omega (z_x - p)^2 + (z_y - q)^2 \,dx\,dy,

whose Euler-Lagrange equation is the Poisson equation ``\nabla^2 z = p_x + q_y`` with natural
boundary conditions on the border of ``\Omega``.

Methods (``METHODS``, dispatched by :func:`integrate_normals`; each is also a public function
with the common signature ``fn(normals=None, *, gradients=None, mask=None, pixel_size=1.0,
<its options>)``):

- ``"lsq"``: :func:`integrate_lsq`, least squares on the masked domain (default; a descriptive
  name; option ``tol``; AMG-preconditioned conjugate gradients, pyamg imported when called).
- ``"path"``: :func:`integrate_path`, the chapter's path (a descriptive name): the top-left pixel
  is zero, ``q`` is integrated down the left column, then ``p`` along every row.
- ``"frankot1988"``: :func:`integrate_frankot1988`, projection onto integrable Fourier functions
  (periodic rectangle; Frankot & Chellappa 1988).
- ``"simchony1990"``: :func:`integrate_simchony1990`, least squares on the full rectangle with
  Neumann boundary by the DCT (Simchony, Chellappa & Shao 1990).

The three rectangle methods set the gradients outside the mask to 0 and integrate over the whole
image; only ``lsq`` respects the domain.  Gradient helpers: :func:`normals_to_gradients`,
:func:`normals_from_gradients`, :func:`gradients_from_height`, :func:`integrability_residual`.

References
----------
- D. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, "Light and Shading",
  Algorithm 1.2 (path integration, integrability check).
- R. T. Frankot and R. Chellappa, "A method for enforcing integrability in shape from shading
  algorithms", IEEE TPAMI 10(4):439-451, 1988.
- T. Simchony, R. Chellappa and M. Shao, "Direct analytical methods for solving Poisson equations
  in computer vision problems", IEEE TPAMI 12(5):435-446, 1990.
- A. Agrawal, R. Raskar and R. Chellappa, "What is the range of surface reconstructions from a
  gradient field?", ECCV 2006 (masked least squares).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import call_method
from pbrbench.infer._docstring import docstring
from pbrbench.infer.integration.frankot1988 import integrate_frankot1988
from pbrbench.infer.integration.gradients import (
    DOCS,
    gradients_from_height,
    integrability_residual,
    normals_from_gradients,
    normals_to_gradients,
)
from pbrbench.infer.integration.lsq import integrate_lsq
from pbrbench.infer.integration.path import integrate_path
from pbrbench.infer.integration.simchony1990 import integrate_simchony1990

__all__ = [
    "METHODS",
    "integrate_normals",
    "integrate_lsq",
    "integrate_path",
    "integrate_frankot1988",
    "integrate_simchony1990",
    "normals_to_gradients",
    "normals_from_gradients",
    "gradients_from_height",
    "integrability_residual",
]

METHODS = {
    "lsq": integrate_lsq,
    "path": integrate_path,
    "frankot1988": integrate_frankot1988,
    "simchony1990": integrate_simchony1990,
}


@docstring(DOCS)
def integrate_normals(normals=None, *, gradients=None, mask=None, method: str = "lsq",
                      pixel_size: float = 1.0, **options) -> np.ndarray:
    r"""Height map ``z`` (up to a constant) whose gradients best match a normal field.

    .. math:: \min_z \int_\Omega (z_x - p)^2 + (z_y - q)^2 \,dx\,dy,
        \qquad p = -N_x/N_z,\; q = -N_y/N_z

    Dispatches to ``METHODS[method]`` (module docstring), forwarding ``options``; an option the
    chosen method does not take raises ``ValueError`` listing the ones it does.

    Parameters
    ----------
    %(inputs)s
    method : {"lsq", "path", "frankot1988", "simchony1990"}
        ``"lsq"`` (default): :func:`integrate_lsq` (Agrawal, Raskar & Chellappa, ECCV 2006).
        ``"path"``: :func:`integrate_path` (Forsyth & Ponce, Algorithm 1.2).
        ``"frankot1988"``: :func:`integrate_frankot1988` (Frankot & Chellappa, IEEE TPAMI 1988).
        ``"simchony1990"``: :func:`integrate_simchony1990` (Simchony, Chellappa & Shao, IEEE
        TPAMI 1990).
    %(pixel_size)s
    **options
        The chosen method's own options (``lsq``: ``tol``, the relative residual tolerance).

    Returns
    -------
    z : (H, W) float64
        Height with mean zero over the domain (per connected component for ``"lsq"``); 0 outside.

    Raises
    ------
    ValueError
        On an unknown method or option, both or neither of ``normals`` / ``gradients``, bad
        shapes, a mismatched mask, non-finite values in the mask, or a non-positive
        ``pixel_size``.
    """
    return call_method(METHODS, method, "integrate_normals", normals, gradients=gradients, mask=mask,
                       pixel_size=pixel_size, **options)
