"""Disk faults (simulated by tests/corpus/faults.py: read-only, permission denied, full disk, a
file where a directory belongs) and command-line misuse, each through the command line as a
subprocess: a one-line error naming the place, exit 1 (0 where reading still works), no
traceback, and no partial file left under a final name.  The cases and the checks are those of
``python -m tests.corpus.measure faults|cli``."""

from __future__ import annotations

import os

import pytest

from tests.corpus.measure import (
    ROOT,
    SHARED_CACHE,
    classify_cli,
    classify_fault,
    cli_cases,
    fault_cases,
)

pytestmark = pytest.mark.slow   # a subprocess (or several) per case

FAULTS = fault_cases()
CLI = cli_cases()
NEEDS_RENDER = ("cache", "--out", "scratch")


def _marks(name):
    if name.startswith("run "):
        return [pytest.mark.render, pytest.mark.skipif(not os.path.isdir(SHARED_CACHE), reason="no shared draft cache")]
    return [pytest.mark.render] if name.startswith(NEEDS_RENDER) else []


@pytest.mark.parametrize("name,make", [pytest.param(n, m, marks=_marks(n), id=n) for n, m in FAULTS])
def test_disk_fault_is_a_clean_one_line_error(name, make):
    outcome, msg = classify_fault(name, make, ROOT)
    assert outcome == "clean", f"{name}: {outcome}: {msg}"


def _cli_marks(name):
    return [pytest.mark.render] if any(w in name for w in ("LLVM", "libLLVM", "variant")) else []


@pytest.mark.parametrize("name,make", [pytest.param(n, m, marks=_cli_marks(n), id=n) for n, m in CLI])
def test_command_line_misuse_is_handled(name, make):
    outcome, msg = classify_cli(name, make, ROOT)
    assert outcome == "clean", f"{name}: {outcome}: {msg}"


def test_there_are_enough_cases():
    assert len(FAULTS) >= 23 and len(CLI) >= 45
