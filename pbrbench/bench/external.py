"""Score programs written in any language: export every job's inputs to open files, read the
predictions the program writes, and score them as a run.

``export`` (:func:`export_task`) runs each scored job of a task through the task's own
``run_job`` with one recording algorithm, which captures exactly the arguments the task passes
an algorithm (images after the condition's noise, light vectors, masks, the known albedo, ...),
and writes them:

* arrays of two or more dimensions as ``<name>.npy`` (exact: the float64 values the in-process
  algorithms receive) and as open images: float ``<name>.exr`` (float32; a stack as
  ``<name>/000.exr ...``), integer ``<name>.png`` / ``<name>/000.png`` (8 or 16 bits, lossless),
  masks ``<name>.png`` (0 / 255);
* numbers and small vectors (light vectors, exposure times, pixel size) in ``job.json``, exact
  (a JSON number round-trips a float64), with their units;
* ``manifest.json`` naming every job, its scene, condition and folder, and the files a prediction
  must provide (:class:`pbrbench.tasks.base.Prediction`), plus a ``README.txt``.

``evaluate`` (:func:`evaluate_export`) scores the predictions through the same ``run_job`` with
an algorithm (:class:`PredictionReader`) that returns the job's files, so the noise seeds, the
evaluation domains and the metrics are the ones of an in-process run: a program that reproduces
a built-in method from the ``.npy`` inputs gets its scores exactly.  The reader also checks that
the inputs it is handed are the exported ones (their sha256), so predictions made for other
renders are refused instead of scored.  A missing, mis-shaped or non-finite prediction file is
one failed score with a one-line message naming the file; the other jobs are scored.  The
result is stored as a run (report, history, compare).
"""

from __future__ import annotations

import contextvars
import hashlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from pbrbench.errors import UserError

MANIFEST = "manifest.json"
FORMAT = "pbrbench-export/1"
_JOB = contextvars.ContextVar("pbrbench_external_job", default=None)
_SUFFIXES = (".npy", ".exr", ".png", ".tif", ".tiff", ".pfm", ".txt")

CONVENTIONS = {
    "arrays": "images (H, W[, C]) row 0 at the top, stacks (K, H, W[, C]); .npy files hold the exact float64 "
              "inputs of the in-process algorithms, .exr files the same values rounded to float32",
    "camera_frame": "x right, y up, z toward the camera",
    "lights": "light vectors point from the surface toward the source, length = irradiance at the target "
              "(radiance images carry rho E cos / pi)",
    "masks": "PNG 0 / 255 (or bool .npy); non-zero = inside",
    "units": "radiance in the scene's emitter units (W m^-2 sr^-1), irradiance W m^-2, lengths and pixel "
             "size in world units, exposure times in seconds",
}


# ----------------------------------------------------------------------------- helpers
def _safe(s: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in s)[:80]


def array_digest(a) -> str:
    """sha256 of an array's dtype, shape and bytes (how the reader recognises exported inputs)."""
    a = np.ascontiguousarray(a)
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    if isinstance(v, (tuple, list)):
        return [_jsonable(x) for x in v]
    return v


class _Captured(Exception):
    """Raised by the recording algorithm to stop the job once its inputs are captured."""


class _Recorder:
    def __init__(self):
        self.calls = []

    def __call__(self, *args, **kwargs):
        self.calls.append((args, kwargs))
        raise _Captured("inputs captured")


def capture_inputs(task, job, gts, *, seed: int, quality) -> dict:
    """The arguments ``task.run_job`` passes an algorithm of its main calling convention on
    ``job``: ``{name: value}`` (positional arguments named by ``task.input_names``)."""
    from pbrbench.registry import Algorithm

    rec = _Recorder()
    alg = Algorithm("export", task.name, rec, kind="plugin", version="0", fingerprint="export")
    task.run_job(job, gts, seed=seed, algorithms=[alg], quality=quality)
    if not rec.calls:
        raise ValueError(f"job {job.key}: the task called no algorithm; nothing to export")
    args, kwargs = rec.calls[0]
    names = tuple(task.input_names)
    if len(args) != len(names):
        raise ValueError(f"task {task.name}: input_names {names} do not match the {len(args)} positional arguments")
    return {**dict(zip(names, args, strict=True)), **kwargs}


