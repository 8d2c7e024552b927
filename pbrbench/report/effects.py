"""The headline of a run: for each task and algorithm, the metric under the reference condition
and the cost of each effect, with standard errors.

* **Matched scenes.** A condition's cost is averaged over the scenes scored under both it and the
  reference condition, a twin counting as its base scene (``ps_cup_area[albedo=0.5]`` matches
  ``ps_cup[albedo=0.5]``; ``sfs_vase_area:view`` matches ``sfs_vase:view``).  Every cell says how
  many scenes it averages.
* **Cost of an effect** = mean over matched scenes of ``value(condition) - value(reference)``, in
  the metric's own units (positive = worse for a lower-is-better metric).
* **Standard errors.** Per scene, the paired standard error of the difference
  (:func:`pbrbench.bench.uncertainty.paired_se`: from the paired half-sample replicates when both
  come from one render, else independent); the mean over ``n`` independently rendered scenes has
  ``SE = sqrt(sum SE_s^2) / n``.  A cost within two standard errors of zero is *not significant*
  (shown greyed); a cell without an uncertainty estimate is never called significant.
* **Geometry.** Where the interreflection condition's (``global``) matched scenes include both
  convex scenes (tag ``convex``: no part can see another) and scenes with concavities (tag
  ``concave``), its cost is also given for each group: interreflection can only cost something
  where the surface sees itself.

Only the stored scores are read; nothing is recomputed.
"""

from __future__ import annotations

import re
from collections import defaultdict

from pbrbench.uncertainty import finite, mean_se, paired_se, significant

SPLIT_BASES = ("global",)   # conditions whose cost depends on whether a surface sees itself


def match_key(scene: str) -> str:
    """The scene a twin stands for: ``family_area[...]`` -> ``family[...]`` (also with ``:label``)."""
    return re.sub(r"_area(?=$|[\[:])", "", scene, count=1)


def base_scene(scene: str) -> str:
    """The ground truth a score label comes from (``sfs_vase:view`` -> ``sfs_vase``)."""
    return scene.split(":", 1)[0]


# a cost smaller than this fraction of the reference value is float32 rounding of one pipeline run
# twice on identical inputs (a convex scene's global and local images agree to ~1e-7), never an effect
ROUNDING = 1e-6


def cell(value: float, se: float, n: int, *, effect: bool, reference: float = 0.0) -> dict:
    sig = significant(value, se, ROUNDING * abs(reference) if finite(reference) else 0.0) if effect else None
    return {"value": value, "se": se, "n": n, "effect": effect, "significant": sig,
            "insignificant": sig is False}


