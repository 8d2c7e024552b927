"""Measure how the command line treats the corpus: ``python -m tests.corpus.measure scenes [SRC]``.

``SRC`` is the source tree to measure (default: this checkout), so the same corpus can be run
against an older revision (``git worktree add /tmp/before REV``).  Every scene file of
``tests/corpus/scenes`` is rendered by ``pbrbench render FILE --quality draft`` in a fresh
subprocess with its own cache and output directory; the outcome is one of

- ``one_line``: exit 1, one line on stderr, no traceback, the line names the file;
- ``one_line_expected``: the same, and the line holds every ``# expect:`` substring of the file;
- ``traceback``: a Python traceback reached the user;
- ``accepted`` / ``accepted_black``: exit 0 (``_black``: the ground truth's radiance is all zero);
- ``timeout``: still running after the time limit (a job far too large started without warning);
- ``other``: anything else (another exit code, several lines).

``python -m tests.corpus.measure faults|cli [SRC]`` does the same for the disk faults and the
command-line misuse of ``tests/corpus/test_faults_and_cli.py``.  What several of their cases start
from (a results store holding one run, a warm render cache, a draft benchmark's scenes and cache)
is built once, on first use, by :class:`Shared` and copied into each case's directory.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import traceback
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def expectations(path: Path) -> dict:
    exp, stage, cls = [], "load", ""
    with open(path, "rb") as f:
        for raw in f:
            line = raw.decode("utf-8", "replace").strip()
            if not line.startswith("#"):
                break
            k, _, v = line[1:].partition(":")
            k, v = k.strip(), v.strip()
            if k == "expect":
                exp.append(v)
            elif k == "stage":
                stage = v
            elif k == "class":
                cls = v
    return {"expect": exp, "stage": stage, "class": cls}


def child_env(src: Path, env: dict | None = None) -> dict:
    """The environment of a pbrbench child process: this one's without PBRBENCH_* settings and
    without DRJIT_LIBLLVM_PATH (set in this process by its own variant choice, not by the user; a
    case sets it itself), pbrbench imported from ``src``, then ``env``.  PYTHONSAFEPATH: the
    child's working directory (the shared temporary directory, where any ``timeit.py`` may lie)
    is not put first on ``sys.path``."""
    e = {k: v for k, v in os.environ.items() if not k.startswith("PBRBENCH_") and k != "DRJIT_LIBLLVM_PATH"}
    e.update(PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1", PBRBENCH_PROGRESS="0", PYTHONSAFEPATH="1")
    e.update(env or {})
    return e


def run_cli(args: list[str], *, src: Path = ROOT, env: dict | None = None, timeout: float = 60, cwd=None):
    e = child_env(src, env)
    # cwd outside any checkout: ``python -m`` puts the working directory first on sys.path
    cwd = cwd or tempfile.gettempdir()
    try:
        r = subprocess.run([sys.executable, "-m", "pbrbench", *args], capture_output=True, text=True,
                           timeout=timeout, env=e, cwd=cwd)
    except subprocess.TimeoutExpired:
        return None
    return r


def classify_render(path: Path, *, src: Path = ROOT, timeout: float = 60) -> tuple[str, str]:
    info = expectations(path)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sub" / "out"
        r = run_cli(["render", str(path), "--quality", "draft", "--cache", str(Path(tmp) / "cache"), "--out", str(out),
                     "--no-previews"], src=src, timeout=timeout)
        if r is None:
            return "timeout", ""
        err = r.stderr.strip()
        lines = [ln for ln in err.splitlines() if ln.strip()]
        escaped = [p for p in (Path(tmp) / "sub").iterdir() if p.name != "out"] if (Path(tmp) / "sub").exists() else []
        if "Traceback" in err:
            return "traceback", lines[-1] if lines else ""
        if r.returncode == 0:
            black = False
            for meta in out.glob("**/gt.json"):
                try:
                    m = json.loads(meta.read_text())
                    black |= m.get("noise", {}).get("radiance_rel_sd_rms", 1) == 0
                except ValueError:
                    pass
            if escaped:
                return "accepted_escaped", f"wrote {[p.name for p in escaped]} outside --out"
            return ("accepted_black" if black else "accepted"), r.stdout.strip()[-200:]
        if r.returncode == 1 and len(lines) == 1 and str(path) in lines[0]:
            ok = all(x in lines[0] for x in info["expect"])
            return ("one_line_expected" if ok else "one_line"), lines[0]
        return "other", f"rc={r.returncode} " + " // ".join(lines[-3:])


def measure_scenes(src: Path = ROOT, verbose: bool = False) -> Counter:
    c: Counter = Counter()
    for p in sorted((HERE / "scenes").glob("*.toml")):
        outcome, msg = classify_render(p, src=src)
        c[outcome] += 1
        if verbose:
            print(f"{p.name:50s} {outcome:18s} {msg[:240]}", flush=True)
    return c




# ----------------------------------------------------------------------------- disk faults
TINY = ('name = "tiny"\ndescription = "a lit sphere"\n[camera]\nhalf_width = 1.1\n[render]\nresolution = 16\nspp = 4\n'
        '[[shapes]]\ntype = "sphere"\n[[lights]]\ntype = "directional"\ndirection = [0.0, 0.0, 1.0]\nirradiance = 3.0\n')
TINY_HF = TINY.replace('[[shapes]]\ntype = "sphere"\n', '[[shapes]]\ntype = "heightfield"\nsurface = "sphere"\nresolution = 16\n')
# the benchmark-run cases: the draft lightness task on these families alone (PBRBENCH_SCENES: a
# directory holding only their library files), every render already in a cache the cases only read
RUN_FAMILIES = ("mondrian_grey",)


def _faulty(kind, under, budget=None):
    # run as a script (not -m), so the fault injector is this checkout's while pbrbench is src's
    return [sys.executable, str(HERE / "faults.py"), kind, str(under)] + ([str(budget)] if budget is not None else []) + ["--"]


def _run(cmd, src, env=None, timeout=300, cwd=None):
    e = child_env(src, env)
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=e, cwd=cwd or tempfile.gettempdir())
    except subprocess.TimeoutExpired:
        return None


def _this_checkout(src: Path) -> bool:
    """Whether ``src`` is the source tree of the pbrbench this process imported."""
    import pbrbench

    return Path(pbrbench.__file__).resolve().parents[1] == Path(src).resolve()


class Shared:
    """What several cases start from, built once (on its first use) below ``root`` with the
    command line of ``src``, and copied into a case's own directory: a results store holding one
    run (``tests.fakes.fake_run``), a render cache holding TINY, an ``--out`` holding TINY's
    render, and a draft lightness benchmark (:data:`RUN_FAMILIES`: its scene directory and its warm
    cache).  The test session makes one (a session-scoped fixture); ``measure`` makes its own."""

    def __init__(self, root: Path, src: Path = ROOT):
        self.root, self.src = Path(root), Path(src)
        self._built: dict[str, Path | AssertionError] = {}

    def _once(self, key: str, build) -> Path:
        if key not in self._built:
            d = self.root / key
            shutil.rmtree(d, ignore_errors=True)
            d.mkdir(parents=True)
            try:
                build(d)
                self._built[key] = d
            except AssertionError as e:   # said by every case that needs it, built only once
                self._built[key] = e
        got = self._built[key]
        if isinstance(got, AssertionError):
            raise AssertionError(f"shared {key}: {got}")
        return got

    def _render(self, d: Path, args: list[str]):
        (d / "s.toml").write_text(TINY)
        r = _run([sys.executable, "-m", "pbrbench", "render", str(d / "s.toml"), "--quality", "draft", "--no-previews",
                  *args], self.src)
        assert r is not None and r.returncode == 0, r.stderr if r else "timeout"

    def store(self, dest: Path) -> Path:
        """A copy of the store with one fake run: ``dest/h.sqlite`` (the run made in this process
        where ``src`` is the pbrbench it imported)."""
        def build(d):
            if _this_checkout(self.src):
                from tests.fakes import fake_run

                with child_environment(cwd=d):
                    fake_run(d)
                return
            r = _run([sys.executable, "-c", "import sys; from pathlib import Path; from tests.fakes import fake_run; "
                      "fake_run(Path(sys.argv[1]))", str(d)], self.src)
            assert r is not None and r.returncode == 0, r.stderr if r else "timeout"
        d = self._once("store", build)
        dest.mkdir(parents=True, exist_ok=True)
        for f in d.glob("h.sqlite*"):
            shutil.copy2(f, dest / f.name)
        return dest / "h.sqlite"

    def cache(self, dest: Path) -> Path:
        """A copy of a render cache holding TINY at draft quality."""
        d = self._once("cache", lambda d: self._render(d, ["--cache", str(d / "cache")]))
        shutil.copytree(d / "cache", dest)
        return dest

    def exr_size(self) -> int:
        """The size of TINY's gt.exr in the cache."""
        d = self._once("cache", lambda d: self._render(d, ["--cache", str(d / "cache")]))
        return (next((d / "cache" / "gt").glob("*/*")) / "gt.exr").stat().st_size

    def out(self, dest: Path) -> Path:
        """A copy of an ``--out`` directory holding TINY's render (no previews)."""
        def build(d):
            self.cache(d / "cache")
            self._render(d, ["--cache", str(d / "cache"), "--out", str(d / "out")])
        d = self._once("out", build)
        shutil.copytree(d / "out", dest)
        return dest

    def run(self) -> tuple[Path, Path]:
        """(scene directory, render cache) of a draft lightness benchmark on :data:`RUN_FAMILIES`:
        every render it needs is in the cache (one complete run made them)."""
        def build(d):
            (d / "scenes").mkdir()
            for fam in RUN_FAMILIES:
                shutil.copy2(self.src / "scenes" / f"{fam}.toml", d / "scenes")
            r = _run([sys.executable, "-m", "pbrbench", "run", "--tasks", "lightness", "--quality", "draft",
                      "--cache", str(d / "cache"), "--store", str(d / "h.sqlite"), "--out", str(d / "out"),
                      "--no-report"], self.src, {"PBRBENCH_SCENES": str(d / "scenes")}, cwd=d)
            assert r is not None and r.returncode == 0, r.stderr if r else "timeout"
        d = self._once("run", build)
        return d / "scenes", d / "cache"