def _write_input(folder: Path, name: str, value) -> dict:
    """Write one input; returns its manifest entry."""
    from pbrbench import io

    if isinstance(value, (bool, int, float, np.floating, np.integer)) or np.ndim(value) == 0:
        v = _jsonable(value if not isinstance(value, np.ndarray) else value.item())
        return {"value": v, "type": type(v).__name__}
    a = np.asarray(value)
    if a.ndim == 1 or (a.ndim == 2 and a.shape[1] <= 4 and a.shape[0] <= 1024 and a.dtype.kind == "f"):
        return {"value": a.tolist(), "shape": list(a.shape), "dtype": str(a.dtype), "sha256": array_digest(a)}
    np.save(folder / f"{name}.npy", a)
    files = [f"{name}.npy"]
    if a.dtype == bool:
        io.write_mask_png(folder / f"{name}.png", a)
        files.append(f"{name}.png")
    elif a.dtype.kind in "ui":
        stack = a if a.ndim == 4 or (a.ndim == 3 and a.shape[-1] not in (3, 4)) else a[None]
        sub = folder / name if len(stack) > 1 else folder
        sub.mkdir(exist_ok=True)
        dt = np.uint16 if a.max(initial=0) > 255 else np.uint8
        for k, im in enumerate(stack):
            f = sub / (f"{k:03d}.png" if len(stack) > 1 else f"{name}.png")
            io.write_png_exact(f, im.astype(dt), filters=(1,))
            files.append(str(f.relative_to(folder)))
    else:
        stack = a if (a.ndim == 4 or (a.ndim == 3 and a.shape[-1] not in (3, 4))) else a[None]
        sub = folder / name if len(stack) > 1 else folder
        sub.mkdir(exist_ok=True)
        for k, im in enumerate(stack):
            f = sub / (f"{k:03d}.exr" if len(stack) > 1 else f"{name}.exr")
            io.write_exr_image(f, im)
            files.append(str(f.relative_to(folder)))
    return {"files": files, "shape": list(a.shape), "dtype": str(a.dtype), "sha256": array_digest(a),
            "exact": f"{name}.npy"}


def _expected_shape(task, pred, inputs) -> tuple | None:
    """The shape a prediction must have (None entries are free)."""
    if pred.shape == "image":
        return tuple(np.shape(inputs["image"]))
    if pred.shape == "scalar":
        return ()
    h, w = task.frame_shape(inputs)
    out = []
    for tok in pred.shape.split(","):
        tok = tok.strip()
        out.append(h if tok == "H" else w if tok == "W" else int(tok) if tok.isdigit() else None)
    return tuple(out)


def _prediction_entry(task, pred, inputs) -> dict:
    shape = _expected_shape(task, pred, inputs)
    exts = [".txt", ".npy"] if pred.shape == "scalar" else [".exr", ".npy"] + ([".png"] if pred.kind == "mask" else [])
    return {"name": pred.name, "files": [pred.name + e for e in exts], "shape": [s if s is not None else pred.shape.split(",")[i].strip()
                                                                                 for i, s in enumerate(shape)],
            "required": pred.required, "kind": pred.kind, "meaning": pred.meaning}


# ----------------------------------------------------------------------------- export
def input_sets(task, job, gts: dict, seed: int) -> list[tuple[str, dict, int]]:
    """``(sub-folder, ground truths, seed)`` of every input set a job is scored on: the full
    ground truth (``""``), each delete-one-group replicate (``replicates/<i>``) and, where the
    inputs depend on the seed, the second seed (``replicates/noise``): the sets
    :mod:`pbrbench.bench.uncertainty` scores for the standard error."""
    from pbrbench.bench.uncertainty import NOISE_SEED_OFFSET

    sets = [("", gts, seed)]
    groups = {getattr(g, "groups", 0) for g in gts.values()}
    if all(getattr(g, "has_replicates", False) for g in gts.values()) and len(groups) == 1:
        (G,) = groups
        sets += [(f"replicates/{i}", {n: g.replicate(i) for n, g in gts.items()}, seed) for i in range(G)]
    if task.seed_dependent(job):
        sets.append(("replicates/noise", gts, seed + NOISE_SEED_OFFSET))
    return sets


