"""Lightness (retinex) on rendered Mondrians, scored against the rendered albedo.

Scenes: ``mondrian_grey``, ``mondrian_colour``, ``mondrian_shadow`` (a cast shadow: the known
failure), ``mondrian_folded`` (a fold: interreflection between the papers).  The Mondrian is every
shape whose material is ``paper`` (two panels for the folded one); their fully covered pixels
(ground-truth ``mask``) are the evaluation domain.

Conditions: ``local`` = the ``direct`` render (a nearby point source, no interreflection);
``area`` = the ``direct`` render of the ``*_area`` twin (the point source replaced by a small area
source with the same irradiance at the centre: softer cast shadows); ``global`` = the
``radiance`` render (full interreflection; identical to ``local`` for a flat Mondrian up to Monte
Carlo noise, different for the folded one and where the rod of ``mondrian_shadow`` reflects light
onto the paper); ``local+ambient0.1`` = the ``direct`` render plus the chapter's ambient term
(§1.1.3, *Image = Diffuse + Ambient*): a constant ambient illumination ``A`` added to the shading,
i.e. ``rho A`` added to the image, with ``A`` = :data:`AMBIENT` (0.1) times the median direct
shading (``direct / albedo``, per channel) over the paper's lit pixels.  It is added here, when the
task makes the algorithm's input, not rendered: the local model's own term, exactly ``rho A``, with
no interreflection that would come with a rendered environment (that is ``global``).  The paper's
reflectance ratios across an edge are unchanged (``rho_1 (S + A) / rho_2 (S + A)``); what changes is
the cast shadow of ``mondrian_shadow``: its umbra, black under ``local`` (and so outside the
evaluation domain, which keeps only pixels of positive image), becomes ``rho A``, part of the
domain, with a finite step ``(S + A) / A`` at its border that a retinex can read as a paint edge:
shadows are not black (§1.1.2).  The true shading of the condition is ``S + A`` (image / albedo).

Ground truth: reflectance = the albedo AOV, shading = image / albedo.  Grey scenes (albedo equal
in every channel) are scored on the channel mean; colour scenes on RGB.

Algorithms (from the registry), each called as ``fn(image, *, mask)`` with a linear (H, W) or
(H, W, 3) image, returning ``(reflectance, shading)`` of the image's shape: every method of
:data:`pbrbench.infer.lightness.METHODS` with the task's threshold (``THRESHOLD``), its variants
listed in ``VARIANTS`` (``<method>:<variant>``: other anchor or edge rules), any plugin, and two
trivial baselines: ``baseline:image_is_reflectance`` (reflectance = image / its maximum, shading
constant) and ``baseline:uniform_reflectance`` (reflectance = 0.5 everywhere, shading = image / 0.5).

Metrics: :func:`pbrbench.metrics.lightness.lightness_scores` (LMSE with 20-pixel windows every
10, scaled to the image size at small resolutions, the intrinsic LMSE, scale-invariant MSE, the
absolute albedo error that scores the anchor rule, reflectance-ratio errors between papers).
"""

from __future__ import annotations

import numpy as np

from pbrbench.metrics.lightness import lightness_scores
from pbrbench.registry import Algorithm
from pbrbench.tasks.base import Job, JobResult, Prediction, Task, parse_condition
from pbrbench.tasks.common.figures import display, display_map, profile_plot
from pbrbench.tasks.common.inputs import grey
from pbrbench.tasks.common.scoring import ScoreBook, attribute, call, check_array, scene_hash

FAMILIES = ("mondrian_grey", "mondrian_colour", "mondrian_shadow", "mondrian_folded")
MEAN_LIGHTNESS = 0.5   # the mean of the library's papers, drawn uniformly in [0.1, 0.9]
THRESHOLD = 0.05
AMBIENT = 0.1          # the ambient illumination of ``local+ambient``: this fraction of the median direct shading
# configurations scored beside each method's default (method -> variant -> options)
VARIANTS = {
    "blake1985": {
        "mean": {"anchor": "mean", "mean_lightness": MEAN_LIGHTNESS},
        "component": {"anchor": "brightest", "edge_rule": "component"},
        "subtract": {"anchor": "brightest", "edge_illumination": "subtract"},
    },
}


def image_is_reflectance(image, *, mask):
    """``baseline:image_is_reflectance``: reflectance = image / its maximum, shading constant."""
    m = mask[..., None] if image.ndim == 3 else mask
    peak = image[mask].max(axis=0)
    refl = np.where(m, image / np.maximum(peak, 1e-30), 0.0)
    shad = np.where(m, np.broadcast_to(peak, image.shape), 0.0)
    return refl, shad


