"""The headline of a run: for each task and algorithm, the metric under the reference condition
and the cost of each effect, with standard errors.

* **Matched scenes.** A condition's cost is averaged over the scenes scored under both it and the
  reference condition, a twin counting as its base scene (``ps_cup_area[albedo=0.5]`` matches
  ``ps_cup[albedo=0.5]``; ``sfs_vase_area:view`` matches ``sfs_vase:view``).  Every cell says how
  many scenes it averages.
* **Cost of an effect** = mean over matched scenes of ``value(condition) - value(reference)``, in
  the metric's own units (positive = worse for a lower-is-better metric).
* **Standard errors.** Per scene, the paired jackknife standard error of the difference
  (:func:`pbrbench.uncertainty.paired`: from the paired delete-one-group replicates when both
  come from one render, else independent); the mean over ``n`` independently rendered scenes has
  ``SE = sqrt(sum SE_s^2) / n`` on Welch-Satterthwaite degrees of freedom.  A cost inside the 95 %
  Student-t interval of zero is *not significant* (shown greyed); a cell without an uncertainty
  estimate is never called significant.
* **Monte Carlo bias.** Every cell also carries the mean of its scores' bias estimates
  (:func:`pbrbench.uncertainty.jackknife`); a cell whose ``|bias|`` exceeds its standard error is
  *noise-limited* (``noise_limited``) and shows the bias-corrected value ``value - bias`` beside it,
  unless a score's corrected value would fall below the metric's smallest value
  (:data:`METRIC_LOWER_BOUND`: a negative RMSE): then the bias is not first order in 1/spp (the
  delete-one-group replicates all sit far from the full-sample score, as when a calibration
  settles differently with fewer samples), the correction is withheld (``corrected`` NaN,
  ``correction_fails``) and the cell says so.
* **Bimodal replicates.** A cell any of whose scores has bimodal replicates (a discrete choice of
  the pipeline flipped between them: :func:`pbrbench.uncertainty.unstable`) is ``unstable``: its
  ± would average a flip, so it is never called significant.
* **Geometry.** Where the interreflection condition's (``global``) matched scenes include both
  convex scenes (tag ``convex``: no part can see another) and scenes with concavities (tag
  ``concave``), its cost is also given for each group: interreflection can only cost something
  where the surface sees itself.
* **Scene classes.** A task whose scenes fall into classes that a single mean would blur (the
  interreflection task: a white room and a black room, grooves at each albedo, ...) gets one row
  group per class (``classes``: scene -> class), each cell the mean ± SE over that class's
  matched scenes alone; such a table has no convex / concave split.  A task may also show a
  condition's own mean beside its cost (``values``: interreflection's error against what the
  camera sees).

Only the stored scores are read; nothing is recomputed.
"""

from __future__ import annotations

import re
from collections import defaultdict

from pbrbench.uncertainty import bias_of, dof_of, finite, mean_se, paired, paired_bias, significant

SPLIT_BASES = ("global",)   # conditions whose cost depends on whether a surface sees itself


def match_key(scene: str) -> str:
    """The scene a twin stands for: ``family_area[...]`` -> ``family[...]`` (also with ``:label``)."""
    return re.sub(r"_area(?=$|[\[:])", "", scene, count=1)


def base_scene(scene: str) -> str:
    """The ground truth a score label comes from (``sfs_vase:view`` -> ``sfs_vase``)."""
    return scene.split(":", 1)[0]


# the smallest value of every metric (pbrbench.metrics: errors, fractions and counts; a metric's
# ``lower``): a bias-corrected score below it is not a correction (tests/report check the tables)
METRIC_LOWER_BOUND = 0.0

# a cost smaller than this fraction of the reference value is float32 rounding of one pipeline run
# twice on identical inputs (a convex scene's global and local images agree to ~1e-7), never an effect
ROUNDING = 1e-6


def cell(value: float, se: float, n: int, *, effect: bool, reference: float = 0.0, dof: float = 0.0,
         bias: float = float("nan"), unstable: bool = False, correctable: bool = True, chaotic: int = 0) -> dict:
    """One headline cell: value, standard error, dof, scenes, bias, and the flags the report shows;
    ``correctable`` False withholds the bias-corrected value (module docstring); ``chaotic`` the
    number of its scores chaotic in their input (:func:`pbrbench.uncertainty.chaotic`: their ±
    from independent draws, no bias estimate)."""
    sig = significant(value, se, ROUNDING * abs(reference) if finite(reference) else 0.0, dof=dof or None) \
        if effect and not unstable else None
    # a bimodal cell's jackknife bias averages a flip: it is not shown as a correction
    limited = not unstable and finite(bias) and finite(se) and abs(bias) > se and abs(bias) > ROUNDING * abs(value)
    return {"value": value, "se": se, "dof": dof, "n": n, "effect": effect, "significant": sig,
            "insignificant": sig is False, "bias": bias, "noise_limited": bool(limited),
            "corrected": value - bias if finite(bias) and correctable else float("nan"),
            "correction_fails": bool(limited and not correctable), "unstable": bool(unstable), "chaotic": int(chaotic)}


