"""The calibrated inverse camera response shared by every calibration and merge method."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pbrbench.checks import as_float_array, check_finite, check_int

__all__ = ["CameraResponse"]


@dataclass(frozen=True, eq=False)
class CameraResponse:
    """A calibrated inverse camera response, tabulated per pixel level and channel.

    Attributes
    ----------
    inverse : ndarray, (levels, C), float64
        ``f_c^{-1}(z)``: relative linear exposure of level ``z``; strictly increasing, finite and
        positive, with ``inverse[-1, c] == 1`` for every channel (the clipping point).
    levels : int
        Number of pixel levels (``2 ** bit_depth``).
    method : str
        The calibration that produced it: a key of
        :data:`pbrbench.infer.hdr.CALIBRATION_METHODS` (``"debevec1997"``, ``"robertson2003"``,
        ``"mitsunaga1999"``), or any label for a response built by hand.
    exposure_times : ndarray (K,) or None
        Re-estimated exposure times (``"mitsunaga1999"``), else None.  Pass them to
        :func:`pbrbench.infer.hdr.merge_hdr` in place of the stated times.
    coefficients : ndarray (degree + 1, C) or None
        Polynomial coefficients of ``f^{-1}(z / (levels - 1))`` (``"mitsunaga1999"``), else None.
    """

    inverse: np.ndarray
    levels: int
    method: str
    exposure_times: np.ndarray | None = None
    coefficients: np.ndarray | None = None

    def __post_init__(self):
        """Validate on construction, so every response a merge receives is usable: ``inverse``
        real, finite, > 0, (levels, C), non-decreasing along the levels and not constant."""
        levels = check_int(self.levels, "CameraResponse.levels", 2, 1 << 16)
        inv = as_float_array(self.inverse, "CameraResponse.inverse", ndim=(2,))
        if inv.shape[0] != levels or inv.shape[1] < 1:
            raise ValueError(f"CameraResponse.inverse: expected shape (levels, C) = ({levels}, C), got {inv.shape}; "
                             "tabulate f^-1 at every pixel level")
        check_finite(inv, "CameraResponse.inverse")
        if (inv <= 0).any():
            raise ValueError("CameraResponse.inverse: values must be > 0 (relative exposures); got "
                             f"min {inv.min():.3g}")
        if (np.diff(inv, axis=0) < 0).any():
            c = int(np.flatnonzero((np.diff(inv, axis=0) < 0).any(axis=0))[0])
            raise ValueError(f"CameraResponse.inverse: channel {c} decreases; an inverse response must be monotone "
                             "non-decreasing in the pixel level")
        if (inv[-1] <= inv[0]).any():
            raise ValueError("CameraResponse.inverse: constant in some channel; an inverse response must increase "
                             "from the lowest to the highest level")
        if not isinstance(self.method, str):
            raise ValueError(f"CameraResponse.method: must be a string label, got {self.method!r}")
        object.__setattr__(self, "inverse", inv)
        object.__setattr__(self, "levels", levels)
        if self.exposure_times is not None:
            t = as_float_array(self.exposure_times, "CameraResponse.exposure_times", ndim=(1,))
            check_finite(t, "CameraResponse.exposure_times")
            if (t <= 0).any():
                raise ValueError("CameraResponse.exposure_times: must be > 0 (seconds)")
            object.__setattr__(self, "exposure_times", t)
        if self.coefficients is not None:
            co = as_float_array(self.coefficients, "CameraResponse.coefficients", ndim=(2,))
            check_finite(co, "CameraResponse.coefficients")
            object.__setattr__(self, "coefficients", co)

    @property
    def log_inverse(self) -> np.ndarray:
        """``g = ln f^{-1}``, shape (levels, C)."""
        return np.log(self.inverse)

    @property
    def channels(self) -> int:
        """Number of channels C of the tabulated inverse."""
        return self.inverse.shape[1]
