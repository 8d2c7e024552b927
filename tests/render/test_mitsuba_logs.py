"""Mitsuba's log lines go to stderr, prefixed and without colours; stdout carries only what a
script parses (``run ID: ...``), also for a line logged from another thread."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("mitsuba")


def test_mitsuba_warnings_go_to_stderr_not_stdout():
    code = textwrap.dedent("""
        import threading
        from pbrbench.render.variant import mitsuba
        mi = mitsuba("scalar_rgb")
        mi.Log(mi.LogLevel.Warn, "a warning")
        t = threading.Thread(target=lambda: mi.Log(mi.LogLevel.Warn, "from a thread"))
        t.start(); t.join()
        print("run ID: x")
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout == "run ID: x\n", p.stdout
    warns = [ln for ln in p.stderr.splitlines() if ln.startswith("pbrbench: mitsuba:")]
    assert len(warns) == 2 and "a warning" in warns[0] and "from a thread" in warns[1], p.stderr
    assert "\x1b" not in p.stderr
