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

An export may have been handed over by someone else, so ``evaluate`` trusts none of it:

* ``manifest.json`` and every ``job.json`` are read with their types checked (a damaged file is
  one :class:`~pbrbench.errors.UserError` line naming it, before a run is created);
* every folder they name must be a relative path without ``..`` that resolves (symbolic links
  followed) inside the export, and inside ``--predictions`` too; a prediction file that is a
  link out of the predictions folder is refused;
* a prediction file must be a regular file whose header (``.npy``: the checks of
  :func:`pbrbench.scene.data.read_npy`, nothing unpickled; PNG, EXR, TIFF, PFM: their declared
  size) announces at most :data:`MAX_PREDICTION_BYTES` before its data is read; its values and
  mask must be finite and at most :data:`MAX_PREDICTION_VALUE` in magnitude; and a score of the
  predictions that is not finite (an overflow) is refused: the job is scored as failed, with its
  reason.
"""

from __future__ import annotations

import contextvars
import hashlib
import json
import math
import os
import stat
from dataclasses import replace
from pathlib import Path, PurePosixPath

import numpy as np

from pbrbench.errors import UserError
from pbrbench.io.files import fmt_bytes as _fmt_bytes
from pbrbench.scene.data import MAX_DATA_BYTES

MANIFEST = "manifest.json"
PERTURBED = "replicates/perturbed"   # the input set of the perturbed ground truth (chaos test)
FORMAT = "pbrbench-export/2"    # 2: three other noise seeds (replicates/noise, noise2, noise3)
_JOB = contextvars.ContextVar("pbrbench_external_job", default=None)
_SUFFIXES = (".npy", ".exr", ".png", ".tif", ".tiff", ".pfm", ".txt")
MAX_PREDICTION_BYTES = MAX_DATA_BYTES   # largest array a prediction file may hold (as float64), as a scene data file
MAX_PREDICTION_VALUE = 1e150            # largest |value| of a prediction: beyond, squares and norms overflow float64

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


def one_line(exc: BaseException) -> str:
    """``TypeName: message`` of ``exc`` on one line."""
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:300]


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
    ground truth (``""``), each delete-one-group replicate (``replicates/<i>``), the perturbed
    ground truth (``replicates/perturbed``: the chaos test, which a program's predictions get as
    a plugin's do) and, where the inputs depend on the seed, the other seeds
    (``replicates/noise``, ``replicates/noise2``, ...): the sets :mod:`pbrbench.bench.uncertainty`
    scores for the standard error."""
    from pbrbench.bench.uncertainty import noise_seeds
    from pbrbench.uncertainty import PERTURBATION

    sets = [("", gts, seed)]
    groups = {getattr(g, "groups", 0) for g in gts.values()}
    if all(getattr(g, "has_replicates", False) for g in gts.values()) and len(groups) == 1:
        (G,) = groups
        sets += [(f"replicates/{i}", {n: g.replicate(i) for n, g in gts.items()}, seed) for i in range(G)]
        sets.append((PERTURBED, {n: g.perturbed(PERTURBATION) for n, g in gts.items()}, seed))
    if task.seed_dependent(job):
        sets += [(f"replicates/noise{k + 1 if k else ''}", gts, sk) for k, sk in enumerate(noise_seeds(seed))]
    return sets


def export_task(task, out_dir, *, quality, seed: int = 0, source, log=None, replicates: bool = True) -> dict:
    """Write every scored job's inputs of ``task`` at ``quality`` under ``out_dir`` (see the
    module docstring); ground truths come from ``source`` (rendered when missing).  With
    ``replicates`` each job folder also holds ``replicates/<i>/`` (the inputs made from the
    delete-one-group ground truths, and ``replicates/noise*/`` for the other seeds): predictions
    written there too give ``evaluate`` the standard error.  Returns the manifest."""
    from pbrbench.progress import Progress
    from pbrbench.quality import require

    q = require(quality)
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
               "from the render's independent sample groups, one left out each), replicates/perturbed (the full\n"
               "inputs moved by 1e-3 of the way toward replicates/0: whether your program's output jumps with a\n"
               "change far below the render noise, as an iteration stopped before it converged can) and, where\n"
               "the inputs depend on the seed, replicates/noise, replicates/noise2, ... (other noise seeds).  Run\n"
               "your program on every replicates/* folder too and write the same files there: evaluate then\n"
               "gives every score its ± (the delete-one-group jackknife, or the spread of independent draws\n"
               "where the output is chaotic), and its Monte Carlo bias.\n\n"
               if manifest.get("replicates") else "")
            + f"Then score them:  pbrbench evaluate {task.name} THIS_FOLDER [--name MINE]\n\n"
            f"Conventions: {json.dumps(CONVENTIONS, indent=1)}\n")


