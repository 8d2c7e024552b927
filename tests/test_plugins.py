"""Plugins: a user's algorithm scored beside the built-in ones with no edit to pbrbench -- a .py file
or a dotted module passed with ``--algorithm``, an installed entry point (three forms), stored
specs reloaded by ``--resume``, a per-call time limit that kills a hung plugin, crashes and bad
outputs scored as failures while the run goes on, and plugin entries that travel to other
processes (pickled by value)."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.errors import UserError
from pbrbench.plugins import plugin_registry
from pbrbench.registry import (
    Algorithm,
    PluginRegistry,
    Registry,
    algorithm,
    parse_algorithm_spec,
)
from tests.fakes import SphereSource, TinyPS, ps_gt, settings_for

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''
"""A user's photometric stereo: Woodham's least squares, normals rounded to 1e-4."""
import os
import time

import numpy as np

VERSION = "3"


def solve(images, lights, *, mask=None):
    from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980

    r = photometric_stereo_woodham1980(images, lights, mask=mask)
    return {"normals": np.round(r.normals, 4), "albedo": r.albedo, "valid": r.valid}


def hang(images, lights, *, mask=None):
    while True:
        pass


def sleepy(images, lights, *, mask=None):
    time.sleep(3600)


def die(images, lights, *, mask=None):
    os._exit(3)


class MyError(Exception):
    pass


def boom(images, lights, *, mask=None):
    raise MyError("a bug in the plugin")


def nans(images, lights, *, mask=None):
    k, h, w = images.shape
    return np.full((h, w, 3), np.nan), np.ones((h, w))


def chatty(images, lights, *, mask=None):
    print("hello from the plugin")          # must not break the child's protocol
    return solve(images, lights, mask=mask)
'''




def _run(tmp_path, specs=(), *, task=None, limit=60.0, entry_points=True, **kw):
    task = task or TinyPS()
    return run_benchmark(RunConfig(quality="draft", algorithms=list(specs), algorithm_time_limit=limit,
                                   entry_points=entry_points, **kw),
                         settings=settings_for(tmp_path), tasks={task.name: task},
                         source=SphereSource(tmp_path / "cache"), log=lambda m: None)


def _scores(o) -> dict:
    return {(s["algorithm"], s["metric"]): s["value"] for s in o.scores}


@pytest.fixture
def plugin_file(tmp_path) -> Path:
    p = tmp_path / "plugins" / "mine.py"
    p.parent.mkdir()
    p.write_text(PLUGIN)
    return p


# ----------------------------------------------------------------------------- specs
def test_algorithm_specs_parse_and_bad_ones_say_how_to_write_them():
    assert parse_algorithm_spec("photometric_stereo=./mine.py:solve") == ("photometric_stereo", "./mine.py", "solve", None)
    assert parse_algorithm_spec("photometric-stereo=mypkg.ps:Solver.run:mine") == \
        ("photometric_stereo", "mypkg.ps", "Solver.run", "mine")
    assert parse_algorithm_spec("sfs=/a/b c/x.py:f:n") == ("sfs", "/a/b c/x.py", "f", "n")
    for bad in ("photometric_stereo", "=m:f", "photometric_stereo=mine", "ps=m:f:n:extra"):
        with pytest.raises(UserError, match="TASK=MODULE:FUNCTION"):
            parse_algorithm_spec(bad)


def test_unusable_specs_are_one_line_user_errors(tmp_path, plugin_file):
    tasks = {"photometric_stereo": TinyPS()}
    with pytest.raises(UserError, match="not part of this run"):
        plugin_registry(tasks, [f"sfs={plugin_file}:solve"], entry_points=False)
    with pytest.raises(UserError, match="no such plugin file"):
        plugin_registry(tasks, [f"photometric_stereo={tmp_path}/nope.py:solve"], entry_points=False)
    with pytest.raises(UserError, match="has no 'solv'.*solve"):
        plugin_registry(tasks, [f"photometric_stereo={plugin_file}:solv"], entry_points=False)
    with pytest.raises(UserError, match="cannot be imported"):
        plugin_registry(tasks, ["photometric_stereo=no_such_module_xyz:solve"], entry_points=False)
    with pytest.raises(UserError, match="already registered.*add :NAME"):
        plugin_registry(tasks, [f"photometric_stereo={plugin_file}:solve:woodham1980"], entry_points=False)
    with pytest.raises(UserError, match="'photometric_sterio' is not a pbrbench task.*photometric_stereo"):
        plugin_registry(tasks, [f"photometric_sterio={plugin_file}:solve"], entry_points=False)


def test_a_plugin_that_fails_at_import_is_scored_as_failed_and_never_runs_here(tmp_path):
    broken = tmp_path / "broken.py"
    broken.write_text("import numpy\nimport sys\nsys.modules['pbrbench'].BROKEN = 1\n"
                      "raise RuntimeError('broken at import')\n")
    logs = []
    reg = plugin_registry({"photometric_stereo": TinyPS()}, [f"photometric_stereo={broken}:f"], entry_points=False,
                          time_limit=30.0, log=logs.append)
    import pbrbench

    assert not hasattr(pbrbench, "BROKEN")          # imported in the child only
    assert len(logs) == 1 and "failed to load (RuntimeError: broken at import)" in logs[0] and str(broken) in logs[0]
    alg = reg.get("photometric_stereo", "f")
    with pytest.raises(RuntimeError, match="broken at import"):
        alg(np.zeros((3, 2, 2)), np.eye(3))


# ----------------------------------------------------------------------------- scored in a run
def test_a_py_file_and_a_dotted_module_are_scored_beside_the_builtins(tmp_path, plugin_file, monkeypatch):
    pkg = tmp_path / "site" / "userpkg"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "ps.py").write_text(PLUGIN.replace('VERSION = "3"', 'VERSION = "0.9"'))
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    o = _run(tmp_path, [f"photometric_stereo={plugin_file}:solve", "photometric_stereo=userpkg.ps:chatty:dotted"])
    assert not o.errors
    sc = _scores(o)
    builtin = sc[("woodham1980", "normal_mean_deg")]
    for name in ("solve", "dotted"):
        assert sc[(name, "normal_mean_deg")] == pytest.approx(builtin, abs=0.01)   # normals rounded to 1e-4
        assert sc[(name, "coverage")] == 1.0 and (name, "failed") not in sc
    versions = {s["algorithm"]: s["algorithm_version"] for s in o.scores}
    import hashlib

    file_hash = hashlib.sha256(plugin_file.read_bytes()).hexdigest()[:10]   # the file's bytes
    assert versions["solve"] == f"3+{file_hash}" and versions["dotted"].startswith("0.9+")
    info = o.task_info["photometric_stereo"]
    assert info["algorithm_kinds"]["solve"] == "plugin"
    assert info["algorithm_origins"]["solve"] == f"--algorithm photometric_stereo={plugin_file.resolve()}:solve"
    html = o.report.read_text()
    assert 'data-algorithm="solve"' in html and 'data-algorithm="dotted"' in html
    assert "normals: solve" in (o.report.parent / "task-photometric_stereo.html").read_text()
    from pbrbench.bench.store import Store

    with Store(settings_for(tmp_path).store_path()) as st:
        cfg = st.get_run(o.run_id)["config"]
    assert cfg["algorithms"] == [f"photometric_stereo={plugin_file.resolve()}:solve",
                                 "photometric_stereo=userpkg.ps:chatty:dotted"]


def test_resume_reloads_the_stored_algorithm_specs(tmp_path, plugin_file, monkeypatch):
    task = TinyPS()
    task.fail_once = tmp_path / "flag"
    first = _run(tmp_path, [f"photometric_stereo={plugin_file}:solve"], task=task)
    assert first.errors and not first.scores
    monkeypatch.chdir(tmp_path)   # the stored spec holds the absolute path
    again = run_benchmark(RunConfig(resume=first.run_id), settings=settings_for(tmp_path),
                          tasks={task.name: task}, source=SphereSource(tmp_path / "cache"), log=lambda m: None)
    assert again.run_id == first.run_id and not again.errors
    assert _scores(again)[("solve", "coverage")] == 1.0


@pytest.mark.slow   # two plugins run to their time limit
def test_a_hanging_crashing_raising_or_malformed_plugin_fails_and_the_run_goes_on(tmp_path, plugin_file):
    names = ("hang", "sleepy", "die", "boom", "nans", "solve")
    # the limit covers solve's first call in the child started after `die`, which imports
    # pbrbench.infer (over 2 s on a loaded 2-core machine)
    o = _run(tmp_path, [f"photometric_stereo={plugin_file}:{n}" for n in names], limit=4.0)
    assert not o.errors
    sc = _scores(o)
    for n in names[:-1]:
        assert sc[(n, "failed")] == 1.0 and (n, "normal_mean_deg") not in sc
    assert sc[("solve", "coverage")] == 1.0 and sc[("woodham1980", "normal_mean_deg")] < 0.01
    secs = {s["algorithm"]: s["seconds"] for s in o.scores if s["metric"] == "failed"}
    assert 4.0 <= secs["hang"] < 30 and 4.0 <= secs["sleepy"] < 30
    html = o.report.read_text()
    assert html.count("ran past its time limit of 4 s") == 2
    assert "process died (exit status 3)" in html
    assert "MyError: a bug in the plugin" in html and "non-finite" in html


def test_without_a_time_limit_plugins_run_in_process(tmp_path, plugin_file):
    reg = plugin_registry({"photometric_stereo": TinyPS()}, [f"photometric_stereo={plugin_file}:solve"],
                          entry_points=False, time_limit=None)
    alg = reg.get("photometric_stereo", "solve")
    assert alg.time_limit is None and alg.kind == "plugin"
    gt, vec = ps_gt()
    imgs = gt.light_stack("direct").mean(-1).astype(float)
    assert alg(imgs, vec, mask=gt.mask)["normals"].shape == gt["normals"].shape


# ----------------------------------------------------------------------------- entry points
def _dist_info(site: Path, dist: str, entry_points: str, modules: dict[str, str]):
    for rel, body in modules.items():
        f = site / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(textwrap.dedent(body))
    di = site / f"{dist}-0.1.dist-info"
    di.mkdir(parents=True)
    (di / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    (di / "entry_points.txt").write_text(textwrap.dedent(entry_points))


REGISTER = '''
import numpy as np
from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980
from pbrbench.registry import algorithm

def _ls(images, lights, *, mask=None, scale=1.0):
    r = photometric_stereo_woodham1980(images, lights, mask=mask)
    return r.normals, r.albedo * scale

def register(registry):
    assert "photometric_stereo" in registry.tasks
    registry.add("photometric_stereo", "ep_register", _ls, version="2", options={"scale": 2.0})
    registry.add("sfs", "not_in_this_run", _ls)          # ignored: the task is not run

def direct(images, lights, *, mask=None):
    return _ls(images, lights, mask=mask)

@algorithm("photometric_stereo", "ep_marked", version="5")
def marked(images, lights, *, mask=None):
    return _ls(images, lights, mask=mask)
'''


def test_installed_entry_points_in_all_three_forms_and_a_broken_one_skipped(tmp_path, monkeypatch):
    site = tmp_path / "site"
    _dist_info(site, "userps", '''
        [pbrbench.algorithms]
        mine = userps_plugin:register
        photometric_stereo:ep_named = userps_plugin:direct
        marked = userps_plugin:marked
        broken = userps_missing_module:register
        ''', {"userps_plugin.py": REGISTER})
    monkeypatch.syspath_prepend(str(site))
    logs = []
    reg = plugin_registry({"photometric_stereo": TinyPS()}, entry_points=True, time_limit=30.0, log=logs.append)
    plugins = {a.name: a for a in reg.for_task("photometric_stereo", kinds=["plugin"])}
    assert set(plugins) == {"ep_register", "ep_named", "ep_marked"}
    assert plugins["ep_register"].full_version.startswith("2+") and plugins["ep_marked"].full_version.startswith("5+")
    assert plugins["ep_register"].options == {"scale": 2.0} and plugins["ep_register"].time_limit == 30.0
    assert plugins["ep_register"].origin == "entry point mine = userps_plugin:register (userps 0.1)"
    assert len(logs) == 1 and "broken" in logs[0] and "userps_missing_module" in logs[0]
    o = _run(tmp_path, limit=30.0)
    sc = _scores(o)
    for n in plugins:
        assert sc[(n, "coverage")] == 1.0
    assert sc[("ep_register", "albedo_rel_err_scaled")] == pytest.approx(sc[("woodham1980", "albedo_rel_err_scaled")])
    assert not {a for a, _ in sc} & {"not_in_this_run"}
    assert "ep_register" not in {a for a, _ in _scores(_run(tmp_path / "off", entry_points=False))}


def test_the_register_form_refuses_a_name_twice_and_needs_a_callable():
    reg = Registry([Algorithm("woodham1980", "photometric_stereo", len)])
    pr = PluginRegistry(reg, ["photometric_stereo"], origin="test", time_limit=None)
    with pytest.raises(ValueError, match="already registered"):
        pr.add("photometric_stereo", "woodham1980", abs)
    with pytest.raises(ValueError, match="must be a callable"):
        pr.add("photometric_stereo", "x", 3)
    assert pr.add("lightness", "y", abs) is None and pr.skipped


def _wheel(tmp_path) -> Path:
    """A wheel of a user's package (built by hand: no build backend needed) whose entry point
    registers one photometric-stereo algorithm."""
    whl = tmp_path / "userwheel-0.1-py3-none-any.whl"
    with zipfile.ZipFile(whl, "w") as z:
        z.writestr("userwheel/__init__.py", "")
        z.writestr("userwheel/ps.py", REGISTER)
        di = "userwheel-0.1.dist-info"
        z.writestr(f"{di}/METADATA", "Metadata-Version: 2.1\nName: userwheel\nVersion: 0.1\n")
        z.writestr(f"{di}/WHEEL", "Wheel-Version: 1.0\nGenerator: hand\nRoot-Is-Purelib: true\nTag: py3-none-any\n")
        z.writestr(f"{di}/entry_points.txt", "[pbrbench.algorithms]\nmine = userwheel.ps:register\n")
        z.writestr(f"{di}/RECORD", "")
    return whl


@pytest.mark.slow
def test_a_pip_installed_package_with_an_entry_point_is_scored_in_a_subprocess(tmp_path):
    target = tmp_path / "target"
    p = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--target", str(target),
                        str(_wheel(tmp_path))], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    script = textwrap.dedent(f'''
        from pathlib import Path
        from tests.test_plugins import _run, _scores
        o = _run(Path({str(tmp_path / "run")!r}), limit=60.0)
        sc = _scores(o)
        print("PLUGIN", sc[("ep_register", "coverage")], o.task_info["photometric_stereo"]["algorithm_origins"]["ep_register"])
        ''')
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(target), str(ROOT)]))
    q = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert q.returncode == 0, q.stderr[-3000:]
    assert "PLUGIN 1.0 entry point mine = userwheel.ps:register (userwheel 0.1)" in q.stdout


# ----------------------------------------------------------------------------- other processes
def test_a_plugin_file_travels_by_value_to_another_process(tmp_path, plugin_file):
    reg = plugin_registry({"photometric_stereo": TinyPS()}, [f"photometric_stereo={plugin_file}:solve"],
                          entry_points=False, time_limit=None)
    alg = reg.get("photometric_stereo", "solve")
    data = pickle.dumps(alg)
    plugin_file.unlink()          # the other process cannot read the file: it gets the function by value
    gt, vec = ps_gt()
    np.save(tmp_path / "imgs.npy", gt.light_stack("direct").mean(-1).astype(float))
    np.save(tmp_path / "mask.npy", gt.mask)
    np.save(tmp_path / "vec.npy", vec)
    (tmp_path / "alg.pkl").write_bytes(data)
    script = textwrap.dedent(f'''
        import pickle, numpy as np
        d = {str(tmp_path)!r}
        alg = pickle.load(open(d + "/alg.pkl", "rb"))
        out = alg(np.load(d + "/imgs.npy"), np.load(d + "/vec.npy"), mask=np.load(d + "/mask.npy"))
        print("VERSION", alg.full_version, alg.kind, out["normals"].shape)
        ''')
    q = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, timeout=300,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert q.returncode == 0, q.stderr[-3000:]
    assert f"VERSION {alg.full_version} plugin (40, 40, 3)" in q.stdout


@pytest.mark.slow
def test_plugins_run_on_dask_workers(tmp_path, plugin_file):
    pytest.importorskip("distributed")
    from pbrbench.bench.executors import DaskExecutor
    from pbrbench.settings import Settings

    ex = DaskExecutor(scheduler=None, workers=1, variant=None, settings=Settings.from_env())
    try:
        ex.client.run(lambda: sys.path.insert(0, str(ROOT)))
        task = TinyPS()
        o = run_benchmark(RunConfig(quality="draft", executor="dask", algorithm_time_limit=60.0,
                                    algorithms=[f"photometric_stereo={plugin_file}:solve",
                                                f"photometric_stereo={plugin_file}:boom"]),
                          settings=settings_for(tmp_path), tasks={task.name: task},
                          source=SphereSource(tmp_path / "cache"), executor=ex, log=lambda m: None)
    finally:
        ex.close()
    assert not o.errors, o.errors
    sc = _scores(o)
    assert sc[("solve", "coverage")] == 1.0 and sc[("boom", "failed")] == 1.0


def test_time_limit_must_be_positive():
    with pytest.raises(ValueError, match="time_limit"):
        Algorithm("a", "t", abs, time_limit=0)


def test_the_algorithm_marker_sets_task_name_and_version():
    @algorithm("sfs", "mine", version="4", smooth=0.5)
    def f(image, light, **kw):
        return kw

    assert (f.pbrbench_task, f.pbrbench_name, f.pbrbench_version, f.pbrbench_options) == ("sfs", "mine", "4", {"smooth": 0.5})
