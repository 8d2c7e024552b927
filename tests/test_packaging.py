"""A wheel of pbrbench, installed outside the source checkout, ships its scene library and runs
a draft benchmark task and writes its report (the scene files and the report's templates are package
data, nothing reads the checkout).  One task: the whole draft benchmark runs from the checkout in the
regression suite; here it would only repeat those jobs."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.render
@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_wheel_outside_the_checkout_lists_scenes_and_runs_draft(tmp_path, cache_dir):
    whl = tmp_path / "wheel"
    p = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(whl), str(ROOT)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "Deprecat" not in p.stderr, p.stderr[-3000:]
    (wheel,) = whl.glob("pbrbench-*.whl")
    site = tmp_path / "site"
    p = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site), str(wheel)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("PBRBENCH_")}
    env.update(PYTHONPATH=str(site), PBRBENCH_CACHE=str(cache_dir))

    def run(*args, timeout=900):
        return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, cwd=work, timeout=timeout)

    q = run("-c", "import pbrbench, pbrbench.settings as s; print(pbrbench.__file__); print(s.LIBRARY_DIR)")
    where, library = q.stdout.split()
    assert where.startswith(str(site)) and library.startswith(str(site)), q.stdout
    q = run("-m", "pbrbench", "scenes")
    assert q.returncode == 0 and "ps_groove" in q.stdout and "hdr_scene" in q.stdout, q.stderr[-2000:]
    q = run("-m", "pbrbench", "run", "--quality", "draft", "--tasks", "lightness", "--out", str(work / "reports"))
    assert q.returncode == 0, q.stdout[-2000:] + q.stderr[-3000:]
    assert (work / "reports" / "history.sqlite").is_file() and "report: " in q.stdout
    report = Path(q.stdout.split("report: ")[-1].strip())
    assert (report.parent / "style.css").is_file() and (report.parent / "task-lightness.html").is_file()
    assert "baselines:" not in q.stdout  # a wheel has no regression baselines, and says nothing about them
