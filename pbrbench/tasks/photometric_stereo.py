"""Photometric stereo (with surface integration) on the scene library (SCIENCE.md §6).

Inputs: the per-light images of a scene's light set (grey = channel mean) and the nominal source
vectors of its spec (direction x irradiance, camera frame).  Conditions (naming contract):

* ``local``: the ``lightNN.direct`` images of the distant-source scene (the model's assumptions);
* ``local+noise0.01``: the same plus Gaussian noise of 1 % of the stack's peak;
* ``area``: the ``lightNN.direct`` images of the ``*_area`` twin (nearby rectangles centred on the
  nominal directions): the distant-source model is violated;
* ``global``: the ``lightNN.radiance`` images (full interreflection): biased in concavities.

Algorithms: every method of :func:`pbrbench.infer.photometric_stereo.photometric_stereo`, the
naive baseline (one least-squares solve with every light, shadows included), and -- for the
height scores -- the four integrators of :func:`pbrbench.infer.integration.integrate_normals`
applied to the *true* normals (the integration floor, condition ``local`` only).

Evaluation domain (algorithm independent): the ground-truth mask eroded by one pixel, restricted
to pixels lit by at least 3 lights in the job's own direct renders (a pixel seen by fewer has no
unique normal; "lit" = direct shading above 5 % of the light's peak, i.e. not grazing), whose lit
directions are not coplanar (three coplanar sources leave the normal undetermined).  Angular
errors (:mod:`pbrbench.metrics.normals`, DiLiGenT protocol) are scored over the whole domain, an
invalid estimate counting 90 degrees; ``coverage`` is the valid fraction of the domain.  Albedo:
the estimate times pi (radiance images carry ``rho E cos / pi``) against the albedo AOV, absolute
(``albedo_rel_err``: shows the inflation by interreflection) and after one best global scale
(``albedo_rel_err_scaled``).  Height: the estimated normals integrated by ``lsq`` on the largest
connected part of the domain, RMSE after the free offset (world units, ``height_rmse``) and
relative to the true height range (``height_rmse_rel``).

Plot jobs (no scores): ``albedo_sweep`` per swept family (error vs albedo, direct vs global
renders, across the ``[sweep]`` of albedos: the concave cup and groove show the interreflection
bias, the convex shapes are the control) and ``reflex`` (on ``groove_reflex_*``: the radiosity
``pi L`` across the groove for each albedo, and ``B / albedo`` against the local model).

Draft quality (the regression run) uses ``draft_families`` (``sphere_5lights``, ``ps_groove``) with
the first and last albedo of each sweep (``sweep_keep``), and ``groove_reflex_parallel`` with
three albedos.
"""

from __future__ import annotations

import numpy as np

from pbrbench.infer.integration import METHODS as INTEGRATION_METHODS
from pbrbench.infer.integration import integrate_normals
from pbrbench.infer.photometric_stereo import METHODS as PS_METHODS
from pbrbench.infer.photometric_stereo import photometric_stereo
from pbrbench.metrics.normals import (
    albedo_relative_error,
    angular_error_map,
    angular_error_stats,
    height_rmse,
)
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult, Task

FAMILIES = ("sphere_5lights", "sphere_12lights", "sphere_textured", "ps_bumps", "ps_vase", "ps_cup", "ps_groove")
REFLEX = ("groove_reflex_parallel", "groove_reflex_bisector")
NOISE = 0.01
NAIVE = "baseline:naive_lstsq_all_lights"
INTEGRATORS = tuple(INTEGRATION_METHODS)
LIT = 0.05            # a light lights a pixel above this fraction of its peak shading
# albedo values kept per swept family, by quality (first and last, then evenly spaced); a
# quality not listed keeps the whole sweep.  Reflex families keep one more at draft.
SWEEP_KEEP = {"draft": 2}

DIRECTIONS = {"normal_mean_deg": "lower", "normal_median_deg": "lower", "normal_frac_under_5deg": "higher",
              "normal_frac_under_10deg": "higher", "coverage": "higher", "albedo_rel_err": "lower",
              "albedo_rel_err_scaled": "lower", "height_rmse": "lower", "height_rmse_rel": "lower"}


