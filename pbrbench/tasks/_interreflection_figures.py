"""The plot jobs of the interreflection task: the chapter's shadow and interreflection figures.

Each figure's name starts with the chapter figure it reproduces (``Fig 1.18 ...``) or, for an
effect the chapter describes without a figure, its section (``§1.3.5 ...``), so the report's
chapter gallery collects it (:func:`pbrbench.report.html.chapter_gallery`).  The path tracer's
renders are the chapter's "data"; the models are pbrbench's own: the radiosity solution of
:mod:`pbrbench.radiosity.forward_models` (converged, and its local model: zero bounces), the exact
irradiance of a polygonal source partly hidden by a convex occluder
(:func:`pbrbench.shading.irradiance.visible_polygon_irradiance`) and the gain kernel of
:mod:`pbrbench.shading.gain_curve`.
"""

from __future__ import annotations

import numpy as np

from pbrbench.tasks.base import JobResult
from pbrbench.tasks.common.figures import display
from pbrbench.tasks.common.inputs import grey
from pbrbench.tasks.common.scenes import sweep_value

__all__ = ["plot_job"]

GROOVE = {"groove_reflex_parallel": ("Fig 1.18", "source parallel to the left face"),
          "groove_reflex_bisector": ("Fig 1.20", "source along the bisector")}
ROOM_ROW = 0.72


def _vis(gt) -> np.ndarray:
    from pbrbench.tasks.common.inputs import visible_surface

    return visible_surface(gt)


def _cells(task, quality) -> int:
    """Patches across the view of the task's models at this quality (the last built-in method's)."""
    from pbrbench.radiosity.forward_models import DEFAULT_CELLS

    methods = [a for a in task.builtin_algorithms() if a.kind == "method"]
    return int(methods[-1].options_for(quality).get("cells", DEFAULT_CELLS)) if methods else DEFAULT_CELLS


def _models(spec, shape, cells):
    """(converged radiosity image, local model image) of ``spec`` at ``shape = (H, W)``."""
    from pbrbench.radiosity.forward_models import predict_radiance

    H, W = shape
    return (predict_radiance(spec, (W, H), cells=cells), predict_radiance(spec, (W, H), bounces=0, cells=cells))


def _display(img, exposure: float) -> np.ndarray:
    """Display-ready sRGB [0, 1] with a given exposure (so two images share one)."""
    from pbrbench.io import srgb_encode

    return np.clip(srgb_encode(display(img) * exposure), 0.0, 1.0).astype(np.float32)


def _exposure(img, mask) -> float:
    g = grey(img)[mask]
    w = np.percentile(g[g > 0], 99.0) if np.any(g > 0) else 1.0
    return 1.0 / w if w > 0 else 1.0


def _columns(a, mask) -> np.ndarray:
    """Mean of each column over the rows where ``mask`` (NaN where none)."""
    v = grey(a)
    cnt = mask.sum(axis=0)
    with np.errstate(invalid="ignore"):
        return np.where(cnt > 0, np.where(mask, v, 0.0).sum(axis=0) / np.maximum(cnt, 1), np.nan)


def _x(spec, W, H) -> np.ndarray:
    from pbrbench.shading.surfaces import pixel_grid

    return pixel_grid(H, W, spec.camera.half_width)[0][0]


def _series(x, y, color, **style) -> dict:
    clean = [None if not np.isfinite(v) else float(v) for v in np.asarray(y, float)]
    return dict({"x": [float(v) for v in x], "y": clean, "color": color}, **style)