def _correctable(scores: list[dict]) -> bool:
    """Whether every score's bias-corrected value stays at or above :data:`METRIC_LOWER_BOUND`."""
    biases = ((s["value"], bias_of(s)) for s in scores)
    return all(v - b >= METRIC_LOWER_BOUND for v, b in biases if finite(b))


def summary(scores: list[dict], *, effect: bool = False, reference: float = 0.0) -> dict:
    """The cell of the mean of independent scores (``effect`` False) ."""
    m, se, dof = mean_se([s["value"] for s in scores], [s.get("uncertainty") for s in scores],
                         [dof_of(s) for s in scores])
    biases = [bias_of(s) for s in scores]
    bias = sum(biases) / len(biases) if biases and all(finite(b) for b in biases) else float("nan")
    return cell(m, se, len(scores), effect=effect, reference=reference, dof=dof, bias=bias,
                unstable=any(s.get("unstable") for s in scores), correctable=_correctable(scores),
                chaotic=sum(bool(s.get("chaotic")) for s in scores))


def difference(others: list[dict], bases: list[dict]) -> dict:
    """The cell of the mean of paired differences ``other - base`` (one pair per scene)."""
    pairs = [paired(o, b) for o, b in zip(others, bases, strict=True)]
    m, se, dof = mean_se([o["value"] - b["value"] for o, b in zip(others, bases, strict=True)],
                         [p[0] for p in pairs], [p[1] for p in pairs])
    biases = [paired_bias(o, b) for o, b in zip(others, bases, strict=True)]
    bias = sum(biases) / len(biases) if all(finite(x) for x in biases) else float("nan")
    ref_mean = sum(b["value"] for b in bases) / len(bases)
    return cell(m, se, len(bases), effect=True, reference=ref_mean, dof=dof, bias=bias,
                unstable=any(s.get("unstable") for s in [*others, *bases]), correctable=_correctable([*others, *bases]),
                chaotic=sum(bool(s.get("chaotic")) for s in [*others, *bases]))


