"""The HTML report of a run: a small offline site in the run's folder.

``index.html`` (contents, the headline effect tables of every task, failures, the regression
check, the ground truths' noise, the run's details), one page per task (``task-<name>.html``: its
headline, all metrics, per-scene rows, and the figures grouped by scene family and condition),
``history.html`` (the headline metric per task and condition over the stored runs) and, where the
run has chapter figures, ``gallery.html``.  Images are the PNG files the run saved under
``figures/`` (and ``history/``), referenced relatively and loaded lazily; ``style.css`` is copied
beside the pages; nothing refers outside the folder, so it can be zipped and opened anywhere.

It reads only the results store (run metadata, scores, ground-truth noise, history of earlier
runs) and the figures the run saved; it recomputes no score.  Jinja2 autoescaping is on, so scene
names, descriptions, algorithm names and error messages cannot inject markup.
"""

from __future__ import annotations

import json
import math
import re
from collections import defaultdict
from pathlib import Path

TEMPLATE_DIR = Path(__file__).parent / "templates"


# ----------------------------------------------------------------------------- aggregation
def _mean(vals):
    vals = [v for v in vals if v is not None]
    if not vals:
        return float("nan")
    finite = [v for v in vals if math.isfinite(v)]
    return sum(finite) / len(finite) if len(finite) == len(vals) else float("nan")


def _cond_sort_key(c: str, order: list[str]):
    base = c.split("+", 1)[0]
    return (order.index(base) if base in order else len(order), c)