# ------------------------------------------------------------------------------ the figures
def _groove(task, job, gts, quality) -> JobResult:
    from pbrbench.quality import subsample
    res = JobResult(job)
    names = sorted([job.scene, *job.extra_scenes], key=lambda n: sweep_value(n, "albedo") or 0.0)
    fam = job.scene.split("[")[0]
    fig, what = GROOVE.get(fam, ("Fig 1.18", fam))
    shown = subsample([n for n in names if (sweep_value(n, "albedo") or 0) > 0] or names, 3)
    cells = _cells(task, quality)
    series, local = {}, None
    for k, name in enumerate(shown):
        gt, spec = gts[name], task.scenes.spec(name)
        rho = float(sweep_value(name, "albedo") or np.mean(grey(gt["albedo"])[_vis(gt)]))
        H, W = gt['radiance'].shape[:2]
        x = _x(spec, W, H)
        model, loc = _models(spec, (H, W), cells)
        col = f"C{k}"
        scale = np.pi / max(rho, 1e-12)
        series[f"albedo {rho:g}: path tracer"] = _series(x, scale * _columns(gt["radiance"], _vis(gt)), col, marker="")
        series[f"albedo {rho:g}: radiosity model"] = _series(x, scale * _columns(model, _vis(gt)), col, linestyle="--",
                                                             marker="")
        local = (x, scale * _columns(loc, _vis(gt)))
    if local is not None:
        series["local model (every albedo)"] = _series(*local, "black", linestyle=":", marker="")
    res.plots[f"{fig} groove, {what}: radiosity / albedo across the groove"] = {
        "x": None, "series": series, "xlabel": "x across the groove (crease at 0)",
        "ylabel": "B / albedo = pi L / albedo (column means)",
        "title": f"{fig}: {what}: path tracer, radiosity (--), local (..)"}
    top = gts[names[-1]]
    res.images[f"{fig} groove, {what} (albedo {sweep_value(names[-1], 'albedo') or 0:g}): path tracer"] = _display(
        top["radiance"], 0.9 * _exposure(top["radiance"], _vis(top)))
    if fam == "groove_reflex_parallel":
        res.plots["Fig 1.19 gain of interreflection: a patch at unit height above a plane of radiosity sin(omega x)"] = \
            _gain_plot(quality)
    return res


GAIN_SLANTS = 10                        # the chapter's curves: slants 0 to pi/2 in 10 steps
GAIN_MITSUBA_OMEGAS = (0.5, 1.0, 2.0, 3.0, 4.0)
GAIN_MITSUBA_SLANTS = (0, 4, 8)         # indices into the slants: 0, 40 and 80 degrees


def _gain_plot(quality) -> dict:
    """Fig 1.19: the kernel integral's gain at the chapter's ten slants and, as points, the gain
    Mitsuba's irradiance meter measures (:func:`pbrbench.render.proofs.gain.measure_gain_mitsuba`,
    four phases, the validate check's samples at this quality) at three of them; about 0.2 s a
    point."""
    from pbrbench.render.proofs.gain import GAIN_SPP, measure_gain_mitsuba
    from pbrbench.shading.gain_curve import gain_curve

    om = np.linspace(0.0, 6.0, 61)
    slants = np.linspace(0.0, np.pi / 2, GAIN_SLANTS)
    G = gain_curve(om, slants)
    series = {f"slant {np.degrees(s):.0f} deg": _series(om, G[k], f"C{k}", marker="") for k, s in enumerate(slants)}
    spp = quality.spp(GAIN_SPP) if quality is not None else GAIN_SPP
    for n, k in enumerate(GAIN_MITSUBA_SLANTS):
        g = [measure_gain_mitsuba(w, float(slants[k]), spp=spp, seed=k)["gain"] for w in GAIN_MITSUBA_OMEGAS]
        label = "Mitsuba irradiance meter (points)" if n == 0 else f"_Mitsuba, slant {np.degrees(slants[k]):.0f} deg"
        series[label] = _series(GAIN_MITSUBA_OMEGAS, g, f"C{k}", marker="o", linestyle="", markersize=6)
    return {"x": None, "series": series, "xlabel": "spatial frequency omega (1 / distance)",
            "ylabel": "gain |H(omega, slant)|",
            "title": "Fig 1.19: high frequencies do not jump the gap (lines: kernel; points: Mitsuba)"}


