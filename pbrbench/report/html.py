"""The HTML report of a run: one self-contained file (CSS inline, images as base64 PNG).

It reads only the results store (run metadata, scores, ground-truth noise, history of earlier
runs) and the figures the run saved under ``<run>/figures/``; it recomputes no score.  Tables
show means over scenes of stored scores.  Jinja2 autoescaping is on, so scene names,
descriptions, algorithm names and error messages cannot inject markup.
"""

from __future__ import annotations

import base64
import json
import math
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


def headline_tables(scores: list[dict], info: dict, marks: dict | None = None,
                    geometry: dict | None = None) -> list[dict]:
    """Per task: the effect table of :func:`pbrbench.report.effects.effect_tables` with display
    text, colours and regression markers.  The reference column is coloured green (best) to red
    (worst) across algorithms; an effect is red when it costs accuracy significantly, green when it
    helps, and greyed when it is within two standard errors of zero."""
    from pbrbench.report.effects import effect_tables, format_cell

    marks = marks or {}
    out = []
    for t in effect_tables(scores, info, geometry):
        ref_vals = [r["cells"][0]["value"] for r in t["rows"] if r["cells"][0] is not None]
        finite = [v for v in ref_vals if math.isfinite(v)]
        lo, hi = (min(finite), max(finite)) if finite else (float("nan"), float("nan"))
        log = bool(finite) and lo > 0 and hi / lo > 10
        rows = []
        for r in t["rows"]:
            cells = []
            for col, c in zip(t["columns"], r["cells"], strict=True):
                if c is None:
                    cells.append({"text": "", "value": None, "n": 0, "colour": None, "mark": None, "cls": ""})
                    continue
                if not col["effect"]:
                    colour = _colour(c["value"], lo, hi, t["better"], log)
                    cls = ""
                else:
                    worse = (c["value"] > 0) == (t["better"] == "lower")
                    colour = None
                    cls = "ns" if c["insignificant"] else ("cost" if c["significant"] and worse else
                                                            "gain" if c["significant"] else "")
                title = f"n = {c['n']} scene(s)" + ("" if col["group"] is None else f", {col['group']}")
                if col["effect"]:
                    title += "; " + ("within 2 SE of zero: not an effect" if c["insignificant"] else
                                     "beyond 2 SE: an effect" if c["significant"] else "no uncertainty estimate")
                cells.append({"text": format_cell(c), "value": c["value"], "se": c["se"], "n": c["n"], "colour": colour,
                              "cls": cls, "title": title, "mark": marks.get((t["task"], r["algorithm"], col["condition"]))})
            rows.append({"algorithm": r["algorithm"], "cells": cells})
        out.append(dict(t, conditions=[c["label"] for c in t["columns"]], rows=rows))
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
def _data_uri(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def load_figures(run_dir: Path) -> dict[str, list[dict]]:
    """Per task, the saved figures of each job (from ``figures/*/manifest.json``)."""
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
            p = fig_dir / f["file"]
            if p.is_file():
                caption = f["name"][len("linear:"):] if f["name"].startswith("linear:") else f["name"]
                figs.setdefault(f["kind"], []).append({"name": f["name"], "caption": caption, "src": _data_uri(p)})
        if not any(figs.values()) and not m.get("errors") and not m.get("failures"):
            continue
        params = ", ".join(f"{k}={v}" for k, v in m.get("params", []))
        out[m["task"]].append({"scene": m["scene"], "condition": m["condition"], "params": params,
                               "images": figs["image"], "error_maps": figs["error_map"], "plots": figs["plot"],
                               "errors": m.get("errors", []), "failures": m.get("failures", {})})
    for task in out:
        out[task].sort(key=lambda j: (j["scene"], j["condition"], j["params"]))
    return dict(out)


def history_figures(store, run_id: str, info: dict, quality: str) -> list[dict]:
    """A history plot of each task's headline metric across stored runs of the same quality."""
    from pbrbench.report.figures import history_png

    out = []
    for task, ti in info.items():
        metric = ti.get("headline_metric")
        if not metric:
            continue
        rows = [r for r in store.metric_history(task, metric, quality=quality)]
        if not rows:
            continue
        runs = []
        for r in rows:
            if r["run"] not in runs:
                runs.append(r["run"])
        # per run and algorithm: mean over conditions of the per-condition means
        acc = defaultdict(list)
        for r in rows:
            if r["value"] is not None:
                acc[(r["run"], r["algorithm"])].append(r["value"])
        algs = sorted({r["algorithm"] for r in rows})
        series = {a: [(sum(acc[(ru, a)]) / len(acc[(ru, a)])) if acc.get((ru, a)) else None for ru in runs]
                  for a in algs}
        marks = [runs.index(run_id)] if run_id in runs else []
        png = history_png(f"{task}: {metric} (mean over scenes and conditions; {quality})", runs, series,
                          ylabel=metric, marks=marks)
        out.append({"task": task, "metric": metric, "n_runs": len(runs),
                    "src": "data:image/png;base64," + base64.b64encode(png).decode("ascii")})
    return out


# ----------------------------------------------------------------------------- the report
def render_html(context: dict) -> str:
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)),
                      autoescape=select_autoescape(["html", "htm", "xml"], default=True))
    env.filters["fmt"] = fmt
    return env.get_template("report.html").render(**context)


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


