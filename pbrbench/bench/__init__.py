"""The benchmark in four parts: :mod:`.plan` (jobs from tasks and a quality profile),
:mod:`.source` (ground truths from the render cache), :mod:`.executors` (local, Dask) and
:mod:`.run` (orchestration, store, regression check, report); :mod:`.store` is the SQLite results
store and :mod:`.regress` the regression baselines."""

from pbrbench.bench.run import RunConfig, RunOutcome, run_benchmark
from pbrbench.bench.source import GroundTruthSource
from pbrbench.bench.store import Store

__all__ = ["GroundTruthSource", "RunConfig", "RunOutcome", "Store", "run_benchmark"]
