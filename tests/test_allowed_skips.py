"""A skip whose reason is not on tests/allowed_skips.txt fails the run (the hooks of
tests/conftest.py): the list parses, every entry says why, and a run with another skip exits 1."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from tests.conftest import ALLOWED_SKIPS, ROOT, allowed_skip_patterns, unexpected_skips


def test_the_list_parses_and_every_entry_says_why():
    patterns = allowed_skip_patterns()
    assert 0 < len(patterns) <= 8, "keep the list short: a line there is a check that may never run"
    for p, why in patterns:
        assert len(why.split()) >= 4, (p.pattern, why)


def test_a_line_without_its_reason_is_refused(tmp_path):
    p = tmp_path / "allowed.txt"
    p.write_text("# a comment\n\nno libLLVM installed\n")
    with pytest.raises(ValueError, match="allowed.txt:3: write 'REGEX # why"):
        allowed_skip_patterns(p)


def test_unexpected_skips_are_those_no_pattern_matches():
    patterns = allowed_skip_patterns()
    skips = [("a", "/usr/bin/chromium not installed (Debian package `chromium`)"), ("b", "could not import 'cv2': x"),
             ("c", "no libLLVM 14/15 to disguise"), ("d", "no shared draft cache")]
    assert unexpected_skips(skips, patterns) == [skips[1], skips[3]]


@pytest.mark.slow
def test_a_run_with_a_skip_not_on_the_list_fails(tmp_path):
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "allowed.txt").write_text("the platform lacks it # a test of the hook\n")
    (tmp_path / "conftest.py").write_text(textwrap.dedent(f"""
        from pathlib import Path
        from tests import conftest as C
        from tests.conftest import (pytest_collectreport, pytest_runtest_logreport, pytest_sessionfinish,
                                    pytest_terminal_summary)
        C.ALLOWED_SKIPS = Path({str(tmp_path / "allowed.txt")!r})
        """))
    (tmp_path / "test_x.py").write_text(textwrap.dedent("""
        import pytest

        def test_ok():
            pass

        def test_platform():
            pytest.skip("the platform lacks it")

        def test_forgotten():
            pytest.skip("could not import 'nosuchmodule'")

        @pytest.mark.xfail(reason="an expected failure is no skip")
        def test_xfail():
            assert False
        """))

    def run(*args):
        return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", *args], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})

    ok = run("-k", "not forgotten")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad = run()
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert "1 skip(s) not on tests/allowed_skips.txt" in bad.stdout
    assert "test_x.py::test_forgotten: could not import 'nosuchmodule'" in bad.stdout
    assert ALLOWED_SKIPS.is_file()