def export_task(task, out_dir, *, quality, seed: int = 0, source, log=None, replicates: bool = True) -> dict:
    """Write every scored job's inputs of ``task`` at ``quality`` under ``out_dir`` (see the
    module docstring); ground truths come from ``source`` (rendered when missing).  With
    ``replicates`` each job folder also holds ``replicates/<i>/`` (the inputs made from the
    delete-one-group ground truths, and ``replicates/noise/`` for a second seed): predictions
    written there too give ``evaluate`` the standard error.  Returns the manifest."""
    from pbrbench.progress import Progress
    from pbrbench.render.quality import get_quality

    q = get_quality(quality)
    out = Path(out_dir)
    if out.exists() and any(out.iterdir()) and not (out / MANIFEST).is_file():
        raise UserError(f"--out {out}: the folder exists and is not an export; give an empty or new folder")
    (out / "jobs").mkdir(parents=True, exist_ok=True)
    jobs = task.export_jobs(q)
    if not jobs:
        raise UserError(f"task {task.name}: no job at quality {q.name} (is the scene library complete?)")
    specs = source.specs(sorted({n for j in jobs for n in (j.scene, *j.extra_scenes)}))
    entries = []
    with Progress(len(jobs), f"export {task.name}", bars=False, unit="job") as bar:
        for i, job in enumerate(jobs):
            gts = {n: source.load(specs[n]) for n in (job.scene, *job.extra_scenes)}
            inputs = capture_inputs(task, job, gts, seed=seed, quality=q)
            rel = f"jobs/{i:03d}-{_safe(job.scene)}-{_safe(job.condition)}"
            folder = out / rel
            folder.mkdir(parents=True, exist_ok=True)
            written = {n: _write_input(folder, n, v) for n, v in inputs.items()}
            reps = []
            for sub, gts_r, seed_r in (input_sets(task, job, gts, seed)[1:] if replicates else []):
                inp_r = capture_inputs(task, job, gts_r, seed=seed_r, quality=q)
                (folder / sub).mkdir(parents=True, exist_ok=True)
                reps.append({"folder": f"{rel}/{sub}", "seed": seed_r,
                             "inputs": {n: _write_input(folder / sub, n, v) for n, v in inp_r.items()}})
            if "lights" in inputs and np.ndim(inputs["lights"]) == 2:   # the vectors split, for convenience
                lv = np.asarray(inputs["lights"], float)
                e = np.linalg.norm(lv, axis=1)
                written["lights"]["directions"] = (lv / np.where(e > 0, e, 1.0)[:, None]).tolist()
                written["lights"]["irradiances"] = e.tolist()
                written["lights"]["meaning"] = ("rows: unit direction toward the source (camera frame) x irradiance at "
                                                "the target (W m^-2); directions and irradiances give the two factors")
            preds = [_prediction_entry(task, p, inputs) for p in task.predictions]
            record = {"format": FORMAT, "task": task.name, "key": job.key, "scene": job.scene,
                      "condition": job.condition, "params": _jsonable(list(job.params)), "seed": seed,
                      "quality": q.name, "folder": rel, "inputs": written, "call": _call_text(task, inputs),
                      "predictions": preds, "conventions": CONVENTIONS, "replicates": reps}
            (folder / "job.json").write_text(json.dumps(record, indent=1))
            entries.append({k: record[k] for k in ("key", "scene", "condition", "folder")}
                           | {"predictions": [p["name"] for p in preds if p["required"]]})
            bar.update(1, job.scene)
    manifest = {"format": FORMAT, "task": task.name, "quality": q.name, "seed": seed, "replicates": bool(replicates),
                "input_names": list(task.input_names), "conventions": CONVENTIONS,
                "predictions": [{"name": p.name, "shape": p.shape, "required": p.required, "kind": p.kind,
                                 "meaning": p.meaning} for p in task.predictions],
                "jobs": entries}
    (out / MANIFEST).write_text(json.dumps(manifest, indent=1))
    (out / "README.txt").write_text(_readme(task, manifest))
    if log:
        log(f"exported {len(entries)} job(s) of {task.name} ({q.name}) to {out}")
    return manifest


def _call_text(task, inputs) -> str:
    pos = ", ".join(task.input_names)
    kw = ", ".join(f"{k}={k}" for k in inputs if k not in task.input_names)
    return f"fn({pos}{', ' if kw else ''}{kw})"


