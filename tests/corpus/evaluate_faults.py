"""Hostile exports for ``pbrbench evaluate``: ``python -m tests.corpus.evaluate_faults``.

An export may come from someone else.  Every case starts from one good export of a small
photometric-stereo task (three jobs, synthetic ground truths: no renderer) whose predictions a
program outside pbrbench would have written, damages one thing, and runs ``pbrbench evaluate``
through :func:`pbrbench.cli.main.main` in this process (:func:`tests.corpus.measure.run_in_process`;
the task and the ground-truth source are the synthetic ones, :func:`synthetic_world`).  Three kinds:

- ``prediction``: one prediction file of job 0 is damaged (a header that announces terabytes, an
  empty or pickled ``.npy``, a wrong dtype or shape, NaN, a folder or a link out of the export
  where the file belongs, ...): exit 1, exactly one stderr line ``prediction failed: FILE: ...``
  naming the file, no traceback, and the two good jobs scored and stored with finite values;
- ``replicate``: a prediction in a replicate folder is damaged: exit 1, one line naming it, all
  three jobs scored;
- ``export``: ``manifest.json`` or a ``job.json`` is damaged or names a path outside the export:
  exit 1, one line naming the file, no run stored, nothing outside the export read.

:func:`classify` gives ``clean`` or what went wrong; ``python -m tests.corpus.evaluate_faults``
prints every case's outcome and the count.
"""

from __future__ import annotations

import builtins
import contextlib
import json
import os
import re
import shutil
import sqlite3
import struct
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from unittest import mock

import numpy as np

from pbrbench.quality import DRAFT
from pbrbench.tasks.base import Job
from pbrbench.tasks.photometric_stereo import PhotometricStereoTask
from tests.fakes import FakeSource, ps_gt, ps_job

TASK = "photometric_stereo"
GTS = {"ps_a": lambda: ps_gt()[0], "ps_b": lambda: ps_gt("bumps", gi_gain=1.1)[0]}


class SmallPS(PhotometricStereoTask):
    """Three jobs on two synthetic scenes; job 1 (``local+noise0.01``) has a replicate folder
    (``replicates/noise``: the inputs of a second seed)."""

    def jobs(self, quality) -> list[Job]:
        return [ps_job("local", scene="ps_a"), ps_job("local+noise0.01", scene="ps_a"), ps_job("global", scene="ps_b")]


class SyntheticSource(FakeSource):
    """The ground-truth source the command line builds (``GroundTruthSource(quality, cache=...)``),
    with analytic ground truths instead of renders."""

    def __init__(self, quality=DRAFT, *, cache=None, variant=None, library=None, **_):
        super().__init__(Path(getattr(cache, "root", None) or tempfile.gettempdir()) / "synthetic", quality)

    def load(self, spec):
        gt = GTS[spec.name]()
        gt.meta["scene_hash"] = spec.content_hash()
        return gt


@contextlib.contextmanager
def synthetic_world():
    """``pbrbench evaluate`` with the synthetic task and ground truths of this module."""
    with mock.patch("pbrbench.tasks.get_tasks", lambda names, **_: {n: SmallPS() for n in names}), \
            mock.patch("pbrbench.bench.source.GroundTruthSource", SyntheticSource):
        yield


# ----------------------------------------------------------------------------- the good export
def write_predictions(folder: Path, job_json: Path | None = None) -> None:
    """What an external program writes: Woodham's normals, albedo and valid mask from the exported
    ``.npy`` inputs of ``folder`` (the light vectors from ``job_json``, default its job.json)."""
    from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980

    job = json.loads((job_json or folder / "job.json").read_text())
    lights = np.asarray(job["inputs"]["lights"]["value"], float)
    r = photometric_stereo_woodham1980(np.load(folder / "images.npy"), lights, mask=np.load(folder / "mask.npy"))
    np.save(folder / "normals.npy", r.normals)
    np.save(folder / "albedo.npy", r.albedo)
    np.save(folder / "valid.npy", r.valid)