def _rooms(task, job, gts, quality) -> JobResult:
    res = JobResult(job)
    names = sorted([job.scene, *job.extra_scenes], key=lambda n: "white" in n)  # black first
    cells = _cells(task, quality)
    series, shown = {}, {}
    white = gts[names[-1]]
    expo = 0.9 * _exposure(white["radiance"], _vis(white))   # the white room's render just below white
    for k, name in enumerate(names):
        gt, spec = gts[name], task.scenes.spec(name)
        H, W = gt['radiance'].shape[:2]
        row = int(ROOM_ROW * H)
        band = np.zeros((H, W), bool)
        band[max(0, row - max(1, H // 32)):row + max(1, H // 32) + 1] = True
        model, loc = _models(spec, (H, W), cells)
        x = np.arange(W)
        col = f"C{k}"
        label = "black room" if "black" in name else ("white room" if "white" in name else name)
        series[f"{label}: path tracer"] = _series(x, _columns(gt["radiance"], band), col, marker="")
        series[f"{label}: radiosity model"] = _series(x, _columns(model, band), col, linestyle="--", marker="")
        shown[label] = (gt["radiance"], loc)
    # the local model is the same for both rooms (the sources are scaled so that the direct light matches)
    series["local model (either room)"] = _series(x, _columns(loc, band), "black", linestyle=":", marker="")
    res.plots["Fig 1.17 black room vs white room: a section (image rows ~72 % down, through the boxes)"] = {
        "x": None, "series": series, "xlabel": "image column", "ylabel": "radiance (band of rows)",
        "title": "Fig 1.17: black vs white room, one section through the boxes"}
    for label, (img, _) in shown.items():
        res.images[f"Fig 1.17 {label}: path tracer (one exposure for both rooms)"] = _display(img, expo)
    if shown:
        local_white = shown[list(shown)[-1]][1]
        res.images["Fig 1.17 local model of either room (one exposure for both rooms)"] = _display(local_white, expo)
    return res


def _bump(task, job, gts, quality) -> JobResult:
    res = JobResult(job)
    gt, spec = gts[job.scene], task.scenes.spec(job.scene)
    H, W = gt['radiance'].shape[:2]
    band = np.zeros((H, W), bool)
    band[H // 2 - max(1, H // 16):H // 2 + max(1, H // 16)] = True
    band &= _vis(gt)
    x = _x(spec, W, H)
    model, loc = _models(spec, (H, W), _cells(task, quality))
    res.plots["Fig 1.21 reflexes in the shadow of a cylindrical bump: radiance across the bump"] = {
        "x": None, "xlabel": "x (the bump's axis at 0, its shadow at -0.6 < x < -0.3)", "ylabel": "radiance (middle rows)",
        "title": "Fig 1.21: the shadowed plane sees the lit plane: a reflex",
        "series": {"path tracer (global)": _series(x, _columns(gt["radiance"], band), "C0", marker=""),
                   "path tracer, direct light only": _series(x, _columns(gt["direct"], band), "C0", linestyle=":",
                                                             marker=""),
                   "radiosity model": _series(x, _columns(model, band), "C1", linestyle="--", marker=""),
                   "local model": _series(x, _columns(loc, band), "C2", linestyle="-.", marker="")}}
    full = res.plots["Fig 1.21 reflexes in the shadow of a cylindrical bump: radiance across the bump"]
    zoom = _bump_zoom(spec, quality, _cells(task, quality))
    lit = max((v for ser in zoom.values() for v in ser["y"] if v is not None), default=1.0)
    res.plots["Fig 1.21 reflexes in the shadow of a cylindrical bump: inside the shadow (zoom)"] = dict(
        full, series=zoom, xlabel="x (the cast shadow: -0.6 < x < -0.3)", logy=True, ylim=[1e-3 * lit, 2.0 * lit],
        ylabel="radiance (zoom rows' mean, log scale)",
        title="Fig 1.21: in the shadow the light is interreflected only (direct: 0)")
    res.images["Fig 1.21 cylindrical bump: path tracer"] = _display(gt["radiance"], 0.9 * _exposure(gt["radiance"], _vis(gt)))
    return res


ZOOM = (-0.45, 0.3)      # Fig 1.21's zoom: centre x and half width (the cast shadow is -0.6 < x < -0.3)
ZOOM_RES = 96             # its own render: pixels across, at every quality
ZOOM_MIN_SPP = 256        # ... and at least this many samples (the reflex is about 1 % of the lit plane)


def _bump_zoom(spec, quality, cells) -> dict:
    """The series of Fig 1.21's zoom: the bump's scene rendered again through an orthographic
    camera over the cast shadow only (:data:`ZOOM`, :data:`ZOOM_RES` px, at least
    :data:`ZOOM_MIN_SPP` samples; the scene is uniform along y, so every row of it averages),
    full light transport and direct light only, beside the radiosity and local models at the
    same pixels.  At draft the scene's own render has 3 to 5 pixels across the shadow, and their
    reflex of about 0.01 is lost in the noise."""
    from pbrbench.render.variant import mitsuba
    from pbrbench.scene.mitsuba_dict import scene_dict

    x0, hw = ZOOM
    cam = spec.camera.model_copy(update={"origin": (x0, spec.camera.origin[1], spec.camera.origin[2]),
                                         "target": (x0, spec.camera.target[1], spec.camera.target[2]),
                                         "half_width": hw})
    zspec = spec.model_copy(update={"camera": cam})
    n = ZOOM_RES
    spp = max(ZOOM_MIN_SPP, quality.spp(4 * spec.render.spp) if quality is not None else 4 * spec.render.spp)
    mi = mitsuba()
    imgs = {}
    for name, integ in (("global", None), ("direct", {"type": "path", "max_depth": 2})):
        scene = mi.load_dict(scene_dict(mi, zspec, (n, n), spp, integrator=integ))
        imgs[name] = np.array(mi.render(scene, seed=spec.render.seed + 7), dtype=np.float64)[..., :3]
        del scene
    x = x0 + _x(zspec, n, n)
    rows = np.ones((n, n), bool)
    # the models through the scene's own camera at the zoom's pixel size, cropped to the zoom
    # (their patches are sized from the scene's view, so the solution is the same one)
    N = int(round(n * spec.camera.half_width / hw))
    model, loc = _models(spec, (N, N), cells)
    xs = _x(spec, N, N)
    cols = (xs >= x0 - hw) & (xs <= x0 + hw)
    ys = -xs                                      # rows go down: y = -x of the same grid
    band = np.zeros((N, N), bool)
    band[np.abs(ys) <= hw] = True
    band &= cols[None, :]
    return {f"path tracer (global), {spp} spp": _series(x, _columns(imgs["global"], rows), "C0", marker=""),
            "path tracer, direct light only": _series(x, _columns(imgs["direct"], rows), "C0", linestyle=":", marker=""),
            "radiosity model": _series(xs[cols], _columns(model, band)[cols], "C1", linestyle="--", marker=""),
            "local model": _series(xs[cols], _columns(loc, band)[cols], "C2", linestyle="-.", marker="")}


def _bleeding(task, job, gts, quality) -> JobResult:
    from pbrbench.radiosity.patches import rotation_matrix
    res = JobResult(job)
    gt, spec = gts[job.scene], task.scenes.spec(job.scene)
    H, W = gt['radiance'].shape[:2]
    alb = {i: np.asarray(spec.material_of(s).albedo, float) for i, s in enumerate(spec.shapes)}
    coloured = [i for i, a in alb.items() if np.ptp(a) > 0.2 and spec.shapes[i].type == "rectangle"]
    white = [i for i, a in alb.items() if np.ptp(a) < 1e-6 and spec.shapes[i].type == "rectangle"]
    if not coloured or not white:
        return res
    wall, floor = spec.shapes[coloured[0]], white[0]
    R = np.eye(3)
    for r in wall.rotate:
        R = rotation_matrix(r.axis, r.angle) @ R
    n = R @ np.array([0.0, 0.0, 1.0])
    on_floor = _vis(gt) & (gt["object_id"].astype(int) == floor + 1)
    dist = np.abs((gt["position"].astype(float) - np.asarray(wall.center)) @ n)
    bins = np.linspace(0.0, 2.0, 21)
    b = np.digitize(dist, bins) - 1
    ok = on_floor & (b >= 0) & (b < len(bins) - 1)
    model, loc = _models(spec, (H, W), _cells(task, quality))
    xm = 0.5 * (bins[1:] + bins[:-1])

    def red(img):
        a = np.asarray(img, float)
        s = a.sum(-1)
        chi = np.where(s > 0, a[..., 0] / np.where(s > 0, s, 1.0), np.nan)
        cnt = np.bincount(b[ok], minlength=len(xm))
        val = np.bincount(b[ok], np.nan_to_num(chi[ok]), minlength=len(xm))
        return np.where(cnt > 0, val / np.maximum(cnt, 1), np.nan)

    res.plots["§1.3.5 colour bleeding: red chromaticity of the white floor vs distance from the red wall"] = {
        "x": None, "xlabel": "distance from the red wall", "ylabel": "r / (r + g + b) on the white floor (1/3: grey)",
        "title": "§1.3.5 colour bleeding: the white floor turns pink near the red wall",
        "series": {"path tracer (global)": _series(xm, red(gt["radiance"]), "C3"),
                   "path tracer, direct light only": _series(xm, red(gt["direct"]), "C3", linestyle=":"),
                   "radiosity model": _series(xm, red(model), "C0", linestyle="--"),
                   "local model": _series(xm, red(loc), "C2", linestyle="-.")}}
    res.images["§1.3.5 colour bleeding: path tracer"] = _display(gt["radiance"], _exposure(gt["radiance"], _vis(gt)))
    return res


def _shadows(task, job, gts, quality) -> JobResult:
    from pbrbench.shading.irradiance import rectangle_polygon, visible_polygon_irradiance
    res = JobResult(job)
    frac, rad = {}, {}
    labels = {"shadow_near": "occluder near the floor", "shadow_far": "occluder near the source",
              "shadow_small": "small occluder, large source"}
    for k, name in enumerate([job.scene, *job.extra_scenes]):
        gt, spec = gts[name], task.scenes.spec(name)
        H, W = gt['radiance'].shape[:2]
        lights = [lt for lt in spec.lights if lt.type == "area"]
        occ = [s for s in spec.shapes if s.occluder and s.type == "rectangle"]
        recv = [s for s in spec.shapes if not s.occluder]
        if not lights or not occ or not recv or "unoccluded_fraction" not in gt:
            continue
        lt = lights[0]
        src = rectangle_polygon(lt.center, lt.size, lt.normal, lt.up)
        occs = [rectangle_polygon(o.center, o.size, (0.0, 0.0, 1.0)) for o in occ]
        rho = float(np.mean(spec.material_of(recv[0]).albedo))
        x = _x(spec, W, H)
        row = H // 2
        hh = spec.camera.half_width * H / W
        y = hh * (1.0 - 2.0 * (row + 0.5) / H)
        pts = np.stack([x, np.full_like(x, y), np.zeros_like(x)], -1)
        nz = np.array([0.0, 0.0, 1.0])
        L = float(np.mean(lt.radiance))
        vis = visible_polygon_irradiance(pts, nz, src, occs, L)
        full = visible_polygon_irradiance(pts, nz, src, [], L)
        label = labels.get(name.split("[")[0], name)
        col = f"C{k}"
        frac[f"{label}: path tracer"] = _series(x, gt["unoccluded_fraction"][row], col, marker="")
        frac[f"{label}: exact"] = _series(x, vis / np.maximum(full, 1e-300), col, linestyle="--", marker="")
        rad[f"{label}: path tracer"] = _series(x, grey(gt["radiance"])[row], col, marker="")
        rad[f"{label}: exact (rho E_visible / pi)"] = _series(x, rho * vis / np.pi, col, linestyle="--", marker="")
        fig = "Fig 1.6" if "small" in name else "Fig 1.5"
        res.images[f"{fig} {name}: {label} (path tracer)"] = _display(gt["radiance"], _exposure(gt["radiance"], _vis(gt)))
    if frac:
        res.plots["Figs 1.4-1.6 area-source shadows: fraction of the source visible across the shadow"] = {
            "x": None, "series": frac, "xlabel": "x on the floor (middle row)", "ylabel": "unoccluded fraction",
            "title": "Figs 1.4-1.6: umbra (0), penumbra (between) and no visible shadow"}
        res.plots["Figs 1.4-1.6 area-source shadows: radiance across the shadow"] = {
            "x": None, "series": rad, "xlabel": "x on the floor (middle row)", "ylabel": "radiance",
            "title": "Figs 1.4-1.6: path tracer vs the exact irradiance of the visible part of the source"}
    return res


PLOTS = {"groove": _groove, "rooms": _rooms, "bump": _bump, "bleeding": _bleeding, "shadows": _shadows}


def plot_job(task, job, gts, plot: str, quality) -> JobResult:
    """The figures of one plot job (no scores)."""
    if plot not in PLOTS:
        raise ValueError(f"plot={plot!r}: not a plot of the interreflection task ({', '.join(PLOTS)})")
    return PLOTS[plot](task, job, gts, quality)
