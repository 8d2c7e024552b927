"""Exact power-of-two rescaling of inputs whose magnitude would overflow or underflow float64.

The methods are scale-covariant (normals and light directions do not depend on the scale of
the images; heights, albedos and radiances scale with it), but their intermediate products
(squares, normal equations) overflow near 1e300 and underflow near 1e-300.  An input whose
largest magnitude lies outside [1e-100, 1e100] is multiplied by a power of two, which is exact,
before the solve and the result scaled back; inputs inside that range are not touched, so
ordinary results are bit-for-bit unchanged.
"""

from __future__ import annotations

import math

import numpy as np

LOW, HIGH = 1e-100, 1e100


def pow2_exponent(maxabs: float) -> int:
    """The exponent ``e`` such that ``x * 2**-e`` brings a magnitude ``maxabs`` near 1, or 0
    when ``maxabs`` is zero, not finite or already within [1e-100, 1e100]."""
    m = float(maxabs)
    if not math.isfinite(m) or m == 0.0 or LOW <= m <= HIGH:
        return 0
    return math.frexp(m)[1]


def max_abs(a, where=None) -> float:
    """The largest finite magnitude of ``a`` (over ``where``), 0 when there is none."""
    a = np.asarray(a, float)
    if where is not None:
        a = a[where]
    a = np.abs(a[np.isfinite(a)])
    return float(a.max()) if a.size else 0.0


def robust_norm(v, axis=-1) -> np.ndarray:
    """Euclidean norms along ``axis`` that neither overflow nor underflow for finite input."""
    v = np.asarray(v, float)
    s = np.max(np.abs(v), axis=axis, keepdims=True)
    safe = np.where((s > 0) & np.isfinite(s), s, 1.0)
    return np.linalg.norm(v / safe, axis=axis) * np.squeeze(safe, axis=axis)