def effect_tables(scores: list[dict], info: dict, geometry: dict[str, str] | None = None) -> list[dict]:
    """Per task: ``{"task", "metric", "better", "unit", "reference", "columns", "rows",
    "noise_floor", "partial"}``; ``rows``: ``[{"algorithm", "cells": [cell per column]}]``;
    ``partial``: algorithms with no score under the reference (run on a subset of scenes and
    conditions), each condition's mean ``beside`` every algorithm scored on all the same scenes
    (``[{"algorithm", "condition", "scenes", "value", "se", "n", "beside": [...]}]``); ``geometry``:
    scene -> "convex" / "concave" (from the scene files' tags)."""
    geometry = geometry or {}
    by_task = defaultdict(list)
    for s in scores:
        by_task[s["task"]].append(s)
    out = []
    for task in sorted(by_task, key=lambda t: (list(info).index(t) if t in info else 99, t)):
        ti = info.get(task, {})
        metric = ti.get("headline_metric") or sorted({s["metric"] for s in by_task[task]})[0]
        rows = [s for s in by_task[task] if s["metric"] == metric and finite(s.get("value"))]
        if not rows:
            continue
        order = ti.get("conditions") or sorted({s["condition"] for s in rows})
        present = {s["condition"] for s in rows}
        ref = ti.get("reference_condition")
        if ref not in present:
            ref = next((c for c in order if c in present), sorted(present)[0])
        conds = [c for c in order if c in present and c != ref] + sorted(present - set(order) - {ref})
        alg_order = ti.get("algorithms") or []
        algs = sorted({s["algorithm"] for s in rows},
                      key=lambda a: (alg_order.index(a) if a in alg_order else len(alg_order), a))
        at = defaultdict(dict)   # (algorithm, condition) -> match key -> score
        for s in rows:
            at[(s["algorithm"], s["condition"])][match_key(s["scene"])] = s
        columns = [{"label": ref, "condition": ref, "group": None, "effect": False}]
        for c in conds:
            keys = set().union(*(at[(a, c)].keys() & at[(a, ref)].keys() for a in algs))
            groups = sorted({geometry.get(base_scene(k), "") for k in keys} - {""})
            columns.append({"label": f"{c} − {ref}", "condition": c, "group": None, "effect": True})
            if len(groups) > 1 and c.split("+")[0] in SPLIT_BASES and ref.split("+")[0] not in SPLIT_BASES:
                columns += [{"label": f"{c} − {ref} ({g})", "condition": c, "group": g, "effect": True} for g in groups]
        table, partial = [], []
        for a in algs:
            base = at[(a, ref)]
            if not base:   # run on a subset only (e.g. an expensive method): beside the others on its scenes
                for c in conds:
                    mine = at[(a, c)]
                    if not mine:
                        continue
                    keys = sorted(mine)
                    m, se = mean_se([mine[k]["value"] for k in keys], [mine[k].get("uncertainty") for k in keys])
                    beside = []
                    for b in algs:
                        theirs = at[(b, c)]
                        if b != a and all(k in theirs for k in keys):
                            bm, bse = mean_se([theirs[k]["value"] for k in keys],
                                              [theirs[k].get("uncertainty") for k in keys])
                            beside.append({"algorithm": b, **cell(bm, bse, len(keys), effect=False)})
                    partial.append({"algorithm": a, "condition": c, "scenes": keys,
                                    **cell(m, se, len(keys), effect=False), "beside": beside})
                continue
            cells = []
            for col in columns:
                if not col["effect"]:
                    vals = list(base.values())
                    m, se = mean_se([s["value"] for s in vals], [s.get("uncertainty") for s in vals])
                    cells.append(cell(m, se, len(vals), effect=False))
                    continue
                other = at[(a, col["condition"])]
                keys = sorted(k for k in other.keys() & base.keys()
                              if col["group"] is None or geometry.get(base_scene(k)) == col["group"])
                if not keys:
                    cells.append(None)
                    continue
                m, se = mean_se([other[k]["value"] - base[k]["value"] for k in keys],
                                [paired_se(other[k], base[k]) for k in keys])
                ref_mean = sum(base[k]["value"] for k in keys) / len(keys)
                cells.append(cell(m, se, len(keys), effect=True, reference=ref_mean))
            table.append({"algorithm": a, "cells": cells})
        ses = sorted(s["uncertainty"] for s in rows if s["condition"] == ref and finite(s.get("uncertainty")))
        floor = ses[len(ses) // 2] if ses else float("nan")
        out.append({"task": task, "metric": metric, "better": rows[0].get("better", "lower"),
                    "unit": rows[0].get("unit", ""), "reference": ref, "columns": columns, "rows": table,
                    "noise_floor": floor, "description": ti.get("description", ""), "notes": ti.get("notes", ""),
                    "partial": partial})
    return out


def format_cell(c: dict | None, digits: int = 3) -> str:
    """``1.23 ± 0.05`` (``+`` sign for effects); ``–`` for an empty cell."""
    if c is None or not finite(c["value"]):
        return "–"
    v = f"{c['value']:+.{digits}g}" if c["effect"] else f"{c['value']:.{digits}g}"
    return v + (f" ± {c['se']:.2g}" if finite(c["se"]) else "")
