r"""Path integration (``"path"``): the chapter's algorithm, a descriptive name.

Forsyth & Ponce's photometric-stereo algorithm ends by integrating the normals along one path:
the top-left pixel is height 0, ``q`` is summed down the left column, then ``p`` along every row,

.. math::
    z_{i,0} = \sum_{k < i} g^y_{k,0}, \qquad z_{i,j} = z_{i,0} + \sum_{k < j} g^x_{i,k},

with the trapezoid edge slopes ``g^x = h (p_{i,j} + p_{i,j+1})/2``,
``g^y = -h (q_{i,j} + q_{i+1,j})/2`` (rows go down while ``y`` goes up).  Exact for an integrable
field; otherwise the error accumulates along the path (streaks along the rows).

References
----------
D. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, chapter "Light and Shading",
Algorithm 1.2.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer._docstring import docstring
from pbrbench.infer.integration.gradients import DOCS, _edge_gradients, _prepare

__all__ = ["integrate_path"]


def _path(gx, gy):
    z = np.zeros_like(gx)
    z[1:, 0] = np.cumsum(gy[:-1, 0])
    z[:, 1:] = z[:, :1] + np.cumsum(gx[:, :-1], axis=1)
    return z


@docstring(DOCS)
def integrate_path(normals=None, *, gradients=None, mask=None, pixel_size: float = 1.0) -> np.ndarray:
    r"""Height by integrating down the left column, then along every row (the chapter's path).

    .. math:: z_{i,j} = \sum_{k < i} g^y_{k,0} + \sum_{k < j} g^x_{i,k}

    (module docstring).  A descriptive name: Forsyth & Ponce, "Light and Shading",
    Algorithm 1.2.  The gradients outside the mask are set to 0 and the path runs over the whole
    rectangle, so a path that leaves the domain carries a wrong offset back into it.

    %(rectangle)s

    References
    ----------
    D. Forsyth and J. Ponce, *Computer Vision: A Modern Approach*, "Light and Shading",
    Algorithm 1.2.
    """
    p, q, m, h = _prepare(normals, gradients, mask, pixel_size)
    gx, gy = _edge_gradients(p, q, m, h)
    z = _path(gx, gy)
    z = z - z[m].mean()
    return np.where(m, z, 0.0)
