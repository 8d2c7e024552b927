"""The statistics of stored scores: one standard error from replicate values, the standard error
of a difference and of a mean over scenes, and when a difference is an effect.

The replicates (:mod:`pbrbench.bench.uncertainty` computes them) are ``rep_a`` and ``rep_b``, a
score recomputed on each of the two half-sample renders of its ground truth with the same seed,
and ``rep_noise``, the score recomputed on the full ground truth with a second seed where the
inputs depend on the seed.  Only the standard library is used.
"""

from __future__ import annotations

import math

SIGNIFICANCE = 2.0   # a difference is an effect beyond this many combined standard errors


def finite(x) -> bool:
    return x is not None and isinstance(x, (int, float)) and math.isfinite(x)


def standard_error(value: float, rep_a=None, rep_b=None, rep_noise=None) -> float:
    """One standard error of ``value`` from its replicates (NaN when none is usable)."""
    parts = []
    if rep_a is not None and rep_b is not None and math.isfinite(rep_a) and math.isfinite(rep_b):
        parts.append(((rep_a - rep_b) / 2.0) ** 2)
    if rep_noise is not None and math.isfinite(rep_noise) and math.isfinite(value):
        parts.append((value - rep_noise) ** 2 / 2.0)
    return math.sqrt(sum(parts)) if parts else float("nan")



def combined_se(*ses) -> float:
    """``sqrt(sum se^2)`` of independent errors (NaN if any is missing)."""
    if not all(finite(s) for s in ses):
        return float("nan")
    return math.sqrt(sum(s * s for s in ses))


def mean_se(values: list[float], ses: list[float]) -> tuple[float, float]:
    """Mean of independent values and its standard error ``sqrt(sum se^2) / n`` (NaN if any SE is)."""
    n = len(values)
    if n == 0:
        return float("nan"), float("nan")
    m = sum(values) / n
    return m, combined_se(*ses) / n


def significant(difference: float, se: float, floor: float = 0.0) -> bool | None:
    """True when ``|difference|`` exceeds ``SIGNIFICANCE`` standard errors plus ``floor``; None
    when the standard error is unknown."""
    if not finite(se) or not finite(difference):
        return None
    return abs(difference) > SIGNIFICANCE * se + floor


def paired_se(x: dict, ref: dict) -> float:
    """Standard error of ``x.value - ref.value`` for two scores (dicts with ``uncertainty`` and
    the replicate values).  When both come from one ground truth (the same render: e.g. global and
    local of one scene), the difference of their paired half-sample replicates is used, which keeps
    the correlation between them; otherwise the two are independent and their errors add in
    quadrature."""
    same_gt = bool(x.get("scene_hash")) and x.get("scene_hash") == ref.get("scene_hash")
    if same_gt and all(v is not None and math.isfinite(v) for v in
                       (x.get("rep_a"), x.get("rep_b"), ref.get("rep_a"), ref.get("rep_b"))):
        d_a = x["rep_a"] - ref["rep_a"]
        d_b = x["rep_b"] - ref["rep_b"]
        parts = [((d_a - d_b) / 2.0) ** 2]
        for s in (x, ref):
            if s.get("rep_noise") is not None and math.isfinite(s["rep_noise"]):
                parts.append((s["value"] - s["rep_noise"]) ** 2 / 2.0)
        return math.sqrt(sum(parts))
    ux, ur = x.get("uncertainty"), ref.get("uncertainty")
    if ux is None or ur is None or not (math.isfinite(ux) and math.isfinite(ur)):
        return float("nan")
    return math.sqrt(ux * ux + ur * ur)
