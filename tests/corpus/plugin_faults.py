"""A corpus of plugin faults: a user's plugin that misbehaves at import, at registration or when
called, and the run's bookkeeping around it (the job cache, ``--resume``, the time limit per
job, processes left behind).

Every case runs a small benchmark (the photometric-stereo task on one synthetic sphere with four
sample groups, so the replicates run too: one job, no renderer) with the faulty plugin and returns
its problems (an empty list: handled): the run finished, the built-in scores equal those of the
same run without the plugin, the fault is one line naming the plugin, no traceback, and no
process of the run is left.  ``python -m tests.corpus.plugin_faults`` prints the outcome of every
case and ``N of M handled``; ``tests/corpus/test_plugin_corpus.py`` asserts each case.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LOAD_LIMIT = 4.0          # seconds to import and register a plugin (Settings.plugin_load_limit)

OK = '''
import numpy as np

def solve(images, lights, *, mask=None):
    k, h, w = images.shape
    g = np.linalg.lstsq(lights, images.reshape(k, -1), rcond=None)[0].T.reshape(h, w, 3)
    a = np.linalg.norm(g, axis=-1)
    return {"normals": g / np.maximum(a, 1e-12)[..., None], "albedo": a}
'''


def _task_and_source():
    from functools import partial

    from tests.fakes import SphereSource, TinyPS

    return TinyPS, partial(SphereSource, groups=True)


@contextlib.contextmanager
def _site(tmp: Path, entry_points: str, modules: dict[str, str]):
    """An installed distribution with ``entry_points`` (dist-info on a path put first on sys.path)."""
    site = tmp / "site"
    for rel, body in modules.items():
        (site / rel).parent.mkdir(parents=True, exist_ok=True)
        (site / rel).write_text(textwrap.dedent(body))
    di = site / "faulty-0.1.dist-info"
    di.mkdir(parents=True)
    (di / "METADATA").write_text("Metadata-Version: 2.1\nName: faulty\nVersion: 0.1\n")
    (di / "entry_points.txt").write_text("[pbrbench.algorithms]\n" + textwrap.dedent(entry_points))
    sys.path.insert(0, str(site))
    try:
        yield site
    finally:
        sys.path.remove(str(site))
        for m in [m for m in sys.modules if m.startswith("faulty_")]:
            del sys.modules[m]


def run(tmp: Path, specs=(), *, limit=30.0, entry_points=False, task=None, resume=None, logs=None):
    """One small benchmark; returns (outcome, log lines)."""
    from pbrbench.bench.run import RunConfig, run_benchmark
    from tests.fakes import settings_for

    TinyPS, GroupSource = _task_and_source()
    task = task or TinyPS()
    logs = [] if logs is None else logs
    cfg = RunConfig(quality="draft", algorithms=list(specs), algorithm_time_limit=limit, entry_points=entry_points,
                    resume=resume, report=False)
    o = run_benchmark(cfg, settings=settings_for(tmp).with_(plugin_load_limit=LOAD_LIMIT), tasks={task.name: task},
                      source=GroupSource(tmp / "cache"), log=logs.append)
    return o, logs


_REFERENCE: dict = {}


def builtin_scores(o) -> dict:
    names = _builtins()
    return {(s["algorithm"], s["metric"]): (s["value"], s.get("uncertainty")) for s in o.scores
            if s["algorithm"] in names}


def _builtins() -> set[str]:
    TinyPS, _ = _task_and_source()
    return {a.name for a in TinyPS().builtin_algorithms()}


def reference() -> dict:
    """The built-in scores of the run without a plugin (once per process)."""
    if not _REFERENCE:
        with tempfile.TemporaryDirectory() as d:
            o, _ = run(Path(d))
            _REFERENCE.update(builtin_scores(o))
    return _REFERENCE


def _same(a, b) -> bool:
    import math

    if a == b:
        return True
    return all((x == y) or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))
               for x, y in zip(a, b, strict=True))


def check(o, logs, *, plugin: str | None = None, failed: bool = True, line: str | None = None) -> list[str]:
    """The standard checks: the run finished, the built-ins as without the plugin, the plugin
    scored as failed (or not), ``line`` in exactly one log line, no traceback."""
    problems = []
    if o.errors:
        problems.append(f"job errors: {list(o.errors.values())[0][-300:]}")
    ref = reference()
    got = builtin_scores(o)
    changed = [k for k in ref if k not in got or not _same(ref[k], got[k])]
    if changed:
        problems.append(f"{len(changed)} of {len(ref)} built-in scores changed, e.g. {changed[0]}: "
                        f"{ref[changed[0]]} -> {got.get(changed[0])}")
    if plugin is not None:
        sc = {s["metric"]: s["value"] for s in o.scores if s["algorithm"] == plugin}
        if failed and sc.get("failed") != 1.0:
            problems.append(f"{plugin} not scored as failed: {sc}")
        if not failed and (sc.get("failed") or "normal_mean_deg" not in sc):
            problems.append(f"{plugin} not scored: {sc}")
    if line is not None:
        hits = [ln for ln in logs if line in ln]
        if len(hits) != 1:
            problems.append(f"{len(hits)} log lines with {line!r}: {logs}")
    if any("Traceback" in ln or "\n" in ln for ln in logs):
        problems.append(f"a traceback or a multi-line message: {logs}")
    return problems


def _file(tmp: Path, body: str, name="mine.py") -> Path:
    p = tmp / name
    p.write_text(textwrap.dedent(body))
    return p


# ----------------------------------------------------------------------------- at import (file)
def _at_import(statement: str):
    def case(tmp: Path) -> list[str]:
        p = _file(tmp, statement + "\n" + OK)
        t0 = time.perf_counter()
        o, logs = run(tmp, [f"photometric_stereo={p}:solve"])
        probs = check(o, logs, plugin="solve", line=str(p))
        if time.perf_counter() - t0 > 40:
            probs.append(f"took {time.perf_counter() - t0:.0f} s")
        return probs
    return case


def case_import_monkeypatch(tmp: Path) -> list[str]:
    """The plugin replaces pbrbench and NumPy functions when imported: only its own process."""
    p = _file(tmp, textwrap.dedent('''
        import numpy
        import pbrbench.tasks.photometric_stereo as T
        import pbrbench.metrics as M
        for mod in (T, M):
            for n in dir(mod):
                if callable(getattr(mod, n)) and not n.startswith("__") and "score" in n:
                    setattr(mod, n, lambda *a, **k: ({"normal_mean_deg": 99.0}, None))
        numpy.arccos = lambda x, *a, **k: numpy.zeros_like(x)
        numpy.linalg.lstsq = lambda *a, **k: (None,)
        ''') + OK.replace("np.linalg.lstsq(lights, images.reshape(k, -1), rcond=None)[0]",
                         "(np.linalg.pinv(lights) @ images.reshape(k, -1))"))
    o, logs = run(tmp, [f"photometric_stereo={p}:solve"])
    return check(o, logs, plugin="solve", failed=False)


# ----------------------------------------------------------------------------- at import / register (entry points)
def _entry(module_body: str, *, line: str = "plugin skipped: entry point bad"):
    def case(tmp: Path) -> list[str]:
        with _site(tmp, "bad = faulty_mod:register\nfine = faulty_ok:register\n",
                   {"faulty_mod.py": module_body,
                    "faulty_ok.py": OK + "\ndef register(r):\n    r.add('photometric_stereo', 'ep_fine', solve)\n"}):
            t0 = time.perf_counter()
            o, logs = run(tmp, entry_points=True)
        probs = check(o, logs, plugin="ep_fine", failed=False, line=line)
        if time.perf_counter() - t0 > 40:
            probs.append(f"took {time.perf_counter() - t0:.0f} s")
        return probs
    return case


REGISTER = OK + "\ndef register(registry):\n    STATEMENT\n    registry.add('photometric_stereo', 'ep_bad', solve)\n"


def _reg(statement: str) -> str:
    return REGISTER.replace("STATEMENT", statement)


# ----------------------------------------------------------------------------- when called
def case_mutates_inputs_isolated(tmp: Path) -> list[str]:
    p = _file(tmp, OK + '''
def wreck(images, lights, *, mask=None):
    out = solve(images, lights, mask=mask)
    images *= 0.0; lights[...] = 0.0
    if mask is not None:
        mask[...] = False
    return out
''')
    o, logs = run(tmp, [f"photometric_stereo={p}:wreck"])
    return check(o, logs, plugin="wreck", failed=False)


def case_mutates_inputs_in_process(tmp: Path) -> list[str]:
    p = _file(tmp, OK + '''
def wreck(images, lights, *, mask=None):
    out = solve(images, lights, mask=mask)
    images *= 0.0; lights[...] = 0.0
    if mask is not None:
        mask[...] = False
    return out
''')
    o, logs = run(tmp, [f"photometric_stereo={p}:wreck"], limit=None)
    return check(o, logs, plugin="wreck", failed=False)


def case_sys_exit_in_call_in_process(tmp: Path) -> list[str]:
    p = _file(tmp, OK + "\nimport sys\ndef bye(images, lights, *, mask=None):\n    sys.exit(3)\n")
    try:
        o, logs = run(tmp, [f"photometric_stereo={p}:bye"], limit=None)
    except SystemExit as e:
        return [f"the run ended: SystemExit({e.code})"]
    return check(o, logs, plugin="bye")


def case_sleep_at_import_in_process(tmp: Path) -> list[str]:
    """In-process mode: the import is still probed in a child, with the load limit."""
    p = _file(tmp, "import time\ntime.sleep(3600)\n" + OK)
    o, logs = run(tmp, [f"photometric_stereo={p}:solve"], limit=None)
    return check(o, logs, plugin="solve", line=str(p))


def case_one_budget_per_job(tmp: Path) -> list[str]:
    """A hung plugin costs its limit once per job, not once per call (5 calls with the replicates)."""
    p = _file(tmp, OK + "\ndef hang(images, lights, *, mask=None):\n    while True:\n        pass\n")
    t0 = time.perf_counter()
    o, logs = run(tmp, [f"photometric_stereo={p}:hang"], limit=3.0)
    wall = time.perf_counter() - t0
    probs = check(o, logs, plugin="hang")
    if wall > 3.0 * 2.5:
        probs.append(f"the run took {wall:.1f} s with a 3 s limit: the limit is not per job")
    return probs


def case_cache_across_limits(tmp: Path) -> list[str]:
    """A timeout at a 1 s limit is not served from the job cache after the limit is raised."""
    p = _file(tmp, OK + '''
import time
_first = [True]
def slow(images, lights, *, mask=None):
    if _first[0]:
        _first[0] = False
        time.sleep(2.5)
    return solve(images, lights, mask=mask)
''')
    o1, logs1 = run(tmp, [f"photometric_stereo={p}:slow"], limit=1.0)
    probs = check(o1, logs1, plugin="slow")
    o2, logs2 = run(tmp, [f"photometric_stereo={p}:slow"], limit=30.0)
    if o2.n_cached:
        probs.append("the job came from the cache of the 1 s run")
    return probs + check(o2, logs2, plugin="slow", failed=False)


def case_resume_after_edit(tmp: Path) -> list[str]:
    from pbrbench.errors import UserError

    TinyPS, _ = _task_and_source()
    task = TinyPS()
    task.fail_once = tmp / "flag"
    p = _file(tmp, OK)
    first, _ = run(tmp, [f"photometric_stereo={p}:solve"], task=task)
    if not first.errors:
        return ["the first run did not fail as the case needs"]
    p.write_text(OK.replace("1e-12", "1e-9"))
    try:
        run(tmp, task=task, resume=first.run_id)
    except UserError as e:
        msg = str(e)
        if "\n" in msg or "changed since the run began" not in msg or "photometric_stereo/solve" not in msg:
            return [f"unclear refusal: {msg}"]
        return []
    return ["--resume mixed two versions of the plugin without a word"]


def case_bad_task_in_register(tmp: Path) -> list[str]:
    with _site(tmp, "typo = faulty_typo:register\n",
               {"faulty_typo.py": OK + "\ndef register(r):\n    r.add('photometric_sterio', 'typo', solve)\n"}):
        o, logs = run(tmp, entry_points=True)
    return check(o, logs, line="'photometric_sterio' -- not a pbrbench task")


def case_bad_task_in_spec(tmp: Path) -> list[str]:
    from pbrbench.errors import UserError

    p = _file(tmp, OK)
    try:
        run(tmp, [f"photometric_sterio={p}:solve"])
    except UserError as e:
        return [] if "'photometric_sterio' is not a pbrbench task" in str(e) and "\n" not in str(e) else [str(e)]
    return ["a mistyped task was accepted"]


# ----------------------------------------------------------------------------- kill -9 of the run
KILL_SCRIPT = '''
import sys
from pathlib import Path
from tests.corpus.plugin_faults import run
run(Path(sys.argv[1]), [f"photometric_stereo={sys.argv[2]}:hang"], limit=600.0)
'''


def _children(pid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if ppid == pid:
                out.append(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def case_hang_then_kill_9(tmp: Path) -> list[str]:
    if not Path("/proc").is_dir():
        return []
    p = _file(tmp, OK + "\ndef hang(images, lights, *, mask=None):\n    while True:\n        pass\n")
    proc = subprocess.Popen([sys.executable, "-c", KILL_SCRIPT, str(tmp / "run"), str(p)], cwd=ROOT,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        kids: list[int] = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            kids = _children(proc.pid)
            if kids and (tmp / "run" / "reports").exists():
                time.sleep(1.0)       # the plugin's call is under way
                kids = _children(proc.pid)
                break
            time.sleep(0.2)
        if not kids:
            return [f"no plugin process started (run exit {proc.poll()})"]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(_alive(k) for k in kids):
            time.sleep(0.1)
        left = [k for k in kids if _alive(k)]
        for k in left:
            os.kill(k, signal.SIGKILL)
        return [f"processes left after kill -9 of the run: {left}"] if left else []
    finally:
        if proc.poll() is None:
            proc.kill()


CASES = {
    "import: monkeypatch of pbrbench and NumPy": case_import_monkeypatch,
    "import: time.sleep": _at_import("import time\ntime.sleep(3600)"),
    "import: sys.exit": _at_import("import sys\nsys.exit(4)"),
    "import: os._exit": _at_import("import os\nos._exit(5)"),
    "import: raise": _at_import("raise RuntimeError('broken at import')"),
    "import: sleep, in-process mode": case_sleep_at_import_in_process,
    "entry point import: time.sleep": _entry("import time\ntime.sleep(3600)\n" + _reg("pass")),
    "entry point import: os._exit": _entry("import os\nos._exit(5)\n" + _reg("pass")),
    "register: time.sleep": _entry(_reg("import time; time.sleep(3600)")),
    "register: sys.exit": _entry(_reg("import sys; sys.exit(4)")),
    "register: os._exit": _entry(_reg("import os; os._exit(5)")),
    "register: raise": _entry(_reg("raise ValueError('bad register')")),
    "call: mutates its inputs (isolated)": case_mutates_inputs_isolated,
    "call: mutates its inputs (in-process)": case_mutates_inputs_in_process,
    "call: sys.exit (in-process)": case_sys_exit_in_call_in_process,
    "call: hangs; one limit per job": case_one_budget_per_job,
    "call: hangs; kill -9 of the run": case_hang_then_kill_9,
    "job cache: a timeout is not replayed under a higher limit": case_cache_across_limits,
    "--resume after the plugin file changed": case_resume_after_edit,
    "register: mistyped task name": case_bad_task_in_register,
    "--algorithm: mistyped task name": case_bad_task_in_spec,
}


def main() -> int:
    handled = 0
    for name, case in CASES.items():
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            try:
                probs = case(Path(d))
            except Exception as e:  # noqa: BLE001 - a case that crashes is a case not handled
                probs = [f"{type(e).__name__}: {e}"]
            dt = time.perf_counter() - t0
        handled += not probs
        print(f"{'handled' if not probs else 'NOT HANDLED'}  {name}  ({dt:.1f} s)" + (f": {probs[0]}" if probs else ""))
    print(f"{handled} of {len(CASES)} handled")
    return 0 if handled == len(CASES) else 1


if __name__ == "__main__":
    sys.exit(main())