def _readme(task, manifest) -> str:
    preds = "\n".join(f"  {p['name']}{'.txt' if p['shape'] == 'scalar' else '.exr'} or {p['name']}.npy"
                      f"{' (or .png)' if p['kind'] == 'mask' else ''}"
                      f"  shape {p['shape']}{'' if p['required'] else ' (optional)'}: {p['meaning']}"
                      for p in manifest["predictions"])
    return (f"pbrbench export of task {task.name} (quality {manifest['quality']}, seed {manifest['seed']})\n\n"
            f"Each folder under jobs/ holds one job: job.json (the scene, the condition, every input with its\n"
            f"file or value, the files to write) and the input files.  The .npy files are the exact inputs of\n"
            f"pbrbench's own algorithms (float64); the .exr/.png files are the same images for any program.\n\n"
            f"Write into each job folder (or a copy of the tree given to --predictions):\n{preds}\n\n"
            + ("Standard errors: each job folder also holds replicates/0, replicates/1, ... (the same inputs made\n"
               "from the render's independent sample groups, one left out each; replicates/noise: a second noise\n"
               "seed).  Run your program on every replicates/* folder too and write the same files there: evaluate\n"
               "then gives every score its ± (the delete-one-group jackknife), and its Monte Carlo bias.\n\n"
               if manifest.get("replicates") else "")
            + f"Then score them:  pbrbench evaluate {task.name} THIS_FOLDER [--name MINE]\n\n"
            f"Conventions: {json.dumps(CONVENTIONS, indent=1)}\n")


# ----------------------------------------------------------------------------- evaluate
def read_manifest(folder) -> dict:
    p = Path(folder) / MANIFEST
    if not p.is_file():
        raise UserError(f"{folder}: no {MANIFEST}; pass a folder written by `pbrbench export TASK --out DIR`")
    try:
        m = json.loads(p.read_text())
    except ValueError as e:
        raise UserError(f"{p}: not valid JSON ({e})") from None
    if m.get("format") != FORMAT:
        raise UserError(f"{p}: format {m.get('format')!r}, expected {FORMAT!r}; export again with this pbrbench")
    return m


def _find(folder: Path, name: str) -> Path | None:
    for ext in _SUFFIXES:
        p = folder / f"{name}{ext}"
        if p.is_file():
            return p
    return None


def load_prediction(task, folder: Path, inputs: dict, record: dict) -> dict:
    """The prediction files of one job as arrays (name -> array), checked against the expected
    shapes and for finite values; ``ValueError`` with one line naming the file otherwise."""
    from pbrbench import io

    mask = inputs.get("mask")
    where = np.asarray(mask, bool) if mask is not None and np.ndim(mask) == 2 else None
    out = {}
    for pred in task.predictions:
        path = _find(folder, pred.name)
        if path is None:
            if pred.required:
                raise ValueError(f"{folder / pred.name}.exr (or .npy): missing; write {pred.name} "
                                 f"{pred.shape} ({pred.meaning})")
            continue
        if path.suffix == ".txt":
            try:
                a = np.asarray(float(path.read_text().split()[0]))
            except (ValueError, IndexError):
                raise ValueError(f"{path}: not a number; write one number") from None
        else:
            a = np.asarray(io.read_image(path))
        want = _expected_shape(task, pred, inputs)
        if a.ndim == len(want) + 1 and a.shape[-1] == 1:
            a = a[..., 0]
        if pred.kind == "mask":
            if a.ndim == 3:
                a = a.any(axis=-1)
            a = a > 0
        elif a.dtype.kind not in "fiub":
            raise ValueError(f"{path}: dtype {a.dtype}; write real numbers")
        else:
            a = a.astype(np.float64)
        if a.ndim != len(want) or any(w is not None and s != w for s, w in zip(a.shape, want, strict=False)):
            shown = tuple(w if w is not None else tok.strip() for w, tok in zip(want, pred.shape.split(","), strict=False)) \
                if pred.shape != "image" else want
            raise ValueError(f"{path}: shape {a.shape}, expected {shown} ({pred.name})")
        if pred.kind != "mask":
            sel = where if (where is not None and a.shape[:2] == where.shape) else None
            bad = ~np.isfinite(a)
            if a.ndim > 2:
                bad = bad.reshape(a.shape[:2] + (-1,)).any(axis=-1)
            n_bad = int((bad if sel is None else bad[sel]).sum())
            if n_bad:
                unit = "pixel(s)" if a.ndim >= 2 else "value(s)"
                raise ValueError(f"{path}: {n_bad} {unit} with NaN/inf{' inside the mask' if sel is not None else ''}; "
                                 "write finite numbers (values outside the mask are ignored)")
            if sel is not None:   # non-finite values outside the mask become 0; finite ones are kept
                inside = sel.reshape(sel.shape + (1,) * (a.ndim - 2))
                a = np.where(inside | np.isfinite(a), a, 0.0)
        out[pred.name] = a
    return out


