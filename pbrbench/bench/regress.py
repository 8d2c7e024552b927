"""Baselines and regression checks.

A baseline file ``tests/baselines/<quality>.json`` holds, per (task, scene, condition,
algorithm, metric), what :data:`N_SEEDS` runs with independent *render* seeds (every scene's
``render.seed`` offset by 0, 1, 2, ...: ``pbrbench run --render-seed``) and job seeds measured:

* ``value``: the mean over the seeds; ``values``: each seed's value;
* ``sd`` and ``dof``: the standard deviation of *one* run's score, pooled from the spread over the
  seeds (``N_SEEDS - 1`` degrees of freedom) and every seed's own jackknife standard error
  (``G - 1`` each, :mod:`pbrbench.uncertainty`);
* the direction of improvement, the scene hashes and the algorithm versions.

A new score ``v`` (with its own jackknife standard error) is checked with
:func:`pbrbench.uncertainty.change`: its standard deviation pooled once more with the new run's
own estimate, it *changed* when ``|v - value| > t_{1 - alpha/2}(dof) * sd * sqrt(1 + 1/N_SEEDS)``
plus the float32 rounding floor, ``alpha`` = :data:`pbrbench.uncertainty.ALPHA` (the false-alarm
rate per score when only the render seeds changed).  It *regresses* when it moved in the worse
direction (a value that became NaN counts as a regression), *improved* the other way (a hint to
run ``pbrbench run --update-baselines``).  The check fails (:attr:`Comparison.ok`) on a
regression beyond the family-wise limit (``alpha`` / number of scores, Bonferroni) or on more
per-score regressions than chance gives at ``alpha`` (the 99.9th percentile of a binomial count):
the per-score flags find a moderate change of one score, the family-wise rule keeps a re-seeded
run with unchanged code from failing.  Scores whose replicates are bimodal (a discrete choice
flipped: :func:`pbrbench.uncertainty.unstable`) in the baseline or the run are listed apart as
``unstable``, never as regressions: a flip is not a code change.

``pbrbench compare`` uses the same rule for two runs (``n_a = 1``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from pbrbench.quality import Quality
from pbrbench.uncertainty import ALPHA, change, dof_of, finite, pooled_sd, rounding, unstable

N_SEEDS = 4
FORMAT = 2
KEY_FIELDS = ("task", "scene", "condition", "algorithm", "metric")


def score_key(s: dict) -> str:
    return "|".join(str(s.get(f, "")) for f in KEY_FIELDS)


def _val(x) -> float:
    return float("nan") if x is None else float(x)


def _unc(s: dict) -> float | None:
    u = s.get("uncertainty")
    return float(u) if u is not None and math.isfinite(float(u)) else None


def _sig(x: float) -> float:
    """Rounded to 6 significant digits (the baseline file stays small and diffs stay readable)."""
    return float(f"{x:.6g}") if finite(x) else None


def build_baselines(runs: list[list[dict]], *, quality: Quality, seeds: list, note: str = "") -> dict:
    """Baselines from the scores of several runs with independent render seeds (module docstring)."""
    if not runs:
        raise ValueError("runs: need the scores of at least one run; pass one list of score dicts per seed")
    by_run = [{score_key(s): s for s in r} for r in runs]
    entries, hashes, versions = {}, {}, {}
    for key, s in sorted(by_run[0].items()):
        ss = [b[key] for b in by_run if key in b]
        vals = [_val(x["value"]) for x in ss]
        fin = [v for v in vals if math.isfinite(v)]
        n = len(fin)
        mean = sum(fin) / n if n else float("nan")
        within = [(_unc(x), dof_of(x)) for x in ss if _unc(x) is not None]
        parts = list(within)
        between = None
        if n > 1:
            between = sum((v - mean) ** 2 for v in fin) / (n - 1)
            parts.append((math.sqrt(between), n - 1))
        sd, dof = pooled_sd(*parts)
        flips = any(unstable_of(x) for x in ss) or (n != len(vals) and n > 0) or _spread_too_wide(between, n, within, mean)
        if flips and between is not None and finite(sd):
            sd = max(sd, math.sqrt(between))
        e = {"value": _sig(mean) if n == len(vals) else None, "sd": _sig(sd), "dof": round(dof, 2),
             "n_seeds": len(vals)}
        if s.get("better", "lower") != "lower":
            e["better"] = s["better"]
        if flips:
            e["unstable"] = True
        entries[key] = e
        if s.get("scene_hash"):
            hashes[s["scene"]] = s["scene_hash"][:16]
        if s.get("algorithm_version"):
            versions[f"{s['task']}/{s['algorithm']}"] = s["algorithm_version"]
    # bimodality is a property of a pipeline on a job's inputs, not of one metric: every metric of an
    # algorithm on a (scene, condition) where one of them is unstable is unstable
    flipped = {tuple(k.split("|")[:4]) for k, e in entries.items() if e.get("unstable")}
    for k, e in entries.items():
        if tuple(k.split("|")[:4]) in flipped:
            e["unstable"] = True
    return {"format": FORMAT, "quality": quality.name, "seeds": list(seeds), "scene_hashes": hashes,
            "algorithm_versions": versions,
            "method": (f"value = mean over {len(runs)} runs with independent render seeds; sd = one run's standard "
                       "deviation pooled from the spread over the seeds and each run's jackknife standard error; a "
                       "score changed when |new - value| > t(1 - alpha/2, dof) * sd * sqrt(1 + 1/n_seeds) + float32 "
                       "rounding (pbrbench.uncertainty.change)"),
            "note": note, "entries": entries,
            "fields": "entries: 'task|scene|condition|algorithm|metric' -> value (mean over the seeds), sd and dof "
                      "(one run's noise), n_seeds, better (when not 'lower'), unstable (when the replicates were "
                      "bimodal); scene_hashes: the first 16 hex digits of each scene's content hash"}


SPREAD_ALPHA = 1e-3   # the spread over the seeds is wider than the jackknife allows at this level: bimodal


def _spread_too_wide(between, n: int, within, mean: float = 0.0) -> bool:
    """Whether the variance of the score over ``n`` render seeds exceeds what the runs' own
    jackknife variances predict (an F test at :data:`SPREAD_ALPHA`): the score jumps between
    render seeds in a way no run's replicates see (a discrete choice that differs between renders
    but not between one render's sample groups)."""
    if between is None or n < 2 or not within or math.sqrt(between) <= rounding(mean):
        return False     # spreads of float32 rounding are never a jump
    w = [(se, d) for se, d in within if finite(se) and d > 0]
    if not w:
        return False
    mean_within = sum(se * se for se, _ in w) / len(w)
    dof_w = sum(d for _, d in w)
    if mean_within <= 0:
        return True      # noise-free runs that still differ beyond rounding
    from scipy import stats

    return between / mean_within > float(stats.f.ppf(1 - SPREAD_ALPHA, n - 1, dof_w))


