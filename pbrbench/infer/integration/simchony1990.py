r"""Simchony, Chellappa & Shao (1990): the Neumann Poisson equation on a rectangle by the DCT.

The least-squares height of the trapezoid edge slopes over the *full* rectangle,

.. math:: \nabla^2 z = \operatorname{div}(g_x, g_y), \qquad \partial_n z = 0 \text{ on the border},

is diagonalised by the discrete cosine transform (DCT-II), which solves it directly in
``O(N log N)`` (:func:`pbrbench.infer.poisson.solve_gradient_field` with ``method="dct"``).  The
gradients outside the mask are set to 0, which biases the result on a non-rectangular domain;
:mod:`pbrbench.infer.integration.lsq` solves the same problem on the mask itself.

References
----------
T. Simchony, R. Chellappa and M. Shao, "Direct analytical methods for solving Poisson equations
in computer vision problems", IEEE Transactions on Pattern Analysis and Machine Intelligence
12(5):435-446, 1990.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer._docstring import docstring
from pbrbench.infer.integration.gradients import DOCS, _edge_gradients, _prepare
from pbrbench.infer.poisson import solve_gradient_field

__all__ = ["integrate_simchony1990"]


@docstring(DOCS)
def integrate_simchony1990(normals=None, *, gradients=None, mask=None, pixel_size: float = 1.0) -> np.ndarray:
    r"""Height by a direct DCT solve of the Neumann Poisson equation on the full rectangle.

    .. math:: \nabla^2 z = \operatorname{div}(g_x, g_y), \quad \partial_n z = 0

    (module docstring; Simchony, Chellappa & Shao 1990).  Gradients outside the mask are set
    to 0.

    %(rectangle)s

    References
    ----------
    T. Simchony, R. Chellappa and M. Shao, "Direct analytical methods for solving Poisson
    equations in computer vision problems", IEEE TPAMI 12(5):435-446, 1990.
    """
    p, q, m, h = _prepare(normals, gradients, mask, pixel_size)
    gx, gy = _edge_gradients(p, q, m, h)
    z = solve_gradient_field(gx, gy, method="dct")
    z = z - z[m].mean()
    return np.where(m, z, 0.0)
