r"""Lee & Rosenfeld (1985): light direction and albedo from image statistics.

The tilt is the direction of the mean image gradient over the object's interior; the slant is
found by matching the ratio of the first two brightness moments to its value for a Lambertian
sphere lit at that slant (normals uniform over the image disc, attached shadows included),

.. math::
    \frac{\langle I \rangle^2}{\langle I^2 \rangle} = \frac{e_1(\sigma)^2}{e_2(\sigma)}, \qquad
    e_k(\sigma) = \big\langle \max(0, N \cdot S(\sigma))^k \big\rangle_{\text{disc}},

and the albedo is ``<I> / e_1(sigma)``.

References
----------
C.-H. Lee and A. Rosenfeld, "Improved methods of estimating shape from shading using the light
source coordinate system", Artificial Intelligence 26(2):125-143, 1985.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from pbrbench.infer._docstring import docstring
from pbrbench.infer._scale import pow2_exponent
from pbrbench.infer.sfs._common import DOCS, LightEstimate, _prepare_light_image

__all__ = ["light_from_shading_lee_rosenfeld1985"]


def _disc_moments(slant: float, n: int = 201):
    """Mean of ``max(0, N.S)`` and of its square over the image of a sphere (uniform on the disc)."""
    u = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(u, u)
    inside = x * x + y * y < 1
    nz = np.sqrt(np.clip(1 - x * x - y * y, 0, None))
    sh = np.maximum(0.0, x * math.sin(slant) + nz * math.cos(slant))[inside]
    return sh.mean(), (sh * sh).mean()


@docstring(DOCS)
def light_from_shading_lee_rosenfeld1985(image, mask=None) -> LightEstimate:
    r"""Distant light direction and albedo from the image's gradient and brightness moments.

    .. math::
        \tau = \operatorname{atan2}(\langle I_y \rangle, \langle I_x \rangle), \qquad
        \frac{\langle I \rangle^2}{\langle I^2 \rangle} = \frac{e_1(\sigma)^2}{e_2(\sigma)}, \qquad
        \rho = \frac{\langle I \rangle}{e_1(\sigma)}

    (Lee & Rosenfeld, Artificial Intelligence 1985): the tilt ``tau`` is the direction of the
    mean image gradient over the object's interior (the mask eroded by 2 pixels); the slant
    ``sigma`` is found by matching the ratio ``<I>^2 / <I^2>`` to its value for a sphere
    (normals uniform over the image disc, attached shadows included; tabulated over 0-89
    degrees), the albedo from ``<I>``.  Assumes one object of uniform albedo whose normals are
    distributed like a sphere's.

    Parameters
    ----------
    image : (H, W) array
        Linear image (>= 0).
    mask : (H, W) bool, optional
        The object's pixels (default: the whole image).

    %(light_result)s

    References
    ----------
    C.-H. Lee and A. Rosenfeld, "Improved methods of estimating shape from shading using the
    light source coordinate system", Artificial Intelligence 26(2):125-143, 1985.
    """
    img, m, imax = _prepare_light_image(image, mask)
    e = pow2_exponent(imax)   # the moments of 1e300 / 1e-300 images overflow: solve exactly rescaled
    if e:
        est = light_from_shading_lee_rosenfeld1985(np.ldexp(img, -e), m)
        return LightEstimate(direction=est.direction, albedo=float(np.ldexp(est.albedo, e)), method=est.method)
    inner = ndimage.binary_erosion(m, iterations=2, border_value=0)
    if inner.sum() < 16:
        inner = m
    gr, gc = np.gradient(img)
    mx, my = float(gc[inner].mean()), float(-gr[inner].mean())
    tilt = math.atan2(my, mx)
    m1 = float(img[m].mean())
    m2 = float((img[m] ** 2).mean())
    ratio = m1 * m1 / m2
    slants = np.linspace(0.0, math.radians(89.0), 90)
    table = np.array([_disc_moments(a) for a in slants])
    rt = table[:, 0] ** 2 / table[:, 1]
    # the ratio decreases with the slant; interpolate on the reversed (increasing) arrays
    slant = float(np.interp(ratio, rt[::-1], slants[::-1]))
    e1 = float(np.interp(slant, slants, table[:, 0]))
    rho = m1 / e1 if e1 > 0 else imax
    d = np.array([math.sin(slant) * math.cos(tilt), math.sin(slant) * math.sin(tilt), math.cos(slant)])
    return LightEstimate(direction=d, albedo=float(rho), method="lee_rosenfeld1985")