def unstable_of(s: dict) -> bool:
    """Whether a stored score's replicates are bimodal (:func:`pbrbench.uncertainty.unstable`)."""
    u = s.get("unstable")
    if u is not None:
        return bool(u)
    from pbrbench.uncertainty import replicates_of

    return bool(unstable(replicates_of(s)))


def write_baselines(data: dict, path: str | os.PathLike) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=0, sort_keys=True, separators=(",", ":")) + "\n")
    os.replace(tmp, p)
    return p


def load_baselines(path: str | os.PathLike) -> dict | None:
    p = Path(path)
    if not p.is_file():
        return None
    data = json.loads(p.read_text())
    if data.get("format") != FORMAT:
        from pbrbench.errors import UserError

        raise UserError(f"{p}: baseline format {data.get('format')!r}, expected {FORMAT}; regenerate it with "
                        "`pbrbench run --update-baselines`")
    return data


@dataclass(frozen=True)
class Change:
    """A score that moved beyond its tolerance."""

    task: str
    scene: str
    condition: str
    algorithm: str
    metric: str
    old: float
    new: float
    tolerance: float
    better: str
    kind: str  # "regression", "improvement" or "unstable"
    scene_changed: bool = False  # the scene's content hash differs from the baseline's

    def __str__(self) -> str:
        return (f"{self.kind}: {self.task} / {self.scene} / {self.condition} / {self.algorithm} / {self.metric}: "
                f"old {self.old:.6g}, new {self.new:.6g}, limit {self.tolerance:.3g} ({self.better} is better)"
                + (" [the scene file changed since the baseline, or its render seed]" if self.scene_changed else ""))


@dataclass
class Comparison:
    regressions: list[Change]
    improvements: list[Change]
    missing: list[str]       # baseline keys the run did not produce (only for tasks it ran)
    new: list[str]           # scores without a baseline
    n_checked: int
    version_changed: list[str] = field(default_factory=list)  # algorithms whose version differs
    unstable: list[Change] = field(default_factory=list)  # beyond the limit, but the replicates are bimodal
    no_noise: int = 0        # scores compared without a noise estimate (only a change beyond rounding counts)
    strong: list[Change] = field(default_factory=list)    # regressions beyond the family-wise limit

    @property
    def expected_false(self) -> float:
        """Regressions expected by chance alone: ``n_checked * alpha / 2`` (one direction)."""
        return self.n_checked * ALPHA / 2

    @property
    def allowed(self) -> int:
        """The most regressions chance gives (the 99.9th percentile of Binomial(n, alpha / 2))."""
        if not self.n_checked:
            return 0
        from scipy import stats

        return int(stats.binom.ppf(0.999, self.n_checked, ALPHA / 2))

    @property
    def ok(self) -> bool:
        """No regression beyond the family-wise limit (Bonferroni over every score checked), and
        no more per-score regressions than chance gives (:attr:`allowed`): a re-seeded run with
        unchanged code passes with probability about 99 %, a real regression of many scores or a
        large one of a few fails."""
        return not self.strong and len(self.regressions) <= self.allowed


