"""Export -> a program outside pbrbench -> evaluate: every task's inputs written to open files, the
built-in methods re-run by an external script that reads only the exported files, and the
evaluated scores identical to the in-process run; bad prediction files are one-line failures
naming the file, and the other jobs are still scored."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pbrbench import io
from pbrbench.bench.external import evaluate_export, export_task, read_manifest
from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.quality import DRAFT, get_quality
from pbrbench.registry import Registry, builtin_registry
from pbrbench.tasks.base import Job
from pbrbench.tasks.hdr import HDRTask
from pbrbench.tasks.lightness import LightnessTask
from pbrbench.tasks.photometric_stereo import PhotometricStereoTask
from pbrbench.tasks.sfs import SFSTask
from pbrbench.tasks.specular import SpecularTask
from tests.fakes import (
    FakeSource,
    hdr_gt,
    mondrian_gt,
    ps_gt,
    ps_job,
    settings_for,
    sfs_gt,
    specular_gt,
)

ROOT = Path(__file__).resolve().parents[2]


class PS(PhotometricStereoTask):
    def jobs(self, quality):
        return [ps_job("local", scene="ps_a"), ps_job("local+noise0.01", scene="ps_a"), ps_job("global", scene="ps_b")]


class SFS(SFSTask):
    def jobs(self, quality):
        _, job = sfs_gt()
        return [Job("sfs", "sfs_a", c, job.params) for c in ("local", "local+noise0.01", "global")]


class Lightness(LightnessTask):
    def jobs(self, quality):
        return [Job("lightness", "mondrian_a", c, (("paper_ids", ()),)) for c in ("local", "global")]


class HDR(HDRTask):
    def jobs(self, quality):
        return [Job("hdr", "hdr_a", c) for c in ("global+noise0", "global+readnoise0.002")]


class Specular(SpecularTask):
    def jobs(self, quality):
        return [Job("specular", "spec_a", c) for c in self.conditions]


GTS = {"ps_a": lambda: ps_gt()[0], "ps_b": lambda: ps_gt("bumps", gi_gain=1.1)[0], "sfs_a": lambda: sfs_gt()[0],
       "mondrian_a": lambda: mondrian_gt(48, shadow=True), "hdr_a": lambda: hdr_gt(24), "spec_a": lambda: specular_gt(48)}


class Synthetic(FakeSource):
    def load(self, spec):
        gt = GTS[spec.name]()
        gt.meta["scene_hash"] = spec.content_hash()
        return gt


TASKS = {"photometric_stereo": PS(), "sfs": SFS(), "lightness": Lightness(), "hdr": HDR(), "specular": Specular()}
# the built-in each task's external program reproduces
BUILTIN = {"photometric_stereo": "woodham1980", "sfs": "pentland1990", "lightness": "blake1985", "hdr": "debevec1997",
           "specular": "harmonic"}

EXTERNAL = r'''
"""An external program: reads only the exported files, writes predictions next to them."""
import json, sys
from pathlib import Path
import numpy as np
from pbrbench.infer.hdr import calibrate_debevec1997, merge_hdr
from pbrbench.infer.lightness import lightness_blake1985
from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980
from pbrbench.infer.sfs import shape_from_shading_pentland1990
from pbrbench.infer.specular import detect_specularities, remove_specularities_harmonic

root, fmt = Path(sys.argv[1]), sys.argv[2]
reps = len(sys.argv) > 3 and sys.argv[3] == "replicates"
m = json.loads((root / "manifest.json").read_text())
todo = []
for e in m["jobs"]:
    job = json.loads((root / e["folder"] / "job.json").read_text())
    todo.append((root / e["folder"], job["inputs"]))
    if reps:
        todo += [(root / r["folder"], r["inputs"]) for r in job["replicates"]]
for d, inputs in todo:
    def get(name):
        x = inputs[name]
        return np.load(d / x["exact"]) if "exact" in x else (np.asarray(x["value"]) if isinstance(x["value"], list) else x["value"])
    def put(name, a):
        if fmt == "exr" and np.asarray(a).dtype != bool:
            from pbrbench.io import write_exr_image
            write_exr_image(d / f"{name}.exr", a)
        else:
            np.save(d / f"{name}.npy", a)
    t = m["task"]
    if t == "photometric_stereo":
        r = photometric_stereo_woodham1980(get("images"), get("lights"), mask=get("mask"))
        put("normals", r.normals); put("albedo", r.albedo); put("valid", r.valid)
    elif t == "sfs":
        r = shape_from_shading_pentland1990(get("image"), get("light"), albedo=get("albedo"), mask=get("mask"),
                                            pixel_size=get("pixel_size"))
        put("height", r.height); put("normals", r.normals)
        if r.converged is not None:
            (d / "converged.txt").write_text(str(int(bool(r.converged))))
    elif t == "lightness":
        refl, shad = lightness_blake1985(get("image"), mask=get("mask"), threshold=0.05)
        put("reflectance", refl); put("shading", shad)
    elif t == "hdr":
        resp = calibrate_debevec1997(get("images"), get("exposure_times"), seed=m["seed"])
        if fmt == "radiance":
            put("radiance", merge_hdr(get("images"), get("exposure_times"), resp))
        else:
            put("response", resp.inverse)
    elif t == "specular":
        image, mask = get("image"), get("mask")
        det = detect_specularities(image, mask=mask)
        put("mask", det); put("removed", remove_specularities_harmonic(image, det))
'''


def _in_process(tmp_path, task, seed, uncertainty=False):
    # without the replicates a seed-dependent score is the own seed's draw, as a program that ran
    # on the jobs only is scored (with them, the mean over the seeds: docs/science.md §8)
    return run_benchmark(RunConfig(quality="draft", seed=seed, entry_points=False, uncertainty=uncertainty),
                         settings=settings_for(tmp_path),
                         tasks={task.name: task}, source=Synthetic(tmp_path / "cache"),
                         registry=Registry([builtin_registry({task.name: task}).get(task.name, BUILTIN[task.name])]),
                         log=lambda m: None)


def _external(export_dir, fmt="npy", *extra):
    # one BLAS thread, as the benchmark's own jobs run (pbrbench.bench.executors.blas_threads): a
    # LAPACK solve on two threads can differ in the last bits, and these scores are compared bit for bit
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    q = subprocess.run([sys.executable, "-c", EXTERNAL, str(export_dir), fmt, *extra], capture_output=True, text=True,
                       timeout=600, env=env, cwd=export_dir)
    assert q.returncode == 0, q.stderr[-3000:]


def _by_key(scores, algorithm):
    return {(s["scene"], s["condition"], s["metric"]): s["value"] for s in scores if s["algorithm"] == algorithm}


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
@pytest.mark.parametrize("name", list(TASKS))
def test_export_external_program_evaluate_reproduces_the_in_process_scores_exactly(tmp_path, name):
    task, seed = TASKS[name], 3
    ref = _in_process(tmp_path / "ref", task, seed)
    assert not ref.errors
    manifest = export_task(task, tmp_path / "export", quality=get_quality(DRAFT), seed=seed,
                           source=Synthetic(tmp_path / "cache"))
    assert len(manifest["jobs"]) == len(task.export_jobs(get_quality("draft")))
    _external(tmp_path / "export")
    out, reader = evaluate_export(task, tmp_path / "export", name="mine", version="7", settings=settings_for(tmp_path / "ev"),
                                  source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert not out.errors and not reader.errors, reader.errors
    want, got = _by_key(ref.scores, BUILTIN[name]), _by_key(out.scores, "mine")
    assert len(want) > 3 and got == want          # bit-identical scores, every metric of every job
    assert {s["algorithm_version"].split("+")[0] for s in out.scores} == {"7"}
    html = out.report.read_text()
    assert 'data-algorithm="mine"' in html
    from pbrbench.bench.store import Store

    with Store(settings_for(tmp_path / "ev").store_path()) as st:
        assert [r["id"] for r in st.runs()] == [out.run_id]


class Grouped(Synthetic):
    """Synthetic ground truths with G = 4 noisy sample groups (delete-one-group replicates)."""

    def load(self, spec):
        from tests.fakes import with_groups

        return with_groups(super().load(spec), 0.01, seed=sum(map(ord, spec.name)))


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
def test_evaluate_gives_the_standard_errors_when_the_program_ran_on_the_replicates(tmp_path):
    task, seed = TASKS["photometric_stereo"], 1
    ref = run_benchmark(RunConfig(quality="draft", seed=seed, entry_points=False), settings=settings_for(tmp_path / "ref"),
                        tasks={task.name: task}, source=Grouped(tmp_path / "cache"),
                        registry=Registry([builtin_registry({task.name: task}).get(task.name, "woodham1980")]),
                        log=lambda m: None)
    want = {(s["scene"], s["condition"], s["metric"]): (s["value"], s["uncertainty"], s["dof"], s["bias"])
            for s in ref.scores}
    assert all(math.isfinite(u) for _, u, _, _ in want.values())
    export_task(task, tmp_path / "export", quality=get_quality(DRAFT), seed=seed, source=Grouped(tmp_path / "cache"))
    job = json.loads((tmp_path / "export" / read_manifest(tmp_path / "export")["jobs"][1]["folder"] / "job.json").read_text())
    assert [r["folder"].split("/", 2)[-1] for r in job["replicates"]] == [
        "replicates/0", "replicates/1", "replicates/2", "replicates/3", "replicates/perturbed",
        "replicates/noise", "replicates/noise2", "replicates/noise3"]   # local+noise0.01: three other seeds
    # the program ran on the jobs only: scores, no standard errors, and the reader says why; a
    # seed-dependent score is then the own seed's draw (the in-process run without replicates)
    _external(tmp_path / "export")
    out, reader = evaluate_export(task, tmp_path / "export", name="mine", settings=settings_for(tmp_path / "a"),
                                  source=Grouped(tmp_path / "cache"), log=lambda m: None)
    assert not reader.errors and len(reader.missing_replicates) == 3
    got = {(s["scene"], s["condition"], s["metric"]): s for s in out.scores if s["algorithm"] == "mine"}
    plain = run_benchmark(RunConfig(quality="draft", seed=seed, entry_points=False, uncertainty=False),
                          settings=settings_for(tmp_path / "plain"), tasks={task.name: task}, source=Grouped(tmp_path / "cache"),
                          registry=Registry([builtin_registry({task.name: task}).get(task.name, "woodham1980")]),
                          log=lambda m: None)
    plain = _by_key(plain.scores, "woodham1980")
    assert {k: v["value"] for k, v in got.items()} == plain
    assert all(math.isnan(v["uncertainty"]) for v in got.values())
    k = ("ps_a", "local+noise0.01", "normal_mean_deg")
    assert want[k][0] != plain[k]              # the mean over the seeds, not the own seed's draw
    # ... and on every replicate folder too: the in-process standard errors, bit for bit
    _external(tmp_path / "export", "npy", "replicates")
    out, reader = evaluate_export(task, tmp_path / "export", name="mine", settings=settings_for(tmp_path / "b"),
                                  source=Grouped(tmp_path / "cache"), log=lambda m: None)
    assert not reader.errors and not reader.missing_replicates
    mine = [s for s in out.scores if s["algorithm"] == "mine"]
    got = {(s["scene"], s["condition"], s["metric"]): (s["value"], s["uncertainty"], s["dof"], s["bias"]) for s in mine}
    assert got == want
    # an outside program's convergence is unknown: it was scored on the perturbed inputs too, and
    # Woodham's least squares is smooth in them (not chaotic: the jackknife above stands)
    scored = [s for s in mine if s["metric"] not in ("failed", "converged")]
    assert all(math.isfinite(s["perturbed"]) and s["chaotic"] is False for s in scored)
    # without predictions on the perturbed inputs: the same ± (the jackknife and the other seeds'
    # part; the chaos test is skipped, not a failure), and the reader says which jobs lack them
    import shutil

    for rec in read_manifest(tmp_path / "export")["jobs"]:
        shutil.rmtree(tmp_path / "export" / rec["folder"] / "replicates" / "perturbed")
        (tmp_path / "export" / rec["folder"] / "replicates" / "perturbed").mkdir()
    out, reader = evaluate_export(task, tmp_path / "export", name="mine", settings=settings_for(tmp_path / "c"),
                                  source=Grouped(tmp_path / "cache"), log=lambda m: None)
    assert not reader.errors and not reader.missing_replicates and len(reader.missing_perturbed) == 3
    mine = [s for s in out.scores if s["algorithm"] == "mine"]
    assert {(s["scene"], s["condition"], s["metric"]): (s["value"], s["uncertainty"], s["dof"], s["bias"])
            for s in mine} == want
    assert all(s["perturbed"] is None and s["chaotic"] is None for s in mine)


def test_the_exported_files_are_open_formats_with_the_exact_values(tmp_path):
    task = TASKS["photometric_stereo"]
    export_task(task, tmp_path / "x", quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    m = read_manifest(tmp_path / "x")
    assert m["input_names"] == ["images", "lights"] and [p["name"] for p in m["predictions"]] == ["normals", "albedo", "valid"]
    d = tmp_path / "x" / m["jobs"][0]["folder"]
    job = json.loads((d / "job.json").read_text())
    imgs = np.load(d / "images.npy")
    assert imgs.dtype == np.float64 and imgs.shape == (5, 40, 40)
    for k in range(5):
        assert np.array_equal(io.read_image(d / "images" / f"{k:03d}.exr"), imgs[k].astype(np.float32))
    mask = np.load(d / "mask.npy")
    assert np.array_equal(io.read_png(d / "mask.png") > 0, mask) and mask.dtype == bool
    lights = np.asarray(job["inputs"]["lights"]["value"])
    assert np.array_equal(lights, np.asarray(ps_job().param("lights"), float))   # exact, from JSON
    e = np.asarray(job["inputs"]["lights"]["irradiances"])
    assert np.allclose(np.asarray(job["inputs"]["lights"]["directions"]) * e[:, None], lights) and np.allclose(e, np.pi)
    assert job["predictions"][0] == {"name": "normals", "files": ["normals.exr", "normals.npy"], "shape": [40, 40, 3],
                                     "required": True, "kind": "float",
                                     "meaning": task.predictions[0].meaning}
    assert job["call"] == "fn(images, lights, mask=mask)" and "camera_frame" in job["conventions"]
    hd = tmp_path / "h"
    export_task(TASKS["hdr"], hd, quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    d = hd / read_manifest(hd)["jobs"][0]["folder"]
    ims = np.load(d / "images.npy")
    assert ims.dtype.kind == "u" and np.array_equal(io.read_png(d / "images" / "000.png"), ims[0])
    assert "exposure_times" in json.loads((d / "job.json").read_text())["inputs"]


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
def test_float32_exr_predictions_score_close_to_the_exact_ones(tmp_path):
    task = TASKS["photometric_stereo"]
    ref = _in_process(tmp_path / "ref", task, 0)
    export_task(task, tmp_path / "export", quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    _external(tmp_path / "export", "exr")
    out, reader = evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                                  source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert not reader.errors
    want, got = _by_key(ref.scores, "woodham1980"), _by_key(out.scores, "external")
    assert set(got) == set(want)
    for k, v in want.items():
        if k[2] in ("normal_mean_deg", "normal_median_deg"):
            assert got[k] == pytest.approx(v, abs=1e-3), k      # float32 normals: ~1e-7 rad


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
def test_hdr_radiance_predictions_are_scored_without_the_response(tmp_path):
    task = TASKS["hdr"]
    ref = _in_process(tmp_path / "ref", task, 1)
    export_task(task, tmp_path / "export", quality=DRAFT, seed=1, source=Synthetic(tmp_path / "cache"))
    _external(tmp_path / "export", "radiance")
    out, reader = evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                                  source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert not reader.errors and not out.errors
    want = {k: v for k, v in _by_key(ref.scores, "debevec1997").items() if k[2] != "response_rmse"}
    assert _by_key(out.scores, "external") == want


def test_bad_prediction_files_are_one_line_failures_naming_the_file(tmp_path):
    task = TASKS["photometric_stereo"]
    export_task(task, tmp_path / "export", quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    _external(tmp_path / "export")
    m = read_manifest(tmp_path / "export")
    d = [tmp_path / "export" / e["folder"] for e in m["jobs"]]
    (d[0] / "normals.npy").unlink()                                     # missing
    np.save(d[1] / "normals.npy", np.zeros((10, 10, 3)))                # mis-shaped
    n = np.load(d[2] / "normals.npy")
    mask = np.load(d[2] / "mask.npy")
    n[np.argwhere(mask)[0][0], np.argwhere(mask)[0][1]] = np.nan          # NaN inside the mask
    n[0, 0] = np.nan                                                      # outside: ignored
    np.save(d[2] / "normals.npy", n)
    out, reader = evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                                  source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert not out.errors
    msgs = [reader.errors[e["key"]] for e in m["jobs"]]
    assert msgs[0].startswith(str(d[0] / "normals.exr")) and "missing" in msgs[0]
    assert msgs[1].startswith(str(d[1] / "normals.npy")) and "shape (10, 10, 3), expected (40, 40, 3)" in msgs[1]
    assert msgs[2].startswith(str(d[2] / "normals.npy")) and "1 pixel(s) with NaN/inf inside the mask" in msgs[2]
    assert all("\n" not in x for x in msgs)
    failed = {(s["scene"], s["condition"]) for s in out.scores if s["metric"] == "failed"}
    assert len(failed) == 3 and not [s for s in out.scores if s["metric"] == "normal_mean_deg"]
    assert "normals.npy: shape (10, 10, 3)" in out.report.read_text()


def test_some_jobs_bad_others_scored_and_tampered_inputs_refused(tmp_path):
    task = TASKS["sfs"]
    export_task(task, tmp_path / "export", quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    _external(tmp_path / "export")
    m = read_manifest(tmp_path / "export")
    d0 = tmp_path / "export" / m["jobs"][0]["folder"]
    (d0 / "normals.npy").unlink()          # optional: derived from the height
    d1 = tmp_path / "export" / m["jobs"][1]["folder"]
    jf = d1 / "job.json"
    job = json.loads(jf.read_text())
    job["inputs"]["image"]["sha256"] = "0" * 64
    jf.write_text(json.dumps(job))
    out, reader = evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                                  source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert list(reader.errors) == [m["jobs"][1]["key"]] and "input 'image' differs from the exported one" in \
        reader.errors[m["jobs"][1]["key"]]
    scored = {s["condition"] for s in out.scores if s["metric"] == "normal_mean_deg"}
    assert scored == {m["jobs"][0]["condition"], m["jobs"][2]["condition"]}


def test_evaluate_refuses_a_folder_that_is_no_export_and_a_wrong_task(tmp_path):
    from pbrbench.errors import UserError

    with pytest.raises(UserError, match="no manifest.json"):
        evaluate_export(TASKS["sfs"], tmp_path, settings=settings_for(tmp_path))
    export_task(TASKS["lightness"], tmp_path / "e", quality=DRAFT, source=Synthetic(tmp_path / "cache"))
    with pytest.raises(UserError, match="an export of task 'lightness'"):
        evaluate_export(TASKS["sfs"], tmp_path / "e", settings=settings_for(tmp_path))
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "x.txt").write_text("mine")
    with pytest.raises(UserError, match="not an export"):
        export_task(TASKS["lightness"], tmp_path / "busy", quality=DRAFT, source=Synthetic(tmp_path / "cache"))


def test_readme_of_an_export_says_what_to_write(tmp_path):
    export_task(TASKS["specular"], tmp_path / "e", quality=DRAFT, source=Synthetic(tmp_path / "cache"))
    text = (tmp_path / "e" / "README.txt").read_text()
    assert "mask.exr or mask.npy (or .png)" in text and "pbrbench evaluate specular" in text
    assert textwrap.dedent(text) == text


@pytest.mark.render
@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_the_commands_on_draft_renders_round_trip_exactly(tmp_path, cache_dir, capsys):
    """`pbrbench run --algorithm` (a .py plugin that crashes beside one that works), `pbrbench export`,
    an external program, `pbrbench evaluate`: the evaluated scores equal the run's built-in ones."""
    from pbrbench.bench.store import Store
    from pbrbench.cli.main import main

    plugin = tmp_path / "mine.py"
    plugin.write_text("from pbrbench.infer.lightness import lightness_blake1985\n"
                      "def same(image, *, mask=None):\n    return lightness_blake1985(image, mask=mask, threshold=0.05)\n"
                      "def crash(image, *, mask=None):\n    raise RuntimeError('crash')\n")
    common = ["--quality", "draft", "--cache", str(cache_dir)]
    store = ["--out", str(tmp_path / "rep"), "--store", str(tmp_path / "h.sqlite")]
    assert main(["run", "--tasks", "lightness", *common, *store, "--algorithm", f"lightness={plugin}:same",
                 "--algorithm", f"lightness={plugin}:crash"]) == 0
    err = capsys.readouterr().err
    assert "crash (lightness) scored as failed on" in err
    assert main(["export", "lightness", *common, "--out", str(tmp_path / "exp")]) == 0
    _external(tmp_path / "exp")
    assert main(["evaluate", "lightness", str(tmp_path / "exp"), "--name", "ext", "--cache", str(cache_dir), *store]) == 0
    with Store(tmp_path / "h.sqlite") as st:
        runs = {r["id"]: {s["algorithm"] for s in st.scores(r["id"])} for r in st.runs()}
        run = next(r for r, a in runs.items() if "same" in a)
        ev = next(r for r, a in runs.items() if "ext" in a)
        a, b = st.scores(run), st.scores(ev)
    ref = _by_key(a, "blake1985")
    assert _by_key(a, "same") == ref and _by_key(b, "ext") == ref and len(ref) >= 12


