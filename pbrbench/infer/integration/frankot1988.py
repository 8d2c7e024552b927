r"""Frankot & Chellappa (1988): the nearest integrable surface in the Fourier basis.

The least-squares surface on a periodic rectangle: with the discrete Fourier transforms
``G_x``, ``G_y`` of the slopes (per pixel, ``g_x = h p``, ``g_y = -h q`` along the rows, which go
down) and the angular frequencies ``w_x``, ``w_y``,

.. math::
    Z(w) = \frac{-i\, w_x G_x(w) - i\, w_y G_y(w)}{w_x^2 + w_y^2}, \qquad Z(0) = 0,

the projection of the gradient field onto the integrable Fourier functions.  Spectrally exact for
a periodic surface; assumes periodicity, so slopes that do not wrap around (a paraboloid) bias the
whole result, and gradients outside the mask are set to 0.

References
----------
R. T. Frankot and R. Chellappa, "A method for enforcing integrability in shape from shading
algorithms", IEEE Transactions on Pattern Analysis and Machine Intelligence 10(4):439-451, 1988.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from pbrbench.infer._docstring import docstring
from pbrbench.infer.integration.gradients import DOCS, _prepare

__all__ = ["integrate_frankot1988"]


def _frankot_chellappa(p, q, h):
    rows, cols = p.shape
    gx = h * p        # derivative along columns (per pixel)
    gy = -h * q       # derivative along rows (rows go down)
    wx = 2 * np.pi * scipy.fft.fftfreq(cols)[None, :]
    wy = 2 * np.pi * scipy.fft.fftfreq(rows)[:, None]
    den = wx**2 + wy**2
    den[0, 0] = 1.0
    zf = (-1j * wx * scipy.fft.fft2(gx) - 1j * wy * scipy.fft.fft2(gy)) / den
    zf[0, 0] = 0.0
    return np.real(scipy.fft.ifft2(zf))


@docstring(DOCS)
def integrate_frankot1988(normals=None, *, gradients=None, mask=None, pixel_size: float = 1.0) -> np.ndarray:
    r"""Height by Fourier projection onto integrable surfaces (Frankot & Chellappa 1988).

    .. math:: Z(w) = \frac{-i w_x G_x(w) - i w_y G_y(w)}{w_x^2 + w_y^2}

    on the whole (periodic) rectangle, gradients outside the mask set to 0 (module docstring).

    %(rectangle)s

    References
    ----------
    R. T. Frankot and R. Chellappa, "A method for enforcing integrability in shape from shading
    algorithms", IEEE TPAMI 10(4):439-451, 1988.
    """
    p, q, m, h = _prepare(normals, gradients, mask, pixel_size)
    z = _frankot_chellappa(p, q, h)
    z = z - z[m].mean()
    return np.where(m, z, 0.0)
