"""Shape from one shaded image on the scene library.

Scenes: ``sfs_sphere``, ``sfs_vase``, ``sfs_random`` and their ``*_area`` twins.  Each has a light
set of two sources (``light00`` along the view, ``light01`` oblique, 45 degrees in x), rendered one
at a time; each light is a separate case, scored under the scene label ``<scene>:view`` or
``<scene>:oblique`` (a scene with a single light in ``lights`` is one case under its own name).
Input: one grey image (channel mean); the light is the case's nominal source (direction in the
camera frame; for an area twin ``normalize(center - target)``, for a point source
``normalize(position - target)``) and the albedo is the known ``rho E / pi`` (median albedo AOV
times the nominal irradiance over pi), as every method but one assumes a known uniform albedo.

Conditions:

* ``local`` (``direct``) and ``local+noise0.01`` (1 % Gaussian noise of the peak);
* ``local+ambient0.1``: the chapter's ``Image = Diffuse + Ambient`` (section 1.1.3, ``I = rho
  (N . S) + rho A``): the ``direct`` image plus the constant ``rho A`` on the object, ``A`` a
  tenth of the source's term at normal incidence (``rho A = 0.1 rho E / pi``, ``rho`` the albedo
  AOV), the same in lit and attached-shadow pixels; the methods are told nothing about it (the
  given albedo stays ``rho E / pi``);
* ``local+wrong_albedo0.7``: the ``direct`` image, but every method is handed 0.7 times the
  known albedo: SFS given a wrong albedo, against ``zheng_chellappa1991``, which estimates the
  albedo (and light) from the image and ignores the one given (the chapter's section 1.3.6 says
  no method infers both shading and albedo: this one does, for a uniform albedo);
* ``area`` (the ``*_area`` twin's ``direct``: a nearby rectangle along the nominal direction);
* ``near+d<d>`` (``d`` = 2, 4, 8, :data:`NEAR_DISTANCES`): the ``sfs_near`` family, the
  sphere and camera of ``sfs_sphere`` lit by an isotropic point source ``d`` radii from the
  centre, along the view or oblique (direct light only); the methods are given the nominal
  direction from the object's centre and the irradiance ``I / d^2`` there.  Draft runs keep the
  middle distance only;
* ``global`` (``radiance``: interreflection).

Matched scenes (the headline pairs a condition's score with the reference's by scene label):
``ambient`` and ``wrong_albedo`` are scored on the reference's own ground truth (paired ±); an
``area`` twin is labelled ``<family>_area:<label>``, which the report matches to
``<family>:<label>``; a near scene is labelled with the ``sfs_sphere`` case it is the twin of
(``sfs_sphere:view`` / ``sfs_sphere:oblique``; its job is on ``sfs_near[...]``, its condition
names the distance), and, being another render, its ± adds the two scenes' errors in
quadrature, like the area twins'.  Draft runs add ``ambient``, ``wrong_albedo`` and ``near`` on
``sfs_sphere`` only.

Algorithms (from the registry), by calling convention (``interface``):

* main -- every method of :data:`pbrbench.infer.sfs.METHODS` and any plugin, called as
  ``fn(image, light, *, albedo, mask, pixel_size)`` returning an
  :class:`~pbrbench.infer.sfs.SFSResult` or anything with ``height`` (H, W) and ``normals``
  (H, W, 3) (and optionally ``converged``); the same methods with the light and albedo estimated
  from the image by the ``contour`` estimator (``<method>+estimated_light``, condition ``local``),
  except a method that estimates them itself (its ``light`` argument defaults to None:
  ``zheng_chellappa1991``);
* ``light`` -- the light estimators of :data:`pbrbench.infer.sfs.LIGHT_METHODS`, called as
  ``fn(image, mask)``, scored by ``light_error_deg`` (condition ``local``);
* ``reference`` -- ``baseline:flat`` (z = 0, normals along the view) and
  ``floor:integrate_true_normals`` (the true normals through the SFS methods' own integrator),
  which score the ground truth directly (:func:`pbrbench.metrics.sfs.flat_baseline`,
  :func:`pbrbench.metrics.sfs.floor_scores`).

Metrics: :mod:`pbrbench.metrics.sfs` (height errors after the free offset and after the best
scale, relative RMSE, mean normal angle, the convex/concave-ambiguity-aware versions), plus
``converged`` and ``failed`` (:mod:`pbrbench.metrics.table`).
"""

