"""The plugin-fault corpus (tests/corpus/plugin_faults.py): a plugin that sleeps, exits, crashes,
raises or monkeypatches pbrbench at import or registration, mutates its inputs, exits or hangs
when called (and the run killed with ``kill -9``), a timeout under the job cache, ``--resume``
after the plugin changed, and mistyped task names.  Each case: the run goes on, one clear line,
built-in scores unchanged, no process left.  ``python -m tests.corpus.plugin_faults`` prints
the same cases as ``N of M handled``."""

from __future__ import annotations

import pytest

from tests.corpus.plugin_faults import CASES

# each case starts worker processes and waits out load and time limits (2-5 s): in `make test`,
# not in the fast loop
pytestmark = pytest.mark.slow


@pytest.mark.parametrize("name", list(CASES))
def test_plugin_fault_is_handled(name, tmp_path):
    problems = CASES[name](tmp_path)
    assert not problems, f"{name}: {problems}"


def test_there_are_enough_cases():
    assert len(CASES) >= 20
