"""Baselines and regression checks.

A baseline file ``tests/baselines/<quality>.json`` holds, per (task, scene, condition,
algorithm, metric), the value of a reference run, the direction of improvement and a
tolerance.  The tolerance is *measured*, not guessed:

    the benchmark is run with :data:`N_SEEDS` different seeds (``seed``, ``seed + 1``, ...);
    ``spread`` = max - min of the metric over those runs;
    ``tolerance = max(K * spread, ABS_FLOOR + REL_FLOOR * |value|)``.

``K = 3`` leaves room for seeds that were not sampled; the floor (1e-6 absolute plus 0.1 %
relative) only covers floating-point differences between machines (BLAS, compilers) for
metrics that do not depend on the seed at all (the ground truth is bit-reproducible: box
filter and fixed render seed, docs/rendering.md).  The value kept is that of the run with the
base seed, which the regression suite reproduces.

Each entry also records the score's standard error when the baseline was measured
(``uncertainty``: Monte Carlo noise of the render plus the input-noise seed,
:mod:`pbrbench.bench.uncertainty`).  A comparison allows at least ``2 * sqrt(u_base^2 + u_new^2)``
(:data:`pbrbench.uncertainty.SIGNIFICANCE` combined standard errors): a change smaller than the
noise of the two measurements is not a change.

A score *regresses* when it moved in the worse direction by more than its tolerance (a value
that became NaN counts as a regression); it *improved* when it moved the other way by more than
the tolerance (a hint to run ``pbrbench run --update-baselines``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from pbrbench.uncertainty import SIGNIFICANCE, combined_se

K = 3.0
ABS_FLOOR = 1e-6
REL_FLOOR = 1e-3
N_SEEDS = 3
FORMAT = 1
KEY_FIELDS = ("task", "scene", "condition", "algorithm", "metric")


def baseline_path(quality: str, settings=None) -> Path | None:
    """``<baselines>/<quality>.json`` of the ``baselines`` setting (None without one)."""
    from pbrbench.settings import Settings

    return (settings or Settings.from_env()).baseline_path(quality)


def score_key(s: dict) -> str:
    return "|".join(str(s.get(f, "")) for f in KEY_FIELDS)


def _val(x) -> float:
    return float("nan") if x is None else float(x)


def _unc(s: dict) -> float | None:
    u = s.get("uncertainty")
    return float(u) if u is not None and math.isfinite(float(u)) else None


def tolerance(value: float, spread: float) -> float:
    floor = ABS_FLOOR + REL_FLOOR * (abs(value) if math.isfinite(value) else 0.0)
    return max(K * spread, floor)


def build_baselines(runs: list[list[dict]], *, quality: str, seeds: list[int], note: str = "") -> dict:
    """Baselines from the scores of several runs with different seeds; ``runs[0]`` is the reference."""
    if not runs:
        raise ValueError("runs: need the scores of at least one run; pass one list of score dicts per seed")
    by_run = [{score_key(s): s for s in r} for r in runs]
    entries = {}
    for key, s in sorted(by_run[0].items()):
        vals = [_val(b[key]["value"]) for b in by_run if key in b]
        finite = [v for v in vals if math.isfinite(v)]
        spread = (max(finite) - min(finite)) if len(finite) > 1 else 0.0
        value = _val(s["value"])
        entries[key] = {**{f: s.get(f, "") for f in KEY_FIELDS}, "scene_hash": s.get("scene_hash", ""),
                        "algorithm_version": s.get("algorithm_version", ""),
                        "uncertainty": _unc(s),
                        "value": value if math.isfinite(value) else None,
                        "better": s.get("better", "lower"), "spread": spread, "n_seeds": len(vals),
                        "tolerance": tolerance(value, spread)}
    return {"format": FORMAT, "quality": quality, "seeds": list(seeds),
            "method": (f"tolerance = max({K:g} * spread over {len(runs)} seeds, {ABS_FLOOR:g} + {REL_FLOOR:g} * |value|); "
                       "spread = max - min over the seeds; value and uncertainty (one standard error) from the first "
                       f"seed; a comparison allows at least {SIGNIFICANCE:g} * sqrt(u_base^2 + u_new^2)"),
            "note": note, "entries": entries}


def write_baselines(data: dict, path: str | os.PathLike) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
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
    kind: str  # "regression" or "improvement"
    scene_changed: bool = False  # the scene's content hash differs from the baseline's

    def __str__(self) -> str:
        return (f"{self.kind}: {self.task} / {self.scene} / {self.condition} / {self.algorithm} / {self.metric}: "
                f"old {self.old:.6g}, new {self.new:.6g}, tolerance {self.tolerance:.3g} ({self.better} is better)"
                + (" [the scene file changed since the baseline]" if self.scene_changed else ""))


@dataclass
class Comparison:
    regressions: list[Change]
    improvements: list[Change]
    missing: list[str]       # baseline keys the run did not produce (only for tasks it ran)
    new: list[str]           # scores without a baseline
    n_checked: int
    version_changed: list[str] = field(default_factory=list)  # algorithms whose version differs

    @property
    def ok(self) -> bool:
        return not self.regressions


def compare(scores: list[dict], baselines: dict | None) -> Comparison:
    """Check ``scores`` (dicts with the key fields, value, better) against ``baselines``."""
    entries = (baselines or {}).get("entries", {})
    regs, imps, new = [], [], []
    seen = set()
    changed_versions: dict[str, None] = {}
    for s in scores:
        key = score_key(s)
        b = entries.get(key)
        if b is None:
            new.append(key)
            continue
        seen.add(key)
        if b.get("algorithm_version") and s.get("algorithm_version") and b["algorithm_version"] != s["algorithm_version"]:
            changed_versions.setdefault(f"{s['task']}/{s['algorithm']}: {b['algorithm_version']} -> {s['algorithm_version']}")
        old, cur = _val(b["value"]), _val(s["value"])
        tol = float(b["tolerance"])
        ub, un = b.get("uncertainty"), _unc(s)
        if ub is not None and un is not None:
            tol = max(tol, SIGNIFICANCE * combined_se(ub, un))
        better = b.get("better", s.get("better", "lower"))
        kind = None
        if math.isnan(old):
            kind = None if math.isnan(cur) else "improvement"
        elif math.isnan(cur):
            kind = "regression"
        else:
            delta = cur - old if better == "lower" else old - cur  # > 0: worse
            if delta > tol:
                kind = "regression"
            elif delta < -tol:
                kind = "improvement"
        if kind:
            changed = bool(b.get("scene_hash")) and bool(s.get("scene_hash")) and b["scene_hash"] != s["scene_hash"]
            ch = Change(*(str(s.get(f, "")) for f in KEY_FIELDS), old=old, new=cur, tolerance=tol, better=better,
                        kind=kind, scene_changed=changed)
            (regs if kind == "regression" else imps).append(ch)
    tasks = {s["task"] for s in scores}
    missing = sorted(k for k, b in entries.items() if b["task"] in tasks and k not in seen)
    return Comparison(regs, imps, missing, new, len(seen), list(changed_versions))