class InfPS(PS):
    """Photometric stereo whose scoring of the predictions overflows on the ``local`` job (a
    stand-in for 1e308 values squared) or, with ``crash``, raises there."""

    crash = False

    def run_job(self, job, gts, *, seed=0, algorithms=(), quality=None):
        from dataclasses import replace

        res = super().run_job(job, gts, seed=seed, algorithms=algorithms, quality=quality)
        if job.condition == "local" and any(a.name == "external" for a in algorithms):
            if self.crash:
                raise FloatingPointError("overflow in the metric")
            res.scores = [replace(s, value=math.inf) if s.metric == "normal_mean_deg" else s for s in res.scores]
        return res


@pytest.mark.parametrize("crash", [False, True], ids=["inf score", "scoring raises"])
def test_a_score_that_is_not_finite_is_refused_and_the_other_jobs_are_scored(tmp_path, crash):
    task = InfPS()
    task.crash = crash
    export_task(task, tmp_path / "export", quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    _external(tmp_path / "export")
    m = read_manifest(tmp_path / "export")
    out, reader = evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                                  source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    bad = m["jobs"][0]
    assert list(reader.errors) == [bad["key"]] and not out.errors
    msg = reader.errors[bad["key"]]
    assert msg.startswith(str(tmp_path / "export" / bad["folder"])) and "\n" not in msg
    assert ("not finite" in msg) != crash and ("cannot be scored" in msg) == crash
    assert all(math.isfinite(s["value"]) for s in out.scores)
    scored = {s["condition"] for s in out.scores if s["metric"] == "normal_mean_deg"}
    assert scored == {"local+noise0.01", "global"}
    assert [s["condition"] for s in out.scores if s["metric"] == "failed" and s["value"] == 1.0] == ["local"]


def test_a_job_folder_outside_the_export_is_never_read(tmp_path):
    """A manifest whose job folder is ``../outside`` (a good job's copy, predictions included) or a
    link out of the export: refused before a run is created, naming the manifest."""
    import shutil

    from pbrbench.errors import UserError

    task = TASKS["photometric_stereo"]
    export_task(task, tmp_path / "export", quality=DRAFT, seed=0, source=Synthetic(tmp_path / "cache"))
    _external(tmp_path / "export")
    mp = tmp_path / "export" / "manifest.json"
    m = json.loads(mp.read_text())
    shutil.copytree(tmp_path / "export" / m["jobs"][0]["folder"], tmp_path / "outside")
    good = m["jobs"][0]["folder"]
    m["jobs"][0]["folder"] = "../outside"
    mp.write_text(json.dumps(m))
    with pytest.raises(UserError, match=r"manifest.json: jobs\[0\].folder '../outside' is not a plain path"):
        evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                        source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    m["jobs"][0]["folder"] = good
    mp.write_text(json.dumps(m))
    shutil.rmtree(tmp_path / "export" / good)
    (tmp_path / "export" / good).symlink_to(tmp_path / "outside")
    with pytest.raises(UserError, match="resolves to .*outside.*a symbolic link"):
        evaluate_export(task, tmp_path / "export", settings=settings_for(tmp_path / "ev"),
                        source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert not (tmp_path / "ev" / "h.sqlite").exists()