from __future__ import annotations

import functools
import inspect

import numpy as np

from pbrbench.metrics.sfs import flat_baseline, floor_scores, sfs_scores
from pbrbench.registry import Algorithm
from pbrbench.scene.geometry import nominal_light
from pbrbench.tasks.base import Job, JobResult, Prediction, Task, parse_condition
from pbrbench.tasks.common.figures import display, display_map, normals_display, profile_plot
from pbrbench.tasks.common.inputs import add_noise, as_param, grey, job_rng, pixel_size
from pbrbench.tasks.common.scoring import ScoreBook, Timer, attribute, call, check_array, scene_hash

FAMILIES = ("sfs_sphere", "sfs_vase", "sfs_random")
NOISE = 0.01
AMBIENT = 0.1         # rho A as a fraction of rho E / pi (local+ambient0.1)
WRONG_ALBEDO = 0.7    # the factor on the known albedo (local+wrong_albedo0.7)
NEAR_FAMILY = "sfs_near"
NEAR_MATCH = "sfs_sphere"   # the family whose cases the near scenes are the twins of
NEAR_DISTANCES = (2, 4, 8)  # point-source distances of sfs_near, in sphere radii
EST = "+estimated_light"
# the draft run's budgets (every job is also scored on its delete-one-group replicates): the
# iterative methods' sweeps halved; zheng_chellappa1991's shape step is horn1989
BUDGETS = {"horn1989": {"draft": {"max_iter": 50}}, "tsai_shah1994": {"draft": {"max_iter": 50}},
           "zheng_chellappa1991": {"draft": {"shape_options": {"max_iter": 50}}}}
COST_NOTES = {
    "horn1989": "iterative: 100 coarse-to-fine sweeps per pyramid level (5x on the coarsest), each a "
                "vectorised pass over the image; the most accurate method with an oblique light",
    "tsai_shah1994": "Newton steps of the causal system with a damped line search; it stalls after a few "
                     "steps and the remaining time is spent in rejected trial steps (a stationary point "
                     "of the linearisation, reported as not converged)",
}
ESTIMATOR = "contour"


def near_condition(distance: float) -> str:
    """``near+d<d>``: the condition of a point source ``distance`` radii from the object's centre
    (direct light, as ``area``; the base ``near`` is photometric stereo's too)."""
    return f"near+d{round(float(distance), 2):g}"


def estimates_its_own_light(fn) -> bool:
    """Whether an SFS method estimates the light itself: its ``light`` argument defaults to None
    (then a ``+estimated_light`` variant would only repeat it)."""
    try:
        p = inspect.signature(fn).parameters.get("light")
    except (TypeError, ValueError):
        return False
    return p is not None and p.default is None


def with_estimated_light(image, light, *, albedo=None, mask=None, pixel_size=1.0, method, estimator, **options):
    """Run SFS ``method`` with the light and albedo that ``estimator`` finds in ``image`` (the
    given ``light`` and ``albedo`` are ignored)."""
    est = estimator(image, mask)
    return method(image, est.direction, albedo=est.albedo, mask=mask, pixel_size=pixel_size, **options)


def flat_reference(true_height, true_normals, mask, *, pixel_size=1.0, height_range=None) -> dict:
    """``baseline:flat``: :func:`pbrbench.metrics.sfs.flat_baseline`."""
    return flat_baseline(true_height, true_normals, mask, height_range=height_range)


def floor_reference(true_height, true_normals, mask, *, pixel_size=1.0, height_range=None) -> dict:
    """``floor:integrate_true_normals``: :func:`pbrbench.metrics.sfs.floor_scores` on the pixels
    whose true normal faces the camera."""
    dom = mask & (true_normals[..., 2] > 1e-3)
    return floor_scores(true_height, true_normals, dom, pixel_size=pixel_size, height_range=height_range)


def result_arrays(out, shape):
    """(height, normals, converged or None) from what an SFS algorithm returned."""
    z = attribute(out, "height", 0)
    n = attribute(out, "normals", 1)
    if z is None or n is None:
        raise ValueError("output: return height (H, W) and normals (H, W, 3) (an SFSResult, a dict or a tuple)")
    z = check_array(z, "height", shape)
    n = check_array(n, "normals", shape + (3,))
    conv = attribute(out, "converged", None)
    return z, n, (None if conv is None else float(bool(conv)))


