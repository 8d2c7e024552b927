"""The statistics of stored scores: a jackknife standard error with its degrees of freedom, a
Monte Carlo bias estimate, the standard error of a difference and of a mean over scenes, when a
difference is an effect, and when the replicates disagree beyond the model (a flipped discrete
choice).

Every rendered pass is the mean of ``G`` independent sample groups.  A score ``v`` computed on the
full ground truth is recomputed on each of the ``G`` delete-one-group ground truths (every group
but ``i``), with the same seed: the replicates ``v_(i)`` (:mod:`pbrbench.bench.uncertainty`).
The delete-one-group jackknife (Quenouille 1956, Tukey 1958; Efron & Stein 1981) gives

.. math::

    \\bar v = \\frac1G \\sum_i v_{(i)}, \\qquad
    \\mathrm{SE}^2 = \\frac{G-1}{G} \\sum_i (v_{(i)} - \\bar v)^2 \\quad (G - 1 \\text{ dof}), \\qquad
    \\hat b = (G - 1)(\\bar v - v),

``\\hat b`` the bias that render noise gives the score (a score that is not linear in the
images is biased by O(1/spp): each replicate has ``(G-1)/G`` of the samples, so its bias is
``G/(G-1)`` times the full score's) and ``v - \\hat b`` the bias-corrected score.  Where the inputs
also depend on the seed (injected camera noise), the job is also scored with ``K`` other seeds
(``v_{n,1} ... v_{n,K}``, on the full ground truth): ``v`` and those ``K`` are ``K + 1``
independent draws of the seed's effect, and their sample variance (``K`` degrees of freedom) is
added.  A score chaotic in its input (an iteration stopped before its fixed point: a change of
the input far below the render noise moves it by a large part of its spread) makes the
replicates independent draws rather than a jackknife series; a rescoring on a slightly perturbed
ground truth detects it (:func:`chaotic`), and its standard error then comes from the draws
(:func:`draws`, ``G`` dof, no bias estimate).  The degrees of freedom of a sum of variances come from the Welch-Satterthwaite rule.  Intervals use Student's t on those degrees of freedom.

Only the standard library and, for the t quantiles, SciPy (imported on first use) are used.

References
----------
M. H. Quenouille, "Notes on bias in estimation", Biometrika 43, 1956.  B. Efron, C. Stein,
"The jackknife estimate of variance", Annals of Statistics 9, 1981.  F. E. Satterthwaite, "An
approximate distribution of estimates of variance components", Biometrics Bulletin 2, 1946.
R. B. Dean, W. J. Dixon, "Simplified statistics for small numbers of observations", Analytical
Chemistry 23, 1951 (the gap test of :func:`unstable`).
"""

from __future__ import annotations

import json
import math
from functools import lru_cache

CONFIDENCE = 0.95    # two-sided level of the intervals and of "a difference is an effect"
# largest gap between sorted replicates / their range above which the replicates are bimodal
# (a discrete choice flipped): the 99.9th percentile of the statistic for G Gaussian replicates
# (Monte Carlo, 10^6 draws each; tests/bench/test_uncertainty.py re-measures it)
GAP_CRITICAL = {3: 0.9994, 4: 0.9783, 5: 0.9242, 6: 0.8613, 7: 0.8028, 8: 0.7557}
SIDES_FROM = 6           # from this many replicates on, a flip leaves at least two on each side of its gap
UNSTABLE_MIN_GAP = 0.05  # a flip moves the score by at least this fraction of its size: smaller gaps
                         # are the quantisation of a counting metric (one pixel more or less), not a flip
PERTURBATION = 1e-3     # the perturbed ground truth: this fraction of the way toward the replicate without
                        # group 0 (a change a thousand times below the render noise)
CHAOS_THRESHOLD = 0.05  # a perturbed score that moves more than this many jackknife SEs beyond its
                        # first-order change is chaotic in its input (:func:`chaotic`)


def finite(x) -> bool:
    return x is not None and isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@lru_cache(maxsize=256)
def t_quantile(dof: float, q: float = 0.5 + CONFIDENCE / 2) -> float:
    """Student's t quantile ``q`` on ``dof`` degrees of freedom (the normal quantile for
    ``dof = inf``; NaN for ``dof < 1`` or unknown)."""
    if not finite(dof) and dof != math.inf:
        return float("nan")
    if dof < 1:
        return float("nan")
    from scipy import stats

    return float(stats.norm.ppf(q) if dof == math.inf or dof > 1e6 else stats.t.ppf(q, dof))


