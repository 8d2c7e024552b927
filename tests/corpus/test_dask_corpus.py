"""The Dask faults of ``tests/corpus/dask_faults.py``, each through a run of the benchmark: one
line naming the scheduler's address and ``--resume RUN``, the run recorded as ``interrupted``
with every job it stored kept, no traceback on stderr, and a resume whose scores equal a local
run's, bit for bit (locally, and for one case on a new scheduler).  One case also runs through
the command line (``pbrbench run --scheduler`` at an address that never answers)."""

from __future__ import annotations

import re
import socket

import pytest

from pbrbench.settings import Settings

pytest.importorskip("distributed", reason="Dask distributed is not installed (pip install 'dask[distributed]')")

from tests.corpus.dask_faults import (  # noqa: E402
    CASES,
    N_JOBS,
    dask_cli,
    free_port,
    local_run,
    resume,
    run_case,
    score_table,
)

pytestmark = pytest.mark.slow   # a Dask scheduler and worker per case


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    return score_table(local_run(tmp_path_factory.mktemp("dask-reference")))


def _check_one_line(res, captured: str):
    from pbrbench.bench.executors import SchedulerLost

    assert isinstance(res.error, SchedulerLost), f"{type(res.error).__name__}: {res.error}"
    msg = str(res.error)
    assert "\n" not in msg and res.address in msg, msg
    assert res.run_id and f"--resume {res.run_id}" in msg, msg
    assert "Traceback" not in captured and "distributed.client - ERROR" not in captured, captured[-2000:]
    assert res.status == "interrupted", res.status


@pytest.mark.parametrize("case", [pytest.param(c, id=c.name) for c in CASES])
def test_a_dask_fault_interrupts_the_run_in_one_line_and_resumes(case, tmp_path, capfd, reference):
    if case.address is None and dask_cli() is None:
        pytest.skip("the `dask` command is not installed")
    res = run_case(case, tmp_path)
    _check_one_line(res, capfd.readouterr().err)
    assert case.min_done <= res.done < N_JOBS, res.done
    on_new = case.kill == "jobs:2"
    o = resume(res, tmp_path, on_new_scheduler=on_new)
    assert not o.errors and o.n_skipped == res.done and o.n_jobs == N_JOBS
    assert score_table(o) == reference        # nothing lost, nothing computed twice differently
    assert "Traceback" not in capfd.readouterr().err


def test_a_scheduler_that_never_answers_through_the_command_line(tmp_path, capfd, monkeypatch):
    """``pbrbench run --executor dask --scheduler ADDR``: one line on stderr, nothing on stdout, exit
    1, and the run it created reads ``interrupted`` (resumable)."""
    from pbrbench.bench.store import Store
    from pbrbench.cli.main import main

    monkeypatch.setenv("DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT", "2s")
    import dask

    dask.config.refresh()
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(4)
        addr = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        code = main(["run", "--executor", "dask", "--scheduler", addr, "--tasks", "lightness", "--quality", "draft",
                     "--out", str(tmp_path / "out"), "--store", str(tmp_path / "h.sqlite"),
                     "--cache", str(tmp_path / "cache"), "--no-report"])
    dask.config.refresh()
    out, err = capfd.readouterr()
    # the progress bar's closing summary ("render (draft) done (0/6 scenes)") is not the error
    lines = [ln for ln in err.splitlines() if ln.strip() and not re.match(r"pbrbench: render \(\w+\) done", ln)]
    assert code == 1 and out == "", (code, out)
    assert len(lines) == 1 and addr in lines[0] and "--resume" in lines[0], err
    assert "Traceback" not in err
    with Store(tmp_path / "h.sqlite") as s:
        runs = s.runs()
    assert [r["status"] for r in runs] == ["interrupted"]
    assert f"--resume {runs[0]['id']}" in lines[0]


def test_an_address_that_is_not_one_is_a_usage_line():
    from pbrbench.bench.executors import DaskExecutor
    from pbrbench.errors import UserError

    ex = DaskExecutor(scheduler=f"nonsense://127.0.0.1:{free_port()}", workers=None, variant=None,
                      settings=Settings.from_env())
    with pytest.raises(UserError, match="--scheduler nonsense://"):
        _ = ex.client
    ex.close()