class SFSTask(Task):
    name = "sfs"
    description = ("Shape from one shaded image (Horn 1989, Tsai-Shah 1994, Pentland 1990, Kimmel-"
                   "Sethian 2001) with the flat baseline and the true-normal integration floor.")
    conditions = ("local", f"local+noise{NOISE:g}", f"local+ambient{AMBIENT:g}",
                  f"local+wrong_albedo{WRONG_ALBEDO:g}", "area", *(near_condition(d) for d in NEAR_DISTANCES),
                  "global")
    headline_metric = "normal_mean_deg"
    families = FAMILIES
    short_families = ("sfs_sphere", "sfs_vase")   # the vase stands on a plane: interreflection
    def builtin_algorithms(self) -> list[Algorithm]:
        from pbrbench.infer.sfs import LIGHT_METHODS, METHODS

        out = [Algorithm(n, self.name, fn, budgets=BUDGETS.get(n, {}), cost_note=COST_NOTES.get(n, ""))
               for n, fn in METHODS.items()]
        out += [Algorithm(n + EST, self.name, functools.partial(with_estimated_light, method=fn,
                                                                estimator=LIGHT_METHODS[ESTIMATOR]),
                          conditions=("local",), figures=False, variant_of=n, budgets=BUDGETS.get(n, {}),
                          description=f"{n} with the light and albedo estimated by the {ESTIMATOR} method")
                for n, fn in METHODS.items() if not estimates_its_own_light(fn)]
        out += [Algorithm("baseline:flat", self.name, flat_reference, kind="baseline", interface="reference"),
                Algorithm("floor:integrate_true_normals", self.name, floor_reference, kind="floor",
                          interface="reference")]
        out += [Algorithm(f"light_from_shading:{n}", self.name, fn, interface="light", conditions=("local",))
                for n, fn in LIGHT_METHODS.items()]
        return out

    @staticmethod
    def _params(spec, light, index) -> tuple:
        d, e = nominal_light(light, spec.camera)
        label = "view" if d[2] > 0.999 else "oblique"
        return (("light", as_param(d)), ("irradiance", round(float(e), 9)), ("light_index", index),
                ("label", label), ("half_width", float(spec.camera.half_width)))

    @staticmethod
    def _cases(spec):
        """(light, index) pairs: each light of the light set (rendered alone as ``lightNN.*``), or
        the single light of ``lights`` (rendered as ``direct`` / ``radiance``)."""
        if spec.light_set:
            return [(li, k) for k, li in enumerate(spec.light_set)]
        if len(spec.lights) == 1:
            return [(spec.lights[0], -1)]
        return []

    def jobs(self, quality) -> list[Job]:
        out = []
        short = quality.short_subset
        for fam in quality.pick(self.families, self.short_families):
            twins = self.scenes.family(f"{fam}_area")
            for i, s in enumerate(self.scenes.family(fam)):
                tw = twins[i] if i < len(twins) else None
                tw_cases = dict((k, li) for li, k in self._cases(tw)) if tw is not None else {}
                for light, k in self._cases(s):
                    p = self._params(s, light, k)
                    out.append(Job(self.name, s.name, "local", p))
                    out.append(Job(self.name, s.name, f"local+noise{NOISE:g}", p))
                    if not short or fam == NEAR_MATCH:
                        out.append(Job(self.name, s.name, f"local+ambient{AMBIENT:g}", p))
                        out.append(Job(self.name, s.name, f"local+wrong_albedo{WRONG_ALBEDO:g}", p))
                    out.append(Job(self.name, s.name, "global", p))
                    if k in tw_cases:
                        out.append(Job(self.name, tw.name, "area", self._params(tw, tw_cases[k], k)))
        if NEAR_MATCH in quality.pick(self.families, self.short_families):
            out += self._near_jobs(quality)
        out += [Job(self.name, s.name, "global", (("plot", "relief"),)) for s in self.scenes.family(RELIEF)[:1]]
        return out

    def _near_jobs(self, quality) -> list[Job]:
        """``near+d<d>`` jobs: each scene of ``sfs_near`` (one point source), labelled as the
        ``sfs_sphere`` case of its direction; per direction the distances ``quality.keep`` keeps
        less one (draft: the middle one)."""
        by_label: dict[str, list] = {}
        for s in self.scenes.family(NEAR_FAMILY):
            for light, k in self._cases(s):
                p = self._params(s, light, k)
                d = float(np.linalg.norm(np.asarray(light.position, float) - np.asarray(s.camera.target, float)))
                by_label.setdefault(dict(p)["label"], []).append((d, s, p))
        out = []
        for label in sorted(by_label):
            cases = sorted(by_label[label], key=lambda c: c[0])
            for d, s, p in quality.keep(cases, extra=-1 if quality.sweep_keep else 0):
                out.append(Job(self.name, s.name, near_condition(d), p + (("match", NEAR_MATCH),)))
        return out

    # --------------------------------------------------- export / evaluate (pbrbench.bench.external)
    input_names = ("image", "light")
    predictions = (
        Prediction("height", "H,W", True, "height z in world units (any offset), camera frame"),
        Prediction("normals", "H,W,3", False, "unit normals in the camera frame (missing: from the height "
                   "by finite differences, pbrbench.infer.integration.gradients_from_height)"),
        Prediction("converged", "scalar", False, "1 if the method converged, 0 if not (missing: not scored)"),
    )

    def prediction_output(self, files: dict, inputs: dict):
        out = dict(files)
        if "normals" not in out:
            from pbrbench.infer.integration import gradients_from_height, normals_from_gradients

            p, q = gradients_from_height(out["height"], pixel_size=float(inputs.get("pixel_size", 1.0)))
            out["normals"] = normals_from_gradients(p, q)
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        if job.param("plot") == "relief":
            return relief_figures(job, gts[job.scene], self.library_spec(job.scene))
        algorithms = [a for a in algorithms if a.applies(job.condition)]
        gt = gts[job.scene]
        base, mods = parse_condition(job.condition)
        k = int(job.param("light_index", -1))
        kind = "radiance" if base == "global" else "direct"
        img = grey(gt[kind if k < 0 else f"light{k:02d}.{kind}"])
        if mods.get("noise", 0) > 0:
            img = add_noise(img, mods["noise"], job_rng(job, seed))
        mask = gt.mask
        light = np.asarray(job.param("light"), float)
        irr = float(job.param("irradiance", np.pi))
        if mods.get("ambient", 0) > 0:   # Image = Diffuse + Ambient: rho A, A = ambient * E / pi
            img = img + np.where(mask, mods["ambient"] * grey(gt["albedo"]) * irr / np.pi, 0.0)
        rho = float(np.median(grey(gt["albedo"])[mask])) if mask.any() else 1.0
        known_albedo = rho * irr / np.pi * mods.get("wrong_albedo", 1.0)
        px = pixel_size(job.param("half_width", 1.0), img.shape[1])
        z_true = np.where(mask, -gt["depth"].astype(float), 0.0)
        zrange = float(np.ptp(z_true[mask])) if mask.any() else None
        n_true = gt["normals"].astype(float)
        label = job.param("label")
        shown = job.param("match", job.scene)   # a near scene is scored as the sfs_sphere case it twins
        book = ScoreBook(job, scene_hash(gt), algorithms, scene_label=f"{shown}:{label}" if label else None)
        res = JobResult(job)
        res.images["linear:input"] = display(img)
        res.images["normals: truth"] = normals_display(n_true, mask)
        if job.condition == "local" and label == "oblique" and job.scene == "sfs_sphere":
            res.plots["Fig 1.3 Lambert's cosine law: the rendered sphere's radiance against the cosine of "
                      "the angle between normal and source"] = cosine_law_plot(gt, img, light, irr)
        row = img.shape[0] // 2
        zt_row = np.where(mask[row], z_true[row] - z_true[mask].mean(), np.nan)
        prof = {"truth": zt_row}
        s_unit = light / np.linalg.norm(light)
        for alg in algorithms:
            if alg.interface == "reference":
                with Timer() as t:
                    sc = alg(z_true, n_true, mask, pixel_size=px, height_range=zrange, quality=quality)
                book.add(alg.name, sc, t.seconds)
                if alg.kind == "baseline":
                    prof[alg.name] = np.where(mask[row], 0.0, np.nan)
                continue
            if alg.interface == "light":
                out, seconds, err = call(alg, img, mask, quality=quality,
                                           check=lambda o: check_array(attribute(o, "direction", 0), "direction", (3,)))
                if err is not None:
                    book.add(alg.name, {"failed": 1.0}, seconds)
                    res.failures[alg.name] = err
                else:
                    nd = float(np.linalg.norm(out))
                    d = out if abs(nd - 1.0) <= 1e-9 else out / max(nd, 1e-300)
                    ang = float(np.degrees(np.arccos(np.clip(np.dot(d, s_unit), -1, 1))))
                    book.add(alg.name, {"light_error_deg": ang}, 0.0)
                continue
            out, seconds, err = call(alg, img, light, albedo=known_albedo, mask=mask, pixel_size=px,
                                       quality=quality, check=lambda o: result_arrays(o, img.shape))
            if err is not None:
                book.add(alg.name, {"failed": 1.0}, seconds)
                res.failures[alg.name] = err
                continue
            z, n, conv = out
            sc = sfs_scores(z, n, z_true, n_true, mask, height_range=zrange)
            if conv is not None:
                sc["converged"] = conv
            sc["failed"] = 0.0
            book.add(alg.name, sc, seconds)
            if alg.figures:
                prof[alg.name] = np.where(mask[row], z[row], np.nan)
                res.images[f"normals: {alg.name}"] = normals_display(n, mask)
                res.error_maps[f"height error (offset removed): {alg.name}"] = display_map(
                    np.where(mask, (z - z[mask].mean()) - (z_true - z_true[mask].mean()), np.nan))
        floors = [a for a in algorithms if a.kind == "floor" and a.interface == "reference"]
        if floors:
            from pbrbench.metrics.sfs import floor_height

            dom = mask & (n_true[..., 2] > 1e-3)
            z_floor = floor_height(n_true, dom, pixel_size=px)
            prof[floors[0].name] = np.where(dom[row], z_floor[row], np.nan)
        res.plots[f"height profile, row {row}"] = profile_plot(
            np.arange(img.shape[1]) * px, prof, "x (world units from the left edge)", "height (offset removed)")
        res.scores = book.scores
        return res


