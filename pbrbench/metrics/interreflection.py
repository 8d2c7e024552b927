"""Scores of forward models of radiance (the interreflection task): predicted against rendered radiance.

Over the evaluation domain ``D`` (pixels ``p``, channels ``c``), with the prediction ``P`` and
the reference ``R`` (the path tracer's global radiance, or its direct light):

.. math::  e_1 = \\frac{\\sum_{p, c} |P - R|}{\\sum_{p, c} R}, \\qquad
           e_2 = \\frac{\\sqrt{\\mathrm{mean}_{p, c} (P - R)^2}}{\\mathrm{mean}_{p, c} R}, \\qquad
           b = \\frac{\\sum P}{\\sum R} - 1,

and the luminance-weighted chromaticity error
``sum_p Y_p |chi(P_p) - chi(R_p)|_1 / sum_p Y_p`` with ``chi = (r, g, b) / (r + g + b)`` and
``Y`` the reference's channel sum: a model that misses colour bleeding (light reflected by a
coloured surface onto a white one) has the right brightness but the wrong colour there.  The
same difference in perceptual units is ``delta_e2000``, the mean CIEDE2000 colour difference
(Sharma, Wu and Dalal 2005) between ``P`` and ``R`` read as linear sRGB (through colour-science:
sRGB primaries, D65, CIE L*a*b*), both scaled so that the reference's 99th-percentile luminance
over ``D`` is white (``Y = 1``): about 1 is a just-noticeable difference.  ``chi`` is the
chapter's normalised RGB, the camera's own coordinates; CIE chromaticities would add a
colourspace the renders do not have.

References: G. Sharma, W. Wu and E. N. Dalal, "The CIEDE2000 color-difference formula:
implementation notes, supplementary test data, and mathematical observations", Color Research &
Application 30(1), 2005.  D. A. Forsyth and A. Zisserman, "Reflections on shading", IEEE PAMI 13(7), 1991 (the
local model against interreflections); C. M. Goral et al., SIGGRAPH 1984 (the radiosity model).
"""

from __future__ import annotations

import numpy as np

from pbrbench.checks import as_float_array, check_mask
from pbrbench.metrics.table import table

__all__ = ["METRICS", "radiosity_scores", "chromaticity_error", "delta_e2000"]

METRICS = table("""
radiosity_rel_error | lower | -    | radiosity_scores   | sum |predicted - rendered radiance| / sum rendered, over the visible surface
radiosity_rel_rmse  | lower | -    | radiosity_scores   | RMS of predicted - rendered radiance / mean rendered radiance, visible surface
radiosity_abs_bias  | lower | -    | radiosity_scores   | |sum predicted / sum rendered - 1|: the missing (or extra) light overall
chromaticity_error  | lower | -    | chromaticity_error | luminance-weighted L1 distance of the (r, g, b) / (r + g + b) chromaticities
delta_e2000         | lower | dE00 | delta_e2000        | mean CIEDE2000 colour difference, linear sRGB scaled to the reference's white
""")


def _pair(pred, ref, mask):
    P = as_float_array(pred, "pred")
    R = as_float_array(ref, "ref")
    if P.ndim == 2:
        P = P[..., None]
    if R.ndim == 2:
        R = R[..., None]
    if P.shape[:2] != R.shape[:2] or P.shape[-1] not in (1, R.shape[-1]):
        raise ValueError(f"pred: shape {P.shape} does not match the reference's {R.shape}")
    P = np.broadcast_to(P, R.shape)
    m = np.ones(R.shape[:2], bool) if mask is None else check_mask(mask, R.shape[:2])
    return P[m], R[m]


def chromaticity_error(pred, ref, mask=None) -> float:
    """Luminance-weighted L1 distance of the chromaticities (see the module docstring); 0 for
    one-channel images."""
    P, R = _pair(pred, ref, mask)
    if R.shape[-1] < 3:
        return 0.0
    sp, sr = P.sum(-1), R.sum(-1)
    ok = (sr > 0) & (sp > 0)
    if not ok.any():
        return float("nan")
    dchi = np.abs(P[ok] / sp[ok, None] - R[ok] / sr[ok, None]).sum(-1)
    return float(np.sum(sr[ok] * dchi) / np.sum(sr[ok]))


def delta_e2000(pred, ref, mask=None, *, white_percentile: float = 99.0) -> float:
    """Mean CIEDE2000 difference of two linear sRGB images over ``mask`` (module docstring); both
    are divided by the reference's ``white_percentile`` luminance there.  One-channel images
    are grey (the channel repeated).

    Raises
    ------
    ValueError
        On mismatched shapes, an empty domain, or a reference without light in it.
    """
    import colour

    P, R = _pair(pred, ref, mask)
    if R.size == 0:
        raise ValueError("mask: the evaluation domain is empty; give a mask with some pixels")
    if R.shape[-1] == 1:
        P, R = np.repeat(P, 3, axis=-1), np.repeat(R, 3, axis=-1)
    if R.shape[-1] != 3:
        raise ValueError(f"ref: {R.shape[-1]} channels; delta_e2000 reads RGB images (3 channels) or grey ones")
    space = colour.RGB_COLOURSPACES["sRGB"]
    XP = colour.RGB_to_XYZ(P, space, apply_cctf_decoding=False)
    XR = colour.RGB_to_XYZ(R, space, apply_cctf_decoding=False)
    white = float(np.percentile(XR[:, 1], white_percentile))
    if not white > 0:
        raise ValueError("ref: no light in the evaluation domain (the colour difference is undefined)")
    lab = [colour.XYZ_to_Lab(X / white, space.whitepoint) for X in (XP, XR)]
    return float(np.mean(colour.delta_E(lab[0], lab[1], method="CIE 2000")))


def radiosity_scores(pred, ref, mask=None) -> dict[str, float]:
    """``radiosity_rel_error``, ``radiosity_rel_rmse``, ``radiosity_abs_bias``,
    ``chromaticity_error`` and ``delta_e2000`` of a predicted radiance image (H, W[, C]) against the reference over
    ``mask`` (see the module docstring).

    Raises
    ------
    ValueError
        On mismatched shapes, an empty domain or a reference without light in it.
    """
    P, R = _pair(pred, ref, mask)
    if R.size == 0:
        raise ValueError("mask: the evaluation domain is empty; give a mask with some pixels")
    total = float(R.sum())
    if not total > 0:
        raise ValueError("ref: no light in the evaluation domain (the relative errors are undefined)")
    d = P - R
    return {"radiosity_rel_error": float(np.abs(d).sum() / total),
            "radiosity_rel_rmse": float(np.sqrt(np.mean(d * d)) / np.mean(R)),
            "radiosity_abs_bias": float(abs(P.sum() / total - 1.0)),
            "chromaticity_error": chromaticity_error(pred, ref, mask),
            "delta_e2000": delta_e2000(pred, ref, mask)}
