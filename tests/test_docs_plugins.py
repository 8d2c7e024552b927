"""The examples of docs/plugins.md work as written: each task's example plugin, loaded from its
own .py file with --algorithm, is scored in a run of that task (synthetic ground truths)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.plugins import plugin_registry
from pbrbench.registry import Registry
from tests.bench.test_external import TASKS, Synthetic
from tests.fakes import settings_for

DOC = Path(__file__).resolve().parents[1] / "docs" / "plugins.md"
EXAMPLES = {"mine.py": ("photometric_stereo", "lstsq"), "flat.py": ("sfs", "facing"),
            "blur.py": ("lightness", "homomorphic"), "gamma.py": ("hdr", "gamma22"),
            "clip.py": ("specular", "clip_top")}


def _blocks() -> dict[str, str]:
    out = {}
    for code in re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S):
        m = re.match(r"# (\w+\.py)\b", code)
        if m:
            out[m.group(1)] = code
    return out


def test_every_task_has_an_example():
    assert set(_blocks()) == set(EXAMPLES)


@pytest.mark.parametrize("file", list(EXAMPLES))
def test_the_example_plugin_is_scored(tmp_path, file):
    task_name, fn = EXAMPLES[file]
    code = _blocks()[file]
    assert 6 <= len(code.strip().splitlines()) <= 12          # "a 10-line example"
    (tmp_path / file).write_text(code)
    task = TASKS[task_name]
    reg = plugin_registry({task.name: task}, [f"{task_name}={tmp_path / file}:{fn}"], entry_points=False,
                          time_limit=120.0)
    o = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path), tasks={task.name: task},
                      source=Synthetic(tmp_path / "cache"), registry=Registry(reg.for_task(task.name, kinds=["plugin"])),
                      log=lambda m: None)
    mine = [s for s in o.scores if s["algorithm"] == fn]
    assert mine and not [s for s in mine if s["metric"] == "failed" and s["value"] == 1.0], \
        (tmp_path / "reports" / o.run_id / "index.html").read_text()[-3000:]
    assert any(s["metric"] == task.headline_metric for s in mine)