def naive_lstsq(images: np.ndarray, lights: np.ndarray, mask: np.ndarray):
    """The naive baseline: ``g = pinv(V) I`` with every light, shadowed (clamped) ones included.

    Returns ``(normals (H, W, 3), albedo (H, W), valid (H, W))``.
    """
    k, h, w = images.shape
    g = np.linalg.pinv(np.asarray(lights, float)) @ images.reshape(k, -1)  # (3, H*W)
    g = g.T.reshape(h, w, 3)
    a = np.linalg.norm(g, axis=-1)
    valid = mask & (a > 0)
    n = np.divide(g, a[..., None], out=np.zeros_like(g), where=valid[..., None])
    return n, np.where(valid, a, 0.0), valid


def normal_scores(est, true, domain, valid) -> tuple[dict, np.ndarray]:
    """DiLiGenT angular-error scores over ``domain`` (an invalid estimate scores 90 degrees:
    :func:`pbrbench.metrics.normals.angular_error_map`) plus ``coverage``, the valid fraction of
    the domain; returns (scores, error map)."""
    if not domain.any():
        return {}, np.full(domain.shape, np.nan)
    n = np.where(valid[..., None], est, 0.0)
    emap = angular_error_map(n, true, domain)
    st = angular_error_stats(n, true, domain)
    return {"normal_mean_deg": st["mean"], "normal_median_deg": st["median"],
            "normal_frac_under_5deg": st["frac_under_5"], "normal_frac_under_10deg": st["frac_under_10"],
            "coverage": float((domain & valid).sum() / domain.sum())}, emap


def albedo_scores(est_pi, true, sel) -> dict:
    """``albedo_rel_err``: mean ``|est / true - 1|`` with the nominal intensities (no rescaling:
    shows the inflation by interreflection); ``albedo_rel_err_scaled``:
    :func:`pbrbench.metrics.normals.albedo_relative_error` (one global least-squares scale)."""
    if not sel.any() or not np.any(est_pi[sel] > 0):
        return {}
    r = est_pi[sel] / np.maximum(true[sel], 1e-6)
    return {"albedo_rel_err": float(np.mean(np.abs(r - 1))),
            "albedo_rel_err_scaled": albedo_relative_error(est_pi, true, sel)}


