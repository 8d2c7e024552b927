"""Interreflection: forward models of radiance scored against the path tracer.

Scenes: the V grooves (``groove_reflex_parallel``, ``groove_reflex_bisector``: albedo sweeps), the
black and the white room (``room_black``, ``room_white``: perspective view), the cylindrical bump
(``cylinder_bump``), the concave cap (``ps_cap``: albedo sweep) and the red wall beside a white
floor (``colour_bleeding``).  Each model is called as ``fn(spec, (width, height))`` with the
scene's :class:`~pbrbench.scene.spec.SceneSpec` and returns the radiance it predicts at each pixel
(H, W, 3) (or (H, W)): the built-ins are the local shading model (``local``, a baseline: the direct
light of every source with shadows, no interreflection) and the radiosity model after 1, 2 and 4
bounces and converged (``radiosity:1``, ``radiosity:2``, ``radiosity:4``, ``radiosity``), all from
one memoised solution per scene (:mod:`pbrbench.radiosity.forward_models`; ``cells`` patches across
the view: 16, 8 in a draft run).

Conditions: ``local`` -- the prediction against the path tracer's direct light alone (the
reference condition, as in every task: the light transport the local shading model assumes; the
local model is right there by construction, so its error is the models' own discretisation, and
the radiosity models' excess is the interreflected light they add); ``global`` -- against its full
radiance (what a camera sees).  The headline's effect column is therefore ``global − local``, the
cost of interreflection with every task's sign: positive where a model gets worse when the light
it is judged against includes interreflection (the local model, which ignores it), negative where
it gets better (the radiosity models, which add it).  Beside it, ``headline_values``: the error
under ``global`` itself, each model's error against what the camera sees.

Scene classes (:meth:`InterreflectionTask.scene_class`; the headline gives each its own mean ± SE,
since a mean over a white room and a black one says nothing about either): the white room, the
black room, the grooves at each albedo (both groove families), the concave cap at each albedo, the
bump, and the colour-bleeding scene.  Scores
(:mod:`pbrbench.metrics.interreflection`) over the visible surface (:func:`pbrbench.tasks.common.inputs.visible_surface`): ``radiosity_rel_error`` (the headline), ``radiosity_rel_rmse``, ``radiosity_abs_bias``,
``chromaticity_error`` and ``delta_e2000`` (CIEDE2000, through colour-science).

Plot jobs (figures, no scores) reproduce the chapter's figures for the report's gallery: Figs
1.4-1.6 (shadows of an area source: ``shadow_near``, ``shadow_far``, ``shadow_small``), 1.17
(sections of the black and the white room), 1.18 and 1.20 (the groove's profile against albedo),
1.19 (the gain curve), 1.21 (reflexes in the bump's shadow) and colour bleeding (§1.3.5).
"""

from __future__ import annotations

import numpy as np

from pbrbench.metrics.interreflection import radiosity_scores
from pbrbench.registry import Algorithm
from pbrbench.tasks import _interreflection_figures as FIG
from pbrbench.tasks.base import Job, JobResult, Task, parse_condition
from pbrbench.tasks.common.figures import display, display_map
from pbrbench.tasks.common.inputs import grey, visible_surface
from pbrbench.tasks.common.scenes import sweep_value
from pbrbench.tasks.common.scoring import ScoreBook, call, check_array, scene_hash

GROOVES = ("groove_reflex_parallel", "groove_reflex_bisector")
FAMILIES = GROOVES + ("room_black", "room_white", "cylinder_bump", "ps_cap", "colour_bleeding")
SHADOWS = ("shadow_near", "shadow_far", "shadow_small")
CONDITIONS = ("global", "local")
# the headline's scene classes of the families that are not swept (grooves and cap: one class per albedo)
SCENE_CLASSES = {"room_white": "white room", "room_black": "black room", "cylinder_bump": "bump",
                 "colour_bleeding": "colour bleeding"}



def as_radiance(out, shape) -> np.ndarray:
    """A model's output as an (H, W, 3) float64 image (an (H, W) one is taken as grey)."""
    h, w = shape
    a = np.asarray(out, dtype=float) if out is not None else None
    if a is not None and a.shape == (h, w):
        a = np.repeat(a[..., None], 3, axis=2)
    return check_array(a, "radiance", (h, w, 3))


