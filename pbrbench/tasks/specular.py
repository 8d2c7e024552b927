"""Specularity detection and removal on rendered glossy objects.

Scenes: ``specular_sphere``, ``specular_shapes`` (plastic / roughplastic); their ground truth has
``diffuse_only``, the same scene with every coating removed.  The true specular mask is where
``radiance - diffuse_only``, averaged over the 3 x 3 neighbourhood on the object, exceeds 10 % of
the brightest diffuse radiance (:func:`pbrbench.metrics.specular.specular_mask_from_twin`,
``reference="peak"``, ``window=3``: pixelwise, the noise of the two renders decided most of the
mask of ``specular_shapes``'s rough lobes, and the ``+true_mask`` floors moved by 4.7 combined
standard errors between two render seeds).

Conditions: ``global`` (the ``radiance`` render; the twin is rendered with the same integrator,
so it is the exact target) and ``global+noise0.01`` (1 % Gaussian noise of the peak).  There is no
``local`` / ``area`` axis: the chapter's recipe (find small bright blobs, fill them from their
surroundings) does not model the light transport, and the glossy lobe of an area source is not a
small blob, so a direct-only or an area-source twin would measure the detector's size prior, not
the cost of an effect.

Algorithms (from the registry), by calling convention (``interface``):

* main -- ``fn(image, *, mask) -> (detected_mask, removed_image)``: every fill method of
  :data:`pbrbench.infer.specular.FILL_METHODS` after
  :func:`pbrbench.infer.specular.detect_specularities` (defaults, restricted to the object
  mask), any plugin, and ``baseline:no_removal`` (the image unchanged, nothing detected);
* ``fill`` -- ``<fill>+true_mask``, floors: the same fill given the true specular mask
  (``fn(image, mask) -> removed_image``): the fill's own error, without detection errors.

Metrics: :func:`pbrbench.metrics.specular.specular_scores` (``mask_iou`` of the detected mask;
``inside_rel`` / ``ring_rel`` against the twin inside and around the true mask;
``image_rel_rmse`` over the whole object).
"""

from __future__ import annotations

import functools

import numpy as np

from pbrbench.metrics.specular import specular_mask_from_twin, specular_scores
from pbrbench.registry import Algorithm
from pbrbench.tasks.base import Job, JobResult, Prediction, Task, parse_condition
from pbrbench.tasks.common.figures import display, display_map
from pbrbench.tasks.common.inputs import add_noise, grey, job_rng
from pbrbench.tasks.common.scoring import ScoreBook, attribute, call, check_array, scene_hash

FAMILIES = ("specular_sphere", "specular_shapes")
NOISE = 0.01
ORACLE = "+true_mask"
TRUE_MASK_WINDOW = 3   # the true mask thresholds the specular component's 3 x 3 mean (docstring)


def detect_and_fill(image, *, mask, fill):
    """Detect specularities inside ``mask`` and remove them with the fill method ``fill``."""
    from pbrbench.infer.specular import detect_specularities

    detected = detect_specularities(image, mask=mask)
    return detected, fill(image, detected)


def no_removal(image, *, mask):
    """``baseline:no_removal``: nothing detected, the image unchanged."""
    return np.zeros_like(mask), image