# ----------------------------------------------------------------------------- evaluate: the export's files
# An export may come from someone else: every path it names must stay inside it, every JSON file
# must have the shape pbrbench writes, and every prediction file is checked (header, size, dtype,
# shape, finite values) before its data is read.
MAX_JSON_BYTES = 64 * 2**20     # largest manifest.json / job.json read
MAX_TEXT_BYTES = 4096           # largest <name>.txt (one number)
MAX_SEED = 2**62                # largest seed a manifest may give
_FIX_EXPORT = "the export is damaged: export it again (`pbrbench export TASK --out DIR`)"


def _damaged(path, what: str) -> UserError:
    return UserError(f"{path}: {what}; {_FIX_EXPORT}")


def _kind(v) -> str:
    """The JSON name of ``v``'s type, for messages."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, (int, float)):
        return f"the number {v!r}"[:60]
    if isinstance(v, str):
        return f"the string {v!r}"[:60]
    return "a list" if isinstance(v, list) else "an object" if isinstance(v, dict) else type(v).__name__


def _finite_float(text: str) -> float:
    v = float(text)
    if not math.isfinite(v):
        raise ValueError(f"the number {text[:40]} is out of range")
    return v


def _no_constant(text: str):
    raise ValueError(f"{text} is not a JSON number")


def read_json_file(path, *, shown=None):
    """The JSON value in the file ``path`` (at most :data:`MAX_JSON_BYTES`; numbers finite:
    ``NaN``, ``Infinity`` and ``1e999`` are refused); :class:`~pbrbench.errors.UserError` with one
    line naming ``shown`` (default: ``path``) otherwise.

    Parameters
    ----------
    path : path-like
        The file to read.
    shown : path-like, optional
        The name the messages give the file (the path as the manifest wrote it).
    """
    p, shown = Path(path), shown if shown is not None else path
    try:
        st = p.stat()
    except OSError as e:
        raise UserError(f"{shown}: cannot be read ({e.strerror or e}); check that it exists and its permissions") from None
    if not stat.S_ISREG(st.st_mode):
        raise _damaged(shown, "is not a file")
    if st.st_size > MAX_JSON_BYTES:
        raise _damaged(shown, f"holds {st.st_size} bytes, above the {MAX_JSON_BYTES} bytes pbrbench reads")
    try:
        data = p.read_bytes()
    except OSError as e:
        raise UserError(f"{shown}: cannot be read ({e.strerror or e}); check its permissions") from None
    try:
        return json.loads(data, parse_float=_finite_float, parse_constant=_no_constant)
    except RecursionError:
        raise _damaged(shown, "not valid JSON (nested too deeply)") from None
    except ValueError as e:   # UnicodeDecodeError and JSONDecodeError too
        raise _damaged(shown, f"not valid JSON ({' '.join(str(e).split())[:160]})") from None


def _field(d: dict, key: str, types, path, where: str = "", *, optional: bool = False):
    """``d[key]`` when it is one of ``types`` (a bool is not a number), else a damaged-file error."""
    if key not in d:
        if optional:
            return None
        raise _damaged(path, f"{where}{key!r} is missing")
    v = d[key]
    types = types if isinstance(types, tuple) else (types,)
    if not isinstance(v, types) or (isinstance(v, bool) and bool not in types):
        want = " or ".join({str: "a string", int: "an integer", float: "a number", bool: "true or false",
                            list: "a list", dict: "an object", type(None): "null"}[t] for t in types)
        raise _damaged(path, f"{where}{key!r} is {_kind(v)}, expected {want}")
    return v


def _check_relative(rel, path, where: str) -> str:
    """``rel`` when it is a plain relative path (no ``..``, not absolute, no control characters)."""
    if not isinstance(rel, str) or not rel.strip():
        raise _damaged(path, f"{where} is {_kind(rel)}, expected a relative folder path")
    pure = PurePosixPath(rel)
    if (pure.is_absolute() or Path(rel).is_absolute() or rel.startswith(("/", "\\")) or ".." in pure.parts
            or ".." in rel.split("\\") or any(ord(c) < 32 or ord(c) == 127 for c in rel)):
        raise UserError(f"{path}: {where} {rel!r} is not a plain path inside the export (it is absolute, holds "
                        f"'..' or control characters): pbrbench reads only files inside the export; {_FIX_EXPORT}")
    return rel


def resolve_inside(root, rel, *, path, where: str) -> Path:
    """The real path of ``root / rel`` (symbolic links followed), which must lie inside ``root``.

    Parameters
    ----------
    root : path-like
        The folder everything must stay inside (the export, or the predictions folder).
    rel : str
        A relative path from a JSON file of the export.
    path : path-like
        The JSON file, named by the messages.
    where : str
        The field that holds ``rel`` (``jobs[3].folder``), named by the messages.

    Returns
    -------
    Path
        The resolved path (it need not exist).

    Raises
    ------
    UserError
        ``rel`` is absolute, holds ``..``, or resolves outside ``root`` (a symbolic link).
    """
    _check_relative(rel, path, where)
    base = Path(root).resolve()
    try:
        real = (base / rel).resolve()
    except (OSError, RuntimeError) as e:   # a symlink loop
        raise UserError(f"{path}: {where} {rel!r} cannot be resolved ({e}); {_FIX_EXPORT}") from None
    if not real.is_relative_to(base):
        raise UserError(f"{path}: {where} {rel!r} resolves to {real}, outside {base} (a symbolic link?): pbrbench "
                        f"reads only files inside the folder; replace the link by the folder itself or export again")
    return real


def read_manifest(folder) -> dict:
    """The checked ``manifest.json`` of the export ``folder``.

    Parameters
    ----------
    folder : path-like
        A folder written by :func:`export_task`.

    Returns
    -------
    dict
        The manifest: ``task``, ``quality``, ``seed`` and ``jobs`` (each with a ``key`` and a
        ``folder`` that lies inside ``folder``) have the types pbrbench writes.

    Raises
    ------
    UserError
        One line naming the file: no manifest, invalid JSON, a wrong type, a missing key, a job
        folder outside the export.
    """
    from pbrbench.quality import PRESETS

    p = Path(folder) / MANIFEST
    if not p.is_file():
        raise UserError(f"{folder}: no {MANIFEST}; pass a folder written by `pbrbench export TASK --out DIR`")
    real = resolve_inside(folder, MANIFEST, path=p, where="the manifest")
    m = read_json_file(real, shown=p)
    if not isinstance(m, dict):
        raise _damaged(p, f"holds {_kind(m)}, expected a JSON object")
    if m.get("format") != FORMAT:
        raise UserError(f"{p}: format {m.get('format')!r}, expected {FORMAT!r}; export again with this pbrbench")
    _field(m, "task", str, p)
    if _field(m, "quality", str, p) not in PRESETS:
        raise _damaged(p, f"'quality' is {m['quality']!r}, not one of {', '.join(PRESETS)}")
    if not 0 <= _field(m, "seed", int, p) <= MAX_SEED:
        raise _damaged(p, f"'seed' is {m['seed']}, expected an integer from 0 to {MAX_SEED}")
    _field(m, "replicates", bool, p, optional=True)
    jobs = _field(m, "jobs", list, p)
    if not jobs:
        raise _damaged(p, "'jobs' is empty")
    keys, folders = set(), set()
    for i, e in enumerate(jobs):
        if not isinstance(e, dict):
            raise _damaged(p, f"jobs[{i}] is {_kind(e)}, expected an object")
        key = _field(e, "key", str, p, f"jobs[{i}].")
        rel = _field(e, "folder", str, p, f"jobs[{i}].")
        real = resolve_inside(folder, rel, path=p, where=f"jobs[{i}].folder")
        if key in keys or real in folders:
            raise _damaged(p, f"jobs[{i}] repeats the {'key ' + repr(key) if key in keys else 'folder ' + repr(rel)} "
                              "of an earlier job")
        keys.add(key)
        folders.add(real)
    return m


def _check_inputs_entry(inputs, path, where: str) -> None:
    if not isinstance(inputs, dict):
        raise _damaged(path, f"{where} is {_kind(inputs)}, expected an object")
    for name, entry in inputs.items():
        if not isinstance(entry, dict):
            raise _damaged(path, f"{where}.{name} is {_kind(entry)}, expected an object")
        if "sha256" in entry:
            _field(entry, "sha256", str, path, f"{where}.{name}.")
        elif "value" not in entry:
            raise _damaged(path, f"{where}.{name} has neither 'sha256' nor 'value'")


def read_job_records(export_dir, manifest: dict, predictions_dir=None) -> dict:
    """Every job's checked ``job.json`` (job key -> record) of the export ``export_dir``, whose
    manifest :func:`read_manifest` returned; every folder a record names (the job's, its
    replicates') lies inside the export, and inside ``predictions_dir`` too when given.

    Raises
    ------
    UserError
        One line naming the job.json: missing, invalid JSON, a wrong type, a missing key, a key or
        folder that differs from the manifest's, a folder outside the export.
    """
    export_dir = Path(export_dir)
    mp = export_dir / MANIFEST
    roots = [export_dir] + ([Path(predictions_dir)] if predictions_dir is not None else [])
    records = {}
    for i, e in enumerate(manifest["jobs"]):
        jp = export_dir / e["folder"] / "job.json"
        real = resolve_inside(export_dir, e["folder"], path=mp, where=f"jobs[{i}].folder")
        if not real.is_dir():
            raise UserError(f"{export_dir / e['folder']}: {'missing' if not real.exists() else 'not a folder'}; "
                            "the export is incomplete (export again)")
        jreal = resolve_inside(export_dir, f"{e['folder']}/job.json", path=mp, where=f"jobs[{i}].folder's job.json")
        if not jreal.exists():
            raise UserError(f"{jp}: missing; the export is incomplete (export again)")
        rec = read_json_file(jreal, shown=jp)
        if not isinstance(rec, dict):
            raise _damaged(jp, f"holds {_kind(rec)}, expected a JSON object")
        if _field(rec, "key", str, jp) != e["key"]:
            raise _damaged(jp, f"'key' is {rec['key']!r}, the manifest's is {e['key']!r}")
        if _field(rec, "folder", str, jp) != e["folder"]:
            raise _damaged(jp, f"'folder' is {rec['folder']!r}, the manifest's is {e['folder']!r}")
        _check_inputs_entry(_field(rec, "inputs", dict, jp), jp, "inputs")
        reps = _field(rec, "replicates", (list, type(None)), jp, optional=True) or []
        for r, rep in enumerate(reps):
            if not isinstance(rep, dict):
                raise _damaged(jp, f"replicates[{r}] is {_kind(rep)}, expected an object")
            _field(rep, "folder", str, jp, f"replicates[{r}].")
            _check_inputs_entry(_field(rep, "inputs", dict, jp, f"replicates[{r}]."), jp, f"replicates[{r}].inputs")
        for root in roots:
            for k, rel in enumerate([rec["folder"]] + [rep["folder"] for rep in reps]):
                resolve_inside(root, rel, path=jp, where="folder" if k == 0 else f"replicates[{k - 1}].folder")
        records[e["key"]] = rec
    return records


def _find(folder: Path, name: str) -> Path | None:
    """The first ``<name><suffix>`` in ``folder`` that exists (a file or not: the reader says)."""
    for ext in _SUFFIXES:
        p = folder / f"{name}{ext}"
        if os.path.lexists(p):
            return p
    return None


def _check_declared(path, shape, what: str) -> None:
    """Refuse a file whose header announces more than :data:`MAX_PREDICTION_BYTES` (as float64)."""
    count = 1
    for n in shape:
        count *= max(int(n), 0)
    if count * 8 > MAX_PREDICTION_BYTES:
        raise ValueError(f"{path}: its {what} announces shape {tuple(int(n) for n in shape)} ({_fmt_bytes(count * 8)} "
                         f"as float64), above the {_fmt_bytes(MAX_PREDICTION_BYTES)} limit for a prediction file; "
                         "write an array of the expected shape")


def _png_shape(path) -> tuple:
    from pbrbench.io import png_info

    info = png_info(path)
    return (info["height"], info["width"], info["channels"])


def _pfm_shape(path) -> tuple:
    with open(path, "rb") as f:
        kind, dims = f.readline(64).strip(), f.readline(64).split()
    if kind not in (b"PF", b"Pf") or len(dims) != 2 or not all(d.isdigit() for d in dims):
        raise ValueError(f"{path}: not a PFM file (damaged header); write it again, or write a .npy or .exr file")
    return (int(dims[1]), int(dims[0]), 3 if kind == b"PF" else 1)


def _tif_shape(path) -> tuple:
    import logging

    import tifffile

    log = logging.getLogger("tifffile")     # it logs damaged files; the reader's one line says it
    was, log.disabled = log.disabled, True
    try:
        with tifffile.TiffFile(str(path)) as t:
            return tuple(t.series[0].shape)
    finally:
        log.disabled = was


def _read_file(path: Path, real: Path) -> np.ndarray:
    """The array in one prediction file, its header checked before its data is read."""
    from pbrbench import io
    from pbrbench.io.images import read_npy

    suffix = path.suffix.lower()
    if suffix == ".txt":
        if real.stat().st_size > MAX_TEXT_BYTES:
            raise ValueError(f"{path}: holds {real.stat().st_size} bytes; write one number")
        try:
            return np.asarray(float(real.read_bytes().decode("utf-8").split()[0]))
        except (ValueError, IndexError):
            raise ValueError(f"{path}: not a number; write one number") from None
    if suffix == ".npy":
        return read_npy(real, where=str(path), limit=MAX_PREDICTION_BYTES, what="a prediction file")
    shape = {".png": _png_shape, ".exr": io.exr_shape, ".pfm": _pfm_shape, ".tif": _tif_shape,
             ".tiff": _tif_shape}[suffix](real)
    _check_declared(path, shape, "header")
    return np.asarray(io.read_image(real))


def _shape_text(pred, want) -> tuple:
    if pred.shape == "image":
        return want
    return tuple(w if w is not None else tok.strip() for w, tok in zip(want, pred.shape.split(","), strict=False))


def _read_prediction(path: Path, pred, want, root: Path | None) -> np.ndarray:
    """One prediction file as an array: inside ``root``, a regular file of a bounded size, read by
    :func:`_read_file`; ``ValueError`` with one line naming the file and the fix otherwise."""
    try:
        real = path.resolve()
    except (OSError, RuntimeError) as e:
        raise ValueError(f"{path}: cannot be resolved ({e}); write the prediction as a plain file") from None
    if root is not None and not real.is_relative_to(root):
        raise ValueError(f"{path}: a symbolic link to {real}, outside the predictions folder {root}; write the "
                         "prediction file itself there")
    try:
        st = real.stat()
    except OSError as e:
        raise ValueError(f"{path}: cannot be read ({e.strerror or e}); write it again") from None
    if not stat.S_ISREG(st.st_mode):
        what = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise ValueError(f"{path}: is {what}; write {pred.name} {pred.shape} as a file ({pred.meaning})")
    if st.st_size > MAX_PREDICTION_BYTES + 2**20:
        raise ValueError(f"{path}: holds {_fmt_bytes(st.st_size)}, above the {_fmt_bytes(MAX_PREDICTION_BYTES)} limit "
                         f"for a prediction file; write an array of shape {_shape_text(pred, want)}")
    try:
        with np.errstate(all="ignore"):
            return _read_file(path, real)
    except ValueError as e:
        msg = " ".join(str(e).split())
        raise ValueError(msg if str(path) in msg else f"{path}: {msg}") from None
    except PermissionError as e:
        raise ValueError(f"{path}: cannot be read ({e.strerror}); fix its permissions") from None
    except Exception as e:  # noqa: BLE001 - a damaged file of any format (EOFError, struct.error, MemoryError ...)
        raise ValueError(f"{path}: cannot be read ({one_line(e)[:160]}); write it again "
                         f"({pred.name} {pred.shape}: {pred.meaning})") from None


def load_prediction(task, folder: Path, inputs: dict, record: dict, *, root: Path | None = None) -> dict:
    """The prediction files of one job as arrays (name -> array), checked against the expected
    shapes and for finite values; ``ValueError`` with one line naming the file otherwise.

    Parameters
    ----------
    task : Task
        The task (its ``predictions`` say which files to read).
    folder : Path
        The job's (or a replicate's) predictions folder.
    inputs : dict
        The job's inputs (the mask, the shapes).
    record : dict
        The job's ``job.json``.
    root : Path, optional
        The resolved predictions folder: a prediction file that resolves outside it (a symbolic
        link) is refused.
    """
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
        want = _expected_shape(task, pred, inputs)
        a = _read_prediction(path, pred, want, root)
        if a.ndim == len(want) + 1 and a.shape[-1] == 1:
            a = a[..., 0]
        if a.dtype.kind not in "fiub":
            raise ValueError(f"{path}: dtype {a.dtype}; write real numbers")
        if pred.kind == "mask":
            n_bad = int((~np.isfinite(a)).sum()) if a.dtype.kind == "f" else 0
            if n_bad:
                raise ValueError(f"{path}: {n_bad} NaN/inf value(s) in a mask; write 0 (outside) or non-zero "
                                 "(inside), e.g. a bool array or a 0/255 PNG")
            if a.ndim == 3:
                a = a.any(axis=-1)
            a = a > 0
        else:
            a = a.astype(np.float64)
        if a.ndim != len(want) or any(w is not None and s != w for s, w in zip(a.shape, want, strict=False)):
            raise ValueError(f"{path}: shape {a.shape}, expected {_shape_text(pred, want)} ({pred.name}); write an "
                             "array of that shape")
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
            top = float(np.max(np.abs(a), initial=0.0))
            if top > MAX_PREDICTION_VALUE:
                raise ValueError(f"{path}: values reach {top:.3g}, beyond {MAX_PREDICTION_VALUE:.0e} (their squares "
                                 f"overflow float64); write {pred.name} in its units ({pred.meaning})")
        out[pred.name] = a
    return out


class PredictionReader:
    """The algorithm of an evaluated run: for the job being scored it checks that the inputs it
    is handed are the exported ones and returns the job's prediction files (as the task's own
    algorithms would return them).

    ``errors`` maps job keys to the one-line reasons their predictions were scored as failed;
    ``replicate_errors`` those of the replicates' predictions that were refused (the score then
    has no standard error); ``missing_replicates`` the jobs scored without replicate predictions,
    ``missing_perturbed`` those without predictions on the perturbed inputs (their ± is the
    jackknife's, not tested for chaos: :func:`pbrbench.uncertainty.chaotic`).
    """

    def __init__(self, task, export_dir: Path, predictions_dir: Path, records: dict):
        self.task = task
        self.export_dir = Path(export_dir)
        self.predictions_dir = Path(predictions_dir)
        self.root = self.predictions_dir.resolve()
        self.records = records          # job key -> job.json
        self.errors: dict[str, str] = {}
        self.replicate_errors: dict[str, str] = {}
        self.missing_replicates: set[str] = set()   # jobs scored without replicate predictions
        self.missing_perturbed: set[str] = set()    # jobs without predictions on replicates/perturbed
        self.loaded: Path | None = None              # the predictions folder of the last call
        self.largest: float = 0.0                    # the largest |value| it read

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

    def _load(self, folder, inputs, record) -> dict:
        files = load_prediction(self.task, folder, inputs, record, root=self.root)
        self.largest = max([float(np.max(np.abs(a), initial=0.0)) for a in files.values() if a.dtype != bool]
                           + [0.0])
        return files

    def load(self, record, inputs) -> dict:
        """The prediction files for ``inputs`` (the job's, or a replicate's)."""
        folder = self._check_inputs(record, inputs)
        self.loaded, self.largest = folder, 0.0
        if folder != self.folder(record):
            if not any(_find(folder, p.name) is not None for p in self.task.predictions):
                # without the perturbed set the score keeps its jackknife ±, untested for chaos
                (self.missing_perturbed if str(folder).endswith(PERTURBED) else self.missing_replicates).add(record["key"])
                raise _NoReplicate(f"{folder}: no prediction for this replicate")
            try:
                return self._load(folder, inputs, record)
            except ValueError as e:
                self.missing_replicates.add(record["key"])
                self.replicate_errors.setdefault(record["key"], " ".join(str(e).split()))
                raise _NoReplicate(f"{folder}: no prediction for this replicate") from None
        return self._load(folder, inputs, record)

    def files(self, record) -> dict:
        return load_prediction(self.task, self.folder(record), {}, record, root=self.root)

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
        except Exception as e:  # noqa: BLE001 - the task cannot use these files: the job's failure, named
            msg = f"{self.loaded or self.folder(record)}: the predictions cannot be used ({one_line(e)})"
            self.errors[job.key] = msg
            raise ValueError(msg) from None

    def is_replicate(self, record) -> bool:
        """Whether the last call read a replicate's predictions."""
        return self.loaded is not None and self.loaded != self.folder(record)


class _NoReplicate(RuntimeError):
    """A replicate's prediction files are absent: the score has no standard error (not a failure)."""


class EvaluatedTask:
    """A task restricted to the exported jobs, whose run_job tells the reader which job it is
    scoring (and lets the task score predictions that bypass its calling convention).  A score
    of the predictions that is not finite (an overflow: values of 1e308) is refused: the job is
    scored as failed with a one-line reason."""

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

    def scores_perturbed(self, job) -> bool:
        """Whether the export holds the job's perturbed input set (exports made before it existed
        do not: the chaos test is then not run, :mod:`pbrbench.bench.uncertainty`)."""
        return any(r.get("folder", "").endswith(PERTURBED) for r in self.records[job.key].get("replicates") or [])

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
        try:
            with np.errstate(all="ignore"):
                return self.task.score_outputs(job, gts, files, algorithm=alg, seed=seed, quality=quality)
        except Exception as e:  # noqa: BLE001 - predictions the task cannot score: the job's failure, named
            msg = f"{self.reader.loaded}: the predictions cannot be scored ({one_line(e)})"
            return self._failed(job, gts, alg, msg, [])

    @staticmethod
    def _failed(job, gts, alg, msg: str, scores) -> object:
        """A result holding ``scores`` and one ``failed`` score of ``alg`` (reason ``msg``)."""
        from pbrbench.tasks.base import JobResult
        from pbrbench.tasks.common.scoring import ScoreBook, scene_hash

        book = ScoreBook(job, scene_hash(gts.get(job.scene)), [alg])
        book.add(alg.name, {"failed": 1.0}, 0.0)
        res = JobResult(job, scores=list(scores) + book.scores)
        res.failures[alg.name] = msg
        return res

    def _refuse_non_finite(self, job, gts, alg, res):
        """``res`` with the predictions' scores replaced by ``failed`` when one is not finite."""
        bad = [s for s in res.scores if s.algorithm == alg.name and s.metric != "failed"
               and not math.isfinite(float(s.value))]
        if not bad:
            return res
        record = self.records[job.key]
        folder = self.reader.loaded or self.reader.folder(record)
        more = f" and {len(bad) - 1} more" if len(bad) > 1 else ""
        msg = (f"{folder}: the predictions score {bad[0].metric} = {bad[0].value}{more} (not finite; the largest "
               f"|value| read is {self.reader.largest:.3g}); write finite values of the expected magnitude")
        if self.reader.is_replicate(record):
            self.reader.replicate_errors.setdefault(job.key, msg)
            self.reader.missing_replicates.add(job.key)
        else:
            self.reader.errors[job.key] = msg
        others = [s for s in res.scores if s.algorithm != alg.name]
        out = self._failed(job, gts, alg, msg, others)
        for k in ("images", "error_maps", "plots"):
            getattr(out, k).update(getattr(res, k))
        out.failures.update({a: m for a, m in res.failures.items() if a != alg.name})
        return out

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        token = _JOB.set(job)
        self.reader.loaded = None
        try:
            alg = next((a for a in algorithms if a.fn is self.reader), None)
            try:
                res = self._scored(job, gts, alg, algorithms, seed, quality)
            except Exception as e:  # noqa: BLE001 - the task could not score the predictions it read
                if alg is None or self.reader.loaded is None:
                    raise
                msg = f"{self.reader.loaded}: the predictions cannot be scored ({one_line(e)}); write finite values " \
                      "of the expected magnitude"
                others = [a for a in algorithms if a is not alg]
                more = self.task.run_job(job, gts, seed=seed, algorithms=others, quality=quality) if others else None
                res = self._failed(job, gts, alg, msg, more.scores if more else [])
                if more is not None:
                    for k in ("images", "error_maps", "plots", "failures"):
                        getattr(res, k).update(getattr(more, k))
            if alg is None:
                return res
            record = self.records[job.key]
            if alg.name in res.failures:
                if not self.reader.is_replicate(record):
                    self.reader.errors.setdefault(job.key, res.failures[alg.name])
                elif not res.failures[alg.name].startswith("_NoReplicate"):
                    self.reader.replicate_errors.setdefault(job.key, res.failures[alg.name])
            return self._refuse_non_finite(job, gts, alg, res)
        finally:
            _JOB.reset(token)

    def _scored(self, job, gts, alg, algorithms, seed, quality):
        """The task's result on ``job``: the predictions' own scoring route, else run_job."""
        res = self._direct(job, gts, alg, seed, quality) if alg is not None else None
        if res is None:
            with np.errstate(all="ignore"):
                return self.task.run_job(job, gts, seed=seed, algorithms=algorithms, quality=quality)
        others = [a for a in algorithms if a is not alg]
        if others:
            more = self.task.run_job(job, gts, seed=seed, algorithms=others, quality=quality)
            res.scores += more.scores
            for k in ("images", "error_maps", "plots", "failures"):
                getattr(res, k).update(getattr(more, k))
        return res


def _file_digest(h, p: Path, root: Path) -> None:
    """Feed the bytes of the prediction file ``p`` to ``h``: only a regular file inside ``root`` of
    a bounded size is read (the reader refuses the others, with their reason)."""
    try:
        real = p.resolve()
        st = real.stat()
        if not real.is_relative_to(root) or not stat.S_ISREG(st.st_mode) or st.st_size > MAX_PREDICTION_BYTES + 2**20:
            h.update(f"unreadable:{st.st_size}".encode())
            return
        with open(real, "rb") as f:
            for chunk in iter(lambda: f.read(2**20), b""):
                h.update(chunk)
    except (OSError, RuntimeError) as e:
        h.update(f"unreadable:{type(e).__name__}".encode())


def prediction_fingerprint(export_dir: Path, predictions_dir: Path, records: dict, task) -> str:
    """sha256 (10 hex digits) of every prediction file: the evaluated algorithm's version hash."""
    h = hashlib.sha256()
    root = Path(predictions_dir).resolve()
    for key in sorted(records):
        folder = predictions_dir / records[key]["folder"]
        for pred in task.predictions:
            p = _find(folder, pred.name)
            if p is not None:
                h.update(f"{key}/{p.name}".encode())
                _file_digest(h, p, root)
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
    records = read_job_records(export_dir, manifest, pdir if predictions_dir is not None else None)
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
    from pbrbench.quality import get_quality

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
