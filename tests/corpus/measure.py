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
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
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


def run_cli(args: list[str], *, src: Path = ROOT, env: dict | None = None, timeout: float = 60, cwd=None):
    e = {k: v for k, v in os.environ.items() if not k.startswith("PBRBENCH_")}
    e.update(PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1", PBRBENCH_PROGRESS="0")
    e.update(env or {})
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


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "scenes"
    src = Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT
    if what == "scenes":
        c = measure_scenes(src, verbose=True)
        print(f"{sum(c.values())} scene files: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))