def fmt(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    v = float(v)
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 1e4 or a < 1e-3:
        return f"{v:.2e}"
    return f"{v:.4g}"


def _colour(value, lo, hi, better, log) -> str | None:
    """Background colour of a cell: green (best of the table) .. red (worst)."""
    if value is None or not math.isfinite(value) or not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return None
    if log:
        t = (math.log10(value) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
    else:
        t = (value - lo) / (hi - lo)
    good = 1 - t if better == "lower" else t
    return f"hsl({int(round(120 * good))}, 65%, 82%)"


def task_layout(tasks) -> dict:
    """How the headline lays out each task of ``tasks`` (names) that asks for more than the
    default: task -> ``{"scene_class": fn, "values": conditions}`` (see
    :func:`pbrbench.report.effects.effect_tables`), from its task module's ``scene_class(scene)``
    (a class label or None; :class:`pbrbench.tasks.interreflection.InterreflectionTask`) and
    ``headline_values`` (conditions whose own mean is also shown).  A class's sort key is its
    scene's family's place in the task's families (a class spanning several families sorts with
    its first).  A task that is not a module of :mod:`pbrbench.tasks` (a test's fake) has none."""
    from pbrbench.tasks import get_tasks, task_names

    known = set(task_names())
    out = {}
    for name in tasks:
        task = get_tasks([name])[name] if name in known else None
        fn = getattr(task, "scene_class", None)
        values = tuple(getattr(task, "headline_values", ()) or ())
        lay = {"values": values} if values else {}
        if callable(fn):
            families = list(task.families)

            def classify(scene, fn=fn, families=families):
                label = fn(scene)
                if label is None:
                    return None
                fam = scene.split("[", 1)[0]
                return (families.index(fam) if fam in families else len(families), label)

            lay["scene_class"] = classify
        if lay:
            out[name] = lay
    return out


def headline_tables(scores: list[dict], info: dict, marks: dict | None = None,
                    geometry: dict | None = None, layout: dict | None = None) -> list[dict]:
    """Per task: the effect table of :func:`pbrbench.report.effects.effect_tables` with display
    text, colours and regression markers.  The reference column is coloured green (best) to red
    (worst) across algorithms, as is a column of a condition's own mean (within each row group,
    when the task has scene classes: ``layout``, see :func:`task_layout`), unless its spread is
    within twice its largest standard error (a difference inside the noise is not coloured); an
    effect is red when it costs accuracy significantly, green when it
    helps, and greyed when it is inside the 95 % Student-t interval of zero; a noise-limited cell
    (|bias| > SE) is marked ``biased``, a cell with bimodal replicates ``unstable``.  A grouped
    cell carries the regression marker of a score of its own scenes (``marks`` keyed by
    ``(task, algorithm, condition, scene)``: :func:`markers`)."""
    from pbrbench.report.effects import effect_tables, format_cell

    marks = marks or {}
    out = []
    for t in effect_tables(scores, info, geometry, layout):
        ranges = {}   # (row group, column) -> (lo, hi, log scale) of the colours
        for g in {r["group"] for r in t["rows"]}:
            for i, col in enumerate(t["columns"]):
                if col["effect"]:
                    continue
                cs = [r["cells"][i] for r in t["rows"]
                      if r["group"] == g and r["cells"][i] is not None and not r.get("subset")]
                finite = [c["value"] for c in cs if math.isfinite(c["value"])]
                ses = [c["se"] for c in cs if math.isfinite(c["se"])]
                lo, hi = (min(finite), max(finite)) if finite else (float("nan"), float("nan"))
                if finite and ses and hi - lo <= 2 * max(ses):
                    lo = hi = float("nan")   # a spread inside the noise: not coloured
                ranges[(g, i)] = (lo, hi, bool(finite) and lo > 0 and hi / lo > 10)
        rows = []
        for r in t["rows"]:
            cells = []
            for i, (col, c) in enumerate(zip(t["columns"], r["cells"], strict=True)):
                if c is None:
                    cells.append({"text": "", "value": None, "n": 0, "colour": None, "mark": None, "cls": ""})
                    continue
                if not col["effect"]:
                    colour = None if r.get("subset") else _colour(c["value"], *ranges[(r["group"], i)][:2], t["better"],
                                                                 ranges[(r["group"], i)][2])
                    cls = ""
                else:
                    worse = (c["value"] > 0) == (t["better"] == "lower")
                    colour = None
                    cls = "ns" if c["insignificant"] else ("cost" if c["significant"] and worse else
                                                            "gain" if c["significant"] else "")
                title = f"n = {c['n']} scene(s)" + ("" if col["group"] is None else f", {col['group']}")
                if r.get("subset") and not col["effect"]:
                    title += (f"; scored on {r['subset'][0]} of the {r['subset'][1]} scenes: not coloured against "
                              "the other rows (their means are over other scenes); the lines below the table put "
                              "it beside them on its own scenes")
                if math.isfinite(c.get("dof") or float("nan")) and c.get("dof"):
                    title += f"; {c['dof']:.3g} degrees of freedom"
                if col["effect"]:
                    title += "; " + ("bimodal replicates: not tested" if c.get("unstable") else
                                     "inside the 95 % t interval of zero: not an effect" if c["insignificant"] else
                                     "beyond the 95 % t interval: an effect" if c["significant"] else
                                     "no uncertainty estimate")
                if c.get("noise_limited"):
                    cls = (cls + " biased").strip()
                    title += (f"; noise-limited: the Monte Carlo bias estimate {c['bias']:+.3g} exceeds the standard "
                              + ("error, and the corrected value of a score would fall below the metric's smallest "
                                 "value: the bias is not first order in 1/spp, no correction is given"
                                 if c.get("correction_fails") else f"error, bias-corrected value {c['corrected']:.4g}"))
                if c.get("unstable"):
                    cls = (cls + " unstable").strip()
                if c.get("chaotic"):
                    title += (f"; {c['chaotic']} score(s) chaotic in their input (an iteration stopped before it "
                              "converged: a change far below the render noise moves them): their ± from the "
                              "replicates as independent draws, no bias estimate")
                if r["group"] is None:
                    mark = marks.get((t["task"], r["algorithm"], col["condition"]))
                else:
                    found = {marks.get((t["task"], r["algorithm"], col["condition"], s)) for s in c.get("scenes", ())}
                    mark = "regression" if "regression" in found else "improvement" if "improvement" in found else None
                main, _, note = format_cell(c).partition(" (")
                cells.append({"text": format_cell(c), "main": main, "note": f"({note}" if note else "",
                              "value": c["value"], "se": c["se"], "n": c["n"], "colour": colour,
                              "cls": cls, "title": title, "mark": mark})
            rows.append({"algorithm": r["algorithm"], "group": r["group"], "cells": cells, "subset": r.get("subset")})
        partial = [dict(p, text=format_cell(p), beside=[dict(b, text=format_cell(b)) for b in p["beside"]])
                   for p in t["partial"]]
        out.append(dict(t, conditions=[c["label"] for c in t["columns"]], rows=rows, partial=partial))
    return out


def metric_tables(scores: list[dict]) -> dict[str, dict]:
    """Per task: (algorithm, condition) x metric means, and the per-scene detail rows."""
    out = {}
    by_task = defaultdict(list)
    for s in scores:
        by_task[s["task"]].append(s)
    for task, rows in by_task.items():
        metrics = sorted({s["metric"] for s in rows})
        better = {s["metric"]: s["better"] for s in rows}
        unit = {s["metric"]: s.get("unit", "") for s in rows}
        agg = defaultdict(list)
        detail = defaultdict(dict)
        secs = defaultdict(list)
        for s in rows:
            agg[(s["algorithm"], s["condition"], s["metric"])].append(s["value"])
            detail[(s["scene"], s["condition"], s["algorithm"])][s["metric"]] = s["value"]
            secs[(s["algorithm"], s["condition"])].append(s.get("seconds") or 0.0)
        keys = sorted({(a, c) for a, c, _ in agg})
        summary = [{"algorithm": a, "condition": c, "seconds": fmt(_mean(secs[(a, c)])),
                    "cells": [fmt(_mean(agg[(a, c, m)])) if (a, c, m) in agg else "" for m in metrics]}
                   for a, c in keys]
        det = [{"scene": sc, "condition": c, "algorithm": a,
                "cells": [fmt(detail[(sc, c, a)].get(m)) if m in detail[(sc, c, a)] else "" for m in metrics]}
               for sc, c, a in sorted(detail)]
        out[task] = {"metrics": [{"name": m, "better": better[m], "unit": unit[m]} for m in metrics],
                     "summary": summary, "detail": det}
    return out


# ----------------------------------------------------------------------------- figures
def job_label(manifest: dict) -> str:
    """A short label: scene family, the swept value, the case, the condition (and the plot)."""
    scene = manifest.get("scene", "")
    fam, _, rest = scene.partition("[")
    params = dict(manifest.get("params", []))
    parts = [fam, rest.rstrip("]").replace(",", ", ") if rest else "", params.get("label", ""),
             manifest.get("condition", ""), f"plot: {params['plot']}" if params.get("plot") else ""]
    return " · ".join(p for p in parts if p)


def load_figures(run_dir: Path) -> dict[str, list[dict]]:
    """Per task, the saved figures of each job (from ``figures/*/manifest.json``), with paths
    relative to the run's folder."""
    from pbrbench.report.effects import match_key

    out = defaultdict(list)
    fig_dir = Path(run_dir) / "figures"
    if not fig_dir.is_dir():
        return {}
    for mf in sorted(fig_dir.glob("*/manifest.json")):
        try:
            m = json.loads(mf.read_text())
        except (OSError, ValueError):
            continue
        figs = {"image": [], "error_map": [], "plot": []}
        for f in m.get("figures", []):
            if (fig_dir / f["file"]).is_file():
                caption = f["name"][len("linear:"):] if f["name"].startswith("linear:") else f["name"]
                figs.setdefault(f["kind"], []).append({"name": f["name"], "caption": caption,
                                                       "src": f"figures/{f['file']}"})
        if not any(figs.values()) and not m.get("errors") and not m.get("failures"):
            continue
        params = "\n".join(f"{k} = {v}" for k, v in m.get("params", []))
        out[m["task"]].append({"scene": m["scene"], "condition": m["condition"], "params": params,
                               "label": job_label(m), "family": match_key(m["scene"].split("[")[0]),
                               "images": figs["image"], "error_maps": figs["error_map"], "plots": figs["plot"],
                               "errors": m.get("errors", []), "failures": m.get("failures", {})})
    for task in out:
        out[task].sort(key=lambda j: (j["family"], j["scene"].replace("_area", ""), j["condition"], j["params"]))
    return dict(out)


CHAPTER = re.compile(r"^(?:linear:)?Figs? (\d+)\.(\d+)")
SECTION = re.compile(r"^(?:linear:)?§(\d+)\.(\d+)(?:\.(\d+))?")   # an effect the chapter names without a figure


def chapter_gallery(figures: dict[str, list[dict]]) -> list[dict]:
    """Every figure whose name starts with a chapter figure number (``Fig 1.18 ...``, ``Figs
    1.4-1.6 ...``), ordered by that number, then those that start with a section of the chapter
    (``§1.3.5 colour bleeding ...``: effects the text describes without a figure), in section
    order after the figures of that chapter: the chapter gallery."""
    out = []
    for task, jobs in figures.items():
        for j in jobs:
            for kind in ("plots", "images", "error_maps"):
                for f in j[kind]:
                    m = CHAPTER.match(f["name"])
                    if m:
                        order = (int(m.group(1)), 0, int(m.group(2)), 0)
                    else:
                        m = SECTION.match(f["name"])
                        if not m:
                            continue
                        order = (int(m.group(1)), 1, int(m.group(2)), int(m.group(3) or 0))
                    out.append(dict(f, task=task, job=j["label"], kind=kind, order=order))
    return sorted(out, key=lambda f: (f["order"], f["name"]))


TIME_SHARE = 0.15   # an algorithm above this share of the job time needs a reason in the report


def algorithm_time(scores: list[dict], info: dict) -> list[dict]:
    """Seconds per (task, algorithm) summed over jobs (one score per job and algorithm counts;
    the time of the delete-one-group replicates is not in the scores), the share of the total, and,
    above :data:`TIME_SHARE`, the reason the task gives (its ``cost_notes``)."""
    per: dict[tuple[str, str], float] = defaultdict(float)
    seen = set()
    for s in scores:
        k = (s["task"], s.get("job", ""), s["algorithm"])
        if k in seen:
            continue
        seen.add(k)
        per[(s["task"], s["algorithm"])] += float(s.get("seconds") or 0.0)
    total = sum(per.values()) or 1.0
    out = []
    for (task, alg), sec in sorted(per.items(), key=lambda kv: -kv[1]):
        share = sec / total
        note = info.get(task, {}).get("cost_notes", {}).get(alg, "")
        out.append({"task": task, "algorithm": alg, "seconds": sec, "share": share,
                    "flag": share > TIME_SHARE, "note": note})
    return out


def _anchor(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-") or "x"


def by_family(jobs: list[dict], conditions: list[str]) -> list[dict]:
    """Jobs grouped by scene family (a twin with its family), each group ordered by condition."""
    groups: dict[str, list] = defaultdict(list)
    for j in jobs:
        groups[j["family"]].append(j)
    order = {c: i for i, c in enumerate(conditions)}
    return [{"name": f, "anchor": "fig-" + _anchor(f),
             "jobs": sorted(js, key=lambda j: (order.get(j["condition"], len(order)), j["scene"], j["params"]))}
            for f, js in sorted(groups.items())]


def history_figures(store, run_id: str, info: dict, quality_name: str, out_dir: Path) -> list[dict]:
    """One history plot per task and condition of its headline metric (mean over scenes) across
    the stored runs of the same quality, written under ``<out_dir>/history/``.  A task with
    fewer than two such runs gets none: one point is not a history, and drawing the plots
    is most of a report's time."""
    from pbrbench.report.figures import history_png

    out = []
    (out_dir / "history").mkdir(parents=True, exist_ok=True)
    for task, ti in info.items():
        metric = ti.get("headline_metric")
        if not metric:
            continue
        rows = [r for r in store.metric_history(task, metric, quality_name=quality_name)]
        if not rows:
            continue
        runs = []
        for r in rows:
            if r["run"] not in runs:
                runs.append(r["run"])
        if len(runs) < 2:
            continue
        conds = [c for c in ti.get("conditions", []) if any(r["condition"] == c for r in rows)]
        conds += sorted({r["condition"] for r in rows} - set(conds))
        for cond in conds:
            acc = {(r["run"], r["algorithm"]): r["value"] for r in rows if r["condition"] == cond}
            algs = sorted({a for _, a in acc})
            series = {a: [acc.get((ru, a)) for ru in runs] for a in algs}
            marks = [runs.index(run_id)] if run_id in runs else []
            png = history_png(f"{task}: {metric} under {cond} (mean over scenes; {quality_name})", runs, series,
                              ylabel=metric, marks=marks)
            name = f"history/{_anchor(task)}-{_anchor(cond)}.png"
            _write(out_dir / name, png)
            out.append({"task": task, "metric": metric, "condition": cond, "n_runs": len(runs), "src": name,
                        "anchor": f"h-{_anchor(task)}-{_anchor(cond)}"})
    return out


# ----------------------------------------------------------------------------- the report
def _env():
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)),
                      autoescape=select_autoescape(["html", "htm", "xml"], default=True))
    env.filters["fmt"] = fmt
    return env