class SpecularTask(Task):
    name = "specular"
    description = ("Find small bright blobs and replace them by smooth interpolation (the chapter's "
                   "§1.1 recipe), scored against the diffuse-only twin render.")
    conditions = ("global", f"global+noise{NOISE:g}")
    headline_metric = "inside_rel"
    reference_condition = "global"
    notes = ("No local/area axis: the chapter's recipe (find small bright blobs, fill them from their "
             "surroundings) does not model light transport, and an area source's glossy lobe is not a "
             "small blob, so a direct-only or area-source twin would measure the detector's size prior, "
             "not the cost of an effect. The noise column is the cost of camera noise.")
    families = FAMILIES
    short_families = ("specular_sphere",)

    def builtin_algorithms(self) -> list[Algorithm]:
        from pbrbench.infer.specular import FILL_METHODS

        out = [Algorithm(n, self.name, functools.partial(detect_and_fill, fill=fn)) for n, fn in FILL_METHODS.items()]
        out += [Algorithm(n + ORACLE, self.name, fn, kind="floor", interface="fill") for n, fn in FILL_METHODS.items()]
        out.append(Algorithm("baseline:no_removal", self.name, no_removal, kind="baseline"))
        return out

    # --------------------------------------------------- export / evaluate (pbrbench.bench.external)
    input_names = ("image",)
    predictions = (
        Prediction("mask", "H,W", True, "the detected specular pixels", "mask"),
        Prediction("removed", "image", True, "the image with the highlights removed (linear radiance)"),
    )

    def jobs(self, quality) -> list[Job]:
        out = []
        for fam in quality.pick(self.families, self.short_families):
            for s in self.scenes.family(fam):
                if s.has_glossy:
                    out += [Job(self.name, s.name, c) for c in self.conditions]
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        algorithms = [a for a in algorithms if a.applies(job.condition)]
        gt = gts[job.scene]
        _, mods = parse_condition(job.condition)
        obj = gt.mask
        img = np.maximum(np.asarray(gt["radiance"], np.float64), 0.0)
        if mods.get("noise", 0) > 0:
            img = add_noise(img, mods["noise"], job_rng(job, seed), peak=float(img[obj].max()))
        twin = np.asarray(gt["diffuse_only"], np.float64)
        true_mask = specular_mask_from_twin(gt["radiance"], twin, threshold=0.1, reference="peak", mask=obj,
                                            window=TRUE_MASK_WINDOW)
        book = ScoreBook(job, scene_hash(gt), algorithms)
        res = JobResult(job)
        res.images["linear:input"] = display(img)
        res.images["linear:truth (diffuse-only twin)"] = display(twin)
        res.images["specular mask: truth"] = display(true_mask.astype(float))
        if job.condition == self.reference_condition:
            spec = self.library_spec(job.scene)
            fig = specular_direction_figure(spec, gt, img) if spec is not None else None
            if fig is not None:
                res.images["Figs 1.1-1.2 a specularity lies along the specular direction: the render, "
                           "the pixel whose normal bisects source and view marked (+)"] = fig

        def check_removed(o):
            return check_array(o, "removed", img.shape)

        def check_pair(o):
            det, rem = attribute(o, "mask", 0), attribute(o, "removed", 1)
            if det is None or rem is None:
                raise ValueError("output: return (detected_mask (H, W), removed_image) ")
            det = np.asarray(det)
            if det.shape != obj.shape:
                raise ValueError(f"detected mask: returned shape {det.shape}, expected {obj.shape}")
            return det.astype(bool), check_removed(rem)

        first = True
        for alg in algorithms:
            if alg.interface == "fill":
                out, seconds, err = call(alg, img, true_mask, quality=quality, check=check_removed)
                detected = None
            else:
                out, seconds, err = call(alg, img, mask=obj, quality=quality, check=check_pair)
                if err is None:
                    detected, out = out
            if err is not None:
                book.add(alg.name, {"failed": 1.0}, seconds)
                res.failures[alg.name] = err
                continue
            book.add(alg.name, specular_scores(out, twin, true_mask, obj, detected=detected), seconds)
            if first and alg.kind == "method":
                first = False
                res.images[f"specular mask: {alg.name}"] = display(detected.astype(float))
                res.images[f"linear:removed: {alg.name}"] = display(out)
                ref_b = max(float(grey(twin)[obj].max()), 1e-30) if obj.any() else 1.0
                res.error_maps[f"|removed - twin| / peak: {alg.name}"] = display_map(
                    np.where(obj, np.abs(grey(out) - grey(twin)) / ref_b, np.nan))
        res.scores = book.scores
        return res


def specular_direction_figure(spec, gt, img):
    """Figs 1.1-1.2 from a render: the image (tone-mapped, display-ready) with a red cross on the
    pixel whose normal is closest to the half vector ``H = (S + V) / |S + V|`` of the scene's
    directional source ``S`` and the view ``V`` (the camera's +z): a mirror there reflects the
    source into the camera, and the specularity sits on it.  None without a directional source."""
    from pbrbench.io import tonemap
    from pbrbench.scene.geometry import nominal_light

    lights = [li for li in spec.lights if li.type == "directional"]
    if not lights:
        return None
    S, _ = nominal_light(lights[0], spec.camera)
    H = S + np.array([0.0, 0.0, 1.0])
    H /= np.linalg.norm(H)
    m = np.asarray(gt.mask, bool)
    if not m.any():
        return None
    score = np.where(m, np.asarray(gt["normals"], float) @ H, -np.inf)
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    out = tonemap(img).astype(float) / 255.0
    if out.ndim == 2 or out.shape[-1] == 1:
        out = np.repeat(out.reshape(*out.shape[:2], 1), 3, axis=-1)
    r = max(4, img.shape[0] // 16)
    gap = max(2, r // 2)      # the cross's centre is left open: the highlight shows through it
    for di in (*range(-r, -gap + 1), *range(gap, r + 1)):
        for ii, jj in ((i + di, j), (i, j + di)):
            if 0 <= ii < out.shape[0] and 0 <= jj < out.shape[1]:
                out[ii, jj] = (1.0, 0.0, 0.0)
    return display(out)


TASK = SpecularTask()
