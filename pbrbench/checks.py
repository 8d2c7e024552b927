"""One set of input checks for every layer (inference, metrics, shading, rendering statistics).

Every check raises :class:`ValueError` whose message names the argument, says what is wrong and
how to fix it, e.g. ``images: 3 non-finite value(s) (NaN or inf); replace them (e.g.
np.nan_to_num) or exclude those pixels with the mask argument``.  The command line turns such an
error into one line and exit code 1.

Only NumPy is imported here (``pbrbench.infer`` must stay importable with NumPy and SciPy alone).

The module also holds the one dispatcher used by every methods table (:func:`call_method`): it
looks a method up by name and forwards only the options that method accepts, rejecting an
unknown option with the list of that method's options.
"""

from __future__ import annotations

import inspect
import sys
import warnings
from collections.abc import Callable, Iterable, Mapping

import numpy as np

__all__ = [
    "as_array",
    "as_float_array",
    "call_method",
    "check_finite",
    "check_int",
    "check_mask",
    "check_method",
    "check_number",
    "check_pixel_size",
    "check_positive",
    "check_seed",
    "check_tolerance",
    "method_options",
]


def as_array(x, name: str) -> np.ndarray:
    """``np.asarray(x)``, with a ``ValueError`` naming the argument when that fails (ragged nested
    lists, objects NumPy cannot convert) or when ``x`` is None."""
    if x is None:
        raise ValueError(f"{name}: got None; pass a NumPy array")
    try:
        return np.asarray(x)
    except Exception as exc:  # noqa: BLE001 - numpy raises many things for unconvertible input
        first = str(exc).split(". ")[0].split("\n")[0]
        raise ValueError(f"{name}: could not convert to an array ({first}); pass a NumPy array of one shape "
                         "(nested lists must all have the same length)") from None


def as_float_array(x, name: str, *, ndim: Iterable[int] | None = None, dtype=np.float64,
                   allow_empty: bool = False) -> np.ndarray:
    """``x`` as a real float array, checking its number of dimensions.

    Raises ``ValueError`` if ``x`` is None, not numeric (object, string, complex), ragged, has the
    wrong number of dimensions, or is empty (unless ``allow_empty``).
    """
    arr = as_array(x, name)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name}: complex values (dtype {arr.dtype}); pass real values "
                         "(np.real(x) or np.abs(x), whichever the data means)")
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise ValueError(f"{name}: expected a numeric array, got dtype {arr.dtype}; pass a NumPy array of numbers")
    if ndim is not None:
        ndims = tuple(ndim)
        if arr.ndim not in ndims:
            want = " or ".join(str(n) for n in ndims)
            raise ValueError(f"{name}: expected {want} dimensions, got shape {arr.shape}; reshape the input")
    if arr.size == 0 and not allow_empty:
        raise ValueError(f"{name}: empty array (shape {arr.shape}); pass at least one value")
    return arr.astype(dtype, copy=False)


def check_finite(arr: np.ndarray, name: str, *, where: np.ndarray | None = None) -> None:
    """Raise ``ValueError`` if ``arr`` holds NaN or infinite values (inside ``where`` if given)."""
    if arr.dtype.kind in "biu" or np.isfinite(arr).all():
        return                      # the common case: no gather of the masked values needed
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
    m = as_array(mask, name)
    if m.dtype == object or np.iscomplexobj(m) or not (np.issubdtype(m.dtype, np.number) or m.dtype == bool):
        raise ValueError(f"{name}: must be boolean (or 0/1), got dtype {m.dtype}; pass an (H, W) boolean mask")
    if m.shape != tuple(shape):
        raise ValueError(f"{name}: shape {m.shape} does not match the image shape {tuple(shape)}; pass an (H, W) boolean mask")
    if m.dtype != bool:
        if m.dtype == object or np.iscomplexobj(m) or not np.isin(m, (0, 1)).all():
            raise ValueError(f"{name}: must be boolean (or 0/1); got values outside {{0, 1}}")
        m = m.astype(bool)
    if not m.any():
        raise ValueError(f"{name}: no pixel is selected; pass a mask with at least one True pixel")
    return m


def check_method(method: str, methods: Iterable[str], name: str = "method") -> str:
    """Raise ``ValueError`` naming the valid choices if ``method`` is not one of ``methods``."""
    valid = list(methods)
    if not isinstance(method, str) or method not in valid:
        raise ValueError(f"{name}={method!r} is not known; choose one of {', '.join(repr(m) for m in valid)}")
    return method