def render_page(template: str, context: dict) -> str:
    return _env().get_template(template).render(**context)


def geometry_of(ground_truths: list[dict]) -> dict[str, str]:
    """scene -> "concave" / "convex" from the scene files' tags (scenes with neither are left out)."""
    out = {}
    for g in ground_truths:
        tags = set(g.get("tags") or ())
        if "concave" in tags:
            out[g["scene"]] = "concave"
        elif "convex" in tags:
            out[g["scene"]] = "convex"
    return out


def markers(comparison: dict | None) -> dict[tuple, str]:
    """(task, algorithm, condition) and (task, algorithm, condition, scene) -> "regression" /
    "improvement", from a stored comparison (a regression wins over an improvement)."""
    out: dict[tuple, str] = {}
    if not comparison:
        return out
    for ch in comparison.get("improvements", []):
        out.setdefault((ch["task"], ch["algorithm"], ch["condition"]), "improvement")
        out.setdefault((ch["task"], ch["algorithm"], ch["condition"], ch.get("scene")), "improvement")
    for ch in comparison.get("regressions", []):
        out[(ch["task"], ch["algorithm"], ch["condition"])] = "regression"
        out[(ch["task"], ch["algorithm"], ch["condition"], ch.get("scene"))] = "regression"
    return out


def build_context(store, run_id: str, *, run_dir: Path, status: str | None = None) -> dict:
    """Everything the pages show, read from ``store`` (a :class:`pbrbench.bench.store.Store`)
    and the run's figure files; nothing is recomputed (``status``: the status to show, when the
    run is about to take it)."""
    run = store.get_run(run_id)
    if run is None:
        raise KeyError(run_id)
    if status is not None:
        run["status"] = status
    all_scores = store.scores(run_id)
    scores = [s for s in all_scores if s["task"] != "perf"]
    perf = [s for s in all_scores if s["task"] == "perf"]
    info = run["config"].get("task_info", {})
    comparison = run.get("comparison")
    marks = markers(comparison)
    gts = store.ground_truths(run_id)
    heads = headline_tables(scores, info, marks, geometry_of(gts), task_layout(sorted({s["task"] for s in scores})))
    tables = metric_tables(scores)
    figures = load_figures(run_dir)
    history = history_figures(store, run_id, info, run["quality"], Path(run_dir))
    head_by_task = {h["task"]: h for h in heads}
    tasks = []
    for task in [h["task"] for h in heads] + [t for t in figures if t not in head_by_task]:
        ti = info.get(task, {})
        hist = next((h["src"] for h in history if h["task"] == task and h["condition"] == ti.get("reference_condition")),
                    next((h["src"] for h in history if h["task"] == task), None))
        tasks.append({"name": task, "description": ti.get("description", ""), "headline": head_by_task.get(task),
                      "table": tables.get(task), "families": by_family(figures.get(task, []), ti.get("conditions", [])),
                      "n_jobs": len(figures.get(task, [])), "history": hist})
    for g in gts:
        n = g.get("noise") or {}
        g["noise_rms"] = n.get("radiance_rel_sd_rms")
        g["noise_median"] = n.get("radiance_rel_sd_median")
        g["inputs_rms"] = n.get("inputs_rel_sd_rms")
        g["inputs_median"] = n.get("inputs_rel_sd_median")
        g["res_text"] = "×".join(str(x) for x in g["resolution"]) if g.get("resolution") else ""
    meta_rows = [("run", run["id"]), ("time (UTC)", run["time"]), ("finished", run.get("finished") or ""),
                 ("status", run["status"]), ("quality", run["quality"]), ("variant", run.get("variant") or ""),
                 ("git revision", run.get("git_revision") or "unknown"),
                 ("pbrbench", run.get("pbrbench_version") or ""), ("mitsuba", run.get("mitsuba_version") or ""),
                 ("drjit", run.get("drjit_version") or ""), ("numpy", run.get("numpy_version") or ""),
                 ("machine", run.get("machine") or ""),
                 ("configuration", json.dumps({k: v for k, v in run["config"].items() if k not in ("task_info", "environment")},
                                              sort_keys=True)),
                 ("dependency lock", _lock_text(run["config"].get("environment", {}).get("lock"))),
                 ("scores", str(len(scores)))]
    gallery = chapter_gallery(figures)
    time_shares = algorithm_time(scores, info)
    failures = [{"task": t, "scene": j["scene"], "condition": j["condition"], "algorithm": a, "message": msg}
                for t, jobs in figures.items() for j in jobs for a, msg in sorted(j["failures"].items())]
    return {
        "noise": noise_statement(heads, gts),
        "run": run, "meta_rows": meta_rows, "headlines": heads, "tasks": tasks, "ground_truths": gts,
        "history": history, "nav_tasks": [t["name"] for t in tasks], "gallery": gallery,
        "has_gallery": bool(gallery),
        "comparison": comparison, "baseline_quality": (comparison or {}).get("baseline_quality"),
        "job_errors": _job_errors(store.job_errors(run_id)), "perf": perf, "failures": failures,
        "n_scores": len(scores), "time_shares": time_shares,
    }


