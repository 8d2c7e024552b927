"""Malformed real-data folders (tests/corpus/realdata_faults.py) through the loaders of
pbrbench.datasets and through `pbrbench infer`: every malformed input is one line naming the
file (a typed UserError for API users; exit 1 and one `pbrbench: error:` line, no traceback, for
the command line), data that may still be valid is a warning naming the file, and the valid
controls load without a warning.  In this process (fast), except two cases run as
`python -m pbrbench` to check what the shell sees, C libraries' own output included."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from tests.corpus.realdata_faults import (
    API_SURFACES,
    cases,
    classify_api,
    classify_cli,
    cli_argv,
    prepare,
)

CASES = cases()
ROOT = Path(__file__).resolve().parents[2]


def test_the_corpus_covers_every_surface_and_outcome():
    kinds = Counter((c.surface, c.expect) for c in CASES)
    for surface in ("bracket", "diligent", "mit", "render", "image"):
        assert kinds[(surface, "error")] >= 8 and kinds[(surface, "ok")] >= 1, surface
    for surface in ("bracket", "diligent", "mit"):
        assert kinds[(surface, "warn")] >= 2, surface
    assert len(CASES) >= 120 and len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", [c for c in CASES if c.surface in API_SURFACES], ids=lambda c: c.id)
def test_loader_gives_a_typed_one_line_error_or_warning(case, tmp_path):
    outcome, msg = classify_api(case, tmp_path)
    assert outcome == "as_expected", f"{case.id} (expected {case.expect}): {outcome}: {msg}"


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_infer_command_exits_1_with_one_line_naming_the_file(case, tmp_path):
    outcome, msg = classify_cli(case, tmp_path)
    assert outcome == "as_expected", f"{case.id} (expected {case.expect}): {outcome}: {msg}"


@pytest.mark.parametrize("cid", ["render:exr_truncated", "bracket:times_reversed"])
def test_what_the_shell_sees(cid, tmp_path):
    """A subprocess: the exit code, and stderr free of a C library's own lines and tracebacks."""
    case = next(c for c in CASES if c.id == cid)
    path = prepare(case, tmp_path)
    p = subprocess.run([sys.executable, "-m", "pbrbench", *cli_argv(case, path, tmp_path / "out")], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 1, p.stderr
    assert all(ln.startswith("pbrbench: ") for ln in lines), p.stderr
    errors = [ln for ln in lines if ln.startswith("pbrbench: error:")]
    assert len(errors) == 1 and case.names in errors[0] and "Traceback" not in p.stderr, p.stderr
