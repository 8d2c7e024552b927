"""Photometric stereo (with surface integration) on the scene library.

Inputs: the per-light images of a scene's light set (grey = channel mean) and the nominal source
vectors of its spec (direction x irradiance, camera frame; ``docs/conventions.md``).  Conditions
(``docs/conditions.md``):

* ``local``: the ``lightNN.direct`` images of the distant-source scene (the model's assumptions);
* ``local+noise0.01``: the same plus Gaussian noise of 1 % of the stack's peak;
* ``area``: the ``lightNN.direct`` images of the ``*_area`` twin (nearby rectangles centred on the
  nominal directions): the distant-source model is violated;
* ``global``: the ``lightNN.radiance`` images (full interreflection): biased in concavities;
* ``local+ambient0.1``: the ``local`` images plus the chapter's ambient term (§1.1.3, Image =
  Diffuse + Ambient: "shadows are not black"), the **local model** of it, not a render: every
  image of the stack gets the same constant irradiance ``A = 0.1 x mean_k E_k`` added to its
  sources, i.e. ``I_k <- I_k + rho A / pi`` (``rho`` the albedo AOV; radiance units), unoccluded
  and not interreflected.  It costs no render and is exactly the model the chapter writes; a
  rendered constant environment would add occlusion and interreflection of the ambient light,
  which the ``global`` condition already measures for the sources;
* ``near``: the ``lightNN.direct`` images of :data:`NEAR_FAMILIES` (``ps_near``: a sphere under
  five *point* sources at 2, 3, 5 and 10 radii from its centre: ``I_k = rho I_src N . (P_k - X)
  / (pi |P_k - X|^3)``, §1.3.5), scored against the distant-source twin
  ``ps_near_distant`` under ``local``: the twin's scores carry the near scene's name (as an area
  twin counts as its base scene), so the headline's ``near`` column is ``near - local`` on matched
  sphere sizes.  Distant-source methods get the nominal source vectors (direction from the
  sphere's centre, irradiance ``I / d^2`` there: :func:`pbrbench.scene.geometry.light_vectors`);
  the methods of the ``near`` interface get the source positions.  At a short-subset quality
  only the nearest sources (2 radii) run.

Calling conventions (``Algorithm.interface``, set from :data:`INTERFACES`): the main one below;
``"colour"`` (``woodham1980_colour``): the same call with the (K, H, W, 3) colour stack (the
channel mean is what the others get; on grey scenes the channels are equal), its per-channel
albedo scored by its channel mean; ``"near"`` (``iwahori1990``, under ``near`` only): ``fn(images,
positions, *, mask, intensities, pixel_size, depth0)`` with the source positions (camera frame,
origin at the camera target), their intensities, the film's pixel size and, as the stated
distance of the object, the mean true height of the visible surface over the mask.

Algorithms (from the registry): every method of :data:`pbrbench.infer.photometric_stereo.METHODS`
and any plugin, called as ``fn(images, lights, *, mask)`` with ``images`` (K, H, W) float64 and
``lights`` (K, 3), returning a :class:`~pbrbench.infer.photometric_stereo.PhotometricStereoResult`
or anything with ``normals`` (H, W, 3) and ``albedo`` (H, W) (attributes, dict keys, or a tuple
``(normals, albedo[, valid])``; normals that are not unit length are normalised, pixels outside
``valid`` count as invalid estimates); the naive baseline (one least-squares solve with every light,
shadows included); as floors for the height scores, the integration methods of
:data:`pbrbench.infer.integration.METHODS` applied to the *true* normals (condition ``local``); and
the inverse-rendering methods of :data:`pbrbench.inverse.METHODS` as ``inverse:<name>``
(``interface="scene"``, ``docs/inverse.md``), called as ``fn(images, lights, *, mask, scene,
max_depth, seed)`` with the job's :class:`~pbrbench.scene.spec.SceneSpec` (camera, light set,
extent) and the transport of its images (``max_depth`` -1 under ``global``, else 2).  They render
(minutes a scene at standard), so they run only on the highest albedo of the concave families
(:data:`INVERSE_FAMILIES`; ``ps_groove`` alone at a short-subset quality) under
:data:`INVERSE_CONDITIONS` (``global`` and ``local``; ``global`` alone at a short-subset quality); their job also shows the
loss curve and the angular error of their start (Woodham) beside the final one.

Evaluation domain (algorithm independent): the ground-truth mask eroded by one pixel, restricted
to pixels lit by at least 3 lights in the job's own direct renders (a pixel seen by fewer has no
unique normal; "lit" = direct shading above 5 % of the light's peak, i.e. not grazing), whose lit
directions are not coplanar (three coplanar sources leave the normal undetermined).  Scores: see
:func:`pbrbench.metrics.normals.normal_scores`, ``albedo_scores`` (the estimate times pi against
the albedo AOV: radiance images carry ``rho E cos / pi``) and ``height_scores`` (the estimated
normals integrated by ``lsq`` on the largest connected part of the domain), and the chapter's
self-checks (§1.3.4), which need no truth: :func:`pbrbench.metrics.ps_checks.check_scores`
(integrability residual, relative Lambertian least-squares residual with the nominal source
vectors, fraction with pi-scaled albedo ``pi |g| > 1``), on the domain pixels the method solved.
Plot job ``checks`` per family (its first kept scene, the first method): the Pearson and Spearman
correlations of each check's per-pixel map with the angular-error map under each condition the
scene has: whether the checks predict where the normals are wrong.  Plot job ``near_sweep`` (full
sweep only): mean angular error against the source distance (in radii) per method.

For ``sphere_5lights`` under ``local`` the first method's job also draws the chapter's Figs
1.13-1.16 (the input images, the recovered albedo and normals, a shaded view of the integrated
height: :func:`chapter_figures`) for the report's chapter gallery.  ``ps_cap`` (a concave spherical
cap) has a closed-form interreflection bias: :mod:`pbrbench.radiosity.concave_cap`.

Plot jobs (no scores): ``albedo_sweep`` per swept family (error vs albedo, direct vs global
renders: the concave cup and groove show the interreflection bias, the convex shapes are the
control) and ``reflex`` (on ``groove_reflex_*``: the radiosity ``pi L`` across the groove for each
albedo, and ``B / albedo`` against the local model).
"""

