"""The regression suite: the benchmark at draft quality on every task, *re-rendered with a render
seed the baselines never saw*, each score compared with the committed baselines
``tests/baselines/draft.json`` (the mean and noise of three runs with independent render seeds:
see :mod:`pbrbench.bench.regress`).  The check must pass (no regression beyond the family-wise
limit, no more per-score flags than chance gives) and flag at most 1 % of the scores: the
false-alarm rate of the per-score rule on a run whose only change is the render noise.

Renders every draft ground truth the tasks need (minutes from a cold cache; set
PBRBENCH_TEST_CACHE to keep them between sessions).  Rewrite the baselines deliberately with
``pbrbench run --quality draft --update-baselines``.
"""

import pytest

from pbrbench.bench import regress
from pbrbench.bench.plan import load_tasks
from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.bench.source import GroundTruthSource
from pbrbench.quality import DRAFT
from pbrbench.render.cache import RenderCache
from pbrbench.settings import Settings
from tests.fakes import settings_for

pytestmark = [pytest.mark.render, pytest.mark.slow]


@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_draft_scores_match_baselines(tmp_path, cache_dir):
    path = Settings.from_env().baseline_path(DRAFT)
    baselines = regress.load_baselines(path) if path is not None else None
    if baselines is None:
        pytest.skip(f"{path} does not exist; create it with `pbrbench run --quality draft --update-baselines`")
    tasks = load_tasks(None)
    st = settings_for(tmp_path, cache=cache_dir)
    fresh = 1 + max(int(s["render_seed"]) for s in baselines["seeds"])    # a render seed not in the baselines
    o = run_benchmark(RunConfig(quality="draft", seed=fresh, render_seed=fresh, report=False), settings=st,
                      tasks=tasks, source=GroundTruthSource(DRAFT, cache=RenderCache(cache_dir), render_seed=fresh),
                      log=lambda m: None)
    assert not o.errors, "jobs failed:\n" + "\n".join(f"{k}: {v.strip().splitlines()[-1]}" for k, v in o.errors.items())
    comp = regress.compare(o.scores, baselines)
    assert comp.n_checked > 0, "no score of this run has a baseline; regenerate them with --update-baselines"
    missing = [f"missing score (in baselines, not produced): {k}" for k in comp.missing]
    assert not missing, "\n".join(missing[:50])
    flagged = comp.regressions + comp.improvements
    assert comp.ok, (f"{len(comp.regressions)} regression(s) (at most {comp.allowed} by chance), {len(comp.strong)} beyond "
                     f"the family-wise limit, against {path}:\n" + "\n".join(str(c) for c in comp.strong[:30] + comp.regressions[:30]))
    assert len(flagged) <= 0.01 * comp.n_checked, (f"{len(flagged)} of {comp.n_checked} scores flagged by a re-seeded "
                                                   "run (false alarms above 1 %):\n" + "\n".join(str(c) for c in flagged[:40]))
    # the same run with every noisy score made worse by 5 standard deviations of the comparison
    # (the baseline's sd pooled with the run's own jackknife SE, as the check pools them): at least
    # 90 % of them are flagged, and the check fails
    from pbrbench.uncertainty import dof_of, pooled_sd

    planted, keys = [], set()
    for s in o.scores:
        e = baselines["entries"].get(regress.score_key(s))
        if e is None or not e.get("sd") or e["sd"] <= regress.rounding(s["value"]) or e.get("unstable") or s.get("unstable"):
            planted.append(s)
            continue
        sd, _ = pooled_sd((e["sd"], e["dof"]), (s["uncertainty"], dof_of(s)))
        keys.add(regress.score_key(s))
        planted.append(dict(s, value=s["value"] + (5 if s["better"] == "lower" else -5) * sd))
    cp = regress.compare(planted, baselines)
    hit = sum(1 for c in cp.regressions if regress.score_key(c.__dict__) in keys)
    assert len(keys) > 0.5 * comp.n_checked and hit >= 0.9 * len(keys) and not cp.ok, (hit, len(keys))
