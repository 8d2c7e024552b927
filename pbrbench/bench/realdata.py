"""Evaluate algorithms on real data sets with their published protocols, stored as a run.

* photometric stereo on DiLiGenT-layout folders (:mod:`pbrbench.datasets.diligent`): every
  object with ground-truth normals; the grey images (channel means, each channel divided by its
  light's intensity) and the unit light directions go to each algorithm with the task's calling
  convention ``fn(images, lights, *, mask)``; scores: the DiLiGenT mean and median angular error
  over the mask (an invalid estimate counts 90 degrees), and the fractions under 5 / 10 degrees;
* lightness on MIT-Intrinsic-layout folders (:mod:`pbrbench.datasets.mit`): the grey diffuse
  image to ``fn(image, *, mask)``; scores: the Grosse et al. 2009 ``intrinsic_lmse`` (0.5
  shading + 0.5 reflectance LMSE, window 20, step 10) and the reflectance term ``lmse``; the
  shading term is printed and written to the JSON.

The algorithms: the task's built-in methods and baselines (``methods`` selects some), plugins
(``specs``, as ``pbrbench run --algorithm``; run in a child process with a time limit) and, with
``predictions``, an external program's files per object (``PDIR/<object>/normals.npy`` or
``.exr`` / ``.mat`` / ``.txt``; ``PDIR/<object>/reflectance.*`` and ``shading.*``).  Scores go
into the results store as a run of quality ``real`` and condition ``real`` (report, history and
compare read it); a failing algorithm is one failed score with its message.  A malformed
object folder stops the evaluation with the loader's one-line error naming the file; the
loaders' warnings (data that may be wrong) become notes of the evaluation.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrbench.errors import UserError

CONDITION = "real"


def _one_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {' '.join(str(e).split())}"[:300]


def _call(alg, *args, check, **kwargs):
    """(output, seconds, error): an algorithm's exception or unusable output is its failure."""
    import warnings

    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out = alg(*args, **kwargs)
        seconds = time.perf_counter() - t0
        return check(out), seconds, None
    except Exception as e:  # noqa: BLE001 - a user's algorithm may raise anything
        return None, time.perf_counter() - t0, _one_line(e)


def _load(loader, path, notes: list, **kw):
    """``loader(path, **kw)`` with its data warnings (one line each) added to ``notes``; a
    malformed folder raises the loader's one-line ``UserError``."""
    import warnings

    from pbrbench.datasets.files import DataWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataWarning)
        obj = loader(path, **kw)
    for w in caught:
        if issubclass(w.category, DataWarning):
            notes.append(f"warning: {' '.join(str(w.message).split())}")
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return obj


def _failed(ev, res, job, digest, obj, alg, err: str, seconds: float) -> None:
    """Record one algorithm's failure on one object: its ``failed`` score, the reason, the row."""
    res.scores += _scores(job, digest, alg, {"failed": 1.0}, seconds)
    res.failures[alg.name] = err
    ev.failures.append(f"{obj.name}: {alg.name}: {err}")
    ev.rows.append({"object": obj.name, "algorithm": alg.name, "scores": {}, "error": err})


def _scores(job, scene_hash, alg, values: dict, seconds: float) -> list:
    from pbrbench.metrics import metric
    from pbrbench.tasks.base import Score

    return [Score(task=job.task, scene=job.scene, scene_hash=scene_hash, condition=job.condition, algorithm=alg.name,
                  algorithm_version=alg.full_version, metric=k, value=float(v), seconds=float(seconds),
                  better=metric(k).better, unit=metric(k).unit) for k, v in values.items()]