_SHARED: dict[Path, tuple] = {}


def shared_for(src: Path) -> Shared:
    """This process's Shared for ``src`` (in a temporary directory removed at exit)."""
    if src not in _SHARED:
        t = tempfile.TemporaryDirectory(prefix="pbrbench-corpus-")
        _SHARED[src] = (t, Shared(Path(t.name), src))
    return _SHARED[src][1]


def _entries(cache: Path) -> int:
    return len([p for p in (cache / "gt").glob("*/*") if p.is_dir() and not p.name.startswith(".tmp-")])


def _stale(cache: Path) -> int:
    return len(list((cache / "gt").glob("*/.tmp-*")))


def _pngs_ok(d: Path) -> bool:
    from PIL import Image

    for p in d.rglob("*.png"):
        if p.name.startswith(".tmp-"):
            return False
        try:
            with Image.open(p) as im:
                im.load()
        except Exception:  # noqa: BLE001
            return False
    return True


def _store_status(store: Path, src: Path) -> list[str]:
    import sqlite3

    try:
        con = sqlite3.connect(f"file:{store}?mode=ro", uri=True)
        rows = [r[0] for r in con.execute("SELECT status FROM runs ORDER BY time")]
        ok = con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        con.close()
        return rows + ([] if ok else ["CORRUPT"])
    except sqlite3.Error as e:
        return [f"unreadable: {e}"]


