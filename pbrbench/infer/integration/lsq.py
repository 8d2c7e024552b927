r"""Masked least-squares surface integration (``"lsq"``, the default integrator).

A descriptive name, not a paper's: the method is the textbook least-squares integration, the
Poisson equation solved on the masked, non-rectangular domain with natural boundary conditions,
as analysed by Agrawal, Raskar & Chellappa (2006).

.. math::
    \min_z \sum_{\text{x-edges}} \big(z_{i,j+1} - z_{i,j} - h \tfrac{p_{i,j} + p_{i,j+1}}{2}\big)^2
         + \sum_{\text{y-edges}} \big(z_{i+1,j} - z_{i,j} + h \tfrac{q_{i,j} + q_{i+1,j}}{2}\big)^2,

an equation for every pair of 4-neighbours inside the mask (rows go down while ``y`` goes up,
hence the sign of the ``q`` term).  Its normal equations are the graph-Laplacian system
``L z = D^T g``, solved by :func:`pbrbench.infer.poisson.solve_gradient_field` (AMG-preconditioned
conjugate gradients, pyamg imported lazily, or the DCT on a full rectangle).

References
----------
A. Agrawal, R. Raskar and R. Chellappa, "What is the range of surface reconstructions from a
gradient field?", ECCV 2006.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer._docstring import docstring
from pbrbench.infer.integration.gradients import DOCS, _edge_gradients, _prepare
from pbrbench.infer.poisson import solve_gradient_field

__all__ = ["integrate_lsq"]


@docstring(DOCS)
def integrate_lsq(normals=None, *, gradients=None, mask=None, pixel_size: float = 1.0,
                  tol: float = 1e-8) -> np.ndarray:
    r"""Height whose edge differences best match the trapezoid slopes, on the masked domain.

    .. math:: \min_z \int_\Omega (z_x - p)^2 + (z_y - q)^2 \,dx\,dy
        \;\Longrightarrow\; \nabla^2 z = p_x + q_y \text{ in } \Omega,\;
        \partial_n z = (p, q) \cdot n \text{ on } \partial\Omega,

    discretised on the mask's 4-neighbour edges (module docstring).  A descriptive name: plain
    masked least squares (Agrawal, Raskar & Chellappa, ECCV 2006), the only integrator here that
    respects a non-rectangular domain.

    Parameters
    ----------
    %(inputs)s
    %(pixel_size)s
    tol : float
        Relative residual tolerance of the iterative solver.

    Returns
    -------
    z : (H, W) float64
        Height with mean zero on each connected component of the domain, 0 outside.

    Raises
    ------
    ValueError
        Both or neither of ``normals`` / ``gradients``, bad shapes, a mismatched mask,
        non-finite values in the mask, an empty domain or a non-positive ``pixel_size``.

    References
    ----------
    A. Agrawal, R. Raskar and R. Chellappa, "What is the range of surface reconstructions from a
    gradient field?", ECCV 2006.
    """
    p, q, m, h = _prepare(normals, gradients, mask, pixel_size)
    gx, gy = _edge_gradients(p, q, m, h)
    return solve_gradient_field(gx, gy, mask=m, tol=tol, method="auto")