from __future__ import annotations

import numpy as np

from pbrbench.metrics.normals import albedo_scores, height_scores, normal_scores
from pbrbench.metrics.ps_checks import check_error_correlation, check_scores
from pbrbench.registry import Algorithm
from pbrbench.scene.geometry import light_vectors
from pbrbench.tasks.base import Job, JobResult, Prediction, Task, parse_condition
from pbrbench.tasks.common.figures import display, display_map, normals_display, profile_plot
from pbrbench.tasks.common.inputs import add_noise, as_param, erode, grey, job_rng, pixel_size
from pbrbench.tasks.common.scenes import sweep_value
from pbrbench.tasks.common.scoring import ScoreBook, Timer, attribute, call, check_array, scene_hash

FAMILIES = ("sphere_5lights", "sphere_12lights", "sphere_textured", "ps_bumps", "ps_vase", "ps_cup", "ps_groove",
            "ps_cap")
REFLEX = ("groove_reflex_parallel", "groove_reflex_bisector")
NOISE = 0.01
INVERSE_FAMILIES = ("ps_groove", "ps_cup", "ps_cap")   # concave: where every local method is biased
SHORT_INVERSE_FAMILIES = ("ps_groove",)
INVERSE_APPLIES = ("global", "local")  # the transports the methods model (not area sources)
# where the benchmark runs them: global and local at standard (one call per job, its standard errors from the noise
# scales over render seeds, pbrbench/bench/noise_scales.json: so the headline has the method's local score and the cost
# of interreflection to it), global alone at draft; elsewhere five calls: the images and the four delete-one-group
# replicates
INVERSE_CONDITIONS = ("global", "local")
SHORT_INVERSE_CONDITIONS = ("global",)
LIT = 0.05            # a light lights a pixel above this fraction of its peak shading
AMBIENT = 0.1         # ambient irradiance of local+ambient<level>: this fraction of the sources' mean irradiance
NEAR_FAMILIES = ("ps_near",)            # point sources; their distant twins are f"{family}_distant"
SHORT_NEAR_FAMILIES = ("ps_near",)
# calling conventions other than the main one, by METHODS name: (interface, conditions)
INTERFACES = {"iwahori1990": ("near", ("near",)), "woodham1980_colour": ("colour", None)}


