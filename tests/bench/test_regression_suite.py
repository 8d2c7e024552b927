"""The regression suite: the benchmark at draft quality on every task, each score compared with
the committed baselines ``tests/baselines/draft.json`` (value, direction and a tolerance measured
from the run-to-run spread over seeds: see :mod:`pbrbench.bench.regress`).

Renders every draft ground truth the tasks need (minutes from a cold cache; set
PBRBENCH_TEST_CACHE to keep them between sessions).  Rewrite the baselines deliberately with
``pbrbench run --quality draft --update-baselines``.
"""

import pytest

from pbrbench.bench import regress
from pbrbench.bench.plan import load_tasks
from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.bench.source import GroundTruthSource
from pbrbench.render.cache import RenderCache
from tests.fakes import settings_for

pytestmark = [pytest.mark.render, pytest.mark.slow]


def test_draft_scores_match_baselines(tmp_path, cache_dir):
    path = regress.baseline_path("draft")
    baselines = regress.load_baselines(path) if path is not None else None
    if baselines is None:
        pytest.skip(f"{path} does not exist; create it with `pbrbench run --quality draft --update-baselines`")
    tasks = load_tasks(None)
    st = settings_for(tmp_path, cache=cache_dir)
    o = run_benchmark(RunConfig(quality="draft", seed=baselines["seeds"][0], report=False), settings=st, tasks=tasks,
                      source=GroundTruthSource("draft", cache=RenderCache(cache_dir)), log=lambda m: None)
    assert not o.errors, "jobs failed:\n" + "\n".join(f"{k}: {v.strip().splitlines()[-1]}" for k, v in o.errors.items())
    comp = regress.compare(o.scores, baselines)
    assert comp.n_checked > 0, "no score of this run has a baseline; regenerate them with --update-baselines"
    problems = [str(c) for c in comp.regressions] + [f"missing score (in baselines, not produced): {k}" for k in comp.missing]
    assert not problems, f"{len(problems)} problem(s) against {path}:\n" + "\n".join(problems[:50])
