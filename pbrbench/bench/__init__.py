"""The benchmark: run tasks (:mod:`.runner`), store results (:mod:`.store`), check them
against baselines (:mod:`.regress`)."""

from pbrbench.bench.runner import GroundTruthSource, RunConfig, RunOutcome, plan, run_benchmark
from pbrbench.bench.store import Store

__all__ = ["GroundTruthSource", "RunConfig", "RunOutcome", "Store", "plan", "run_benchmark"]