def check_positive(value, name: str) -> float:
    """Return ``value`` as float, raising ``ValueError`` unless it is finite and > 0."""
    return check_number(value, name, lo=0.0, lo_open=True)


MAX_PIXEL_SIZE = 1e6


def check_pixel_size(value, name: str = "pixel_size") -> float:
    """A pixel size (world units per pixel): a finite number > 0 and <= :data:`MAX_PIXEL_SIZE`
    (heights are pixel heights times it, which must stay finite)."""
    return check_number(value, name, lo=0.0, lo_open=True, hi=MAX_PIXEL_SIZE)


def check_tolerance(value, name: str = "tol") -> float:
    """A relative tolerance: a finite number > 0 and <= 1 (a larger one stops at once)."""
    return check_number(value, name, lo=0.0, lo_open=True, hi=1.0)


def check_number(value, name: str, *, lo: float | None = None, hi: float | None = None,
                 lo_open: bool = False, hi_open: bool = False) -> float:
    """``value`` as a finite float inside ``[lo, hi]`` (``lo_open`` / ``hi_open``: strict bounds)."""
    if isinstance(value, bool) or np.iscomplexobj(value):
        raise ValueError(f"{name}: must be a real number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be a number, got {value!r}") from exc
    below = lo is not None and (v <= lo if lo_open else v < lo)
    above = hi is not None and (v >= hi if hi_open else v > hi)
    if not np.isfinite(v) or below or above:
        parts = []
        if lo is not None:
            parts.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            parts.append(f"{'<' if hi_open else '<='} {hi:g}")
        rng = f" {' and '.join(parts)}" if parts else ""
        raise ValueError(f"{name}: must be a finite number{rng}, got {value!r}")
    return v


def check_seed(seed, name: str = "seed"):
    """``seed`` if NumPy accepts it as a seed (an integer >= 0, a sequence of them, a
    SeedSequence or a Generator), else ``ValueError`` naming the argument."""
    if isinstance(seed, (np.random.Generator, np.random.SeedSequence)):
        return seed
    if isinstance(seed, bool) or seed is None:
        raise ValueError(f"{name}: must be an integer >= 0 (or a sequence of them), got {seed!r}")
    try:
        np.random.SeedSequence(seed)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name}: must be an integer >= 0 (or a sequence of them), got {seed!r}") from None
    return seed


def check_int(value, name: str, lo: int = 1, hi: int | None = None) -> int:
    """``value`` as an int in ``[lo, hi]``; floats with an integral value are accepted, bools not."""
    if isinstance(value, bool):
        raise ValueError(f"{name}: must be an integer >= {lo}, got {value!r}")
    try:
        iv = int(value)
        ok = iv == value
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok or iv < lo or (hi is not None and iv > hi):
        rng = f">= {lo}" + (f" and <= {hi}" if hi is not None else "")
        raise ValueError(f"{name}: must be an integer {rng}, got {value!r}")
    return iv


# ----------------------------------------------------------------------------- dispatching
def method_options(fn: Callable) -> tuple[str, ...]:
    """The keyword options a method accepts (its keyword-only parameters and those with defaults)."""
    out = []
    for p in inspect.signature(fn).parameters.values():
        if p.kind is inspect.Parameter.KEYWORD_ONLY or (
                p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD and p.default is not inspect.Parameter.empty):
            out.append(p.name)
    return tuple(out)


def call_method(methods: Mapping[str, Callable], method: str, problem: str, *args, **options):
    """Call ``methods[method](*args, **options)`` after checking the name and the options.

    ``problem`` names the dispatcher in messages (e.g. ``"shape_from_shading"``).  An option the
    chosen method does not accept raises ``ValueError`` listing the options it does accept, so a
    misspelt or misplaced option never goes silently unused.  Warnings the method issues are
    re-issued at the line that called the dispatcher (not inside pbrbench).
    """
    check_method(method, methods)
    fn = methods[method]
    accepted = method_options(fn)
    unknown = sorted(k for k in options if k not in accepted)
    if unknown:
        raise ValueError(f"{problem}(method={method!r}): unknown option(s) {', '.join(unknown)}; "
                         f"{method} accepts {', '.join(accepted) or 'no options'}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args, **options)
    if caught:
        caller = sys._getframe(2) if hasattr(sys, "_getframe") else None
        for w in caught:
            if caller is None:
                warnings.warn(w.message, w.category, stacklevel=3)
                continue
            g = caller.f_globals
            warnings.warn_explicit(w.message, w.category, caller.f_code.co_filename, caller.f_lineno,
                                   module=g.get("__name__"), registry=g.setdefault("__warningregistry__", {}))
    return out