RELIEF = "craters"     # Fig 1.23's scene family: a cratered plain under a grazing and a high source (a figure)


def relief_figures(job: Job, gt, spec) -> JobResult:
    """Fig 1.23 from the ``craters`` render: the plain under each source of its light set, the
    grazing one first (shading and cast shadows pick out every crater), the high one after
    (the relief all but vanishes)."""
    res = JobResult(job)
    for k, light in enumerate(spec.light_set if spec is not None else ()):
        d, _ = nominal_light(light, spec.camera)
        elev = float(np.degrees(np.arcsin(np.clip(d[2], -1.0, 1.0))))
        name = f"light{k:02d}.radiance"
        if name in gt:
            res.images[f"linear:Fig 1.23 craters, source at {elev:.0f} deg elevation"
                       + (": shading and cast shadows pick out the relief" if elev < 30 else ": the relief all but vanishes")] = \
                display(gt[name])
    return res


def cosine_law_plot(gt, image, light, irradiance: float, n_points: int = 1500) -> dict:
    """Fig 1.3 from a render: ``pi L / (rho E)`` of every fully covered pixel of ``image`` (the
    job's direct-light image of one source, grey) against ``N . S`` (the AOV normal, the unit
    source direction), with Lambert's ``max(0, N . S)``; a tilted patch collects light in
    proportion to the cosine."""
    s = np.asarray(light, float)
    s = s / np.linalg.norm(s)
    m = np.asarray(gt.mask, bool)
    cos = (np.asarray(gt["normals"], float) @ s)[m]
    rho = grey(gt["albedo"])[m]
    L = np.asarray(image, float)[m]
    ok = rho > 0
    y = np.pi * L[ok] / (rho[ok] * irradiance)
    x = cos[ok]
    if x.size > n_points:
        idx = np.random.default_rng(0).choice(x.size, n_points, replace=False)
        x, y = x[idx], y[idx]
    line = np.linspace(-0.3, 1.0, 27)
    return {"x": None, "series": {
        "Lambert: max(0, cos theta)": {"x": line.tolist(), "y": np.maximum(line, 0.0).tolist(), "color": "0.6",
                                       "marker": ""},
        "rendered pixels (direct light)": {"x": x.tolist(), "y": y.tolist(), "color": "C0", "marker": ".",
                                           "linestyle": "", "markersize": 3}},
        "xlabel": "cos theta = N . S", "ylabel": "pi L / (albedo E)",
        "title": "Fig 1.3: brightness follows the cosine of the angle to the source"}


TASK = SFSTask()