def uniform_reflectance(image, *, mask):
    """``baseline:uniform_reflectance``: reflectance 0.5 everywhere, shading = image / 0.5."""
    m = mask[..., None] if image.ndim == 3 else mask
    refl = np.where(m, MEAN_LIGHTNESS, 0.0) * np.ones_like(image)
    shad = np.where(m, image / MEAN_LIGHTNESS, 0.0)
    return refl, shad


def with_ambient(image: np.ndarray, albedo: np.ndarray, paper: np.ndarray, level: float) -> np.ndarray:
    """The image plus the chapter's ambient term ``rho A`` (*Image = Diffuse + Ambient*).

    Parameters
    ----------
    image : ndarray
        The direct render, (H, W, 3) linear radiance.
    albedo : ndarray
        The albedo AOV ``rho``, (H, W, 3).
    paper : ndarray
        (H, W) bool: the Mondrian's pixels (albedo above zero).
    level : float
        ``A`` as a fraction of the median direct shading ``image / albedo`` over the paper's lit
        pixels (per channel: the ambient light has the colour of the source).

    Returns
    -------
    ndarray
        ``image + albedo * A`` on the paper, ``image`` elsewhere; ``A`` is 0 where no paper pixel
        is lit.
    """
    img = np.asarray(image, float)
    alb = np.asarray(albedo, float)
    m = paper[..., None]
    shading = np.divide(img, alb, out=np.zeros_like(img), where=m & (alb > 0))
    lit = paper & (shading.min(axis=-1) > 0)
    a = level * np.median(shading[lit], axis=0) if lit.any() else np.zeros(img.shape[-1])
    return np.where(m, img + alb * a, img)