def noise_statement(heads: list[dict], gts: list[dict]) -> dict:
    """How many headline cells are noise-limited (|Monte Carlo bias| > SE) or bimodal, per task,
    and what more samples would change.  The bias falls as 1/spp and the standard error as
    1/sqrt(spp); the standard quality renders at least each scene file's samples per pixel
    (``gts``: the run's ground truths, with ``spp`` and the file's ``spp_file``), so a run with
    ``1/s`` of them would see its bias cut to about ``1/s`` and its standard error to ``1/sqrt(s)``.
    The range of ``s`` is over the run's scenes (draft's floor of two samples per group makes it
    differ from scene to scene)."""
    per_task, n_cells, n_lim, n_unst = [], 0, 0, 0
    for h in heads:
        cells = [c for r in h["rows"] for c in r["cells"] if c.get("value") is not None]
        lim = sum(1 for c in cells if "biased" in c.get("cls", ""))
        unst = sum(1 for c in cells if "unstable" in c.get("cls", ""))
        n_cells, n_lim, n_unst = n_cells + len(cells), n_lim + lim, n_unst + unst
        if lim or unst:
            per_task.append({"task": h["task"], "cells": len(cells), "limited": lim, "unstable": unst})
    # the scenes rendered below their files' samples (the others are already at them)
    ratios = sorted(r for g in gts if (g.get("spp") or 0) > 0 and (g.get("spp_file") or 0) > 0
                    and (r := g["spp_file"] / g["spp"]) > 1)
    hint = ""
    if n_lim and ratios:
        lo, hi = ratios[0], ratios[-1]
        few = f"1/{lo:.3g}" if lo == hi else f"1/{lo:.3g} to 1/{hi:.3g}"
        hint = (f"This run rendered {few} of the scene files' samples per pixel; the standard quality renders at least "
                f"the files' counts, which cuts the bias to about {few} of the values shown (it falls as 1/spp) and "
                f"the standard error to about {lo ** -0.5:.2g}" + ("" if lo == hi else f" to {hi ** -0.5:.2g}") +
                ": run `pbrbench run --quality standard` before drawing conclusions from the marked cells.")
    return {"cells": n_cells, "limited": n_lim, "unstable": n_unst, "per_task": per_task, "hint": hint}


