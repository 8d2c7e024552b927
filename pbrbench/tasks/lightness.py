"""Lightness (retinex) on rendered Mondrians, scored against the rendered albedo (SCIENCE.md §5).

Scenes (naming contract): ``mondrian_grey``, ``mondrian_colour``, ``mondrian_shadow`` (a cast
shadow: the known failure), ``mondrian_folded`` (a fold: interreflection between the papers).
The Mondrian is every shape whose material is ``paper`` (two panels for the folded one); their
fully covered pixels (ground-truth ``mask``) are the evaluation domain.

Conditions: ``local`` = the ``direct`` render (nearby source, no interreflection); ``global`` =
the ``radiance`` render (full interreflection; identical to ``local`` for a flat Mondrian up to
Monte Carlo noise, different for the folded one).

Ground truth: reflectance = the albedo AOV, shading = image / albedo.  Grey scenes (albedo equal
in every channel) are scored on the channel mean; colour scenes on RGB.

Algorithms: :func:`pbrbench.infer.lightness.retinex` with each anchor rule (``brightest``: the
brightest patch is white; ``mean``: the mean reflectance is fixed to ``MEAN_LIGHTNESS`` = 0.5, the
mean of the library's papers drawn uniformly in [0.1, 0.9]), the Grosse et al. per-component edge
rule, the illumination-subtracting edge variant, and two trivial baselines:
``baseline:image_is_reflectance`` (reflectance = image / its maximum, shading constant) and
``baseline:uniform_reflectance`` (reflectance = 0.5 everywhere, shading = image / 0.5).

Metrics (:mod:`pbrbench.metrics.lightness`): ``lmse`` of the reflectance (Grosse et al. 2009,
MIT variant, 20-pixel windows every 10, scaled to the image size at draft quality), the published
``intrinsic_lmse`` (mean of reflectance and shading LMSE), ``si_mse``, ``albedo_abs_err`` (no
rescaling: scores the anchor rule), and the worst / median relative error of reflectance ratios
between papers (``ratio_err_max``, ``ratio_err_median``; scale-free).

Draft quality uses ``mondrian_grey`` and ``mondrian_shadow`` only.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer.lightness import retinex, retinex_1d
from pbrbench.metrics.lightness import albedo_abs_error, intrinsic_lmse, lmse, ratio_errors, si_mse
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult, Task

FAMILIES = ("mondrian_grey", "mondrian_colour", "mondrian_shadow", "mondrian_folded")
MEAN_LIGHTNESS = 0.5
THRESHOLD = 0.05
ALGORITHMS = {
    "retinex:brightest": {"anchor": "brightest"},
    "retinex:mean": {"anchor": "mean", "mean_lightness": MEAN_LIGHTNESS},
    "retinex:brightest,component": {"anchor": "brightest", "edge_rule": "component"},
    "retinex:brightest,subtract": {"anchor": "brightest", "edge_illumination": "subtract"},
}
IMAGE_IS_REFLECTANCE = "baseline:image_is_reflectance"
UNIFORM = "baseline:uniform_reflectance"
DIRECTIONS = {"lmse": "lower", "intrinsic_lmse": "lower", "si_mse": "lower", "albedo_abs_err": "lower",
              "ratio_err_max": "lower", "ratio_err_median": "lower"}


def patch_labels(albedo: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Integer labels of the distinct albedo values (rounded to 1e-3) inside ``mask``; -1 outside."""
    a = np.asarray(albedo, float)
    a = a[..., None] if a.ndim == 2 else a
    key = np.round(a.reshape(-1, a.shape[-1]) * 1000).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    lab = inv.reshape(a.shape[:2]).astype(np.int64)
    return np.where(mask, lab, -1)


