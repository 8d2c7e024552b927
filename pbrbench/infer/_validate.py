"""Input validation shared by the inference modules.

Every check raises :class:`ValueError` with a message that names the argument, says what
is wrong and how to fix it.  Only NumPy is imported here.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


def as_float_array(x, name: str, *, ndim: Iterable[int] | None = None, dtype=np.float64) -> np.ndarray:
    """Convert ``x`` to a float array, checking its dimensionality.

    Raises ``ValueError`` if ``x`` is not numeric or has the wrong number of dimensions.
    """
    try:
        arr = np.asarray(x)
    except Exception as exc:  # pragma: no cover - numpy raises many things
        raise ValueError(f"{name}: could not convert to an array ({exc}); pass a NumPy array") from exc
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise ValueError(f"{name}: expected a numeric array, got dtype {arr.dtype}; pass a NumPy array of numbers")
    if ndim is not None:
        ndims = tuple(ndim)
        if arr.ndim not in ndims:
            want = " or ".join(str(n) for n in ndims)
            raise ValueError(f"{name}: expected {want} dimensions, got shape {arr.shape}; reshape the input")
    return arr.astype(dtype, copy=False)


def check_finite(arr: np.ndarray, name: str, *, where: np.ndarray | None = None) -> None:
    """Raise ``ValueError`` if ``arr`` holds NaN or infinite values (inside ``where`` if given)."""
    vals = arr if where is None else arr[where]
    bad = ~np.isfinite(vals)
    if np.any(bad):
        n = int(bad.sum())
        raise ValueError(
            f"{name}: {n} non-finite value(s) (NaN or inf); replace them (e.g. np.nan_to_num) "
            "or exclude those pixels with the mask argument"
        )


def check_mask(mask, shape: tuple[int, ...], name: str = "mask") -> np.ndarray:
    """Return ``mask`` as a boolean array of ``shape`` (all True when ``mask`` is None)."""
    if mask is None:
        return np.ones(shape, dtype=bool)
    m = np.asarray(mask)
    if m.shape != tuple(shape):
        raise ValueError(f"{name}: shape {m.shape} does not match the image shape {tuple(shape)}; pass an (H, W) boolean mask")
    if m.dtype != bool:
        if not np.isin(m, (0, 1)).all():
            raise ValueError(f"{name}: must be boolean (or 0/1); got values outside {{0, 1}}")
        m = m.astype(bool)
    if not m.any():
        raise ValueError(f"{name}: no pixel is selected; pass a mask with at least one True pixel")
    return m


def check_method(method: str, methods: Iterable[str], name: str = "method") -> str:
    """Raise ``ValueError`` naming the valid choices if ``method`` is not one of ``methods``."""
    valid = list(methods)
    if method not in valid:
        raise ValueError(f"{name}={method!r} is not known; choose one of {', '.join(repr(m) for m in valid)}")
    return method


def check_positive(value, name: str) -> float:
    """Return ``value`` as float, raising ``ValueError`` unless it is finite and > 0."""
    v = float(value)
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")
    return v