def _lock_text(lock: dict | None) -> str:
    if not lock:
        return "not recorded"
    mism = lock.get("mismatches") or []
    return (f"{lock.get('lock_file', '')} sha256 {str(lock.get('lock_sha256') or '')[:12]}; "
            f"{len(lock.get('packages') or {})} packages, "
            + (f"{len(mism)} differ from the lock: " + ", ".join(f"{m['name']} {m['installed']} (lock {m['locked']})" for m in mism[:8])
               if mism else "all as locked"))


def _job_errors(errors: dict[str, str]) -> list[dict]:
    out = []
    for key, err in sorted(errors.items()):
        parts = key.split("|")
        lines = [ln for ln in (err or "").strip().splitlines() if ln.strip()]
        out.append({"key": key, "short": " | ".join(parts[:3]), "last": lines[-1][:200] if lines else "", "error": err})
    return out


def _write(path: Path, text: str | bytes):
    """Write a page (text) or an image (bytes) of the report atomically: a full or read-only disk
    is one line naming the file and ``--out``, and leaves no temporary file behind."""
    from pbrbench.errors import disk_error
    from pbrbench.io import write_bytes, write_text

    try:
        (write_bytes if isinstance(text, bytes) else write_text)(path, text)
    except OSError as exc:
        raise disk_error(exc, f"report file {path}", option="--out") from None