def build_base(d: Path) -> Path:
    """A good export with every job's predictions (not the replicates') under ``d``."""
    from pbrbench.bench.external import export_task

    d = Path(d)
    m = export_task(SmallPS(), d, quality=DRAFT, seed=0, source=SyntheticSource(cache=None))
    for e in m["jobs"]:
        write_predictions(d / e["folder"])
    return d


def job_dirs(exp: Path) -> list[Path]:
    return [exp / e["folder"] for e in json.loads((exp / "manifest.json").read_text())["jobs"]]


# ----------------------------------------------------------------------------- the cases
@dataclass
class Case:
    """One hostile export: ``make(export, tmp)`` damages the copy ``export`` and returns the text
    the error line must hold (a file's path); ``kind``: prediction, replicate or export."""

    name: str
    kind: str
    make: object
    patch: object = None     # a function (export) -> context manager active while evaluate runs


def _npy_header(header: str, version: bytes = b"\x01\x00") -> bytes:
    h = header.encode("latin-1")
    pad = 64 - (10 + len(h) + 1) % 64
    h = h + b" " * pad + b"\n"
    return b"\x93NUMPY" + version + struct.pack("<H", len(h)) + h


def _pred(name="normals", job=0):
    """A case function that writes ``data(path)`` at job ``job``'s prediction ``name`` (bytes, an
    array, or a callable that makes the file itself)."""
    def deco(data, suffix=".npy", drop_npy=False):
        def make(exp: Path, tmp: Path) -> str:
            d = job_dirs(exp)[job]
            if drop_npy:
                (d / f"{name}.npy").unlink()
            p = d / f"{name}{suffix}"
            if p.exists() or p.is_symlink():
                p.unlink()
            if callable(data):
                data(p, d, tmp)
            elif isinstance(data, bytes):
                p.write_bytes(data)
            else:
                np.save(p, data, allow_pickle=True)
            return str(p)
        return make
    return deco


def _normals(exp: Path, job=0) -> np.ndarray:
    return np.load(job_dirs(exp)[job] / "normals.npy")


def _edit(which: str, fn, *, raw=False):
    """A case that rewrites ``manifest.json`` (``which`` = "manifest") or job 0's job.json
    ("job") with ``fn(value, exp, tmp)`` (a JSON value, or the file's text when ``raw``)."""
    def make(exp: Path, tmp: Path) -> str:
        p = exp / "manifest.json" if which == "manifest" else job_dirs(exp)[0] / "job.json"
        text = p.read_text()
        new = fn(text if raw else json.loads(text), exp, tmp)
        if isinstance(new, bytes):
            p.write_bytes(new)
        else:
            p.write_text(new if raw else json.dumps(new))
        return str(p)
    return make


def _set(path: list, value):
    """``fn`` for :func:`_edit`: set the item at ``path`` (keys / indices) to ``value`` (or delete it
    when ``value`` is :data:`DELETE`)."""
    def fn(v, exp, tmp):
        obj = v
        for k in path[:-1]:
            obj = obj[k]
        if value is DELETE:
            del obj[path[-1]]
        else:
            obj[path[-1]] = value(exp, tmp) if callable(value) else value
        return v
    return fn


DELETE = object()


def _outside_job(exp: Path, tmp: Path) -> str:
    """A copy of job 0's folder (good predictions included) outside the export: must not be scored."""
    out = tmp / "outside_job"
    shutil.copytree(job_dirs(exp)[0], out)
    return os.path.relpath(out, exp)


def _link_out(target_of):
    """A case function that replaces job 0's folder by a link to ``target_of(exp, tmp)``."""
    def make(exp: Path, tmp: Path) -> str:
        d = job_dirs(exp)[0]
        target = target_of(exp, tmp)
        shutil.rmtree(d)
        d.symlink_to(target, target_is_directory=True)
        return str(exp / "manifest.json")
    return make


def _fifo(p, d, tmp):
    os.mkfifo(p)