def replicates_of(s: dict) -> list[float] | None:
    """The delete-one-group replicate values of a score dict: ``replicates`` (a list or its JSON
    text); for scores stored before the groups existed, the two half-sample values ``rep_a``,
    ``rep_b`` are the two-group jackknife's replicates (the replicate that deletes half ``a`` is
    half ``b``).  None when there are none or any is not finite."""
    r = s.get("replicates")
    if isinstance(r, str):
        try:
            r = json.loads(r)
        except ValueError:
            r = None
    if r is None and s.get("rep_a") is not None and s.get("rep_b") is not None:
        r = [s["rep_b"], s["rep_a"]]
    if not r or len(r) < 2:
        return None
    try:
        r = [float(v) for v in r]
    except (TypeError, ValueError):
        return None
    return r if all(math.isfinite(v) for v in r) else None


def jackknife(value: float, reps) -> tuple[float, float, int]:
    """``(SE, bias, dof)`` of ``value`` from its delete-one-group replicates ``reps``
    (module docstring); NaN and dof 0 when fewer than 2 finite replicates or ``value`` is not finite."""
    if reps is None or len(reps) < 2 or not finite(float(value)) or not all(math.isfinite(float(r)) for r in reps):
        return float("nan"), float("nan"), 0
    G = len(reps)
    m = sum(reps) / G
    var = (G - 1) / G * sum((r - m) ** 2 for r in reps)
    return math.sqrt(var), (G - 1) * (m - value), G - 1


def satterthwaite(parts: list[tuple[float, float]]) -> float:
    """Degrees of freedom of ``sum var_k`` for ``parts = [(var_k, dof_k)]`` (Welch-Satterthwaite):
    ``(sum var_k)^2 / sum(var_k^2 / dof_k)``; inf when every part is 0."""
    tot = sum(v for v, _ in parts)
    den = sum(v * v / d for v, d in parts if d > 0 and v > 0)
    if tot <= 0 or den <= 0:
        return math.inf
    return tot * tot / den


def noise_values(rep_noise) -> list[float]:
    """The other seeds' values of a score (:func:`estimate`): ``rep_noise`` as stored, one value
    (scores stored before there were several), a list of them or its JSON text; the finite ones."""
    r = rep_noise
    if isinstance(r, str):
        try:
            r = json.loads(r)
        except ValueError:
            return []
    if r is None:
        return []
    if not isinstance(r, (list, tuple)):
        r = [r]
    return [float(v) for v in r if finite(v)]


def noise_part(value: float, rep_noise, *, mean: bool = False) -> tuple[float, int] | None:
    """``(variance, dof)`` of the seed's part of a score's error from its other seeds' values
    ``rep_noise`` (``K`` of them, ``K`` degrees of freedom); None without any.

    ``mean`` False: ``value`` is one draw (the job's own seed), and the part is the sample
    variance of ``value`` and the ``K`` others.  ``mean`` True: ``value`` is the mean of the
    ``K + 1`` draws (:func:`mean_over_seeds`); the own seed's draw is ``(K + 1) value - sum``
    of the others, and the part is their sample variance over ``K + 1``, the variance of the mean."""
    vals = noise_values(rep_noise)
    if not vals or not finite(value):
        return None
    k = len(vals)
    own = (k + 1) * float(value) - sum(vals) if mean else float(value)
    xs = [own, *vals]
    m = sum(xs) / len(xs)
    var = sum((x - m) ** 2 for x in xs) / (len(xs) - 1)
    return (var / (k + 1) if mean else var), k


def mean_over_seeds(value: float, reps, rep_noise) -> tuple[float, list[float] | None]:
    """A seed-dependent score as the mean of its ``K + 1`` draws: ``(mean, replicates)``, the
    delete-one-group replicates (computed at the job's own seed) moved by the same amount as the
    value, so that their spread and the jackknife bias are those of the own seed's draw: the
    render noise is common to every draw (they are scored on the same ground truth)."""
    vals = noise_values(rep_noise)
    if not vals or not finite(value):
        return value, reps
    m = (float(value) + sum(vals)) / (len(vals) + 1)
    return m, (None if reps is None else [float(r) + (m - float(value)) for r in reps])


