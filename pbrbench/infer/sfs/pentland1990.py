r"""Pentland (1990): linear shape from shading in the Fourier domain.

Linearising the reflectance map at ``p = q = 0`` gives ``E - S_z = -S_x f_x - S_y f_y``, a linear
filter of the height, inverted in the Fourier domain with a Wiener-type regularisation:

.. math::
    Z(w) = \frac{\mathcal{F}[E - S_z](w)\, \overline{H(w)}}{|H(w)|^2 + \varepsilon}, \qquad
    H(w) = -i\,(S_x w_x + S_y w_y).

References
----------
A. P. Pentland, "Linear shape from shading", International Journal of Computer Vision
4(2):153-162, 1990.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from pbrbench.checks import check_positive
from pbrbench.infer._docstring import docstring
from pbrbench.infer.sfs._common import DOCS, SFSResult, _finish, _is_frontal, _prepare

__all__ = ["shape_from_shading_pentland1990"]


def _pentland(E, s, m, *, reg):
    H, W = E.shape
    ph, pw = 2 * H, 2 * W
    src = np.zeros((ph, pw))
    src[:H, :W] = np.where(m, E - s[2], 0.0)
    F = np.fft.fft2(src)
    kr = 2 * np.pi * np.fft.fftfreq(ph)[:, None]
    kc = 2 * np.pi * np.fft.fftfreq(pw)[None, :]
    # E - S_z ~ -S_x f_x - S_y f_y, with f_x = d/dcol and f_y = -d/drow
    hsym = 1j * (-s[0] * kc + s[1] * kr)
    a2 = np.abs(hsym) ** 2
    eps = reg * (2 * np.pi / max(ph, pw)) ** 2  # relative to the lowest frequency of the padded grid
    Z = F * np.conj(hsym) / (a2 + eps)
    Z[0, 0] = 0.0
    z = np.real(np.fft.ifft2(Z))[:H, :W]
    return np.where(m, z, 0.0)


@docstring(DOCS)
def shape_from_shading_pentland1990(image, light, *, albedo=None, mask=None, pixel_size: float = 1.0,
                                    regularization: float = 0.1) -> SFSResult:
    r"""Height and normals from one image by Pentland's (1990) linear shape from shading.

    .. math::
        Z(w) = \frac{F[E - S_z]\, \overline{H}}{|H|^2 + \varepsilon}, \quad
        H = -i (S_x w_x + S_y w_y), \quad \varepsilon = \text{regularization} \cdot w_{\min}^2

    Linearises ``R`` at ``p = q = 0``: ``E - S_z = -S_x f_x - S_y f_y``, solved in the Fourier
    domain (Wiener-regularised where ``H`` vanishes; ``w_min = 2 pi / N`` the lowest frequency of
    the 2x zero-padded ``N``-pixel grid, so the damping is independent of the light's slant and
    of the image size: a light close to the view gives a nearly flat result instead of huge
    heights), with ``E - S_z`` set to 0 outside the mask.  Cannot see frequencies
    perpendicular to the light's tilt and fails for a frontal light (then returns the flat
    surface with a ``RuntimeWarning`` and ``converged=False``).  Direct: ``n_iter = 0``.

    Parameters
    ----------
    image, light, albedo, mask, pixel_size
        As for :func:`pbrbench.infer.sfs.shape_from_shading`.
    regularization : float
        ``eps`` in units of ``w_min^2`` (> 0).

    Returns
    -------
    SFSResult
        ``method="pentland1990"``; normals from the height's central differences.

    %(raises)s

    References
    ----------
    A. P. Pentland, "Linear shape from shading", International Journal of Computer Vision
    4(2):153-162, 1990.
    """
    E, s, m, rho, h = _prepare(image, light, albedo, mask, pixel_size)
    reg = check_positive(regularization, "regularization")
    t0 = time.perf_counter()
    converged = True
    if _is_frontal(s):
        warnings.warn("pentland1990: the linear term vanishes for a light along the view "
                      "(S_x = S_y = 0); returning the flat surface", RuntimeWarning, stacklevel=2)
        z = np.zeros_like(E)
        converged = False
    else:
        z = _pentland(E, s, m, reg=reg) * h
    return _finish(z, None, None, m, h, method="pentland1990", converged=converged, n_iter=0, s=s, rho=rho,
                   t0=t0, info={})