def _denied(exp: Path):
    """Reading job 0's normals.npy fails with EACCES (as for a file without read permission; the
    suite may run as root, where chmod does not stop a read)."""
    target = os.path.realpath(job_dirs(exp)[0] / "normals.npy")
    real_open = builtins.open

    def fopen(file, mode="r", *a, **k):
        if not isinstance(file, int) and os.path.realpath(os.fspath(file)) == target:
            raise PermissionError(13, "Permission denied", os.fspath(file))
        return real_open(file, mode, *a, **k)
    return mock.patch("builtins.open", fopen)


def _png_header(w: int, h: int) -> bytes:
    import zlib

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    chunk = struct.pack(">I", len(ihdr)) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr) & 0xFFFFFFFF)
    idat = zlib.compress(b"\x00" * 1024)
    chunk2 = struct.pack(">I", len(idat)) + b"IDAT" + idat + struct.pack(">I", zlib.crc32(b"IDAT" + idat) & 0xFFFFFFFF)
    return b"\x89PNG\r\n\x1a\n" + chunk + chunk2


def _bad_replicate(exp: Path, tmp: Path) -> str:
    """Good predictions in job 1's replicates/noise folder, but its normals of the wrong shape."""
    d = job_dirs(exp)[1]
    rep = d / "replicates" / "noise"
    write_predictions(rep, d / "job.json")
    np.save(rep / "normals.npy", np.zeros((5, 5, 3)))
    return str(rep / "normals.npy")