def chaotic(value: float, reps, perturbed, *, threshold: float = CHAOS_THRESHOLD) -> bool | None:
    """Whether a score is chaotic in its input: rescored on the ground truth moved by
    :data:`PERTURBATION` toward its replicate without group 0
    (:meth:`pbrbench.render.groundtruth.GroundTruth.perturbed`), a score smooth in its input
    moves by ``eps (v_(0) - v)`` to first order; one whose move differs from that by more than
    ``threshold`` (:data:`CHAOS_THRESHOLD`) of its jackknife standard error depends on far less
    than the render noise (an iteration stopped before it converged, whose end point jumps with
    the last bits of its input).  None when there is no perturbed value or no jackknife."""
    se_j, _, dof_j = jackknife(value, reps)
    return _chaotic(value, reps, perturbed, se_j, dof_j, threshold)


def _chaotic(value, reps, perturbed, se_j, dof_j, threshold=CHAOS_THRESHOLD) -> bool | None:
    """:func:`chaotic` given the jackknife's ``se_j`` and ``dof_j`` of ``value`` and ``reps``."""
    if not finite(perturbed) or not dof_j or not finite(se_j):
        return None
    e = (float(perturbed) - float(value)) - PERTURBATION * (float(reps[0]) - float(value))
    return se_j > 0 and abs(e) > threshold * se_j


def draws(value: float, reps, perturbed) -> tuple[float, int]:
    r"""``(SE, dof)`` of a chaotic score (:func:`chaotic`), whose ``G`` replicates and perturbed
    value are independent draws rather than a jackknife series: the variance of one draw pooled
    from the perturbed pair, ``(v_eps - v)^2 / 2`` (1 dof), and the replicates' sample variance
    scaled to the full sample count by ``(G - 1) / G`` (``G - 1`` dof),

    .. math::

        \mathrm{SE}^2 = \frac1G \Big[\frac{(v_\varepsilon - v)^2}{2}
                         + \frac{G-1}{G} \sum_i (v_{(i)} - \bar v)^2\Big] \quad (G \text{ dof}).

    The jackknife would state ``(G - 1) / \sqrt G`` times that spread (its ``G - 1`` factor
    assumes the replicates share all but one group's noise), and its bias ``(G - 1)(\bar v - v)``
    is noise: a chaotic score has no bias estimate."""
    G = len(reps)
    m = sum(float(r) for r in reps) / G
    ss = sum((float(r) - m) ** 2 for r in reps)
    var = ((float(perturbed) - float(value)) ** 2 / 2 + (G - 1) / G * ss) / G
    return math.sqrt(var), G


def estimate(value: float, reps=None, rep_noise=None, *, mean: bool = False, perturbed=None) -> dict:
    """``uncertainty`` (one standard error), ``dof``, ``bias``, ``unstable`` and ``chaotic`` of a
    score from its replicates, its other seeds' values ``rep_noise`` and its value on the
    perturbed ground truth ``perturbed`` (module docstring); NaN / 0 / None where they cannot be
    estimated.  ``mean``: ``value`` is the mean over the seeds (:func:`mean_over_seeds`,
    :func:`noise_part`; ``perturbed`` then moved with it).  A chaotic score (:func:`chaotic`)
    takes the render part of its error from :func:`draws` and has no bias estimate."""
    se_j, bias, dof_j = jackknife(value, reps)
    chaos = _chaotic(value, reps, perturbed, se_j, dof_j) if dof_j else None   # the jackknife once
    if chaos:
        se_j, dof_j = draws(value, reps, perturbed)
        bias = float("nan")
    parts = []
    if dof_j:
        parts.append((se_j * se_j, dof_j))
    noise = noise_part(value, rep_noise, mean=mean)
    if noise is not None:
        parts.append(noise)
    if not parts:
        return {"uncertainty": float("nan"), "dof": 0.0, "bias": float("nan"), "unstable": None, "chaotic": None}
    var = sum(v for v, _ in parts)
    dof = satterthwaite(parts) if var > 0 else float(sum(d for _, d in parts))
    return {"uncertainty": math.sqrt(var), "dof": round(float(min(dof, sum(d for _, d in parts))), 3), "bias": bias,
            "unstable": unstable(reps) if dof_j else None, "chaotic": chaos}


def standard_error(value: float, reps=None, rep_noise=None) -> float:
    """One standard error of ``value`` from its replicates (NaN when none is usable)."""
    return estimate(value, reps, rep_noise)["uncertainty"]