def result_arrays(out, shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(normals (H, W, 3), albedo (H, W), valid (H, W)) from what a photometric-stereo algorithm
    returned; ``ValueError`` naming the problem when it is unusable.  Normals are renormalised;
    ``valid`` defaults to the pixels with a finite non-zero normal."""
    h, w = shape
    n = attribute(out, "normals", 0)
    a = attribute(out, "albedo", 1)
    if n is None or a is None:
        raise ValueError("output: return normals (H, W, 3) and albedo (H, W) "
                         "(a PhotometricStereoResult, a dict or a tuple)")
    valid = attribute(out, "valid", 2)
    if valid is not None:
        valid = np.asarray(valid)
        if valid.shape != (h, w):
            raise ValueError(f"valid: returned shape {valid.shape}, expected {(h, w)}")
        valid = valid.astype(bool)
    n = check_array(n, "normals", (h, w, 3), where=valid)
    a = np.asarray(a)
    a = check_array(a[..., 0] if a.ndim == 3 and a.shape[2] == 1 else a, "albedo", (h, w), where=valid)
    finite = np.isfinite(n).all(axis=-1)
    norm = np.linalg.norm(np.where(finite[..., None], n, 0.0), axis=-1)
    valid = (finite if valid is None else valid) & (norm > 0)
    # unit normals pass unchanged (bit for bit); others are normalised
    fix = valid & (np.abs(norm - 1.0) > 1e-6)
    n = np.where(valid[..., None], n, 0.0)
    if fix.any():
        n[fix] /= norm[fix][:, None]
    return n, np.where(valid, a, 0.0), valid


GALLERY_FAMILY = "sphere_5lights"   # the chapter's Figs 1.13-1.16 (five images of a sphere and what they give)


def chapter_figures(scene: str, method: str, images, normals, albedo, valid, height, pixel_size) -> dict:
    """Figs 1.13-1.16 for the report's chapter gallery: the input images (one exposure), the
    recovered albedo (x pi), the recovered normals and a shaded view of the integrated height."""
    from pbrbench.io import srgb_encode

    k = len(images)
    cols = 3
    rows = -(-k // cols)
    H, W = images.shape[1:3]
    expo = 1.0 / max(float(np.percentile(images[images > 0], 99.5)) if np.any(images > 0) else 1.0, 1e-30)
    tiles = np.ones((rows * (H + 2), cols * (W + 2)))
    for i, im in enumerate(images):
        r, c = divmod(i, cols)
        tiles[r * (H + 2):r * (H + 2) + H, c * (W + 2):c * (W + 2) + W] = np.clip(srgb_encode(im * expo), 0, 1)
    z = np.nan_to_num(np.asarray(height, float), nan=np.nan)
    gy, gx = np.gradient(np.where(np.isfinite(z), z, 0.0), pixel_size)
    nrm = np.stack([-gx, gy, np.ones_like(gx)], -1)   # rows run toward -y
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    light = np.array([-0.5, 0.5, 0.7]) / np.linalg.norm([-0.5, 0.5, 0.7])
    shaded = np.where(np.isfinite(z), np.clip(nrm @ light, 0.0, 1.0), 0.0)
    tag = f"{scene}, {method}"
    return {f"Fig 1.13 photometric stereo ({tag}): the {k} input images": tiles.astype(np.float32),
            f"Fig 1.14 recovered albedo x pi ({tag})": display(np.where(valid, np.clip(np.pi * albedo, 0, 1), 0.0)),
            f"Fig 1.15 recovered normals ({tag})": normals_display(normals, valid),
            f"Fig 1.16 height integrated from the recovered normals, shaded ({tag})": display(shaded)}


class PhotometricStereoTask(Task):
    name = "photometric_stereo"
    description = ("Normals, albedo and height from K images under distant sources (Woodham 1980; "
                   "robust L1); scored on direct, area-source and full-GI renders of the scene library.")
    conditions = ("local", f"local+noise{NOISE:g}", f"local+ambient{AMBIENT:g}", "area", "global", "near")
    headline_metric = "normal_mean_deg"
    families = FAMILIES
    short_families = ("sphere_5lights", "ps_groove")
    near_families = NEAR_FAMILIES
    short_near_families = SHORT_NEAR_FAMILIES
    reflex_families = REFLEX
    short_reflex_families = ("groove_reflex_parallel",)

    # ------------------------------------------------------------------------- algorithms
    def builtin_algorithms(self) -> list[Algorithm]:
        from pbrbench.infer.integration import METHODS as INTEGRATION
        from pbrbench.infer.photometric_stereo import BASELINES, METHODS
        from pbrbench.inverse import METHODS as INVERSE

        out = []
        for n, fn in METHODS.items():
            interface, conds = INTERFACES.get(n, ("", None))
            out.append(Algorithm(n, self.name, fn, interface=interface, conditions=conds))
        out += [Algorithm(f"baseline:{n}", self.name, fn, kind="baseline") for n, fn in BASELINES.items()]
        out += [Algorithm(f"integrate:{n}", self.name, fn, kind="floor", conditions=("local",),
                          description="the true normals integrated by this method: the integration floor")
                for n, fn in INTEGRATION.items()]
        out += [Algorithm(f"inverse:{n}", self.name, fn, interface="scene", conditions=INVERSE_APPLIES,
                          description="inverse rendering with Mitsuba (needs the scene's camera and lights)",
                          seeded=True, applies_to=self._inverse_applies,
                          # draft (one scene, 32 x 32 images at 8 spp): fewer iterations and samples, a larger
                          # height step (its start is noisier: docs/inverse.md)
                          budgets={"draft": {"iterations": (10,), "spp": 8, "spp_grad": 2, "lr_height": 0.005}},
                          cost_note="analysis by synthesis: Adam over a height field and an albedo texture, each "
                                    "iteration a Mitsuba render of every light and its gradient (about 47 M camera "
                                    "paths per call at standard), called once per job where the noise scales cover it (its "
                                    "standard errors from eight independent render seeds, docs/uncertainty.md), else five "
                                    "times (the images and the four delete-one-group replicates); run on three scenes, "
                                    "under global and local at standard and global at draft (docs/inverse.md)")
                for n, fn in INVERSE.items()]
        return out

    # ------------------------------------------------------------------------------ jobs
    def _params(self, spec) -> tuple:
        return (("lights", as_param(light_vectors(spec))), ("half_width", float(spec.camera.half_width)))

    @staticmethod
    def _near_params(spec) -> tuple:
        """The source positions (camera frame, origin at the camera target), their intensities
        (channel mean) and the camera's distance from the target: what the ``near`` interface
        needs besides the images."""
        from pbrbench.scene.geometry import camera_rotation

        R = camera_rotation(spec.camera)
        t = np.asarray(spec.camera.target, float)
        pos = [R @ (np.asarray(li.position, float) - t) for li in spec.light_set]
        inten = [float(np.mean(li.intensity)) for li in spec.light_set]
        dist = float(np.linalg.norm(np.asarray(spec.camera.origin, float) - t))
        return (("positions", as_param(pos)), ("intensities", as_param(inten)), ("camera_distance", dist))

    def jobs(self, quality) -> list[Job]:
        out: list[Job] = []
        for fam in quality.pick(self.families, self.short_families):
            specs = self.scenes.family(fam)
            if not specs:
                continue
            twins = {sweep_value(s, "albedo"): s for s in self.scenes.family(f"{fam}_area")}
            specs = quality.keep(specs)
            for s in specs:
                if not s.light_set:
                    continue
                p = self._params(s)
                out.append(Job(self.name, s.name, "local", p))
                out.append(Job(self.name, s.name, f"local+noise{NOISE:g}", p))
                out.append(Job(self.name, s.name, f"local+ambient{AMBIENT:g}", p))
                out.append(Job(self.name, s.name, "global", p))
                tw = twins.get(sweep_value(s, "albedo"))
                if tw is not None and tw.light_set:
                    out.append(Job(self.name, tw.name, "area", self._params(tw)))
            if specs and specs[0].light_set:   # do the chapter's checks predict the error?
                tw = twins.get(sweep_value(specs[0], "albedo"))
                out.append(Job(self.name, specs[0].name, "local", (("plot", "checks"),) + self._params(specs[0]),
                               extra_scenes=(tw.name,) if tw is not None and tw.light_set else ()))
            if len(specs) > 1:  # a swept family: error vs albedo (convex shapes are the control)
                names = tuple(s.name for s in specs)
                out.append(Job(self.name, names[-1], "global", (("plot", "albedo_sweep"),) + self._params(specs[-1]),
                               extra_scenes=names[:-1]))
        out += self._near_jobs(quality)
        for fam in quality.pick(self.reflex_families, self.short_reflex_families):
            specs = quality.keep(self.scenes.family(fam), extra=1)
            if len(specs) > 0:
                names = tuple(s.name for s in specs)
                out.append(Job(self.name, names[-1], "global", (("plot", "reflex"),), extra_scenes=names[:-1]))
        return out

    def _near_jobs(self, quality) -> list[Job]:
        """``near`` on each kept scene of the point-source families and ``local`` on its distant
        twin (scored under the near scene's name: the headline matches them); only the nearest
        sources (the first sweep value) at a short-subset quality; a ``checks`` plot job on the
        nearest, a ``near_sweep`` plot job when more than one distance is kept."""
        out: list[Job] = []
        for fam in quality.pick(self.near_families, self.short_near_families):
            specs = [s for s in self.scenes.family(fam) if s.light_set]
            twins = {s.name.replace(f"{fam}_distant", fam, 1): s for s in self.scenes.family(f"{fam}_distant")}
            specs = specs[:1] if quality.short_subset else quality.keep(specs)
            for s in specs:
                p = self._params(s) + self._near_params(s)
                out.append(Job(self.name, s.name, "near", p))
                tw = twins.get(s.name)
                if tw is not None and tw.light_set:
                    out.append(Job(self.name, tw.name, "local", self._params(tw) + (("label", s.name),)))
            if specs:
                tw = twins.get(specs[0].name)
                out.append(Job(self.name, specs[0].name, "near",
                               (("plot", "checks"),) + self._params(specs[0]) + self._near_params(specs[0]),
                               extra_scenes=(tw.name,) if tw is not None else ()))
            if len(specs) > 1:
                names = tuple(s.name for s in specs)
                extra = tuple(twins[n].name for n in names if n in twins)
                out.append(Job(self.name, names[0], "near", (("plot", "near_sweep"),),
                               extra_scenes=names[1:] + extra))
        return out

    # --------------------------------------------------- export / evaluate (pbrbench.bench.external)
    input_names = ("images", "lights")
    predictions = (
        Prediction("normals", "H,W,3", True, "unit normals in the camera frame (x right, y up, z toward the camera)"),
        Prediction("albedo", "H,W", False, "albedo as the method recovers it (missing: no albedo scores)"),
        Prediction("valid", "H,W", False, "pixels with an estimate (missing: where the normal is non-zero)", "mask"),
    )

    def prediction_output(self, files: dict, inputs: dict):
        out = dict(files)
        out.setdefault("albedo", np.zeros(self.frame_shape(inputs)))   # zero albedo: albedo scores skipped
        return out

    # --------------------------------------------------------------------------- helpers
    @staticmethod
    def _stack(gt, kind: str) -> np.ndarray:
        return grey(gt.light_stack(kind))

    @staticmethod
    def _domain(gt, lights) -> np.ndarray:
        """The evaluation domain: mask eroded by one pixel, lit by >= 3 lights of independent
        directions (not all coplanar), where light k lights a pixel when its direct shading
        ``direct_k / albedo`` exceeds ``LIT`` (5 %) of that light's peak shading
        (cos(theta) > ~0.05: grazing and shadowed measurements out)."""
        direct = grey(gt.light_stack("direct"))
        alb = grey(gt["albedo"])
        m = erode(gt.mask, 1)
        shading = np.where(m & (alb > 0), direct / np.where(alb > 0, alb, 1.0), 0.0)
        peak = shading.reshape(shading.shape[0], -1).max(axis=1)
        lit = (shading > LIT * np.maximum(peak, 1e-30)[:, None, None]).astype(float)
        s = np.asarray(lights, float)
        s = s / np.linalg.norm(s, axis=1, keepdims=True)
        gram = np.einsum("khw,ki,kj->hwij", lit, s, s)
        tr = np.trace(gram, axis1=-2, axis2=-1)
        independent = np.linalg.det(gram) > 1e-6 * (tr / 3.0) ** 3
        return m & (lit.sum(axis=0) >= 3) & independent & (tr > 0)

    @staticmethod
    def _solve(alg, images, lights, mask, quality):
        return call(alg, images, lights, mask=mask, quality=quality,
                      check=lambda out: result_arrays(out, images.shape[1:3]))

    @staticmethod
    def _inputs(job: Job, gt, seed: int, *, colour: bool = False) -> np.ndarray:
        """The job's image stack: (K, H, W) grey, or (K, H, W, 3) with ``colour``; the condition's
        transport (``radiance`` under ``global``, else ``direct``), then its ambient term (the local
        model, ``rho A / pi`` with ``A = level x mean_k E_k``), then its noise."""
        base, mods = parse_condition(job.condition)
        kind = "radiance" if base == "global" else "direct"
        images = np.asarray(gt.light_stack(kind), np.float64) if colour else PhotometricStereoTask._stack(gt, kind)
        if mods.get("ambient", 0) > 0:
            lights = np.asarray(job.param("lights"), float)
            irr = mods["ambient"] * float(np.mean(np.linalg.norm(lights, axis=1)))
            alb = np.asarray(gt["albedo"], np.float64) if colour else grey(gt["albedo"])
            m = gt.mask[..., None] if colour else gt.mask
            images = images + np.where(m, alb, 0.0)[None] * (irr / np.pi)
        if mods.get("noise", 0) > 0:
            images = add_noise(images, mods["noise"], job_rng(job, seed))
        return images

    def _solve_as(self, alg, job: Job, gt, images, lights, mask, quality, seed: int):
        """Call a main, ``colour`` or ``near`` interface algorithm with the inputs it takes:
        ``((normals, albedo (H, W), valid), seconds, error)``."""
        shape = images.shape[1:3]
        if alg.interface == "colour":
            col = self._inputs(job, gt, seed, colour=True)

            def check(out):
                a = attribute(out, "albedo", 1)
                if a is not None and np.ndim(a) == 3 and np.shape(a)[2] == 3:
                    n = attribute(out, "normals", 0)
                    out = {"normals": n, "albedo": np.mean(np.asarray(a, float), axis=-1),
                           "valid": attribute(out, "valid", 2)}
                return result_arrays(out, shape)
            return call(alg, col, lights, mask=mask, quality=quality, check=check)
        if alg.interface == "near":
            pos = np.asarray(job.param("positions"), float)
            inten = np.asarray(job.param("intensities"), float)
            height = float(job.param("camera_distance")) - np.asarray(gt["depth"], float)
            depth0 = float(np.mean(height[gt.mask]))
            px = pixel_size(job.param("half_width", 1.0), images.shape[2])
            return call(alg, images, pos, mask=mask, intensities=inten, pixel_size=px, depth0=depth0,
                        quality=quality, check=lambda out: result_arrays(out, shape))
        return self._solve(alg, images, lights, mask, quality)

    def _inverse_applies(self, job: Job, quality) -> bool:
        """Whether the inverse-rendering methods run on this job: the highest albedo of a family
        of :data:`INVERSE_FAMILIES` (or of its area twin) under :data:`INVERSE_CONDITIONS` (the
        short lists at a short-subset quality)."""
        if quality is None:
            from pbrbench.quality import STANDARD

            quality = STANDARD
        fam = job.scene.split("[")[0]
        fam = fam[:-len("_area")] if fam.endswith("_area") else fam
        if fam not in quality.pick(INVERSE_FAMILIES, SHORT_INVERSE_FAMILIES):
            return False
        if job.condition not in quality.pick(INVERSE_CONDITIONS, SHORT_INVERSE_CONDITIONS):
            return False
        albedos = [sweep_value(s, "albedo") for s in self.scenes.family(fam)]
        albedos = [a for a in albedos if a is not None]
        return not albedos or sweep_value(job.scene, "albedo") == max(albedos)

    def _solve_scene(self, alg, job: Job, images, lights, mask, quality, seed: int):
        """Call an ``interface="scene"`` algorithm: ``(((normals, albedo, valid), raw output),
        seconds, error)``."""
        spec = self.scenes.spec(job.scene)
        depth = int(spec.render.max_depth) if parse_condition(job.condition)[0] == "global" else 2
        return call(alg, images, lights, mask=mask, scene=spec, max_depth=depth, seed=seed, quality=quality,
                      check=lambda out: (result_arrays(out, images.shape[1:3]), out))

    @staticmethod
    def _inverse_figures(res: JobResult, name: str, raw, n_true, domain, valid) -> None:
        """The loss curve and the angular error of the start beside the final one."""
        loss = attribute(raw, "loss")
        if loss is not None and len(loss):
            level = attribute(raw, "level")
            note = f"coarse-to-fine levels (film downsampling) {list(dict.fromkeys(np.asarray(level).tolist()))}" \
                if level is not None else ""
            res.plots[f"{name}: loss per iteration"] = profile_plot(
                np.arange(len(loss)), {"objective E": np.asarray(loss, float)}, "iteration", "objective E", note=note)
        n0 = attribute(raw, "initial_normals")
        if n0 is not None:
            n0 = np.asarray(n0, float)
            ok = valid & (np.linalg.norm(n0, axis=-1) > 0)
            _, emap0 = normal_scores(np.where(ok[..., None], n0, 0.0), n_true, domain, ok)
            opts = attribute(raw, "options")
            began = opts.get("start") if isinstance(opts, dict) else None
            res.error_maps[f"angular error (deg): {name}, its start" + (f" ({began})" if began else "")] = display_map(emap0)

    # ----------------------------------------------------------------------------- run
    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        algorithms = [a for a in algorithms if a.applies(job.condition)]
        plot = job.param("plot")
        if plot == "albedo_sweep":
            return self._albedo_sweep(job, gts, algorithms, quality)
        if plot == "reflex":
            return self._reflex(job, gts)
        if plot == "checks":
            return self._checks_plot(job, gts, algorithms, quality, seed)
        if plot == "near_sweep":
            return self._near_sweep(job, gts, algorithms, quality)
        gt = gts[job.scene]
        lights = np.asarray(job.param("lights"), float)
        images = self._inputs(job, gt, seed)
        domain = self._domain(gt, lights)
        n_true = gt["normals"].astype(float)
        alb_true = grey(gt["albedo"])
        z_true = -gt["depth"].astype(float)
        px = pixel_size(job.param("half_width", 1.0), images.shape[2])
        book = ScoreBook(job, scene_hash(gt), algorithms, scene_label=job.param("label"))
        res = JobResult(job)
        res.images["linear:input (light 0)"] = display(images[0])
        res.images["normals: truth"] = normals_display(n_true, gt.mask)
        first = True
        for alg in algorithms:
            if alg.kind == "floor":
                with Timer() as t:
                    hs, z = height_scores(n_true, z_true, domain, px, integrate=lambda *a, _f=alg, **k: _f(*a, **k))
                book.add(alg.name, hs, t.seconds)
                if "true height" not in " ".join(res.error_maps):
                    res.error_maps[f"true height ({alg.name} of the true normals)"] = display_map(z)
                continue
            raw = None
            if alg.interface == "scene":
                # the task's rule for every scene-interface method (a plugin's too), and the entry's own
                if not (self._inverse_applies(job, quality) and alg.applies_to_job(job, quality)):
                    continue
                out, seconds, err = self._solve_scene(alg, job, images, lights, gt.mask, quality, seed)
                if err is None:
                    out, raw = out
            else:
                out, seconds, err = self._solve_as(alg, job, gt, images, lights, gt.mask, quality, seed)
            if err is not None:
                book.add(alg.name, {"failed": 1.0}, seconds)
                res.failures[alg.name] = err
                continue
            n, a, valid = out
            sc, emap = normal_scores(n, n_true, domain, valid)
            sc.update(albedo_scores(np.pi * a, alb_true, domain & valid))
            hs, z_est = height_scores(n, z_true, domain & valid, px)
            sc.update(hs)
            sc.update(check_scores(images, lights, n, a, domain & valid, px)[0])
            book.add(alg.name, sc, seconds)
            res.images[f"normals: {alg.name}"] = normals_display(n, valid)
            res.error_maps[f"angular error (deg): {alg.name}"] = display_map(emap)
            if raw is not None:
                self._inverse_figures(res, alg.name, raw, n_true, domain, valid)
            if first and alg.kind == "method":
                first = False
                res.images[f"albedo x pi: {alg.name}"] = display(np.clip(np.pi * a, 0, 1))
                with np.errstate(invalid="ignore", divide="ignore"):
                    rel = np.where(domain & valid, np.pi * a / np.maximum(alb_true, 1e-6) - 1, np.nan)
                res.error_maps[f"albedo relative error: {alg.name}"] = display_map(rel)
                if job.scene.split("[")[0] == GALLERY_FAMILY and job.condition == "local":
                    res.images.update(chapter_figures(job.scene, alg.name, images, n, a, valid, z_est, px))
        res.scores = book.scores
        return res

    # ---------------------------------------------------------------------------- plots
    def _albedo_sweep(self, job: Job, gts: dict, algorithms, quality) -> JobResult:
        names = list(job.extra_scenes) + [job.scene]
        names.sort(key=lambda s: sweep_value(s, "albedo") or 0.0)
        lights = np.asarray(job.param("lights"), float)
        alg = next((a for a in algorithms if a.kind == "method"), None)
        res = JobResult(job)
        if alg is None:
            return res
        xs, series = [], {}
        for name in names:
            gt = gts[name]
            xs.append(sweep_value(name, "albedo"))
            domain = self._domain(gt, lights)
            for kind, label in (("direct", "direct (local)"), ("radiance", "full GI (global)")):
                out, _, err = self._solve(alg, self._stack(gt, kind), lights, gt.mask, quality)
                sc, al = {}, {}
                if err is None:
                    n, a, valid = out
                    sc, _ = normal_scores(n, gt["normals"], domain, valid)
                    al = albedo_scores(np.pi * a, grey(gt["albedo"]), domain & valid)
                series.setdefault(f"angular error, {label}", []).append(sc.get("normal_mean_deg", np.nan))
                series.setdefault(f"albedo rel. error, {label}", []).append(al.get("albedo_rel_err", np.nan))
        fam = job.scene.split("[")[0]
        res.plots[f"{fam}: {alg.name} error vs albedo"] = profile_plot(
            xs, {k: v for k, v in series.items() if k.startswith("angular")}, "albedo", "mean angular error (deg)")
        res.plots[f"{fam}: {alg.name} albedo error vs albedo"] = profile_plot(
            xs, {k: v for k, v in series.items() if k.startswith("albedo")}, "albedo",
            "mean |albedo_est / albedo - 1|")
        return res

    def _checks_plot(self, job: Job, gts: dict, algorithms, quality, seed: int) -> JobResult:
        """Pearson and Spearman correlation of each check map (integrability, least-squares
        residual, pi |g|) with the angular-error map of the first method, under each condition
        the scene has (``local``, noise, ambient, ``global`` where the scene renders radiance,
        ``area`` on the twin; ``near`` on a point-source scene and ``local`` on its twin)."""
        from pbrbench.metrics.normals import angular_error_map

        alg = next((a for a in algorithms if a.kind == "method" and not a.interface), None)
        res = JobResult(job)
        if alg is None:
            return res
        if job.condition == "near":
            cases = [("near", job.scene)] + [("local", n) for n in job.extra_scenes]
        else:
            cases = [("local", job.scene), (f"local+noise{NOISE:g}", job.scene),
                     (f"local+ambient{AMBIENT:g}", job.scene)]
            cases += [("global", job.scene)] + [("area", n) for n in job.extra_scenes]
        checks = ("integrability", "lsq residual", "pi |g|")
        series = {}
        for cond, name in cases:
            g = gts[name]
            spec_lights = job.param("lights") if name == job.scene else None
            lights = np.asarray(spec_lights if spec_lights is not None
                                else light_vectors(self.scenes.spec(name)), float)
            sub = Job(job.task, name, cond, (("lights", as_param(lights)),))
            images = self._inputs(sub, g, seed)
            out, _, err = self._solve(alg, images, lights, g.mask, quality)
            if err is not None:
                continue
            n, a, valid = out
            dom = self._domain(g, lights) & valid
            px = pixel_size(job.param("half_width", 1.0), images.shape[2])
            emap = np.where(dom, angular_error_map(n, g["normals"].astype(float), dom), np.nan)
            _, maps = check_scores(images, lights, n, a, dom, px)
            corr = [check_error_correlation(maps[c], emap) for c in checks]
            series[f"Pearson, {cond}"] = [c[0] for c in corr]
            series[f"Spearman, {cond}"] = [c[1] for c in corr]
        fam = job.scene.split("[")[0]
        res.plots[f"{fam}: do the chapter's checks predict the angular error? ({alg.name})"] = profile_plot(
            np.arange(len(checks)), series, "check: 0 integrability |dp/dy - dq/dx|, 1 least-squares residual, "
            "2 pi |g|", "correlation with the angular-error map",
            note="per-pixel correlation over the evaluation domain; 1 = the check ranks the pixels as their error does")
        return res

    def _near_sweep(self, job: Job, gts: dict, algorithms, quality) -> JobResult:
        """Mean angular error against the distance of the point sources (in radii of the sphere)
        for the first method and the ``near`` interface methods, with the distant twins' error
        (the first method under ``local``) for reference."""
        names = [job.scene] + list(job.extra_scenes)
        near = sorted((n for n in names if "_distant" not in n), key=lambda n: -(sweep_value(n, "radius") or 0.0))
        first = next((a for a in algorithms if a.kind == "method" and not a.interface), None)
        algs = ([first] if first is not None else []) + [a for a in algorithms if a.interface == "near"]
        res = JobResult(job)
        if not algs:
            return res
        xs, series = [], {}
        for name in near:
            spec = self.scenes.spec(name)
            radius = float(sweep_value(name, "radius") or spec.shapes[0].radius)
            target = np.asarray(spec.camera.target, float)
            dist = float(np.median([np.linalg.norm(np.asarray(li.position, float) - target) for li in spec.light_set]))
            xs.append(dist / radius)
            gt = gts[name]
            lights = light_vectors(spec)
            sub = Job(job.task, name, "near", self._params(spec) + self._near_params(spec))
            images = self._inputs(sub, gt, 0)
            domain = self._domain(gt, lights)
            for alg in algs:
                out, _, err = self._solve_as(alg, sub, gt, images, lights, gt.mask, quality, 0)
                v = np.nan
                if err is None:
                    v = normal_scores(out[0], gt["normals"], domain, out[2])[0].get("normal_mean_deg", np.nan)
                series.setdefault(f"{alg.name}, near", []).append(v)
            twin = name.replace(name.split("[")[0], name.split("[")[0] + "_distant", 1)
            if first is not None and twin in gts:
                tl = light_vectors(self.scenes.spec(twin))
                out, _, err = self._solve(first, self._stack(gts[twin], "direct"), tl, gts[twin].mask, quality)
                v = np.nan
                if err is None:
                    v = normal_scores(out[0], gts[twin]["normals"], self._domain(gts[twin], tl), out[2])[0].get(
                        "normal_mean_deg", np.nan)
                series.setdefault(f"{first.name}, distant twin (local)", []).append(v)
        fam = job.scene.split("[")[0]
        res.plots[f"{fam}: angular error vs source distance"] = profile_plot(
            xs, series, "source distance from the sphere's centre (radii)", "mean angular error (deg)")
        return res

    def _reflex(self, job: Job, gts: dict) -> JobResult:
        """Radiosity ``B = pi L`` across the groove (middle row, along x) for each albedo, and
        ``B / albedo`` (the total irradiance) against the local model's (direct) one."""
        names = list(job.extra_scenes) + [job.scene]
        names.sort(key=lambda s: sweep_value(s, "albedo") or 0.0)
        radiosity, gain = {}, {}
        x = None
        for name in names:
            gt = gts[name]
            row = gt["radiance"].shape[0] // 2
            rad, dire = grey(gt["radiance"])[row], grey(gt["direct"])[row]
            x = np.arange(rad.size) if x is None else x
            alb = sweep_value(name, "albedo")
            alb = float(alb) if alb is not None else float(np.median(grey(gt["albedo"])[row]))
            radiosity[f"albedo {alb:g}"] = np.pi * rad
            if alb > 0:
                gain[f"albedo {alb:g}, global"] = np.pi * rad / alb
                if "local model (direct)" not in gain:
                    gain["local model (direct)"] = np.pi * dire / alb
        res = JobResult(job)
        fam = job.scene.split("[")[0]
        res.plots[f"{fam}: radiosity across the groove vs albedo"] = profile_plot(
            x, radiosity, "column (pixels)", "radiosity B = pi L (middle row)")
        if gain:
            res.plots[f"{fam}: B / albedo (total irradiance) vs the local model"] = profile_plot(
                x, gain, "column (pixels)", "B / albedo (middle row)",
                note="the local model predicts the direct curve for every albedo; interreflection adds a roof that grows with albedo")
        res.images["linear:radiance (highest albedo)"] = display(gts[names[-1]]["radiance"])
        return res


TASK = PhotometricStereoTask()