def effect_tables(scores: list[dict], info: dict, geometry: dict[str, str] | None = None,
                  layout: dict | None = None) -> list[dict]:
    """The headline's effect table of each task.

    Parameters
    ----------
    scores : list of dict
        The run's stored scores.
    info : dict
        task -> the stored task information (``headline_metric``, ``conditions``,
        ``reference_condition``, ``algorithms``, ``description``, ``notes``).
    geometry : dict, optional
        scene -> ``"convex"`` / ``"concave"`` (from the scene files' tags).
    layout : dict, optional
        task -> ``{"scene_class": fn, "values": conditions}``, both optional: ``fn`` maps a
        scene name to ``(sort key, class label)``, or None for a scene of no class, and that
        task's rows are grouped by class (groups in the order of the smallest sort key of their
        scenes, then by label; scenes of no class last, as ``other scenes``); ``values`` are
        conditions whose mean itself (not its cost) is also a column, after the costs, over the
        same matched scenes as the cost.

    Returns
    -------
    list of dict
        Per task ``{"task", "metric", "better", "unit", "reference", "columns", "rows", "groups",
        "noise_floor", "description", "notes", "partial"}``: ``rows`` ``[{"algorithm", "group",
        "cells": [cell per column], "subset"}]`` (``group`` the class label, None without classes;
        ``subset`` None, or ``(n, of)`` for an algorithm scored under the reference on ``n`` of the
        ``of`` scenes its row group's algorithms are scored on, whose reference mean is then not
        comparable with the other rows'; a cell also lists the ``scenes`` of its scores; a column ``{"label", "condition", "group",
        "effect", "value"}``, ``value`` True for a column of a condition's own mean); ``groups`` ``[{"label", "scenes"}]`` in row
        order (empty without classes); ``partial`` the algorithms with no score under the
        reference (run on a subset of scenes and conditions), each condition's mean ``beside``
        every algorithm scored on all the same scenes (``[{"algorithm", "condition", "scenes",
        "value", "se", "n", "beside": [...]}]``), and likewise every condition of each ``subset``
        row, the reference included (those lines with ``"ref_n"`` and ``"of"``: the algorithm's and
        all the algorithms' numbers of reference scenes).
    """
    geometry = geometry or {}
    layout = layout or {}
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
        classify = layout.get(task, {}).get("scene_class")
        columns = [{"label": ref, "condition": ref, "group": None, "effect": False, "value": False}]
        for c in conds:
            keys = set().union(*(at[(a, c)].keys() & at[(a, ref)].keys() for a in algs))
            groups = sorted({geometry.get(base_scene(k), "") for k in keys} - {""})
            columns.append({"label": f"{c} − {ref}", "condition": c, "group": None, "effect": True, "value": False})
            if classify is None and len(groups) > 1 and c.split("+")[0] in SPLIT_BASES \
                    and ref.split("+")[0] not in SPLIT_BASES:
                columns += [{"label": f"{c} − {ref} ({g})", "condition": c, "group": g, "effect": True, "value": False}
                            for g in groups]
        columns += [{"label": c, "condition": c, "group": None, "effect": False, "value": True}
                    for c in layout.get(task, {}).get("values", ()) if c in conds]
        all_keys = sorted({match_key(s["scene"]) for s in rows})
        if classify is None:
            row_groups = [(None, all_keys)]
        else:
            found, rank = defaultdict(list), {}   # label -> match keys; label -> its smallest sort key
            for k in all_keys:
                c = classify(base_scene(k))
                label = c[1] if c else None
                found[label].append(k)
                if c:
                    rank[label] = min(rank.get(label, c[0]), c[0])
            row_groups = [(label or "other scenes", found[label])
                          for label in sorted(found, key=lambda g: (g is None, (rank[g], g) if g else ()))]
        table, partial = [], []
        ref_keys = set().union(*(at[(a, ref)].keys() for a in algs))
        for a in algs:
            if not at[(a, ref)]:   # run on a subset only (e.g. an expensive method): beside the others on its scenes
                partial += _beside(a, conds, algs, at)
            elif len(at[(a, ref)]) < len(ref_keys):
                # a row over fewer scenes than the others: its reference mean is not comparable with
                # theirs, so it is also given beside every algorithm scored on its scenes
                partial += [dict(p, of=len(ref_keys), ref_n=len(at[(a, ref)])) for p in _beside(a, [ref] + conds, algs, at)]
        for label, group_keys in row_groups:
            for a in algs:
                base = {k: v for k, v in at[(a, ref)].items() if k in group_keys}
                if not at[(a, ref)] or not base:
                    continue
                cells = []
                for col in columns:
                    if not col["effect"] and not col["value"]:
                        cells.append(dict(summary(list(base.values())), scenes=[v["scene"] for v in base.values()]))
                        continue
                    other = at[(a, col["condition"])]
                    keys = sorted(k for k in other.keys() & base.keys()
                                  if col["group"] is None or geometry.get(base_scene(k)) == col["group"])
                    if not keys:
                        cells.append(None)
                        continue
                    if col["value"]:
                        cells.append(dict(summary([other[k] for k in keys]), scenes=[other[k]["scene"] for k in keys]))
                        continue
                    cells.append(dict(difference([other[k] for k in keys], [base[k] for k in keys]),
                                      scenes=[other[k]["scene"] for k in keys]))
                of = len(ref_keys & set(group_keys))
                table.append({"algorithm": a, "group": label, "cells": cells,
                              "subset": (len(base), of) if len(base) < of else None})
        ses = sorted(s["uncertainty"] for s in rows if s["condition"] == ref and finite(s.get("uncertainty")))
        floor = ses[len(ses) // 2] if ses else float("nan")
        groups = [{"label": label, "scenes": keys} for label, keys in row_groups
                  if label is not None and any(r["group"] == label for r in table)]
        out.append({"task": task, "metric": metric, "better": rows[0].get("better", "lower"),
                    "unit": rows[0].get("unit", ""), "reference": ref, "columns": columns, "rows": table,
                    "groups": groups, "noise_floor": floor, "description": ti.get("description", ""),
                    "notes": ti.get("notes", ""), "partial": partial})
    return out


def _beside(a: str, conds: list[str], algs: list[str], at: dict) -> list[dict]:
    """The lines of an algorithm with no reference score: per condition its mean over its scenes,
    beside every other algorithm scored on all of them."""
    out = []
    for c in conds:
        mine = at[(a, c)]
        if not mine:
            continue
        keys = sorted(mine)
        beside = []
        for b in algs:
            theirs = at[(b, c)]
            if b != a and all(k in theirs for k in keys):
                beside.append({"algorithm": b, **summary([theirs[k] for k in keys])})
        out.append({"algorithm": a, "condition": c, "scenes": keys, **summary([mine[k] for k in keys]),
                    "beside": beside})
    return out


def format_cell(c: dict | None, digits: int = 3) -> str:
    """``1.23 ± 0.05`` (``+`` sign for effects); ``–`` for an empty cell."""
    if c is None or not finite(c["value"]):
        return "–"
    v = f"{c['value']:+.{digits}g}" if c["effect"] else f"{c['value']:.{digits}g}"
    v += f" ± {c['se']:.2g}" if finite(c["se"]) else ""
    if c.get("noise_limited"):
        v += (f" (bias {c['bias']:+.2g}: not first order, no correction)" if c.get("correction_fails") else
              f" (bias {c['bias']:+.2g}: {c['corrected']:.{digits}g} corrected)")
    if c.get("unstable"):
        v += " (bimodal replicates)"
    return v