def _style(out_dir: Path):
    _write(out_dir / "style.css", (TEMPLATE_DIR / "style.css").read_text())


def write_report(store, run_id: str, *, out_dir: str | Path, status: str | None = None) -> Path:
    """Write the run's site into ``out_dir`` and return the path of its ``index.html``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ctx = build_context(store, run_id, run_dir=out_dir, status=status)
    _style(out_dir)
    for t in ctx["tasks"]:
        _write(out_dir / f"task-{t['name']}.html", render_page("task.html", dict(ctx, t=t, page=f"task-{t['name']}")))
    _write(out_dir / "history.html", render_page("history.html", dict(ctx, page="history")))
    if ctx["has_gallery"]:
        _write(out_dir / "gallery.html", render_page("gallery.html", dict(ctx, page="gallery")))
    index = out_dir / "index.html"
    _write(index, render_page("index.html", dict(ctx, page="index")))
    return index


def write_compare(path: str | Path, runs: tuple[dict, dict], rows: list[dict], counts: dict) -> Path:
    """A page of the differences between two runs (``rows`` of
    :func:`pbrbench.cli.compare.differences`), grouped by task, changes first, with the noise
    allowance of each comparison (2 combined standard errors)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _style(path.parent)
    order = {"worse": 0, "better": 1, "only-a": 2, "only-b": 3, "same": 4}
    by_task = defaultdict(list)
    for r in sorted(rows, key=lambda r: (order.get(r["direction"], 9), r["scene"], r["condition"], r["algorithm"], r["metric"])):
        by_task[r["task"]].append(dict(r, a_text=fmt(r["a"]), b_text=fmt(r["b"]), d_text=fmt(r["delta"]),
                                       n_text=fmt(r["limit"]) if math.isfinite(r.get("limit", float("nan"))) else "–"))
    tasks = [{"name": t, "rows": rs, "counts": {d: sum(1 for r in rs if r["direction"] == d) for d in order}}
             for t, rs in sorted(by_task.items())]
    _write(path, render_page("compare.html", {"run": runs[1], "runs": runs, "tasks": tasks, "counts": counts,
                                              "page": "compare", "nav_tasks": [], "has_gallery": False}))
    return path