def unstable(reps) -> bool | None:
    """Whether the replicates split into two groups far apart (a discrete choice of the pipeline
    flipped between them): the largest gap between the sorted values, over their range, exceeds
    :data:`GAP_CRITICAL` (a spread a smooth score's Gaussian replicates reach once in 1000), and
    the gap is at least :data:`UNSTABLE_MIN_GAP` of the score's magnitude.  From
    :data:`SIDES_FROM` replicates on, each side of the gap must hold at least two: one replicate
    alone beyond it is one sample group far from the rest, which the heavy tail of Monte Carlo
    noise (a group that caught a firefly) gives as well as a flip (eight groups of a penumbra:
    the image-as-reflectance baseline, which has no choice to flip, was flagged in one run of
    eight without this).  None below 3 replicates (no test)."""
    if reps is None or len(reps) < 3:
        return None
    v = sorted(float(r) for r in reps)
    rng = v[-1] - v[0]
    scale = max(abs(x) for x in v)
    gaps = [b - a for a, b in zip(v, v[1:], strict=False)]
    gap = max(gaps)
    if rng <= 0 or gap < UNSTABLE_MIN_GAP * scale:
        return False
    at = gaps.index(gap)          # the gap lies between v[at] and v[at + 1]
    if len(v) >= SIDES_FROM and min(at + 1, len(v) - at - 1) < 2:
        return False
    crit = GAP_CRITICAL.get(len(v), GAP_CRITICAL[max(GAP_CRITICAL)])
    return gap / rng > crit


def combined(*pairs) -> tuple[float, float]:
    """``(sqrt(sum se^2), dof)`` of independent errors given as ``(se, dof)`` pairs (NaN if any
    se is missing); dof by Welch-Satterthwaite."""
    if not pairs or not all(finite(se) for se, _ in pairs):
        return float("nan"), 0.0
    return math.sqrt(sum(se * se for se, _ in pairs)), satterthwaite([(se * se, d or math.inf) for se, d in pairs])


def combined_se(*ses) -> float:
    """``sqrt(sum se^2)`` of independent errors (NaN if any is missing)."""
    if not all(finite(s) for s in ses):
        return float("nan")
    return math.sqrt(sum(s * s for s in ses))


def mean_se(values: list[float], ses: list[float], dofs: list[float] | None = None) -> tuple[float, float, float]:
    """Mean of independent values, its standard error ``sqrt(sum se^2) / n`` (NaN if any SE is)
    and the Welch-Satterthwaite degrees of freedom of that error (inf when ``dofs`` is omitted)."""
    n = len(values)
    if n == 0:
        return float("nan"), float("nan"), 0.0
    m = sum(values) / n
    if dofs is None:
        return m, combined_se(*ses) / n, math.inf
    se, dof = combined(*zip(ses, dofs, strict=True))
    return m, se / n, dof


def limit(se: float, dof: float = math.inf) -> float:
    """Half-width of the two-sided :data:`CONFIDENCE` interval: ``t(dof) * se``."""
    return t_quantile(dof if dof else math.inf) * se if finite(se) else float("nan")


def significant(difference: float, se: float, floor: float = 0.0, dof: float = math.inf) -> bool | None:
    """True when ``|difference|`` exceeds the :data:`CONFIDENCE` interval (Student's t on ``dof``
    degrees of freedom) plus ``floor``; None when the standard error is unknown."""
    if not finite(se) or not finite(difference) or (dof is not None and finite(dof) and dof < 1):
        return None
    return abs(difference) > limit(se, dof) + floor


def _paired_jackknife(x: dict, ref: dict):
    """``(SE, bias, dof)`` of the jackknife of ``x.value - ref.value`` on the paired replicates'
    differences when both scores come from one ground truth (the same render, e.g. global and
    local of one scene) with the same number of replicates; None otherwise."""
    same_gt = bool(x.get("scene_hash")) and x.get("scene_hash") == ref.get("scene_hash")
    if x.get("chaotic") or ref.get("chaotic"):
        return None   # independent draws (:func:`chaotic`): no jackknife series to pair
    rx, rr = replicates_of(x), replicates_of(ref)
    if same_gt and rx and rr and len(rx) == len(rr) and finite(x.get("value")) and finite(ref.get("value")):
        return jackknife(x["value"] - ref["value"], [a - b for a, b in zip(rx, rr, strict=True)])
    return None