class InterreflectionTask(Task):
    name = "interreflection"
    description = ("Forward models of radiance against the path tracer: the local shading model and the radiosity "
                   "model after 1, 2, 4 bounces and converged, on grooves, rooms, a bump, a concave cap and a "
                   "colour-bleeding scene (Goral et al. 1984; Forsyth and Zisserman 1991).")
    conditions = CONDITIONS
    headline_metric = "radiosity_rel_error"
    families = FAMILIES
    short_families = FAMILIES
    reference_condition = "local"
    headline_values = ("global",)   # the headline also shows each model's error against what the camera sees
    notes = ("Columns: local (the reference, as in every task) = each model's prediction against the path tracer's "
             "direct light only, where the local model is right by construction (its error there is the models' own "
             "discretisation: piecewise-constant patches, sampled shadows) and the radiosity models' error is the "
             "interreflected light they add; global − local = the cost of interreflection: the change of the error "
             "when the prediction is judged against the full radiance (what the camera sees) instead, positive = "
             "worse (the local model, which ignores interreflection), negative = better (the radiosity models, "
             "which add it); global = the error against what the camera sees (the sum of the two). One row "
             "group per scene class (white room, black room, grooves and cap at each albedo, bump, colour "
             "bleeding): the local model fails where surfaces see each other brightly (white room, grooves and cap "
             "at high albedo, the bump's shadow) and holds where they are dark (black room, albedo 0.1); "
             "radiosity:k counts k bounces. The models of a scene share one solution, whose time is charged to "
             "the first model called. Export/evaluate: not supported (the models take the scene description).")

    def scene_class(self, scene: str) -> str | None:
        """The class of a scene in the headline (its own row group, mean ± SE over its scenes).

        Parameters
        ----------
        scene : str
            A score's scene name (``room_white``, ``groove_reflex_parallel[albedo=0.9]``, ...).

        Returns
        -------
        str or None
            ``white room``, ``black room``, ``grooves, albedo <a>`` (both groove families),
            ``concave cap, albedo <a>``, ``bump``, ``colour bleeding``; None for a scene of no
            family of the task.
        """
        fam = scene.split("[", 1)[0]
        albedo = sweep_value(scene, "albedo")
        if fam in GROOVES:
            return f"grooves, albedo {albedo:g}" if albedo is not None else "grooves"
        if fam == "ps_cap":
            return f"concave cap, albedo {albedo:g}" if albedo is not None else "concave cap"
        return SCENE_CLASSES.get(fam)

    # ------------------------------------------------------------------------- algorithms
    def builtin_algorithms(self) -> list[Algorithm]:
        from pbrbench.radiosity.forward_models import MODELS

        draft = {"draft": {"cells": 8}}   # the forward models at draft: 8 patches across the view instead of 16
        out = [Algorithm("local", self.name, MODELS["local"], kind="baseline", budgets=draft,
                         description="the local shading model: direct light with shadows, no interreflection",
                         cost_note="charged with the scene's shared work: the patch mesh, the form factors with "
                                   "their visibility rays and the radiosity solution every model of the scene reads "
                                   "(one memoised solve per scene); the local model itself is the direct term")]
        out += [Algorithm(n, self.name, fn, budgets=draft,
                          description=f"the radiosity model, {n.partition(':')[2] or 'converged'}"
                          f"{' bounce(s)' if ':' in n else ''}")
                for n, fn in MODELS.items() if n != "local"]
        return out

    # ------------------------------------------------------------------------------ jobs
    def jobs(self, quality) -> list[Job]:
        out: list[Job] = []
        kept = {}
        for fam in quality.pick(self.families, self.short_families):
            # a black scene (albedo 0 of a sweep) reflects nothing: no relative error to score
            specs = quality.keep([s for s in self.scenes.family(fam) if sweep_value(s, "albedo") != 0.0])
            kept[fam] = [s.name for s in specs]
            for s in specs:
                out += [Job(self.name, s.name, c) for c in self.conditions]
        for fam in GROOVES:  # Figs 1.18 and 1.20 (and the gain curve, Fig 1.19, with the first)
            names = kept.get(fam)
            if names:
                out.append(Job(self.name, names[-1], "global", (("plot", "groove"),), extra_scenes=tuple(names[:-1])))
        if kept.get("room_black") and kept.get("room_white"):
            out.append(Job(self.name, kept["room_white"][0], "global", (("plot", "rooms"),),
                           extra_scenes=(kept["room_black"][0],)))
        if kept.get("cylinder_bump"):
            out.append(Job(self.name, kept["cylinder_bump"][0], "global", (("plot", "bump"),)))
        if kept.get("colour_bleeding"):
            out.append(Job(self.name, kept["colour_bleeding"][0], "global", (("plot", "bleeding"),)))
        shadows = [s.name for fam in SHADOWS for s in self.scenes.family(fam)[:1]]
        if shadows:
            out.append(Job(self.name, shadows[0], "global", (("plot", "shadows"),), extra_scenes=tuple(shadows[1:])))
        return out

    # ----------------------------------------------------------------------------- run
    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        plot = job.param("plot")
        if plot is not None:
            return FIG.plot_job(self, job, gts, plot, quality)
        algorithms = [a for a in algorithms if a.applies(job.condition)]
        gt = gts[job.scene]
        spec = self.scenes.spec(job.scene)
        base, _ = parse_condition(job.condition)
        H, W = gt["radiance"].shape[:2]
        ref = np.asarray(gt["radiance"] if base == "global" else gt["direct"], np.float64)
        domain = visible_surface(gt)
        book = ScoreBook(job, scene_hash(gt), algorithms)
        res = JobResult(job)
        figures = base == "global" and gt.meta.get("replicate") is None  # not again on the delete-one-group replicates
        if figures:
            res.images[f"linear:path tracer ({base})"] = display(ref)
        shown = {}   # figures: the first baseline and the last method (the converged model among the built-ins)
        for alg in algorithms:
            out, seconds, err = call(alg, spec, (W, H), quality=quality, check=lambda o: as_radiance(o, (H, W)))
            if err is not None:
                book.add(alg.name, {"failed": 1.0}, seconds)
                res.failures[alg.name] = err
                continue
            book.add(alg.name, radiosity_scores(out, ref, domain), seconds)
            if alg.kind == "method" or (alg.kind == "baseline" and "baseline" not in shown):
                shown[alg.kind] = (alg.name, out)
        if figures:
            for kind in ("baseline", "method"):
                if kind in shown:
                    name, out = shown[kind]
                    res.images[f"linear:{name}"] = display(out)
                    with np.errstate(invalid="ignore", divide="ignore"):
                        rel = grey(out) / grey(ref) - 1.0
                    res.error_maps[f"relative error: {name}"] = display_map(np.where(domain, rel, np.nan), domain)
        res.scores = book.scores
        return res


TASK = InterreflectionTask()
