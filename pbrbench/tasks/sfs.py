"""Shape from one shaded image on the scene library (SCIENCE.md §7).

Scenes: ``sfs_sphere``, ``sfs_vase``, ``sfs_random`` and their ``*_area`` twins.  Each has a light
set of two sources (``light00`` along the view, ``light01`` oblique, 45 degrees in x), rendered one
at a time; each light is a separate case, scored under the scene label ``<scene>:view`` or
``<scene>:oblique`` (a scene with a single light in ``lights`` is one case under its own name).
Input: one grey image (channel mean); the light is the case's nominal source (direction in the
camera frame; for an area twin ``normalize(center - target)``) and the albedo is the known ``rho E / pi`` (median albedo AOV times
the nominal irradiance over pi), as every method assumes a known uniform albedo.

Conditions: ``local`` (``direct``), ``local+noise0.01`` (1 % Gaussian noise of the peak),
``area`` (the ``*_area`` twin's ``direct``: a nearby rectangle along the nominal direction) and
``global`` (``radiance``: interreflection).

Algorithms: every method of :func:`pbrbench.infer.sfs.shape_from_shading` with the known light,
the same with the light (and albedo) estimated by :func:`pbrbench.infer.sfs.light_from_shading`
(``<method>+estimated_light``; condition ``local`` only, to keep the run short), and the two
references that always stand beside them: ``baseline:flat`` (z = 0, normals along the view) and
``floor:integrate_true_normals`` (the true normals through the same least-squares integrator).

Metrics (:mod:`pbrbench.metrics.sfs`): height RMSE and mean absolute error after removing the
free offset (world units, ``height_rmse``, ``height_mae``), the same after the best scale
(``height_rmse_scaled``, ``height_mae_scaled``), RMSE relative to the true height range
(``height_rmse_rel``), the mean normal angle (``normal_mean_deg``), the convex/concave-ambiguity-
aware ``height_rmse_flip`` and ``normal_mean_deg_flip`` (the better of ``z`` and ``-z``: under a
frontal light both give the same image), ``converged`` (1 when the method met its tolerance; the
only higher-is-better score), ``failed`` (1 when the method raised ``ValueError`` for this input;
then it has no other score; ``kimmel2001`` without a singular point no longer raises but seeds
the brightest pixels with a warning)
and, for the light estimate, ``light_error_deg``.  The floor uses the
SFS methods' own integrator (:func:`pbrbench.metrics.sfs.floor_scores`).

Draft quality uses ``sfs_sphere`` (and its twin) only, with iteration budgets capped
(``DRAFT_OPTIONS``: horn1989 300, tsai_shah1994 200 iterations).
"""

from __future__ import annotations

import warnings

import numpy as np

from pbrbench.infer.sfs import METHODS as SFS_METHODS
from pbrbench.infer.sfs import light_from_shading, shape_from_shading
from pbrbench.metrics.sfs import flat_baseline, floor_height, floor_scores, sfs_scores
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult, Task

FAMILIES = ("sfs_sphere", "sfs_vase", "sfs_random")
NOISE = 0.01
FLAT = "baseline:flat"
FLOOR = "floor:integrate_true_normals"
EST = "+estimated_light"
LIGHT_EST = "light_from_shading:contour"
# iteration budgets at draft quality (the regression run must stay short; standard uses the
# methods' own defaults)
DRAFT_OPTIONS = {"horn1989": {"max_iter": 300}, "tsai_shah1994": {"max_iter": 200}}
DIRECTIONS = {"converged": "higher"}  # every other metric: lower is better


def rename(scores: dict, pixel_range: float | None = None) -> dict:
    """Metric names of :mod:`pbrbench.metrics.sfs` -> the task's score names."""
    names = {"rmse": "height_rmse", "mae": "height_mae", "rmse_scaled": "height_rmse_scaled",
             "mae_scaled": "height_mae_scaled", "normal_angle": "normal_mean_deg",
             "rmse_ambiguous": "height_rmse_flip", "normal_angle_ambiguous": "normal_mean_deg_flip"}
    out = {names[k]: float(v) for k, v in scores.items() if k in names}
    if pixel_range and "height_rmse" in out:
        out["height_rmse_rel"] = out["height_rmse"] / pixel_range
    return out