def fault_cases():
    """(name, function(tmp, src, shared) -> (command, env, expected rc, path the message must name,
    check(result) -> note)); ``shared``: a :class:`Shared`."""
    cases = []

    def render_base(tmp, src):
        (tmp / "s.toml").write_text(TINY)
        return ["render", str(tmp / "s.toml"), "--quality", "draft", "--no-previews"]

    def cache_fault(kind, budget=None):
        def make(tmp, src, shared):
            cache = tmp / "cache"
            cache.mkdir()
            b = budget
            if budget == "after_exr":  # room for the EXR, not for gt.json
                b = shared.exr_size() + 50
            cmd = _faulty(kind, cache, b) + render_base(tmp, src) + ["--cache", str(cache)]
            return cmd, None, 1, cache, lambda r: "" if _entries(cache) == 0 and _stale(cache) == 0 else \
                f"cache left {_entries(cache)} entries, {_stale(cache)} temporaries"
        return make

    cases += [("cache read-only", cache_fault("readonly")), ("cache permission denied", cache_fault("denied")),
              ("cache full during the EXR", cache_fault("full", 0)), ("cache full during gt.json", cache_fault("full", "after_exr"))]

    def cache_is_file(tmp, src, shared):
        (tmp / "cache").write_text("x")
        return [sys.executable, "-m", "pbrbench"] + render_base(tmp, src) + ["--cache", str(tmp / "cache")], None, 1, tmp / "cache", \
            lambda r: ""

    def cache_gt_is_file(tmp, src, shared):
        (tmp / "cache").mkdir()
        (tmp / "cache" / "gt").write_text("x")
        return [sys.executable, "-m", "pbrbench"] + render_base(tmp, src) + ["--cache", str(tmp / "cache")], None, 1, tmp / "cache", \
            lambda r: ""

    cases += [("cache root is a file", cache_is_file), ("cache/gt is a file", cache_gt_is_file)]

    def warm(tmp, shared):   # TINY in the case's cache (a copy of the shared one)
        return shared.cache(tmp / "cache")

    def out_fault(kind, budget=None, previews=False, previous=False):
        def make(tmp, src, shared):
            cache = warm(tmp, shared)
            out = tmp / "out"
            old = None
            if previous:   # TINY rendered into --out before
                shared.out(out)
                old = (out / "tiny" / "gt.exr").read_bytes()
            else:
                out.mkdir()
            args = render_base(tmp, src) + ["--cache", str(cache), "--out", str(out)]
            if previews:
                args.remove("--no-previews")
            cmd = _faulty(kind, out, budget) + args

            def check(r):
                exr = out / "tiny" / "gt.exr"
                if previous:
                    return "" if exr.read_bytes() == old else "the previous gt.exr was damaged"
                leftovers = [p.name for p in out.rglob(".tmp-*")]
                if leftovers:
                    return f"temporaries left: {leftovers}"
                if exr.exists() and exr.stat().st_size != (next((cache / "gt").glob("*/*")) / "gt.exr").stat().st_size:
                    return "a truncated gt.exr is left under its final name"
                if not _pngs_ok(out):
                    return "a damaged PNG is left"
                return ""
            return cmd, None, 1, out, check
        return make

    cases += [("--out read-only", out_fault("readonly")), ("--out permission denied", out_fault("denied")),
              ("--out full during gt.exr", out_fault("full", 1000)),
              ("--out full during the previews", out_fault("full", 60000, previews=True)),
              ("--out full over a previous render", out_fault("full", 1000, previous=True))]

    def out_is_file(tmp, src, shared):
        warm(tmp, shared)
        (tmp / "out").write_text("x")
        return [sys.executable, "-m", "pbrbench"] + render_base(tmp, src) + ["--cache", str(tmp / "cache"), "--out", str(tmp / "out")], \
            None, 1, tmp / "out", lambda r: ""

    def out_scene_is_file(tmp, src, shared):
        warm(tmp, shared)
        (tmp / "out").mkdir()
        (tmp / "out" / "tiny").write_text("x")
        return [sys.executable, "-m", "pbrbench"] + render_base(tmp, src) + ["--cache", str(tmp / "cache"), "--out", str(tmp / "out")], \
            None, 1, tmp / "out", lambda r: ""

    cases += [("--out is a file", out_is_file), ("--out/<scene> is a file", out_scene_is_file)]

    # ---- the results store
    def store_read(kind, command):
        def make(tmp, src, shared):
            sdir = tmp / "sdir"
            store = shared.store(sdir)
            args = {"history": ["history"], "report": ["report", "--out", str(tmp / "rep")],
                    "compare": ["compare", "latest", "latest"]}[command]
            return _faulty(kind, sdir) + args + ["--store", str(store)], None, 0, None, \
                lambda r: "" if r.stdout.strip() else "printed nothing"
        return make

    cases += [("history on a read-only store", store_read("readonly", "history")),
              ("report on a read-only store", store_read("readonly", "report")),
              ("compare on a read-only store", store_read("readonly", "compare")),
              ("history on a store without write permission", store_read("denied", "history"))]

    def store_broken(what):
        def make(tmp, src, shared):
            p = tmp / "h.sqlite"
            if what == "directory":
                p.mkdir()
            elif what == "text":
                p.write_text("this is not a database\n" * 100)
            else:
                import sqlite3
                con = sqlite3.connect(p)
                con.execute("CREATE TABLE people (name TEXT)")
                con.commit()
                con.close()
            return [sys.executable, "-m", "pbrbench", "history", "--store", str(p)], None, 1, p, lambda r: ""
        return make

    cases += [("store is a directory", store_broken("directory")), ("store is a text file", store_broken("text")),
              ("store is another SQLite database", store_broken("foreign"))]

    def report_out_readonly(tmp, src, shared):
        store = shared.store(tmp)
        rep = tmp / "rep"
        rep.mkdir()
        return _faulty("readonly", rep) + ["report", "--store", str(store), "--out", str(rep)], None, 1, rep, lambda r: ""

    cases.append(("report with a read-only --out", report_out_readonly))

    # ---- a benchmark run (draft lightness on RUN_FAMILIES: every render is in the shared cache, read only)
    def run_fault(kind, where, budget=None, report=False):
        def make(tmp, src, shared):
            scenes, shared_cache = shared.run()
            env = {"PBRBENCH_SCENES": str(scenes)}
            sdir, out = tmp / "sdir", tmp / "out"
            sdir.mkdir()
            out.mkdir()
            store = sdir / "h.sqlite"
            if where == "store":
                _run([sys.executable, "-m", "pbrbench", "history", "--store", str(store)], src)
            args = ["run", "--tasks", "lightness", "--quality", "draft", "--cache", str(shared_cache), "--no-report",
                    "--store", str(store), "--out", str(out)]
            if report:
                args.remove("--no-report")
            under = sdir if where == "store" else out
            if kind == "full" and where == "store":
                # a store with one complete run, then the disk fills during the next
                r = _run([sys.executable, "-m", "pbrbench"] + args, src, env)
                assert r is not None and r.returncode == 0, r.stderr if r else "timeout"

            def check(r):
                st = _store_status(store, src) if store.exists() else []
                if any(s.startswith("unreadable") or s == "CORRUPT" for s in st):
                    return f"store damaged: {st}"
                if where == "out" and kind != "full" and len(st) > (0 if not store.exists() else 0):
                    return f"a run was created: {st}"
                if where == "out" and kind == "full":
                    if st and st[-1] == "complete":
                        return "the run is complete although its report could not be written"
                    sj = list(out.glob("*/scores.json"))
                    for p in sj:
                        try:
                            json.loads(p.read_text())
                        except ValueError:
                            return "a truncated scores.json is left"
                return ""
            return _faulty(kind, under, budget) + args, env, 1, under, check
        return make

    cases += [("run with a read-only store directory", run_fault("readonly", "store")),
              ("run with a full store", run_fault("full", "store", 3)),
              ("run with a read-only --out", run_fault("readonly", "out")),
              ("run with --out full during the report", run_fault("full", "out", 4000, report=True))]

    # ---- scratch and cache maintenance
    def scratch_full(tmp, src, shared):
        (tmp / "s.toml").write_text(TINY_HF)
        scratch = tmp / "scratchtmp"
        scratch.mkdir()
        return _faulty("full", scratch, 0) + ["render", str(tmp / "s.toml"), "--quality", "draft", "--no-previews",
                                               "--cache", str(tmp / "cache")], {"TMPDIR": str(scratch)}, 1, scratch, lambda r: ""

    def clear_readonly(tmp, src, shared):
        cache = warm(tmp, shared)
        return _faulty("readonly", cache) + ["cache", "clear", "--cache", str(cache)], None, 1, cache, \
            lambda r: "" if _entries(cache) == 1 else "the entry vanished"

    cases += [("scratch directory full (heightfield mesh)", scratch_full),
              ("cache clear on a read-only cache", clear_readonly)]
    return cases


