"""Figures of the report: PNG encoding of job images, error maps (with colour bar) and plots.

Figures are made where a job finishes (possibly on a Dask worker) and shipped back as PNG
bytes plus JSON plot data; the runner writes them under ``reports/<run>/figures/<job>/`` with a
``manifest.json``.  The HTML report only reads those files (and the store).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import re

import numpy as np

MAX_SIDE = 160          # images larger than this are box-downsampled (integer factor) for the report
STRIP = 4               # ... except that a row of panels (a bracket, a composite) may be this many times as wide
PLOT_SIZE = (7.0, 4.4)
DPI = 90


def slug(text: str, n: int = 60) -> str:
    """A file-system-safe, unique name for a job key or figure name."""
    s = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_")[:n]
    return f"{s}-{hashlib.sha1(text.encode()).hexdigest()[:8]}"


def _downsample(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[:2]
    f = int(math.ceil(max(h, w / STRIP) / MAX_SIDE))
    if f <= 1:
        return a
    h2, w2 = h // f * f, w // f * f
    a = a[:h2, :w2]
    return a.reshape(h2 // f, f, w2 // f, f, *a.shape[2:]).mean(axis=(1, 3))


def png_bytes(rgb8: np.ndarray) -> bytes:
    """Encode an 8-bit (H, W) or (H, W, 3|4) array as PNG."""
    from PIL import Image

    a = np.ascontiguousarray(rgb8, dtype=np.uint8)
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG", optimize=False)
    return buf.getvalue()


def image_png(name: str, img) -> bytes:
    """A job image as PNG: display-ready [0, 1], or linear radiance when ``name`` starts with ``linear:``."""
    from pbrbench.io import tonemap

    a = np.asarray(img, dtype=np.float64)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (3, 4)):
        raise ValueError(f"image {name!r}: shape {a.shape}; expected (H, W) or (H, W, 3)")
    a = _downsample(np.nan_to_num(a, nan=0.0, posinf=0.0, neginf=0.0))
    if name.startswith("linear:"):
        rgb8 = tonemap(a)
    else:
        rgb8 = (np.clip(a, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
    return png_bytes(rgb8)


def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def error_map_png(name: str, data, *, label: str | None = None) -> bytes:
    """A scalar map with a colour bar (drawn with PIL: fast enough for every job of a run).

    Non-negative maps use ``magma`` from 0, signed maps ``coolwarm`` symmetric about 0; colours
    are clipped at the 99.5th percentile of |value| (">" on the bar's top label when clipped);
    NaN (outside the mask) is light grey.  Small maps are enlarged (nearest) to at least 160 px.
    """
    from matplotlib import colormaps
    from PIL import Image, ImageDraw

    d = np.asarray(data, dtype=np.float64)
    if d.ndim == 3:
        d = d.mean(-1)
    if d.ndim != 2 or d.size == 0:
        raise ValueError(f"error map {name!r}: shape {d.shape}; expected (H, W)")
    d = _downsample(d)
    finite = d[np.isfinite(d)]
    signed = bool(finite.size) and float(finite.min()) < 0
    hi = float(np.percentile(np.abs(finite), 99.5)) if finite.size else 1.0
    hi = hi if hi > 0 else (float(np.abs(finite).max()) if finite.size and np.abs(finite).max() > 0 else 1.0)
    lo = -hi if signed else 0.0
    clipped = bool(finite.size) and float(np.abs(finite).max()) > hi
    cmap = colormaps["coolwarm" if signed else "magma"]
    t = np.clip((d - lo) / (hi - lo), 0, 1)
    rgba = (cmap(np.nan_to_num(t)) * 255 + 0.5).astype(np.uint8)
    rgba[~np.isfinite(d)] = (208, 208, 208, 255)
    img = Image.fromarray(rgba[..., :3])
    h, w = d.shape
    scale = max(1, int(math.ceil(160 / max(h, w))))
    if scale > 1:
        img = img.resize((w * scale, h * scale), Image.NEAREST)
    W, H = img.size
    font = _font(11)
    bar_w, pad, text_w = 12, 6, 62
    top = 6  # the caption (figure name) is in the HTML; only the scale is drawn here
    canvas = Image.new("RGB", (W + pad + bar_w + 4 + text_w, H + top + 4), "white")
    canvas.paste(img, (0, top))
    ramp = (cmap(np.linspace(1, 0, H))[:, :3] * 255 + 0.5).astype(np.uint8)
    bar = Image.fromarray(np.repeat(ramp[:, None, :], bar_w, axis=1))
    canvas.paste(bar, (W + pad, top))
    draw = ImageDraw.Draw(canvas)
    draw.rectangle([W + pad, top, W + pad + bar_w - 1, top + H - 1], outline="black")
    x_text = W + pad + bar_w + 4
    for frac, val in ((0.0, hi), (0.5, (hi + lo) / 2), (1.0, lo)):
        y = top + int(frac * (H - 1))
        draw.line([W + pad + bar_w, y, W + pad + bar_w + 2, y], fill="black")
        txt = (">" if clipped and frac == 0.0 else "") + f"{val:.3g}"
        draw.text((x_text, min(max(y - 6, top - 2), top + H - 12)), txt, fill="black", font=font)
    buf = io.BytesIO()
    canvas.save(buf, format="PNG")
    return buf.getvalue()


def wrap_title(title: str, width_in: float, fontsize: float = 11.0) -> str:
    """``title`` broken into lines that fit a figure ``width_in`` inches wide at ``fontsize``
    points (about 0.55 em per character); a long title is otherwise cut at both edges."""
    import textwrap

    per_line = max(20, int(width_in * 72.0 / (0.55 * fontsize)))
    return "\n".join(textwrap.wrap(title, per_line)) or title


def _figure(size):
    """A matplotlib Figure without pyplot (no global state, cheaper)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _series(plot: dict) -> list[tuple[str, list, list, dict]]:
    x0 = plot.get("x")
    out = []
    for label, s in plot.get("series", {}).items():
        style = {}
        if isinstance(s, dict):
            x, y = s.get("x", x0), s.get("y", [])
            style = {k: s[k] for k in ("linestyle", "marker", "color", "markersize") if k in s}
        else:
            x, y = x0, s
        if x is None:
            x = list(range(len(y)))
        out.append((str(label), list(x), [float("nan") if v is None else v for v in y], style))
    return out


def plot_png(name: str, plot: dict) -> bytes:
    """A line plot from ``{"x": [...], "series": {label: [...] | {"x", "y"}}, "xlabel", "ylabel"}``.

    Optional keys: ``title``, ``logx``, ``logy``, ``ylim`` ([low, high]), ``kind`` ("line" default,
    or "scatter"); a
    series dict may set ``color``, ``marker``, ``markersize`` and ``linestyle``, and a label that
    starts with ``_`` is left out of the legend.
    """
    fig = _figure(PLOT_SIZE)
    ax = fig.add_axes((0.11, 0.12, 0.86, 0.78))
    series = _series(plot)
    for label, x, y, style in series:
        if plot.get("kind") == "scatter":
            ax.scatter(x, y, s=10, label=label)
        else:
            ax.plot(x, y, label=label, marker=style.get("marker", "o" if len(y) <= 12 else None),
                    markersize=style.get("markersize", 3), linestyle=style.get("linestyle", "-"),
                    color=style.get("color"))
    ax.set_xlabel(str(plot.get("xlabel", "")), fontsize=10)
    ax.set_ylabel(str(plot.get("ylabel", "")), fontsize=10)
    ax.set_title(wrap_title(str(plot.get("title", name)), PLOT_SIZE[0]), fontsize=11)
    if plot.get("logx"):
        ax.set_xscale("log")
    if plot.get("logy"):
        ax.set_yscale("log")
    if plot.get("ylim"):
        ax.set_ylim(*plot["ylim"])
    ax.tick_params(labelsize=9)
    ax.grid(alpha=0.3)
    if series:   # a label starting with "_" stays out of the legend (matplotlib's rule)
        shown = sum(1 for label, *_ in series if not label.startswith("_"))
        ax.legend(fontsize=8, loc="best", ncol=2 if shown > 8 else 1)
    return _save(fig)


def history_png(title: str, runs: list[str], series: dict[str, list[float]], *, ylabel: str = "",
                marks: list[int] | None = None) -> bytes:
    """Headline metric across runs: one line per algorithm; ``marks`` highlights run indices."""
    fig = _figure((10.0, 3.8))
    ax = fig.add_axes((0.09, 0.2, 0.62, 0.7))
    x = list(range(len(runs)))
    for label, y in series.items():
        ax.plot(x, [float("nan") if v is None else v for v in y], marker="o", markersize=3, label=label)
    for m in marks or []:
        ax.axvline(m, color="#999", lw=0.8, ls=":")
    step = max(1, len(runs) // 8)
    ax.set_xticks(x[::step])
    ax.set_xticklabels([r[:15] for r in runs[::step]], rotation=20, fontsize=8, ha="right")
    ax.set_ylabel(ylabel, fontsize=10)
    ax.set_title(title, fontsize=11)
    ax.tick_params(labelsize=9)
    ax.grid(alpha=0.3)
    if series:
        ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    return _save(fig)


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return [_jsonable(v) for v in x.tolist()]
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        f = float(x)
        return f if math.isfinite(f) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def job_figures(result, job_dir: str) -> tuple[dict[str, bytes], dict]:
    """PNG files (relative path -> bytes) and the manifest of one :class:`JobResult`.

    A figure that cannot be drawn is listed in the manifest with its error instead of failing
    the job (its scores are still good).
    """
    job = result.job
    files: dict[str, bytes] = {}
    manifest = {"job": job.key, "task": job.task, "scene": job.scene, "condition": job.condition,
                "params": [[str(k), str(v)] for k, v in job.params], "figures": [], "errors": [],
                "failures": {str(k): str(v) for k, v in getattr(result, "failures", {}).items()}}

    def add(kind, name, fn, *args):
        rel = f"{job_dir}/{kind}-{slug(name, 40)}.png"
        try:
            files[rel] = fn(name, *args)
        except Exception as e:  # noqa: BLE001 - a broken figure must not lose the scores
            manifest["errors"].append(f"{kind} {name}: {type(e).__name__}: {e}")
            return
        manifest["figures"].append({"kind": kind, "name": name, "file": rel})

    for name, img in result.images.items():
        add("image", name, image_png, img)
    for name, em in result.error_maps.items():
        add("error_map", name, error_map_png, em)
    plots = {}
    for name, p in result.plots.items():
        add("plot", name, plot_png, p)
        plots[name] = _jsonable(p)
    if plots:
        rel = f"{job_dir}/plots.json"
        files[rel] = json.dumps(plots, sort_keys=True).encode()
        manifest["plot_data"] = rel
    files[f"{job_dir}/manifest.json"] = json.dumps(manifest, indent=1).encode()
    return files, manifest