class SFSTask(Task):
    name = "sfs"
    description = ("Shape from one shaded image (Horn 1989, Tsai-Shah 1994, Pentland 1990, Kimmel-"
                   "Sethian 2001) with the flat baseline and the true-normal integration floor.")
    algorithms = (tuple(SFS_METHODS) + tuple(m + EST for m in SFS_METHODS) + (FLAT, FLOOR, LIGHT_EST))
    conditions = ("local", f"local+noise{NOISE:g}", "area", "global")
    headline_metric = "normal_mean_deg"
    headline_better = "lower"
    families = FAMILIES
    draft_families = ("sfs_sphere",)

    @staticmethod
    def _params(spec, light, index, quality) -> tuple:
        d, e = C.nominal_light(light, spec.camera)
        label = "view" if d[2] > 0.999 else "oblique"
        return (("light", C.as_param(d)), ("irradiance", round(float(e), 9)), ("light_index", index),
                ("label", label), ("half_width", float(spec.camera.half_width)), ("draft", quality == "draft"))

    @staticmethod
    def _cases(spec):
        """(light, index) pairs: each light of the light set (rendered alone as ``lightNN.*``), or
        the single light of ``lights`` (rendered as ``direct`` / ``radiance``)."""
        if spec.light_set:
            return [(li, k) for k, li in enumerate(spec.light_set)]
        if len(spec.lights) == 1:
            return [(spec.lights[0], -1)]
        return []

    def jobs(self, quality: str) -> list[Job]:
        out = []
        for fam in C.families_for(self, quality):
            twins = C.family_scenes(f"{fam}_area")
            for i, s in enumerate(C.family_scenes(fam)):
                tw = twins[i] if i < len(twins) else None
                tw_cases = dict((k, li) for li, k in self._cases(tw)) if tw is not None else {}
                for light, k in self._cases(s):
                    p = self._params(s, light, k, quality)
                    out.append(Job(self.name, s.name, "local", p))
                    out.append(Job(self.name, s.name, f"local+noise{NOISE:g}", p))
                    out.append(Job(self.name, s.name, "global", p))
                    if k in tw_cases:
                        out.append(Job(self.name, tw.name, "area", self._params(tw, tw_cases[k], k, quality)))
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0) -> JobResult:
        gt = gts[job.scene]
        base, mods = C.parse_condition(job.condition)
        k = int(job.param("light_index", -1))
        kind = "radiance" if base == "global" else "direct"
        img = C.grey(gt[kind if k < 0 else f"light{k:02d}.{kind}"])
        if mods.get("noise", 0) > 0:
            img = C.add_noise(img, mods["noise"], C.job_rng(job, seed))
        mask = gt.mask
        light = np.asarray(job.param("light"), float)
        irr = float(job.param("irradiance", np.pi))
        rho = float(np.median(C.grey(gt["albedo"])[mask])) if mask.any() else 1.0
        known_albedo = rho * irr / np.pi
        px = C.pixel_size(job.param("half_width", 1.0), img.shape[1])
        z_true = np.where(mask, -gt["depth"].astype(float), 0.0)
        zrange = float(np.ptp(z_true[mask])) if mask.any() else None
        n_true = gt["normals"].astype(float)
        draft = bool(job.param("draft", False))
        label = job.param("label")
        book = C.ScoreBook(job, C.scene_hash(gt), scene_label=f"{job.scene}:{label}" if label else None)
        res = JobResult(job)
        res.images["linear:input"] = C.display(img)
        res.images["normals: truth"] = C.normals_display(n_true, mask)
        row = img.shape[0] // 2
        zt_row = np.where(mask[row], z_true[row] - z_true[mask].mean(), np.nan)
        prof = {"truth": zt_row}

        runs = [(m, light, known_albedo) for m in SFS_METHODS]
        if base == "local" and not mods:
            try:
                est = light_from_shading(img, mask)
                ang = float(np.degrees(np.arccos(np.clip(np.dot(est.direction, light / np.linalg.norm(light)), -1, 1))))
                book.add(LIGHT_EST, "light_error_deg", ang, 0.0, "lower")
                runs += [(m + EST, est.direction, est.albedo) for m in SFS_METHODS]
            except ValueError:
                pass
        for alg, s, alb in runs:
            method = alg.split("+")[0]
            opts = DRAFT_OPTIONS.get(method, {}) if draft else {}
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                with C.Timer() as t:
                    try:
                        r = shape_from_shading(img, s, method=method, albedo=alb, mask=mask, pixel_size=px, **opts)
                    except ValueError:
                        r = None  # the method refuses this input: scored as a failure
            if r is None:
                book.add(alg, "failed", 1.0, t.seconds, "lower")
                continue
            sc = rename(sfs_scores(r.height, r.normals, z_true, n_true, mask), zrange)
            sc["converged"] = float(r.converged)
            sc["failed"] = 0.0
            book.add_all(alg, sc, t.seconds, DIRECTIONS)
            if EST not in alg:
                prof[alg] = np.where(mask[row], r.height[row], np.nan)
                res.images[f"normals: {alg}"] = C.normals_display(r.normals, mask)
                res.error_maps[f"height error (offset removed): {alg}"] = C.display_map(
                    np.where(mask, (r.height - r.height[mask].mean()) - (z_true - z_true[mask].mean()), np.nan))
        # the two references
        with C.Timer() as t:
            sc = rename(flat_baseline(z_true, n_true, mask), zrange)
        book.add_all(FLAT, sc, t.seconds, DIRECTIONS)
        prof[FLAT] = np.where(mask[row], 0.0, np.nan)
        dom = mask & (n_true[..., 2] > 1e-3)
        with C.Timer() as t:
            sc = rename(floor_scores(z_true, n_true, dom, pixel_size=px), zrange)
        book.add_all(FLOOR, sc, t.seconds, DIRECTIONS)
        z_floor = floor_height(n_true, dom, pixel_size=px)
        prof[FLOOR] = np.where(dom[row], z_floor[row], np.nan)
        res.plots[f"height profile, row {row}"] = C.profile_plot(
            np.arange(img.shape[1]) * px, prof, "x (world units from the left edge)", "height (offset removed)")
        res.scores = book.scores
        return res


TASK = SFSTask()