def paired(x: dict, ref: dict) -> tuple[float, float]:
    """``(SE, dof)`` of ``x.value - ref.value`` for two score dicts: the paired jackknife when both
    come from one ground truth, which keeps their correlation (:func:`_paired_jackknife`), plus
    the seed's part (paired too when both were scored with the same other seeds); otherwise the two are independent and their errors add in
    quadrature."""
    jk = _paired_jackknife(x, ref)
    if jk is not None:
        se, _, dof = jk
        parts = [(se * se, dof)]
        nx, nr = (noise_values(s.get("rep_noise")) for s in (x, ref))
        mx, mr = bool(x.get("noise_mean")), bool(ref.get("noise_mean"))
        if nx and len(nx) == len(nr) and mx == mr:
            # both depend on the seed and were scored with the same other seeds: the seed's part of
            # the difference from the paired differences (their correlation kept)
            parts.append(noise_part(x["value"] - ref["value"], [a - b for a, b in zip(nx, nr, strict=True)], mean=mx))
        else:
            parts += [p for p in (noise_part(s["value"], s.get("rep_noise"), mean=bool(s.get("noise_mean")))
                                  for s in (x, ref)) if p is not None]
        var = sum(v for v, _ in parts)
        return math.sqrt(var), (satterthwaite(parts) if var > 0 else float(dof))
    ux, ur = x.get("uncertainty"), ref.get("uncertainty")
    if not (finite(ux) and finite(ur)):
        return float("nan"), 0.0
    return combined((ux, dof_of(x)), (ur, dof_of(ref)))


def bias_of(s: dict) -> float:
    """A stored score's Monte Carlo bias estimate (from its replicates when ``bias`` is absent)."""
    b = s.get("bias")
    if finite(b):
        return float(b)
    if s.get("chaotic"):
        return float("nan")   # its replicates are independent draws: their mean is no bias (:func:`draws`)
    return jackknife(s.get("value", float("nan")), replicates_of(s))[1]


def paired_bias(x: dict, ref: dict) -> float:
    """Monte Carlo bias of ``x.value - ref.value``: the paired jackknife's when both come from one
    ground truth, else the difference of the two biases."""
    jk = _paired_jackknife(x, ref)
    return jk[1] if jk is not None else bias_of(x) - bias_of(ref)


def paired_se(x: dict, ref: dict) -> float:
    """Standard error of ``x.value - ref.value`` (:func:`paired`)."""
    return paired(x, ref)[0]


def dof_of(s: dict) -> float:
    """A stored score's degrees of freedom (1 for scores stored before they were recorded)."""
    d = s.get("dof")
    return float(d) if finite(d) and d > 0 else 1.0


# ----------------------------------------------------------------------------- two measurements
ALPHA = 0.01           # false-alarm rate per score of the regression check and of ``compare``
ROUNDING_ABS = 1e-5    # float32 rounding of a score: never a change (absolute, in the metric's unit)
ROUNDING_REL = 1e-4    # ... and relative to the score


def rounding(value: float) -> float:
    """The change a score can show from float32 rounding alone."""
    return ROUNDING_ABS + ROUNDING_REL * (abs(value) if finite(value) else 0.0)


def change(a: float, b: float, sd: float, dof: float, *, n_a: int = 1, alpha: float = ALPHA) -> dict:
    """Whether ``b`` differs from ``a`` beyond Monte Carlo noise: ``a`` the mean of ``n_a``
    independent measurements, ``b`` one more, each with standard deviation ``sd`` (estimated on
    ``dof`` degrees of freedom).  ``|b - a| > t_{1 - alpha/2}(dof) * sd * sqrt(1 + 1/n_a)`` plus
    the float32 rounding floor (:func:`rounding`) is a change.  Returns ``{"limit", "changed"}``;
    ``changed`` is None when ``sd`` is unknown (then only a change beyond rounding, with no
    noise estimate, counts; the caller says so)."""
    fl = rounding(a)
    if not (finite(a) and finite(b)):
        return {"limit": float("nan"), "changed": None}
    if not finite(sd) or not dof or dof < 1:
        return {"limit": fl, "changed": None}
    lim = t_quantile(dof, 1 - alpha / 2) * sd * math.sqrt(1 + 1 / max(n_a, 1)) + fl
    return {"limit": lim, "changed": abs(b - a) > lim}


def pooled_sd(*parts) -> tuple[float, float]:
    """``(sd, dof)`` of one measurement from several independent estimates of its variance,
    given as ``(sd_k, dof_k)``: ``sd^2 = sum dof_k sd_k^2 / sum dof_k`` on ``sum dof_k`` degrees of
    freedom (NaN, 0 when none is finite)."""
    ok = [(s, d) for s, d in parts if finite(s) and finite(d) and d > 0]
    if not ok:
        return float("nan"), 0.0
    dof = sum(d for _, d in ok)
    return math.sqrt(sum(d * s * s for s, d in ok) / dof), dof