def patch_labels(albedo: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Integer labels of the distinct albedo values (rounded to 1e-3) inside ``mask``; -1 outside."""
    a = np.asarray(albedo, float)
    a = a[..., None] if a.ndim == 2 else a
    key = np.round(a.reshape(-1, a.shape[-1]) * 1000).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    lab = inv.reshape(a.shape[:2]).astype(np.int64)
    return np.where(mask, lab, -1)


def shadow_row(gt, mask: np.ndarray) -> int:
    """The row to profile: the one crossing the deepest cast shadow (scenes with an occluder),
    else the middle row."""
    h = mask.shape[0]
    if "unoccluded_fraction" in gt:
        f = np.where(mask, gt["unoccluded_fraction"], 1.0)
        edge = np.abs(np.diff(f, axis=1)).sum(axis=1)
        if edge.max() > 0.2:
            return int(np.argmax(edge))
    return h // 2


class LightnessTask(Task):
    name = "lightness"
    description = ("Retinex (Land & McCann 1971; Horn 1974; Blake 1985) on rendered Mondrians: "
                   "reflectance vs the albedo AOV, with a cast shadow and a fold as the known failures.")
    conditions = ("local", f"local+ambient{AMBIENT:g}", "area", "global")
    headline_metric = "lmse"
    families = FAMILIES
    short_families = ("mondrian_grey", "mondrian_shadow", "mondrian_folded")

    def builtin_algorithms(self) -> list[Algorithm]:
        from pbrbench.infer.lightness import METHODS

        out = []
        for n, fn in METHODS.items():
            out.append(Algorithm(n, self.name, fn, options={"threshold": THRESHOLD}))
            for v, opts in VARIANTS.get(n, {}).items():
                out.append(Algorithm(f"{n}:{v}", self.name, fn, options={"threshold": THRESHOLD, **opts}))
        out += [Algorithm("baseline:image_is_reflectance", self.name, image_is_reflectance, kind="baseline"),
                Algorithm("baseline:uniform_reflectance", self.name, uniform_reflectance, kind="baseline")]
        return out

    # --------------------------------------------------- export / evaluate (pbrbench.bench.external)
    input_names = ("image",)
    predictions = (
        Prediction("reflectance", "image", False, "reflectance (any scale); missing: image / shading"),
        Prediction("shading", "image", False, "shading (any scale); missing: image / reflectance"),
    )

    def prediction_output(self, files: dict, inputs: dict):
        out = dict(files)
        if not out:
            raise ValueError("prediction: write reflectance or shading (or both)")
        image = np.asarray(inputs["image"], float)
        for want, have in (("reflectance", "shading"), ("shading", "reflectance")):
            if want not in out:
                h = np.asarray(out[have], float)
                out[want] = np.divide(image, h, out=np.zeros_like(image), where=h > 0)
        return out

    def jobs(self, quality) -> list[Job]:
        out = []
        for fam in quality.pick(self.families, self.short_families):
            twins = self.scenes.family(f"{fam}_area")
            for i, s in enumerate(self.scenes.family(fam)):
                paper = tuple(i + 1 for i, sh in enumerate(s.shapes) if sh.material == "paper")
                p = (("paper_ids", paper),)
                out.append(Job(self.name, s.name, "local", p))
                out.append(Job(self.name, s.name, f"local+ambient{AMBIENT:g}", p))
                out.append(Job(self.name, s.name, "global", p))
                if i < len(twins):
                    tw = twins[i]
                    tp = tuple(k + 1 for k, sh in enumerate(tw.shapes) if sh.material == "paper")
                    out.append(Job(self.name, tw.name, "area", (("paper_ids", tp),)))
        out += [Job(self.name, s.name, "local", (("plot", "retexture"),)) for s in self.scenes.family(RETEXTURE)[:1]]
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        if job.param("plot") == "retexture":
            return retexture_figures(job, gts[job.scene], self.library_spec(job.scene))
        algorithms = [a for a in algorithms if a.applies(job.condition)]
        gt = gts[job.scene]
        base, mods = parse_condition(job.condition)
        img = np.asarray(gt["radiance" if base == "global" else "direct"], float)
        alb = np.asarray(gt["albedo"], float)
        ids = tuple(job.param("paper_ids", ()) or ())
        paper = gt.mask & (alb.min(axis=-1) > 0)
        if ids and "object_id" in gt:
            paper &= np.isin(np.rint(gt["object_id"]), ids)
        if mods.get("ambient"):
            img = with_ambient(img, alb, paper, mods["ambient"])
        mask = paper & (img.min(axis=-1) > 0)
        colour = float(np.ptp(alb[mask], axis=-1).max()) > 1e-3 if mask.any() else False
        if not colour:
            img, alb = grey(img), grey(alb)
        m = mask if img.ndim == 2 else mask[..., None]
        shad_true = np.where(m, img / np.where(m, alb, 1.0), 0.0)
        alb = np.where(m, alb, 0.0)
        img = np.where(m, img, 0.0)
        labels = patch_labels(alb, mask)
        win = int(min(20, max(4, min(img.shape[:2]) // 4)))
        book = ScoreBook(job, scene_hash(gt), algorithms)
        res = JobResult(job)
        res.images["linear:input"] = display(img)
        res.images["reflectance: truth"] = display(np.clip(alb, 0, 1))
        row = shadow_row(gt, mask)
        cols = np.flatnonzero(mask[row])
        prof = {"image / max": img[row] / max(float(img[row][mask[row]].max()), 1e-30) if cols.size else img[row],
                "true reflectance": alb[row]}

        inside = np.broadcast_to(m, img.shape)

        def check(out):
            refl, shad = attribute(out, "reflectance", 0), attribute(out, "shading", 1)
            if refl is None or shad is None:
                raise ValueError("output: return (reflectance, shading) of the image's shape")
            return (check_array(refl, "reflectance", img.shape, where=inside),
                    check_array(shad, "shading", img.shape, where=inside))

        first = True
        for alg in algorithms:
            out, seconds, err = call(alg, img, mask=mask, quality=quality, check=check)
            if err is not None:
                book.add(alg.name, {"failed": 1.0}, seconds)
                res.failures[alg.name] = err
                continue
            refl, shad = out
            sc = lightness_scores(refl, shad, alb, shad_true, mask=mask, labels=labels, window=win)
            book.add(alg.name, sc, seconds)
            if alg.figures:
                res.images[f"reflectance: {alg.name}"] = display(np.clip(refl, 0, 1))
            if first and alg.kind == "method":
                first = False
                g_est, g_true = grey(refl), grey(alb)
                with np.errstate(divide="ignore", invalid="ignore"):
                    lr = np.where(mask, np.log2(g_est / g_true), np.nan)
                lr -= np.nanmedian(lr)
                res.error_maps[f"log2 reflectance error (median removed): {alg.name}"] = display_map(lr)
                prof[f"reflectance: {alg.name}"] = refl[row]
        if cols.size > 1:
            from pbrbench.infer.lightness import retinex_1d

            seg = slice(cols[0], cols[-1] + 1)
            r1, _ = retinex_1d(np.maximum(img[row, seg], 1e-12), threshold=THRESHOLD, anchor="brightest")
            full = np.full(img.shape[1:] if img.ndim == 3 else img.shape[1], np.nan)
            full[seg] = r1
            prof["reflectance: 1-D retinex of this row (Horn 1974)"] = full
            if base == "local" and not mods and job.scene.split("[")[0] == CHAPTER_1D_FAMILY:
                res.plots[FIG_1_11] = lightness_1d_figure(grey(img)[row, seg], seg.start, THRESHOLD)
            if "unoccluded_fraction" in gt:
                prof["unoccluded fraction"] = gt["unoccluded_fraction"][row]
            series = {k: np.asarray(v, float).mean(axis=-1) if np.ndim(v) == 2 else v for k, v in prof.items()}
            res.plots[f"profile along row {row}"] = profile_plot(
                np.arange(img.shape[1]), series, "column (pixels)", "value (grey)",
                note="row crossing the cast shadow" if "unoccluded_fraction" in gt else "middle row")
        res.scores = book.scores
        return res


CHAPTER_1D_FAMILY = "mondrian_grey"
RETEXTURE = "retexture"     # Fig 1.22's scene family: one shape twice, plain and textured (a figure, no score)


def retexture_figures(job: Job, gt, spec) -> JobResult:
    """Fig 1.22 from the ``retexture`` render: the two copies (plain, textured), their shading
    ``radiance / albedo`` (the same on both: the texture changes the albedo, not the shading),
    and the shading of both along the middle row, in each copy's own x."""
    from pbrbench.shading.surfaces import pixel_grid

    res = JobResult(job)
    img = np.asarray(gt["radiance"], float)
    alb = np.asarray(gt["albedo"], float)
    m = gt.mask & (alb.min(axis=-1) > 0)
    shading = np.where(m[..., None], img / np.where(alb > 0, alb, 1.0), 0.0)
    res.images["linear:Fig 1.22 one shape under one source, plain and textured: the render"] = display(img, 256)
    res.images["linear:Fig 1.22 the shading, radiance / albedo: the same on both copies"] = display(shading, 256)
    H, W = img.shape[:2]
    ids = np.rint(np.asarray(gt["object_id"], float)).astype(int) if "object_id" in gt else None
    if spec is None or ids is None or len(spec.shapes) < 2:
        return res
    x = pixel_grid(H, W, spec.camera.half_width)[0][0]
    row = H // 2
    series = {}
    for k, (sh, col) in enumerate(zip(spec.shapes[:2], ("C0", "C1"), strict=True)):
        on = m[row] & (ids[row] == k + 1)
        xl = (x - sh.center[0])[on]
        series[f"shading, {sh.name} copy"] = {"x": xl.tolist(), "y": grey(shading)[row][on].tolist(), "color": col,
                                              "marker": "", "linestyle": "-" if k == 0 else "--"}
        series[f"radiance, {sh.name} copy"] = {"x": xl.tolist(), "y": grey(img)[row][on].tolist(), "color": col,
                                               "marker": "", "linestyle": ":"}
    res.plots["Fig 1.22 shading and radiance along the middle row of each copy"] = {
        "x": None, "series": series, "xlabel": "x within the copy", "ylabel": "grey value",
        "title": "Fig 1.22: the texture changes the radiance (dotted), not the shading"}
    return res


FIG_1_11 = ("Fig 1.11 lightness in 1-D (Horn 1974) along a row of the grey Mondrian: the log image, its "
            "derivative, the derivative thresholded (paint edges kept, shading gradients dropped) and its "
            "integral, the log reflectance up to the brightest paper")


def lightness_1d_figure(row, start: int, threshold: float) -> dict:
    """Fig 1.11's four curves for one image row (grey values > 0): ``log C``, ``d = diff log C``,
    ``d`` where ``|d| > threshold`` (else 0), and its running sum with the brightest point at 0."""
    c = np.log(np.maximum(np.asarray(row, float), 1e-12))
    d = np.diff(c)
    dt = np.where(np.abs(d) > threshold, d, 0.0)
    integral = np.concatenate([[0.0], np.cumsum(dt)])
    pad = np.concatenate
    return profile_plot(np.arange(start, start + c.size),
                        {"log image": c, "log derivative": pad([d, [np.nan]]),
                         f"thresholded (|d| > {threshold:g})": pad([dt, [np.nan]]),
                         "integral: log reflectance (brightest = 0)": integral - integral.max()},
                        "column (pixels)", "natural log", note=f"threshold {threshold:g} per pixel")


TASK = LightnessTask()