def classify_fault(name, make, src: Path, shared: Shared | None = None) -> tuple[str, str]:
    shared = shared or shared_for(src)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        try:
            cmd, env, want_rc, path, check = make(tmp, src, shared)
        except AssertionError as e:
            return "setup_failed", str(e)[-200:]
        work = tmp / "cwd"
        work.mkdir()
        r = _run(cmd, src, env, cwd=work)
        if r is None:
            return "timeout", ""
        err = r.stderr.strip()
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("pbrbench: no CUDA")]
        note = check(r)
        if "Traceback" in err:
            return "traceback", (lines[-1] if lines else "")[:200]
        if r.returncode != want_rc:
            return "other", f"rc={r.returncode} (want {want_rc}) " + " // ".join(lines[-2:])[:200]
        if want_rc == 1:
            errs = [ln for ln in lines if "error" in ln]
            if len(errs) != 1 or (path is not None and str(path) not in errs[0]):
                return "other", " // ".join(lines[-3:])[:240]
        if note:
            return "dirty", note
        return "clean", (lines[-1][:200] if lines else "") if want_rc else "ok"


def measure_faults(src: Path = ROOT, verbose: bool = False) -> Counter:
    c: Counter = Counter()
    for name, make in fault_cases():
        outcome, msg = classify_fault(name, make, src)
        c[outcome] += 1
        if verbose:
            print(f"{name:52s} {outcome:10s} {msg}", flush=True)
    return c