def markers(comparison: dict | None) -> dict[tuple[str, str, str], str]:
    """(task, algorithm, condition) -> "regression" / "improvement", from a stored comparison."""
    out: dict[tuple[str, str, str], str] = {}
    if not comparison:
        return out
    for ch in comparison.get("improvements", []):
        out.setdefault((ch["task"], ch["algorithm"], ch["condition"]), "improvement")
    for ch in comparison.get("regressions", []):
        out[(ch["task"], ch["algorithm"], ch["condition"])] = "regression"
    return out


def build_context(store, run_id: str, *, run_dir: Path, status: str | None = None) -> dict:
    """Everything the template shows, read from ``store`` (a :class:`pbrbench.bench.store.Store`)
    and the run's figure files; nothing is recomputed (``status``: the status to show, when the
    run is about to take it)."""
    run = store.get_run(run_id)
    if run is None:
        raise KeyError(run_id)
    if status is not None:
        run["status"] = status
    scores = [s for s in store.scores(run_id) if s["task"] != "perf"]
    perf = [s for s in store.scores(run_id) if s["task"] == "perf"]
    info = run["config"].get("task_info", {})
    comparison = run.get("comparison")
    marks = markers(comparison)
    gts = store.ground_truths(run_id)
    heads = headline_tables(scores, info, marks, geometry_of(gts))
    tables = metric_tables(scores)
    figures = load_figures(run_dir)
    tasks = []
    for task in [h["task"] for h in heads] + [t for t in figures if t not in {h["task"] for h in heads}]:
        tasks.append({"name": task, "description": info.get(task, {}).get("description", ""),
                      "table": tables.get(task), "figures": figures.get(task, [])})
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
                 ("configuration", json.dumps({k: v for k, v in run["config"].items() if k != "task_info"}, sort_keys=True)),
                 ("scores", str(len(scores)))]
    return {
        "run": run, "meta_rows": meta_rows, "headlines": heads, "tasks": tasks, "ground_truths": gts,
        "history": history_figures(store, run_id, info, run["quality"]),
        "comparison": comparison, "baseline_quality": (comparison or {}).get("baseline_quality"),
        "job_errors": _job_errors(store.job_errors(run_id)), "perf": perf,
        "failures": [{"task": t, "scene": j["scene"], "condition": j["condition"], "algorithm": a, "message": msg}
                     for t, jobs in figures.items() for j in jobs for a, msg in sorted(j["failures"].items())],
    }


def _job_errors(errors: dict[str, str]) -> list[dict]:
    out = []
    for key, err in sorted(errors.items()):
        parts = key.split("|")
        lines = [ln for ln in (err or "").strip().splitlines() if ln.strip()]
        out.append({"key": key, "short": " | ".join(parts[:3]), "last": lines[-1][:200] if lines else "", "error": err})
    return out


def write_report(store, run_id: str, *, out_dir: str | Path, status: str | None = None) -> Path:
    """Write ``<out_dir>/index.html`` for ``run_id`` and return its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    html = render_html(build_context(store, run_id, run_dir=out_dir, status=status))
    p = out_dir / "index.html"
    tmp = p.with_name("index.html.tmp")
    tmp.write_text(html, encoding="utf-8")
    tmp.replace(p)
    return p