def cases() -> list[Case]:
    """Every hostile export of the corpus."""
    normals = _pred("normals")
    valid = _pred("valid")
    c = [
        # ---- prediction files (job 0): header, size, dtype
        Case("npy header announces 7.28 TiB", "prediction",
             normals(_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 1000000), }"))),
        Case("npy header announces a huge 1-D array", "prediction",
             normals(_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (9223372036854775807,), }"))),
        Case("empty npy", "prediction", normals(b"")),
        Case("npy truncated after its header", "prediction",
             normals(_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (40, 40, 3), }") + b"\0" * 100)),
        Case("npy that is text", "prediction", normals(b"1.0 2.0 3.0\n")),
        Case("npy header is not a dict", "prediction", normals(_npy_header("[1, 2, 3]") + b"\0" * 64)),
        Case("npy header is not Python", "prediction", normals(_npy_header("{'descr': '<f8', 'shape': (40,") + b"\0" * 64)),
        Case("npy header with a negative shape", "prediction",
             normals(_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (-40, 40, 3), }") + b"\0" * 64)),
        Case("npy header with an unknown dtype", "prediction",
             normals(_npy_header("{'descr': '<q9', 'fortran_order': False, 'shape': (40, 40, 3), }") + b"\0" * 64)),
        Case("npy of an unknown format version", "prediction",
             normals(_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }", b"\x09\x00") + b"\0" * 24)),
        Case("npy of Python objects (a pickle)", "prediction", normals(np.array([{"a": 1}, None], dtype=object))),
        Case("npy of strings", "prediction", normals(np.full((40, 40, 3), "x"))),
        Case("npy of complex numbers", "prediction", normals(np.zeros((40, 40, 3), complex))),
        Case("npy of a structured dtype", "prediction", normals(np.zeros((40, 40), dtype=[("x", "f8"), ("y", "f8")]))),
        Case("npy of datetimes", "prediction", normals(np.zeros((40, 40, 3), "datetime64[s]"))),
        # ---- shape and values
        Case("normals of the wrong shape", "prediction", normals(np.zeros((10, 10, 3)))),
        Case("normals of the wrong rank", "prediction", normals(np.zeros((40, 40)))),
        Case("normals transposed", "prediction", normals(np.zeros((3, 40, 40)))),
        Case("normals of zero size", "prediction", normals(np.zeros((0, 40, 3)))),
        Case("a 0-d npy", "prediction", normals(np.float64(1.0))),
        Case("NaN normals inside the mask", "prediction",
             normals(lambda p, d, tmp: np.save(p, np.full((40, 40, 3), np.nan)))),
        Case("inf normals inside the mask", "prediction",
             normals(lambda p, d, tmp: np.save(p, np.where(np.load(d / "mask.npy")[..., None], np.inf, 0.0)
                                               * np.ones(3)))),
        Case("normals of 1e308 (overflow)", "prediction",
             normals(lambda p, d, tmp: np.save(p, np.full((40, 40, 3), 1e308)))),
        Case("albedo of 1e308 (an infinite score)", "prediction",
             _pred("albedo")(lambda p, d, tmp: np.save(p, np.full((40, 40), 1e308)))),
        Case("a NaN mask", "prediction", valid(np.full((40, 40), np.nan))),
        Case("an inf mask", "prediction", valid(np.full((40, 40), -np.inf))),
        Case("a mask of Python objects", "prediction", valid(np.array([None] * 4, dtype=object))),
        Case("a mask of the wrong shape", "prediction", valid(np.ones((40, 39), bool))),
        # ---- where the file should be
        Case("normals missing", "prediction", lambda e, tmp: (normals(lambda p, d, t: None)(e, tmp),
                                                              str(job_dirs(e)[0] / "normals.exr"))[1]),
        Case("a folder named normals.npy", "prediction", normals(lambda p, d, tmp: p.mkdir())),
        Case("a named pipe as normals.npy", "prediction", normals(_fifo)),
        Case("normals.npy links to /etc/hostname", "prediction", normals(lambda p, d, tmp: p.symlink_to("/etc/hostname"))),
        Case("normals.npy links to a good file outside the export", "prediction",
             normals(lambda p, d, tmp: (np.save(tmp / "elsewhere.npy", np.load(d / "albedo.npy")[..., None]
                                                * np.ones(3)), p.symlink_to(tmp / "elsewhere.npy")))),
        Case("normals.npy links to /dev/zero", "prediction", normals(lambda p, d, tmp: p.symlink_to("/dev/zero"))),
        Case("a dangling link as normals.npy", "prediction", normals(lambda p, d, tmp: p.symlink_to(d / "nothing.npy"))),
        Case("a link loop as normals.npy", "prediction", normals(lambda p, d, tmp: p.symlink_to(p))),
        Case("a sparse 1 GiB normals.npy", "prediction",
             normals(lambda p, d, tmp: (np.save(p, np.zeros((40, 40, 3))), os.truncate(p, 2**30)))),
        Case("an unreadable normals.npy", "prediction", normals(lambda p, d, tmp: np.save(p, np.zeros((40, 40, 3)))),
             patch=_denied),
        # ---- other formats (the .npy removed)
        Case("normals.exr that is not an EXR", "prediction", normals(b"not an exr at all", ".exr", drop_npy=True)),
        Case("normals.exr of the wrong size", "prediction",
             normals(lambda p, d, tmp: __import__("pbrbench.io").io.write_exr_image(p, np.zeros((8, 8, 3))), ".exr",
                     drop_npy=True)),
        Case("normals.png announcing 100000 x 100000 pixels", "prediction",
             normals(_png_header(100000, 100000), ".png", drop_npy=True)),
        Case("normals.png with a bad CRC", "prediction",
             normals(_png_header(40, 40)[:-5] + b"\0\0\0\0\0", ".png", drop_npy=True)),
        Case("normals.png that is empty", "prediction", normals(b"", ".png", drop_npy=True)),
        Case("normals.pfm with a damaged header", "prediction", normals(b"PF\nforty 40\n-1\n", ".pfm", drop_npy=True)),
        Case("normals.pfm announcing 10^9 x 10^9 pixels", "prediction",
             normals(b"PF\n1000000000 1000000000\n-1\n" + b"\0" * 64, ".pfm", drop_npy=True)),
        Case("normals.tif that is not a TIFF", "prediction", normals(b"II*\0garbage", ".tif", drop_npy=True)),
        # ---- a replicate's prediction (job 1 has replicates/noise)
        Case("a replicate prediction of the wrong shape", "replicate", _bad_replicate),
    ]

    m, j = "manifest", "job"
    c += [
        # ---- manifest.json
        Case("manifest truncated", "export", _edit(m, lambda t, e, tmp: t[: len(t) // 2], raw=True)),
        Case("manifest empty", "export", _edit(m, lambda t, e, tmp: "", raw=True)),
        Case("manifest not UTF-8", "export", _edit(m, lambda t, e, tmp: b"\xff\xfe{\x00", raw=True)),
        Case("manifest a list", "export", _edit(m, lambda v, e, tmp: [v])),
        Case("manifest a number", "export", _edit(m, lambda v, e, tmp: "1e999", raw=True)),
        Case("manifest nested 100000 deep", "export", _edit(m, lambda t, e, tmp: "[" * 100000 + "]" * 100000, raw=True)),
        Case("manifest jobs missing", "export", _edit(m, _set(["jobs"], DELETE))),
        Case("manifest jobs an object", "export", _edit(m, _set(["jobs"], {"a": 1}))),
        Case("manifest jobs empty", "export", _edit(m, _set(["jobs"], []))),
        Case("manifest job a string", "export", _edit(m, _set(["jobs", 0], "jobs/000"))),
        Case("manifest job without its folder", "export", _edit(m, _set(["jobs", 0, "folder"], DELETE))),
        Case("manifest job without its key", "export", _edit(m, _set(["jobs", 0, "key"], DELETE))),
        Case("manifest job folder a number", "export", _edit(m, _set(["jobs", 0, "folder"], 7))),
        Case("manifest job key a list", "export", _edit(m, _set(["jobs", 0, "key"], ["k"]))),
        Case("manifest two jobs with one key", "export",
             _edit(m, lambda v, e, tmp: _set(["jobs", 1, "key"], v["jobs"][0]["key"])(v, e, tmp))),
        Case("manifest seed huge", "export", _edit(m, _set(["seed"], 10**40))),
        Case("manifest seed 1e999", "export", _edit(m, lambda t, e, tmp: t.replace('"seed": 0', '"seed": 1e999'), raw=True)),
        Case("manifest seed NaN", "export", _edit(m, lambda t, e, tmp: t.replace('"seed": 0', '"seed": NaN'), raw=True)),
        Case("manifest seed of 5000 digits", "export",
             _edit(m, lambda t, e, tmp: t.replace('"seed": 0', '"seed": ' + "9" * 5000), raw=True)),
        Case("manifest seed a string", "export", _edit(m, _set(["seed"], "0"))),
        Case("manifest seed negative", "export", _edit(m, _set(["seed"], -1))),
        Case("manifest quality unknown", "export", _edit(m, _set(["quality"], "ultra"))),
        Case("manifest quality a list", "export", _edit(m, _set(["quality"], ["draft"]))),
        Case("manifest task a number", "export", _edit(m, _set(["task"], 3))),
        Case("manifest replicates a string", "export", _edit(m, _set(["replicates"], "yes"))),
        Case("manifest job folder ../../outside_job", "export", _edit(m, _set(["jobs", 0, "folder"], _outside_job))),
        Case("manifest job folder /etc", "export", _edit(m, _set(["jobs", 0, "folder"], "/etc"))),
        Case("manifest job folder absolute, inside the export", "export",
             _edit(m, lambda v, e, tmp: _set(["jobs", 0, "folder"], str(job_dirs(e)[0]))(v, e, tmp))),
        Case("manifest job folder with .. in the middle", "export",
             _edit(m, lambda v, e, tmp: _set(["jobs", 0, "folder"], "jobs/../../" + os.path.basename(e) + "/"
                                             + v["jobs"][0]["folder"])(v, e, tmp))),
        Case("manifest job folder with a NUL", "export", _edit(m, _set(["jobs", 0, "folder"], "jobs/\u0000x"))),
        Case("manifest job folder empty", "export", _edit(m, _set(["jobs", 0, "folder"], ""))),
        Case("manifest a link out of the export", "export",
             lambda e, tmp: (shutil.move(e / "manifest.json", tmp / "m.json"), (e / "manifest.json").symlink_to(tmp / "m.json"),
                             str(e / "manifest.json"))[2]),
        Case("job folder a link to /etc", "export", _link_out(lambda e, tmp: "/etc")),
        Case("job folder a link to a good job outside", "export",
             _link_out(lambda e, tmp: (shutil.copytree(job_dirs(e)[0], tmp / "copy"), tmp / "copy")[1])),
        # ---- job.json (job 0)
        Case("job.json truncated", "export", _edit(j, lambda t, e, tmp: t[: len(t) // 3], raw=True)),
        Case("job.json empty", "export", _edit(j, lambda t, e, tmp: "", raw=True)),
        Case("job.json a list", "export", _edit(j, lambda v, e, tmp: [v])),
        Case("job.json null", "export", _edit(j, lambda v, e, tmp: None)),
        Case("job.json inputs missing", "export", _edit(j, _set(["inputs"], DELETE))),
        Case("job.json inputs a list", "export", _edit(j, _set(["inputs"], [1, 2]))),
        Case("job.json an input a number", "export", _edit(j, _set(["inputs", "images"], 3))),
        Case("job.json an input's sha256 a number", "export", _edit(j, _set(["inputs", "images", "sha256"], 1e300))),
        Case("job.json an input without sha256 or value", "export", _edit(j, _set(["inputs", "images"], {"shape": [1]}))),
        Case("job.json key differs from the manifest's", "export", _edit(j, _set(["key"], "another job"))),
        Case("job.json key missing", "export", _edit(j, _set(["key"], DELETE))),
        Case("job.json folder ../..", "export", _edit(j, _set(["folder"], "../.."))),
        Case("job.json replicates a string", "export", _edit(j, _set(["replicates"], "all"))),
        Case("job.json replicate folder /etc", "export",
             _edit(j, _set(["replicates"], [{"folder": "/etc", "seed": 1, "inputs": {}}]))),
        Case("job.json replicate folder ../../..", "export",
             _edit(j, _set(["replicates"], [{"folder": "jobs/../../..", "seed": 1, "inputs": {}}]))),
        Case("job.json replicate without inputs", "export",
             _edit(j, lambda v, e, tmp: _set(["replicates"], [{"folder": v["folder"] + "/replicates/0"}])(v, e, tmp))),
        Case("job.json a number of 5000 digits", "export",
             _edit(j, lambda t, e, tmp: t.replace('"seed": 0', '"seed": ' + "7" * 5000), raw=True)),
        Case("job.json missing", "export", lambda e, tmp: (os.unlink(job_dirs(e)[0] / "job.json"),
                                                           str(job_dirs(e)[0] / "job.json"))[1]),
        Case("job.json a folder", "export", lambda e, tmp: (os.unlink(job_dirs(e)[0] / "job.json"),
                                                            (job_dirs(e)[0] / "job.json").mkdir(),
                                                            str(job_dirs(e)[0] / "job.json"))[2]),
        Case("job.json a link out of the export", "export",
             lambda e, tmp: ((tmp / "j.json").write_text((job_dirs(e)[0] / "job.json").read_text()),
                             os.unlink(job_dirs(e)[0] / "job.json"),
                             (job_dirs(e)[0] / "job.json").symlink_to(tmp / "j.json"), str(e / "manifest.json"))[3]),
        Case("job folder missing", "export", lambda e, tmp: (shutil.rmtree(job_dirs(e)[0]), str(job_dirs(e)[0]))[1]),
        Case("job folder a file", "export", lambda e, tmp: (shutil.rmtree(job_dirs(e)[0]), job_dirs(e)[0].write_text("x"),
                                                            str(job_dirs(e)[0]))[2]),
    ]
    return c


# ----------------------------------------------------------------------------- running a case
PROGRESS = re.compile(r"pbrbench: (render|jobs|export)\b.*(\d+%|done) \(")   # progress lines, not messages


def evaluate(exp: Path, tmp: Path, extra=(), patch=None):
    """``pbrbench evaluate photometric_stereo EXP`` in this process (store and cache in ``tmp``)."""
    from tests.corpus.measure import run_in_process

    args = ["evaluate", TASK, str(exp), "--no-report", "--store", str(tmp / "h.sqlite"), "--out", str(tmp / "reports"),
            "--cache", str(tmp / "cache"), *extra]
    work = tmp / "cwd"
    work.mkdir(parents=True, exist_ok=True)
    with synthetic_world(), (patch or contextlib.nullcontext()):
        return run_in_process(args, cwd=work)


def stored(tmp: Path) -> list[dict]:
    """The scores of every run in ``tmp``'s store (none when there is no store)."""
    p = tmp / "h.sqlite"
    if not p.exists():
        return []
    con = sqlite3.connect(f"file:{p}?mode=ro", uri=True)
    try:
        con.row_factory = sqlite3.Row
        names = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if "scores" not in names:
            return []
        return [dict(r) for r in con.execute("SELECT * FROM scores")]
    finally:
        con.close()


def classify(case: Case, base: Path) -> tuple[str, str]:
    """``("clean", last line)`` when ``case`` is handled as its kind says (module docstring), else
    ``(what went wrong, detail)``."""
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        exp = tmp / "export"
        shutil.copytree(base, exp, symlinks=True)
        named = case.make(exp, tmp)
        r = evaluate(exp, tmp, patch=case.patch(exp) if case.patch else None)
        err = r.stderr
        lines = [ln for ln in err.splitlines() if ln.strip() and not PROGRESS.match(ln)]
        if "Traceback" in err or "internal error" in err:
            return "traceback", (lines[-1] if lines else "")[:240]
        if r.returncode != 1:
            return "accepted", f"rc={r.returncode}: " + " // ".join(lines[-2:])[:240]
        if len(lines) != 1:
            return "lines", f"{len(lines)} lines: " + " // ".join(lines[:3])[:300]
        line = lines[0]
        if named not in line:
            return "unnamed", f"{line[:240]} (want {named})"
        scores = stored(tmp)
        if case.kind == "export":
            if "prediction failed" in line or scores:
                return "scored", f"{line[:200]} ({len(scores)} scores stored)"
            return "clean", line[:200]
        want = "pbrbench: prediction failed: " if case.kind == "prediction" else "pbrbench: replicate prediction refused"
        if not line.startswith(want):
            return "other", line[:240]
        if not all(s["value"] is not None and np.isfinite(float(s["value"])) for s in scores):
            return "non_finite", "a non-finite score was stored"
        ok = {(s["scene"], s["condition"]) for s in scores if s["metric"] == "normal_mean_deg"}
        bad = {(s["scene"], s["condition"]) for s in scores if s["metric"] == "failed" and float(s["value"]) == 1.0}
        good = {("ps_a", "local+noise0.01"), ("ps_b", "global")}
        want_ok = good | ({("ps_a", "local")} if case.kind == "replicate" else set())
        if ok != want_ok or bad != (set() if case.kind == "replicate" else {("ps_a", "local")}):
            return "lost", f"scored {sorted(ok)}, failed {sorted(bad)}"
        scored = "scored on 3 of 3" if case.kind == "replicate" else "scored on 2 of 3"
        if scored not in r.stdout:
            return "other", f"stdout lacks {scored!r}: {r.stdout[:200]}"
        return "clean", line[:200]


def measure(verbose: bool = True) -> dict:
    from collections import Counter

    out: Counter = Counter()
    with tempfile.TemporaryDirectory() as d:
        base = build_base(Path(d) / "base")
        for case in cases():
            outcome, msg = classify(case, base)
            out[outcome] += 1
            if verbose:
                print(f"{case.kind:10s} {case.name:52s} {outcome:10s} {msg}", flush=True)
    return out


if __name__ == "__main__":
    c = measure()
    print(f"{sum(c.values())} hostile exports: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))
    sys.exit(0 if set(c) == {"clean"} else 1)