# ----------------------------------------------------------------------------- command-line misuse
ESC_SCENE = TINY.replace('description = "a lit sphere"', 'description = "red \\u001b[31mALERT\\u001b[0m \\u001b]0;title\\u0007 \\u001b[2J"')


def cli_cases():
    """(name, function(tmp, src, shared) -> (args, env, expected rc, substring the stderr line must
    hold or None)); ``shared``: a :class:`Shared`.  A function's ``env`` is the environment its
    case sets (None: none)."""
    c = []

    def simple(args, rc=1, want=None, env=None):
        def make(tmp, src, shared):
            return args, env, rc, want
        make.env = env
        return make

    def with_store(args, rc=1, want=None):
        def make(tmp, src, shared):
            shared.store(tmp)
            return [a.replace("STORE", str(tmp / "h.sqlite")).replace("TMP", str(tmp)) for a in args], None, rc, want
        return make

    def with_scene(args, rc=1, want=None, env=None, text=TINY):
        def make(tmp, src, shared):
            (tmp / "s.toml").write_text(text)
            e = {k: v.replace("TMP", str(tmp)) for k, v in (env or {}).items()}
            return [a.replace("SCENE", str(tmp / "s.toml")).replace("TMP", str(tmp)) for a in args], e, rc, want
        make.env = env
        return make

    c += [
        ("no command", simple([], 1)),
        ("unknown command", simple(["frobnicate"], 1, "invalid choice")),
        ("unknown option", simple(["render", "--bogus"], 1, "--bogus")),
        ("misspelt global option", simple(["--versionn"], 1, "--versionn")),
        ("bad --quality choice", simple(["render", "x", "--quality", "ultra"], 1, "ultra")),
        ("option without its value", simple(["run", "--tasks"], 1, "--tasks")),
        ("--workers not a number", simple(["run", "--workers", "abc"], 1, "--workers")),
        ("--workers 0", simple(["run", "--workers", "0"], 1, "--workers")),
        ("--workers negative", simple(["run", "--executor", "dask", "--workers", "-2"], 1, "--workers")),
        ("--seed not a number", simple(["run", "--seed", "x"], 1, "--seed")),
        ("--seed negative", simple(["run", "--seed", "-1"], 1, "--seed")),
        ("--limit not a number", simple(["history", "--limit", "x"], 1, "--limit")),
        ("compare with one run", simple(["compare", "onlyone"], 1, "run_b")),
        ("cache without action", simple(["cache"], 1, "action")),
        ("cache bad action", simple(["cache", "wipe"], 1, "wipe")),
        ("history bad --quality", simple(["history", "--quality", "ultra"], 1, "ultra")),
        ("render nothing", simple(["render"], 1, "SCENE")),
        ("render unknown scene", simple(["render", "nosuchscene"], 1, "nosuchscene")),
        ("render misspelt scene", simple(["render", "sphere_5light"], 1, "did you mean")),
        ("render missing file", simple(["render", "/nonexistent/x.toml"], 1, "/nonexistent/x.toml")),
        ("render a directory", simple(["render", "/tmp/"], 1, "directory")),
        ("render --all with names", simple(["render", "--all", "sphere_5lights"], 1, "--all")),
        ("run unknown task", simple(["run", "--tasks", "nosuchtask"], 1, "nosuchtask")),
        ("--workers without dask", simple(["run", "--workers", "2"], 1, "--workers")),
        ("--scheduler without dask", simple(["run", "--scheduler", "tcp://x:1"], 1, "--scheduler")),
        ("empty --cache", simple(["cache", "info", "--cache", ""], 1, "--cache")),
        ("empty --store", simple(["history", "--store", ""], 1, "--store")),
        ("missing store", simple(["history", "--store", "/nonexistent/h.sqlite"], 1, "/nonexistent/h.sqlite")),
        ("validate unknown check", simple(["validate", "--checks", "nosuch"], 1, "nosuch")),
        ("perf unknown area", simple(["perf", "nosuch", "--no-store"], 1, "nosuch")),
        ("cache info on a file", simple(["cache", "info", "--cache", "/etc/hostname"], 1, "/etc/hostname")),
        ("PBRBENCH_WORKER_THREADS not a number", simple(["run", "--tasks", "lightness"], 1, "PBRBENCH_WORKER_THREADS",
                                                         {"PBRBENCH_WORKER_THREADS": "abc"})),
        ("PBRBENCH_SCENES missing", simple(["scenes"], 1, "/nonexistent", {"PBRBENCH_SCENES": "/nonexistent"})),
        ("PBRBENCH_VARIANT unknown", with_scene(["render", "SCENE", "--quality", "draft", "--cache", "TMP/c"], 1, "foo_rgb",
                                                {"PBRBENCH_VARIANT": "foo_rgb"})),
        ("render --variant unknown", with_scene(["render", "SCENE", "--quality", "draft", "--cache", "TMP/c",
                                                 "--variant", "foo_rgb"], 1, "foo_rgb")),
        ("render --variant cuda without a GPU", with_scene(["render", "SCENE", "--quality", "draft", "--cache", "TMP/c",
                                                            "--variant", "cuda_ad_rgb"], 1, "cuda_ad_rgb",
                                                           {"PBRBENCH_NO_CUDA": "1"})),
        ("history --limit 0", with_store(["history", "--store", "STORE", "--limit", "0"], 1, "--limit")),
        ("history --limit negative", with_store(["history", "--store", "STORE", "--limit", "-3"], 1, "--limit")),
        ("report unknown run", with_store(["report", "nosuchrun", "--store", "STORE", "--out", "TMP/r"], 1, "nosuchrun")),
        ("report a run beyond the history", with_store(["report", "-5", "--store", "STORE", "--out", "TMP/r"], 1, "-5")),
        ("compare unknown runs", with_store(["compare", "aaa", "bbb", "--store", "STORE"], 1, "aaa")),
        ("compare --rel negative", with_store(["compare", "latest", "latest", "--store", "STORE", "--rel", "-1"], 1, "--rel")),
        ("compare --rel nan", with_store(["compare", "latest", "latest", "--store", "STORE", "--rel", "nan"], 1, "--rel")),
        ("run --resume unknown run", with_store(["run", "--resume", "nosuchrun", "--store", "STORE", "--out", "TMP/o"], 1,
                                                "nosuchrun")),
        ("run --resume with --tasks", with_store(["run", "--resume", "latest", "--tasks", "lightness", "--store", "STORE"], 1,
                                                 "--resume")),
        ("run --variant unknown leaves no run", with_store(["run", "--tasks", "lightness", "--variant", "foo_rgb",
                                                            "--store", "STORE", "--out", "TMP/o"], 1, "foo_rgb")),
        ("scenes with terminal escapes in a description", with_scene(["scenes"], 0, None, {"PBRBENCH_SCENES": "TMP"},
                                                                      text=ESC_SCENE)),
        ("DRJIT_LIBLLVM_PATH is a renamed LLVM 15", with_scene(["render", "SCENE", "--quality", "draft", "--cache", "TMP/c",
                                                                "--no-previews"], 0, None,
                                                               {"DRJIT_LIBLLVM_PATH": "TMP/libLLVM-19.so"})),
        ("no usable libLLVM: one notice, scalar_rgb", with_scene(["render", "SCENE", "--quality", "draft", "--cache", "TMP/c",
                                                                  "--no-previews"], 0, None,
                                                                 {"PBRBENCH_LLVM_SEARCH": "TMP/llvm", "PBRBENCH_NO_CUDA": "1"})),
    ]
    return c