def largest_component(mask: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    lab, n = ndimage.label(mask)
    if n <= 1:
        return mask.copy()
    sizes = ndimage.sum(mask, lab, index=np.arange(1, n + 1))
    return lab == (1 + int(np.argmax(sizes)))


def height_scores(normals, z_true, domain, pixel_size, method="lsq") -> tuple[dict, np.ndarray]:
    """Integrate ``normals`` on the largest component of ``domain``; height RMSE vs ``z_true``
    after removing the free offset (:func:`pbrbench.metrics.normals.height_rmse`, world units)
    and relative to the true height range."""
    dom = largest_component(domain & (normals[..., 2] > 1e-3))
    if dom.sum() < 4:
        return {}, np.full(z_true.shape, np.nan)
    z = integrate_normals(normals, mask=dom, method=method, pixel_size=pixel_size)
    rmse = height_rmse(z, z_true, dom)
    rng = float(np.ptp(z_true[dom]))
    return {"height_rmse": rmse, "height_rmse_rel": rmse / rng if rng > 0 else float("nan")}, \
        np.where(dom, z - z[dom].mean(), np.nan)


class PhotometricStereoTask(Task):
    name = "photometric_stereo"
    description = ("Normals, albedo and height from K images under distant sources (Woodham 1980; "
                   "robust L1); scored on direct, area-source and full-GI renders of the scene library.")
    algorithms = tuple(PS_METHODS) + (NAIVE,) + tuple(f"integrate:{m}" for m in INTEGRATORS)
    conditions = ("local", f"local+noise{NOISE:g}", "area", "global")
    headline_metric = "normal_mean_deg"
    headline_better = "lower"
    families = FAMILIES
    draft_families = ("sphere_5lights", "ps_groove")
    reflex_families = REFLEX
    draft_reflex_families = ("groove_reflex_parallel",)
    sweep_keep = SWEEP_KEEP

    # ------------------------------------------------------------------------------ jobs
    def _params(self, spec) -> tuple:
        return (("lights", C.as_param(C.light_vectors(spec))), ("half_width", float(spec.camera.half_width)))

    def jobs(self, quality: str) -> list[Job]:
        out: list[Job] = []
        draft = quality == "draft"
        for fam in C.families_for(self, quality):
            specs = C.family_scenes(fam)
            if not specs:
                continue
            twins = {C.sweep_value(s, "albedo"): s for s in C.family_scenes(f"{fam}_area")}
            if quality in self.sweep_keep:
                specs = C.subsample(specs, self.sweep_keep[quality])
            for s in specs:
                if not s.light_set:
                    continue
                p = self._params(s)
                out.append(Job(self.name, s.name, "local", p))
                out.append(Job(self.name, s.name, f"local+noise{NOISE:g}", p))
                out.append(Job(self.name, s.name, "global", p))
                tw = twins.get(C.sweep_value(s, "albedo"))
                if tw is not None and tw.light_set:
                    out.append(Job(self.name, tw.name, "area", self._params(tw)))
            if len(specs) > 1:  # a swept family: error vs albedo (convex shapes are the control)
                names = tuple(s.name for s in specs)
                out.append(Job(self.name, names[-1], "global", (("plot", "albedo_sweep"),) + self._params(specs[-1]),
                               extra_scenes=names[:-1]))
        for fam in (self.draft_reflex_families if draft else self.reflex_families):
            specs = C.family_scenes(fam)
            if quality in self.sweep_keep:
                specs = C.subsample(specs, self.sweep_keep[quality] + 1)
            if len(specs) > 0:
                names = tuple(s.name for s in specs)
                out.append(Job(self.name, names[-1], "global", (("plot", "reflex"),), extra_scenes=names[:-1]))
        return out

    # --------------------------------------------------------------------------- helpers
    @staticmethod
    def _stack(gt, kind: str) -> np.ndarray:
        return C.grey(gt.light_stack(kind))

    @staticmethod
    def _domain(gt, lights) -> np.ndarray:
        """The evaluation domain: mask eroded by one pixel, lit by >= 3 lights of independent
        directions (not all coplanar), where light k lights a pixel when its direct shading
        ``direct_k / albedo`` exceeds ``LIT`` (5 %) of that light's peak shading
        (cos(theta) > ~0.05: grazing and shadowed measurements out)."""
        direct = C.grey(gt.light_stack("direct"))
        alb = C.grey(gt["albedo"])
        m = C.erode(gt.mask, 1)
        shading = np.where(m & (alb > 0), direct / np.where(alb > 0, alb, 1.0), 0.0)
        peak = shading.reshape(shading.shape[0], -1).max(axis=1)
        lit = (shading > LIT * np.maximum(peak, 1e-30)[:, None, None]).astype(float)
        s = np.asarray(lights, float)
        s = s / np.linalg.norm(s, axis=1, keepdims=True)
        gram = np.einsum("khw,ki,kj->hwij", lit, s, s)
        tr = np.trace(gram, axis1=-2, axis2=-1)
        independent = np.linalg.det(gram) > 1e-6 * (tr / 3.0) ** 3
        return m & (lit.sum(axis=0) >= 3) & independent & (tr > 0)

    def _run_ps(self, algorithm, images, lights, mask):
        if algorithm == NAIVE:
            return naive_lstsq(images, lights, mask)
        r = photometric_stereo(images, lights, mask=mask, method=algorithm)
        return r.normals, r.albedo, r.valid

    # ----------------------------------------------------------------------------- run
    def run_job(self, job: Job, gts: dict, *, seed: int = 0) -> JobResult:
        plot = job.param("plot")
        if plot == "albedo_sweep":
            return self._albedo_sweep(job, gts)
        if plot == "reflex":
            return self._reflex(job, gts)
        gt = gts[job.scene]
        base, mods = C.parse_condition(job.condition)
        lights = np.asarray(job.param("lights"), float)
        images = self._stack(gt, "radiance" if base == "global" else "direct")
        if mods.get("noise", 0) > 0:
            images = C.add_noise(images, mods["noise"], C.job_rng(job, seed))
        domain = self._domain(gt, lights)
        n_true = gt["normals"].astype(float)
        alb_true = C.grey(gt["albedo"])
        z_true = -gt["depth"].astype(float)
        px = C.pixel_size(job.param("half_width", 1.0), images.shape[2])
        book = C.ScoreBook(job, C.scene_hash(gt))
        res = JobResult(job)
        res.images["linear:input (light 0)"] = C.display(images[0])
        res.images["normals: truth"] = C.normals_display(n_true, gt.mask)
        for alg in tuple(PS_METHODS) + (NAIVE,):
            with C.Timer() as t:
                n, a, valid = self._run_ps(alg, images, lights, gt.mask)
            sc, emap = normal_scores(n, n_true, domain, valid)
            sc.update(albedo_scores(np.pi * a, alb_true, domain & valid))
            hs, _ = height_scores(n, z_true, domain & valid, px)
            sc.update(hs)
            book.add_all(alg, sc, t.seconds, DIRECTIONS)
            res.images[f"normals: {alg}"] = C.normals_display(n, valid)
            res.error_maps[f"angular error (deg): {alg}"] = C.display_map(emap)
            if alg == PS_METHODS[0]:
                res.images[f"albedo x pi: {alg}"] = C.display(np.clip(np.pi * a, 0, 1))
                with np.errstate(invalid="ignore", divide="ignore"):
                    rel = np.where(domain & valid, np.pi * a / np.maximum(alb_true, 1e-6) - 1, np.nan)
                res.error_maps[f"albedo relative error: {alg}"] = C.display_map(rel)
        if job.condition == "local":
            for m in INTEGRATORS:
                with C.Timer() as t:
                    hs, z = height_scores(n_true, z_true, domain, px, method=m)
                book.add_all(f"integrate:{m}", hs, t.seconds, DIRECTIONS)
                if m == "lsq":
                    res.error_maps["true height (lsq from true normals)"] = C.display_map(z)
        res.scores = book.scores
        return res

    # ---------------------------------------------------------------------------- plots
    def _albedo_sweep(self, job: Job, gts: dict) -> JobResult:
        names = list(job.extra_scenes) + [job.scene]
        names.sort(key=lambda s: C.sweep_value(s, "albedo") or 0.0)
        lights = np.asarray(job.param("lights"), float)
        alg = PS_METHODS[0]
        xs, series = [], {}
        for name in names:
            gt = gts[name]
            xs.append(C.sweep_value(name, "albedo"))
            domain = self._domain(gt, lights)
            for kind, label in (("direct", "direct (local)"), ("radiance", "full GI (global)")):
                n, a, valid = self._run_ps(alg, self._stack(gt, kind), lights, gt.mask)
                sc, _ = normal_scores(n, gt["normals"], domain, valid)
                al = albedo_scores(np.pi * a, C.grey(gt["albedo"]), domain & valid)
                series.setdefault(f"angular error, {label}", []).append(sc.get("normal_mean_deg", np.nan))
                series.setdefault(f"albedo rel. error, {label}", []).append(al.get("albedo_rel_err", np.nan))
        fam = job.scene.split("[")[0]
        res = JobResult(job)
        res.plots[f"{fam}: {alg} error vs albedo"] = C.profile_plot(
            xs, {k: v for k, v in series.items() if k.startswith("angular")}, "albedo", "mean angular error (deg)")
        res.plots[f"{fam}: {alg} albedo error vs albedo"] = C.profile_plot(
            xs, {k: v for k, v in series.items() if k.startswith("albedo")}, "albedo",
            "mean |albedo_est / albedo - 1|")
        return res

    def _reflex(self, job: Job, gts: dict) -> JobResult:
        """Radiosity ``B = pi L`` across the groove (middle row, along x) for each albedo, and
        ``B / albedo`` (the total irradiance) against the local model's (direct) one."""
        names = list(job.extra_scenes) + [job.scene]
        names.sort(key=lambda s: C.sweep_value(s, "albedo") or 0.0)
        radiosity, gain = {}, {}
        x = None
        for name in names:
            gt = gts[name]
            row = gt["radiance"].shape[0] // 2
            rad, dire = C.grey(gt["radiance"])[row], C.grey(gt["direct"])[row]
            x = np.arange(rad.size) if x is None else x
            alb = C.sweep_value(name, "albedo")
            alb = float(alb) if alb is not None else float(np.median(C.grey(gt["albedo"])[row]))
            radiosity[f"albedo {alb:g}"] = np.pi * rad
            if alb > 0:
                gain[f"albedo {alb:g}, global"] = np.pi * rad / alb
                if "local model (direct)" not in gain:
                    gain["local model (direct)"] = np.pi * dire / alb
        res = JobResult(job)
        fam = job.scene.split("[")[0]
        res.plots[f"{fam}: radiosity across the groove vs albedo"] = C.profile_plot(
            x, radiosity, "column (pixels)", "radiosity B = pi L (middle row)")
        if gain:
            res.plots[f"{fam}: B / albedo (total irradiance) vs the local model"] = C.profile_plot(
                x, gain, "column (pixels)", "B / albedo (middle row)",
                note="the local model predicts the direct curve for every albedo; interreflection adds a roof that grows with albedo")
        res.images["linear:radiance (highest albedo)"] = C.display(gts[names[-1]]["radiance"])
        return res


TASK = PhotometricStereoTask()