def judge(old: float, cur: float, *, sd_old: float, dof_old: float, sd_cur: float, dof_cur: float, better: str,
          n_old: int = 1, unstable: bool = False, rel: float = 0.0, alpha: float = ALPHA) -> tuple[str, float, bool]:
    """The one comparator of two scores (``pbrbench compare`` and the regression check).

    ``old`` is the mean of ``n_old`` measurements with standard deviation ``sd_old`` (on
    ``dof_old`` degrees of freedom), ``cur`` one measurement with ``sd_cur``.  The pooled standard
    deviation gives the limit of :func:`pbrbench.uncertainty.change` (plus the float32 rounding
    floor and ``rel * |old|``): within it the scores are ``"same"``; beyond it ``"better"`` or
    ``"worse"`` by the direction ``better``, or ``"unstable"`` when either side's replicates were
    bimodal.  Both NaN is the same; NaN on one side only is worse (NaN now) or better (NaN before).
    Returns ``(direction, limit, noise_known)``; without a noise estimate only a change beyond the
    rounding floor (and ``rel``) counts, and ``noise_known`` is False."""
    if math.isnan(old) and math.isnan(cur):
        return "same", float("nan"), True
    if math.isnan(old) or math.isnan(cur):
        return ("better" if math.isnan(old) else "worse"), float("nan"), True
    sd, dof = pooled_sd((sd_old, dof_old), (sd_cur, dof_cur))
    test = change(old, cur, sd, dof, n_a=n_old, alpha=alpha)
    limit = test["limit"] + rel * abs(old)
    noise_known = test["changed"] is not None
    if cur == old or abs(cur - old) <= (limit if finite(limit) else rounding(old) + rel * abs(old)):
        return "same", limit, noise_known
    if unstable:
        return "unstable", limit, noise_known
    worse = cur > old if better == "lower" else cur < old
    return ("worse" if worse else "better"), limit, noise_known


def compare(scores: list[dict], baselines: dict | None) -> Comparison:
    """Check ``scores`` (dicts with the key fields, value, better) against ``baselines``."""
    entries = (baselines or {}).get("entries", {})
    hashes = (baselines or {}).get("scene_hashes", {})
    versions = (baselines or {}).get("algorithm_versions", {})
    regs, imps, unst, new, strong = [], [], [], [], []
    no_noise = 0
    seen = set()
    n_all = max(1, sum(1 for s in scores if score_key(s) in entries))
    alpha_fw = 0.01 / n_all     # family-wise 1 % over every score checked (Bonferroni)
    changed_versions: dict[str, None] = {}
    for s in scores:
        key = score_key(s)
        b = entries.get(key)
        if b is None:
            new.append(key)
            continue
        seen.add(key)
        bv = versions.get(f"{s['task']}/{s['algorithm']}")
        if bv and s.get("algorithm_version") and bv != s["algorithm_version"]:
            changed_versions.setdefault(f"{s['task']}/{s['algorithm']}: {bv} -> {s['algorithm_version']}")
        old, cur = _val(b["value"]), _val(s["value"])
        sd_old, dof_old = _val(b.get("sd")), float(b.get("dof") or 0)
        sd_cur, dof_cur = _unc(s) or float("nan"), dof_of(s)
        better = b.get("better", "lower")     # the compact baseline format leaves out "lower"
        n_old = int(b.get("n_seeds") or 1)
        direction, tol, noise_known = judge(old, cur, sd_old=sd_old, dof_old=dof_old, sd_cur=sd_cur, dof_cur=dof_cur,
                                            better=better, n_old=n_old,
                                            unstable=bool(b.get("unstable") or unstable_of(s)))
        if not noise_known and not (math.isnan(old) or math.isnan(cur)):
            no_noise += 1
        kind = {"worse": "regression", "better": "improvement", "unstable": "unstable"}.get(direction)
        if kind:
            bh = hashes.get(s["scene"], "")
            changed = bool(bh) and bool(s.get("scene_hash")) and not s["scene_hash"].startswith(bh)
            ch = Change(*(str(s.get(f, "")) for f in KEY_FIELDS), old=old, new=cur, tolerance=tol, better=better,
                        kind=kind, scene_changed=changed)
            {"regression": regs, "improvement": imps, "unstable": unst}[kind].append(ch)
            if kind == "regression" and (math.isnan(cur) or judge(
                    old, cur, sd_old=sd_old, dof_old=dof_old, sd_cur=sd_cur, dof_cur=dof_cur, better=better,
                    n_old=n_old, alpha=alpha_fw)[0] != "same"):
                strong.append(ch)
    tasks = {s["task"] for s in scores}
    missing = sorted(k for k in entries if k.split("|", 1)[0] in tasks and k not in seen)
    return Comparison(regs, imps, missing, new, len(seen), list(changed_versions), unst, no_noise, strong)
