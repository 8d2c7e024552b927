"""The pool executor (``--executor pool``): renders and jobs in worker processes of this machine.
Every score equals the local executor's, bit for bit; a worker that dies is one clear error and
the results finished before it are kept; the longest jobs are handed out first."""

import os
import time

import pytest

from pbrbench.bench.executors import PoolExecutor, make_executor
from pbrbench.bench.run import RunConfig, _expected_cost, run_benchmark
from pbrbench.errors import UserError
from pbrbench.quality import DRAFT
from pbrbench.registry import Algorithm
from pbrbench.tasks.base import Job
from tests.fakes import FakeSource, FakeTask, settings_for


def _key(s):
    return (s["task"], s["scene"], s["condition"], s["algorithm"], s["metric"], s["job"])


def _pid_and_square(x):
    return os.getpid(), x * x


def _die_on(x, bad):
    if x == bad:
        os._exit(3)
    return x


def test_results_come_from_several_processes_each_exactly_once(tmp_path):
    ex = PoolExecutor(workers=2, variant=None, settings=settings_for(tmp_path))
    try:
        out = list(ex.imap(_pid_and_square, [(i,) for i in range(12)]))
    finally:
        ex.close()
    assert sorted(v for _, v in out) == [i * i for i in range(12)]
    assert os.getpid() not in {p for p, _ in out}


def test_a_worker_that_dies_is_one_error_and_the_results_before_it_are_kept(tmp_path):
    ex = PoolExecutor(workers=1, variant=None, settings=settings_for(tmp_path))
    got = []
    try:
        with pytest.raises(UserError, match=r"a worker process died \(\d+ of 6 tasks finished and kept.*--resume"):
            for v in ex.imap(_die_on, [(i, 4) for i in range(6)]):
                got.append(v)
    finally:
        ex.close()
    assert sorted(got) == [0, 1, 2, 3]      # one worker runs them in order: every result before the death


def test_unknown_executor_names_the_choices(tmp_path):
    with pytest.raises(UserError, match="choose local, pool or dask"):
        make_executor("threads", settings=settings_for(tmp_path))


def test_the_pool_scores_exactly_what_the_local_executor_scores(tmp_path):
    ex = PoolExecutor(workers=2, variant=None, settings=settings_for(tmp_path / "p"))
    try:
        o_p = run_benchmark(RunConfig(quality="draft", executor="pool"), settings=settings_for(tmp_path / "p"),
                            tasks={"fake": FakeTask()}, source=FakeSource(tmp_path / "fake-p"), executor=ex,
                            log=lambda m: None)
    finally:
        ex.close()
    o_l = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path / "l"), tasks={"fake": FakeTask()},
                        source=FakeSource(tmp_path / "fake-l"), log=lambda m: None)
    assert not o_p.errors and not o_l.errors
    dp = {_key(s): repr((s["value"], s.get("uncertainty"))) for s in o_p.scores}   # repr: nan == nan
    dl = {_key(s): repr((s["value"], s.get("uncertainty"))) for s in o_l.scores}
    assert len(dp) > 0 and dp == dl      # bit-identical, standard errors included
    # figures came back from the workers
    assert len(list((tmp_path / "p" / "reports" / o_p.run_id / "figures").glob("*/manifest.json"))) == \
        len(list((tmp_path / "l" / "reports" / o_l.run_id / "figures").glob("*/manifest.json"))) > 0


def _solve(images, lights, **kw):   # pragma: no cover - never called
    raise AssertionError


def test_jobs_with_inverse_rendering_are_ranked_first():
    job = Job("photometric_stereo", "ps_cup[albedo=0.9]", "global", ())
    plain = Algorithm("a", "photometric_stereo", _solve)
    scene = Algorithm("inv", "photometric_stereo", _solve, interface="scene", conditions=("global",))
    assert _expected_cost(job, [plain], DRAFT) == 0
    assert _expected_cost(job, [plain, scene], DRAFT) == 1
    off = Algorithm("inv", "photometric_stereo", _solve, interface="scene", conditions=("local",))
    assert _expected_cost(job, [plain, off], DRAFT) == 0


def test_every_result_that_arrived_with_a_death_is_kept():
    # the results that came back in the same wait() as a dead worker's future are yielded before
    # the error, whatever order the set of finished futures has (it once lost one of them: the
    # result of the task just before the death, intermittently, under load)
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    import cloudpickle

    futures = []

    class _Pool:
        def submit(self, fn, payload):
            f = Future()
            i = len(futures)
            if i == 7:
                f.set_exception(BrokenProcessPool("a child process terminated abruptly"))
            else:
                f.set_result(cloudpickle.dumps(i))
            futures.append(f)
            return f

        def shutdown(self, **kw):
            pass

    ex = object.__new__(PoolExecutor)
    ex.workers, ex._pool, ex._pending, ex._total, ex._done = 1, _Pool(), set(), 0, 0
    got = []
    with pytest.raises(UserError, match=r"a worker process died \(20 of 21 tasks finished and kept"):
        for v in ex.imap(_die_on, [(i, -1) for i in range(21)]):
            got.append(v)
    assert sorted(got) == [i for i in range(21) if i != 7]


class _WaitForAJobSource(FakeSource):
    """Each render after the first waits (up to 20 s) until a worker has loaded a ground truth
    for a job, and notes in ``saw`` whether one did: with the renders and the jobs in sequence
    none can."""

    def render(self, spec):
        root = self.cache.root
        root.mkdir(parents=True, exist_ok=True)
        if list(root.glob("rendered-*")):
            deadline = time.monotonic() + 20.0
            while not list(root.glob("loaded-*")) and time.monotonic() < deadline:
                time.sleep(0.05)
            (root / f"saw-{spec.name}").write_text(str(bool(list(root.glob("loaded-*")))))
        (root / f"rendered-{spec.name}").write_text("")
        return super().render(spec)

    def load(self, spec):
        (self.cache.root / f"loaded-{spec.name}").write_text("")
        return super().load(spec)


def test_a_job_starts_on_the_pool_as_soon_as_its_scenes_are_rendered(tmp_path):
    ex = PoolExecutor(workers=2, variant=None, settings=settings_for(tmp_path))
    src = _WaitForAJobSource(tmp_path / "fake")
    try:
        o = run_benchmark(RunConfig(quality="draft", executor="pool"), settings=settings_for(tmp_path),
                          tasks={"fake": FakeTask()}, source=src, executor=ex, log=lambda m: None)
    finally:
        ex.close()
    assert not o.errors and o.renders == 2
    (saw,) = (tmp_path / "fake").glob("saw-*")     # the second render ran while a job of the first scene did
    assert saw.read_text() == "True"
    # and the scores are those of the same run with the renders and jobs in sequence
    o_l = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path / "l"), tasks={"fake": FakeTask()},
                        source=FakeSource(tmp_path / "fake-l"), log=lambda m: None)
    assert {_key(s): repr(s["value"]) for s in o.scores} == {_key(s): repr(s["value"]) for s in o_l.scores}
