"""Disk faults (simulated by tests/corpus/faults.py: read-only, permission denied, full disk, a
file where a directory belongs) and command-line misuse, each through the command line: a
one-line error naming the place, exit 1 (0 where reading still works), no traceback, and no
partial file left under a final name.  A disk fault runs as a subprocess (the fault injector
patches the process); a misuse case calls ``pbrbench.cli.main.main`` in this process unless it
sets the environment or chooses a variant or libLLVM (``measure.isolated``), and one of each
kind also runs as a subprocess (``python -m pbrbench``: the exit code the shell sees).  The
cases and the checks are those of ``python -m tests.corpus.measure faults|cli``; what the cases
start from (a store with one run, a warm render cache, a draft lightness benchmark's cache) is
built once per session, when a case first needs it."""

from __future__ import annotations

import pytest

from tests.corpus.measure import (
    ROOT,
    Shared,
    classify_cli,
    classify_fault,
    cli_cases,
    fault_cases,
    isolated,
)

FAULTS = fault_cases()
CLI = cli_cases()
NEEDS_RENDER = ("cache", "--out", "scratch", "run ")


@pytest.fixture(scope="session")
def shared(tmp_path_factory) -> Shared:
    """What the cases start from, each part built on first use (the draft lightness benchmark's
    cache by one run of the command line)."""
    return Shared(tmp_path_factory.mktemp("corpus-shared"), ROOT)


def _marks(name):
    return [pytest.mark.render] if name.startswith(NEEDS_RENDER) else []


@pytest.mark.slow   # a subprocess (or several) per case
@pytest.mark.parametrize("name,make", [pytest.param(n, m, marks=_marks(n), id=n) for n, m in FAULTS])
def test_disk_fault_is_a_clean_one_line_error(name, make, shared):
    outcome, msg = classify_fault(name, make, ROOT, shared)
    assert outcome == "clean", f"{name}: {outcome}: {msg}"


def _cli_marks(name, make):
    marks = [pytest.mark.render] if any(w in name for w in ("LLVM", "libLLVM", "variant")) else []
    return marks + ([pytest.mark.slow] if _isolated(name, make) else [])


def _isolated(name, make):
    """The case runs as a subprocess."""
    return isolated(name, getattr(make, "env", None))


@pytest.mark.parametrize("name,make", [pytest.param(n, m, marks=_cli_marks(n, m), id=n) for n, m in CLI])
def test_command_line_misuse_is_handled(name, make, shared):
    outcome, msg = classify_cli(name, make, ROOT, shared)
    assert outcome == "clean", f"{name}: {outcome}: {msg}"


# the in-process cases once more through ``python -m pbrbench``: a usage error, a store, a scene file
THROUGH_THE_SHELL = ["unknown option", "report unknown run", "render missing file"]


@pytest.mark.slow
@pytest.mark.parametrize("name", THROUGH_THE_SHELL)
def test_command_line_misuse_is_handled_by_a_subprocess_too(name, shared):
    make = dict(CLI)[name]
    assert not _isolated(name, make)
    outcome, msg = classify_cli(name, make, ROOT, shared, subprocess_only=True)
    assert outcome == "clean", f"{name}: {outcome}: {msg}"


def test_there_are_enough_cases():
    assert len(FAULTS) >= 23 and len(CLI) >= 45
