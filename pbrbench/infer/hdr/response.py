"""The calibrated inverse camera response shared by every calibration and merge method."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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

    @property
    def log_inverse(self) -> np.ndarray:
        """``g = ln f^{-1}``, shape (levels, C)."""
        return np.log(self.inverse)

    @property
    def channels(self) -> int:
        """Number of channels C of the tabulated inverse."""
        return self.inverse.shape[1]