OLD_LLVM = sorted(p for p in __import__("glob").glob("/usr/lib/*/libLLVM-1[45]*.so*") if os.path.isfile(p) and not os.path.islink(p))


def isolated(name: str, env: dict | None) -> bool:
    """Whether a command-line case needs a process of its own: one that sets the environment, or
    chooses a variant or a libLLVM (chosen once per process, before Mitsuba is imported)."""
    return bool(env) or any(w in name for w in ("variant", "LLVM", "GPU"))


def run_in_process(args: list[str], *, env: dict | None = None, cwd=None) -> subprocess.CompletedProcess:
    """``pbrbench ARGS`` as :func:`pbrbench.cli.main.main` in this process, with the environment
    of :func:`child_env` (no PBRBENCH_* settings of this process) in ``cwd``: the exit code and
    what it printed (an exception that escapes ``main`` is printed as the traceback the
    interpreter would print, exit code 1)."""
    from pbrbench.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with child_environment(env, cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(list(args))
        except SystemExit as e:
            rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except Exception:  # noqa: BLE001 - what the user would see
            traceback.print_exc()
            rc = 1
    return subprocess.CompletedProcess(["pbrbench", *args], rc, out.getvalue(), err.getvalue())


@contextlib.contextmanager
def child_environment(env: dict | None = None, cwd=None):
    """This process with the PBRBENCH_* settings of :func:`child_env` (none of its own, progress
    off, then ``env``), in ``cwd``; both restored after."""
    saved_env, saved_cwd = dict(os.environ), os.getcwd()
    try:
        for k in [k for k in os.environ if k.startswith("PBRBENCH_")]:
            del os.environ[k]
        os.environ.update(PBRBENCH_PROGRESS="0", **(env or {}))
        os.chdir(cwd or tempfile.gettempdir())
        yield
    finally:
        os.chdir(saved_cwd)
        os.environ.clear()
        os.environ.update(saved_env)


def classify_cli(name, make, src: Path, shared: Shared | None = None, *, subprocess_only: bool = False) -> tuple[str, str]:
    """The outcome of one command-line case: in this process where isolation is not the point
    (:func:`isolated`) and ``src`` is the pbrbench this process imported, else a subprocess."""
    shared = shared or shared_for(src)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if OLD_LLVM:  # an LLVM 15 under a name that says 19, and a directory holding only it
            os.symlink(OLD_LLVM[-1], tmp / "libLLVM-19.so")
            (tmp / "llvm").mkdir()
            os.symlink(OLD_LLVM[-1], tmp / "llvm" / "libLLVM-19.so")
        try:
            args, env, want_rc, want = make(tmp, src, shared)
        except AssertionError as e:
            return "setup_failed", str(e)[-200:]
        store_before = _store_status(tmp / "h.sqlite", src) if (tmp / "h.sqlite").exists() else None
        work = tmp / "cwd"   # relative defaults (reports/, the store) land inside the case's directory
        work.mkdir()
        if subprocess_only or isolated(name, env) or not _this_checkout(src):
            r = _run([sys.executable, "-m", "pbrbench", *args], src, env, timeout=120, cwd=work)
        else:
            r = run_in_process(args, env=env, cwd=work)
        if r is None:
            return "timeout", ""
        if any(work.iterdir()) and want_rc == 1:
            return "other", f"a refused command left files behind: {sorted(p.name for p in work.rglob('*'))[:5]}"
        err = r.stderr.strip()
        lines = [ln for ln in err.splitlines() if ln.strip()]
        if "Traceback" in err or r.returncode in (-6, 134):
            return "traceback", (lines[-1] if lines else f"rc={r.returncode}")[:200]
        if r.returncode != want_rc:
            return "other", f"rc={r.returncode} (want {want_rc}) " + " // ".join(lines[-2:])[:200]
        if "\x1b" in r.stdout or "\x1b" in r.stderr or "\x07" in r.stdout:
            return "other", "a terminal escape sequence reached the terminal"
        if want_rc == 1 and (len(lines) > 1 or (want and want not in (lines[0] if lines else ""))):
            return "other", " // ".join(lines[-3:])[:240]
        if want_rc == 0 and "LLVM" in name:
            notes = [ln for ln in lines if "LLVM" in ln]
            if len(notes) != 1 or "/dev/null" in err:
                return "other", f"{len(notes)} notices: " + " // ".join(lines[-3:])[:240]
        if store_before is not None and _store_status(tmp / "h.sqlite", src) != store_before:
            return "other", f"the store changed: {store_before} -> {_store_status(tmp / 'h.sqlite', src)}"
        return "clean", (lines[-1][:200] if lines else "ok")


def measure_cli(src: Path = ROOT, verbose: bool = False) -> Counter:
    c: Counter = Counter()
    for name, make in cli_cases():
        outcome, msg = classify_cli(name, make, src)
        c[outcome] += 1
        if verbose:
            print(f"{name:48s} {outcome:10s} {msg}", flush=True)
    return c


if __name__ == "__main__" and len(sys.argv) > 1 and sys.argv[1] == "cli":
    src = Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT
    c = measure_cli(src, verbose=True)
    print(f"{sum(c.values())} command-line misuses: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))


if __name__ == "__main__" and len(sys.argv) > 1 and sys.argv[1] == "faults":
    src = Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT
    c = measure_faults(src, verbose=True)
    print(f"{sum(c.values())} disk faults: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))


if __name__ == "__main__" and (len(sys.argv) < 2 or sys.argv[1] == "scenes"):
    src = Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT
    c = measure_scenes(src, verbose=True)
    print(f"{sum(c.values())} scene files: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))