def baseline(name: str, image: np.ndarray, mask: np.ndarray):
    """(reflectance, shading) of a trivial baseline."""
    m = mask[..., None] if image.ndim == 3 else mask
    if name == IMAGE_IS_REFLECTANCE:
        peak = image[mask].max(axis=0)
        refl = np.where(m, image / np.maximum(peak, 1e-30), 0.0)
        shad = np.where(m, np.broadcast_to(peak, image.shape), 0.0)
    elif name == UNIFORM:
        refl = np.where(m, MEAN_LIGHTNESS, 0.0) * np.ones_like(image)
        shad = np.where(m, image / MEAN_LIGHTNESS, 0.0)
    else:
        raise ValueError(f"algorithm: {name!r} is not a baseline of the lightness task")
    return refl, shad


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
    algorithms = tuple(ALGORITHMS) + (IMAGE_IS_REFLECTANCE, UNIFORM)
    conditions = ("local", "global")
    headline_metric = "lmse"
    headline_better = "lower"
    families = FAMILIES
    draft_families = ("mondrian_grey", "mondrian_shadow")

    def jobs(self, quality: str) -> list[Job]:
        out = []
        for fam in C.families_for(self, quality):
            for s in C.family_scenes(fam):
                paper = tuple(i + 1 for i, sh in enumerate(s.shapes) if sh.material == "paper")
                p = (("paper_ids", paper),)
                for cond in self.conditions:
                    out.append(Job(self.name, s.name, cond, p))
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0) -> JobResult:
        gt = gts[job.scene]
        base, _ = C.parse_condition(job.condition)
        img = np.asarray(gt["radiance" if base == "global" else "direct"], float)
        alb = np.asarray(gt["albedo"], float)
        ids = tuple(job.param("paper_ids", ()) or ())
        mask = gt.mask & (alb.min(axis=-1) > 0) & (img.min(axis=-1) > 0)
        if ids and "object_id" in gt:
            mask &= np.isin(np.rint(gt["object_id"]), ids)
        colour = float(np.ptp(alb[mask], axis=-1).max()) > 1e-3 if mask.any() else False
        if not colour:
            img, alb = C.grey(img), C.grey(alb)
        m = mask if img.ndim == 2 else mask[..., None]
        shad_true = np.where(m, img / np.where(m, alb, 1.0), 0.0)
        alb = np.where(m, alb, 0.0)
        img = np.where(m, img, 0.0)
        labels = patch_labels(alb, mask)
        win = int(min(20, max(4, min(img.shape[:2]) // 4)))
        book = C.ScoreBook(job, C.scene_hash(gt))
        res = JobResult(job)
        res.images["linear:input"] = C.display(img)
        res.images["reflectance: truth"] = C.display(np.clip(alb, 0, 1))
        row = shadow_row(gt, mask)
        cols = np.flatnonzero(mask[row])
        prof = {"image / max": img[row] / max(float(img[row][mask[row]].max()), 1e-30) if cols.size else img[row],
                "true reflectance": alb[row]}
        for alg in self.algorithms:
            with C.Timer() as t:
                if alg in ALGORITHMS:
                    refl, shad = retinex(img, mask=mask, threshold=THRESHOLD, **ALGORITHMS[alg])
                else:
                    refl, shad = baseline(alg, img, mask)
            sc = {"lmse": lmse(refl, alb, mask=mask, window=win),
                  "intrinsic_lmse": intrinsic_lmse(refl, shad, alb, shad_true, mask=mask, window=win),
                  "si_mse": si_mse(refl, alb, mask=mask),
                  "albedo_abs_err": albedo_abs_error(refl, alb, mask=mask)}
            if alg != UNIFORM:
                try:
                    r = np.abs(ratio_errors(refl, alb, labels, mask=mask, erode=1))
                    r = r[np.isfinite(r)]
                    if r.size:
                        sc["ratio_err_max"] = float(r.max())
                        sc["ratio_err_median"] = float(np.median(r))
                except ValueError:
                    pass
            book.add_all(alg, sc, t.seconds, DIRECTIONS)
            if alg in ("retinex:brightest", "retinex:mean", IMAGE_IS_REFLECTANCE):
                res.images[f"reflectance: {alg}"] = C.display(np.clip(refl, 0, 1))
            if alg == "retinex:brightest":
                g_est, g_true = C.grey(refl), C.grey(alb)
                with np.errstate(divide="ignore", invalid="ignore"):
                    lr = np.where(mask, np.log2(g_est / g_true), np.nan)
                lr -= np.nanmedian(lr)
                res.error_maps[f"log2 reflectance error (median removed): {alg}"] = C.display_map(lr)
                prof[f"reflectance: {alg}"] = refl[row]
        if cols.size > 1:
            seg = slice(cols[0], cols[-1] + 1)
            r1, _ = retinex_1d(np.maximum(img[row, seg], 1e-12), threshold=THRESHOLD, anchor="brightest")
            full = np.full(img.shape[1:] if img.ndim == 3 else img.shape[1], np.nan)
            full[seg] = r1
            prof["reflectance: retinex_1d (this row)"] = full
            if "unoccluded_fraction" in gt:
                prof["unoccluded fraction"] = gt["unoccluded_fraction"][row]
            series = {k: np.asarray(v, float).mean(axis=-1) if np.ndim(v) == 2 else v for k, v in prof.items()}
            res.plots[f"profile along row {row}"] = C.profile_plot(
                np.arange(img.shape[1]), series, "column (pixels)", "value (grey)",
                note="row crossing the cast shadow" if "unoccluded_fraction" in gt else "middle row")
        res.scores = book.scores
        return res


TASK = LightnessTask()