class PredictionReader:
    """The algorithm of an evaluated run: for the job being scored it checks that the inputs it
    is handed are the exported ones and returns the job's prediction files (as the task's own
    algorithms would return them)."""

    def __init__(self, task, export_dir: Path, predictions_dir: Path, records: dict):
        self.task = task
        self.export_dir = Path(export_dir)
        self.predictions_dir = Path(predictions_dir)
        self.records = records          # job key -> job.json
        self.errors: dict[str, str] = {}

        self.missing_replicates: set[str] = set()   # jobs scored without replicate predictions

    def folder(self, record) -> Path:
        return self.predictions_dir / record["folder"]

    @staticmethod
    def _same(written: dict, inputs: dict) -> str | None:
        """The first input of ``inputs`` that differs from the exported set ``written``, or None."""
        for name, entry in written.items():
            if name not in inputs:
                continue
            v = inputs[name]
            same = array_digest(np.asarray(v)) == entry["sha256"] if "sha256" in entry else _jsonable(v) == entry["value"]
            if not same:
                return name
        return None

    def _check_inputs(self, record, inputs) -> Path:
        """The predictions folder of the exported input set ``inputs`` are (the job's own, or one
        of its replicates'); ``ValueError`` naming the first input that matches none."""
        bad = self._same(record["inputs"], inputs)
        if bad is None:
            return self.folder(record)
        for rep in record.get("replicates") or []:
            if self._same(rep["inputs"], inputs) is None:
                return self.predictions_dir / rep["folder"]
        raise ValueError(f"{self.export_dir / record['folder']}: input {bad!r} differs from the exported one "
                         "(other renders or another pbrbench?); export again and rerun your program")

    def load(self, record, inputs) -> dict:
        """The prediction files for ``inputs`` (the job's, or a replicate's)."""
        folder = self._check_inputs(record, inputs)
        if folder != self.folder(record):
            if not any(_find(folder, p.name) is not None for p in self.task.predictions):
                self.missing_replicates.add(record["key"])
                raise _NoReplicate(f"{folder}: no prediction for this replicate")
            try:
                return load_prediction(self.task, folder, inputs, record)
            except ValueError:
                self.missing_replicates.add(record["key"])
                raise _NoReplicate(f"{folder}: no prediction for this replicate") from None
        return load_prediction(self.task, folder, inputs, record)

    def files(self, record) -> dict:
        return load_prediction(self.task, self.folder(record), {}, record)

    def __call__(self, *args, **kwargs):
        job = _JOB.get()
        record = self.records.get(job.key) if job is not None else None
        if record is None:
            raise ValueError(f"no exported job for {getattr(job, 'key', '?')}")
        inputs = {**dict(zip(self.task.input_names, args, strict=False)), **kwargs}
        try:
            files = self.load(record, inputs)
            return self.task.prediction_output(files, inputs)
        except _NoReplicate:
            raise
        except ValueError as e:
            self.errors[job.key] = " ".join(str(e).split())
            raise


class _NoReplicate(RuntimeError):
    """A replicate's prediction files are absent: the score has no standard error (not a failure)."""


