"""Specularity detection and removal on rendered glossy objects (SCIENCE.md §1).

Scenes (naming contract): ``specular_sphere``, ``specular_shapes`` (plastic / roughplastic); their
ground truth has ``diffuse_only``, the same scene with every coating removed.  The true specular
mask is where ``radiance - diffuse_only`` exceeds 10 % of the brightest diffuse radiance
(:func:`pbrbench.metrics.specular.specular_mask_from_twin`, ``reference="peak"``).

Conditions: ``global`` (the ``radiance`` render; the twin is rendered with the same integrator,
so it is the exact target) and ``global+noise0.01`` (1 % Gaussian noise of the peak).

Algorithms: :func:`pbrbench.infer.specular.remove_specularities` with each fill method after
:func:`pbrbench.infer.specular.detect_specularities` (defaults, restricted to the object mask);
``<fill>+true_mask`` (the same fill with the true specular mask: the fill's own error, without
detection errors); ``baseline:no_removal`` (the image unchanged, nothing detected).

Metrics: ``mask_iou`` of the detected vs the true mask (higher is better); from
:func:`pbrbench.metrics.specular.removal_errors` against the twin, ``inside_rel`` (relative RMS
error inside the true mask) and ``ring_rel`` (in a 3-pixel ring around it); ``image_rel_rmse``,
the relative RMS error vs the twin over the whole object.

Draft quality uses ``specular_sphere`` only.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer.specular import FILL_METHODS, detect_specularities, remove_specularities
from pbrbench.metrics.specular import mask_iou, removal_errors, specular_mask_from_twin
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult, Task

FAMILIES = ("specular_sphere", "specular_shapes")
NOISE = 0.01
NO_REMOVAL = "baseline:no_removal"
ORACLE = "+true_mask"
DIRECTIONS = {"mask_iou": "higher", "inside_rel": "lower", "ring_rel": "lower", "image_rel_rmse": "lower"}


class SpecularTask(Task):
    name = "specular"
    description = ("Find small bright blobs and replace them by smooth interpolation (the chapter's "
                   "§1.1 recipe), scored against the diffuse-only twin render.")
    algorithms = tuple(FILL_METHODS) + tuple(m + ORACLE for m in FILL_METHODS) + (NO_REMOVAL,)
    conditions = ("global", f"global+noise{NOISE:g}")
    headline_metric = "inside_rel"
    headline_better = "lower"
    families = FAMILIES
    draft_families = ("specular_sphere",)

    def jobs(self, quality: str) -> list[Job]:
        out = []
        for fam in C.families_for(self, quality):
            for s in C.family_scenes(fam):
                if s.has_glossy:
                    out += [Job(self.name, s.name, c) for c in self.conditions]
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0) -> JobResult:
        gt = gts[job.scene]
        _, mods = C.parse_condition(job.condition)
        obj = gt.mask
        img = np.maximum(np.asarray(gt["radiance"], np.float64), 0.0)
        if mods.get("noise", 0) > 0:
            img = C.add_noise(img, mods["noise"], C.job_rng(job, seed), peak=float(img[obj].max()))
        twin = np.asarray(gt["diffuse_only"], np.float64)
        true_mask = specular_mask_from_twin(gt["radiance"], twin, threshold=0.1, reference="peak", mask=obj)
        book = C.ScoreBook(job, C.scene_hash(gt))
        res = JobResult(job)
        res.images["linear:input"] = C.display(img)
        res.images["linear:truth (diffuse-only twin)"] = C.display(twin)
        res.images["specular mask: truth"] = C.display(true_mask.astype(float))
        detected = None
        det_seconds = 0.0
        for alg in self.algorithms:
            with C.Timer() as t:
                if alg == NO_REMOVAL:
                    mask, out = np.zeros_like(obj), img
                elif alg.endswith(ORACLE):
                    mask = true_mask
                    out = remove_specularities(img, mask, method=alg[: -len(ORACLE)])
                else:
                    if detected is None:
                        with C.Timer() as td:
                            detected = detect_specularities(img, mask=obj)
                        det_seconds = td.seconds
                    mask = detected
                    out = remove_specularities(img, mask, method=alg)
            seconds = t.seconds + (det_seconds if alg in FILL_METHODS else 0.0)
            sc = removal_errors(out, twin, true_mask, valid=obj)
            sc = {k: v for k, v in sc.items() if k in ("inside_rel", "ring_rel") and np.isfinite(v)}
            if not alg.endswith(ORACLE):
                sc["mask_iou"] = mask_iou(mask, true_mask)
            d = (out - twin)[obj]
            ref = float(np.sqrt(np.mean(twin[obj] ** 2))) if obj.any() else 0.0
            if ref > 0:
                sc["image_rel_rmse"] = float(np.sqrt(np.mean(d * d))) / ref
            book.add_all(alg, sc, seconds, DIRECTIONS)
            if alg == next(iter(FILL_METHODS)):
                res.images[f"specular mask: {alg}"] = C.display(mask.astype(float))
                res.images[f"linear:removed: {alg}"] = C.display(out)
                ref_b = max(float(C.grey(twin)[obj].max()), 1e-30) if obj.any() else 1.0
                res.error_maps[f"|removed - twin| / peak: {alg}"] = C.display_map(
                    np.where(obj, np.abs(C.grey(out) - C.grey(twin)) / ref_b, np.nan))
        res.scores = book.scores
        return res


TASK = SpecularTask()