def _thumb(a, mask=None, normals=False, size: int = 128) -> np.ndarray:
    """A small float32 copy for the report (block means), normals as (n + 1) / 2."""
    a = np.nan_to_num(np.asarray(a, np.float64))
    if normals:
        a = np.clip((a + 1) / 2, 0, 1)
    if mask is not None:
        a = np.where(mask.reshape(mask.shape + (1,) * (a.ndim - 2)), a, 0.0)
    f = max(1, -(-max(a.shape[:2]) // size))
    h, w = a.shape[0] // f * f, a.shape[1] // f * f
    a = a[:h, :w].reshape((h // f, f, w // f, f) + a.shape[2:]).mean(axis=(1, 3))
    return a.astype(np.float32)


@dataclass
class Evaluation:
    task: str
    dataset: str
    rows: list[dict] = field(default_factory=list)          # object, algorithm, scores
    failures: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    headline: tuple[str, ...] = ()
    run_id: str | None = None
    report: Path | None = None

    def table(self) -> tuple[list[str], list[str], dict]:
        objs = list(dict.fromkeys(r["object"] for r in self.rows))
        algs = list(dict.fromkeys(r["algorithm"] for r in self.rows))
        cells = {(r["object"], r["algorithm"]): r["scores"] for r in self.rows}
        return objs, algs, cells

    def lines(self) -> list[str]:
        objs, algs, cells = self.table()
        out = [f"{self.task} on {self.dataset} ({len(objs)} object(s)): " + " / ".join(self.headline)
               + ("; lower is better" if self.headline else "")]
        if not objs:
            return out + [f"  {n}" for n in self.notes] + [f"  failed: {f}" for f in self.failures]
        from pbrbench.text import text_table

        def cell(sc):
            if not sc or any(k not in sc for k in self.headline):
                return "failed"
            return " / ".join(f"{sc[k]:.3g}" for k in self.headline)

        table = [[o] + [cell(cells.get((o, a))) for a in algs] for o in objs]
        means = []
        for a in algs:
            vals = [cells.get((o, a)) for o in objs]
            if all(v and all(k in v for k in self.headline) for v in vals):
                means.append(" / ".join(f"{np.mean([v[k] for v in vals]):.3g}" for k in self.headline))
            else:
                means.append("-")
        out += text_table(table + [["mean", *means]], header=["object", *algs], indent="  ", gap="    ")
        out += [f"  note: {n}" for n in self.notes]
        out += [f"pbrbench: failed: {f}" for f in self.failures]
        if self.run_id:
            out.append(f"run {self.run_id}" + (f"; report: {self.report.resolve()}" if self.report else ""))
        return out

    def as_dict(self) -> dict:
        return {"task": self.task, "dataset": self.dataset, "headline": list(self.headline), "rows": self.rows,
                "failures": self.failures, "notes": self.notes, "run": self.run_id}


def _digest(files) -> str:
    h = hashlib.sha256()
    for f in sorted(Path(f) for f in files):
        try:
            h.update(f"{f.name}:{f.stat().st_size}".encode())
        except OSError:
            pass
    return h.hexdigest()[:16]


def _algorithms(task, methods, specs, extra) -> list:
    from pbrbench.plugins import add_algorithm_spec
    from pbrbench.registry import DEFAULT_TIME_LIMIT, Registry

    builtins = [a for a in task.builtin_algorithms() if a.kind in ("method", "baseline") and not a.interface
                and a.conditions is None]
    if methods:
        names = {a.name: a for a in builtins}
        unknown = [m for m in methods if m not in names]
        if unknown:
            raise UserError(f"--method {unknown[0]}: not a method of {task.name}; choose from {', '.join(names)}")
        builtins = [names[m] for m in methods]
    reg = Registry(builtins)
    for spec in specs:
        add_algorithm_spec(reg, spec, [task.name], time_limit=DEFAULT_TIME_LIMIT)
    for alg in extra:
        reg.add(alg)
    return list(reg)


def _prediction_file(pdir: Path, obj: str, stem: str) -> Path | None:
    from pbrbench.datasets.files import find_stem

    for folder, s in ((pdir / obj, stem), (pdir, f"{obj}_{stem}"), (pdir, obj if stem == "normals" else "")):
        if s and folder.is_dir():
            p = find_stem(folder, s, (".npy", ".exr", ".mat", ".txt", ".png", ".tif", ".tiff"))
            if p is not None:
                return p
    return None


class _FileNormals:
    """An external program's normals for DiLiGenT objects, from ``PDIR``."""

    def __init__(self, pdir: Path):
        self.pdir = Path(pdir)
        self.current = None

    def __call__(self, images, lights, *, mask=None):
        from pbrbench.datasets.diligent import read_normals

        obj = self.current
        p = _prediction_file(self.pdir, obj.name, "normals")
        if p is None:
            raise ValueError(f"{self.pdir / obj.name}/normals.npy (or .exr, .mat, .txt): missing")
        try:
            n = read_normals(p, obj.mask.shape)
        except UserError as e:
            raise ValueError(str(e)) from None
        return {"normals": n, "albedo": np.ones(obj.mask.shape)}


class _FileIntrinsics:
    def __init__(self, pdir: Path):
        self.pdir = Path(pdir)
        self.current = None

    def __call__(self, image, *, mask=None):
        from pbrbench.io import read_image

        obj = self.current
        out = {}
        for stem in ("reflectance", "shading"):
            p = _prediction_file(self.pdir, obj.name, stem)
            if p is not None:
                a = np.asarray(read_image(p), float)
                out[stem] = a.mean(axis=-1) if a.ndim == 3 else a
        if not out:
            raise ValueError(f"{self.pdir / obj.name}/reflectance.npy or shading.npy (or .exr, .png): missing")
        for want, have in (("reflectance", "shading"), ("shading", "reflectance")):
            if want not in out:
                h = out[have]
                out[want] = np.divide(image, h, out=np.zeros_like(image), where=h > 0)
        return out["reflectance"], out["shading"]


def evaluate_folder(task_name: str, folder, *, methods=(), specs=(), predictions=None, name: str = "external",
                    settings=None, store_run: bool = True, report: bool = True, log=None) -> Evaluation:
    """Evaluate on a DiLiGenT-layout folder (``photometric_stereo``) or an MIT-layout folder
    (``lightness``); see the module docstring."""
    from pbrbench.datasets import diligent_objects, mit_objects

    folder = Path(folder)
    layouts = {   # task -> (reader, evaluation, what the layout's object folder holds)
        "photometric_stereo": (diligent_objects, _diligent, "DiLiGenT object folder (light_directions.txt, "
                               "001.png ..., mask.png, Normal_gt.mat)"),
        "lightness": (mit_objects, _mit, "MIT Intrinsic Images object folder (diffuse.png, reflectance.png, "
                      "shading.png, mask.png)"),
    }
    if task_name in layouts:
        read, evaluate, layout = layouts[task_name]
        objs = read(folder)
        if not objs:
            raise UserError(f"{folder}: no manifest.json and no {layout} at or below it")
        return evaluate(objs, folder, methods, specs, predictions, name, settings, store_run, report, log)
    raise UserError(f"evaluate {task_name} {folder}: not an export (no manifest.json); real data sets are read for "
                    "photometric_stereo (DiLiGenT layout) and lightness (MIT Intrinsic Images layout)")


def _file_alg(task, fn, name, pdir):
    from pbrbench.registry import Algorithm

    return Algorithm(name, task, fn, kind="plugin", version="1",
                     fingerprint=_digest(p for p in Path(pdir).rglob("*") if p.is_file()),
                     origin=f"pbrbench evaluate --predictions {Path(pdir).resolve()}")


def _diligent(objs, root, methods, specs, predictions, name, settings, store_run, report, log) -> Evaluation:
    from pbrbench.datasets.diligent import frame_check, load_diligent
    from pbrbench.metrics.normals import angular_error_map, angular_error_stats
    from pbrbench.tasks.base import Job, JobResult
    from pbrbench.tasks.photometric_stereo import TASK, result_arrays

    reader = _FileNormals(predictions) if predictions else None
    algs = _algorithms(TASK, methods, specs, [_file_alg(TASK.name, reader, name, predictions)] if reader else [])
    ev = Evaluation(TASK.name, f"DiLiGenT-layout data in {root}", headline=("normal_mean_deg", "normal_median_deg"))
    jobs = []
    for path in objs:
        obj = _load(load_diligent, path, ev.notes, log=log)
        if obj.normals is None:
            ev.notes.append(f"{obj.name}: no ground-truth normals (Normal_gt.mat / .txt); not scored")
            continue
        fc = frame_check(obj)
        best = max(fc, key=fc.get)
        if best != "as_given":
            ev.notes.append(f"{obj.name}: the images fit the normals better with {best} ({fc[best]:.3f} vs "
                            f"{fc['as_given']:.3f}): normals and lights seem to be in different frames")
        if reader is not None:
            reader.current = obj
        job = Job(TASK.name, f"diligent:{obj.name}", CONDITION)
        digest = _digest(obj.files)
        res = JobResult(job)
        res.images["linear:input (light 0)"] = _thumb(obj.grey[0])
        res.images["normals: truth"] = _thumb(obj.normals, obj.mask, normals=True)
        g = obj.grey
        for alg in algs:
            if log:
                log(f"{obj.name}: {alg.name}")
            out, seconds, err = _call(alg, g, obj.lights, mask=obj.mask,
                                      check=lambda o, hw=g.shape[1:3]: result_arrays(o, hw))
            if err is not None:
                _failed(ev, res, job, digest, obj, alg, err, seconds)
                continue
            n, _, valid = out
            n = np.where(valid[..., None], n, 0.0)
            st = angular_error_stats(n, obj.normals, obj.mask)
            sc = {"normal_mean_deg": st["mean"], "normal_median_deg": st["median"],
                  "normal_frac_under_5deg": st["frac_under_5"], "normal_frac_under_10deg": st["frac_under_10"],
                  "coverage": float((valid & obj.mask).sum() / obj.mask.sum())}
            res.scores += _scores(job, digest, alg, sc, seconds)
            ev.rows.append({"object": obj.name, "algorithm": alg.name, "scores": sc, "seconds": seconds})
            res.images[f"normals: {alg.name}"] = _thumb(n, obj.mask, normals=True)
            res.error_maps[f"angular error (deg): {alg.name}"] = _thumb(
                np.where(obj.mask, angular_error_map(n, obj.normals, obj.mask), np.nan))
        jobs.append(res)
    if store_run and jobs:
        _store(ev, jobs, TASK, algs, settings, report, f"photometric stereo on {root}")
    return ev


def _mit(objs, root, methods, specs, predictions, name, settings, store_run, report, log) -> Evaluation:
    from pbrbench.checks import as_float_array, check_finite
    from pbrbench.datasets.mit import EVALUATED, load_mit_object, mit_scores
    from pbrbench.tasks.base import Job, JobResult
    from pbrbench.tasks.lightness import TASK

    reader = _FileIntrinsics(predictions) if predictions else None
    algs = _algorithms(TASK, methods, specs, [_file_alg(TASK.name, reader, name, predictions)] if reader else [])
    ev = Evaluation(TASK.name, f"MIT-Intrinsic-layout data in {root}", headline=("intrinsic_lmse",))
    jobs = []

    def grey2d(a, what, shape, m):
        a = as_float_array(a, what)
        a = a.mean(-1) if a.ndim == 3 else a
        if a.shape != shape:
            raise ValueError(f"{what}: returned shape {a.shape}, expected {shape}")
        check_finite(a, what, where=m)
        return a

    for path in objs:
        obj = _load(load_mit_object, path, ev.notes)
        if reader is not None:
            reader.current = obj
        job = Job(TASK.name, f"mit:{obj.name}", CONDITION)
        digest = _digest(p for p in obj.path.iterdir() if p.is_file())
        res = JobResult(job)
        img = obj.image
        res.images["linear:input (diffuse, grey)"] = _thumb(img)
        res.images["reflectance: truth"] = _thumb(obj.reflectance_grey / max(obj.reflectance_grey.max(), 1e-12))

        def check(o, shape=img.shape, m=obj.mask):
            if isinstance(o, dict):
                r, s = o.get("reflectance"), o.get("shading")
            elif isinstance(o, (tuple, list)) and len(o) >= 2:
                r, s = o[0], o[1]
            else:
                r, s = getattr(o, "reflectance", None), getattr(o, "shading", None)
            if r is None or s is None:
                raise ValueError("output: return (reflectance, shading) of the image's shape")
            return grey2d(r, "reflectance", shape, m), grey2d(s, "shading", shape, m)

        for alg in algs:
            if log:
                log(f"{obj.name}: {alg.name}")
            out, seconds, err = _call(alg, img, mask=obj.mask, check=check)
            if err is None:
                try:
                    sc = mit_scores(out[0], out[1], obj)
                except ValueError as e:
                    err = _one_line(e)
            if err is not None:
                _failed(ev, res, job, digest, obj, alg, err, seconds)
                continue
            res.scores += _scores(job, digest, alg, {"intrinsic_lmse": sc["intrinsic_lmse"], "lmse": sc["lmse_reflectance"]},
                                  seconds)
            ev.rows.append({"object": obj.name, "algorithm": alg.name, "scores": sc, "seconds": seconds})
            r = out[0]
            peak = float(np.max(r[obj.mask])) if obj.mask.any() else 1.0
            res.images[f"reflectance: {alg.name}"] = _thumb(np.clip(r / max(peak, 1e-12), 0, 1))
        jobs.append(res)
    if {Path(p).name for p in objs} != set(EVALUATED):
        ev.notes.append("the published table averages exactly the 16 objects of pbrbench.datasets.mit.EVALUATED; "
                        "this mean is over the objects found")
    if store_run and jobs:
        _store(ev, jobs, TASK, algs, settings, report, f"lightness on {root}")
    return ev


def _store(ev: Evaluation, results, task, algs, settings, report: bool, what: str):
    from pbrbench.bench.run import _check_scores, _write_files
    from pbrbench.bench.store import Store
    from pbrbench.report.figures import job_figures, slug
    if settings is None:
        raise TypeError("settings: storing an evaluation needs the run's Settings (pass settings=, or store_run=False)")
    info = {task.name: {"description": f"{task.description} Real data: {what}.", "conditions": [CONDITION],
                        "headline_metric": ev.headline[0], "algorithms": [a.name for a in algs],
                        "algorithm_kinds": {a.name: a.kind for a in algs},
                        "algorithm_versions": {a.name: a.full_version for a in algs},
                        "algorithm_origins": {a.name: a.origin for a in algs}}}
    with Store(settings.store_path()) as store:
        run_id = store.create_run(quality_name="real", config={"tasks": [task.name], "quality": "real", "dataset": what,
                                                           "task_info": info}, variant=None)
        run_dir = Path(settings.out) / run_id
        run_dir.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        for res in results:
            files, _ = job_figures(res, slug(res.job.key))
            _write_files(run_dir, files)
            store.add_job_result(run_id, res.job.key, task.name, _check_scores(res.job, res.scores),
                                 seconds=time.perf_counter() - t0)
        store.export_json(run_id, run_dir / "scores.json", status="complete")
        if report:
            from pbrbench.report.html import write_report

            ev.report = write_report(store, run_id, out_dir=run_dir, status="complete")
        store.set_status(run_id, "complete")
    ev.run_id = run_id