class EvaluatedTask:
    """A task restricted to the exported jobs, whose run_job tells the reader which job it is
    scoring (and lets the task score predictions that bypass its calling convention)."""

    def __init__(self, task, records: dict, reader: PredictionReader, predictions_dir: Path):
        self.task = task
        self.records = records
        self.reader = reader
        self.name = task.name
        self.description = f"{task.description} Predictions read from {predictions_dir}."
        self.conditions = task.conditions
        self.headline_metric = task.headline_metric
        self.families = task.families

    def __getattr__(self, name):
        # everything else (reference condition, notes, seed dependence ...) is the task's
        return getattr(self.task, name)

    def builtin_algorithms(self):
        return self.task.builtin_algorithms()

    def jobs(self, quality):
        jobs = [j for j in self.task.export_jobs(quality) if j.key in self.records]
        missing = set(self.records) - {j.key for j in jobs}
        if missing:
            raise UserError(f"{len(missing)} exported job(s) are not jobs of {self.task.name} at this quality any more "
                            f"(e.g. {sorted(missing)[0]}); export again")
        return jobs

    def _direct(self, job, gts, alg, seed, quality):
        """The task's own scoring of predictions that bypass its calling convention, or None."""
        from pbrbench.tasks.base import Task

        if type(self.task).score_outputs is Task.score_outputs:
            return None
        record = self.records[job.key]
        try:
            inputs = capture_inputs(self.task, job, gts, seed=seed, quality=quality)
            files = self.reader.load(record, inputs)
        except (ValueError, _NoReplicate):
            return None            # the calling-convention route reports the problem
        return self.task.score_outputs(job, gts, files, algorithm=alg, seed=seed, quality=quality)

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        token = _JOB.set(job)
        try:
            alg = next((a for a in algorithms if a.fn is self.reader), None)
            res = self._direct(job, gts, alg, seed, quality) if alg is not None else None
            if res is None:
                return self.task.run_job(job, gts, seed=seed, algorithms=algorithms, quality=quality)
            if alg.name in res.failures:
                self.reader.errors[job.key] = res.failures[alg.name]
            others = [a for a in algorithms if a is not alg]
            if others:
                more = self.task.run_job(job, gts, seed=seed, algorithms=others, quality=quality)
                res.scores += more.scores
                for k in ("images", "error_maps", "plots", "failures"):
                    getattr(res, k).update(getattr(more, k))
            return res
        finally:
            _JOB.reset(token)


def prediction_fingerprint(export_dir: Path, predictions_dir: Path, records: dict, task) -> str:
    """sha256 (10 hex digits) of every prediction file: the evaluated algorithm's version hash."""
    h = hashlib.sha256()
    for key in sorted(records):
        folder = predictions_dir / records[key]["folder"]
        for pred in task.predictions:
            p = _find(folder, pred.name)
            if p is not None:
                h.update(f"{key}/{p.name}".encode())
                h.update(p.read_bytes())
    return h.hexdigest()[:10]


def evaluate_export(task, export_dir, *, predictions_dir=None, name: str = "external", version: str = "1",
                    with_builtins: bool = False, settings, source=None, report: bool = True, log=None):
    """Score the predictions of an export as a run (see the module docstring).  Returns
    ``(RunOutcome, reader)``; ``reader.errors`` maps job keys to the one-line reasons their
    predictions were scored as failed."""
    from pbrbench.bench.run import RunConfig, run_benchmark
    from pbrbench.registry import Algorithm, Registry

    export_dir = Path(export_dir)
    manifest = read_manifest(export_dir)
    if manifest["task"] != task.name:
        raise UserError(f"{export_dir}: an export of task {manifest['task']!r}, not {task.name!r}")
    pdir = Path(predictions_dir) if predictions_dir is not None else export_dir
    if not pdir.is_dir():
        raise UserError(f"--predictions {pdir}: no such folder")
    records = {}
    for e in manifest["jobs"]:
        jp = export_dir / e["folder"] / "job.json"
        if not jp.is_file():
            raise UserError(f"{jp}: missing; the export is incomplete (export again)")
        records[e["key"]] = json.loads(jp.read_text())
    reader = PredictionReader(task, export_dir, pdir, records)
    try:
        alg = Algorithm(name, task.name, reader, kind="plugin", version=version,
                        fingerprint=prediction_fingerprint(export_dir, pdir, records, task),
                        origin=f"pbrbench evaluate {pdir.resolve()}", description=f"predictions in {pdir}")
    except ValueError as e:
        raise UserError(f"--name {name!r}: {e}") from None
    reg = Registry(task.builtin_algorithms() if with_builtins else [])
    if (task.name, name) in reg:
        raise UserError(f"--name {name!r} is a built-in algorithm of {task.name}; choose another name")
    reg.add(alg)
    proxy = EvaluatedTask(task, records, reader, pdir)
    from pbrbench.render.quality import get_quality

    proxy.jobs(get_quality(manifest["quality"]))       # refuse a stale export before a run is created
    # the replicates' predictions (when the program wrote them) give the standard errors; files
    # change between evaluations (no job cache)
    has_reps = any(r.get("replicates") for r in records.values())
    cfg = RunConfig(tasks=[task.name], quality=manifest["quality"], seed=int(manifest["seed"]), report=report,
                    uncertainty=has_reps, job_cache=False,
                    entry_points=False, algorithm_time_limit=None)
    outcome = run_benchmark(cfg, settings=replace(settings, baselines=None), tasks={task.name: proxy},
                            source=source, registry=reg, log=log)
    return outcome, reader
